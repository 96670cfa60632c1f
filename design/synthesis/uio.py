"""Unknown-input observers with minimum-variance gains (Hu et al. 2013).

Hu, Sun, Jiang, He & Zhang, "An optimal unknown input observer based fault
diagnosis method", Acta Automatica Sinica 39(8), 2013; equation and section
numbers below are theirs. The existence conditions ``rank(C E) = rank(E)``
and ``(C, A1)`` detectable are stated as necessary and sufficient by Long &
Wang, Aeroengine 43(5), 2017, section 1.

Plant ``x⁺ = A x + B u + E d + w``, ``y = C x + D u + v`` (discrete).
Construction (eqs. (3)–(11))::

    M C E = I            (M: the Moore–Penrose inverse of C E)
    H = E M,  T = I − H C,  A1 = T A,  G = T B
    z⁺ = F z + G u + K ỹ,   x̂ = z + H ỹ,   ỹ = y − D u
    F = A1 − L C,  K = F H + L = A1 H + L (I − C H)
    r = ỹ − C x̂ = (I − C H) ỹ − C z

The error ``ε = T x − z`` obeys ``ε⁺ = F ε + T w − K v`` exactly, so its
steady-state covariance solves the Lyapunov equation
``Σ = F Σ Fᵀ + T Q Tᵀ + K R Kᵀ`` and the residual ``r = C ε + (I − CH) v``
has covariance ``Σ_r = C Σ Cᵀ + (I − CH) R (I − CH)ᵀ`` (``ε(k)`` does not
depend on ``v(k)``). The paper's covariance step (eq. (16)) drops the
correlation between ``−H v(k)`` (inside the error) and ``−L v(k)``, adding
``H R Hᵀ`` and ``L R Lᵀ`` as if independent, so its gain minimises another
quantity than the true error covariance — even when the cross term
``S = −A1 H R (I − CH)ᵀ`` vanishes (``R = σ² I`` with the Moore–Penrose
``M``). fdisyn minimises the exact covariance above and keeps the paper's
recursion as ``variant="paper"``.

Gains:

``kalman_uio(variant="optimal")``
    ``L`` minimises ``trace Σ(L)`` subject to the exact Lyapunov equation, a
    CasADi/IPOPT NLP over ``L``. Verified against the stabilising solution of
    the filtering DARE with the cross term ``S = −A1 H R (I − CH)ᵀ`` and the
    singular ``(I − CH) R (I − CH)ᵀ`` (:mod:`fdisyn.numerics.riccati`).
``kalman_uio(variant="paper")``
    The steady state of the paper's recursion (eqs. (14), (16)), from the DARE
    in ``(A1, C, T Q Tᵀ + H R Hᵀ, R)``, certified as the recursion's fixed point.
``uio_pole_placement``
    The plain UIO the paper compares against: ``eig(A1 − L C)`` assigned.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any, Literal

import casadi as ca
import numpy as np
import scipy.signal
from fdisyn.models.linear import LinearPlant
from fdisyn.numerics.certificate import Certificate, Check
from fdisyn.numerics.linalg import dlyap, rank, rel_diff, spectral_radius, unobservable_modes
from fdisyn.numerics.riccati import solve_filter_dare
from fdisyn.runtime.errors import ArgumentError, CertificateError, ExistenceError, ShapeError, SolverError
from fdisyn.runtime.gainfile import Generator
from fdisyn.synthesis.residual import internal_form

__all__ = [
    "UIOStructure",
    "UIODesign",
    "uio_structure",
    "kalman_uio",
    "uio_pole_placement",
    "uio_error_covariance",
    "ce_condition",
    "design_coordinates",
    "in_user_states",
]

# Tolerances, each with its reason (used in the certificates below).
DECOUPLING_TOL = 1e-9
"""T E = 0 and a zero internal-form transfer hold algebraically; in floating
point they are round-off, ~1e-15 times cond(C E). 1e-9 leaves six orders of
margin while still catching any real coupling."""
GAIN_TOL = 1e-8
"""Agreement of the optimised gain with the analytic Riccati gain. The NLP
and the Riccati solution are independent routes to the same optimum, so their
gap is the NLP's error; it guards against a gain that is optimal to only a
few digits (a stalled or local IPOPT solution). IPOPT is run to a KKT
tolerance of 1e-14, which puts the gain within ~cond(Hessian)·1e-14 of the
optimum: 1e-8 leaves room for a Hessian condition number up to 1e6."""
NLP_STATES = 16
"""Largest reduced minimum-variance problem (states of the error) whose gain is also found by the NLP and
compared with the Riccati gain. IPOPT's time grows like ``n⁵·⁵`` (measured on seeded random plants, 2 cores:
0.3 s at 14 states, 1.7 s at 18, 9.5 s at 24, 110 s at 40); above, the Riccati gain is certified by the
optimality condition alone (:func:`_riccati_gain`). Every reference problem's UIOs are below it."""
RESIDUAL_TOL = 1e-10
"""Relative residual of a Riccati or Lyapunov equation: backward-stable
solvers give ~n·eps ≈ 1e-15; 1e-10 flags a genuinely wrong solution."""
STABILITY_MARGIN = 1e-9
"""F must be Schur: spectral radius ≤ 1 − 1e-9 (a root on the circle to
round-off is not stable)."""
CE_CONDITION_MAX = 1e6
"""Largest ``κ = ‖C‖‖E‖ / σ_min(C E)`` a UIO is built for. ``T = I − E (C E)⁺ C``
carries ``κ`` into its round-off, so ``T E = 0`` holds to ~1e-15·κ; at 1e6 that
reaches :data:`DECOUPLING_TOL` and the decoupling can no longer be certified."""
CE_CONDITION_HINT = 1e3
"""From this ``κ`` on, a failed UIO design names a weak ``C E`` as the likely
cause (measured: the motor example fails from κ ≈ 4e3 on, IPOPT not converging
or a singular Lyapunov equation; the built-in banks have κ ≤ 533)."""


@dataclass(frozen=True, eq=False)
class UIOStructure:
    """The decoupling part of a UIO (Hu et al. 2013, eqs. (3), (8), (11))."""

    M: np.ndarray
    """Left inverse of ``C E`` (Moore–Penrose), eq. (3)."""
    H: np.ndarray
    """``H = E M``."""
    T: np.ndarray
    """``T = I − H C`` (so ``T E = 0``), eq. (8)."""
    A1: np.ndarray
    """``A1 = T A``."""
    G: np.ndarray
    """``G = T B``."""
    Cbar: np.ndarray
    """``I − C H``: the residual lives in its range (dimension ``p − q``)."""


