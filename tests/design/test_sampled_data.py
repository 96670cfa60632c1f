"""Qiu, Wen & Jiang, Control Theory & Applications 27(8), 2010: Lemma 1, Lemma 4 (DTARS, co-inner–outer)
and Theorem 1 against independent truths."""

from __future__ import annotations

import math

import control
import numpy as np
import pytest
import scipy.integrate as sint
import scipy.linalg as sla
import scipy.optimize
from fdisyn.app.bench import random_sampled_data_plant
from fdisyn.simulation.sampled_data import sampled_disturbance, simulate_sampled_data
from fdisyn.models.linear import LinearPlant
from fdisyn.models.sampled_data import SampledDataPlant, check_sampling, norm_invariant_discretisation
from fdisyn.numerics.factorisation import co_inner_outer, solve_dtars
from fdisyn.numerics.linalg import spectral_radius
from fdisyn.numerics.norms import DiscreteLTI, h2_norm, hinf_norm
from fdisyn.numerics.riccati import solve_filter_dare
from fdisyn.problems.sampled_data_example import PAPER, PAPER_GAINS
from fdisyn.runtime.errors import ArgumentError, CertificateError, ExistenceError, ShapeError
from fdisyn.synthesis.residual import internal_form
from fdisyn.synthesis.sampled_data_observer import ETAS, _extra_block, optimal_diagnostic_observer, performance, residual_dynamics
from hypothesis import given, settings
from hypothesis import strategies as st

# Grid of frequencies (rad/sample) for transfer-function identities.
W_TEST = np.array([0.0, 0.3, 1.1, 2.0, math.pi])


# ---------------------------------------------------------------------------
# Lemma 1
# ---------------------------------------------------------------------------


@settings(derandomize=True, max_examples=8, deadline=None)
@given(n=st.integers(1, 4), q=st.integers(1, 2), ts=st.floats(0.05, 2.0), seed=st.integers(0, 2**16))
def test_lemma1_gramian_is_the_integral(n: int, q: int, ts: float, seed: int) -> None:
    """``W = ∫₀ʰ e^{Aτ} B Bᵀ e^{Aᵀτ} dτ`` by adaptive quadrature (any A, stable or not)."""
    rng = np.random.default_rng(seed)
    a, b = rng.standard_normal((n, n)), rng.standard_normal((n, q))
    ad, bj, w = norm_invariant_discretisation(A=a, B=b, Ts=ts)
    ref, _ = sint.quad_vec(lambda t: sla.expm(a * t) @ b @ b.T @ sla.expm(a.T * t), 0.0, ts, epsabs=1e-14, epsrel=1e-12)
    # Quadrature is asked for 1e-12 relative; expm for ~1e-15.
    assert np.linalg.norm(w - ref) <= 1e-10 * np.linalg.norm(ref)
    assert np.linalg.norm(bj @ bj.T - w) <= 1e-13 * np.linalg.norm(w)
    assert np.linalg.norm(ad - sla.expm(a * ts)) == 0.0


def test_lemma1_rank_deficient_gramian_gives_fewer_columns() -> None:
    """An uncontrollable mode: ``B_J`` has ``rank W`` columns, not ``n`` (zero columns would zero H₋)."""
    a = np.diag([-1.0, -2.0, -3.0])
    b = np.array([[1.0], [1.0], [0.0]])  # third mode not excited
    _, bj, w = norm_invariant_discretisation(A=a, B=b, Ts=0.7)
    assert bj.shape == (3, 2)
    assert np.linalg.norm(bj @ bj.T - w) <= 1e-14 * np.linalg.norm(w)
    assert np.all(bj[2] == 0.0) or np.max(np.abs(bj[2])) <= 1e-16


@settings(derandomize=True, max_examples=10, deadline=None)
@given(n=st.integers(1, 4), p=st.integers(1, 2), ts=st.floats(0.1, 2.0), seed=st.integers(0, 2**16))
def test_lemma1_h2_is_the_continuous_h2_norm(n: int, p: int, ts: float, seed: int) -> None:
    """``Σ_k A_D^k W A_Dᵀ^k = ∫₀^∞ e^{At}BBᵀe^{Aᵀt}dt``, so ``‖G_J‖₂ = ‖G‖_H2`` of the continuous plant (slycot)."""
    pl = random_sampled_data_plant(rng=np.random.default_rng(seed), n=n, p=p, q=n, Ts=ts)
    ref = control.norm(control.ss(pl.A, pl.E, pl.C, np.zeros((p, pl.E.shape[1]))), 2)
    assert abs(h2_norm(pl.G_d()) - ref) <= 1e-9 * ref  # two Lyapunov solves, ~1e-13 each


