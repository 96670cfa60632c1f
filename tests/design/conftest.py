"""Shared data for the design tests: seed 004's example and seeded random systems."""

from __future__ import annotations

import numpy as np
import pytest

from fdisyn.design.norms import DiscreteLTI
from fdisyn.design.sampled_data import SampledDataPlant

# Seed 004, section 4: the paper's continuous plant, sampled at h = 1 s.
PAPER = {
    "A": np.array([[-1.0, 5.0], [0.0, -2.0]]),
    "Bu": np.array([[0.0], [1.0]]),
    "Bd": np.array([[0.1], [1.0]]),
    "Bf": np.array([[0.0], [1.0]]),
    "C": np.eye(2),
    "h": 1.0,
}
# The gains the paper prints (2 decimals); its "H" is E.
PAPER_GAINS = {
    "L": np.array([[0.38, 1.16], [0.0, 0.14]]),
    "E": np.array([[1.0], [0.43]]),
    "W": np.array([[0.90, -0.90], [0.0, 2.86]]),
    "V": np.array([[0.90, -0.90], [0.0, 2.86]]),
}


@pytest.fixture(scope="session")
def paper_plant() -> SampledDataPlant:
    return SampledDataPlant.create(**PAPER)


def random_stable(rng: np.random.Generator, n: int, m: int, p: int, *, radius: float = 0.9, d: bool = True) -> DiscreteLTI:
    """A random Schur-stable system with spectral radius ``radius``."""
    a = rng.standard_normal((n, n))
    a *= radius / max(np.abs(np.linalg.eigvals(a)))
    return DiscreteLTI.create(
        A=a,
        B=rng.standard_normal((n, m)),
        C=rng.standard_normal((p, n)),
        D=0.3 * rng.standard_normal((p, m)) if d else np.zeros((p, m)),
    )