def uio_structure(plant: LinearPlant) -> UIOStructure:
    """Check the existence conditions and build ``M, H, T, A1, G``.

    Raises :class:`ExistenceError` naming the failed condition:
    ``rank(C E) = rank(E) = q`` (Hu et al. 2013, eq. (3)), ``p > q`` (otherwise no
    residual is left), and detectability of ``(C, A1)``.
    """
    if not plant.is_discrete:
        raise ArgumentError("the UIO is designed on a discrete plant; call plant.discretise(Ts) first")
    n, p, q = plant.n, plant.p, plant.q
    e, c = np.asarray(plant.E), np.asarray(plant.C)
    if q == 0:
        m = np.zeros((0, p))
    else:
        re_, rce = rank(e), rank(c @ e)
        if re_ != q:
            raise ExistenceError(
                f"rank(E) = {re_} but E has q = {q} columns: the unknown inputs are not independent; "
                "merge dependent columns of E (Hu et al. 2013, eq. (3) needs rank(E) = q)"
            )
        if rce != q:
            raise ExistenceError(
                f"rank(C E) = {rce} ≠ rank(E) = {q}: the unknown input cannot be decoupled from the outputs "
                f"{list(plant.outputs)} (Hu et al. 2013, eq. (3): rank(C E) = rank(E))"
            )
        kappa = ce_condition(plant)
        if kappa > CE_CONDITION_MAX:
            raise ExistenceError(f"the UIO cannot be built: {_weak_ce(plant, kappa)}")
        m = np.linalg.pinv(c @ e)
    if p <= q:
        raise ExistenceError(
            f"p = {p} outputs and q = {q} unknown inputs leave no residual (p − q = {p - q}); "
            "a UIO residual needs more outputs than unknown inputs"
        )
    h = e @ m
    t = np.eye(n) - h @ c
    a1 = t @ np.asarray(plant.A)
    _check_detectable(a1, c, plant)
    return UIOStructure(M=m, H=h, T=t, A1=a1, G=t @ np.asarray(plant.B), Cbar=np.eye(p) - c @ h)


def ce_condition(plant: LinearPlant) -> float:
    """``κ = ‖C‖₂ ‖E‖₂ / σ_min(C E)``: how weakly the unknown input reaches the outputs.

    ``rank(C E)`` is judged relative to ``C E`` itself, so a tiny but nonzero
    ``C E`` passes it; ``κ`` measures it against ``C`` and ``E``, i.e. the
    amplification ``‖H‖‖C‖`` of the decoupling (1 when ``E`` enters the
    measured states directly). ``inf`` when ``C E`` has lower rank.
    """
    c, e = np.asarray(plant.C), np.asarray(plant.E)
    if e.size == 0:
        return 1.0
    sv = np.linalg.svd(c @ e, compute_uv=False)
    return float(np.linalg.norm(c, 2) * np.linalg.norm(e, 2) / sv[-1]) if sv[-1] > 0 else float("inf")


def _weak_ce(plant: LinearPlant, kappa: float) -> str:
    """The explanation and remedies of a weak ``C E`` (for error messages)."""
    return (
        f"C E is nearly zero for the outputs {list(plant.outputs)} (‖C‖·‖E‖ / σ_min(C E) = {kappa:.3g}): the unknown input "
        "barely reaches them within a sample, and decoupling it amplifies their noise by that factor; remedy: give this "
        "group of the bank a sensor the unknown input reaches directly, drop the group, or sample more slowly (a longer Ts)"
    )


def _in_context(exc: Exception, plant: LinearPlant) -> Exception:
    """``exc`` (a failure after the structure was built) as the same fdisyn error, naming
    the outputs the UIO was designed for and, when ``C E`` is weak, the cause and remedy.
    A ``LinAlgError`` (a singular Lyapunov or Riccati system) becomes a :class:`SolverError`."""
    kappa = ce_condition(plant)
    hint = f"; {_weak_ce(plant, kappa)}" if kappa >= CE_CONDITION_HINT else ""
    cls = type(exc) if isinstance(exc, (SolverError, CertificateError, ExistenceError)) else SolverError
    return cls(f"UIO for the outputs {list(plant.outputs)}: {exc}{hint}")


def _check_detectable(a1: np.ndarray, c: np.ndarray, plant: LinearPlant) -> None:
    bad = unobservable_modes(a1, c, region="unstable-discrete")
    if bad:
        lam = bad[0]
        raise ExistenceError(
            f"(C, A1) is not detectable: the mode λ = {lam:.6g} (|λ| = {abs(lam):.6g}) of A1 = T A "
            f"is unobservable from outputs {list(plant.outputs)} (a UIO needs (C, A1) detectable: Long & Wang 2017, section 1)"
        )


