"""Semidefinite programmes through cvxpy and Clarabel: the solver ladder, its results and
the balancing that keeps the norm LMIs well conditioned.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import cvxpy as cp
import numpy as np
from fdisyn.numerics.certificate import Certificate
from fdisyn.numerics.linalg import dlyap, spectral_radius
from fdisyn.numerics.norms import DiscreteLTI
from fdisyn.runtime.errors import ExistenceError, InternalError, SolverError

__all__ = ['SDP_BOUND_TOL', 'SDP_BOUND_TOL_SINGULAR', 'SdpResult', 'SdpStats']

# Clarabel's gap and feasibility tolerances. Norm LMIs: first 1e-11, with
# "almost solved" redefined as 1e-9 (Clarabel's default reduced tolerances
# are 5e-5/1e-4) and accepted; if Clarabel stops short of that, 1e-9 with
# only "solved" accepted. On problems scaled to ‖G‖ ~ 1 that puts H∞ and H2
# within ~1e-9 relative and an H₋ index within ~1e-10·‖G‖∞ absolute
# (measured: at 1e-9 alone an index 1e-4 of ‖G‖∞ was off by 3e-4 relative,
# at 1e-11 by 7e-7). Design SDPs: 1e-9, "almost solved" accepted, because
# their optimum is degenerate and they are re-evaluated independently.
_CLARABEL = {"tol_gap_abs": 1e-9, "tol_gap_rel": 1e-9, "tol_feas": 1e-9, "max_iter": 400}
_CLARABEL_TIGHT = {
    "tol_gap_abs": 1e-11,
    "tol_gap_rel": 1e-11,
    "tol_feas": 1e-11,
    "reduced_tol_gap_abs": 1e-9,
    "reduced_tol_gap_rel": 1e-9,
    "reduced_tol_feas": 1e-9,
    "max_iter": 400,
}
_NORM_LADDER = ((_CLARABEL_TIGHT, True), (_CLARABEL, False))
_CLARABEL_RESCUE = {**_CLARABEL, "static_regularization_constant": 1e-7}
"""A design SDP's second try when Clarabel fails outright (its KKT factorisation broke down): ten times its default
static regularisation. Measured on a seeded unstable plant with state scales spread over 1e4, whose H2 observer
LMI Clarabel solved under OpenBLAS's Haswell kernel and failed under SkylakeX: "almost solved" on every kernel, the
gain then checked as every design's is."""
SDP_BOUND_TOL = 1e-4
"""Achieved J (frequency response) against the SDP's bound γ: the LMIs hold to Clarabel's
feasibility tolerance 1e-9 times the size of their entries; measured excess
≤ 2e-5 when ``G_d`` has full row normal rank."""
SDP_BOUND_TOL_SINGULAR = 1e-3
"""The same when ``G_d`` has normal rank below ``p`` (nearly decoupled
residuals): the entries reach ~1e4·γ² and more, and the excess depends on the
BLAS kernel — measured on the paper's ZOH model 2e-5 (OpenBLAS SkylakeX,
Haswell, Zen) and 1.8e-4 (SandyBridge); 1e-3 leaves a factor 5."""


@dataclass(frozen=True)
class SdpStats:
    """What one SDP solve reported."""

    what: str
    status: str
    solve_time: float
    """Solver-reported time in seconds (Clarabel's own clock)."""
    wall_time: float
    """cvxpy canonicalisation + solve, seconds."""
    iterations: int | None
    n_scalar_variables: int


@dataclass(frozen=True, eq=False)
class SdpResult:
    """An optimal value and the SDP's statistics."""

    value: float
    stats: SdpStats | None
    """``None`` when no SDP was needed (e.g. ``‖G‖₋ = 0`` for a wide system)."""
    route: str = "sdp"
    """Which formulation produced ``value`` (:func:`~fdisyn.numerics.lmi_norms.hminus_index_lmi` names its routes)."""
    bracket: tuple[float, float] | None = None
    """``(proven lower bound, attained upper bound)`` when ``value`` was verified (H₋ index)."""
    certificate: Certificate | None = None
    """What ``value`` was verified against, and how well (H₋ index)."""


