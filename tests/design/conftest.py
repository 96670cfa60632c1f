"""Shared fixtures of the design tests."""

from __future__ import annotations

import pytest
from fdisyn.models.sampled_data import SampledDataPlant
from fdisyn.problems.sampled_data_example import PLANT


@pytest.fixture(scope="session")
def paper_plant() -> SampledDataPlant:
    """The example plant of Qiu, Wen & Jiang (Control Theory & Applications 27(8), 2010, section 4),
    sampled at Ts = 1 s: the ``sampled_data_example`` problem's."""
    return PLANT
