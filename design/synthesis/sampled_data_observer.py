"""Optimal diagnostic observer for sampled-data systems (Qiu, Wen & Jiang 2010).

Qiu, Wen & Jiang, "Optimal diagnostic observer for sampled-data systems",
Control Theory & Applications 27(8), 2010; equation, lemma and theorem
numbers below are theirs.

Continuous plant, sampled output, held input (eqs. (1)–(3)), in the letters of
every fdisyn plant (the paper writes ``B_u``, ``B_d``, ``B_f`` for ``B``,
``E``, ``Fx`` and ``h`` for ``Ts``)::

    ẋ = A x + B u + E d + Fx f,   y = C x,   ψ(k) = y(k Ts),   u(t) = v(k) on [k Ts, (k+1) Ts)

and the discrete diagnostic observer (eq. (6)), with fdisyn's names for the
paper's ``E`` (the input gain ``G``) and ``Q`` (the input feedthrough ``D``)::

    λ(k+1) = F λ + G v + L ψ,   r(k) = −W λ − D v + V ψ

— in fdisyn's canonical form ``Ar = F, Bu = G, By = L, Cr = −W, Du = −D,
Dy = V``. The paper's parts and where they live:

* Lemma 1, the norm-invariant discretisation ``G_J = (A_D, B_J, C, 0)``,
  ``A_D = e^{A Ts}``, ``B_J B_Jᵀ = ∫₀^Ts e^{Aτ} B Bᵀ e^{Aᵀτ} dτ``
  (:func:`~fdisyn.models.sampled_data.norm_invariant_discretisation`), and the
  step-invariant ``B_D = ∫₀^Ts e^{Aτ} dτ B`` (eq. (13), the paper's ``B_uD``);
  :class:`~fdisyn.models.sampled_data.SampledDataPlant` holds both.
* Exact sampling of continuous white noise for simulation
  (:func:`~fdisyn.simulation.sampled_data.sampled_disturbance`,
  :func:`~fdisyn.simulation.sampled_data.simulate_sampled_data`).
* Lemma 4 / eq. (20), the discrete-time algebraic Riccati system (DTARS) and the
  co-inner–outer factorisation ``G = G_o G_i``
  (:func:`~fdisyn.numerics.factorisation.solve_dtars`,
  :func:`~fdisyn.numerics.factorisation.co_inner_outer`).
* Theorem 1, here: the optimal diagnostic observer of any order ``s ≥ n``
  (:func:`optimal_diagnostic_observer`), ``design="direct"`` (the paper's
  method) or ``"indirect"`` (ZOH-discretise the plant first, the paper's
  comparison), with a :class:`~fdisyn.numerics.certificate.Certificate`.

Interpretations of the paper:

* "Hurwitz" in eq. (8) and Theorem 1 means Schur (discrete time).
* The factor ``B_J`` is not unique; fdisyn uses the full-column-rank
  eigen-factor :func:`~fdisyn.numerics.linalg.psd_factor` (``n × r``,
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
  sampled operator's kernel (see :mod:`fdisyn.numerics.norms`). Consequence: a
  design with fewer residuals than ``rank Fx_J`` (e.g. the indirect one, when
  ``q < p``) has ``‖G_rψ G_fJ‖₋ = 0`` and ``J₋ = ∞``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import scipy.linalg as sla
from fdisyn.models.sampled_data import SampledDataPlant, check_sampling
from fdisyn.numerics.certificate import Certificate, Check, worst
from fdisyn.numerics.factorisation import INNER_TOL, KAPPA_FACTOR, KAPPA_MAX, CoInnerOuter, co_inner_outer
from fdisyn.numerics.linalg import as_matrix, spectral_radius
from fdisyn.numerics.norms import DiscreteLTI, Eta, hinf_norm, hminus_index, series, system_norm
from fdisyn.runtime.errors import ArgumentError, ExistenceError, ShapeError
from fdisyn.runtime.gainfile import Generator
from fdisyn.synthesis.residual import internal_form

__all__ = ['DECOUPLING_TOL', 'DiagnosticObserver', 'ETAS', 'LUENBERGER_TOL', 'OPTIMUM_TOL', 'RESIDUAL_TOL', 'STABILITY_MARGIN', 'canonical_generator', 'error_performance', 'optimal_diagnostic_observer', 'performance', 'residual_dynamics']

ETAS: tuple[Eta, ...] = ("inf", "2", "-")

# Tolerances, each with its reason.
RESIDUAL_TOL = 1e-10
"""Relative residual of the DTARS, of the co-inner identities and of the
Luenberger equations: backward-stable computations give ~n·eps ≈ 1e-15 (times
cond(T_t) for the Luenberger equations, see :data:`LUENBERGER_TOL`, and times
κ = cond(NᵀN) where ``M`` or ``N#`` enter, see :data:`KAPPA_FACTOR`)."""
LUENBERGER_TOL = 1e-10
"""Per unit of cond(T_t): forming ``T_t F₀ T_t⁻¹`` costs ~eps·cond(T_t), and
the extra block's ``T_d`` (Krylov powers, eq. (21)) a few digits more; 1e-10
leaves ~1e4 of margin over the measured ~1e-15·cond(T_t)."""
OPTIMUM_TOL = 1e-8
"""Achieved J against J* = 1/‖G_do# G_fJ‖_η: the same quantity computed by two
routes (the order-s generator in series with G_fJ vs the order-n formula)."""
DECOUPLING_TOL = 1e-9
"""u → r coupling of the internal form: exact up to round-off (~1e-15)."""
STABILITY_MARGIN = 1e-9
"""F must be Schur: spectral radius ≤ 1 − 1e-9 (a root on the circle to round-off is not stable)."""


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
    believes in), and evaluated by :mod:`fdisyn.numerics.norms`. ``band`` restricts
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
    E: np.ndarray,
    Fx: np.ndarray,
    eta: Eta,
    band: tuple[float, float] | None = None,
) -> float:
    """Eq. (19) from the error form: ``e = T x − λ``, ``e⁺ = F e + T B w``, ``r = W e``.

    ``E`` and ``Fx`` are the discrete disturbance and fault input matrices of
    the model (``E_J``, ``Fx_J`` or ``E_D``, ``Fx_D``). Valid for any generator
    that satisfies Corollary 1's conditions (then ``G_rψ G_d = (F, T E, W, 0)``),
    also for an unstable plant, where the series realisation of
    :func:`performance` is not stable.
    """
    nr = W.shape[0]
    gd = DiscreteLTI(A=F, B=T @ E, C=W, D=np.zeros((nr, E.shape[1])))
    gf = DiscreteLTI(A=F, B=T @ Fx, C=W, D=np.zeros((nr, Fx.shape[1])))
    den = system_norm(gf, eta=eta, band=band)
    return hinf_norm(gd).value / den if den > 0 else math.inf


