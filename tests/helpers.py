"""Helpers shared by the tests (seeded random systems)."""

from __future__ import annotations

import numpy as np

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
