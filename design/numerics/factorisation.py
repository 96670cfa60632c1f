"""The discrete-time algebraic Riccati system (DTARS) and the co-inner–outer factorisation
``G = G_o G_i`` (Qiu, Wen & Jiang, Control Theory & Applications 27(8), 2010, Lemma 4 and eq. (20)).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from fdisyn.numerics.certificate import worst
from fdisyn.numerics.linalg import as_matrix, as_square, normal_rank, psd_factor, rank_tol, spectral_radius, unobservable_modes
from fdisyn.numerics.norms import DiscreteLTI
from fdisyn.numerics.riccati import dare_pencil_eigenvalues, solve_filter_dare
from fdisyn.runtime.errors import ExistenceError, SolverError

__all__ = ['CoInnerOuter', 'Dtars', 'INNER_TOL', 'KAPPA_FACTOR', 'KAPPA_MAX', 'co_inner_outer', 'solve_dtars']
KAPPA_FACTOR = 2e-13
"""Per unit of κ = cond(NᵀN): ``E_J`` (from ``expm``) is accurate to
eps·‖W_E‖, so its weakly excited directions, which ``N# = N⁻¹`` amplifies by
~√κ, carry relative errors ~eps·κ into every identity below; measured worst
6.4e-14·κ over 160 random plants (n ≤ 4, one disturbance), so 2e-13·κ."""
KAPPA_MAX = 1e10
"""Beyond κ = 1e10 the identities keep fewer than three digits (2e-13·κ >
2e-3): the disturbance barely excites some output direction within a sample
(typical with fewer disturbances than outputs and a short Ts), and the computed
optimum is not trustworthy. Remedies: fewer outputs, a longer Ts, or a
disturbance model that excites every state."""
INNER_TOL = 1e-8
"""|‖G_rψ G_dJ‖∞ − 1| and |‖·‖₋ − 1| at κ ≲ 1e5: the norm (AB13DD) and the sweep are exact to ~1e-12
relative and the DTARS solution to ~1e-14·κ (larger κ: see :data:`KAPPA_FACTOR`)."""


# ---------------------------------------------------------------------------
# Lemma 4: DTARS and co-inner–outer factorisation
# ---------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Dtars:
    """Stabilising solution ``(X, M)`` of the DTARS (Lemma 4 and eq. (20))::

        [[A X Aᵀ − X + B Bᵀ,  A X Cᵀ + B Dᵀ],
         [C X Aᵀ + D Bᵀ,      C X Cᵀ + D Dᵀ]] [I; M] = 0,   A + Mᵀ C Schur.
    """

    X: np.ndarray
    M: np.ndarray
    N: np.ndarray
    """``N Nᵀ = C X Cᵀ + D Dᵀ``: lower Cholesky factor (``p × p``) when that is
    nonsingular, otherwise the full-column-rank eigen-factor (``p × r``)."""
    N_pinv: np.ndarray
    """``N#``: the left inverse ``(Nᵀ N)⁻¹ Nᵀ`` (``= N⁻¹`` when square)."""
    residual: float
    """Relative residual of both block rows of the DTARS."""
    closed_loop_eigenvalues: np.ndarray
    """Eigenvalues of ``A + Mᵀ C``."""
    rank: int
    """``rank(C X Cᵀ + D Dᵀ)`` = normal rank of ``G`` (``< p``: singular DTARS)."""
    kappa: float
    """``cond(Nᵀ N)``: forming ``M`` and ``N#`` loses ``log10 κ`` digits, so every
    identity downstream holds to ~``eps·κ``; the certificates scale with it.
    Sampled-data ``G_dJ`` with few disturbances is often ill conditioned here:
    a disturbance barely excites some state directions within one sample."""
    method: str
    """``"extended pencil"`` (regular) or ``"value recursion"`` (``rank < p``)."""