_HINTS = {
    cp.INFEASIBLE: "infeasible",
    cp.INFEASIBLE_INACCURATE: "infeasible (inaccurate)",
    cp.UNBOUNDED: "unbounded",
    cp.UNBOUNDED_INACCURATE: "unbounded (inaccurate)",
    cp.OPTIMAL_INACCURATE: "optimal (inaccurate)",
}


def _solve(
    prob: cp.Problem,
    *,
    what: str,
    meaning: Mapping[str, str],
    accept_inaccurate: bool = False,
    settings: Sequence[tuple[Mapping[str, float], bool]] | None = None,
) -> SdpStats:
    """Solve with Clarabel; map every non-optimal status to :class:`SolverError`.

    ``meaning`` says, per status family (``"infeasible"``, ``"unbounded"``),
    what that status means for this LMI and what to try. ``settings`` is a
    ladder of ``(Clarabel settings, accept "almost solved")`` tried in turn
    while the solver fails or stops short; infeasible and unbounded are
    definitive and raised at once. Default: ``[(_CLARABEL, accept_inaccurate)]``, then for a design SDP that accepts
    "almost solved" a second try with more regularisation (``_CLARABEL_RESCUE``).
    """
    ladder = list(settings) if settings is not None else [(_CLARABEL, accept_inaccurate)] + (
        [(_CLARABEL_RESCUE, True)] if accept_inaccurate else [])
    err: SolverError | None = None
    for opts, accept in ladder:
        try:
            return _solve_once(prob, what=what, meaning=meaning, accept_inaccurate=accept, opts=opts)
        except _Definitive as exc:
            raise exc.error from None
        except SolverError as exc:
            err = exc
    if err is None:  # an empty ladder is a programming error, not a solver outcome
        raise InternalError("internal: no Clarabel settings to try")
    raise err


class _Definitive(Exception):
    """Carries an infeasible/unbounded verdict past the settings ladder."""

    def __init__(self, error: SolverError) -> None:
        super().__init__(str(error))
        self.error = error


def _solve_once(
    prob: cp.Problem, *, what: str, meaning: Mapping[str, str], accept_inaccurate: bool, opts: Mapping[str, float]
) -> SdpStats:
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            # cvxpy warns on inaccurate solutions; the status is mapped below instead.
            warnings.filterwarnings("ignore", message="Solution may be inaccurate", category=UserWarning)
            prob.solve(solver=cp.CLARABEL, **opts)
    except cp.error.SolverError as exc:
        raise SolverError(
            f"{what}: Clarabel failed ({exc}); status: solver_error. Try rescaling the system "
            "(balance the realisation, normalise B and C) or reducing its order"
        ) from exc
    wall = time.perf_counter() - t0
    status = prob.status
    st = prob.solver_stats
    stats = SdpStats(
        what=what,
        status=str(status),
        solve_time=float(st.solve_time) if st and st.solve_time is not None else float("nan"),
        wall_time=wall,
        iterations=int(st.num_iters) if st and st.num_iters is not None else None,
        n_scalar_variables=int(sum(v.size for v in prob.variables())),
    )
    if status == cp.OPTIMAL or (status == cp.OPTIMAL_INACCURATE and accept_inaccurate):
        return stats
    definitive = False
    if status in (cp.INFEASIBLE, cp.INFEASIBLE_INACCURATE):
        hint, definitive = meaning.get("infeasible", "the LMIs have no solution"), True
    elif status in (cp.UNBOUNDED, cp.UNBOUNDED_INACCURATE):
        hint, definitive = meaning.get("unbounded", "the objective is unbounded"), True
    elif status == cp.OPTIMAL_INACCURATE:
        hint = (
            "the solver stopped near, not at, the optimum (its reduced tolerances were met, the full ones "
            "not); try rescaling the system (balanced realisation) or reducing its order"
        )
    else:
        hint = "the solver did not finish; try rescaling the system or reducing its order"
    error = SolverError(
        f"{what}: SDP status {_HINTS.get(status, str(status))} after {stats.iterations} iterations "
        f"(Clarabel, {stats.solve_time:.3g} s): {hint}"
    )
    if definitive:
        raise _Definitive(error)
    raise error


