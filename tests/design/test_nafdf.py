"""NAFDF (Zhou, Xi & Zhang, Shanghai Jiao Tong University, c. 1991) against truths: Riccati,
Cramér–Rao, χ² law; skip, divergence and latching contracts."""

from __future__ import annotations

import json
from contextlib import nullcontext

import casadi as ca
import numpy as np
import pytest
import scipy.stats
from fdisyn.detectors.wssr import wssr_threshold_table
from fdisyn.models.nonlinear import NonlinearPlant
from fdisyn.simulation.nonlinear import simulate_nonlinear
from fdisyn.numerics.linalg import rel_diff
from fdisyn.numerics.riccati import solve_filter_dare
from fdisyn.problems import ship_propulsion as sp
from fdisyn.runtime.errors import ArgumentError, GainFileError, ShapeError
from fdisyn.synthesis.nafdf.design import nafdf
from fdisyn.synthesis.nafdf.payload import nafdf_from_payload, nafdf_payload, step_from_payload
from hypothesis import given, settings
from hypothesis import strategies as st

NEVER_ALARM = dict(threshold_rule="beta0", beta0=1e150)  # the largest a gain file holds: the WSSR of a working filter never reaches it: filters run undisturbed


@pytest.fixture(scope="module")
def ship_design():
    return sp.design()


@pytest.fixture(scope="module")
def ship_paper_run(ship_design):
    run = sp.PROBLEM.run(sp.fault_scenario("paper_a_half", {"a": 0.5}, length=3000), [1])
    return run, ship_design.run(u=run.U[0], y=run.Y[0])


def linear_plant(rng: np.random.Generator, n: int, p: int) -> tuple[NonlinearPlant, dict[str, np.ndarray]]:
    """``x⁺ = (A + θ E) x + B u``, ``y = C x`` with nominal ``θ = 0``: the EKF on it is a Kalman filter."""
    a = rng.standard_normal((n, n))
    a *= 0.9 / max(np.abs(np.linalg.eigvals(a)))
    b = rng.standard_normal((n, 1))
    c = rng.standard_normal((p, n))
    e = rng.standard_normal((n, n))
    g = rng.standard_normal((n, n))
    q = 0.1 * g @ g.T + 0.01 * np.eye(n)
    hmat = rng.standard_normal((p, p))
    r = 0.2 * hmat @ hmat.T + 0.05 * np.eye(p)
    x, u, th = ca.SX.sym("x", n), ca.SX.sym("u", 1), ca.SX.sym("theta", 1)
    f = ca.Function("f", [x, u, th], [ca.mtimes(ca.DM(a) + th[0] * ca.DM(e), x) + ca.mtimes(ca.DM(b), u)])
    h = ca.Function("h", [x, th], [ca.mtimes(ca.DM(c), x)])
    pl = NonlinearPlant.create(
        f=f, h=h, states=[f"x{i}" for i in range(n)], inputs=["u"], outputs=[f"y{i}" for i in range(p)],
        parameters=["theta"], nominal={"theta": 0.0}, Q=q, R=r,
    )
    return pl, {"A": a, "C": c, "Q": q, "R": r}


