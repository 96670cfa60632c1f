"""Helpers shared by the tests (seeded random systems)."""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
from fdisyn.models.linear import LinearPlant
from fdisyn.models.sampled_data import SampledDataPlant
from fdisyn.numerics.norms import DiscreteLTI


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


def check_values(certificate: object) -> dict[str, list[float]]:
    """``name → values`` of every check in a :class:`Certificate` or a gain file's certificate
    document (its generators' and its bank's checks), for tests that judge the values
    themselves: a design whose certificate failed has raised, so ``passed`` is always true."""
    if hasattr(certificate, "checks"):
        rows = [(c.name, float(c.value)) for c in certificate.checks]  # type: ignore[attr-defined]
    else:
        doc = dict(certificate)  # type: ignore[call-overload]
        parts = [*doc.get("generators", []), *([doc["bank"]] if "bank" in doc else []), doc]
        rows = [(c["name"], float(c["value"])) for part in parts for c in part.get("checks", [])]
    out: dict[str, list[float]] = {}
    for name, value in rows:
        out.setdefault(name, []).append(value)
    return out


def coupling_markov(plant: dict, gen: object, count: int | None = None) -> tuple[float, float]:
    """How much ``u`` and ``d`` reach a generator's residual through the plant, computed here
    from the matrices alone: the largest Markov parameter of ``u → r`` and ``d → r`` of
    plant-in-series-with-generator, relative to the product of the norms that form it
    (0 for exact decoupling; round-off leaves ~1e-16)."""
    a, b, c, d, e = (np.asarray(plant[k], dtype=float) for k in ("A", "B", "C", "D", "E"))
    ar, bu, by, cr, du, dy = (np.asarray(getattr(gen, k), dtype=float) for k in ("Ar", "Bu", "By", "Cr", "Du", "Dy"))
    n, ns = a.shape[0], ar.shape[0]
    big_a = np.block([[a, np.zeros((n, ns))], [by @ c, ar]])
    big_c = np.hstack([dy @ c, cr])
    inputs = {"u": (np.vstack([b, by @ d + bu]), dy @ d + du), "d": (np.vstack([e, np.zeros((ns, e.shape[1]))]), np.zeros((cr.shape[0], e.shape[1])))}
    out = []
    for bb, dd in inputs.values():
        scale = max(np.linalg.norm(dy) * np.linalg.norm(d) + np.linalg.norm(du), np.finfo(float).tiny)
        worst = float(np.linalg.norm(dd)) / scale
        power = np.eye(n + ns)
        for _ in range(count or 2 * (n + ns)):
            term = big_c @ power @ bb
            worst = max(worst, float(np.linalg.norm(term)) / max(np.linalg.norm(big_c) * np.linalg.norm(power) * np.linalg.norm(bb), np.finfo(float).tiny))
            power = power @ big_a
        out.append(worst)
    return out[0], out[1]


def random_sampled_data_plant(
    *, n: int, p: int, rng: np.random.Generator, q: int = 1, Ts: float = 0.5, stable: bool = True
) -> SampledDataPlant:
    """A random continuous plant with ``n`` states, ``p`` outputs, 1 input, ``q`` disturbances, 1 fault.

    With ``q = 1`` the lifted disturbance barely excites some directions within
    a sample and κ = cond(C X Cᵀ) can pass 1e10 already at ``n = p = 3``;
    ``q = n`` keeps it moderate (≤ ~1e6 at n = 16 in the timing runs).

    Eigenvalues ``−U(0.3, 2)`` or ``−U(0.3, 2) ± j·U(0.1, 1.5)`` in a random
    basis of condition ≤ 4; with ``|Im λ| < 1.5`` and ``Ts = 0.5`` the sampling is
    never pathological (that needs ``Ts·|Im(λ_i − λ_j)| = 2πk``).
    ``stable=False`` makes the first mode unstable (real part ``+U(0.06, 0.4)``).
    """
    blocks, k = [], 0
    while k < n:
        s = rng.uniform(0.3, 2.0) * (1 if stable or k else -0.2)
        if n - k >= 2 and rng.random() < 0.5:
            w = rng.uniform(0.1, 1.5)
            blocks.append(np.array([[-s, w], [-w, -s]]))
            k += 2
        else:
            blocks.append(np.array([[-s]]))
            k += 1
    qm, _ = np.linalg.qr(rng.standard_normal((n, n)))
    t = qm @ np.diag(rng.uniform(0.5, 2.0, n))
    a = t @ sla.block_diag(*blocks) @ np.linalg.inv(t)
    return SampledDataPlant.create(
        A=a,
        B=rng.standard_normal((n, 1)),
        E=rng.standard_normal((n, q)),
        Fx=rng.standard_normal((n, 1)),
        C=rng.standard_normal((p, n)),
        Ts=Ts,
    )