@dataclass(frozen=True, eq=False)
class DiagnosticObserver:
    """A sampled-data diagnostic observer (eq. (6)) with its certificate.

    ``G`` is the input gain (the paper's ``E``) and ``D`` the input
    feedthrough of the residual (the paper's ``Q``, zero in Theorem 1):
    ``λ(k+1) = F λ + G v + L ψ``, ``r(k) = −W λ − D v + V ψ``.

    ``J`` is the achieved performance on the true sampled-data system (Lemma 1's
    ``G_dJ``, ``G_fJ``) for each ``η``; ``J_star`` is the analytic optimum
    ``1/‖G_do# G_fJ‖_η`` of Theorem 1 for the model the design was made on
    (for ``design="indirect"`` that is the ZOH model, so ``J ≥ J_star`` of the
    direct design and ``J_star`` is what the indirect design *believes*).
    """

    design: str
    plant: SampledDataPlant
    F: np.ndarray
    G: np.ndarray
    L: np.ndarray
    W: np.ndarray
    V: np.ndarray
    D: np.ndarray
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
        """Canonical form ``Ar = F, Bu = G, By = L, Cr = −W, Du = −D, Dy = V`` (the gain file's ``generators``, ``runtime/REFERENCE.md``)."""
        dt = self.factorisation.dtars
        method = {"name": "sampled_data_observer", "design": self.design, "T": self.T, "X": dt.X, "M": dt.M, "N": dt.N}
        return canonical_generator(
            name=name, F=self.F, G=self.G, L=self.L, W=self.W, V=self.V, D=self.D, Ts=self.plant.Ts, method=method
        )