def test_lemma1_hinf_is_the_limit_of_piecewise_constant_inputs(paper_plant: SampledDataPlant) -> None:
    """The lifting argument behind Lemma 1, checked directly.

    Inputs piecewise constant on ``N`` subintervals of ``[k Ts, (k+1) Ts)`` give the
    discrete system ``(A_D, B_N, C, 0)`` with ``B_N B_Nᵀ = 𝔅 Π_N 𝔅* ⪯ W``; so its
    H∞ norm is below ``‖G_J‖∞`` and converges to it as ``N → ∞`` (the
    Riemann error is O(1/N²)).
    """
    pl = paper_plant
    gaps = []
    for nsub in (8, 16, 32, 64):
        dt = pl.Ts / nsub
        cols = []
        # ∫₀^δ e^{As} ds E, the ZOH input matrix of one subinterval.
        phi = sla.expm(np.block([[pl.A, pl.E], [np.zeros((1, 3))]]) * dt)[:2, 2:]
        for i in range(nsub):
            # ∫ over [iδ, (i+1)δ] of e^{A(Ts−τ)} E dτ, per unit L2 norm of the input (÷√δ).
            cols.append(sla.expm(pl.A * (pl.Ts - (i + 1) * dt)) @ phi / math.sqrt(dt))
        bn = np.hstack(cols)
        deficit = np.linalg.eigvalsh(pl.W_E - bn @ bn.T)
        assert deficit.min() >= -1e-14  # W − B_N B_Nᵀ ⪰ 0 (a projection of the lifted input)
        gn = DiscreteLTI(A=pl.A_D, B=bn, C=pl.C, D=np.zeros((2, nsub)))
        gaps.append(hinf_norm(pl.G_d()).value - hinf_norm(gn).value)
    assert all(g >= -1e-12 for g in gaps)
    # O(1/N²): each halving of δ shrinks the gap by ≈ 4 (3.5 allows higher-order terms).
    assert all(gaps[i] / gaps[i + 1] > 3.5 for i in range(len(gaps) - 1))
    assert gaps[-1] <= 1e-4 * hinf_norm(pl.G_d()).value


def test_step_invariant_input_matrix_matches_the_ode(paper_plant: SampledDataPlant) -> None:
    """``B_D``: state after one held unit step from rest, by an ODE solver, and in closed form."""
    pl = paper_plant
    sol = sint.solve_ivp(lambda t, x: pl.A @ x + pl.B[:, 0], (0.0, pl.Ts), np.zeros(2), rtol=1e-12, atol=1e-14)
    assert np.linalg.norm(sol.y[:, -1] - pl.B_D[:, 0]) <= 1e-10  # solver asked for 1e-12 relative
    e1, e2 = math.exp(-1.0), math.exp(-2.0)
    closed = np.array([5 * (1 - e1) - 2.5 * (1 - e2), 0.5 * (1 - e2)])
    assert np.linalg.norm(pl.B_D[:, 0] - closed) <= 1e-14  # expm: a few ulps
    assert np.linalg.norm(pl.A_D - np.array([[e1, 5 * (e1 - e2)], [0.0, e2]])) <= 1e-14


def test_simulation_matches_the_ode_and_samples_noise_exactly(paper_plant: SampledDataPlant) -> None:
    pl = paper_plant
    steps = 8
    v = np.ones((steps, 1))
    f = np.zeros((steps, 1))
    f[3:] = 10.0  # step fault at the fourth sampling instant
    sim = simulate_sampled_data(plant=pl, v=v, f=f, intensity=np.zeros((1, 1)), rng=np.random.default_rng(0))

    def rhs(t: float, x: np.ndarray) -> np.ndarray:
        return pl.A @ x + pl.B[:, 0] * 1.0 + pl.Fx[:, 0] * (10.0 if t >= 3 * pl.Ts else 0.0)

    sol = sint.solve_ivp(rhs, (0.0, (steps - 1) * pl.Ts), np.zeros(2), t_eval=np.arange(steps) * pl.Ts, rtol=1e-11, atol=1e-13, max_step=0.05)
    assert np.max(np.abs(sim.psi - sol.y.T)) <= 1e-8  # ODE tolerance 1e-11 over 7 s with a jump

    # Exact noise sampling: the sample covariance of w_k is W_E (Wishart: relative
    # s.d. ≈ √(2/N) = 0.006 at N = 50 000; 5 s.d. = 0.03).
    w = sampled_disturbance(plant=pl, steps=50_000, rng=np.random.default_rng(1))
    cov = w.T @ w / w.shape[0]
    assert np.max(np.abs(cov - pl.W_E)) <= 0.03 * np.max(np.abs(pl.W_E))


# ---------------------------------------------------------------------------
# Lemma 4: DTARS and co-inner–outer factorisation
# ---------------------------------------------------------------------------


def _factorisation_identities(g: DiscreteLTI) -> None:
    fac = co_inner_outer(A=g.A, B=g.B, C=g.C, D=g.D)
    prod = fac.G_o.freqresp(W_TEST) @ fac.G_i.freqresp(W_TEST)
    ref = g.freqresp(W_TEST)
    assert np.max(np.abs(prod - ref)) <= 1e-9 * max(np.max(np.abs(ref)), 1.0)  # G = G_o G_i
    gi = fac.G_i.freqresp(W_TEST)
    eye = np.eye(fac.G_i.n_out)
    assert np.max(np.abs(gi @ np.conj(np.swapaxes(gi, 1, 2)) - eye)) <= 1e-9  # co-inner on the circle
    left = fac.G_o_pinv.freqresp(W_TEST) @ fac.G_o.freqresp(W_TEST)
    assert np.max(np.abs(left - np.eye(fac.G_o.n_in))) <= 1e-9  # G_o# G_o = I
    assert spectral_radius(fac.G_o_pinv.A) < 1.0  # G_o# (and G_i) stable
    assert fac.dtars.residual <= 1e-12
    assert fac.co_inner_residual() <= 1e-10