@settings(max_examples=8, derandomize=True, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 3), p=st.integers(1, 2))
def test_ekf_steady_gain_equals_dare_kalman_gain(seed: int, n: int, p: int) -> None:
    """On a linear plant the EKF's covariance recursion is the Riccati recursion; its limit is the DARE.

    Bound 1e-9: the recursion contracts like ρ(A − LC)² per step, so 1500 steps leave nothing but
    round-off (~1e-13 relative) for these well-conditioned random systems; 1e-9 leaves four orders
    of margin above it, while a wrong covariance recursion would converge to another gain altogether.
    """
    rng = np.random.default_rng(seed)
    pl, m = linear_plant(rng, n, p)
    dsg = nafdf(pl, x0=np.zeros(n), P0=np.eye(n), R0=1.0, **NEVER_ALARM)
    T = 1500
    u = rng.standard_normal((T, 1))
    _, y = simulate_nonlinear(pl, x0=np.zeros(n), u=u, rng=rng)
    out = dsg.run(u=u, y=y)
    P = dsg.unpack_state(out["state"][-1])["ekf_P"]  # P(T|T−1)
    truth = solve_filter_dare(m["A"], m["C"], m["Q"], m["R"])
    gain = m["A"] @ P @ m["C"].T @ np.linalg.inv(m["C"] @ P @ m["C"].T + m["R"])  # predictor gain A K_f
    assert rel_diff(gain, truth.L) <= 1e-9
    assert rel_diff(P, truth.X) <= 1e-9


def cramer_rao_sd(pl: NonlinearPlant, x0: float, u: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """Standard deviations of the Cramér–Rao bound for θ from y = x + e (output error, Q = 0).

    Fisher information ``Σ ψ ψᵀ / R`` with ``ψ(t) = ∂x(t)/∂θ`` propagated along the true
    trajectory with the AD Jacobians (``ψ⁺ = F_x ψ + F_θ``).
    """
    der = pl.derivatives()
    x = np.array([x0])
    psi = np.zeros((1, pl.l))
    info = np.zeros((pl.l, pl.l))
    for k in range(u.shape[0]):
        info += psi.T @ psi / pl.R[0, 0]
        f, fx, fth, _, _, _ = (np.array(v) for v in der(x, u[k], theta))
        psi = fx @ psi + fth
        x = f.reshape(-1)
    return np.sqrt(np.diag(np.linalg.inv(info)))


@pytest.mark.parametrize("seed", [3, 4, 5])
def test_nf_converges_to_the_true_parameters(seed: int) -> None:
    """Fault-free data, known θ: with a(t) ~ 1/t (λ∞ = 1) the RPE estimate is consistent and
    asymptotically efficient (Ljung 1979), so after 4000 samples |θ̂ − θ| ≤ 5 Cramér–Rao standard
    deviations (a 5σ miss has probability ~6e-7 per parameter); it also started 0.58 and 0.2 away.
    """
    pl = sp.plant()
    dsg = nafdf(pl, x0=[0.0], P0=100.0, theta0=[0.0, 0.0], R0=sp.R0, forgetting_final=1.0, **NEVER_ALARM)
    run = sp.PROBLEM.run(sp.fault_scenario("fault_free", length=4000), [seed])
    out = dsg.run(u=run.U[0], y=run.Y[0])
    est = dsg.unpack_state(out["state"][-1])["nf_theta"]
    sd = cramer_rao_sd(pl, 0.0, run.U[0], pl.theta_nominal)
    assert np.all(np.abs(est - pl.theta_nominal) <= 5 * sd), (est, sd)
    assert np.all(sd < 0.01)  # the bound is informative: the estimate is pinned to ~1 % or better


def test_wssr_fault_free_law_is_chi_square() -> None:
    """Under H0 N·L ~ χ²(N p) (2.4): exceedances of the P_f threshold on non-overlapping full windows
    are Binomial(M, P_f) — checked against its two-sided 99.9 % interval — and the window values pass
    a Kolmogorov–Smirnov test against χ²(N p) at level 1e-3. The NF is kept from ever converging
    (an isolable jump of 1e-12 needs more information than any data carry), so the EKF is never
    re-parameterised and runs on the true model throughout.
    """
    N, pf = 10, 0.01
    dsg = nafdf(sp.plant(), x0=[0.0], P0=100.0, theta0=[0.0, 0.0], R0=sp.R0, window=N,
                false_alarm_probability=pf, isolable_jump=[1e-12, 1e-12])
    run = sp.PROBLEM.run(sp.fault_scenario("fault_free", length=40_000), [11])
    out = dsg.run(u=run.U[0], y=run.Y[0])
    assert dsg.unpack_state(out["state"][-1])["ekf_reparameterisations"] == 0
    jn = list(dsg.J_names)
    idx = np.arange(200 + N - 1, run.Y.shape[1], N)  # skip the EKF's start-up from P(0) = 100
    L = out["J"][idx, jn.index("wssr")]
    thr = out["J"][idx, jn.index("wssr_threshold")]
    np.testing.assert_array_equal(thr, scipy.stats.chi2.isf(pf, N) / N)
    M = idx.size
    count = int(np.sum(L > thr))
    lo, hi = scipy.stats.binom.interval(0.999, M, pf)
    assert lo <= count <= hi, (count, M * pf, lo, hi)
    assert scipy.stats.kstest(N * L, scipy.stats.chi2(N).cdf).pvalue > 1e-3


def test_threshold_table_rules() -> None:
    chi = wssr_threshold_table(window=5, n_outputs=2, rule="chi2", false_alarm_probability=1e-3, beta0=None)
    # rtol 1e-15: the same SciPy quantile divided by k, so equal up to the division's rounding
    np.testing.assert_allclose(chi, [scipy.stats.chi2.isf(1e-3, 2 * k) / k for k in range(1, 6)], rtol=1e-15)
    assert np.all(np.diff(chi) < 0)  # averaging more samples narrows the law
    beta = wssr_threshold_table(window=5, n_outputs=2, rule="beta0", false_alarm_probability=0.5, beta0=0.01)
    assert beta[-1] == 0.01 and np.all(beta[:-1] == 1e150)  # the paper's rule needs a full window (1e150: the gain file's largest number)
    with pytest.raises(ArgumentError, match="beta0"):
        wssr_threshold_table(window=5, n_outputs=1, rule="beta0", false_alarm_probability=0.5, beta0=None)


@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(W1=400.0, W2=350.0), "W1 < W2"),
        (dict(theta0=[1.0, 0.0], theta_lower=[-10.0, 0.0], theta_upper=[0.0, 10.0]), "outside the parameter box"),
        (dict(P0=-1.0), "positive definite"),
        (dict(window=0), "positive integer"),
        (dict(false_alarm_probability=1.5), "between 0 and 1"),
        (dict(threshold_rule="gaussian"), "'chi2' or 'beta0'"),
        (dict(isolable_jump=[0.0, 1.0]), "isolable_jump must be positive"),
        (dict(isolable_jump=[float("nan"), 1.0]), "isolable_jump must be positive"),
        (dict(isolable_jump=[0.1, 0.1], convergence_tolerance=[0.01, 0.01]), "not both"),
    ],
)
def test_bad_settings_are_refused(kw: dict, match: str) -> None:
    base = dict(x0=[0.0], P0=100.0, theta0=[0.0, 0.0], R0=sp.R0)
    with pytest.raises(ArgumentError, match=match), pytest.warns(FutureWarning) if "convergence_tolerance" in kw else nullcontext():
        nafdf(sp.plant(), **{**base, **kw})


