"""A linear generator's warm-up: its initial state by least squares over its first valid samples.

A generator starts at the equilibrium of its first valid sample, ``ξ₀ = Xu u₀ + Xy y₀``. Its initial error
``δ = ξ₀ − ξ₀*`` (``ξ*`` the trajectory whose residual is noise alone) moves the residual by ``r_k − r_k* = Φ_k δ``,
``Φ_k = Cr Ar^k``: one noisy sample's equilibrium of a slow generator, or a plant already moving when the
diagnoser starts, makes that transient many times the noise. Over the first ``N = warmup`` valid samples the
step accumulates ``b = Σ_{k<N} Φ_kᵀ W r_k`` and, after the ``N``-th, moves the state by ``M b`` with
``M = −Ar^N (Σ_{k<N} Φ_kᵀ W Φ_k)⁺``: the least-squares estimate of ``δ``, propagated to the sample after the
warm-up, removed. The statistics and the decision are held until then. ``W`` is the generator's first
statistic's weight (the inverse residual covariance; the identity without one).
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["MAX_WARMUP", "PINV_RTOL", "warmup_constants", "generator_warmup"]

MAX_WARMUP = 1000
"""Most warm-up samples of one generator: each is a constant ``Φ_k`` of the step."""

PINV_RTOL = 1e-10
"""Directions of the warm-up's information ``Σ Φ_kᵀ W Φ_k`` below this fraction of its largest are not corrected:
the residual does not see them over the warm-up (they are unobservable, or decay before a sample shows them)."""


def warmup_constants(gen: Any, weight: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """``(G, M)`` of a generator's warm-up: ``G[k] = Φ_kᵀ W`` (``Φ_k = Cr Ar^k``) for ``k < warmup``, what the
    ``k``-th sample's residual adds to the accumulator, and the correction ``M``.

    Parameters
    ----------
    gen : Generator
        A generator with ``warmup ≥ 1``.
    weight : numpy.ndarray or None
        ``W`` (``n_residual`` square); ``None``: the identity.

    Returns
    -------
    tuple of numpy.ndarray
        ``G`` (``warmup × n_state × n_residual``) and ``M`` (``n_state × n_state``).

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> g = SimpleNamespace(Ar=np.array([[0.5]]), Cr=np.array([[2.0]]), warmup=2)
    >>> phi, m = warmup_constants(g, None)
    >>> phi.ravel().tolist(), m.round(6).tolist()  # G = Φ = [2, 1]; M = −0.25 / (4 + 1)
    ([2.0, 1.0], [[-0.05]])
    """
    n, ns = int(gen.warmup), gen.Ar.shape[0]
    w = np.eye(gen.Cr.shape[0]) if weight is None else np.asarray(weight, dtype=float)
    gains = np.empty((n, ns, gen.Cr.shape[0]))
    power = np.eye(ns)
    info = np.zeros((ns, ns))
    for k in range(n):
        phi = gen.Cr @ power
        gains[k] = phi.T @ w
        info += gains[k] @ phi
        power = gen.Ar @ power
    info = 0.5 * (info + info.T)
    return gains, -power @ np.linalg.pinv(info, rcond=PINV_RTOL, hermitian=True)


def generator_warmup(gf: Any, g: int) -> tuple[np.ndarray, np.ndarray] | None:
    """:func:`warmup_constants` of a linear gain file's generator ``g`` with its first statistic's weight, as the
    NumPy reference and the generated step both use them; ``None`` for a generator without a warm-up.

    Parameters
    ----------
    gf : GainFile
        A ``linear`` gain file.
    g : int
        The generator's index.

    Returns
    -------
    tuple of numpy.ndarray or None
        ``(G, M)``.
    """
    gen = gf.generators[g]
    if not gen.warmup:
        return None
    weights = [ev.W for ev in gf.evaluators if ev.generator == g]
    return warmup_constants(gen, weights[0] if weights else None)