@settings(derandomize=True, max_examples=15, deadline=None)
@given(n=st.integers(1, 5), p=st.integers(1, 3), extra=st.integers(0, 2), seed=st.integers(0, 2**16))
def test_lemma4_with_full_rank_d_matches_scipy(n: int, p: int, extra: int, seed: int) -> None:
    """``D Dᵀ ≻ 0``: the DTARS is an ordinary filtering DARE, which SciPy solves too."""
    rng = np.random.default_rng(seed)
    m = p + extra
    a = rng.standard_normal((n, n))
    a *= 0.9 / max(np.abs(np.linalg.eigvals(a)))
    g = DiscreteLTI.create(A=a, B=rng.standard_normal((n, m)), C=rng.standard_normal((p, n)), D=rng.standard_normal((p, m)))
    dt = solve_dtars(A=g.A, B=g.B, C=g.C, D=g.D)
    ref = sla.solve_discrete_are(g.A.T, g.C.T, g.B @ g.B.T, g.D @ g.D.T, s=g.B @ g.D.T)
    assert np.linalg.norm(dt.X - ref) <= 1e-9 * max(np.linalg.norm(ref), 1.0)  # two backward-stable solvers
    _factorisation_identities(g)


@settings(derandomize=True, max_examples=15, deadline=None)
@given(n=st.integers(2, 5), p=st.integers(1, 3), seed=st.integers(0, 2**16), unstable=st.booleans())
def test_lemma4_strictly_proper_wide(n: int, p: int, seed: int, unstable: bool) -> None:
    """``D = 0`` (the sampled-data case, R = 0) with ``m ≥ p`` inputs, stable or not."""
    rng = np.random.default_rng(seed)
    p = min(p, n)
    a = rng.standard_normal((n, n))
    a *= (1.3 if unstable else 0.9) / max(np.abs(np.linalg.eigvals(a)))
    g = DiscreteLTI.create(A=a, B=rng.standard_normal((n, n)), C=rng.standard_normal((p, n)))
    fac = co_inner_outer(A=g.A, B=g.B, C=g.C)
    assert fac.dtars.method == "extended pencil"
    _factorisation_identities(g)


@settings(derandomize=True, max_examples=15, deadline=None)
@given(n=st.integers(1, 4), q=st.integers(1, 3), ts=st.floats(0.1, 2.0), seed=st.integers(0, 2**16))
def test_dtars_closed_form_with_identity_output(n: int, q: int, ts: float, seed: int) -> None:
    """``C = I``: ``X = E_J E_Jᵀ``, ``M = −A_Dᵀ`` (eq. (20) with ``C = I``: ``M = −A_Dᵀ`` solves the second
    block row ``X A_Dᵀ + X M = 0``, and the first then reduces to ``X = E_J E_Jᵀ``), whether ``E_J`` has
    rank n or less."""
    rng = np.random.default_rng(seed)
    pl = SampledDataPlant.create(
        A=rng.standard_normal((n, n)), B=np.zeros((n, 1)), E=rng.standard_normal((n, q)), Fx=np.ones((n, 1)), C=np.eye(n), Ts=ts
    )
    for model in ("norm_invariant", "zoh"):
        g = pl.G_d(model=model)
        dt = solve_dtars(A=g.A, B=g.B, C=g.C)
        x_ref = g.B @ g.B.T
        assert np.linalg.norm(dt.X - x_ref) <= 1e-10 * max(np.linalg.norm(x_ref), 1e-300)
        # M = −(CXCᵀ)⁻¹ C X Aᵀ has forward error ~eps·κ (κ up to 1e9 for q < n).
        assert np.linalg.norm(dt.M + pl.A_D.T) <= 1e-14 * max(dt.kappa, 1e4) * max(np.linalg.norm(pl.A_D), 1.0)


def test_singular_dtars_is_the_limit_of_regular_ones() -> None:
    """Normal rank < p (tall G): the value-recursion X equals ``lim_{ε→0}`` of the DARE with ``R = ε² I``.

    ``X_ε − X = O(ε²)`` here (one disturbance seen through ``C B`` of full
    column rank), so ε = 1e-4 leaves ~1e-8.
    """
    rng = np.random.default_rng(11)
    a = rng.standard_normal((4, 4))
    a *= 0.8 / max(np.abs(np.linalg.eigvals(a)))
    b = rng.standard_normal((4, 1))
    c = rng.standard_normal((3, 4))
    g = DiscreteLTI.create(A=a, B=b, C=c)
    fac = co_inner_outer(A=a, B=b, C=c)
    assert fac.dtars.method == "value recursion" and fac.dtars.rank == 1
    eps = 1e-4
    ref = solve_filter_dare(a, c, b @ b.T, eps**2 * np.eye(3)).X
    assert np.linalg.norm(fac.dtars.X - ref) <= 1e-6 * np.linalg.norm(ref)
    _factorisation_identities(g)