def test_deprecated_convergence_tolerance_maps_to_the_information_bound() -> None:
    """``convergence_tolerance`` still designs, with a FutureWarning: the tolerance is read as the largest
    standard deviation of θ̂_i, so ``isolable_jump = √W1 · tol`` (W1 = 0 sets no bound); the step is the one
    ``isolable_jump`` designs. A bad tolerance is still refused by its own name."""
    base = dict(x0=[0.0], P0=100.0, theta0=[0.0, 0.0], R0=sp.R0)
    with pytest.warns(FutureWarning, match="convergence_tolerance is deprecated"):
        old = nafdf(sp.plant(), **base, W1=32.0, convergence_tolerance=[0.03, 0.01])
    np.testing.assert_allclose(old.settings.isolable_jump, [0.03 * np.sqrt(32.0), 0.01 * np.sqrt(32.0)], rtol=1e-15)
    new = nafdf(sp.plant(), **base, W1=32.0, isolable_jump=old.settings.isolable_jump)
    assert new.step.serialize() == old.step.serialize()
    with pytest.warns(FutureWarning):
        free = nafdf(sp.plant(), **base, W1=0.0, convergence_tolerance=[0.03, 0.01])
    assert np.all(np.isinf(free.settings.isolable_jump))
    with pytest.warns(FutureWarning), pytest.raises(ArgumentError, match="convergence_tolerance must be positive and finite"):
        nafdf(sp.plant(), **base, convergence_tolerance=[0.0, 1.0])


