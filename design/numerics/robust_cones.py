"""The robust decision of a Beard detection filter under model error (He, Zhang & Wu, Journal of Astronautics, c. 1999).

A Beard filter ``x̂⁺ = A x̂ + B u + L (y − C x̂)`` keeps the residual ``ε = C e`` of fault ``j`` in the output
subspace ``S_j = C T_j`` of its detection space ``T_j`` (:mod:`fdisyn.numerics.detection_filter`). When the
true plant has ``A + δA``, ``‖δA‖₂ ≤ σ``, the error dynamics ``G = A − L C`` become ``G + δG`` with ``δG = δA``
(the paper's *implicit* uncertainty: the eigenvectors move, and the residual leaves ``S_j``).

**The implicit threshold.** First-order eigenvector perturbation (Wilkinson, *The Algebraic Eigenvalue
Problem*, 1965, ch. 2; the paper's theorem on ``Y_th``): for a simple eigenvalue ``λ_m`` with right and left
eigenvectors ``v_m``, ``w_m``,

    δv_m = Σ_{k≠m} (w_kᴴ δG v_m) / ((λ_m − λ_k) w_kᴴ v_k) · v_k.

The components along eigenvectors inside ``T_j`` stay in ``T_j``, so ``C`` maps them into ``S_j``: only the
rest tilts the residual. Summed over the eigenvectors outside ``T_j`` the expansion is the *reduced
resolvent* of ``G`` on its invariant complement of ``T_j``. With ``Q_c`` an orthonormal basis of ``T_j^⊥`` and
``G_c = Q_cᵀ G Q_c`` (``G`` is block upper triangular in the basis ``[T_j, Q_c]`` because ``T_j`` is invariant),

    (I − P_j) C δv_m = (I − P_j) C Q_c (λ_m I − G_c)⁻¹ Q_cᵀ δG v_m               (first order)

(``P_j`` the orthogonal projector onto ``S_j``; the ``T_j``-part of the complement basis is mapped into
``S_j`` and drops out). For ``‖δG‖₂ ≤ σ_d``, the angle between ``C ṽ_m`` and ``S_j`` is then at most

    b_m = σ_d · ‖(I − P_j) C Q_c (λ_m I − G_c)⁻¹ Q_cᵀ‖₂ · ‖v_m‖ / ‖C v_m‖,

a bound attained to first order by the rank-one ``δG = σ_d z v_mᴴ / ‖v_m‖`` (``z`` the leading right singular
vector of the matrix in the norm). ``Y_th,j`` is the largest ``b_m`` over the eigenvectors of ``T_j`` — the paper's bound — times
``1 + 2η`` (:data:`SECOND_ORDER_FACTOR`), a margin for the second-order remainder. The formula needs
no eigenvector outside ``T_j`` and no diagonalisable complement — only ``λ_m ∉ σ(G_c)``: eigenvalues shared by
``T_j`` and its complement make the perturbed eigen-directions arbitrary (not Lipschitz in ``δA``), and the
cone is then a half-space, ``Y_th,j = π/2``. Eigenvalues repeated *inside* ``T_j`` are harmless.

**Sampling.** A continuous plant is designed on ``A_d = e^{A Ts}``; its model error maps to
``δA_d = ∫₀^Ts e^{As} δA e^{A(Ts−s)} ds + O(σ²)`` (the Fréchet derivative of the exponential), whence
``‖δA_d‖₂ ≤ σ_d = σ ∫₀^Ts ‖e^{As}‖₂ ‖e^{A(Ts−s)}‖₂ ds`` (:func:`sampled_model_error`).

**The check.** The bound is first order. :func:`sampled_angles` draws model errors of norm ``σ`` (random
directions and the first-order worst cases), forms the exact ``G̃ = e^{(A+δA)Ts} − L C``, finds its invariant
subspace continuing ``T_j`` (Stewart's iteration) and measures the exact angle between ``C ṽ`` and ``S_j`` for every
eigenvector ``ṽ`` in it. The bound is used only where Stewart's theorem guarantees that subspace
(:data:`STEWART_LIMIT`); beyond, ``Y_th,j = π/2``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
from fdisyn.numerics.linalg import as_matrix, as_square
from fdisyn.runtime.errors import ArgumentError, ShapeError

__all__ = [
    "ImplicitBound",
    "sampled_model_error",
    "output_subspaces",
    "subspace_angle",
    "block_eigenpairs",
    "implicit_thresholds",
    "sampled_angles",
]

HALF_PI = 0.5 * np.pi

STEWART_LIMIT = 0.25
"""Stewart's theorem (SIAM Review 15(4), 1973, thm. 4.1; Stewart & Sun, *Matrix Perturbation Theory*, 1990,
thm. V.2.7): in the basis ``[T_j, Q_c]``, ``G = [[G_T, H], [0, G_c]]``; for ``‖δG‖₂ ≤ σ_d`` let
``δ = sep(G_T, G_c) − 2σ_d``. If ``η = σ_d (‖H‖₂ + σ_d) / δ² < 1/4``, ``G + δG`` has an invariant subspace
``span(T_j + Q_c P)`` with ``‖P‖₂ ≤ 2σ_d/δ``: the residual directions of fault ``j`` continue those of ``T_j``.
Beyond, they need not, and the cone is a half-space."""

SECOND_ORDER_FACTOR = 2.0
"""``Y_th = b · (1 + 2η)``: the first-order bound with a margin for the second-order remainder, whose small
parameter is Stewart's ``η``. Over seeded random plants (``tests/design/test_robust_cones.py``) the exact angle
stayed below ``b (1 + 0.8 η)`` for ``η ≤ 0.2``."""

_SHARED_RTOL = 1e-9
"""Relative distance below which an eigenvalue of ``T_j`` counts as shared with its complement."""


@dataclass(frozen=True)
class ImplicitBound:
    """The first-order implicit thresholds of a Beard filter (module docstring)."""

    Y: np.ndarray
    """``Y_th,j = b_max (1 + 2η)`` per fault (radians, at most π/2; π/2 outside Stewart's range)."""
    coefficient: np.ndarray
    """``Y_th,j / σ_d`` before the cap (``inf`` when an eigenvalue is shared): the bound per unit model error."""
    eigenvalues: tuple[np.ndarray, ...]
    """The eigenvalues of ``G`` on each ``T_j`` (complex)."""
    per_eigenvector: tuple[np.ndarray, ...]
    """``b_m / σ_d`` per eigenvector of each ``T_j``."""
    worst_directions: tuple[tuple[np.ndarray, np.ndarray], ...]
    """Per fault, ``(z, v)``: the rank-one ``δG ∝ z vᴴ`` that attains its largest ``b_m`` to first order."""
    sigma_d: float
    """The model-error bound on the sampled ``A`` the thresholds use."""
    separation: np.ndarray
    """``sep(G_T, G_c)`` per fault (Stewart): the smallest singular value of ``X ↦ G_c X − X G_T``."""
    eta: np.ndarray
    """Stewart's ``η`` per fault (:data:`STEWART_LIMIT`): the small parameter of the expansion."""
    in_range: np.ndarray
    """Per fault, whether ``η < 1/4``, the range where the perturbed subspace provably continues ``T_j``;
    outside it ``Y_th,j = π/2``."""


def sampled_model_error(A: object, Ts: float | None, sigma: float) -> float:
    """``σ_d``: a first-order bound on ``‖δA_d‖₂`` when ``‖δA‖₂ ≤ σ`` (``Ts = None``: a discrete ``A``, ``σ_d = σ``).

    ``σ ∫₀^Ts ‖e^{As}‖₂ ‖e^{A(Ts−s)}‖₂ ds`` by 16-point Gauss–Legendre quadrature: the integrand is smooth (a
    product of norms of matrix exponentials over one sample), and ``σ·Ts`` is its value for ``A = 0``.
    """
    a = as_square(A, "A")
    if not np.isfinite(sigma) or sigma < 0:
        raise ArgumentError(f"sigma must be a finite number ≥ 0; got {sigma!r}")
    if Ts is None:
        return float(sigma)
    nodes, weights = np.polynomial.legendre.leggauss(16)
    s = 0.5 * Ts * (nodes + 1.0)
    vals = [np.linalg.norm(sla.expm(a * si), 2) * np.linalg.norm(sla.expm(a * (Ts - si)), 2) for si in s]
    return float(sigma * 0.5 * Ts * np.dot(weights, vals))


def output_subspaces(C: object, spaces: Sequence[np.ndarray], *, rtol: float = 1e-9) -> tuple[np.ndarray, ...]:
    """Orthonormal bases of ``S_j = C T_j`` (the residual subspaces; a cone's axis when one-dimensional)."""
    c = as_matrix(C, "C")
    out = []
    for j, t in enumerate(spaces):
        img = c @ np.asarray(t, dtype=float)
        u, s, _ = np.linalg.svd(img, full_matrices=False)
        r = int(np.sum(s > rtol * max(float(s[0]) if s.size else 0.0, np.finfo(float).tiny)))
        if r == 0:
            raise ArgumentError(f"the detection space of fault {j + 1} has no output image (C T = 0)")
        out.append(u[:, :r])
    return tuple(out)


def subspace_angle(x: np.ndarray, basis: np.ndarray) -> float:
    """The angle (radians, in [0, π/2]) between the vector ``x`` and the span of the orthonormal ``basis``.

    ``atan2(‖(I − P) x‖, ‖P x‖)``: accurate for small and large angles alike; π/2 for ``x = 0``.
    """
    x = np.asarray(x)
    inside = basis @ (basis.T @ x)
    along = float(np.linalg.norm(inside))
    across = float(np.linalg.norm(x - inside))
    if along == 0.0 and across == 0.0:
        return HALF_PI
    return float(np.arctan2(across, along))


def block_eigenpairs(G: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues and unit eigenvectors of ``G`` on its invariant subspace ``T`` (orthonormal columns)."""
    gj = T.T @ G @ T
    lam, a = np.linalg.eig(gj)
    v = T @ a
    return lam, v / np.linalg.norm(v, axis=0)


def _complement(T: np.ndarray) -> np.ndarray:
    q, _ = np.linalg.qr(T, mode="complete")
    return q[:, T.shape[1] :]


def implicit_thresholds(G: object, C: object, spaces: Sequence[np.ndarray], sigma_d: float) -> ImplicitBound:
    """``Y_th,j`` for every fault ``j`` of a Beard filter with error dynamics ``G`` (module docstring).

    ``spaces``: orthonormal bases of the detection spaces ``T_j`` (each ``G``-invariant). Returns the bounds,
    capped at π/2, with their per-eigenvector parts and the first-order worst-case directions.
    """
    g = as_square(G, "G")
    c = as_matrix(C, "C", cols=g.shape[0])
    if not np.isfinite(sigma_d) or sigma_d < 0:
        raise ArgumentError(f"sigma_d must be a finite number ≥ 0; got {sigma_d!r}")
    axes = output_subspaces(c, spaces)
    scale = max(float(np.linalg.norm(g, 2)), np.finfo(float).tiny)
    ys, coefs, lams, parts, worst, seps, etas, oks = [], [], [], [], [], [], [], []
    for t, s in zip(spaces, axes, strict=True):
        t = np.asarray(t, dtype=float)
        if t.ndim != 2 or t.shape[0] != g.shape[0]:
            raise ShapeError(f"a detection space has shape {t.shape}; expected ({g.shape[0]}, d)")
        lam, v = block_eigenpairs(g, t)
        qc = _complement(t)
        gc = qc.T @ g @ qc
        proj = np.eye(c.shape[0]) - s @ s.T
        mu = np.linalg.eigvals(gc) if gc.size else np.zeros(0)
        per = np.empty(lam.size)
        best = (-1.0, np.zeros(c.shape[1]), np.zeros(g.shape[0]))
        for i, (lm, vm) in enumerate(zip(lam, v.T, strict=True)):
            if mu.size and float(np.min(np.abs(mu - lm))) <= _SHARED_RTOL * scale:
                per[i] = np.inf
                continue
            if not gc.size:
                per[i] = 0.0
                continue
            m = proj @ c @ qc @ np.linalg.solve(lm * np.eye(gc.shape[0]) - gc, qc.T)
            u_, sv, vh = np.linalg.svd(m)
            cv = float(np.linalg.norm(c @ vm))
            per[i] = float(sv[0]) / cv if cv > 0 else np.inf
            if per[i] > best[0]:
                best = (per[i], vh[0].conj(), vm)
        coef = float(np.max(per)) if per.size else 0.0
        sep = _sep(t.T @ g @ t, gc)
        gap = sep - 2.0 * sigma_d
        eta = sigma_d * (float(np.linalg.norm(t.T @ g @ qc, 2)) + sigma_d) / gap**2 if gap > 0 and gc.size else (0.0 if not gc.size else np.inf)
        ok = eta < STEWART_LIMIT
        coefs.append(coef)
        seps.append(sep)
        etas.append(eta)
        oks.append(ok)
        ys.append(min(HALF_PI, coef * sigma_d * (1.0 + SECOND_ORDER_FACTOR * eta)) if np.isfinite(coef) and ok else HALF_PI)
        lams.append(lam)
        parts.append(per)
        worst.append((best[1], best[2]))
    return ImplicitBound(
        Y=np.asarray(ys), coefficient=np.asarray(coefs), eigenvalues=tuple(lams), per_eigenvector=tuple(parts),
        worst_directions=tuple(worst), sigma_d=float(sigma_d), separation=np.asarray(seps), eta=np.asarray(etas), in_range=np.asarray(oks, dtype=bool),
    )


def _sep(gt: np.ndarray, gc: np.ndarray) -> float:
    """``sep(G_T, G_c) = σ_min(I ⊗ G_c − G_Tᵀ ⊗ I)`` (Stewart & Sun, *Matrix Perturbation Theory*, 1990, V.2)."""
    if not gc.size:
        return float("inf")
    op = np.kron(np.eye(gt.shape[0]), gc) - np.kron(gt.T, np.eye(gc.shape[0]))
    return float(np.linalg.svd(op, compute_uv=False)[-1])


def _continued_subspace(gt: np.ndarray, t: np.ndarray, qc: np.ndarray, iterations: int = 100) -> np.ndarray | None:
    """``P`` with ``span(T + Q_c P)`` invariant under ``G̃``: the invariant subspace continuing ``T`` (``None``: none found).

    In the basis ``[T, Q_c]`` with blocks ``A_ij`` of ``G̃``, ``A₂₁ + A₂₂ P − P A₁₁ − P A₁₂ P = 0``; solved by the
    fixed point ``A₂₂ P_{k+1} − P_{k+1} (A₁₁ + A₁₂ P_k) = −A₂₁`` from ``P₀ = 0`` (Stewart's iteration), which
    converges to the solution nearest 0 inside Stewart's range.
    """
    a11, a12 = t.T @ gt @ t, t.T @ gt @ qc
    a21, a22 = qc.T @ gt @ t, qc.T @ gt @ qc
    p = np.zeros((qc.shape[1], t.shape[1]))
    scale = max(float(np.linalg.norm(gt, 2)), 1e-300)
    for _ in range(iterations):
        try:
            nxt = sla.solve_sylvester(a22, -(a11 + a12 @ p), -a21)
        except (np.linalg.LinAlgError, ValueError):
            return None
        if not np.all(np.isfinite(nxt)):
            return None
        step = float(np.linalg.norm(nxt - p))
        p = nxt
        if step <= 1e-14 * max(1.0, float(np.linalg.norm(p))):
            break
    res = a21 + a22 @ p - p @ a11 - p @ a12 @ p
    return p if float(np.linalg.norm(res)) <= 1e-10 * scale * max(1.0, float(np.linalg.norm(p))) else None


def _perturbed_block_angles(gt: np.ndarray, c: np.ndarray, spaces: Sequence[np.ndarray], axes: Sequence[np.ndarray]) -> np.ndarray:
    """Per fault, the largest exact angle between ``C ṽ`` and ``S_j`` over the eigenvectors ``ṽ`` of ``G̃`` in the
    invariant subspace continuing ``T_j`` (:func:`_continued_subspace`; π/2 when there is none)."""
    out = []
    for t, s in zip(spaces, axes, strict=True):
        qc = _complement(t)
        p = _continued_subspace(gt, t, qc)
        if p is None:
            out.append(HALF_PI)
            continue
        basis = t + qc @ p
        lam, a = np.linalg.eig(t.T @ gt @ t + (t.T @ gt @ qc) @ p)
        angles = []
        for i in range(lam.size):
            cv = c @ (basis @ a[:, i])
            # a complex eigenvector: its real and imaginary parts span the real invariant plane
            parts = [cv.real, cv.imag] if np.linalg.norm(cv.imag) > 1e-12 * np.linalg.norm(cv) else [cv.real]
            angles.append(max(subspace_angle(x, s) for x in parts))
        out.append(max(angles) if angles else 0.0)
    return np.asarray(out)


def sampled_angles(
    A: object,
    Ts: float | None,
    L: object,
    C: object,
    spaces: Sequence[np.ndarray],
    bound: ImplicitBound,
    sigma: float,
    *,
    draws: int = 200,
    seed: int = 0,
) -> np.ndarray:
    """Exact residual-direction angles under sampled model errors ``‖δA‖₂ = σ`` (``draws + k`` rows × ``k`` faults).

    ``δA``: ``draws`` Gaussian directions scaled to spectral norm ``σ``, then, per fault, the first-order worst
    case ``σ · Re(z vᴴ)/‖Re(z vᴴ)‖₂`` of :attr:`ImplicitBound.worst_directions` (``Ts ≠ None``: ``δA`` on the
    continuous ``A``, exactly sampled). Row ``r`` holds, per fault, the largest exact angle between ``C ṽ`` and
    ``S_j`` over the eigenvectors of the invariant subspace continuing ``T_j`` (:func:`_perturbed_block_angles`).
    """
    a = as_square(A, "A")
    lm = as_matrix(L, "L", rows=a.shape[0])
    c = as_matrix(C, "C", cols=a.shape[0])
    axes = output_subspaces(c, spaces)
    ad = sla.expm(a * Ts) if Ts is not None else a
    rng = np.random.default_rng(seed)
    deltas = []
    for _ in range(draws):
        d = rng.standard_normal(a.shape)
        deltas.append(sigma * d / np.linalg.norm(d, 2))
    for z, v in bound.worst_directions:
        d = np.real(np.outer(z, v.conj()))
        nd = float(np.linalg.norm(d, 2))
        if nd > 0:
            deltas.append(sigma * d / nd)
    rows = []
    for d in deltas:
        gt = (sla.expm((a + d) * Ts) if Ts is not None else ad + d) - lm @ c
        rows.append(_perturbed_block_angles(gt, c, [np.asarray(t, dtype=float) for t in spaces], axes))
    return np.asarray(rows)