def test_unit_circle_zeros_are_named() -> None:
    # G(z) = (z − 1)/((z − 0.5)(z − 0.3)) = −2.5/(z − 0.5) + 3.5/(z − 0.3): a zero at z = 1.
    a, b, c = np.diag([0.5, 0.3]), np.ones((2, 1)), np.array([[-2.5, 3.5]])
    with pytest.raises(ExistenceError, match=r"invariant zero\(s\) on the unit circle at z = \[\(1\+0j\)\]"):
        solve_dtars(A=a, B=b, C=c)
    # A complex pair of zeros at e^{±jπ/3}: numerator z² − z + 1.
    num = np.array([1.0, -1.0, 1.0])
    den = np.poly([0.5, 0.2, -0.4])
    ss = control.tf2ss(control.tf(num, den, dt=1))
    with pytest.raises(ExistenceError, match=r"invariant zero\(s\) on the unit circle at z = \[\(0\.5-0\.866025j\), \(0\.5\+0\.866025j\)\]"):
        co_inner_outer(A=ss.A, B=ss.B, C=ss.C, D=ss.D)


def test_undetectable_discrete_pair_is_named() -> None:
    with pytest.raises(ExistenceError, match=r"\(A, C\) is not detectable: mode\(s\) \[\(1\.5\+0j\)\]"):
        solve_dtars(A=np.diag([1.5, 0.5]), B=np.eye(2), C=np.array([[0.0, 1.0]]))


# ---------------------------------------------------------------------------
# Theorem 1 on the paper's example
# ---------------------------------------------------------------------------


def test_paper_example_closed_forms_and_optimum(paper_plant: SampledDataPlant) -> None:
    pl = paper_plant
    ob = optimal_diagnostic_observer(plant=pl)
    dt = ob.factorisation.dtars
    # C = I: X = E_J E_Jᵀ = W_E, M = −A_Dᵀ, so F = A_D + MᵀC = 0 and L = A_D.
    assert np.linalg.norm(dt.X - pl.W_E) <= 1e-13
    assert np.linalg.norm(dt.M + pl.A_D.T) <= 1e-13
    assert np.max(np.abs(ob.F)) <= 1e-14  # the paper prints F ≈ 1e-16
    assert np.linalg.norm(ob.L - pl.A_D) <= 1e-13
    # J* without the DTARS: with C = I, G_do# G_fJ = z⁻¹ N# Fx_J, whose squared
    # singular values are the generalised eigenvalues of (W_Fx, W_E).
    lam = np.sort(sla.eigvalsh(pl.W_Fx, pl.W_E))
    closed = {"inf": 1 / math.sqrt(lam[-1]), "2": 1 / math.sqrt(lam.sum()), "-": 1 / math.sqrt(lam[0])}
    for eta in ETAS:
        assert abs(ob.J[eta] - closed[eta]) <= 1e-12 * closed[eta]
        assert abs(ob.J_star[eta] - closed[eta]) <= 1e-12 * closed[eta]


def test_paper_printed_gains_rounded_and_transposed(paper_plant: SampledDataPlant) -> None:
    """The paper's gains, to its two printed decimals, with two interpretations.

    * ``L[0, 0] = e⁻¹ = 0.3679`` is printed 0.38 (a rounding slip); the other
      entries round to the printed ones.
    * The printed ``V = W`` is the transpose of ``N#`` for the lower Cholesky
      factor ``N`` of ``X`` — equivalently MATLAB's ``inv(chol(X))``, which
      does not satisfy ``N Nᵀ = X``. Every valid ``V`` has ``VᵀV = X⁻¹``; the
      printed one has ``V Vᵀ = X⁻¹`` instead.
    """
    ob = optimal_diagnostic_observer(plant=paper_plant)
    L = ob.L
    mask = np.ones((2, 2), bool)
    mask[0, 0] = False
    assert np.all(np.abs(L - PAPER_GAINS["L"])[mask] <= 0.005)
    assert abs(L[0, 0] - math.exp(-1)) <= 1e-15 and abs(PAPER_GAINS["L"][0, 0] - 0.38) == 0.0
    assert np.all(np.abs(ob.G - PAPER_GAINS["E"]) <= 0.005)
    assert np.all(np.abs(ob.V.T - PAPER_GAINS["V"]) <= 0.005)
    assert np.all(np.abs(ob.W.T - PAPER_GAINS["W"]) <= 0.005)
    xinv = np.linalg.inv(ob.factorisation.dtars.X)
    vp = PAPER_GAINS["V"]
    assert np.max(np.abs(vp @ vp.T - xinv)) <= 0.03  # printed-precision agreement
    assert np.max(np.abs(vp.T @ vp - xinv)) > 1.0  # the untransposed reading is far off
    # What the printed gains achieve, as printed and with V transposed back.
    as_printed = residual_dynamics(F=np.zeros((2, 2)), L=PAPER_GAINS["L"], W=vp, V=vp)
    transposed = residual_dynamics(F=np.zeros((2, 2)), L=PAPER_GAINS["L"], W=vp.T, V=vp.T)
    for eta in ETAS:
        assert performance(plant=paper_plant, G_rpsi=as_printed, eta=eta) > ob.J_star[eta] * 1.04
        assert performance(plant=paper_plant, G_rpsi=transposed, eta=eta) < ob.J_star[eta] * 1.05