def uio_error_covariance(st: UIOStructure, L: np.ndarray, Q: np.ndarray, R: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact steady-state covariances ``(Σ, Σ_r)`` for gain ``L``.

    ``Σ = F Σ Fᵀ + T Q Tᵀ + K R Kᵀ`` with ``F = A1 − L C``,
    ``K = A1 H + L (I − C H)``; ``Σ_r = C Σ Cᵀ + (I − CH) R (I − CH)ᵀ``.
    """
    f = st.A1 - L @ C
    if spectral_radius(f) >= 1.0:
        raise ExistenceError(f"F = A1 − L C is not Schur (spectral radius {spectral_radius(f):.6g}); no steady state")
    k = st.A1 @ st.H + L @ st.Cbar
    sig = dlyap(f, st.T @ Q @ st.T.T + k @ R @ k.T)
    sig_r = C @ sig @ C.T + st.Cbar @ R @ st.Cbar.T
    return sig, 0.5 * (sig_r + sig_r.T)


@dataclass(frozen=True, eq=False)
class ReducedProblem:
    """The minimum-variance problem restricted to where the error lives.

    The optimal gain maps into ``range T`` and only the ``range(I − CH)`` part
    of the residual is nonzero, so with orthonormal bases ``V`` of ``range T``
    (``n − q`` columns) and ``Uc`` of ``range(I − CH)`` (``p − q`` columns),
    ``ε = V η``, ``L = V L̃ Ucᵀ`` and ``r̃ = Ucᵀ r`` give the regular filtering
    problem ``η⁺ = (Ā − L̃ C̃) η + w̃ − L̃ ṽ``, ``r̃ = C̃ η + ṽ`` with
    ``Ā = Vᵀ A1 V``, ``C̃ = Ucᵀ C V``, ``Q̃ = Vᵀ(T Q Tᵀ + A1 H R Hᵀ A1ᵀ)V``,
    ``R̃ = Ucᵀ(I − CH) R (I − CH)ᵀ Uc ≻ 0`` and ``S̃ = −Vᵀ A1 H R (I − CH)ᵀ Uc``.
    This deflates the singular measurement term exactly; the full-coordinate
    optimality of the result is checked separately (:func:`_stationarity`).
    """

    V: np.ndarray
    Uc: np.ndarray
    A: np.ndarray
    C: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    S: np.ndarray


def _range_basis(proj: np.ndarray, dim: int, name: str) -> np.ndarray:
    """Orthonormal basis of the range of a projector whose rank ``dim`` is known.

    A projector's singular values are 0 or ≥ 1, so the gap after the ``dim``-th
    one is the check (a generic rank tolerance can keep a round-off direction).
    """
    u, s, _ = np.linalg.svd(proj)
    if dim < s.size and s[dim] > 1e-8 * max(s[0], 1.0):
        raise ExistenceError(f"{name} is not a projector of rank {dim} (singular value {s[dim]:.3g} after the first {dim})")
    return u[:, :dim]


def _reduce(st: UIOStructure, plant: LinearPlant) -> ReducedProblem:
    q, r, c = np.asarray(plant.Q), np.asarray(plant.R), np.asarray(plant.C)
    v = _range_basis(st.T, plant.n - plant.q, "T = I − H C")
    uc = _range_basis(st.Cbar, plant.p - plant.q, "I − C H")
    qbar = st.T @ q @ st.T.T + st.A1 @ st.H @ r @ st.H.T @ st.A1.T
    rt = uc.T @ st.Cbar @ r @ st.Cbar.T @ uc
    return ReducedProblem(
        V=v,
        Uc=uc,
        A=v.T @ st.A1 @ v,
        C=uc.T @ c @ v,
        Q=0.5 * (v.T @ qbar @ v + (v.T @ qbar @ v).T),
        R=0.5 * (rt + rt.T),
        S=-v.T @ st.A1 @ st.H @ r @ st.Cbar.T @ uc,
    )


def _stationarity(st: UIOStructure, plant: LinearPlant, L: np.ndarray, sigma: np.ndarray, sigma_r: np.ndarray) -> float:
    """Relative residual of the full-coordinate optimality condition.

    ``∂ trace Σ / ∂L = 2 P (K R (I − CH)ᵀ − F Σ Cᵀ)`` with ``P ≻ 0`` the adjoint
    Lyapunov solution, so over *all* ``n × p`` gains the optimum satisfies
    ``L Σ_r = A1 Σ Cᵀ + S``, ``S = −A1 H R (I − CH)ᵀ``. A small residual
    certifies that the reduced problem's gain is optimal in the full problem.
    """
    c, r = np.asarray(plant.C), np.asarray(plant.R)
    rhs = st.A1 @ sigma @ c.T - st.A1 @ st.H @ r @ st.Cbar.T
    lhs = L @ sigma_r
    scale = np.linalg.norm(L) * np.linalg.norm(sigma_r) + np.linalg.norm(st.A1 @ sigma @ c.T) + np.linalg.norm(
        st.A1 @ st.H @ r @ st.Cbar.T
    )
    return float(np.linalg.norm(lhs - rhs) / max(scale, np.finfo(float).tiny))


@dataclass(frozen=True, eq=False)
class UIODesign:
    """A designed UIO on one (sub-)plant, with its exact covariances and certificate."""

    plant: LinearPlant
    structure: UIOStructure
    L: np.ndarray
    F: np.ndarray
    K: np.ndarray
    Sigma: np.ndarray
    """Steady-state covariance of ``ε = T x − z`` (exact Lyapunov solution)."""
    Sigma_r: np.ndarray
    """Steady-state residual covariance."""
    method: str
    variant: str
    certificate: Certificate

    def generator(self, name: str, outputs_used: Sequence[int], n_outputs: int) -> Generator:
        """The canonical form on the full output vector of ``n_outputs`` sensors.

        ``Ar = F``, ``Bu = G − K D``, ``By = K``, ``Cr = −C``, ``Du = −(I − CH) D``,
        ``Dy = I − CH`` (columns placed at ``outputs_used``).
        """
        return _canonical(self.plant, self.structure, self.L, self.Sigma, self.method, self.variant, name, outputs_used, n_outputs)


def _canonical(
    pl: LinearPlant,
    st: UIOStructure,
    L: np.ndarray,
    sigma: np.ndarray,
    method: str,
    variant: str,
    name: str,
    outputs_used: Sequence[int],
    n_outputs: int,
) -> Generator:
    idx = list(outputs_used)
    if len(idx) != pl.p:
        raise ShapeError(f"outputs_used has {len(idx)} entries; the designed plant has {pl.p} outputs")
    c, d = np.asarray(pl.C), np.asarray(pl.D)
    f = st.A1 - L @ c
    k = st.A1 @ st.H + L @ st.Cbar
    by = np.zeros((pl.n, n_outputs))
    by[:, idx] = k
    dy = np.zeros((pl.p, n_outputs))
    dy[:, idx] = st.Cbar
    matrices = {"F": f, "G": st.G, "K": k, "H": st.H, "T": st.T, "L": L, "M": st.M, "Sigma": sigma}
    return Generator.from_canonical(
        name=name,
        outputs_used=idx,
        Ar=f.copy(),
        Bu=st.G - k @ d,
        By=by,
        Cr=-c.copy(),
        Du=-st.Cbar @ d,
        Dy=dy,
        method={"name": method, "variant": variant, **matrices},
    )


def _common_checks(plant: LinearPlant, st: UIOStructure, f: np.ndarray) -> list[Check]:
    e = np.asarray(plant.E)
    te = float(np.linalg.norm(st.T @ e) / max(np.linalg.norm(e), np.finfo(float).tiny)) if e.size else 0.0
    return [
        Check("|T E| / |E|", te, DECOUPLING_TOL, "<=", "T E = 0 by construction (M C E = I); only round-off remains"),
        Check("spectral radius of F", spectral_radius(f), 1.0 - STABILITY_MARGIN, "<=", "F must be Schur stable"),
    ]


def _decoupling_checks(design_plant: LinearPlant, gen: Generator) -> list[Check]:
    internal = internal_form(gen, design_plant)
    return [
        Check(
            "internal form coupling u → r",
            internal.coupling("u"),
            DECOUPLING_TOL,
            "<=",
            "the residual must not depend on the known input; exact up to round-off",
        ),
        Check(
            "internal form coupling d → r",
            internal.coupling("d"),
            DECOUPLING_TOL,
            "<=",
            "the residual must be decoupled from the unknown input; exact up to round-off",
        ),
    ]


def _finish(
    plant: LinearPlant,
    st: UIOStructure,
    L: np.ndarray,
    method: str,
    variant: str,
    checks: list[Check],
    info: Mapping[str, object],
) -> UIODesign:
    """Exact covariances, the common checks (stability, Lyapunov, decoupling) and the design."""
    c = np.asarray(plant.C)
    f = st.A1 - L @ c
    k = st.A1 @ st.H + L @ st.Cbar
    subject = f"{method}/{variant}"
    checks = _common_checks(plant, st, f) + checks
    if spectral_radius(f) >= 1.0:
        Certificate.of(subject, checks, info).require()  # fails, naming the stability check
    sig, sig_r = uio_error_covariance(st, L, np.asarray(plant.Q), np.asarray(plant.R), c)
    lyap_res = np.linalg.norm(f @ sig @ f.T + st.T @ plant.Q @ st.T.T + k @ plant.R @ k.T - sig) / max(
        np.linalg.norm(sig), np.finfo(float).tiny
    )
    checks.append(Check("Lyapunov residual of Σ", float(lyap_res), RESIDUAL_TOL, "<=", "backward-stable solver: ~n·eps"))
    gen = _canonical(plant, st, L, sig, method, variant, "check", range(plant.p), plant.p)
    checks.extend(_decoupling_checks(plant, gen))
    info = {
        **info,
        "trace_Sigma": float(np.trace(sig)),
        "trace_Sigma_r": float(np.trace(sig_r)),
        "spectral_radius_F": spectral_radius(f),
        "eig_F": [complex(z) for z in np.linalg.eigvals(f)],
        "norm_M": float(np.linalg.norm(st.M, 2)) if st.M.size else 0.0,
        "cond_A": float(np.linalg.cond(plant.A)),
    }
    return UIODesign(
        plant=plant,
        structure=st,
        L=L,
        F=f,
        K=k,
        Sigma=sig,
        Sigma_r=sig_r,
        method=method,
        variant=variant,
        certificate=Certificate.of(subject, checks, info).require(),
    )


def kalman_uio(plant: LinearPlant, *, variant: Literal["optimal", "paper"] = "optimal") -> UIODesign:
    """Minimum-variance UIO (Hu et al. 2013, section 1.2), verified against a Riccati solution.

    ``variant="optimal"`` (default) poses the gain as the NLP
    ``min_L trace Σ  s.t.  Σ = F Σ Fᵀ + T Q Tᵀ + K R Kᵀ`` (the exact, correlated
    error covariance) on the subspace where the error lives (see
    :class:`ReducedProblem`), solved by CasADi/IPOPT with exact Hessians. The
    certificate requires (i) agreement with the stabilising solution of the
    filtering DARE with cross term, computed by the generalised Schur method,
    to :data:`GAIN_TOL`; (ii) the full-coordinate optimality condition
    ``L Σ_r = A1 Σ Cᵀ + S`` over all ``n × p`` gains; (iii) decoupling. Above
    :data:`NLP_STATES` reduced states the NLP is not solved (its time grows
    like ``n⁵·⁵``): the gain is the Riccati solution, certified by (ii) and
    (iii) (:func:`_riccati_gain`), so a bank on a 100-state plant designs in
    seconds.
    ``variant="paper"`` is the steady state of the paper's recursion (eqs. (14),
    (16)): the stabilising solution of the DARE in ``(A1, C, T Q Tᵀ + H R Hᵀ, R)``
    (the paper itself suggests taking the steady-state Kalman solution),
    certified as the recursion's fixed point; its true covariance is still the
    exact one. It is suboptimal in general — even for ``R = σ² I``, where the
    cross term vanishes, its covariance step optimises a different quantity.

    A failure after the structure is built (solver, certificate) names the
    outputs and, when ``C E`` is weak (:func:`ce_condition`), the likely cause.
    """
    if variant not in ("optimal", "paper"):
        raise ArgumentError(f"variant must be 'optimal' or 'paper'; got {variant!r}")
    work, scale = design_coordinates(plant)
    st = uio_structure(work)
    try:
        return in_user_states(_kalman_uio(work, st, variant), plant, scale)
    except (SolverError, CertificateError, ExistenceError, np.linalg.LinAlgError) as exc:
        raise _in_context(exc, work) from exc


def design_coordinates(plant: LinearPlant) -> tuple[LinearPlant, np.ndarray | None]:
    """The plant a UIO is designed on, and its state scaling (``None``: the plant as given).

    A plant the user scaled (:attr:`~fdisyn.models.linear.LinearPlant.state_scale`, the plant file's
    ``state_scale``) is designed as given; otherwise in the states of its automatic balancing
    (:meth:`~fdisyn.models.linear.LinearPlant.balancing`; as given when that is the identity, so a balanced
    plant's design is the same to the bit). Every existence condition is judged there too: ``rank E``,
    ``‖C‖‖E‖/σ_min(C E)`` and the PBH test depend on how the states are measured, the UIO does not.
    """
    if plant.state_scale is not None:
        return plant, None
    s = plant.balancing()
    if np.all(s == 1.0):
        return plant, None
    return plant.scaled(s), s


def in_user_states(d: UIODesign, plant: LinearPlant, scale: np.ndarray | None) -> UIODesign:
    """A UIO designed in scaled states ``x̃ = S⁻¹ x`` (:func:`design_coordinates`), in the user's states ``x``.

    ``ε = S ε̃``: ``F = S F̃ S⁻¹``, ``L = S L̃``, ``K = S K̃``, ``H = S H̃``, ``T = S T̃ S⁻¹``, ``G = S G̃``,
    ``Σ = S Σ̃ S``; ``M``, ``I − C H`` and ``Σ_r`` are unchanged. With ``S`` a power of two this is exact, and
    the generator's residual is the scaled design's to the bit. The certificate keeps every check of the
    scaled design and adds those of what the user runs, in the user's states: ``F`` Schur, the generator's
    transfers from ``u`` and ``d`` to the residual zero on the user's plant.
    """
    if scale is None:
        return d
    s = np.asarray(scale, dtype=float)
    st = d.structure

    def sim(m: np.ndarray) -> np.ndarray:
        return s[:, None] * m / s[None, :]

    user = UIOStructure(M=st.M, H=s[:, None] * st.H, T=sim(st.T), A1=sim(st.A1), G=s[:, None] * st.G, Cbar=st.Cbar)
    f = sim(d.F)
    gen = _canonical(plant, user, s[:, None] * d.L, s[:, None] * d.Sigma * s[None, :], d.method, d.variant, "check", range(plant.p), plant.p)
    checks = [
        *d.certificate.checks,
        Check("user's states: spectral radius of F", spectral_radius(f), 1.0 - STABILITY_MARGIN, "<=", "F must be Schur stable"),
        *(replace(c, name=f"user's states: {c.name}") for c in _decoupling_checks(plant, gen)),
    ]
    info = {**d.certificate.info, "state_scaling": s.tolist()}
    return UIODesign(
        plant=plant,
        structure=user,
        L=s[:, None] * d.L,
        F=f,
        K=s[:, None] * d.K,
        Sigma=s[:, None] * d.Sigma * s[None, :],
        Sigma_r=d.Sigma_r,
        method=d.method,
        variant=d.variant,
        certificate=Certificate.of(d.certificate.subject, checks, info).require(),
    )


def _kalman_uio(plant: LinearPlant, st: UIOStructure, variant: str) -> UIODesign:
    c, q, r = np.asarray(plant.C), np.asarray(plant.Q), np.asarray(plant.R)
    _check_sensor_noise(st, plant)
    try:
        ptruth = solve_filter_dare(st.A1, c, st.T @ q @ st.T.T + st.H @ r @ st.H.T, r)
    except (ExistenceError, SolverError) as exc:
        silent = [o for o, v in zip(plant.outputs, np.diag(r), strict=True) if v <= 0]
        if not silent:
            raise
        raise ExistenceError(
            f"the covariance recursion of Hu et al. 2013 (eqs. (14), (16)), the minimum-variance UIO's starting gain, has "
            f"no steady state: the outputs {silent} have no sensor noise (R_ii = 0); give them their noise variance in R "
            f"(R > 0 on the outputs used), or choose uio_pole_placement ({exc})"
        ) from exc
    paper = ptruth.L
    red = _reduce(st, plant)
    truth = solve_filter_dare(red.A, red.C, red.Q, red.R, red.S)
    l_truth = red.V @ truth.L @ red.Uc.T
    if variant == "paper":
        fixed, distance = _paper_recursion_check(st, c, q, r, ptruth.X)
        checks = [
            Check(
                "eqs. (14), (16): one step from the steady state P (relative change)",
                fixed,
                RESIDUAL_TOL,
                "<=",
                "the paper's steady-state gain is the fixed point of its recursion",
            ),
            Check("DARE residual", ptruth.residual, RESIDUAL_TOL, "<=", "backward-stable generalised Schur solver"),
        ]
        sig_opt, _ = uio_error_covariance(st, l_truth, q, r, c)
        paper_info: dict[str, object] = {"trace_Sigma_optimal": float(np.trace(sig_opt)), "recursion_distance_after_iterations": distance}
        return _finish(plant, st, paper, "kalman_uio", "paper", checks, paper_info)
    l_red0 = red.V.T @ paper @ red.Uc
    if red.A.shape[0] > NLP_STATES:
        return _riccati_gain(plant, st, red, truth, l_truth, paper, f"reduced problem of {red.A.shape[0]} > {NLP_STATES} states")
    if _noise_free_state(red, l_red0):
        return _riccati_gain(plant, st, red, truth, l_truth, paper, "a state of the error no noise reaches: the NLP's scaling by its variance is void")
    try:
        lt_nlp, stats = _nlp_gain(red, l_red0)
        start = "paper gain"
    except SolverError:
        # IPOPT can leave the stabilising region from the paper's gain and stop at a point of local
        # infeasibility (measured: ~1 random plant in 150); the midpoint of the paper's and the
        # Riccati gains is a second stabilising start, still not the answer itself.
        lt_nlp, stats = _nlp_gain(red, 0.5 * (l_red0 + truth.L))
        start = "midpoint of the paper and Riccati gains"
    l_nlp = red.V @ lt_nlp @ red.Uc.T
    sig_nlp, sig_r_nlp = uio_error_covariance(st, l_nlp, q, r, c)
    # the optimal value, evaluated by the same Lyapunov solver at the Riccati gain: the Riccati and
    # Lyapunov solvers alone disagree by ~cond(X)·eps (2.6e-8 at cond 7e5), which is not suboptimality
    tr_truth = float(np.trace(uio_error_covariance(st, l_truth, q, r, c)[0]))
    checks = [
        Check("gain: NLP vs analytic DARE", rel_diff(l_nlp, l_truth), GAIN_TOL, "<=", "IPOPT KKT tolerance 1e-14; the gain error is first order in it"),
        Check(
            "trace Σ: NLP vs DARE",
            abs(float(np.trace(sig_nlp)) - tr_truth) / max(tr_truth, np.finfo(float).tiny),
            GAIN_TOL,
            "<=",
            "the optimal value is trace Σ at the stabilising DARE gain (both by the same Lyapunov solver)",
        ),
        *_optimality_checks(st, plant, truth, l_nlp, sig_nlp, sig_r_nlp, "the gradient of trace Σ over all n×p gains vanishes "
                            "at the optimum; the residual scales with the gain error (≤ 1e-8) times cond(Σ_r)"),
    ]
    info: dict[str, object] = {
        "nlp_iterations": stats["iter_count"],
        "nlp_start": start,
        "nlp_status": stats["return_status"],
        "dare_residual": truth.residual,
        "paper_gain_excess_trace": float(np.trace(uio_error_covariance(st, paper, q, r, c)[0])) / max(tr_truth, 1e-300) - 1.0,
    }
    return _finish(plant, st, l_nlp, "kalman_uio", "optimal", checks, info)


def _optimality_checks(
    st: UIOStructure, plant: LinearPlant, truth: Any, L: np.ndarray, sigma: np.ndarray, sigma_r: np.ndarray, why: str
) -> list[Check]:
    """The filtering DARE's residual and the full-coordinate optimality condition at the gain ``L`` (its error
    covariances ``sigma``, ``sigma_r``; :func:`_stationarity`), ``why`` the latter's reason."""
    return [
        Check("DARE residual", truth.residual, RESIDUAL_TOL, "<=", "backward-stable generalised Schur solver"),
        Check("full-coordinate optimality L Σ_r = A1 Σ Cᵀ + S", _stationarity(st, plant, L, sigma, sigma_r), 1e-7, "<=", why),
    ]