def _dtars_residual(
    a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray, x: np.ndarray, m: np.ndarray
) -> float:
    """``‖[row 1; row 2]‖_F`` of the DTARS over the size of its terms."""
    top = a @ x @ a.T - x + b @ b.T + (a @ x @ c.T + b @ d.T) @ m
    bot = c @ x @ a.T + d @ b.T + (c @ x @ c.T + d @ d.T) @ m
    scale = np.linalg.norm(a @ x @ a.T) + np.linalg.norm(x) + np.linalg.norm(b @ b.T) + np.linalg.norm(c @ x @ c.T)
    return float(math.hypot(np.linalg.norm(top), np.linalg.norm(bot)) / max(scale, np.finfo(float).tiny))


def _fmt_points(zs: list[complex]) -> list[complex]:
    """Distinct points rounded to 6 decimals, sorted (for messages)."""
    return sorted({complex(round(z.real, 6), round(z.imag, 6)) for z in zs}, key=lambda z: (z.real, z.imag))


def _explain_no_solution(
    a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray, exc: ExistenceError
) -> ExistenceError:
    """Name the Lemma 4 condition behind a failed DTARS: unit-circle zeros or modes."""
    try:
        eig = dare_pencil_eigenvalues(a, c, b @ b.T, d @ d.T, b @ d.T)
    except (ValueError, np.linalg.LinAlgError):
        return exc
    fin = eig[np.isfinite(eig)]
    on = fin[np.abs(np.abs(fin) - 1.0) < 1e-6]
    n = a.shape[0]
    zeros, uncontrollable = [], []
    for z in on:
        s = np.linalg.svd(np.hstack([z * np.eye(n) - a, b]).astype(complex), compute_uv=False)
        if float(s[-1]) <= 1e3 * n * np.finfo(float).eps * max(float(s[0]), 1.0):
            uncontrollable.append(z)
        else:
            zeros.append(z)
    if uncontrollable:
        return ExistenceError(
            f"G has uncontrollable mode(s) on the unit circle at z = {_fmt_points(uncontrollable)}: the DTARS has no "
            "stabilising solution (Lemma 4 and Theorem 1 of Qiu, Wen & Jiang 2010 assume none)"
        )
    if zeros:
        return ExistenceError(
            f"G has invariant zero(s) on the unit circle at z = {_fmt_points(zeros)}: the DTARS (eq. (20)) has no "
            "stabilising solution, so G has no co-inner–outer factorisation (Lemma 4 and Theorem 1 of Qiu, Wen & "
            "Jiang 2010 assume no zeros on the unit circle)"
        )
    return exc


def _value_recursion(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray, *, max_iter: int = 20_000) -> np.ndarray:
    """``X_{k+1} = A X Aᵀ + B Bᵀ − G W⁺ Gᵀ`` from ``X_0 = 0`` (the k-step predictor's error).

    Used when ``C X Cᵀ + D Dᵀ`` is singular (normal rank of ``G`` below ``p``):
    the extended pencil is then a singular pencil, but ``X`` is still unique —
    the limit of the monotone Riccati difference equation, the steady one-step
    prediction error of noise-free measurements.
    """
    n = a.shape[0]
    x = np.zeros((n, n))
    bb, bd, dd = b @ b.T, b @ d.T, d @ d.T
    for _ in range(max_iter):
        g = a @ x @ c.T + bd
        w = c @ x @ c.T + dd
        s = float(np.linalg.norm(w, 2))
        wp = np.linalg.pinv(w, rcond=max(rank_tol(w) / s, 1e-13) if s > 0 else 0.0, hermitian=True)
        xn = a @ x @ a.T + bb - g @ wp @ g.T
        xn = 0.5 * (xn + xn.T)
        # Converged to round-off of the terms that form X (A X Aᵀ can dwarf X
        # for an unstable A); the DTARS residual is checked afterwards.
        scale = np.linalg.norm(a @ x @ a.T) + np.linalg.norm(bb) + np.linalg.norm(xn)
        if np.linalg.norm(xn - x) <= 1e-14 * max(scale, np.finfo(float).tiny):
            return xn
        x = xn
    raise SolverError(
        f"the value recursion for the singular DTARS did not converge in {max_iter} steps "
        "(status: max_iter); the closed loop is nearly marginal — check the zeros of G near the unit circle"
    )


