"""Real numbers as fdisyn.runtime.values reads them: numbers only, never converted from text or booleans."""

from __future__ import annotations

import math

import numpy as np
import pytest
from fdisyn.runtime.values import real_number


@pytest.mark.parametrize(
    ("value", "expected"),
    [(1, 1.0), (-2.5, -2.5), (np.float32(0.5), 0.5), (np.int64(7), 7.0), (10**400, math.inf), (-(10**400), -math.inf)],
)
def test_numbers_are_read_as_floats(value: object, expected: float) -> None:
    assert real_number(value) == expected


def test_nan_and_infinity_are_numbers_the_caller_tests() -> None:
    assert math.isnan(real_number(float("nan")))  # type: ignore[arg-type]
    assert real_number(float("inf")) == math.inf


@pytest.mark.parametrize("value", [True, np.True_, "1.5", None, 1j, [1.0], np.array([1.0]), b"1"])
def test_anything_else_is_no_number(value: object) -> None:
    assert real_number(value) is None