def canonical_generator(
    *,
    name: str,
    F: np.ndarray,
    G: np.ndarray,
    L: np.ndarray,
    W: np.ndarray,
    V: np.ndarray,
    D: np.ndarray,
    Ts: float,
    method: Mapping[str, object] | None = None,
) -> Generator:
    """Eq. (6) in canonical form: ``Ar = F, Bu = G, By = L, Cr = −W, Du = −D, Dy = V``.

    The generator's ``method`` keeps the paper's letters, as the gain file stores them:
    ``E`` (= ``G``), ``Q`` (= ``D``) and ``h`` (= ``Ts``).
    """
    meta: dict[str, object] = {"name": "sampled_data_observer", **(method or {})}
    meta.update({"F": F, "E": G, "L": L, "W": W, "V": V, "Q": D, "h": Ts})
    return Generator.from_canonical(
        name=name,
        outputs_used=range(L.shape[1]),
        Ar=np.array(F, dtype=float),
        Bu=np.array(G, dtype=float),
        By=np.array(L, dtype=float),
        Cr=-np.asarray(W, dtype=float),
        Du=-np.asarray(D, dtype=float),
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

    ``design="direct"`` factorises Lemma 1's ``G_dJ = (A_D, E_J, C, 0)``;
    ``"indirect"`` factorises the ZOH model ``(A_D, E_D, C, 0)`` (the paper's
    comparison: discretise first, then design). With ``(X, M)`` the stabilising
    DTARS solution and ``N Nᵀ = C X Cᵀ``::

        F = T_t diag(A_D + MᵀC, A_d) T_t⁻¹,   L = T_t [−Mᵀ; L_d],   T = T_t [I; T_d],
        W = [N# C, 0] T_t⁻¹,   V = N#,   G = T B_D,   D = 0

    (the paper's ``E = T B_uD``, ``Q = 0``); ``A_d`` (``(s−n) × (s−n)``,
    Schur) and ``Y`` (``(s−n) × p``) give the extra block of eq. (21); omit
    both for ``s = n``. ``T_t`` is any nonsingular ``s × s`` matrix (default
    ``I``). The certificate checks Corollary 1's
    Luenberger conditions, ``F`` Schur, the co-inner property of ``G_rψ G_d``
    (‖·‖∞ = ‖·‖₋ = 1) and the achieved ``J`` against ``J* = 1/‖G_do# G_f‖_η``
    for η ∈ {∞, 2, −}; a failed check raises
    :class:`~fdisyn.runtime.errors.CertificateError`.
    """
    if design not in ("direct", "indirect"):
        raise ArgumentError(f"design must be 'direct' or 'indirect'; got {design!r}")
    n, p = plant.n, plant.p
    check_sampling(A=plant.A, C=plant.C, Ts=plant.Ts, allow_pathological=allow_pathological)
    model: Literal["norm_invariant", "zoh"] = "norm_invariant" if design == "direct" else "zoh"
    gd = plant.G_d(model=model)
    fac = co_inner_outer(A=gd.A, B=gd.B, C=gd.C, D=gd.D)
    dt = fac.dtars
    mt, npi = dt.M.T, dt.N_pinv

    if (A_d is None) != (Y is None):
        raise ArgumentError("give both A_d and Y for an observer of order s > n (eq. (21)), or neither for s = n")
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
        raise ExistenceError(f"T_t must be nonsingular (Theorem 1); cond(T_t) = {cond_t:.3g} (expected ≤ 1e10)")
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
    G = T @ plant.B_D
    D = np.zeros((V.shape[0], plant.m))

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
        # the paper's letters, as every gain file's certificate holds them: E = G, B_uD = B_D, Q = D
        Check(
            "E − T B_uD (eq. (15))",
            rel(G - T @ plant.B_D, G),
            RESIDUAL_TOL,
            "<=",
            "E is formed as T B_uD; only round-off remains",
        ),
        Check("max |Q| (eq. (15): Q = 0)", float(np.max(np.abs(D), initial=0.0)), 0.0, "<=", "Q is set to zero exactly"),
        Check("spectral radius of F (eq. (8))", spectral_radius(F), 1.0 - STABILITY_MARGIN, "<=", "F must be Schur"),
        Check(
            "co-inner identities of G_di (Lemma 4)",
            fac.co_inner_residual(),
            tol_res,
            "<=",
            "N# C X Cᵀ N#ᵀ = I and (A + MᵀC) X Cᵀ = 0 hold exactly; round-off ~eps·κ",
        ),
    ]
    # Inner property on the order-s generator's error form (F, T E, W, 0) —
    # equal to G_rψ G_d under the Luenberger identities checked above, and
    # free of the cancellation through N# (size ~√κ) that the series
    # realisation of :func:`performance` carries. The frequency response is a route
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
            "G_rψ G_d = G_di is co-inner (Theorem 1 proof); AB13DD exact to ~1e-12, data to ~eps·κ",
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
    gen = canonical_generator(name="check", F=F, G=G, L=L, W=W, V=V, D=D, Ts=plant.Ts)
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
        j_model[eta] = error_performance(F=F, T=T, W=W, E=gd.B, Fx=gf_model.B, eta=eta)
        j_sd[eta] = error_performance(F=F, T=T, W=W, E=plant.E_J, Fx=plant.Fx_J, eta=eta)
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
        G=G,
        L=L,
        W=W,
        V=V,
        D=D,
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


# --------------------------------------------------------------------------- the methods


def _check_disturbance(plant: object, options: Mapping[str, object], where: str) -> None:
    """The design normalises by the disturbance's effect on the outputs (eq. (19)): a zero ``E`` has none."""
    from fdisyn.models.linear import LinearPlant

    if isinstance(plant, LinearPlant) and not np.any(plant.E):
        raise ExistenceError(
            f"{where}: the disturbance direction E (Bd of Qiu, Wen & Jiang 2010, eq. (1)) is zero: the sampled-data methods "
            "normalise by the disturbance's effect on the outputs (Qiu, Wen & Jiang, Control Theory & Applications 27(8), "
            "2010, eq. (19)), so they need a nonzero disturbance direction; or use a UIO method"
        )


def sampled_data_generator(observer: Callable[..., object]) -> Callable[..., tuple[Generator, np.ndarray, Certificate]]:
    """The design of one generator of a bank from a continuous plant sampled every ``Ts``.

    ``observer(plant=SampledDataPlant, **options)`` designs on the outputs used;
    the residual covariance is taken under the true sampled-data noise: the
    disturbance, white of unit intensity, sampled exactly (Van Loan) into the
    process noise of the ZOH model.
    """

    def generator(plant: object, outputs_used: Sequence[int], name: str, *, Ts: float, **options: object) -> tuple[Generator, np.ndarray, Certificate]:
        from fdisyn.models.linear import LinearPlant
        from fdisyn.models.sampling import van_loan
        from fdisyn.synthesis.residual import embed_outputs, residual_covariance

        assert isinstance(plant, LinearPlant)
        sd = SampledDataPlant.from_linear_plant(plant.select_outputs(outputs_used), Ts=Ts)
        obs: Any = observer(plant=sd, **options)
        gen = embed_outputs(obs.generator(name=name), outputs_used, plant.p)
        phys = plant.discretise(Ts)
        noise = phys.with_noise(Q=np.asarray(phys.Q) + van_loan(np.asarray(plant.A), sd.E @ sd.E.T, Ts))
        return gen, residual_covariance(gen, noise), obs.certificate

    return generator


def _register() -> None:
    from fdisyn.synthesis.linear_diagnoser import linear_method
    from fdisyn.synthesis.registry import Option

    linear_method(
        "sampled_data_observer",
        summary="optimal diagnostic observer of a continuous plant with sampled outputs (co-inner-outer factorisation)",
        reference="Qiu, Wen & Jiang 2010, Control Theory & Applications 27(8), Lemma 1, eqs. (20)-(26), Theorem 1",
        generator=sampled_data_generator(lambda *, plant, sampling: optimal_diagnostic_observer(plant=plant, design=sampling)),
        options=(
            Option(
                "sampling",
                "direct",
                "'direct': design for the sampled-data plant (Theorem 1); 'indirect': ZOH-discretise first",
                "'direct' (Theorem 1) or 'indirect' (ZOH first)",
                lambda v: v in ("direct", "indirect"),
            ),
        ),
        sampled_data=True,
        check=_check_disturbance,
    )


_register()