def test_indirect_design_is_worse_on_the_sampled_data_system(paper_plant: SampledDataPlant) -> None:
    direct = optimal_diagnostic_observer(plant=paper_plant)
    indirect = optimal_diagnostic_observer(plant=paper_plant, design="indirect")
    # q = 1 < p = 2: the ZOH model is tall, its DTARS singular, one residual.
    assert indirect.factorisation.dtars.method == "value recursion"
    assert indirect.V.shape == (1, 2)
    # Theorem 1 on the true sampled-data system: nothing beats the direct design.
    for eta in ETAS:
        assert indirect.J[eta] >= direct.J_star[eta] * (1 - 1e-12)
    assert indirect.J["inf"] > direct.J["inf"] * 1.05
    assert indirect.J["2"] > direct.J["2"] * 1.4
    # One residual and two lifted fault inputs: ‖G_rψ G_fJ‖₋ = 0.
    assert indirect.J["-"] == math.inf


# ---------------------------------------------------------------------------
# Theorem 1 in general
# ---------------------------------------------------------------------------


@settings(derandomize=True, max_examples=10, deadline=None)
@given(n=st.integers(2, 4), p=st.integers(1, 3), extra=st.integers(0, 3), seed=st.integers(0, 2**16), unstable=st.booleans())
def test_theorem1_any_order_any_basis(n: int, p: int, extra: int, seed: int, unstable: bool) -> None:
    """Order ``s = n + extra``, random Schur ``A_d``, ``Y``, ``T_t``: certified, and the same ``G_rψ``."""
    rng = np.random.default_rng(seed)
    p = min(p, n)
    pl = random_sampled_data_plant(rng=rng, n=n, p=p, q=n, stable=not unstable)
    base = optimal_diagnostic_observer(plant=pl)
    if extra:
        a_d = rng.standard_normal((extra, extra))
        a_d *= 0.8 / max(np.abs(np.linalg.eigvals(a_d)))
        y = rng.standard_normal((extra, p))
        tt = rng.standard_normal((n + extra, n + extra)) + 2 * np.eye(n + extra)
        ob = optimal_diagnostic_observer(plant=pl, A_d=a_d, Y=y, T_t=tt)
    else:
        ob = optimal_diagnostic_observer(plant=pl, T_t=rng.standard_normal((n, n)) + 2 * np.eye(n))
    assert ob.order == n + extra
    # The extra block and T_t change the realisation, not the transfer function
    # (eq. (23)); round-off ~eps·cond(T_t)·κ.
    tol = 1e-13 * max(ob.factorisation.dtars.kappa, 1e4) * np.linalg.cond(ob.T_t)
    # Corollary 1's conditions and stability, recomputed here (the certificate's own values
    # cannot fail this test: a failed certificate raises before)
    ad, c = pl.A_D, pl.C
    assert np.linalg.norm(ob.T @ ad - ob.F @ ob.T - ob.L @ c) <= tol * (np.linalg.norm(ob.T @ ad) + np.linalg.norm(ob.L @ c))
    assert np.linalg.norm(ob.V @ c - ob.W @ ob.T) <= tol * np.linalg.norm(ob.V @ c)
    assert max(abs(np.linalg.eigvals(ob.F))) < 1.0
    g1, g0 = ob.G_rpsi().freqresp(W_TEST), base.G_rpsi().freqresp(W_TEST)
    assert np.max(np.abs(g1 - g0)) <= tol * np.max(np.abs(g0))
    for eta in ETAS:
        if math.isinf(base.J[eta]):  # η = "-" with p < rank Fx_J: ‖G_rψ G_fJ‖₋ = 0
            assert math.isinf(ob.J[eta])
        else:
            assert abs(ob.J[eta] - base.J[eta]) <= tol * base.J[eta]


def test_eq21_solves_eq29_and_the_printed_exponent_does_not() -> None:
    """``T_d A_D − A_d T_d = L_d C`` with the exponent ``n − 1`` in ``J``'s first row; SciPy's Sylvester agrees."""
    rng = np.random.default_rng(4)
    ad = 0.5 * rng.standard_normal((3, 3))
    c = rng.standard_normal((2, 3))
    a_d = np.diag([0.3, -0.6])
    y = rng.standard_normal((2, 2))
    l_d, t_d = _extra_block(a_d, y, ad, c)
    assert np.linalg.norm(t_d @ ad - a_d @ t_d - l_d @ c) <= 1e-13 * np.linalg.norm(t_d)
    ref = sla.solve_sylvester(-a_d, ad, l_d @ c)
    assert np.linalg.norm(t_d - ref) <= 1e-12 * np.linalg.norm(ref)
    # The printed first row a_n C A_D^n + … + a_1 C (one power too many) fails (29).
    a = np.real(np.poly(ad))[::-1]
    row0 = sum(a[j] * c @ np.linalg.matrix_power(ad, j) for j in range(1, 4))
    rows = [row0] + [sum(a[j] * c @ np.linalg.matrix_power(ad, j - i - 1) for j in range(i + 1, 4)) for i in (1, 2)]
    t_bad = np.hstack([y, a_d @ y, a_d @ a_d @ y]) @ np.vstack(rows)
    assert np.linalg.norm(t_bad @ ad - a_d @ t_bad - l_d @ c) > 1e-2 * np.linalg.norm(t_bad)