def _noise_free_state(red: ReducedProblem, lt0: np.ndarray) -> bool:
    """Whether the error covariance at the starting gain ``lt0`` has a state of zero variance (to the floor the
    NLP scales by, :func:`_nlp_gain`): no process or sensor noise reaches it (a plant without process noise, ``Q =
    0``). The NLP's scaling by that variance is then void, while the minimum-variance gain is the Riccati one."""
    f0 = red.A - lt0 @ red.C
    if spectral_radius(f0) >= 1.0:
        return False
    d = np.diag(dlyap(f0, red.Q - red.S @ lt0.T - lt0 @ red.S.T + lt0 @ red.R @ lt0.T))
    return bool(np.min(d) <= np.finfo(float).tiny * max(1.0, float(np.max(d))))


def _riccati_gain(
    plant: LinearPlant, st: UIOStructure, red: ReducedProblem, truth: Any, l_truth: np.ndarray, paper: np.ndarray, why: str
) -> UIODesign:
    """The minimum-variance gain of a reduced problem the NLP does not solve (above :data:`NLP_STATES` states, or
    with a state no noise reaches: ``why``): the stabilising solution of the filtering DARE with cross term,
    certified by the full-coordinate optimality condition.

    ``trace Σ(L)`` over the stabilising gains has one stationary point, the Riccati gain (the steady-state
    Kalman filter's optimality; Anderson & Moore, *Optimal Filtering*, 1979, ch. 4), so the stationarity
    residual, evaluated from the exact error covariance by Lyapunov solves that share nothing with the
    Riccati solver, certifies the gain as the NLP's agreement does below that size.
    """
    c, q, r = np.asarray(plant.C), np.asarray(plant.Q), np.asarray(plant.R)
    sig, sig_r = uio_error_covariance(st, l_truth, q, r, c)
    tr = float(np.trace(sig))
    checks = _optimality_checks(st, plant, truth, l_truth, sig, sig_r, "the gradient of trace Σ over all n×p gains vanishes "
                                "only at the minimum-variance gain; the residual of the Riccati gain is round-off times cond(Σ_r)")
    info: dict[str, object] = {
        "gain_route": f"Riccati ({why}: no NLP cross-check)",
        "dare_residual": truth.residual,
        "paper_gain_excess_trace": float(np.trace(uio_error_covariance(st, paper, q, r, c)[0])) / max(tr, 1e-300) - 1.0,
    }
    return _finish(plant, st, l_truth, "kalman_uio", "optimal", checks, info)


