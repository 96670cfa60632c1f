"""Optimal diagnostic observer for sampled-data systems (Qiu, Wen & Jiang 2010).

Qiu, Wen & Jiang, "Optimal diagnostic observer for sampled-data systems",
Control Theory & Applications 27(8), 2010; equation, lemma and theorem
numbers below are theirs.

Continuous plant, sampled output, held input (eqs. (1)–(3))::

    ẋ = A x + Bu u + Bd d + Bf f,   y = C x,   ψ(k) = y(kh),   u(t) = v(k) on [kh, (k+1)h)

and the discrete diagnostic observer (eq. (6))::

    λ(k+1) = F λ + E v + L ψ,   r(k) = −W λ − Q v + V ψ

— in fdisyn's canonical form ``Ar = F, Bu = E, By = L, Cr = −W, Du = −Q,
Dy = V``. What is here:

* Lemma 1, the norm-invariant discretisation ``G_J = (A_D, B_J, C, 0)``,
  ``A_D = e^{Ah}``, ``B_J B_Jᵀ = ∫₀ʰ e^{Aτ} B Bᵀ e^{Aᵀτ} dτ``
  (:func:`norm_invariant_discretisation`), and the step-invariant
  ``B_uD = ∫₀ʰ e^{Aτ} dτ Bu`` (eq. (13)); :class:`SampledDataPlant` holds both.
* Exact sampling of continuous white noise for simulation
  (:func:`sampled_disturbance`, :func:`simulate_sampled_data`).
* Lemma 4 / eq. (20), the discrete-time algebraic Riccati system (DTARS) and the
  co-inner–outer factorisation ``G = G_o G_i`` (:func:`solve_dtars`,
  :func:`co_inner_outer`).
* Theorem 1, the optimal diagnostic observer of any order ``s ≥ n``
  (:func:`optimal_diagnostic_observer`), ``design="direct"`` (the paper's
  method) or ``"indirect"`` (ZOH-discretise the plant first, the paper's
  comparison), with a :class:`~fdisyn.design.certificate.Certificate`.

Interpretations of the paper:

* "Hurwitz" in eq. (8) and Theorem 1 means Schur (discrete time).
* The factor ``B_J`` is not unique; fdisyn uses the full-column-rank
  eigen-factor :func:`~fdisyn.design.linalg.psd_factor` (``n × r``,
  ``r = rank``). All three measures are invariant under ``B_J → B_J U``.
* ``N_D`` with ``N_D N_Dᵀ = C X Cᵀ`` is not unique either; fdisyn takes the
  lower Cholesky factor, ``N_D# = N_D⁻¹``. The paper's printed ``V = W`` is the
  *transpose* of that ``N_D#`` (it equals ``R⁻¹`` with ``X = Rᵀ R`` MATLAB's
  upper Cholesky factor, which does not satisfy ``N Nᵀ = X``).
* In eq. (21) the first block row of ``J`` is ``a_n C A_D^{n−1} + … + a_2 C A_D
  + a_1 C`` (the paper prints ``A_D^n``; the exponent ``n − 1`` is the one
  that solves eq. (29), checked in the tests), and ``Y ∈ R^{(s−n)×p}``.
* The H₋ index is ``inf_ω σ_m`` over all ``m`` inputs, zero for a wide
  system; that is the convention under which inequality (4) and Theorem 1's
  bound hold. Lemma 1's ``‖S G‖₋`` is read on the orthogonal complement of the
  sampled operator's kernel (see :mod:`fdisyn.design.norms`). Consequence: a
  design with fewer residuals than ``rank B_fJ`` (e.g. the indirect one, when
  ``q < p``) has ``‖G_rψ G_fJ‖₋ = 0`` and ``J₋ = ∞``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import scipy.linalg as sla
from fdisyn.design.certificate import Certificate, Check, worst
from fdisyn.design.linalg import (
    as_matrix,
    normal_rank,
    psd_factor,
    rank_tol,
    spectral_radius,
    unobservable_modes,
)
from fdisyn.design.norms import DiscreteLTI, Eta, hinf_norm, hminus_index, series, system_norm
from fdisyn.design.plant import LinearPlant
from fdisyn.design.residual import internal_form
from fdisyn.design.riccati import dare_pencil_eigenvalues, solve_filter_dare
from fdisyn.design.sampling import check_sample_time, van_loan, zoh
from fdisyn.runtime.errors import ExistenceError, ShapeError, SolverError
from fdisyn.runtime.gainfile import Generator

__all__ = [
    "random_sampled_data_plant",
    "SampledDataPlant",
    "norm_invariant_discretisation",
    "check_sampling",
    "sampled_disturbance",
    "simulate_sampled_data",
    "SimulationResult",
    "Dtars",
    "solve_dtars",
    "CoInnerOuter",
    "co_inner_outer",
    "DiagnosticObserver",
    "optimal_diagnostic_observer",
    "residual_dynamics",
    "canonical_generator",
    "performance",
    "error_performance",
    "ETAS",
]

ETAS: tuple[Eta, ...] = ("inf", "2", "-")

# Tolerances, each with its reason.
RESIDUAL_TOL = 1e-10
"""Relative residual of the DTARS, of the co-inner identities and of the
Luenberger equations: backward-stable computations give ~n·eps ≈ 1e-15 (times
cond(T_t) for the Luenberger equations, see :data:`LUENBERGER_TOL`, and times
κ = cond(NᵀN) where ``M`` or ``N#`` enter, see :data:`KAPPA_FACTOR`)."""
KAPPA_FACTOR = 2e-13
"""Per unit of κ = cond(NᵀN): ``B_dJ`` (from ``expm``) is accurate to
eps·‖W_d‖, so its weakly excited directions, which ``N# = N⁻¹`` amplifies by
~√κ, carry relative errors ~eps·κ into every identity below; measured worst
6.4e-14·κ over 160 random plants (n ≤ 4, one disturbance), so 2e-13·κ."""
KAPPA_MAX = 1e10
"""Beyond κ = 1e10 the identities keep fewer than three digits (2e-13·κ >
2e-3): the disturbance barely excites some output direction within a sample
(typical with fewer disturbances than outputs and a short h), and the computed
optimum is not trustworthy. Remedies: fewer outputs, a longer h, or a
disturbance model that excites every state."""
LUENBERGER_TOL = 1e-10
"""Per unit of cond(T_t): forming ``T_t F₀ T_t⁻¹`` costs ~eps·cond(T_t), and
the extra block's ``T_d`` (Krylov powers, eq. (21)) a few digits more; 1e-10
leaves ~1e4 of margin over the measured ~1e-15·cond(T_t)."""
INNER_TOL = 1e-8
"""|‖G_rψ G_dJ‖∞ − 1| and |‖·‖₋ − 1| at κ ≲ 1e5: the sweep is exact to ~1e-12
relative and the DTARS solution to ~1e-14·κ (larger κ: see :data:`KAPPA_FACTOR`)."""
OPTIMUM_TOL = 1e-8
"""Achieved J against J* = 1/‖G_do# G_fJ‖_η: the same quantity computed by two
routes (the order-s generator in series with G_fJ vs the order-n formula)."""
DECOUPLING_TOL = 1e-9
"""u → r coupling of the internal form: exact up to round-off (~1e-15)."""
STABILITY_MARGIN = 1e-9
"""F must be Schur: spectral radius ≤ 1 − 1e-9 (a root on the circle to round-off is not stable)."""


# ---------------------------------------------------------------------------
# Lemma 1 and the sampled-data plant
# ---------------------------------------------------------------------------


def norm_invariant_discretisation(*, A: object, B: object, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lemma 1 (eq. (5)): ``(A_D, B_J, W)`` with ``‖S G‖_η = ‖G_J‖_η``.

    ``A_D = e^{Ah}``, ``W = ∫₀ʰ e^{Aτ} B Bᵀ e^{Aᵀτ} dτ`` (Van Loan's block
    exponential) and ``B_J`` the full-column-rank factor ``B_J B_Jᵀ = W``
    (:func:`~fdisyn.design.linalg.psd_factor`, ``n × rank W``). ``W`` is the
    covariance of ``∫₀ʰ e^{A(h−τ)} B dβ(τ)`` for unit-intensity white noise
    ``dβ``, which is why the same matrix gives exact noise sampling.
    """
    h = check_sample_time(h, "h")
    a = as_matrix(A, "A")
    n = a.shape[0]
    if a.shape != (n, n):
        raise ShapeError(f"A must be square; got shape {a.shape}")
    b = as_matrix(B, "B", rows=n)
    ad = sla.expm(a * h)
    w = van_loan(a, b @ b.T, h)
    return ad, psd_factor(w, "W = ∫ e^{Aτ} B Bᵀ e^{Aᵀτ} dτ"), w


@dataclass(frozen=True, eq=False)
class SampledDataPlant:
    """Eqs. (1)–(3): continuous plant, sampler, ZOH; with its discretisations.

    ``A_D``, ``B_uD`` (step-invariant, eq. (13)), ``B_dJ``, ``B_fJ`` (Lemma 1)
    and, for the paper's indirect comparison, ``B_dD``, ``B_fD`` (ZOH of the
    disturbance and fault, as if they were held between samples).
    """

    A: np.ndarray
    Bu: np.ndarray
    Bd: np.ndarray
    Bf: np.ndarray
    C: np.ndarray
    h: float
    A_D: np.ndarray
    B_uD: np.ndarray
    B_dJ: np.ndarray
    B_fJ: np.ndarray
    W_d: np.ndarray
    """``B_dJ B_dJᵀ``: also the covariance of the sampled unit-intensity disturbance."""
    W_f: np.ndarray
    B_dD: np.ndarray
    B_fD: np.ndarray

    @classmethod
    def create(cls, *, A: object, Bu: object, Bd: object, Bf: object, C: object, h: float) -> SampledDataPlant:
        """Validate (shapes, ``h > 0``) and discretise."""
        h = check_sample_time(h, "h")
        a = as_matrix(A, "A")
        n = a.shape[0]
        if a.shape != (n, n):
            raise ShapeError(f"A must be square; got shape {a.shape}")
        bu = as_matrix(Bu, "Bu", rows=n, cols=None if np.ndim(np.asarray(Bu)) == 2 else 1)
        bd = as_matrix(Bd, "Bd", rows=n, cols=None if np.ndim(np.asarray(Bd)) == 2 else 1)
        bf = as_matrix(Bf, "Bf", rows=n, cols=None if np.ndim(np.asarray(Bf)) == 2 else 1)
        c = as_matrix(C, "C", cols=n)
        ad, held = zoh(a, np.hstack([bu, bd, bf]), h)
        m, q = bu.shape[1], bd.shape[1]
        _, bdj, wd = norm_invariant_discretisation(A=a, B=bd, h=h)
        _, bfj, wf = norm_invariant_discretisation(A=a, B=bf, h=h)
        return cls(
            A=a,
            Bu=bu,
            Bd=bd,
            Bf=bf,
            C=c,
            h=h,
            A_D=ad,
            B_uD=held[:, :m],
            B_dJ=bdj,
            B_fJ=bfj,
            W_d=wd,
            W_f=wf,
            B_dD=held[:, m : m + q],
            B_fD=held[:, m + q :],
        )

    @classmethod
    def from_linear_plant(cls, plant: LinearPlant, *, h: float) -> SampledDataPlant:
        """From a continuous :class:`LinearPlant`: ``B → Bu``, ``E → Bd``, ``Fx → Bf``.

        The paper's plant is strictly proper (``D = 0``) and noise enters
        through ``d``; a nonzero ``D`` is refused rather than dropped.
        """
        if plant.is_discrete:
            raise ShapeError(f"the sampled-data design needs a continuous plant; this one has Ts = {plant.Ts}")
        if np.any(plant.D != 0):
            raise ShapeError("the sampled-data plant must be strictly proper (D = 0, Qiu, Wen & Jiang 2010, eq. (1))")
        return cls.create(A=plant.A, Bu=plant.B, Bd=plant.E, Bf=plant.Fx, C=plant.C, h=h)

    @property
    def n(self) -> int:
        return self.A.shape[0]

    @property
    def p(self) -> int:
        return self.C.shape[0]

    @property
    def m(self) -> int:
        return self.Bu.shape[1]

    def G_d(self, *, model: Literal["norm_invariant", "zoh"] = "norm_invariant") -> DiscreteLTI:
        """``G_dJ = (A_D, B_dJ, C, 0)`` (Lemma 1) or the ZOH model ``(A_D, B_dD, C, 0)``."""
        return DiscreteLTI(A=self.A_D, B=self.B_dJ if model == "norm_invariant" else self.B_dD, C=self.C, D=np.zeros((self.p, self._cols(model, "d"))))

    def G_f(self, *, model: Literal["norm_invariant", "zoh"] = "norm_invariant") -> DiscreteLTI:
        """``G_fJ = (A_D, B_fJ, C, 0)`` (Lemma 1) or the ZOH model ``(A_D, B_fD, C, 0)``."""
        return DiscreteLTI(A=self.A_D, B=self.B_fJ if model == "norm_invariant" else self.B_fD, C=self.C, D=np.zeros((self.p, self._cols(model, "f"))))

    def _cols(self, model: str, ch: str) -> int:
        if model == "norm_invariant":
            return (self.B_dJ if ch == "d" else self.B_fJ).shape[1]
        if model == "zoh":
            return (self.B_dD if ch == "d" else self.B_fD).shape[1]
        raise ShapeError(f"model must be 'norm_invariant' or 'zoh'; got {model!r}")

    def discrete_plant(self, *, model: Literal["norm_invariant", "zoh"] = "norm_invariant") -> LinearPlant:
        """The discrete :class:`LinearPlant` ``(A_D, B_uD, C, E=B_dJ or B_dD, Fx=B_fJ or B_fD, Ts=h)``."""
        e = self.B_dJ if model == "norm_invariant" else self.B_dD
        fx = self.B_fJ if model == "norm_invariant" else self.B_fD
        if model not in ("norm_invariant", "zoh"):
            raise ShapeError(f"model must be 'norm_invariant' or 'zoh'; got {model!r}")
        return LinearPlant.create(A=self.A_D, B=self.B_uD, C=self.C, E=e, Fx=fx, Ts=self.h)


# ---------------------------------------------------------------------------
# Sampling conditions (Theorem 1's assumptions)
# ---------------------------------------------------------------------------


def _nullity(mat: np.ndarray) -> int:
    s = np.linalg.svd(mat, compute_uv=False)
    tol = 1e3 * max(mat.shape) * np.finfo(float).eps * max(float(s[0]), np.finfo(float).tiny)
    return int(mat.shape[1] - np.sum(s > tol))


def _pathological_losses(a: np.ndarray, c: np.ndarray, h: float) -> list[tuple[complex, complex, int, int]]:
    """Groups of distinct eigenvalues of ``A`` that sampling maps onto one ``e^{λh}``
    *and* that lose observability doing so: ``(λ_i, λ_j, k, modes lost)`` with
    ``h (λ_i − λ_j) = 2πk·j`` (Chen & Francis, 1995, the pathological case)."""
    n = a.shape[0]
    lam = np.linalg.eigvals(a)
    ad = sla.expm(a * h)
    mu = np.exp(lam * h)
    out: list[tuple[complex, complex, int, int]] = []
    seen: set[int] = set()
    for i in range(n):
        if i in seen:
            continue
        group = [j for j in range(n) if abs(mu[j] - mu[i]) <= 1e-8 * max(1.0, abs(mu[i]))]
        seen.update(group)
        distinct: list[complex] = []
        for j in group:
            if all(abs(lam[j] - d) > 1e-8 * max(1.0, abs(d)) for d in distinct):
                distinct.append(complex(lam[j]))
        if len(distinct) < 2:
            continue
        cont = sum(_nullity(np.vstack([d * np.eye(n) - a, c.astype(complex)])) for d in distinct)
        disc = _nullity(np.vstack([mu[i] * np.eye(n) - ad, c.astype(complex)]))
        if disc > cont:
            l1, l2 = distinct[0], distinct[1]
            k = int(round(((l1 - l2) * h / (2j * math.pi)).real))
            out.append((l1, l2, k, disc - cont))
    return out


def check_sampling(*, A: object, C: object, h: float, allow_pathological: bool = False) -> None:
    """Theorem 1's assumptions on the plant and the sampling.

    Raises :class:`ExistenceError` naming the condition:

    * ``(A, C)`` not detectable (an unstable mode, ``Re λ ≥ 0``, unobservable);
    * pathological sampling: distinct eigenvalues with ``h(λ_i − λ_j) = 2πk·j``
      whose images ``e^{λh}`` coincide and become unobservable from ``C``
      (``allow_pathological=True`` accepts this when ``(A_D, C)`` stays
      detectable, i.e. only stable modes are lost);
    * ``(A_D, C)`` not detectable.

    ``h ≤ 0`` or non-finite raises :class:`ShapeError` (not a sample time).
    """
    h = check_sample_time(h, "h")
    a = as_matrix(A, "A")
    n = a.shape[0]
    if a.shape != (n, n):
        raise ShapeError(f"A must be square; got shape {a.shape}")
    c = as_matrix(C, "C", cols=n)
    bad = unobservable_modes(a, c, region="unstable-continuous")
    if bad:
        raise ExistenceError(
            f"(A, C) is not detectable: the mode(s) λ = {[complex(round(z.real, 9), round(z.imag, 9)) for z in bad]} "
            "with Re λ ≥ 0 are unobservable from C (Theorem 1 of Qiu, Wen & Jiang 2010 assumes (A, C) detectable)"
        )
    ad = sla.expm(a * h)
    undetectable = unobservable_modes(ad, c, region="unstable-discrete")
    losses = _pathological_losses(a, c, h)
    if losses and (undetectable or not allow_pathological):
        l1, l2, k, lost = losses[0]
        raise ExistenceError(
            f"pathological sampling: h = {h:g} maps the eigenvalues λ = {l1:.6g} and {l2:.6g} of A "
            f"(h(λ1 − λ2) = 2π·{k}·j) onto one eigenvalue e^(λh) = {np.exp(l1 * h):.6g} of A_D, and {lost} mode(s) "
            "become unobservable from C (Theorem 1 of Qiu, Wen & Jiang 2010 assumes non-pathological sampling); "
            "choose h with h·|Im(λ1 − λ2)| ≠ 2πk"
            + ("" if undetectable else ", or pass allow_pathological=True (the lost modes are stable)")
        )
    if undetectable:
        raise ExistenceError(
            f"(A_D, C) is not detectable: the mode(s) μ = {[complex(round(z.real, 9), round(z.imag, 9)) for z in undetectable]} "
            f"of A_D = e^(A·{h:g}) with |μ| ≥ 1 are unobservable from C"
        )


# ---------------------------------------------------------------------------
# Exact sampling of continuous white noise
# ---------------------------------------------------------------------------


def sampled_disturbance(
    *, plant: SampledDataPlant, steps: int, rng: np.random.Generator, intensity: object | None = None
) -> np.ndarray:
    """``w_k = ∫_{kh}^{(k+1)h} e^{A((k+1)h − t)} Bd dβ(t)`` for ``k < steps``; shape ``(steps, n)``.

    ``d`` is continuous white noise with intensity (power spectral density)
    ``Σ_d`` (``intensity``, default ``I``; the paper's "variance 1"). The
    ``w_k`` are independent Gaussians with covariance
    ``∫₀ʰ e^{Aτ} Bd Σ_d Bdᵀ e^{Aᵀτ} dτ`` (Van Loan), so the state at the sampling
    instants is exact — no intersample discretisation error.
    """
    q = plant.Bd.shape[1]
    sig = np.eye(q) if intensity is None else as_matrix(intensity, "intensity", rows=q, cols=q)
    cov = van_loan(plant.A, plant.Bd @ sig @ plant.Bd.T, plant.h)
    fac = psd_factor(cov, "covariance of the sampled disturbance")
    if int(steps) < 0:
        raise ShapeError(f"steps must be ≥ 0; got {steps}")
    return rng.standard_normal((int(steps), fac.shape[1])) @ fac.T


@dataclass(frozen=True, eq=False)
class SimulationResult:
    """Samples of the sampled-data plant: ``x(kh)`` and ``ψ(k) = C x(kh)``, ``k = 0..N−1``."""

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
) -> SimulationResult:
    """Exact samples of eqs. (1)–(3): ``x(k+1) = A_D x + B_uD v(k) + B_fD f(k) + w_k``.

    ``v`` has shape ``(N, m)`` and is held (ZOH, eq. (3)); ``f`` has shape
    ``(N, n_f)`` and is read as piecewise constant on ``[kh, (k+1)h)``, which is
    exact for the paper's step fault at a sampling instant; ``d`` is
    continuous white noise of intensity ``intensity`` (default ``I``), sampled
    exactly by :func:`sampled_disturbance`.
    """
    vv = as_matrix(v, "v", cols=plant.m if np.ndim(np.asarray(v)) == 2 else 1)
    if vv.shape[1] != plant.m:
        raise ShapeError(f"v has {vv.shape[1]} columns; the plant has m = {plant.m} inputs")
    steps = vv.shape[0]
    nf = plant.Bf.shape[1]
    ff = np.zeros((steps, nf)) if f is None else as_matrix(f, "f", rows=steps, cols=nf if np.ndim(np.asarray(f)) == 2 else 1)
    if ff.shape != (steps, nf):
        raise ShapeError(f"f has shape {ff.shape}; expected ({steps}, {nf})")
    x = np.zeros(plant.n) if x0 is None else as_matrix(x0, "x0", rows=plant.n, cols=1)[:, 0]
    w = sampled_disturbance(plant=plant, steps=steps, rng=rng, intensity=intensity)
    xs = np.empty((steps, plant.n))
    for k in range(steps):
        xs[k] = x
        x = plant.A_D @ x + plant.B_uD @ vv[k] + plant.B_fD @ ff[k] + w[k]
    return SimulationResult(x=xs, psi=xs @ plant.C.T)


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
    by :func:`~fdisyn.design.riccati.solve_filter_dare` (balanced extended
    pencil, which accepts ``R = 0``). When ``G`` has normal rank ``r < p`` the
    pencil is singular; then ``X`` comes from the value recursion and ``M`` is
    fixed only up to ``U₀ Z`` (``U₀`` spanning the kernel of ``C X Cᵀ + D Dᵀ``);
    fdisyn takes the least-squares ``Z`` minimising ``‖A + Mᵀ C‖_F`` (for
    ``C = I`` this gives the closed form ``M = −Aᵀ``) and requires ``A + MᵀC``
    Schur.

    Raises :class:`ExistenceError` for an undetectable ``(A, C)``, unit-circle
    invariant zeros or uncontrollable unit-circle modes of ``G`` (each named).
    """
    a = as_matrix(A, "A")
    n = a.shape[0]
    if a.shape != (n, n):
        raise ShapeError(f"A must be square; got shape {a.shape}")
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


# ---------------------------------------------------------------------------
# Theorem 1
# ---------------------------------------------------------------------------


def residual_dynamics(*, F: np.ndarray, L: np.ndarray, W: np.ndarray, V: np.ndarray) -> DiscreteLTI:
    """``G_rψ = (F, L, −W, V)``: from the sampled output ``ψ`` to the residual (eq. (11))."""
    return DiscreteLTI(A=F, B=L, C=-W, D=V)


def performance(
    *,
    plant: SampledDataPlant,
    G_rpsi: DiscreteLTI,
    eta: Eta,
    model: Literal["norm_invariant", "zoh"] = "norm_invariant",
    band: tuple[float, float] | None = None,
) -> float:
    """Eq. (19): ``J = ‖G_rψ G_dJ‖∞ / ‖G_rψ G_fJ‖_η`` (independent evaluation).

    Both products are formed as series connections of ``G_rψ`` with the plant
    (``model="norm_invariant"``: Lemma 1's ``G_dJ``, ``G_fJ`` — the true
    sampled-data performance; ``"zoh"``: the ZOH model the indirect design
    believes in), and evaluated by :mod:`fdisyn.design.norms`. ``band`` restricts
    the fault measure (``η ∈ {"inf", "-"}``); the disturbance side is always the
    whole circle. The plant must be stable (the series realisation contains
    ``A_D``).
    """
    num = hinf_norm(series(plant.G_d(model=model), G_rpsi)).value
    den = system_norm(series(plant.G_f(model=model), G_rpsi), eta=eta, band=band)
    return num / den if den > 0 else math.inf


def error_performance(
    *,
    F: np.ndarray,
    T: np.ndarray,
    W: np.ndarray,
    B_d: np.ndarray,
    B_f: np.ndarray,
    eta: Eta,
    band: tuple[float, float] | None = None,
) -> float:
    """Eq. (19) from the error form: ``e = T x − λ``, ``e⁺ = F e + T B w``, ``r = W e``.

    Valid for any generator that satisfies Corollary 1's conditions (then
    ``G_rψ G_d = (F, T B_d, W, 0)``), also for an unstable plant, where the
    series realisation of :func:`performance` is not stable.
    """
    nr = W.shape[0]
    gd = DiscreteLTI(A=F, B=T @ B_d, C=W, D=np.zeros((nr, B_d.shape[1])))
    gf = DiscreteLTI(A=F, B=T @ B_f, C=W, D=np.zeros((nr, B_f.shape[1])))
    den = system_norm(gf, eta=eta, band=band)
    return hinf_norm(gd).value / den if den > 0 else math.inf


@dataclass(frozen=True, eq=False)
class DiagnosticObserver:
    """A sampled-data diagnostic observer (eq. (6)) with its certificate.

    ``J`` is the achieved performance on the true sampled-data system (Lemma 1's
    ``G_dJ``, ``G_fJ``) for each ``η``; ``J_star`` is the analytic optimum
    ``1/‖G_do# G_fJ‖_η`` of Theorem 1 for the model the design was made on
    (for ``design="indirect"`` that is the ZOH model, so ``J ≥ J_star`` of the
    direct design and ``J_star`` is what the indirect design *believes*).
    """

    design: str
    plant: SampledDataPlant
    F: np.ndarray
    E: np.ndarray
    L: np.ndarray
    W: np.ndarray
    V: np.ndarray
    Q: np.ndarray
    T: np.ndarray
    T_t: np.ndarray
    A_d: np.ndarray
    L_d: np.ndarray
    T_d: np.ndarray
    Y: np.ndarray
    factorisation: CoInnerOuter
    J: Mapping[str, float]
    J_star: Mapping[str, float]
    certificate: Certificate
    info: Mapping[str, object] = field(default_factory=dict)

    @property
    def order(self) -> int:
        return self.F.shape[0]

    def G_rpsi(self) -> DiscreteLTI:
        """``G_rψ = (F, L, −W, V)``."""
        return residual_dynamics(F=self.F, L=self.L, W=self.W, V=self.V)

    def generator(self, *, name: str = "sampled_data_observer") -> Generator:
        """Canonical form ``Ar = F, Bu = E, By = L, Cr = −W, Du = −Q, Dy = V`` (the gain file's ``generators``, README)."""
        dt = self.factorisation.dtars
        method = {"name": "sampled_data_observer", "design": self.design, "T": self.T, "X": dt.X, "M": dt.M, "N": dt.N}
        return canonical_generator(
            name=name, F=self.F, E=self.E, L=self.L, W=self.W, V=self.V, Q=self.Q, h=self.plant.h, method=method
        )


def canonical_generator(
    *,
    name: str,
    F: np.ndarray,
    E: np.ndarray,
    L: np.ndarray,
    W: np.ndarray,
    V: np.ndarray,
    Q: np.ndarray,
    h: float,
    method: Mapping[str, object] | None = None,
) -> Generator:
    """Eq. (6) in canonical form: ``Ar = F, Bu = E, By = L, Cr = −W, Du = −Q, Dy = V``."""
    meta: dict[str, object] = {"name": "sampled_data_observer", **(method or {})}
    meta.update({"F": F, "E": E, "L": L, "W": W, "V": V, "Q": Q, "h": h})
    return Generator.from_canonical(
        name=name,
        outputs_used=range(L.shape[1]),
        Ar=np.array(F, dtype=float),
        Bu=np.array(E, dtype=float),
        By=np.array(L, dtype=float),
        Cr=-np.asarray(W, dtype=float),
        Du=-np.asarray(Q, dtype=float),
        Dy=np.array(V, dtype=float),
        method=meta,
    )


def _extra_block(a_d: np.ndarray, y: np.ndarray, ad: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eq. (21): ``L_d = −g(A_d) Y``, ``T_d = [Y, A_d Y, …, A_d^{n−1} Y] J``.

    ``g(z) = det(zI − A_D) = Σ a_j z^j``; block row ``i`` of ``J`` is
    ``Σ_{j=i+1}^{n} a_j C A_D^{j−i−1}`` (``i = 0..n−1``). Then
    ``T_d A_D − A_d T_d = L_d C`` (eq. (29)) by Cayley–Hamilton.
    """
    n = ad.shape[0]
    poly = np.real(np.poly(ad))  # [1, c1, …, cn] of z^n + c1 z^{n−1} + … + cn
    a = poly[::-1]  # a[j] multiplies z^j, a[n] = 1
    s_n = a_d.shape[0]
    g_ad = np.zeros((s_n, s_n))
    pw = np.eye(s_n)
    for j in range(n + 1):
        g_ad += a[j] * pw
        pw = pw @ a_d
    l_d = -g_ad @ y
    cpow = [c]
    for _ in range(n - 1):
        cpow.append(cpow[-1] @ ad)  # C A_D^k
    rows = []
    for i in range(n):
        rows.append(sum(a[j] * cpow[j - i - 1] for j in range(i + 1, n + 1)))
    jmat = np.vstack(rows)
    kry = [y]
    for _ in range(n - 1):
        kry.append(a_d @ kry[-1])
    t_d = np.hstack(kry) @ jmat
    return l_d, t_d


def optimal_diagnostic_observer(
    *,
    plant: SampledDataPlant,
    design: Literal["direct", "indirect"] = "direct",
    A_d: object | None = None,
    Y: object | None = None,
    T_t: object | None = None,
    allow_pathological: bool = False,
) -> DiagnosticObserver:
    """Theorem 1 (eqs. (20)–(26)): the optimal diagnostic observer of order ``s ≥ n``.

    ``design="direct"`` factorises Lemma 1's ``G_dJ = (A_D, B_dJ, C, 0)``;
    ``"indirect"`` factorises the ZOH model ``(A_D, B_dD, C, 0)`` (the paper's
    comparison: discretise first, then design). With ``(X, M)`` the stabilising
    DTARS solution and ``N Nᵀ = C X Cᵀ``::

        F = T_t diag(A_D + MᵀC, A_d) T_t⁻¹,   L = T_t [−Mᵀ; L_d],   T = T_t [I; T_d],
        W = [N# C, 0] T_t⁻¹,   V = N#,   E = T B_uD,   Q = 0,

    ``A_d`` (``(s−n) × (s−n)``, Schur) and ``Y`` (``(s−n) × p``) give the extra
    block of eq. (21); omit both for ``s = n``. ``T_t`` is any nonsingular
    ``s × s`` matrix (default ``I``). The certificate checks Corollary 1's
    Luenberger conditions, ``F`` Schur, the co-inner property of ``G_rψ G_d``
    (‖·‖∞ = ‖·‖₋ = 1) and the achieved ``J`` against ``J* = 1/‖G_do# G_f‖_η``
    for η ∈ {∞, 2, −}; a failed check raises
    :class:`~fdisyn.runtime.errors.CertificateError`.
    """
    if design not in ("direct", "indirect"):
        raise ShapeError(f"design must be 'direct' or 'indirect'; got {design!r}")
    n, p = plant.n, plant.p
    check_sampling(A=plant.A, C=plant.C, h=plant.h, allow_pathological=allow_pathological)
    model: Literal["norm_invariant", "zoh"] = "norm_invariant" if design == "direct" else "zoh"
    gd = plant.G_d(model=model)
    fac = co_inner_outer(A=gd.A, B=gd.B, C=gd.C, D=gd.D)
    dt = fac.dtars
    mt, npi = dt.M.T, dt.N_pinv

    if (A_d is None) != (Y is None):
        raise ShapeError("give both A_d and Y for an observer of order s > n (eq. (21)), or neither for s = n")
    if A_d is None:
        a_d, y = np.zeros((0, 0)), np.zeros((0, p))
    else:
        a_d = as_matrix(A_d, "A_d")
        if a_d.shape[0] != a_d.shape[1]:
            raise ShapeError(f"A_d must be square; got shape {a_d.shape}")
        y = as_matrix(Y, "Y", rows=a_d.shape[0], cols=p)
        if a_d.size and spectral_radius(a_d) >= 1.0 - STABILITY_MARGIN:
            raise ExistenceError(
                f"A_d must be Schur (eq. (21), 'Hurwitz' in the paper): spectral radius {spectral_radius(a_d):.6g} ≥ 1"
            )
    s = n + a_d.shape[0]
    if T_t is None:
        tt = np.eye(s)
    else:
        tt = as_matrix(T_t, "T_t", rows=s, cols=s)
    cond_t = float(np.linalg.cond(tt))
    if not np.isfinite(cond_t) or cond_t > 1e10:
        raise ShapeError(f"T_t must be nonsingular (Theorem 1); cond(T_t) = {cond_t:.3g} (expected ≤ 1e10)")
    tt_inv = np.linalg.inv(tt)

    l_d, t_d = _extra_block(a_d, y, plant.A_D, plant.C)
    f0 = sla.block_diag(plant.A_D + mt @ plant.C, a_d)
    l0 = np.vstack([-mt, l_d])
    t0 = np.vstack([np.eye(n), t_d])
    w0 = np.hstack([npi @ plant.C, np.zeros((npi.shape[0], s - n))])
    F = tt @ f0 @ tt_inv
    L = tt @ l0
    T = tt @ t0
    W = w0 @ tt_inv
    V = npi.copy()
    E = T @ plant.B_uD
    Q = np.zeros((V.shape[0], plant.m))

    checks: list[Check] = []
    tol_l = LUENBERGER_TOL * max(cond_t, 1.0)

    def rel(res: np.ndarray, *terms: np.ndarray) -> float:
        sc = sum(float(np.linalg.norm(t)) for t in terms)
        return float(np.linalg.norm(res)) / max(sc, np.finfo(float).tiny)

    kap = dt.kappa
    # worst(), not max(): a NaN κ must give a NaN (failing) bound, not the floor
    tol_res = worst(RESIDUAL_TOL, KAPPA_FACTOR * kap)
    tol_inner = worst(INNER_TOL, KAPPA_FACTOR * kap)
    checks += [
        Check(
            "κ = cond(Nᵀ N), N Nᵀ = C X Cᵀ",
            kap,
            KAPPA_MAX,
            "<=",
            "2e-13·κ must leave three digits in the identities below; else G_dJ is too close to rank deficient",
        ),
        Check(
            "DTARS residual (eq. (20))",
            dt.residual,
            tol_res,
            "<=",
            "backward-stable pencil solver: ~n·eps, times κ = cond(NᵀN) for the row through M",
        ),
        Check(
            "Luenberger T A_D − F T − L C (eq. (14))",
            rel(T @ plant.A_D - F @ T - L @ plant.C, T @ plant.A_D, F @ T, L @ plant.C),
            tol_l,
            "<=",
            "exact algebraically; round-off ~eps·cond(T_t) from T_t F₀ T_t⁻¹",
        ),
        Check(
            "Luenberger V C − W T (eq. (14))",
            rel(V @ plant.C - W @ T, V @ plant.C, W @ T),
            tol_l,
            "<=",
            "exact algebraically; round-off ~eps·cond(T_t)",
        ),
        Check(
            "E − T B_uD (eq. (15))",
            rel(E - T @ plant.B_uD, E),
            RESIDUAL_TOL,
            "<=",
            "E is formed as T B_uD; only round-off remains",
        ),
        Check("max |Q| (eq. (15): Q = 0)", float(np.max(np.abs(Q), initial=0.0)), 0.0, "<=", "Q is set to zero exactly"),
        Check("spectral radius of F (eq. (8))", spectral_radius(F), 1.0 - STABILITY_MARGIN, "<=", "F must be Schur"),
        Check(
            "co-inner identities of G_di (Lemma 4)",
            fac.co_inner_residual(),
            tol_res,
            "<=",
            "N# C X Cᵀ N#ᵀ = I and (A + MᵀC) X Cᵀ = 0 hold exactly; round-off ~eps·κ",
        ),
    ]
    # Inner property on the order-s generator's error form (F, T B_d, W, 0) —
    # equal to G_rψ G_d under the Luenberger identities checked above, and
    # free of the cancellation through N# (size ~√κ) that the series
    # realisation of :func:`performance` carries. The sweep is a route
    # independent of the identities below.
    gd_r = DiscreteLTI(A=F, B=T @ gd.B, C=W, D=np.zeros((V.shape[0], gd.n_in)))
    inner_max = hinf_norm(gd_r).value
    # G G~ = I  ⟺  every singular value is 1  ⟺  ‖Gᵀ‖₋ = 1 (Gᵀ is tall).
    inner_min = hminus_index(gd_r.transpose()).value
    checks += [
        Check(
            "|‖G_rψ G_d‖∞ − 1| (co-inner)",
            abs(inner_max - 1.0),
            tol_inner,
            "<=",
            "G_rψ G_d = G_di is co-inner (Theorem 1 proof); sweep exact to ~1e-12, data to ~eps·κ",
        ),
        Check(
            "|‖(G_rψ G_d)ᵀ‖₋ − 1| (all singular values 1)",
            abs(inner_min - 1.0),
            tol_inner,
            "<=",
            "co-inner: G G~ = I, so every singular value is 1 at every frequency",
        ),
    ]
    # u → r decoupling of the internal form (Corollary 1 / Lemma 2's proof).
    dplant = plant.discrete_plant(model=model)
    gen = canonical_generator(name="check", F=F, E=E, L=L, W=W, V=V, Q=Q, h=plant.h)
    checks.append(
        Check(
            "internal form coupling u → r",
            internal_form(gen, dplant).coupling("u"),
            DECOUPLING_TOL,
            "<=",
            "r must not depend on the known input v (Corollary 1); exact up to round-off",
        )
    )

    # J* of the model designed on, and achieved J on that model and on the SD system.
    gf_model = plant.G_f(model=model)
    k_sys = DiscreteLTI(A=plant.A_D + mt @ plant.C, B=gf_model.B, C=npi @ plant.C, D=np.zeros((npi.shape[0], gf_model.n_in)))
    j_star: dict[str, float] = {}
    j_model: dict[str, float] = {}
    j_sd: dict[str, float] = {}
    for eta in ETAS:
        kn = system_norm(k_sys, eta=eta)
        j_star[eta] = 1.0 / kn if kn > 0 else math.inf
        # Order-s error form (valid under the certified Corollary 1 conditions,
        # also for an unstable plant) against the order-n formula for J*.
        j_model[eta] = error_performance(F=F, T=T, W=W, B_d=gd.B, B_f=gf_model.B, eta=eta)
        j_sd[eta] = error_performance(F=F, T=T, W=W, B_d=plant.B_dJ, B_f=plant.B_fJ, eta=eta)
        both_inf = math.isinf(j_star[eta]) and math.isinf(j_model[eta])
        checks.append(
            Check(
                f"|J − J*| / J*, η = {eta}" + (" (on the ZOH model)" if design == "indirect" else ""),
                0.0 if both_inf else abs(j_model[eta] - j_star[eta]) / j_star[eta],
                worst(OPTIMUM_TOL, KAPPA_FACTOR * kap),
                "<=",
                "Theorem 1: the design attains J* = 1/‖G_do# G_f‖_η; the order-s generator and the "
                "order-n formula must agree",
            )
        )
    info = {
        "design": design,
        "order": s,
        "dtars_method": dt.method,
        "dtars_rank": dt.rank,
        "kappa": kap,
        "cond_T_t": cond_t,
        "spectral_radius_F": spectral_radius(F),
        "J_sampled_data": dict(j_sd),
        "J_on_design_model": dict(j_model),
        "J_star": dict(j_star),
        "hinf_G_rpsi_G_d": inner_max,
        "hminus_G_rpsi_G_d": inner_min,
    }
    cert = Certificate.of(f"sampled_data_observer/{design}", checks, info).require()
    return DiagnosticObserver(
        design=design,
        plant=plant,
        F=F,
        E=E,
        L=L,
        W=W,
        V=V,
        Q=Q,
        T=T,
        T_t=tt,
        A_d=a_d,
        L_d=l_d,
        T_d=t_d,
        Y=y,
        factorisation=fac,
        J=j_sd,
        J_star=j_star,
        certificate=cert,
        info=info,
    )


def random_sampled_data_plant(
    *, n: int, p: int, rng: np.random.Generator, q: int = 1, h: float = 0.5, stable: bool = True
) -> SampledDataPlant:
    """A random continuous plant with ``n`` states, ``p`` outputs, 1 input, ``q`` disturbances, 1 fault.

    With ``q = 1`` the lifted disturbance barely excites some directions within
    a sample and κ = cond(C X Cᵀ) can pass 1e10 already at ``n = p = 3``;
    ``q = n`` keeps it moderate (≤ ~1e6 at n = 16 in the timing runs).

    Eigenvalues ``−U(0.3, 2)`` or ``−U(0.3, 2) ± j·U(0.1, 1.5)`` in a random
    basis of condition ≤ 4; with ``|Im λ| < 1.5`` and ``h = 0.5`` the sampling is
    never pathological (that needs ``h·|Im(λ_i − λ_j)| = 2πk``).
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
        Bu=rng.standard_normal((n, 1)),
        Bd=rng.standard_normal((n, q)),
        Bf=rng.standard_normal((n, 1)),
        C=rng.standard_normal((p, n)),
        h=h,
    )