@settings(derandomize=True, max_examples=6, deadline=None)
@given(seed=st.integers(0, 2**16), n=st.integers(2, 3))
def test_theorem1_is_a_lower_bound_over_random_observers(seed: int, n: int) -> None:
    """Any stable Luenberger observer (random ``L``, ``V``) has ``J_η ≥ J*_η``."""
    rng = np.random.default_rng(seed)
    pl = random_sampled_data_plant(rng=rng, n=n, p=n, q=n)
    ob = optimal_diagnostic_observer(plant=pl)
    for _ in range(3):
        gain = control.place(pl.A_D.T, pl.C.T, rng.uniform(-0.9, 0.9, n)).T
        v = rng.standard_normal((n, n))
        g = residual_dynamics(F=pl.A_D - gain @ pl.C, L=gain, W=v @ pl.C, V=v)
        for eta in ETAS:
            assert performance(plant=pl, G_rpsi=g, eta=eta) >= ob.J_star[eta] * (1 - 1e-9)


def test_generator_canonical_form_and_monte_carlo_whiteness(paper_plant: SampledDataPlant) -> None:
    """The residual under unit white ``d`` is white with covariance ``I`` (co-inner ``G_rψ G_dJ``) and ignores ``u``.

    N = 40 000 samples: each covariance entry has s.d. ≤ √2/√N ≈ 0.007; 0.04
    is > 5 s.d. The fault step of 10 shifts the mean by the noise-free response.
    """
    pl = paper_plant
    ob = optimal_diagnostic_observer(plant=pl)
    gen = ob.generator()
    assert np.array_equal(gen.Ar, ob.F) and np.array_equal(gen.By, ob.L) and np.array_equal(gen.Bu, ob.G)
    assert np.array_equal(gen.Cr, -ob.W) and np.array_equal(gen.Dy, ob.V) and np.array_equal(gen.Du, -ob.D)
    internal = internal_form(gen, pl.discrete_plant())
    assert internal.coupling("u") <= 1e-12

    def run(v: np.ndarray, f: np.ndarray | None, intensity: np.ndarray | None, seed: int) -> np.ndarray:
        sim = simulate_sampled_data(plant=pl, v=v, f=f, intensity=intensity, rng=np.random.default_rng(seed))
        xi = np.zeros(gen.n_state)
        out = np.empty((v.shape[0], gen.n_residual))
        for k in range(v.shape[0]):
            out[k] = gen.Cr @ xi + gen.Du @ v[k] + gen.Dy @ sim.psi[k]
            xi = gen.Ar @ xi + gen.Bu @ v[k] + gen.By @ sim.psi[k]
        return out

    nsamp = 40_000
    r = run(np.ones((nsamp, 1)), None, None, 7)[5:]  # the first samples carry the initial transient
    cov = r.T @ r / r.shape[0]
    lag1 = r[1:].T @ r[:-1] / (r.shape[0] - 1)
    assert np.max(np.abs(cov - np.eye(2))) <= 0.04
    assert np.max(np.abs(lag1)) <= 0.04
    assert np.max(np.abs(r.mean(axis=0))) <= 0.04  # the held unit step of u leaves no trace
    # Fault: noise-free response of the same generator (deterministic, exact).
    f = np.zeros((100, 1))
    f[60:] = 10.0
    clean = run(np.ones((100, 1)), f, np.zeros((1, 1)), 0)
    assert np.max(np.abs(clean[:60])) <= 1e-12  # no fault, no noise: r ≡ 0 (u decoupled)
    # 40 samples after the step the response is at its DC value
    # G_rψ(1) C (I − A_D)⁻¹ Fx_D · 10 (transients decay like e^{−40}).
    dc = ob.G_rpsi().freqresp(np.array([0.0]))[0].real @ pl.C @ np.linalg.solve(np.eye(2) - pl.A_D, pl.Fx_D[:, 0]) * 10.0
    assert np.max(np.abs(clean[-1] - dc)) <= 1e-12 * np.linalg.norm(dc)
    assert np.linalg.norm(dc) > 9.0  # ≈ 9.6: nine standard deviations of the unit-covariance residual


def test_nearly_rank_deficient_disturbance_is_refused_by_the_certificate() -> None:
    """One disturbance, four outputs, Ts = 0.5: W_E's eigenvalues span ~14 decades (κ ≈ 5e14)."""
    pl = random_sampled_data_plant(n=4, p=4, q=1, rng=np.random.default_rng(10))
    with pytest.raises(CertificateError, match=r"κ = cond\(Nᵀ N\), N Nᵀ = C X Cᵀ = [0-9.e+]+ \(must be <= 1e\+10"):
        optimal_diagnostic_observer(plant=pl)


def test_one_disturbance_plants_within_the_kappa_limit_are_certified() -> None:
    """q = 1 < p = n = 3: κ from 1e3 to beyond 1e10; the κ-scaled certificate passes where κ ≤ 1e10."""
    kappas = []
    for seed in range(6):
        pl = random_sampled_data_plant(n=3, p=3, q=1, rng=np.random.default_rng(seed))
        try:
            ob = optimal_diagnostic_observer(plant=pl)
        except CertificateError as exc:
            assert "κ = cond" in str(exc)  # only the κ limit may refuse these
            continue
        dt = ob.factorisation.dtars
        assert dt.kappa == pytest.approx(np.linalg.cond(dt.N.T @ dt.N), rel=1e-9) and dt.kappa <= 1e10
        # the optimum against the independent sweep, to the κ-scaled round-off the certificate allows
        ref = _j_star_sweep(pl)
        for eta in ("inf", "2"):
            assert abs(ob.J[eta] / ref[eta] - 1.0) <= max(1e-8, 2e-13 * dt.kappa), eta
        kappas.append(dt.kappa)
    assert len(kappas) >= 3 and max(kappas) > 1e6