def solve_dtars(*, A: object, B: object, C: object, D: object | None = None) -> Dtars:
    """Lemma 4 / eq. (20): stabilising solution of the DTARS.

    The DTARS is the filtering DARE with ``Q = B Bᵀ``, ``R = D Dᵀ`` (zero for
    the strictly proper ``G_dJ``), ``S = B Dᵀ`` and ``M = −Lᵀ``; it is solved
    by :func:`~fdisyn.numerics.riccati.solve_filter_dare` (balanced extended
    pencil, which accepts ``R = 0``). When ``G`` has normal rank ``r < p`` the
    pencil is singular; then ``X`` comes from the value recursion and ``M`` is
    fixed only up to ``U₀ Z`` (``U₀`` spanning the kernel of ``C X Cᵀ + D Dᵀ``);
    fdisyn takes the least-squares ``Z`` minimising ``‖A + Mᵀ C‖_F`` (for
    ``C = I`` this gives the closed form ``M = −Aᵀ``) and requires ``A + MᵀC``
    Schur.

    Raises :class:`ExistenceError` for an undetectable ``(A, C)``, unit-circle
    invariant zeros or uncontrollable unit-circle modes of ``G`` (each named).
    """
    a = as_square(A, "A")
    n = a.shape[0]
    b = as_matrix(B, "B", rows=n)
    c = as_matrix(C, "C", cols=n)
    p = c.shape[0]
    d = np.zeros((p, b.shape[1])) if D is None else as_matrix(D, "D", rows=p, cols=b.shape[1])
    bad = unobservable_modes(a, c, region="unstable-discrete")
    if bad:
        raise ExistenceError(
            f"(A, C) is not detectable: mode(s) {[complex(round(z.real, 9), round(z.imag, 9)) for z in bad]} with "
            "|λ| ≥ 1 are unobservable, so the DTARS has no stabilising solution (Qiu, Wen & Jiang 2010, Lemma 4)"
        )
    r = normal_rank(a, b, c, d)
    if r == p:
        try:
            sol = solve_filter_dare(a, c, b @ b.T, d @ d.T, b @ d.T)
        except ExistenceError as exc:
            raise _explain_no_solution(a, b, c, d, exc) from exc
        x, m, method = sol.X, -sol.L.T, "extended pencil"
    else:
        x = _value_recursion(a, b, c, d)
        w = c @ x @ c.T + d @ d.T
        s = float(np.linalg.norm(w, 2))
        wp = np.linalg.pinv(w, rcond=max(rank_tol(w) / s, 1e-13) if s > 0 else 0.0, hermitian=True)
        m0 = -wp @ (c @ x @ a.T + d @ b.T)
        lam, u = np.linalg.eigh(0.5 * (w + w.T))
        u0 = u[:, lam <= max(1e-13 * s, rank_tol(w))]
        a0 = a + m0.T @ c
        k = u0.T @ c
        zt = -(a0 @ np.linalg.pinv(k)).T if k.size else np.zeros((0, n))
        m = m0 + u0 @ zt
        method = "value recursion"
    acl = a + m.T @ c
    ev = np.linalg.eigvals(acl)
    if spectral_radius(acl) >= 1.0 - 1e-12:
        err = ExistenceError(
            f"the DTARS has no stabilising solution: A + Mᵀ C has spectral radius {spectral_radius(acl):.6g} ≥ 1 "
            "(Qiu, Wen & Jiang 2010, Lemma 4)"
        )
        raise _explain_no_solution(a, b, c, d, err)
    w = c @ x @ c.T + d @ d.T
    w = 0.5 * (w + w.T)
    if r == p:
        try:
            nn = np.linalg.cholesky(w)
        except np.linalg.LinAlgError:
            raise ExistenceError(
                "C X Cᵀ + D Dᵀ is not positive definite although G has full row normal rank; "
                "the DTARS solution is inaccurate (check the scaling of B and C)"
            ) from None
        npinv = np.linalg.inv(nn)
    else:
        nn = psd_factor(w, "C X Cᵀ + D Dᵀ")
        npinv = np.linalg.pinv(nn)
    return Dtars(
        X=x,
        M=m,
        N=nn,
        N_pinv=npinv,
        residual=_dtars_residual(a, b, c, d, x, m),
        closed_loop_eigenvalues=ev,
        rank=int(nn.shape[1]),
        kappa=float(np.linalg.cond(nn.T @ nn)),
        method=method,
    )