def _check_sensor_noise(st: UIOStructure, plant: LinearPlant) -> None:
    """The minimum-variance gain needs sensor noise on every direction of the residual: ``R̃ = Ucᵀ(I − CH) R (I −
    CH)ᵀ Uc ≻ 0`` (:class:`ReducedProblem`); otherwise the DARE's pencil is singular. Refused naming the sensors
    without noise (``R_ii = 0``) and the remedies, judged relative to ``‖R‖``."""
    r = np.asarray(plant.R)
    uc = _range_basis(st.Cbar, plant.p - plant.q, "I − C H")
    rt = uc.T @ st.Cbar @ r @ st.Cbar.T @ uc
    lam = np.linalg.eigvalsh(0.5 * (rt + rt.T)) if rt.size else np.ones(1)
    if lam[0] > 1e3 * rt.shape[0] * np.finfo(float).eps * max(float(np.linalg.norm(r, 2)), np.finfo(float).tiny):
        return
    silent = [o for o, v in zip(plant.outputs, np.diag(r), strict=True) if v <= 0]
    which = f"the outputs {silent} have none (R_ii = 0)" if silent else f"R is singular on the residual's {plant.p - plant.q} directions"
    raise ExistenceError(
        f"the minimum-variance UIO needs sensor noise on every residual direction, and {which}: give those sensors "
        "their noise variance in R (R > 0 on the outputs used), or choose uio_pole_placement (no noise model)"
    )