def test_unstable_plant_is_designed_through_the_error_form() -> None:
    pl = random_sampled_data_plant(rng=np.random.default_rng(8), n=3, p=2, q=3, stable=False)
    assert spectral_radius(pl.A_D) > 1.0
    ob = optimal_diagnostic_observer(plant=pl)
    assert spectral_radius(ob.F) < 1.0
    # the unstable plant's optimum, judged by the sweep of its spectral density (G G~ is defined
    # on the circle whatever the poles); measured agreement ~1e-15
    ref = _j_star_sweep(pl)
    assert math.isinf(ref["-"]) and math.isinf(ob.J["-"])  # p = 2 outputs, rank Fx_J = 3: ‖G_o⁻¹ G_f‖₋ = 0
    for eta in ("inf", "2"):
        assert abs(ob.J[eta] / ref[eta] - 1.0) <= 1e-9, eta


# ---------------------------------------------------------------------------
# Bad input
# ---------------------------------------------------------------------------


@pytest.mark.parametrize("ts", [0.0, -1.0, float("nan"), float("inf")])
def test_nonpositive_or_nonfinite_sample_time(ts: float) -> None:
    with pytest.raises(ArgumentError, match="Ts must be a positive, finite number of seconds"):
        SampledDataPlant.create(**{**PAPER, "Ts": ts})
    with pytest.raises(ArgumentError, match="Ts must be a positive"):
        check_sampling(A=PAPER["A"], C=PAPER["C"], Ts=ts)


def test_non_detectable_continuous_pair() -> None:
    with pytest.raises(ExistenceError, match=r"\(A, C\) is not detectable: the mode\(s\) λ = \[\(1\+0j\)\]"):
        optimal_diagnostic_observer(
            plant=SampledDataPlant.create(A=np.diag([1.0, -1.0]), B=[[0.0], [1.0]], E=[[1.0], [1.0]], Fx=[[1.0], [0.0]], C=[[0.0, 1.0]], Ts=0.5)
        )


def test_pathological_sampling() -> None:
    """``Ts = π/ω`` maps ``±jω`` (or ``−σ ± jω``) to one eigenvalue of ``A_D``; one output loses a mode."""
    om = 2.0
    ts = math.pi / om
    c = [[1.0, 0.0]]
    undamped = SampledDataPlant.create(A=[[0.0, om], [-om, 0.0]], B=[[0.0], [1.0]], E=[[1.0], [0.5]], Fx=[[0.0], [1.0]], C=c, Ts=ts)
    for allow in (False, True):  # marginal modes lost: never acceptable
        with pytest.raises(ExistenceError, match=r"pathological sampling: Ts = 1\.5708 .*Ts\(λ1 − λ2\) = 2π·1·j"):
            optimal_diagnostic_observer(plant=undamped, allow_pathological=allow)
    damped = SampledDataPlant.create(A=[[-0.3, om], [-om, -0.3]], B=[[0.0], [1.0]], E=[[1.0], [0.5]], Fx=[[0.0], [1.0]], C=c, Ts=ts)
    with pytest.raises(ExistenceError, match="or pass allow_pathological=True"):
        optimal_diagnostic_observer(plant=damped)
    ob = optimal_diagnostic_observer(plant=damped, allow_pathological=True)  # lost modes stable: detectable
    assert spectral_radius(ob.F) < 1.0
    ref = _j_star_sweep(damped)  # one output, two fault directions: ‖G_o⁻¹ G_f‖₋ = 0, J₋ = ∞
    for eta in ("inf", "2"):
        assert abs(ob.J[eta] / ref[eta] - 1.0) <= 1e-9, eta
    # A slightly different Ts is fine.
    check_sampling(A=damped.A, C=damped.C, Ts=ts * 1.01)


def test_bad_extra_block_and_basis(paper_plant: SampledDataPlant) -> None:
    with pytest.raises(ArgumentError, match="give both A_d and Y"):
        optimal_diagnostic_observer(plant=paper_plant, A_d=[[0.1]])
    with pytest.raises(ExistenceError, match="A_d must be Schur"):
        optimal_diagnostic_observer(plant=paper_plant, A_d=[[1.2]], Y=[[1.0, 0.0]])
    with pytest.raises(ExistenceError, match="T_t must be nonsingular"):
        optimal_diagnostic_observer(plant=paper_plant, T_t=[[1.0, 1.0], [1.0, 1.0]])
    with pytest.raises(ShapeError, match=r"Y has shape \(1, 3\); expected \(1, 2\)"):
        optimal_diagnostic_observer(plant=paper_plant, A_d=[[0.1]], Y=[[1.0, 0.0, 0.0]])


def test_from_linear_plant_refuses_discrete_and_feedthrough() -> None:
    lp = LinearPlant.create(A=PAPER["A"], B=PAPER["B"], C=PAPER["C"], E=PAPER["E"], Fx=PAPER["Fx"])
    sd = SampledDataPlant.from_linear_plant(lp, Ts=1.0)
    assert np.array_equal(sd.E_J, SampledDataPlant.create(**PAPER).E_J)
    with pytest.raises(ArgumentError, match="continuous plant"):
        SampledDataPlant.from_linear_plant(lp.discretise(1.0), Ts=1.0)
    with pytest.raises(ExistenceError, match="strictly proper"):
        SampledDataPlant.from_linear_plant(
            LinearPlant.create(A=PAPER["A"], B=PAPER["B"], C=PAPER["C"], D=[[1.0], [0.0]], E=PAPER["E"]), Ts=1.0
        )