@dataclass(frozen=True, eq=False)
class CoInnerOuter:
    """``G = G_o G_i`` (Lemma 4) with ``G_o#`` a stable left inverse of ``G_o``.

    ``G_o = (A, −Mᵀ N, C, N)`` (outer), ``G_i = (A + MᵀC, B + MᵀD, N#C, N#D)``
    (co-inner: ``G_i G_i~ = I``), ``G_o# = (A + MᵀC, Mᵀ, N#C, N#)``.
    Qiu, Wen & Jiang 2010 print ``B − MᵀD`` in ``G_i``; fdisyn uses
    ``B + MᵀD``, because ``G_i = G_o# G`` and Lemma 3 with ``K = −Mᵀ`` gives
    ``B − K D = B + MᵀD`` (the tests check ``G = G_o G_i`` with ``D ≠ 0``).
    For the sampled-data case ``D = 0`` and the two agree.
    """

    G: DiscreteLTI
    dtars: Dtars
    G_o: DiscreteLTI
    G_i: DiscreteLTI
    G_o_pinv: DiscreteLTI

    def co_inner_residual(self) -> float:
        """``max(‖N# C X Cᵀ N#ᵀ − I‖, ‖(A + MᵀC) X Cᵀ N#ᵀ‖ / ‖X‖)`` — both vanish iff ``G_i`` is co-inner.

        ``X`` (the DTARS solution) is the controllability Gramian of
        ``G_i``'s ``(A + MᵀC, B + MᵀD)``: the DTARS rearranges to
        ``X = (A + MᵀC) X (A + MᵀC)ᵀ + (B + MᵀD)(B + MᵀD)ᵀ``. With it these are
        the discrete co-inner conditions ``C_i X C_iᵀ + D_i D_iᵀ = I`` and
        ``A_i X C_iᵀ + B_i D_iᵀ = 0``.
        """
        gi, x = self.G_i, self.dtars.X
        e1 = gi.C @ x @ gi.C.T + gi.D @ gi.D.T - np.eye(gi.n_out)
        scale = float(np.linalg.norm(x)) * max(float(np.linalg.norm(gi.C)), 1e-300)
        e2 = (gi.A @ x @ gi.C.T + gi.B @ gi.D.T) / max(scale, 1e-300)
        return worst(float(np.linalg.norm(e1)), float(np.linalg.norm(e2)))  # NaN stays NaN


def co_inner_outer(*, A: object, B: object, C: object, D: object | None = None) -> CoInnerOuter:
    """Lemma 4: co-inner–outer factorisation from the DTARS (:func:`solve_dtars`)."""
    g = DiscreteLTI.create(A=A, B=B, C=C, D=D)
    dt = solve_dtars(A=g.A, B=g.B, C=g.C, D=g.D)
    mt, nn, npi = dt.M.T, dt.N, dt.N_pinv
    acl = g.A + mt @ g.C
    return CoInnerOuter(
        G=g,
        dtars=dt,
        G_o=DiscreteLTI(A=g.A, B=-mt @ nn, C=g.C, D=nn),
        G_i=DiscreteLTI(A=acl, B=g.B + mt @ g.D, C=npi @ g.C, D=npi @ g.D),
        G_o_pinv=DiscreteLTI(A=acl, B=mt, C=npi @ g.C, D=npi),
    )
