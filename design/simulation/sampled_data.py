"""Exact simulation of a sampled-data plant driven by continuous white noise
(Qiu, Wen & Jiang, Control Theory & Applications 27(8), 2010, eqs. (1)–(3)).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from fdisyn.models.sampled_data import SampledDataPlant
from fdisyn.models.sampling import van_loan
from fdisyn.numerics.linalg import as_matrix, psd_factor
from fdisyn.runtime.errors import ArgumentError, ShapeError

__all__ = ['SimulationResult', 'disturbance_factor', 'sampled_disturbance', 'simulate_sampled_data']


# ---------------------------------------------------------------------------
# Exact sampling of continuous white noise
# ---------------------------------------------------------------------------


def sampled_disturbance(
    *, plant: SampledDataPlant, steps: int, rng: np.random.Generator, intensity: object | None = None, z: np.ndarray | None = None
) -> np.ndarray:
    """``w_k = ∫_{k Ts}^{(k+1) Ts} e^{A((k+1) Ts − t)} E dβ(t)`` for ``k < steps``; shape ``(steps, n)``.

    ``d`` is continuous white noise with intensity (power spectral density)
    ``Σ_d`` (``intensity``, default ``I``; the paper's "variance 1"). The
    ``w_k`` are independent Gaussians with covariance
    ``∫₀^Ts e^{Aτ} E Σ_d Eᵀ e^{Aᵀτ} dτ`` (Van Loan), so the state at the sampling
    instants is exact — no intersample discretisation error. ``z`` (steps ×
    rank) replaces the standard normals drawn from ``rng``.
    """
    fac = disturbance_factor(plant, intensity)
    if int(steps) < 0:
        raise ArgumentError(f"steps must be ≥ 0; got {steps}")
    if z is not None and np.shape(z) != (int(steps), fac.shape[1]):
        raise ShapeError(f"draws have shape {np.shape(z)}; expected ({int(steps)}, {fac.shape[1]})")
    return (rng.standard_normal((int(steps), fac.shape[1])) if z is None else z) @ fac.T


def disturbance_factor(plant: SampledDataPlant, intensity: object | None = None) -> np.ndarray:
    """Full-column-rank factor of the covariance of :func:`sampled_disturbance`'s ``w_k``."""
    q = plant.E.shape[1]
    sig = np.eye(q) if intensity is None else as_matrix(intensity, "intensity", rows=q, cols=q)
    cov = van_loan(plant.A, plant.E @ sig @ plant.E.T, plant.Ts)
    return psd_factor(cov, "covariance of the sampled disturbance")


@dataclass(frozen=True, eq=False)
class SimulationResult:
    """Samples of the sampled-data plant: ``x(k Ts)`` and ``ψ(k) = C x(k Ts)``, ``k = 0..N−1``."""

    x: np.ndarray
    psi: np.ndarray


def simulate_sampled_data(
    *,
    plant: SampledDataPlant,
    v: object,
    rng: np.random.Generator,
    f: object | None = None,
    intensity: object | None = None,
    x0: object | None = None,
    draws: np.ndarray | None = None,
) -> SimulationResult:
    """Exact samples of eqs. (1)–(3): ``x(k+1) = A_D x + B_D v(k) + Fx_D f(k) + w_k``.

    ``v`` has shape ``(N, m)`` and is held (ZOH, eq. (3)); ``f`` has shape
    ``(N, n_f)`` and is read as piecewise constant on ``[k Ts, (k+1) Ts)``, which is
    exact for the paper's step fault at a sampling instant; ``d`` is
    continuous white noise of intensity ``intensity`` (default ``I``), sampled
    exactly by :func:`sampled_disturbance` (from ``draws`` when given).
    """
    vv = as_matrix(v, "v", cols=plant.m if np.ndim(np.asarray(v)) == 2 else 1)
    if vv.shape[1] != plant.m:
        raise ShapeError(f"v has {vv.shape[1]} columns; the plant has m = {plant.m} inputs")
    steps = vv.shape[0]
    nf = plant.Fx.shape[1]
    ff = np.zeros((steps, nf)) if f is None else as_matrix(f, "f", rows=steps, cols=nf if np.ndim(np.asarray(f)) == 2 else 1)
    if ff.shape != (steps, nf):
        raise ShapeError(f"f has shape {ff.shape}; expected ({steps}, {nf})")
    x = np.zeros(plant.n) if x0 is None else as_matrix(x0, "x0", rows=plant.n, cols=1)[:, 0]
    w = sampled_disturbance(plant=plant, steps=steps, rng=rng, intensity=intensity, z=draws)
    xs = np.empty((steps, plant.n))
    for k in range(steps):
        xs[k] = x
        x = plant.A_D @ x + plant.B_D @ vv[k] + plant.Fx_D @ ff[k] + w[k]
    return SimulationResult(x=xs, psi=xs @ plant.C.T)
