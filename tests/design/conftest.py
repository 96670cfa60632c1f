"""Shared data for the design tests: seeded random systems."""

from __future__ import annotations

import numpy as np
from fdisyn.design.norms import DiscreteLTI

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
