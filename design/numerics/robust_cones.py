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
vector of the matrix in the norm). The largest ``b_m`` over the eigenvectors of ``T_j`` is the paper's first-order
``Y_th,j`` (:attr:`ImplicitBound.first_order`). The formula needs no eigenvector outside ``T_j`` and no diagonalisable
complement — only ``λ_m ∉ σ(G_c)``: eigenvalues shared by ``T_j`` and its complement make the perturbed
eigen-directions arbitrary (not Lipschitz in ``δA``), and the cone is then a half-space, ``Y_th,j = π/2``.

**The guaranteed threshold.** A first-order bound can be exceeded at finite ``σ``: the denominator ``‖C ṽ‖``
shrinks, and close eigenvalues inside ``T_j`` mix its eigenvectors. The threshold the filter uses bounds the whole
invariant subspace continuing ``T_j`` instead of single eigenvectors (Stewart, SIAM Review 15(4), 1973, thm. 4.1;
Stewart & Sun, *Matrix Perturbation Theory*, 1990, thm. V.2.7). In the basis ``[T_j, Q_c]``,
``G = [[G_T, H], [0, G_c]]`` and ``δG = [[E₁₁, E₁₂], [E₂₁, E₂₂]]``; the perturbed subspace is ``span(T_j + Q_c P)``
with ``𝒯(P) = G_c P − P G_T = −E₂₁ − E₂₂ P + P E₁₁ + P (H + E₁₂) P``. With ``sep = σ_min(𝒯)`` (Frobenius norm),
``γ = ‖E₂₁‖_F ≤ σ_d √min(d, n − d)``, ``δ = sep − 2σ_d`` and ``κ = γ (‖H‖₂ + σ_d) / δ² < 1/4``, the solution
nearest 0 has ``‖P‖_F ≤ p = 2γ / (δ (1 + √(1 − 4κ)))``; its first-order part ``P₁ = −𝒯⁻¹(E₂₁)`` differs from it by at
most ``r = (2σ_d p + (‖H‖₂ + σ_d) p²) / sep``. Every vector ``x = (T_j + Q_c P) a`` of the subspace (so every
perturbed eigenvector, real and imaginary parts alike) then has, with ``Π = I − P_j``,

    tan ∠(C x, S_j) ≤ (γ ‖(I ⊗ Π C Q_c) 𝒯⁻¹‖₂ + ‖Π C Q_c‖₂ r) / (f_j − ‖P_j C Q_c‖₂ p),

``f_j`` a lower bound on ``‖C T_j a‖`` over the unit eigenvectors ``a`` of the perturbed block
``G_T + E₁₁ + (H + E₁₂) P``: ``σ_min(C T_j)``, or, when ``C T_j`` is rank-deficient (a fault in ``ker C``), a
Bauer–Fike bound on how far those eigenvectors move (:func:`_image_floor`). That is ``Y_th,j``
(:attr:`ImplicitBound.Y`); ``π/2`` when ``κ ≥ 1/4`` or the denominator is not positive. For a one-dimensional
``T_j`` its first-order term is exactly the paper's ``b``. For a plane it also covers mixtures of the block's
eigenvectors (``√2`` more conservative through ``γ``): with ``C T_j`` of rank one and close eigenvalues, those
mixtures turn the residual hundreds of times further than the per-eigenvector bound says.

**Sampling.** A continuous plant is designed on ``A_d = e^{A Ts}``; its model error maps to
``δA_d = ∫₀^Ts e^{As} δA e^{A(Ts−s)} ds + O(σ²)`` (the Fréchet derivative of the exponential), whence
``‖δA_d‖₂ ≤ σ_d = σ ∫₀^Ts ‖e^{As}‖₂ ‖e^{A(Ts−s)}‖₂ ds`` (:func:`sampled_model_error`).

