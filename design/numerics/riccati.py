"""Discrete algebraic Riccati equations by the extended pencil.

The filtering DARE, the form every fdisyn method needs::

    X = A X Aᵀ + Q − (A X Cᵀ + S)(C X Cᵀ + R)⁺ (A X Cᵀ + S)ᵀ
    L = (A X Cᵀ + S)(C X Cᵀ + R)⁺,   A − L C  Schur stable.

``R`` may be singular — the optimal unknown-input observer of Hu et al.
(Acta Automatica Sinica 39(8), 2013) has the rank-``p − q`` measurement term
``(I − CH) R (I − CH)ᵀ`` and a cross term ``S``, and the DTARS of Qiu, Wen &
Jiang (Control Theory & Applications 27(8), 2010, Lemma 4) has ``R = 0``. Forming
``(C X Cᵀ + R)⁻¹`` inside the algorithm would fail there, so the solution is
computed from the deflating subspace of the extended (``2n + p``) symplectic
pencil, which never inverts ``R`` (Arnold & Laub, Proc. IEEE 72(12), 1984;
Van Dooren, SIAM J. Sci. Stat. Comput. 2(2), 1981). The pencil is the dual
(``A → Aᵀ``, ``C → Bᵀ``) of the control-form pencil

    λ [[I, 0, 0], [0, Aᵀ, 0], [0, −Bᵀ, 0]] − [[A, 0, B], [−Q, I, −S], [Sᵀ, 0, R]].

SciPy's ``solve_discrete_are`` is exactly this method (symplectic balancing,
compression of the ``R`` columns, ordered QZ) and accepts a singular ``R``
while the pencil is regular: :func:`solve_filter_dare` calls it on the dual
problem. This module forms the pencil itself only where SciPy cannot answer:
:func:`dare_pencil_eigenvalues`, and the diagnosis of *why* there is no
stabilising solution when SciPy fails or returns a solution that does not
stabilise (eigenvalues on the unit circle, named with their moduli, or a
stable deflating subspace of the wrong dimension).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
from fdisyn.numerics.linalg import as_matrix, as_square, as_symmetric, rank_tol, unobservable_modes
from fdisyn.runtime.errors import ExistenceError, SolverError

__all__ = ["DareSolution", "solve_filter_dare", "dare_residual", "dare_pencil_eigenvalues"]

# Eigenvalues closer than this to the unit circle are treated as on it: a
# generalised eigenvalue of a well-conditioned pencil is accurate to about
# sqrt(eps) when it is (nearly) defective, and 1e-8 ≈ 45·sqrt(eps) leaves room.
UNIT_CIRCLE_TOL = 1e-8


@dataclass(frozen=True)
class DareSolution:
    """The stabilising solution of a filtering DARE and what it implies."""

    X: np.ndarray
    """Stabilising solution (the steady-state error covariance for a Kalman filter)."""
    L: np.ndarray
    """Gain ``(A X Cᵀ + S)(C X Cᵀ + R)⁺``."""
    closed_loop_eigenvalues: np.ndarray
    """Eigenvalues of ``A − L C``."""
    residual: float
    """Relative residual of the DARE at ``X`` (see :func:`dare_residual`)."""
    innovation_rank: int
    """Rank of ``C X Cᵀ + R`` (``p`` unless the problem is singular)."""


def dare_residual(A: np.ndarray, C: np.ndarray, Q: np.ndarray, R: np.ndarray, S: np.ndarray, X: np.ndarray) -> float:
    """``‖A X Aᵀ − X + Q − G W⁺ Gᵀ‖_F / (‖A X Aᵀ‖_F + ‖X‖_F + ‖Q‖_F)``.

    ``G = A X Cᵀ + S``, ``W = C X Cᵀ + R``. Normalised by the size of the
    terms, so round-off of a backward-stable solver gives ~1e-15.
    """
    g = A @ X @ C.T + S
    w = C @ X @ C.T + R
    res = A @ X @ A.T - X + Q - g @ np.linalg.pinv(w, rcond=_rcond(w), hermitian=True) @ g.T
    scale = np.linalg.norm(A @ X @ A.T) + np.linalg.norm(X) + np.linalg.norm(Q)
    return float(np.linalg.norm(res) / max(scale, np.finfo(float).tiny))


def _rcond(w: np.ndarray) -> float:
    s = float(np.linalg.norm(w, 2))
    return rank_tol(w) / s if s > 0 else 0.0


def _reduced_pencil(a: np.ndarray, c: np.ndarray, q: np.ndarray, r: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The balanced, column-compressed ``2n × 2n`` pencil ``(m2, n2)``."""
    n = a.shape[0]
    p = c.shape[0]
    # Control-form extended pencil of the dual problem (a, b) = (Aᵀ, Cᵀ).
    at, b = a.T, c.T
    big = 2 * n + p
    mm = np.zeros((big, big))
    nn = np.zeros((big, big))
    mm[:n, :n] = at
    mm[:n, 2 * n :] = b
    mm[n : 2 * n, :n] = -q
    mm[n : 2 * n, n : 2 * n] = np.eye(n)
    mm[n : 2 * n, 2 * n :] = -s
    mm[2 * n :, :n] = s.T
    mm[2 * n :, 2 * n :] = r
    nn[:n, :n] = np.eye(n)
    nn[n : 2 * n, n : 2 * n] = a
    nn[2 * n :, n : 2 * n] = -b.T
    # Balance with a diagonal similarity diag(D, D⁻¹, Dp) that keeps the
    # symplectic structure (Benner, "Symplectic balancing of Hamiltonian matrices", SIAM J. Sci.
    # Comput. 22(5), 2001): powers of two, so no rounding.
    mag = np.abs(mm) + np.abs(nn)
    np.fill_diagonal(mag, 0.0)
    _, (sca, _) = sla.matrix_balance(mag, separate=True, permute=False)
    lg = np.log2(sca)
    half = np.round((lg[n : 2 * n] - lg[:n]) / 2.0)
    sca = 2.0 ** np.concatenate([half, -half, lg[2 * n :]])
    mm *= sca[:, None] / sca[None, :]
    nn *= sca[:, None] / sca[None, :]
    # Compress the last p columns away (orthogonal, so well conditioned).
    qq, _ = np.linalg.qr(mm[:, 2 * n :], mode="complete")
    w = qq[:, p:].T
    m2 = w @ mm[:, : 2 * n]
    n2 = w @ nn[:, : 2 * n]
    return m2, n2


