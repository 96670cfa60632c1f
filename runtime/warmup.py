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
from fdisyn.runtime.schema import LIMITS

__all__ = ["MAX_WARMUP", "PINV_RTOL", "equilibrated_pinv", "information_pinv", "longest_warmup", "warmup_constants", "warmup_coefficients", "generator_warmup"]

MAX_WARMUP = 1000
"""Most warm-up samples of one generator: each is a constant ``Φ_k`` of the step."""

PINV_RTOL = 1e-10
"""Directions of the warm-up's information ``Σ Φ_kᵀ W Φ_k`` (scaled to a unit diagonal: :func:`equilibrated_pinv`)
below this fraction of its largest are not corrected: the residual does not see them over the warm-up (they are
unobservable, or decay before a sample shows them)."""


def equilibrated_pinv(a: np.ndarray, scale: np.ndarray | None = None) -> np.ndarray:
    """The pseudo-inverse of a positive semidefinite ``a`` after scaling it to a unit diagonal: ``S (S a S)⁺ S``,
    ``S = diag(d)^(-1/2)`` with ``d`` the diagonal of ``scale`` (default ``a``), zero where ``d`` is.

    A state in metres beside one in micrometres gives an information matrix whose eigenvalues spread by 10¹², and a
    relative cut-off on them would drop the small unit's direction as unseen. Scaled to a unit diagonal, the cut-off
    :data:`PINV_RTOL` is on how well the residual separates the directions, whatever their units. ``S (S a S)⁺ S``
    is ``a⁻¹`` for an invertible ``a``, and solves ``a δ = b`` for every ``b`` in its range otherwise.

    Parameters
    ----------
    a : numpy.ndarray
        A symmetric positive semidefinite matrix.
    scale : numpy.ndarray, optional
        The matrix whose diagonal sets ``S`` (``a`` itself by default).

    Returns
    -------
    numpy.ndarray
        ``S (S a S)⁺ S``.

    Examples
    --------
    >>> a = np.diag([1e12, 1.0])
    >>> np.allclose(equilibrated_pinv(a), np.diag([1e-12, 1.0]), rtol=1e-12, atol=0)
    True
    """
    d = np.diag(a if scale is None else scale).astype(float)
    s = np.where(d > 0, 1.0 / np.sqrt(np.where(d > 0, d, 1.0)), 0.0)
    scaled = s[:, None] * a * s[None, :]
    return s[:, None] * np.linalg.pinv(0.5 * (scaled + scaled.T), rcond=PINV_RTOL, hermitian=True) * s[None, :]


def information_pinv(info: np.ndarray, *, equilibrate: bool) -> np.ndarray:
    """The pseudo-inverse of a warm-up's symmetric information ``Σ Φ_kᵀ W Φ_k``: scaled to a unit diagonal
    (:func:`equilibrated_pinv`, a Beard filter's) or not (a linear generator's), directions below :data:`PINV_RTOL`
    of the largest left out.

    Parameters
    ----------
    info : numpy.ndarray
        The information (symmetric positive semidefinite).
    equilibrate : bool
        Scale it to a unit diagonal first.

    Returns
    -------
    numpy.ndarray
        Its pseudo-inverse.
    """
    return equilibrated_pinv(info) if equilibrate else np.linalg.pinv(info, rcond=PINV_RTOL, hermitian=True)


def longest_warmup(shapes: list[tuple[int, int]], budget: int | None = None) -> int:
    """The longest warm-up, common to generators of ``(n_state, n_residual)`` ``shapes``, whose constants stay
    within ``budget`` (:func:`warmup_coefficients`) and :data:`MAX_WARMUP`.

    Parameters
    ----------
    shapes : list of tuple of int
        Each generator's state and residual sizes.
    budget : int, optional
        The constants allowed (default ``LIMITS["warmup_coefficients"]``; a kind of straight-line step passes
        its own).

    Returns
    -------
    int
        The samples (0 when not even one fits).

    Examples
    --------
    >>> longest_warmup([(12, 7)] * 16, 50_000)  # the turbofan's grouped bank: (50 000 − 16·144) // (16·84)
    35
    """
    spare = (LIMITS["warmup_coefficients"] if budget is None else int(budget)) - sum(n * n for n, _ in shapes)
    return min(MAX_WARMUP, max(0, spare) // max(1, sum(n * r for n, r in shapes)))


def warmup_constants(
    Ar: np.ndarray, Cr: np.ndarray, warmup: int, weight: np.ndarray | None, *, equilibrate: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """``(G, M)`` of a warm-up: ``G[k] = Φ_kᵀ W`` (``Φ_k = Cr Ar^k``) for ``k < warmup``, what the ``k``-th
    sample's residual adds to the accumulator, and the correction ``M``.

    Parameters
    ----------
    Ar, Cr : numpy.ndarray
        The error dynamics and the residual's map of the state (a linear generator's ``Ar, Cr``; a Beard
        filter's ``A − L C, C``).
    warmup : int
        ``N ≥ 1``.
    weight : numpy.ndarray or None
        ``W`` (``n_residual`` square); ``None``: the identity.
    equilibrate : bool
        Invert the information scaled to a unit diagonal (:func:`equilibrated_pinv`), as a Beard filter does: the
        correction then does not depend on the states' units. Without it (a linear generator), directions below
        :data:`PINV_RTOL` of the largest unscaled information are left uncorrected.

    Returns
    -------
    tuple of numpy.ndarray
        ``G`` (``warmup × n_state × n_residual``) and ``M`` (``n_state × n_state``).

    Examples
    --------
    >>> phi, m = warmup_constants(np.array([[0.5]]), np.array([[2.0]]), 2, None)
    >>> phi.ravel().tolist(), m.round(6).tolist()  # G = Φ = [2, 1]; M = −0.25 / (4 + 1)
    ([2.0, 1.0], [[-0.05]])
    """
    n, ns = int(warmup), Ar.shape[0]
    w = np.eye(Cr.shape[0]) if weight is None else np.asarray(weight, dtype=float)
    gains = np.empty((n, ns, Cr.shape[0]))
    power = np.eye(ns)
    info = np.zeros((ns, ns))
    for k in range(n):
        phi = Cr @ power
        gains[k] = phi.T @ w
        info += gains[k] @ phi
        power = Ar @ power
    info = 0.5 * (info + info.T)
    return gains, -power @ information_pinv(info, equilibrate=equilibrate)


def warmup_coefficients(warmup: int, n_state: int, n_residual: int) -> int:
    """The constants of a warm-up of ``warmup`` samples (:func:`fdisyn.runtime.warmup.warmup_constants`): its
    gains and its correction, dense; 0 without a warm-up.

    Parameters
    ----------
    warmup, n_state, n_residual : int
        The warm-up's samples, the state's and the residual's sizes.

    Returns
    -------
    int
        ``warmup · n_state · n_residual + n_state²`` (0 when ``warmup`` is 0).
    """
    return warmup * n_state * n_residual + n_state * n_state if warmup else 0


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
    return warmup_constants(gen.Ar, gen.Cr, gen.warmup, weights[0] if weights else None)
