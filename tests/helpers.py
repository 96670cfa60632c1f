"""Helpers shared by the tests (seeded random systems)."""

from __future__ import annotations

import numpy as np
from fdisyn.design.norms import DiscreteLTI
from fdisyn.design.plant import LinearPlant


def random_plant(seed: int, *, n: int | None = None, p: int | None = None, q: int | None = None, radius: float | None = None) -> LinearPlant:
    """A random discrete plant with unknown inputs that meets the UIO conditions generically.

    ``A`` is scaled to spectral radius in [0.5, 1.3] (so unstable plants occur),
    ``Q``, ``R`` are random positive definite covariances.
    """
    rng = np.random.default_rng(seed)
    q = q if q is not None else int(rng.integers(1, 3))
    p = p if p is not None else int(rng.integers(q + 1, q + 3))
    n = n if n is not None else int(rng.integers(max(p, 2), 6))
    a = rng.standard_normal((n, n))
    rad = radius if radius is not None else float(rng.uniform(0.5, 1.3))
    a *= rad / max(abs(np.linalg.eigvals(a)))
    mq = rng.standard_normal((n, n))
    mr = rng.standard_normal((p, p))
    return LinearPlant.create(
        A=a,
        B=rng.standard_normal((n, 2)),
        C=rng.standard_normal((p, n)),
        E=rng.standard_normal((n, q)),
        Q=mq @ mq.T / n + 0.05 * np.eye(n),
        R=mr @ mr.T / p + 0.05 * np.eye(p),
        Ts=0.1,
    )


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