def _dare_data(A: object, C: object, Q: object, R: object, S: object | None) -> tuple[np.ndarray, ...]:
    """Validated ``(A, C, Q, R, S)`` of a filtering DARE (errors name the matrix)."""
    a = as_square(A, "A")
    n = a.shape[0]
    c = as_matrix(C, "C", cols=n)
    p = c.shape[0]
    s = np.zeros((n, p)) if S is None else as_matrix(S, "S", rows=n, cols=p)
    return a, c, as_symmetric(Q, "Q", n), as_symmetric(R, "R", p), s


def solve_filter_dare(
    A: object,
    C: object,
    Q: object,
    R: object,
    S: object | None = None,
) -> DareSolution:
    """Stabilising solution of the filtering DARE (see the module docstring).

    Raises
    ------
    ShapeError
        Inconsistent dimensions.
    ArgumentError
        ``Q``/``R`` not symmetric.
    ExistenceError
        No stabilising solution: the pencil has eigenvalues on the unit circle
        (an undetectable ``(C, A)`` mode or a noise-model zero on the unit
        circle), the stable deflating subspace has the wrong dimension, or its
        basis cannot be solved for ``X``.
    SolverError
        The QZ decomposition failed.
    """
    a, c, q, r, s = _dare_data(A, C, Q, R, S)
    bad = unobservable_modes(a, c, region="unstable-discrete")
    if bad:
        raise ExistenceError(
            f"the DARE has no stabilising solution: (C, A) is not detectable (mode λ = {bad[0]:.6g}, "
            f"|λ| = {abs(bad[0]):.6g}, is invisible in the measurements)"
        )
    if not (np.any(q) or np.any(r) or np.any(s)):
        raise ExistenceError(
            "the DARE has no noise model: Q, R and S are all zero (no process or sensor noise), so there is no "
            "minimum-variance gain; give the plant's noise covariances Q and R (R > 0 on the outputs used)"
        )
    try:
        # SciPy's control-form DARE of the dual problem (a, b) = (Aᵀ, Cᵀ)
        x = sla.solve_discrete_are(a.T, c.T, q, r, s=s)
        if not dare_residual(a, c, q, r, s, x) <= PLAIN_RESIDUAL:
            x = _normalised_solution(a, c, q, r, s, x)
    except ValueError as exc:  # SciPy's ordered QZ failed (the data were validated above)
        why = SolverError(f"the DARE pencil's ordered QZ decomposition failed (SciPy: {exc}); "
                          "the noise model may be degenerate: check that R > 0 on the outputs used and that Q reaches every unstable mode")
        raise _no_solution(a, c, q, r, s, why) from exc
    except np.linalg.LinAlgError as exc:  # SciPy: the stable subspace is not the graph of an X
        unsolvable = f"the stable deflating subspace cannot be solved for X ({exc}); the DARE has no stabilising solution"
        raise _no_solution(a, c, q, r, s, ExistenceError(unsolvable)) from exc
    g = a @ x @ c.T + s
    wmat = c @ x @ c.T + r
    wpinv = np.linalg.pinv(wmat, rcond=_rcond(wmat), hermitian=True)
    gain = g @ wpinv
    ev = np.linalg.eigvals(a - gain @ c)
    # With eigenvalues of the pencil on the unit circle the ordered QZ may still
    # succeed and return a solution that is not stabilising; the pencil says why.
    radius = float(np.max(np.abs(ev), initial=0.0))
    if not radius < 1.0 - UNIT_CIRCLE_TOL:
        unstable = f"the DARE has no stabilising solution: A − L C has spectral radius {radius:.6g}, expected < 1"
        raise _no_solution(a, c, q, r, s, ExistenceError(unstable))
    return DareSolution(
        X=x,
        L=gain,
        closed_loop_eigenvalues=ev,
        residual=dare_residual(a, c, q, r, s, x),
        innovation_rank=int(np.linalg.matrix_rank(wmat, tol=rank_tol(wmat))),
    )