def _paper_recursion_check(
    st: UIOStructure, c: np.ndarray, q: np.ndarray, r: np.ndarray, p_ss: np.ndarray, *, iterations: int = 20_000
) -> tuple[float, float]:
    """Hu et al. 2013, eqs. (14), (16): ``L = A1 P Cᵀ (C P Cᵀ + R)⁻¹``,
    ``P⁺ = A1 P A1ᵀ + T Q Tᵀ + H R Hᵀ − L C P A1ᵀ``.

    Returns the relative change of one step from the steady state ``p_ss`` (a
    fixed-point residual) and the relative distance to ``p_ss`` reached by
    iterating from ``P = T Q Tᵀ + H R Hᵀ`` (the paper's procedure; it
    converges at the rate ``ρ(F)²`` per step, slowly when ``F`` is nearly
    marginal, which is why the design takes the steady state directly).
    """
    a1 = st.A1
    qp = st.T @ q @ st.T.T + st.H @ r @ st.H.T

    def step(p: np.ndarray) -> np.ndarray:
        gain = np.linalg.solve((c @ p @ c.T + r).T, (a1 @ p @ c.T).T).T
        nxt = a1 @ p @ a1.T + qp - gain @ c @ p @ a1.T
        return 0.5 * (nxt + nxt.T)

    scale = max(float(np.linalg.norm(p_ss)), np.finfo(float).tiny)
    fixed = float(np.linalg.norm(step(p_ss) - p_ss)) / scale
    p = qp.copy()
    for _ in range(iterations):
        p = step(p)
        if not np.all(np.isfinite(p)):
            raise SolverError("the paper's covariance recursion diverged (non-finite P); (C, A1) may not be detectable")
    return fixed, float(np.linalg.norm(p - p_ss)) / scale