**The check.** The bound is first order. :func:`sampled_angles` draws model errors of norm ``σ`` (random
directions and the first-order worst cases), forms the exact ``G̃ = e^{(A+δA)Ts} − L C``, finds its invariant
subspace continuing ``T_j`` (Stewart's iteration) and measures the exact angle between ``C ṽ`` and ``S_j`` for every
eigenvector ``ṽ`` in it: a check of the guaranteed threshold and a measure of how tight it is.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
from fdisyn.numerics.linalg import as_matrix, as_square, orth_complement
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
"""Stewart's condition ``κ < 1/4`` (module docstring): below it ``G + δG`` has an invariant subspace continuing
``T_j`` for every ``‖δG‖₂ ≤ σ_d``; beyond, the residual directions of fault ``j`` need not continue, and the cone is
a half-space."""

_SHARED_RTOL = 1e-6
"""Relative distance (to ``‖G‖``) below which an eigenvalue of ``T_j`` counts as shared with its complement. An
eigenvalue that both share is often defective (the plain filter puts every eigenvalue at the decay bound), and an
eigen-decomposition splits it by about ``√ε ‖G‖`` times its coupling: measured 2.7e-8 relative on a plain filter,
where the LU of ``λ I − G_c`` was exactly singular under one BLAS kernel and merely ill-conditioned under
another. A distinct eigenvalue this close would make the cone a half-space anyway."""


@dataclass(frozen=True)
class ImplicitBound:
    """The first-order implicit thresholds of a Beard filter (module docstring)."""

    Y: np.ndarray
    """The guaranteed ``Y_th,j`` per fault (radians, at most π/2; π/2 outside Stewart's range)."""
    first_order: np.ndarray
    """The paper's first-order ``Y_th,j = σ_d · max_m b_m / σ_d`` per fault (radians, at most π/2)."""
    coefficient: np.ndarray
    """The guaranteed bound per unit model error as ``σ_d → 0``, ``√min(d, n−d) ‖(I ⊗ Π C Q_c) 𝒯⁻¹‖₂ / f_j``
    (``inf`` when an eigenvalue is shared): ``max_m b_m / σ_d`` for a one-dimensional ``T_j``."""
    eigenvalues: tuple[np.ndarray, ...]
    """The eigenvalues of ``G`` on each ``T_j`` (complex)."""
    per_eigenvector: tuple[np.ndarray, ...]
    """``b_m / σ_d`` per eigenvector of each ``T_j``."""
    worst_directions: tuple[tuple[np.ndarray, ...], ...]
    """Per fault, the model-error directions ``δG`` (complex; their real parts are used) that attain, to first order,
    each eigenvector's ``b_m`` (rank one, ``z v_mᴴ``) and, for a plane or larger ``T_j``, the numerator of the
    guaranteed bound (``Q_c E₂₁ T_jᵀ``)."""
    sigma_d: float
    """The model-error bound on the sampled ``A`` the thresholds use."""
    separation: np.ndarray
    """``sep(G_T, G_c)`` per fault (Stewart): the smallest singular value of ``X ↦ G_c X − X G_T``."""
    eta: np.ndarray
    """Stewart's ``κ`` per fault (:data:`STEWART_LIMIT`): the small parameter of the expansion."""
    in_range: np.ndarray
    """Per fault, whether ``κ < 1/4``, the range where the perturbed subspace provably continues ``T_j``;
    outside it ``Y_th,j = π/2``."""


def sampled_model_error(A: object, Ts: float | None, sigma: float) -> float:
    """``σ_d``: a bound on ``‖e^{(A+δA)Ts} − e^{A Ts}‖₂`` when ``‖δA‖₂ ≤ σ`` (``Ts = None``: a discrete ``A``, ``σ_d = σ``).

    ``e^{(A+E)Ts} − e^{ATs} = ∫₀^Ts e^{A(Ts−s)} E e^{(A+E)s} ds`` and, by Grönwall's inequality with
    ``M = e^{max(μ₂(A), 0) Ts} ≥ ‖e^{As}‖₂`` on ``[0, Ts]`` (``μ₂`` the logarithmic norm),
    ``‖e^{(A+E)s}‖₂ ≤ ‖e^{As}‖₂ + σ s M² e^{σ s}``; hence

        σ_d = σ ∫₀^Ts ‖e^{A(Ts−s)}‖₂ (‖e^{As}‖₂ + σ s M² e^{σ s}) ds,

    whose first-order part is the norm bound of the exponential's Fréchet derivative. 16-point Gauss–Legendre
    quadrature: the integrand is smooth over one sample, and ``σ·Ts`` is its value for ``A = 0`` to first order.
    """
    a = as_square(A, "A")
    if not np.isfinite(sigma) or sigma < 0:
        raise ArgumentError(f"sigma must be a finite number ≥ 0; got {sigma!r}")
    if Ts is None:
        return float(sigma)
    mu = float(np.max(np.linalg.eigvalsh(0.5 * (a + a.T))))
    big_m = float(np.exp(max(mu, 0.0) * Ts))
    nodes, weights = np.polynomial.legendre.leggauss(16)
    s = 0.5 * Ts * (nodes + 1.0)
    vals = [
        np.linalg.norm(sla.expm(a * (Ts - si)), 2) * (np.linalg.norm(sla.expm(a * si), 2) + sigma * si * big_m**2 * np.exp(sigma * si))
        for si in s
    ]
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


def implicit_thresholds(G: object, C: object, spaces: Sequence[np.ndarray], sigma_d: float) -> ImplicitBound:
    """``Y_th,j`` for every fault ``j`` of a Beard filter with error dynamics ``G`` (module docstring).

    ``spaces``: orthonormal bases of the detection spaces ``T_j`` (each ``G``-invariant). Returns the guaranteed
    bounds and the paper's first-order ones, capped at π/2, with their per-eigenvector parts and the first-order
    worst-case directions.
    """
    g = as_square(G, "G")
    c = as_matrix(C, "C", cols=g.shape[0])
    if not np.isfinite(sigma_d) or sigma_d < 0:
        raise ArgumentError(f"sigma_d must be a finite number ≥ 0; got {sigma_d!r}")
    axes = output_subspaces(c, spaces)
    scale = max(float(np.linalg.norm(g, 2)), np.finfo(float).tiny)
    ys, firsts, coefs, lams, parts, worst, seps, etas = [], [], [], [], [], [], [], []
    for t, s in zip(spaces, axes, strict=True):
        t = np.asarray(t, dtype=float)
        if t.ndim != 2 or t.shape[0] != g.shape[0]:
            raise ShapeError(f"a detection space has shape {t.shape}; expected ({g.shape[0]}, d)")
        lam, v = block_eigenpairs(g, t)
        qc = orth_complement(t)
        gt, h, gc = t.T @ g @ t, t.T @ g @ qc, qc.T @ g @ qc
        across = (np.eye(c.shape[0]) - s @ s.T) @ c @ qc
        mu = np.linalg.eigvals(gc) if gc.size else np.zeros(0)
        shared = bool(mu.size) and any(float(np.min(np.abs(mu - lm))) <= _SHARED_RTOL * scale for lm in lam)
        # the paper's first-order bound, per eigenvector (Wilkinson)
        per = np.zeros(lam.size)
        directions: list[np.ndarray] = []
        for i, (lm, vm) in enumerate(zip(lam, v.T, strict=True)):
            if shared or not gc.size:
                per[i] = np.inf if shared else 0.0
                continue
            try:
                _, sv, vh = np.linalg.svd(across @ np.linalg.solve(lm * np.eye(gc.shape[0]) - gc, qc.T))
            except np.linalg.LinAlgError:  # λ is an eigenvalue of G_c to the last bit: shared
                per[i] = np.inf
                continue
            cv = float(np.linalg.norm(c @ vm))
            per[i] = float(sv[0]) / cv if cv > 0 else np.inf
            directions.append(np.outer(vh[0].conj(), vm.conj()))
        # the guaranteed bound on the continued subspace (Stewart)
        sep = _sep(gt, gc)
        op_norm, direction = _first_order_subspace(gt, gc, across, qc, t)
        if direction is not None and t.shape[1] > 1:  # for a line it is the eigenvector's direction
            directions.append(direction)
        d_, m_ = t.shape[1], gc.shape[0]
        floor = _image_floor(gt, c @ t, 0.0)
        coef = float(np.sqrt(min(d_, m_)) * op_norm / floor) if floor > 0 and np.isfinite(op_norm) else (0.0 if m_ == 0 else float("inf"))
        y, eta = (_subspace_bound(gt, h, c @ t, op_norm, across, s.T @ c @ qc, m_, sep, sigma_d) if np.isfinite(op_norm)
                  else (HALF_PI, float("inf")))
        if shared:
            coef, y = np.inf, (HALF_PI if sigma_d > 0 else 0.0)
        first = float(np.max(per)) if per.size else 0.0
        coefs.append(coef)
        seps.append(sep)
        etas.append(eta)
        ys.append(y)
        firsts.append(min(HALF_PI, first * sigma_d) if np.isfinite(first) else HALF_PI)
        lams.append(lam)
        parts.append(per)
        worst.append(tuple(directions))
    etas_a = np.asarray(etas)
    return ImplicitBound(
        Y=np.asarray(ys), first_order=np.asarray(firsts), coefficient=np.asarray(coefs), eigenvalues=tuple(lams),
        per_eigenvector=tuple(parts), worst_directions=tuple(worst), sigma_d=float(sigma_d), separation=np.asarray(seps),
        eta=etas_a, in_range=etas_a < STEWART_LIMIT,
    )


def _first_order_subspace(gt: np.ndarray, gc: np.ndarray, across: np.ndarray, qc: np.ndarray, t: np.ndarray) -> tuple[float, np.ndarray | None]:
    """``‖(I ⊗ Π C Q_c) 𝒯⁻¹‖₂`` (the numerator of the guaranteed bound per unit ``γ``) and the ``δG = Q_c E₂₁ Tᵀ``
    that attains it (``inf, None`` when ``𝒯`` is singular; ``0, None`` when ``T`` has no complement)."""
    d, m = gt.shape[0], gc.shape[0]
    if m == 0:
        return 0.0, None
    sylvester = np.kron(np.eye(d), gc) - np.kron(gt.T, np.eye(m))
    try:
        op = np.kron(np.eye(d), across) @ np.linalg.inv(sylvester)
    except np.linalg.LinAlgError:
        return float("inf"), None
    _, sv, vh = np.linalg.svd(op)
    return float(sv[0]), qc @ vh[0].reshape(m, d, order="F") @ t.T


def _subspace_bound(
    gt: np.ndarray, h: np.ndarray, ct: np.ndarray, op_norm: float, across: np.ndarray, along: np.ndarray, m: int, sep: float, sigma_d: float
) -> tuple[float, float]:
    """The guaranteed ``Y_th`` of one detection space and Stewart's ``κ`` (module docstring).

    ``gt``, ``h``: the blocks ``G_T``, ``H``; ``ct = C T``; ``op_norm = ‖(I ⊗ Π C Q_c) 𝒯⁻¹‖₂``; ``across = Π C Q_c``,
    ``along = S_jᵀ C Q_c``; ``m = n − d``; ``sep = sep(G_T, G_c)``.
    """
    d = gt.shape[0]
    if m == 0:
        return 0.0, 0.0
    if sigma_d == 0.0:
        return (0.0, 0.0) if sep > 0 else (HALF_PI, float("inf"))
    gamma = sigma_d * np.sqrt(min(d, m))
    delta = sep - 2.0 * sigma_d
    h_norm = float(np.linalg.norm(h, 2)) + sigma_d
    if not delta > 0:
        return HALF_PI, float("inf")
    kappa = gamma * h_norm / delta**2
    if not kappa < STEWART_LIMIT:
        return HALF_PI, float(kappa)
    p = 2.0 * gamma / (delta * (1.0 + np.sqrt(1.0 - 4.0 * kappa)))
    r = (2.0 * sigma_d * p + h_norm * p * p) / sep
    num = gamma * op_norm + float(np.linalg.norm(across, 2)) * r
    den = _image_floor(gt, ct, sigma_d + h_norm * p) - float(np.linalg.norm(along, 2)) * p
    if not den > 0:
        return HALF_PI, float(kappa)
    return float(min(HALF_PI, np.arctan2(num, den))), float(kappa)


def _image_floor(gt: np.ndarray, ct: np.ndarray, eps: float) -> float:
    """A lower bound on ``‖C T ã‖`` over the unit eigenvectors ``ã`` of every real ``G_T + Δ``, ``‖Δ‖₂ ≤ eps``.

    ``σ_min(C T)`` bounds every vector. When ``C T`` is rank-deficient (a fault in ``ker C``) the eigenvectors still
    have an image, bounded thus. If every eigenvalue of ``G_T`` is real and the ``eps``-pseudospectrum
    ``{z : σ_min(G_T − z I) ≤ eps}`` separates them (:func:`_pseudospectrum_separates`), each component holds one
    eigenvalue of ``G_T + Δ``, which is real (a lone eigenvalue in a conjugate-symmetric component), and its unit
    eigenvector ``a`` is an ``eps``-pseudo-eigenvector: ``‖(G_T − λ I) a‖ ≤ eps`` for a real ``λ`` (and conversely,
    with ``Δ = −(G_T − λ I) a aᵀ``). On a grid ``λ_g`` of spacing ``h`` over Bauer–Fike's interval,
    ``‖(G_T − λ_g I) a‖ ≤ eps + h/2 = e``, and by weak duality, for any ``μ ≥ 0``,

        ‖C T a‖² ≥ λ_min(TᵀCᵀC T + μ (G_T − λ_g I)ᵀ(G_T − λ_g I)) − μ e²,

    a concave function of ``μ``, maximised by ternary search. ``eps = 0``: the smallest ``‖C T x_m‖`` of the unit
    eigenvectors of ``G_T``. The larger of the two bounds.
    """
    d = gt.shape[0]
    floor = float(np.linalg.svd(ct, compute_uv=False)[-1]) if d <= ct.shape[0] else 0.0
    lam, x = np.linalg.eig(gt)
    if d == 1 or np.any(np.abs(lam.imag) > 0):
        return floor
    lam, x = lam.real, np.real(x) / np.linalg.norm(np.real(x), axis=0)
    if eps == 0.0:
        return max(floor, float(np.min(np.linalg.norm(ct @ x, axis=0))))
    if not _pseudospectrum_separates(gt, np.sort(lam), eps):
        return floor
    reach = float(np.linalg.cond(x)) * eps  # Bauer–Fike: every eigenvalue of G_T + Δ within this of one of G_T
    pos, hi, h = float(lam.min()) - reach, float(lam.max()) + reach, eps
    e2 = (eps + 0.5 * h) ** 2
    pm = ct.T @ ct
    top = float(np.linalg.eigvalsh(pm)[-1])
    worst = top
    for _ in range(_WALK_LIMIT):
        if pos > hi:
            return max(floor, float(np.sqrt(max(worst, 0.0))))
        gap = _smin(gt, pos) - eps
        if gap >= 0.5 * h:  # σ_min is 1-Lipschitz: no pseudo-eigenvalue in [pos, pos + gap)
            pos += gap
            continue
        shifted = gt - (pos + 0.5 * h) * np.eye(d)  # the grid point covering [pos, pos + h]
        m = shifted.T @ shifted
        m_min = float(np.linalg.eigvalsh(m)[0])
        pos += h
        if m_min > e2:
            continue
        worst = min(worst, _dual_floor(pm, m, e2, top / max(e2 - m_min, 1e-300)))
        if worst <= floor**2:
            return floor
    return floor


_WALK_LIMIT = 100_000
"""Steps along a line through the pseudospectrum before giving up (the conservative answer)."""


def _smin(gt: np.ndarray, z: complex) -> float:
    return float(np.linalg.svd(gt - z * np.eye(gt.shape[0]), compute_uv=False)[-1])


def _dual_floor(pm: np.ndarray, m: np.ndarray, e2: float, mu_max: float) -> float:
    """``max_{0 ≤ μ ≤ μ_max} λ_min(P + μ M) − μ e²`` by ternary search (concave in ``μ``; every value a lower bound)."""
    def dual(mu: float) -> float:
        return float(np.linalg.eigvalsh(pm + mu * m)[0]) - mu * e2

    lo, hi = 0.0, mu_max
    best = dual(0.0)
    for _ in range(60):
        m1, m2 = lo + (hi - lo) / 3.0, hi - (hi - lo) / 3.0
        f1, f2 = dual(m1), dual(m2)
        best = max(best, f1, f2)
        lo, hi = (m1, hi) if f1 < f2 else (lo, m2)
    return best


def _pseudospectrum_separates(gt: np.ndarray, lam: np.ndarray, eps: float) -> bool:
    """Whether vertical lines between consecutive (sorted, real) eigenvalues of ``G_T`` miss its ``eps``-pseudospectrum.

    On the line ``Re z = x₀`` (midway) ``σ_min(G_T − z I)`` is 1-Lipschitz in ``z`` and at least ``|Im z| − ‖G_T‖₂``:
    walking up from ``Im z = 0`` by steps of ``σ_min − eps`` proves the line clear to ``‖G_T‖₂ + eps``.
    """
    top = float(np.linalg.norm(gt, 2)) + eps
    for left, right in zip(lam[:-1], lam[1:], strict=True):
        x0, y = 0.5 * (left + right), 0.0
        for _ in range(_WALK_LIMIT):
            if y > top:
                break
            step = _smin(gt, complex(x0, y)) - eps
            if step <= 1e-3 * eps:
                return False
            y += step
        else:
            return False
    return True


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
        qc = orth_complement(t)
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
    """Exact residual-direction angles under sampled model errors ``‖δA‖₂ = σ`` (one row per model error × ``k`` faults).

    ``δA``: ``draws`` Gaussian directions scaled to spectral norm ``σ``, then, fault after fault, its first-order
    worst cases ``σ · Re D/‖Re D‖₂`` for ``D`` in :attr:`ImplicitBound.worst_directions` (``Ts ≠ None``: ``δA`` on
    the continuous ``A``, exactly sampled). Row ``r`` holds, per fault, the largest exact angle between ``C ṽ`` and
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
    for direction in (dg for per_fault in bound.worst_directions for dg in per_fault):
        d = np.real(direction)
        nd = float(np.linalg.norm(d, 2))
        if nd > 0:
            deltas.append(sigma * d / nd)
    rows = []
    for d in deltas:
        gt = (sla.expm((a + d) * Ts) if Ts is not None else ad + d) - lm @ c
        rows.append(_perturbed_block_angles(gt, c, [np.asarray(t, dtype=float) for t in spaces], axes))
    return np.asarray(rows)