def test_state_layout_round_trip(ship_design) -> None:
    s0 = ship_design.init_state()
    blocks = ship_design.unpack_state(s0)
    np.testing.assert_array_equal(ship_design.pack_state(blocks), s0)
    assert len(ship_design.layout.component_names()) == s0.size == ship_design.nstate
    assert blocks["isolated"] == -1.0 and blocks["ekf_theta"].tolist() == [-0.58, 0.2]
    assert ship_design.step.size_in(0) == (s0.size, 1)
    assert ship_design.step.name_out() == ["state_next", "r", "J", "alarm", "isolated", "status"]
    assert len(ship_design.r_names) == ship_design.step.nnz_out(1)
    assert len(ship_design.J_names) == ship_design.step.nnz_out(2)


@settings(max_examples=25, derandomize=True, deadline=None)
@given(
    bad=st.lists(st.tuples(st.integers(0, 399), st.sampled_from(["u", "y"]), st.sampled_from([np.nan, np.inf, -np.inf])),
                 min_size=1, max_size=30)
)
def test_non_finite_samples_are_skipped(ship_design, bad) -> None:
    """A non-finite u or y: status 1, no alarm, state unchanged except the skip counter."""
    run = sp.PROBLEM.run(sp.fault_scenario("a_half", {"a": 0.5}, length=400, fault_time=200), [2])
    u, y = run.U[0].copy(), run.Y[0].copy()
    for k, which, val in bad:
        (u if which == "u" else y)[k, 0] = val
    out = ship_design.run(u=u, y=y)
    skipped = ~(np.isfinite(u[:, 0]) & np.isfinite(y[:, 0]))
    np.testing.assert_array_equal(out["status"], skipped.astype(float))
    assert np.all(out["alarm"][skipped] == 0)
    for name in ("r", "J", "state"):
        assert np.all(np.isfinite(out[name]))
    prev = np.vstack([ship_design.init_state()[None, :], out["state"][:-1]])
    k_skip = ship_design.layout.offsets()["skipped"][0]
    for k in np.flatnonzero(skipped):
        delta = out["state"][k] - prev[k]
        assert delta[k_skip] == 1.0
        delta[k_skip] = 0.0
        assert not np.any(delta), f"sample {k}: state changed on a skipped sample"
        assert out["isolated"][k] == (out["isolated"][k - 1] if k else -1.0)
    assert ship_design.unpack_state(out["state"][-1])["skipped"] == skipped.sum()


@settings(max_examples=30, derandomize=True, deadline=None)
@given(
    data=st.lists(st.tuples(st.floats(-1e300, 1e300), st.floats(-1e300, 1e300)), min_size=5, max_size=40),
)
def test_wild_finite_data_never_produce_nan(ship_design, data) -> None:
    """Any finite data, however absurd: outputs and state stay finite, covariances stay PSD."""
    arr = np.array(data)
    out = ship_design.run(u=arr[:, :1], y=arr[:, 1:])
    for name in ("r", "J", "state", "alarm", "isolated", "status"):
        assert np.all(np.isfinite(out[name])), name
    for s in out["state"]:
        blk = ship_design.unpack_state(s)
        for key in ("ekf_P", "nf_P"):
            # PSD up to the step's own acceptance shift (1e-12·max diag) plus eigvalsh round-off
            assert np.min(np.linalg.eigvalsh(blk[key])) >= -1e-9 * max(1.0, np.max(np.abs(blk[key])))
        # R is PD in exact arithmetic; data near 1e300 can push cond(R) past 1/eps (eigvalsh then returns 0)
        assert np.min(np.linalg.eigvalsh(blk["nf_R"])) >= -1e-9 * max(1.0, np.max(np.abs(blk["nf_R"])))