def _val(x: cp.Variable | cp.Problem) -> np.ndarray:
    """The solved value of a variable (or a problem's optimal value) as an array."""
    v = x.value
    if v is None:
        raise SolverError("internal: the SDP reported success but left a variable without a value")
    return np.asarray(v, dtype=float)


def _sym(m: cp.Expression) -> cp.Expression:
    """Symmetric (Hermitian) part, so cvxpy accepts the expression in an LMI."""
    return 0.5 * (m + m.H)


def _scale(sys: DiscreteLTI) -> float:
    """A size of ``G`` from Gramians (Hankel norm + ‖D‖), to scale it to O(1).

    Not a norm estimate used in the answer — only a scaling, so the SDP's
    absolute tolerances become relative ones.
    """
    if sys.n == 0 or sys.n_in == 0 or sys.n_out == 0:
        return max(float(np.linalg.norm(sys.D, 2)) if sys.D.size else 0.0, 1.0)
    wc = dlyap(sys.A, sys.B @ sys.B.T, refine=False)
    wo = dlyap(sys.A.T, sys.C.T @ sys.C, refine=False)
    hank = math.sqrt(max(float(np.max(np.real(np.linalg.eigvals(wc @ wo)))), 0.0))
    s = hank + float(np.linalg.norm(sys.D, 2))
    return s if s > 0 else 1.0


def _balance(sys: DiscreteLTI, *, max_cond: float | None = None) -> DiscreteLTI:
    """The system in balanced state coordinates (:func:`_balancing`); norms are similarity invariant.

    With Gramians equal and diagonal the Lyapunov/KYP multipliers are O(1),
    which is what keeps Clarabel at "solved" rather than "almost solved" on
    the (generalised) KYP LMIs.
    """
    if sys.n == 0:
        return sys
    t, ti = _balancing(sys.A, sys.B, sys.C, max_cond=max_cond)
    return DiscreteLTI(A=ti @ sys.A @ t, B=ti @ sys.B, C=sys.C @ t, D=sys.D)


def _require_stable(sys: DiscreteLTI, what: str) -> None:
    if spectral_radius(sys.A) >= 1.0 - 1e-12:
        raise ExistenceError(
            f"{what}: A is not Schur stable (spectral radius {spectral_radius(sys.A):.6g}); "
            "the LMI has no solution and the norm is infinite"
        )


def _balancing(
    a: np.ndarray, b: np.ndarray, c: np.ndarray, *, max_cond: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Square-root balancing ``(T, T⁻¹)``: ``T⁻¹ W_c T⁻ᵀ = Tᵀ W_o T`` diagonal (Laub et al., 1987).

    Falls back to the identity where balancing would be ill conditioned: by
    default when a Gramian is numerically singular (Hankel singular values
    spanning more than 1e6, a nearly non-minimal realisation); with
    ``max_cond``, only when ``cond(T)`` exceeds it. The H₋ index LMI uses the
    latter: a well-damped system of order 10 has Hankel singular values
    spanning 1e6 with ``cond(T) ≈ 50``, and its unbalanced realisation stalls
    Clarabel (measured: β² proven to 2e-9 of ‖G‖∞² unbalanced, 2e-12 balanced).
    """
    n = a.shape[0]
    wc = dlyap(a, b @ b.T, refine=False)
    wo = dlyap(a.T, c.T @ c, refine=False)
    try:
        lc = np.linalg.cholesky(wc + 1e-13 * np.linalg.norm(wc) * np.eye(n))
    except np.linalg.LinAlgError:
        return np.eye(n), np.eye(n)
    u, sv, _ = np.linalg.svd(lc.T @ wo @ lc)
    if sv[-1] <= 0.0 or (max_cond is None and sv[-1] <= 1e-12 * sv[0]):
        return np.eye(n), np.eye(n)
    t = lc @ u @ np.diag(sv**-0.25)
    if max_cond is not None and np.linalg.cond(t) > max_cond:
        return np.eye(n), np.eye(n)
    return t, np.linalg.inv(t)


def _psd_part(m: np.ndarray) -> np.ndarray:
    """Clip the tiny negative eigenvalues an interior-point solution can carry (~1e-10); real or Hermitian."""
    lam, u = np.linalg.eigh(0.5 * (m + m.conj().T))
    return (u * np.maximum(lam, 0.0)[None, :]) @ u.conj().T