def _spectral_density(pl: SampledDataPlant, w: float) -> np.ndarray:
    """Eigenvalues of ``G_f~ (G_d G_d~)⁻¹ G_f`` at ``z = e^{jω}`` (``G_d``, ``G_f``: Lemma 1's models).

    ``G_d = G_o G_i`` with ``G_i`` co-inner gives ``G_o G_o~ = G_d G_d~`` on the unit circle,
    so these are the squared singular values of ``G_o⁻¹ G_f`` there — computed from the plant's
    frequency response alone, without the DTARS or any factorisation.
    """
    z = np.exp(1j * w)
    g = pl.C @ np.linalg.solve(z * np.eye(pl.n) - pl.A_D, np.hstack([pl.E_J, pl.Fx_J]))
    gd, gf = g[:, : pl.E_J.shape[1]], g[:, pl.E_J.shape[1] :]
    m = gf.conj().T @ np.linalg.solve(gd @ gd.conj().T, gf)
    return np.linalg.eigvalsh(0.5 * (m + m.conj().T))


def _j_star_sweep(pl: SampledDataPlant) -> dict[str, float]:
    """Theorem 1's optimum ``J* = 1/‖G_o⁻¹ G_f‖_η`` by sweeping :func:`_spectral_density`.

    ``∞`` and ``−``: the largest (smallest) eigenvalue over a 4001-point grid of ``[0, π]``
    (real systems: the circle is symmetric), refined around the best grid point to 1e-12 in
    ``ω``; ``2``: the mean of the trace over 4096 equispaced points of the circle (the
    trapezoid rule converges geometrically for this periodic analytic function).
    """
    grid = np.linspace(0.0, math.pi, 4001)
    ev = np.array([_spectral_density(pl, w) for w in grid])
    out: dict[str, float] = {}
    for eta, pick, sign in (("inf", -1, -1.0), ("-", 0, 1.0)):
        k = int(np.argmin(sign * ev[:, pick]))
        lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)]
        fine = scipy.optimize.minimize_scalar(lambda w, sign=sign, pick=pick: sign * _spectral_density(pl, w)[pick], bounds=(lo, hi), method="bounded", options={"xatol": 1e-12})
        best = sign * min(sign * ev[k, pick], float(fine.fun))
        out[eta] = 1.0 / math.sqrt(best) if best > 0 else math.inf
    circle = np.linspace(-math.pi, math.pi, 4096, endpoint=False)
    out["2"] = 1.0 / math.sqrt(float(np.mean([_spectral_density(pl, w).sum() for w in circle])))
    return out


@pytest.mark.parametrize("which", ["paper", "random n=2", "random n=3"])
def test_j_star_matches_a_sweep_of_the_spectral_density(paper_plant: SampledDataPlant, which: str) -> None:
    """The certificate's J* (from the DTARS: ``1/‖(A_D + MᵀC, Fx_J, N#C, 0)‖_η``) against an
    independent route, the frequency sweep of ``G_f~ (G_d G_d~)⁻¹ G_f`` (:func:`_j_star_sweep`)."""
    pl = {"paper": paper_plant, "random n=2": None, "random n=3": None}[which]
    if pl is None:
        n = int(which[-1])
        pl = random_sampled_data_plant(n=n, p=n, q=n, rng=np.random.default_rng(n))
    ob = optimal_diagnostic_observer(plant=pl)
    ref = _j_star_sweep(pl)
    for eta in ETAS:
        # measured ≤ 4e-15: the extrema are refined to 1e-12 in ω, where the density is flat
        # to second order, and the trapezoid sum has converged; 1e-10 leaves 1e4 of margin
        assert abs(ob.J_star[eta] / ref[eta] - 1.0) <= 1e-10, (eta, ob.J_star[eta], ref[eta])
        assert abs(ob.J[eta] / ref[eta] - 1.0) <= 1e-10, eta  # and the design attains it


def test_a_wrong_factorisation_fails_the_certificate(paper_plant: SampledDataPlant, monkeypatch: pytest.MonkeyPatch) -> None:
    """The certificate has teeth: an observer built from a DTARS gain ``M`` off by 1e-6 (relative)
    is refused, although its Luenberger identities still hold (F, L, T are formed from that M)."""
    import dataclasses

    from fdisyn.synthesis import sampled_data_observer as sd

    factor = sd.co_inner_outer

    def off(**kw: object) -> object:
        fac = factor(**kw)  # type: ignore[arg-type]
        return dataclasses.replace(fac, dtars=dataclasses.replace(fac.dtars, M=fac.dtars.M * (1.0 + 1e-6)))

    monkeypatch.setattr(sd, "co_inner_outer", off)
    with pytest.raises(CertificateError, match=r"failed its certificate: \|‖G_rψ G_d‖∞ − 1\| \(co-inner\) = [0-9.e-]+ \(must be <= 1e-08.*\|J − J\*\| / J\*, η = inf"):
        optimal_diagnostic_observer(plant=paper_plant)