@pytest.mark.parametrize(
    "corrupt, counter",
    [
        ({"ekf_P": -np.eye(1)}, "ekf_divergence_resets"),
        ({"ekf_P": np.full((1, 1), np.inf)}, "ekf_divergence_resets"),
        ({"nf_P": np.full((1, 1), np.nan)}, "nf_divergence_resets"),
        ({"nf_R": -np.eye(2)}, "nf_divergence_resets"),
        ({"ekf_x": np.array([1e200])}, "ekf_divergence_resets"),  # f(x) = 0.1 a x² overflows
    ],
)
def test_divergence_reinitialises_and_reports(ship_design, corrupt: dict, counter: str) -> None:
    """Covariance not finite or not positive, or an overflowing state: the filter is re-initialised,
    the sample reports ``diverged = 1``, the counter counts it, and nothing is NaN."""
    blocks = ship_design.unpack_state(ship_design.init_state())
    blocks.update(corrupt)
    out = ship_design.run(u=np.array([[5.0], [5.0]]), y=np.array([[0.1], [0.2]]), state=ship_design.pack_state(blocks))
    after = ship_design.unpack_state(out["state"][0])
    assert after[counter] == 1.0
    assert out["J"][0, list(ship_design.J_names).index("diverged")] == 1.0
    for name in ("r", "J", "state"):
        assert np.all(np.isfinite(out[name]))
    key = "ekf_P" if counter.startswith("ekf") else "nf_P"
    np.testing.assert_array_equal(after[key], ship_design.settings.P0)
    assert out["J"][1, list(ship_design.J_names).index("diverged")] == 0.0  # and it stays healthy


def test_isolation_and_fault_size_stay_latched(ship_design, ship_paper_run) -> None:
    """After the classifier isolates ``a``, ``isolated`` and the fault size (2.8) never change again,
    although the filters re-converge and the EKF is re-parameterised; re-initialising clears them."""
    _, out = ship_paper_run
    iso = out["isolated"]
    first = int(np.flatnonzero(iso >= 0)[0])
    assert np.all(iso[:first] == -1) and np.all(iso[first:] == 0)
    jn = list(ship_design.J_names)
    for name in ("fault_size_a", "fault_class_a", "fault_size_b", "fault_class_b"):
        col = out["J"][first:, jn.index(name)]
        assert np.all(col == col[0]), name
    assert out["J"][first, jn.index("fault_class_a")] >= 1 and out["J"][first, jn.index("fault_class_b")] == 0
    last = ship_design.unpack_state(out["state"][-1])
    assert last["ekf_reparameterisations"] >= 1
    # the filters have moved on after the latch: the EKF now runs on the estimated faulty model
    assert abs(last["ekf_theta"][0] - (-0.29)) < 0.05
    fresh = ship_design.unpack_state(ship_design.init_state())
    assert fresh["isolated"] == -1 and not np.any(fresh["fault_size"])