PLAIN_RESIDUAL = 1e-12
"""A DARE solution whose relative residual (:func:`dare_residual`) is above this is solved again with the noise
normalised (:func:`_normalised_solution`): a backward-stable solve of well-scaled data gives ~1e-15, and one of
noise covariances of size 1e-7 beside the pencil's identity blocks was measured at 3.7e-10."""


def _normalised_solution(a: np.ndarray, c: np.ndarray, q: np.ndarray, r: np.ndarray, s: np.ndarray, x: np.ndarray) -> np.ndarray:
    """The DARE solved with its noise scaled to unit size, or ``x`` when that is no better.

    The DARE is homogeneous in its noise: ``X(αQ, αR, αS) = α X(Q, R, S)``. With ``α`` the power of two nearest
    ``max(‖Q‖, ‖R‖, ‖S‖)`` (exact in floating point) the pencil's noise blocks are of the size of its identity
    blocks, so the solution no longer depends on the units of the noise (measured: a relative residual of
    3.7e-10 became 5.6e-16). The solution with the smaller residual is kept.
    """
    size = max(float(np.linalg.norm(m, 2)) for m in (q, r, s) if m.size)
    alpha = float(np.exp2(np.round(np.log2(size))))
    if alpha == 1.0:
        return x
    xn = sla.solve_discrete_are(a.T, c.T, q / alpha, r / alpha, s=s / alpha) * alpha
    return xn if dare_residual(a, c, q, r, s, xn) < dare_residual(a, c, q, r, s, x) else x


def _no_solution(
    a: np.ndarray, c: np.ndarray, q: np.ndarray, r: np.ndarray, s: np.ndarray, otherwise: ExistenceError | SolverError
) -> ExistenceError | SolverError:
    """Why there is no stabilising solution, read off the eigenvalues of the extended pencil.

    Eigenvalues on the unit circle (named with their moduli), or a stable
    deflating subspace of the wrong dimension; else ``otherwise``.
    """
    n = a.shape[0]
    mod = np.abs(dare_pencil_eigenvalues(a, c, q, r, s))
    on_circle = np.abs(mod - 1.0) < UNIT_CIRCLE_TOL
    if np.any(on_circle):
        return ExistenceError(
            "the DARE has no stabilising solution: its pencil has eigenvalue(s) on the unit circle "
            f"(moduli {np.sort(mod[on_circle])}); a mode of (C, A) on the unit circle is undetectable "
            "or not excited by the noise Q"
        )
    stable = int(np.sum(mod < 1.0))
    if stable != n:
        return ExistenceError(
            f"the DARE pencil has {stable} stable eigenvalues, expected {n}: "
            "(C, A) is not detectable or the problem is degenerate"
        )
    return otherwise


def dare_pencil_eigenvalues(A: object, C: object, Q: object, R: object, S: object | None = None) -> np.ndarray:
    """Generalised eigenvalues of the (compressed) extended pencil of the filtering DARE.

    They come in pairs ``(λ, 1/λ̄)``; the stabilising solution exists iff none
    lies on the unit circle (and the stable deflating subspace is a graph).
    Eigenvalues on the circle are the unit-circle zeros of the spectral density
    ``Φ(z) = [C (zI − A)⁻¹, I] [[Q, S], [Sᵀ, R]] [·]~`` — for ``Q = B Bᵀ``,
    ``R = D Dᵀ``, ``S = B Dᵀ`` the invariant zeros of ``(A, B, C, D)`` and its
    uncontrollable modes on the circle — and undetectable modes of ``(C, A)``
    on the circle. Infinite eigenvalues are returned as ``inf``.
    """
    a, c, q, r, s = _dare_data(A, C, Q, R, S)
    alpha, beta = sla.eigvals(*_reduced_pencil(a, c, q, r, s), homogeneous_eigvals=True)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(np.abs(beta) > 0, alpha / np.where(beta == 0, 1, beta), np.inf)