def _nlp_gain(red: ReducedProblem, lt0: np.ndarray) -> tuple[np.ndarray, dict[str, object]]:
    """``min trace Σ̃`` s.t. ``Σ̃ = F̃ Σ̃ F̃ᵀ + Q̃ − S̃ L̃ᵀ − L̃ S̃ᵀ + L̃ R̃ L̃ᵀ`` (CasADi/IPOPT).

    ``F̃ = Ā − L̃ C̃``; the noise term is ``Vᵀ(T Q Tᵀ + K R Kᵀ)V`` of the full
    problem. ``Σ̃ = W Wᵀ`` with ``W`` lower triangular and ``diag W ≥ 0``:
    the objective ``‖W‖_F²`` is bounded below and any feasible point with
    ``Σ̃ ≻ 0`` certifies that ``F̃`` is Schur, so the solver cannot drift to
    an unstable gain with an indefinite "covariance". ``Σ̃`` is scaled by its
    value at the (stabilising) start ``lt0``: ``Σ̃ = D Σ̂ D`` with
    ``D² = diag Σ̃(lt0)``, so every scaled variance starts at one.
    """
    n, nr = red.A.shape[0], red.C.shape[0]
    f0 = red.A - lt0 @ red.C
    if spectral_radius(f0) >= 1.0:
        raise SolverError("the initial gain of the minimum-variance NLP is not stabilising")
    noise0 = red.Q - red.S @ lt0.T - lt0 @ red.S.T + lt0 @ red.R @ lt0.T
    sig0 = dlyap(f0, noise0)
    # Diagonal scaling Σ̃ = D Σ̂ D with D² = diag Σ̃(lt0): every scaled variance is 1 at the start.
    dsc = np.sqrt(np.maximum(np.diag(sig0), np.finfo(float).tiny * max(1.0, float(np.max(np.diag(sig0))))))
    sig0_hat = sig0 / np.outer(dsc, dsc)
    ev = np.linalg.eigvalsh(sig0_hat)
    w0 = np.linalg.cholesky(sig0_hat + max(0.0, 1e-8 - ev[0]) * np.eye(n))
    lhat = ca.SX.sym("Lhat", n, nr)
    tri = ca.SX.sym("W_tri", n * (n + 1) // 2)
    w = ca.SX(n, n)
    k = 0
    lower_bounds = []
    start = []
    for j in range(n):
        for i in range(j, n):
            w[i, j] = tri[k]
            lower_bounds.append(0.0 if i == j else -np.inf)
            start.append(w0[i, j])
            k += 1
    dm = ca.DM(np.diag(dsc))
    dinv = ca.DM(np.diag(1.0 / dsc))
    sig_hat = ca.mtimes(w, w.T)
    a, c, q, r, s = (ca.DM(m) for m in (red.A, red.C, red.Q, red.R, red.S))
    # the gain in scaled states and innovations: L̃ = D L̂ Dₑ⁻¹ with Dₑ² = diag(C̃ Σ̃ C̃ᵀ + R̃) at the start, so
    # that sensors of different units (volts beside kelvins) give gain entries of one magnitude
    dinn = np.sqrt(np.diag(red.C @ sig0 @ red.C.T + red.R))
    lt = ca.mtimes([dm, lhat, ca.DM(np.diag(1.0 / dinn))])
    f_hat = ca.mtimes([dinv, a - ca.mtimes(lt, c), dm])  # D⁻¹ F̃ D
    noise = q - ca.mtimes(s, lt.T) - ca.mtimes(lt, s.T) + ca.mtimes([lt, r, lt.T])
    lyap = ca.mtimes([f_hat, sig_hat, f_hat.T]) + ca.mtimes([dinv, noise, dinv]) - sig_hat
    cons = ca.vertcat(*[lyap[i, j] for j in range(n) for i in range(j, n)])
    x = ca.vertcat(ca.vec(lhat), tri)
    x0 = np.concatenate([(lt0 / dsc[:, None] * dinn[None, :]).reshape(-1, order="F"), start])
    lbx = np.concatenate([np.full(n * nr, -np.inf), lower_bounds])
    opts: dict[str, Any] = {
        "print_time": False,
        "ipopt.print_level": 0,
        "ipopt.sb": "yes",
        "ipopt.tol": 1e-14,
        "ipopt.max_iter": 500,
    }
    weight = dsc**2 / float(np.sum(dsc**2))
    objective = ca.sum1(ca.mtimes(ca.DM(np.diag(weight)), ca.sum2(w * w)))  # trace Σ̃ / trace D²
    solver = ca.nlpsol("kalman_uio_gain", "ipopt", {"x": x, "f": objective, "g": cons}, opts)
    sol = solver(x0=x0, lbx=lbx, lbg=0, ubg=0)
    stats = solver.stats()
    # IPOPT may stop one step short of tol 1e-14 on badly scaled plants; its
    # point is then judged by the certificate against the Riccati solution.
    usable = {"Search_Direction_Becomes_Too_Small", "Solved_To_Acceptable_Level"}
    if not stats.get("success", False) and stats.get("return_status") not in usable:
        raise SolverError(
            f"IPOPT did not solve the minimum-variance gain NLP: {stats.get('return_status')}; "
            "check that (C, A1) is detectable and that Q, R are sensible covariances in scaled states"
        )
    xs = np.asarray(sol["x"]).reshape(-1)
    return dsc[:, None] * xs[: n * nr].reshape((n, nr), order="F") / dinn[None, :], {
        "iter_count": int(stats.get("iter_count", -1)),
        "return_status": str(stats.get("return_status")),
    }


def uio_pole_placement(plant: LinearPlant, *, poles: Sequence[complex]) -> UIODesign:
    """The plain UIO: ``L`` assigns ``eig(A1 − L C) = poles`` (the baseline of Hu et al. 2013, fig. 1).

    Uses SciPy's robust pole assignment (Kautsky–Nichols–Van Dooren) on the
    dual pair ``(A1ᵀ, Cᵀ)``. ``poles`` must lie strictly inside the unit
    circle, be closed under conjugation and number ``n``.
    """
    user_plant = plant
    plant, scale = design_coordinates(plant)
    st = uio_structure(plant)
    try:
        pl = np.asarray(poles, dtype=complex).reshape(-1)
    except (TypeError, ValueError):
        raise ArgumentError(f"poles must be {plant.n} numbers (complex ones in conjugate pairs); got {poles!r}") from None
    if pl.size != plant.n:
        raise ShapeError(f"poles: expected {plant.n} poles (one per state), got {pl.size}")
    if np.any(np.abs(pl) >= 1.0):
        raise ArgumentError(f"poles must lie strictly inside the unit circle; got moduli {np.abs(pl)}")
    c = np.asarray(plant.C)
    _check_assignable(st, c, pl, plant)
    try:
        with warnings.catch_warnings():  # KNV's "convergence was not reached": the certificate judges the poles
            warnings.simplefilter("ignore", UserWarning)
            res = scipy.signal.place_poles(st.A1.T, c.T, pl)
    except ValueError as exc:
        raise ExistenceError(f"the UIO poles {_shown_poles(pl)} cannot be assigned from the outputs {list(plant.outputs)} (SciPy: {exc})") from exc
    gain = np.asarray(res.gain_matrix).T
    achieved = np.sort_complex(np.linalg.eigvals(st.A1 - gain @ c))
    want = np.sort_complex(pl)
    err = float(np.max(np.abs(achieved - want)))
    checks = [
        Check(
            "assigned poles: max |achieved − requested|",
            err,
            1e-6,
            "<=",
            "eigenvalue sensitivity of the assigned closed loop; KNV assignment is accurate well below this",
        )
    ]
    try:
        return in_user_states(
            _finish(plant, st, gain, "uio_pole_placement", "poles", checks, {"poles": [complex(z) for z in pl]}), user_plant, scale
        )
    except (CertificateError, ExistenceError, np.linalg.LinAlgError) as exc:
        raise _in_context(exc, plant) from exc


def _shown_poles(pl: np.ndarray) -> list[float | complex]:
    return [float(z.real) if z.imag == 0 else complex(z) for z in pl]


def _check_assignable(st: UIOStructure, c: np.ndarray, pl: np.ndarray, plant: LinearPlant) -> None:
    """Refuse poles no output injection ``L`` can give ``A1 − L C``, naming why and poles that work.

    A mode of ``A1`` unobservable from ``C`` (fixed by the decoupling: an invariant zero of the plant from the
    unknown input) is an eigenvalue of ``A1 − L C`` for every ``L``; and a pole can be repeated at most
    ``rank C`` times (the multiplicity output injection can place, Kautsky, Nichols & Van Dooren, Int. J.
    Control 41(5), 1985).
    """
    want = list(pl)
    fixed = unobservable_modes(st.A1, c, region="all")
    missing = []
    for lam in fixed:
        near = [i for i, z in enumerate(want) if abs(z - lam) <= 1e-6 * max(1.0, abs(lam))]
        if near:
            want.pop(near[0])
        else:
            missing.append(lam)
    if missing:
        fix = list(pl)
        for lam in missing:
            free = [i for i in range(len(fix)) if all(abs(fix[i] - f) > 1e-6 * max(1.0, abs(f)) for f in fixed)]
            fix[min(free, key=lambda i: abs(fix[i] - lam))] = lam
        raise ExistenceError(
            f"the UIO poles {_shown_poles(pl)} cannot be assigned: the mode(s) {_shown_poles(np.asarray(missing))} of "
            f"A1 = T A are unobservable from the outputs {list(plant.outputs)} (fixed by decoupling the unknown input: "
            f"no gain moves them); list them among the poles, e.g. poles = {_shown_poles(np.asarray(fix))}"
        )
    r = rank(c)
    for z in pl:
        k = int(np.sum(np.abs(pl - z) <= 1e-12 * max(1.0, abs(z))))
        if k > r:
            raise ExistenceError(
                f"the UIO pole {_shown_poles(np.asarray([z]))[0]} is requested {k} times, but the {plant.p} outputs "
                f"{list(plant.outputs)} (rank C = {r}) can place a pole at most {r} times; give distinct poles"
            )


# --------------------------------------------------------------------------- the methods


def _poles(value: Any, where: str, plant: LinearPlant | None) -> list[float]:
    """``poles``: ``n`` real numbers strictly inside the unit circle (one per state).

    TOML has no complex numbers, so complex pairs cannot be written; a string or
    a nested list would otherwise reach NumPy's ``complex()`` and fail there.
    """
    from fdisyn.runtime.names import shown
    from fdisyn.synthesis.registry import at

    label, n = at(where, "poles"), "n" if plant is None else plant.n
    if not isinstance(value, (list, tuple)) or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in value):
        raise ArgumentError(f"{label} must be a list of {n} real numbers inside (-1, 1), one per state; got {shown(value)}")
    if plant is not None and len(value) != plant.n:
        raise ArgumentError(f"{label} must have {plant.n} poles (one per state), got {len(value)}")
    if not all(np.isfinite(x) and abs(x) < 1.0 for x in value):
        raise ArgumentError(f"{label} must lie strictly inside the unit circle (a discrete observer's poles), got {list(value)}")
    return [float(x) for x in value]