def test_payload_round_trip_rebuilds_the_identical_step(ship_design, ship_paper_run) -> None:
    """JSON text → rebuilt step: identical outputs bit for bit, and identical generated C."""
    text = json.dumps(nafdf_payload(ship_design), allow_nan=False)  # strict JSON: no inf/NaN tokens
    payload = json.loads(text)
    rebuilt = nafdf_from_payload(payload)
    run, out = ship_paper_run
    again = rebuilt.run(u=run.U[0, :1500], y=run.Y[0, :1500])
    for k in ("state", "r", "J", "alarm", "isolated", "status"):
        np.testing.assert_array_equal(again[k], out[k][:1500])
    np.testing.assert_array_equal(rebuilt.init_state(), np.array(payload["init_state"]))
    assert step_from_payload(payload).serialize() == ship_design.step.serialize()
    cg1, cg2 = ca.CodeGenerator("a.c"), ca.CodeGenerator("a.c")
    cg1.add(ship_design.step)
    cg2.add(step_from_payload(payload))
    assert cg1.dump() == cg2.dump()
    with pytest.raises(GainFileError, match="format"):
        nafdf_from_payload({**payload, "format": "something else"})


def test_wind_turbine_payload_round_trip() -> None:
    from fdisyn.problems import wind_turbine_efficiency as wt

    dsg = wt.design()
    rebuilt = nafdf_from_payload(json.loads(json.dumps(nafdf_payload(dsg), allow_nan=False)))
    assert rebuilt.step.serialize() == dsg.step.serialize()


def test_payload_with_unbounded_parameters_and_the_beta0_rule() -> None:
    dsg = nafdf(sp.plant(), x0=[0.0], P0=100.0, threshold_rule="beta0", beta0=0.01)
    payload = json.loads(json.dumps(nafdf_payload(dsg), allow_nan=False))
    assert payload["settings"]["theta_lower"] == [None, None]  # −inf has no JSON token
    rebuilt = nafdf_from_payload(payload)
    assert np.all(np.isneginf(rebuilt.settings.theta_lower))
    np.testing.assert_array_equal(rebuilt.thresholds, dsg.thresholds)
    assert rebuilt.step.serialize() == dsg.step.serialize()


# --------------------------------------------------------------------------- limits and the starting point


@pytest.mark.parametrize(
    "kw, match",
    [
        (dict(window=100_000), "window is 100000; at most 1000"),
        (dict(window=1e9), "window is 1000000000; at most 1000"),  # refused before any array of that size exists
        (dict(window=float("inf")), "window must be a positive integer"),
        (dict(classifier_window=float("nan")), "classifier_window must be a positive integer"),
        (dict(T1=10**30), "T1 is 1000000000000000000000000000000; at most 1000000000"),
        (dict(x0=[float("nan")]), "x0 must be finite"),
        (dict(u0=[0.0, 1.0]), "u0 has 2 entries; expected 1"),
        (dict(beta0=float("nan"), threshold_rule="beta0"), "beta0 must be a positive finite number"),
        (dict(name="a b"), "name must be an identifier"),
    ],
)
def test_limits_and_bad_numbers_are_refused_before_building(kw: dict, match: str) -> None:
    base = dict(x0=[0.0], P0=100.0, theta0=[0.0, 0.0], R0=sp.R0)
    with pytest.raises((ArgumentError, ShapeError), match=match) as info:
        nafdf(sp.plant(), **{**base, **kw})
    assert "\n" not in str(info.value)


def test_state_size_is_checked_from_the_layout_before_the_step_is_built() -> None:
    """Four parameters and N2 = 1000 make a 6000-entry state (the θ window is 4 × 1000, the NF's and
    the EKF's innovation windows 2 × 1000): refused from the sizes, without building anything."""
    x, u, th = ca.SX.sym("x"), ca.SX.sym("u"), ca.SX.sym("theta", 4)
    f = ca.Function("f", [x, u, th], [th[0] * x + th[1] * u + th[2] * x * u + th[3]])
    h = ca.Function("h", [x, th], [x])
    pl = NonlinearPlant.create(f=f, h=h, states=["x"], inputs=["u"], outputs=["y"], parameters=list("abcd"),
                               nominal=dict(a=0.5, b=1.0, c=0.0, d=0.0), Q=0.0, R=0.01)
    with pytest.raises(ArgumentError, match=r"state would have 60\d\d entries .*; at most 4096"):
        nafdf(pl, x0=[0.0], P0=1.0, classifier_window=1000)