def _uio_generator(variant: str) -> Any:
    def generator(plant: LinearPlant, outputs_used: Sequence[int], name: str, **options: Any) -> tuple[Generator, np.ndarray, Certificate]:
        sub = plant.select_outputs(outputs_used)
        if variant == "poles":
            d = uio_pole_placement(sub, poles=options["poles"])
        else:
            d = kalman_uio(sub, variant=variant)  # type: ignore[arg-type]
        return d.generator(name, outputs_used, plant.p), d.Sigma_r, d.certificate

    return generator


def _register() -> None:
    from fdisyn.synthesis.linear_diagnoser import linear_method
    from fdisyn.synthesis.registry import REQUIRED, Option

    hu = "Hu, Sun, Jiang, He & Zhang 2013, Acta Automatica Sinica 39(8)"
    linear_method(
        "kalman_uio",
        summary="bank of minimum-variance unknown-input observers (exact correlated error covariance, NLP + DARE check)",
        reference=f"{hu}, eqs. (3)-(11), (14)-(16), (20)",
        generator=_uio_generator("optimal"),
    )
    linear_method(
        "kalman_uio_paper",
        summary="bank of UIOs with the gain of the paper's covariance recursion (its steady state)",
        reference=f"{hu}, eqs. (14), (16)",
        generator=_uio_generator("paper"),
    )
    linear_method(
        "uio_pole_placement",
        summary="bank of plain UIOs with assigned observer poles (the paper's baseline)",
        reference=f"{hu}, eqs. (3)-(11), fig. 1",
        generator=_uio_generator("poles"),
        options=(Option("poles", REQUIRED, "observer poles eig(A1 - L C), one per state", "one real pole inside (-1, 1) per state", refine=_poles),),
    )


_register()