def test_step_operation_and_work_limits(monkeypatch) -> None:
    """The step budget is checked on the SX graph before any C exists: the ship with N = 1000 and
    N2 = 700 has ~44 000 operations (> 40 000) in a 3 848-entry state; lowering the work limit below
    the ship's own ~220 doubles refuses the default ship design by its work memory (the C step's stack)."""
    from fdisyn.synthesis.nafdf import step as mod

    with pytest.raises(ArgumentError, match=r"the NAFDF step has \d+ operations; at most 40000"):
        nafdf(sp.plant(), x0=[0.0], P0=100.0, theta0=[0.0, 0.0], R0=sp.R0, window=1000, classifier_window=700)
    monkeypatch.setattr(mod, "MAX_STEP_WORK", 100)
    with pytest.raises(ArgumentError, match=r"needs \d+ doubles of work memory; at most 100"):
        sp.design()


def test_stack_use_of_the_documented_problems_is_within_the_limits(ship_design) -> None:
    """The C step's stack holds CasADi's work vector and the next state: both bounded by the limits."""
    from fdisyn.synthesis.nafdf.settings import MAX_STATE, MAX_STEP_INSTRUCTIONS, MAX_STEP_WORK

    assert ship_design.step.sz_w() <= MAX_STEP_WORK and ship_design.nstate <= MAX_STATE
    assert ship_design.step.n_instructions() <= MAX_STEP_INSTRUCTIONS
    assert ship_design.certificate.info["work_doubles"] == ship_design.step.sz_w()


@pytest.mark.parametrize(
    "f, theta0, where",
    [
        ("x**x + a*b*u", None, "the EKF's start"),  # ∂f/∂x = 0·∞ at x0 = 0
        ("x + log(-a)*b*u", [0.0, 0.0], "the NF's start"),  # finite at a = −0.58, log(0) = −inf at θ̂(0)
    ],
)
def test_model_not_finite_where_the_filters_start_is_refused(f: str, theta0, where: str) -> None:
    pl = NonlinearPlant.from_expressions(**{**sp.MODEL, "f": {"x": f}})
    with pytest.raises(ArgumentError, match=where) as info:
        nafdf(pl, x0=[0.0], P0=1.0, theta0=theta0)
    assert "\n" not in str(info.value)


def test_certificate_fails_on_a_nan_jacobian_even_past_the_model_check(monkeypatch) -> None:
    """Second line of defence: with the starting-point check disabled, x**x reaches the certificate,
    whose AD-vs-difference gap is NaN — it fails (max(worst, nan) used to report 0 and pass)."""
    from fdisyn.runtime.errors import CertificateError
    from fdisyn.synthesis.nafdf import design as mod

    monkeypatch.setattr(mod, "_check_model_finite", lambda plant, s: None)
    pl = NonlinearPlant.from_expressions(**{**sp.MODEL, "f": {"x": "x**x + a*b*u"}})
    with pytest.raises(CertificateError, match=r"AD Jacobians vs central differences at x0 \(max relative\) = nan"):
        nafdf(pl, x0=[0.0], P0=1.0)


@pytest.mark.parametrize("kw, key", [(dict(P0=1e200), "P0"), (dict(W2=1e200), "W2"), (dict(x0=[1e160]), "x0")])
def test_settings_beyond_what_a_gain_file_holds_are_refused_at_design(kw: dict, key: str) -> None:
    # a design whose gain file the reader would then refuse (numbers beyond 1e150) is refused by its option's name
    with pytest.raises(ArgumentError, match=rf"^{key} holds .*; a design's numbers must be at most 1e\+150 in magnitude"):
        nafdf(sp.plant(), **{**dict(x0=[0.0], P0=100.0), **kw})
