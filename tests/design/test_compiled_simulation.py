"""The compiled Monte Carlo (simulation and diagnosers fused in one C call) against the truths it must keep:
the law of its Gaussian generator, the Python simulators on the same draws, and the diagnoser's own C step."""

from __future__ import annotations

import multiprocessing
import pickle
import tomllib
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import scipy.stats
from fdisyn.app.examples import EXAMPLES
from fdisyn.simulation.plant_file import load_spec, problem_from_document
from fdisyn.evaluation.compiled_campaign import CompiledCampaign, compiled_campaign
from fdisyn.simulation.sample_models import SampleModel, linear_sample_model
from fdisyn.simulation.signals import SensorFaultSpec, Signal
from fdisyn.simulation.simulate import simulate_linear
from fdisyn.models.linear import LinearPlant
from fdisyn.simulation.problem import Scenario, get_problem
from fdisyn.problems.wind_turbine import PROBLEM as WT
from fdisyn.runtime.compiled import manifest_path
from fdisyn.runtime.errors import ArgumentError, ShapeError

DATA = EXAMPLES

TOLERANCE = 1e-11
"""Compiled against Python simulation on the same draws, relative to each signal's largest magnitude: the two
evaluate the same expressions in the same order except inside the matrix products (NumPy's BLAS and CasADi's
sparse loops sum in different orders), a few units in the last place per sample that the stable plants do not
amplify (the wind turbine's closed loop shows ~1e-15 relative)."""


@pytest.fixture(scope="module")
def wt_campaign(wt_built):
    """The wind turbine's fused campaign, written in every vector width (a library for the main job is written in
    this CPU's widest and the baseline only), so that the widths can be compared with each other."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("FDISYN_LANE_WIDTHS", "all")
        return compiled_campaign(WT, {"kalman_uio": wt_built}, "paper_F1")


# ----------------------------------------------------------------------------- the generator's law


def test_normals_follow_the_standard_normal_law(wt_campaign) -> None:
    """Moments within 5 standard errors of the sample size, a KS test at level 10⁻³, adjacent draws uncorrelated,
    and the tail beyond the ziggurat's base layer (drawn by its own method) as heavy as it should be."""
    n = 2_000_000
    z = wt_campaign.normals(20261123, n)
    assert abs(z.mean()) < 5 / np.sqrt(n)
    assert abs(z.var() - 1) < 5 * np.sqrt(2 / n)
    assert abs(scipy.stats.kurtosis(z)) < 5 * np.sqrt(24 / n)
    assert abs(scipy.stats.skew(z)) < 5 * np.sqrt(6 / n)
    assert scipy.stats.kstest(z, "norm").pvalue > 1e-3
    assert abs(np.corrcoef(z[:-1], z[1:])[0, 1]) < 5 / np.sqrt(n)
    assert abs(np.corrcoef(z[:-1] ** 2, z[1:] ** 2)[0, 1]) < 5 / np.sqrt(n)
    tail = 2 * scipy.stats.norm.sf(3.6541528853610088)
    count = int(np.sum(np.abs(z) > 3.6541528853610088))
    assert abs(count - n * tail) < 5 * np.sqrt(n * tail)
    hist, edges = np.histogram(z, bins=np.linspace(-4, 4, 41))
    expected = n * np.diff(scipy.stats.norm.cdf(edges))
    assert scipy.stats.chisquare(hist, expected * hist.sum() / expected.sum()).pvalue > 1e-3


def test_seeds_give_distinct_streams_and_the_same_seed_the_same_one(wt_campaign) -> None:
    a, b, a2 = wt_campaign.normals(1, 1000), wt_campaign.normals(2, 1000), wt_campaign.normals(1, 1000)
    assert np.array_equal(a, a2) and not np.any(a == b)
    assert abs(np.corrcoef(wt_campaign.normals(0, 100_000), wt_campaign.normals(1, 100_000))[0, 1]) < 5 / np.sqrt(100_000)


def test_a_run_is_the_same_whatever_its_chunk(wt_campaign) -> None:
    alone = wt_campaign.run([7], keep_batch=True)
    among = wt_campaign.run([5, 6, 7, 8], keep_batch=True)
    assert np.array_equal(alone.batch.Y[0], among.batch.Y[2]) and np.array_equal(alone.batch.U[0], among.batch.U[2])
    for f in ("r", "J", "alarm", "isolated", "status"):
        assert np.array_equal(getattr(alone.designs["kalman_uio"], f)[0], getattr(among.designs["kalman_uio"], f)[2])
    assert not np.array_equal(among.batch.Y[0], among.batch.Y[1])


# ----------------------------------------------------------------------------- against the Python simulators


def _close(compiled: np.ndarray, python: np.ndarray) -> None:
    assert compiled.shape == python.shape
    scale = max(float(np.max(np.abs(python))), 1e-300)
    assert np.max(np.abs(compiled - python)) <= TOLERANCE * scale


@pytest.mark.parametrize("scenario", ["fault_free", "paper_F1", "paper_F2", "omega_r_m1_one_sigma", "benchmark_gain_pair"])
def test_wind_turbine_matches_the_python_simulation_on_the_same_draws(wt_built, scenario: str) -> None:
    cc = compiled_campaign(WT, {"kalman_uio": wt_built}, scenario)
    seeds = [3, 11]
    got = cc.run(seeds, keep_batch=True)
    py = WT.simulate(WT.scenario(scenario), tuple(seeds), draws=cc.draws(seeds))
    _close(got.batch.U, py.U)
    _close(got.batch.Y, py.Y)
    for name, signal in py.extra.items():
        _close(got.batch.extra[name], signal)
    assert np.array_equal(got.t, py.t)


def test_the_fused_diagnoser_is_the_diagnosers_own_c_step(wt_built, wt_campaign) -> None:
    got = wt_campaign.run([4, 9], keep_batch=True)
    kept = wt_campaign.run([4, 9], keep_batch=False)
    d = got.designs["kalman_uio"]
    for i in range(2):
        ref = wt_built.diagnoser.run(got.batch.U[i], got.batch.Y[i])
        assert np.array_equal(ref.r, d.r[i]) and np.array_equal(ref.J, d.J[i])
        assert np.array_equal(ref.alarm.astype(bool), d.alarm[i]) and np.array_equal(ref.isolated, d.isolated[i])
        assert np.array_equal(ref.status, d.status[i])
    assert kept.batch is None
    for f in ("r", "J", "alarm", "isolated", "status"):
        assert np.array_equal(getattr(kept.designs["kalman_uio"], f), getattr(d, f))
    assert d.alarm.dtype == bool and d.isolated.dtype == np.int32 and d.status.dtype == np.int8
    assert d.r.shape == (2, 20_000, wt_built.gain_file.step.nr) and d.J.shape == (2, 20_000, wt_built.gain_file.step.nj)
    assert d.alarm[:, 10_000:].any(axis=1).all()  # omega_r_m1 stuck at 2 rad/s from 100 s


def test_a_non_finite_measurement_is_status_1_and_no_alarm(wt_built, wt_campaign) -> None:
    """The controller's sensor stuck at NaN from the fault's onset: the torque, the plant and every sensor turn
    NaN, every sample from then on is skipped (status 1) and raises no alarm, as in the diagnoser's own step."""
    sp = wt_campaign.spec
    p = sp.parameters.copy()
    p[1 + 2], p[1 + 4 + 2] = 1.0, np.nan  # omega_g_m1 stuck, at NaN (layout of linear_parameters)
    nan_run = CompiledCampaign(replace(sp, parameters=p)).run([2], keep_batch=True)
    d = nan_run.designs["kalman_uio"]
    assert np.isnan(nan_run.batch.Y[0, 10_001:, 1:]).all() and np.isnan(nan_run.batch.Y[0, 10_000, 2])
    sc = WT.scenario("paper_F1")
    sc = replace(sc, params={"sensor_faults": [*sc.params["sensor_faults"], ("omega_g_m1", "stuck", np.nan)]})
    py = WT.simulate(sc, (2,), draws=wt_campaign.draws([2]))
    assert np.array_equal(np.isnan(py.Y), np.isnan(nan_run.batch.Y))
    _close(np.nan_to_num(nan_run.batch.Y), np.nan_to_num(py.Y))
    assert np.all(d.status[0, 10_000:] == 1) and not d.alarm[0, 10_000:].any() and np.all(d.isolated[0, 10_000:] == -1)
    assert np.all(d.status[0, :10_000] == 0)
    ref = wt_built.diagnoser.run(nan_run.batch.U[0], nan_run.batch.Y[0])
    assert np.array_equal(ref.status, d.status[0]) and np.array_equal(ref.alarm.astype(bool), d.alarm[0])


def test_a_campaign_travels_to_another_process_as_its_library_path(wt_campaign) -> None:
    again = pickle.loads(pickle.dumps(wt_campaign))
    assert again.spec.library == wt_campaign.spec.library
    here = wt_campaign.run([1]).designs["kalman_uio"].J
    assert np.array_equal(again.run([1]).designs["kalman_uio"].J, here)
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        there = pool.submit(wt_campaign.run, [1]).result()
    assert np.array_equal(there.designs["kalman_uio"].J, here)


def test_a_changed_library_is_rebuilt_not_loaded(wt_built, wt_campaign, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("FDISYN_LANE_WIDTHS", "all")  # as the fixture's library was written
    lib = wt_campaign.spec.library
    rebuilt = compiled_campaign(WT, {"kalman_uio": wt_built}, "paper_F1")
    assert rebuilt.spec.library == lib  # reused: same content, same key
    from fdisyn.runtime.errors import BuildError

    copy = tmp_path / lib.name
    copy.write_bytes(lib.read_bytes() + b"\0")
    manifest_path(copy).write_bytes(manifest_path(lib).read_bytes())
    with pytest.raises(BuildError, match="not the library"):
        CompiledCampaign(replace(wt_campaign.spec, library=copy))


# ----------------------------------------------------------------------------- generic linear plants (plant files)


def test_a_plant_file_matches_its_python_simulation(motor_built) -> None:
    prob = load_spec(DATA / "dc_motor.toml")
    for name in prob.scenarios:
        cc = compiled_campaign(prob, {prob.default_design: motor_built}, name)
        got = cc.run([0, 1], keep_batch=True)
        py = prob.simulate(prob.scenario(name), (0, 1), draws=cc.draws([0, 1]))
        _close(got.batch.U, py.U)
        _close(got.batch.Y, py.Y)


def _motor_like(*, d: float, fx: bool) -> LinearPlant:
    """A discrete plant with the DC-motor file's signal names (so its built design reads it), D and Fx as asked."""
    a = np.array([[0.9, -0.05, 0.0], [0.04, 0.97, 0.0], [0.0, 0.01, 1.0]])
    return LinearPlant.create(
        A=a, B=[[0.1], [0.0], [0.0]], C=np.eye(3), D=[[d], [0.0], [0.0]], E=[[0.0], [-0.2], [0.0]],
        Fx=[[0.0], [0.05], [0.0]] if fx else None, Q=np.diag([1e-4, 1e-3, 0.0]), R=np.diag([1e-4, 2.5e-3, 1e-6]), Ts=0.001,
        states=("current", "speed", "angle"), inputs=("voltage",), unknown_inputs=("load",), outputs=("i_meas", "w_meas", "theta_meas"),
        component_faults=("friction",) if fx else None,
    )


SIGNALS = {
    "step_sine": (Signal("step", offset=0.4, amplitude=2.0, start=0.3), Signal("sine", offset=0.1, amplitude=0.05, period=0.07)),
    "square_prbs": (Signal("square", offset=0.0, amplitude=1.0, period=0.02), Signal("prbs", offset=0.0, amplitude=0.3, period=0.0055)),
    "prbs_gauss_markov": (Signal("prbs", offset=1.0, amplitude=0.5, period=0.01), Signal("gauss_markov", offset=0.02, amplitude=0.01, period=0.05)),
}
FAULTS = [
    Scenario("stuck_and_drift", "", 1.0, fault="w_meas", onset=0.4, end=0.8,
             params={"sensor_faults": [SensorFaultSpec("w_meas", "stuck", 0.3), SensorFaultSpec("theta_meas", "drift", 0.5)]}),
    Scenario("gain_then_offset", "", 1.0, fault="i_meas", onset=0.25,
             params={"sensor_faults": [SensorFaultSpec("i_meas", "gain", 1.2), SensorFaultSpec("w_meas", "offset", -0.1)],
                     "component_faults": [("friction", 2.0)]}),
]


@pytest.mark.parametrize("kinds", list(SIGNALS))
def test_every_signal_and_fault_kind_matches_the_python_simulation(motor_built, kinds: str, tmp_path: Path) -> None:
    plant = _motor_like(d=0.5 if kinds != "square_prbs" else 0.0, fx=True)
    u_sig, d_sig = SIGNALS[kinds]
    x0 = np.array([0.1, 0.0, 0.0])
    base = load_spec(DATA / "dc_motor.toml")
    prob = replace(base, sample_model=lambda **_: linear_sample_model(plant, x0=x0, inputs=[u_sig], unknown_inputs=[d_sig]),
                   scenarios={s.name: s for s in FAULTS})
    for sc in FAULTS:
        cc = compiled_campaign(prob, {base.default_design: motor_built}, sc, directory=tmp_path)
        seeds = (5, 6)
        got = cc.run(seeds, keep_batch=True)
        py = simulate_linear(plant, sc, seeds, x0=x0, inputs=[u_sig], unknown_inputs=[d_sig], draws=cc.draws(seeds))
        _close(got.batch.U, py.U)
        _close(got.batch.Y, py.Y)
        for name, signal in py.extra.items():
            _close(got.batch.extra[name], signal)


def test_the_closed_loop_with_a_nonzero_d_is_refused() -> None:
    with pytest.raises(ArgumentError, match="D = 0"):
        linear_sample_model(_motor_like(d=1.0, fx=False), x0=np.zeros(3), inputs=[Signal()], unknown_inputs=[Signal()],
                            feedback=lambda y, k: y[:, 0:1])


def test_non_finite_numbers_never_reach_the_c() -> None:
    plant = _motor_like(d=0.0, fx=False)
    with pytest.raises(ArgumentError, match="finite"):
        linear_sample_model(plant, x0=np.array([np.inf, 0, 0]), inputs=[Signal()], unknown_inputs=[Signal()])
    with pytest.raises(ArgumentError, match="finite"):
        linear_sample_model(plant, x0=np.zeros(3), inputs=[Signal("sine", amplitude=np.nan)], unknown_inputs=[Signal()])
    model = linear_sample_model(plant, x0=np.zeros(3), inputs=[Signal()], unknown_inputs=[Signal()])
    bad = Scenario("s", "", 1.0, fault="i_meas", onset=0.1, params={"sensor_faults": [("i_meas", "offset", np.nan)]})
    with pytest.raises(ArgumentError, match="finite"):
        model.parameters(bad)
    with pytest.raises(ShapeError):
        SampleModel(step=model.step, x0=np.zeros(2), parameters=model.parameters, Ts=0.001, inputs=("voltage",),
                    outputs=plant.outputs, extra=plant.states + plant.unknown_inputs)


def test_a_design_reading_other_signals_is_refused(wt_built, motor_built) -> None:
    with pytest.raises(ArgumentError, match="reads inputs"):
        compiled_campaign(WT, {"motor": motor_built}, "fault_free")


# ----------------------------------------------------------------------------- nonlinear, sampled-data and turbofan plants


@pytest.mark.parametrize("name", ["ship_propulsion", "wind_turbine_efficiency", "sampled_data_example", "turbofan", "satellite_pitch"])
def test_the_other_problems_simulations_match_python(name: str, tmp_path: Path) -> None:
    """Simulation only (no design): U, Y and the kept truths of every scenario against the problem's simulator
    (the satellite's runs also start from the same draws: its random parameters)."""
    prob = get_problem(name)
    for sname in prob.scenarios:
        cc = compiled_campaign(prob, {}, sname, directory=tmp_path)
        seeds = (1, 2)
        got = cc.run(seeds, keep_batch=True)
        start = {"start_draws": cc.start_draws(seeds)} if cc.spec.n0 else {}
        py = prob.simulate(prob.scenario(sname), seeds, draws=cc.draws(seeds), **start)
        assert got.designs == {}
        _close(got.batch.U, py.U)
        _close(got.batch.Y, py.Y)
        for key, signal in py.extra.items():
            _close(got.batch.extra[key], signal)


@pytest.mark.parametrize("signal", [
    {"kind": "square", "offset": 5.0, "amplitude": 4.0, "period": 50},
    {"kind": "prbs", "offset": 5.0, "amplitude": 2.0, "period": 7},
    {"kind": "gauss_markov", "offset": 5.0, "amplitude": 1.0, "period": 30},
])
def test_a_nonlinear_plant_file_matches_its_python_simulation(signal: dict, tmp_path: Path) -> None:
    doc = tomllib.loads((DATA / "ship.toml").read_text(encoding="utf-8"))
    doc["simulation"]["inputs"] = [signal]
    prob = problem_from_document(doc, DATA / "ship.toml")
    for sname in prob.scenarios:
        cc = compiled_campaign(prob, {}, sname, directory=tmp_path)
        seeds = (4, 8)
        got = cc.run(seeds, keep_batch=True)
        py = prob.simulate(prob.scenario(sname), seeds, draws=cc.draws(seeds))
        _close(got.batch.U, py.U)
        _close(got.batch.Y, py.Y)
        for key, values in py.extra.items():
            _close(got.batch.extra[key], values)


# ----------------------------------------------------------------------------- summaries in the C loop

RESIDUAL_SUMS_RTOL = 1e-12
"""The C loop's residual sums against :func:`summarise_runs`'s, relative to each sum's largest magnitude: both add
each run's rows in sample order except the outer products, which NumPy takes by BLAS (blocked, reordered sums: a
rounding error of order N·eps of the magnitude, ~1e-14 relative for the wind turbine's 30 000 samples)."""


def assert_summaries_equal(got, want) -> None:  # noqa: ANN001 - RunSummaries
    """Every count the same, the histograms the same, the residual sums to :data:`RESIDUAL_SUMS_RTOL`."""
    for f in ("quiet_alarms", "episodes", "exceed", "first_alarm", "alarmed_fault", "first_isolation", "mode_isolation",
              "correct_isolated", "nonfinite"):
        assert getattr(got, f).dtype == np.int64 and np.array_equal(getattr(got, f), getattr(want, f)), f
    assert len(got.histogram) == len(want.histogram)
    for a, b in zip(got.histogram, want.histogram, strict=True):
        assert np.array_equal(a, b)
    for f in ("r_on", "r_off", "rr_off"):
        a, b = getattr(got, f), getattr(want, f)
        assert a.shape == b.shape, f
        np.testing.assert_allclose(a, b, rtol=0, atol=RESIDUAL_SUMS_RTOL * max(float(np.max(np.abs(b), initial=0.0)), 1e-300), err_msg=f)


@pytest.mark.parametrize("scenario", ["fault_free", "benchmark_stuck", "paper_F2"])
def test_the_c_loops_summaries_equal_summarise_runs_on_the_arrays(wt_built, scenario: str, tmp_path: Path) -> None:
    """Wind turbine: a fault-free scenario, and faults that end (the recovery window leaves quiet samples out) with
    a Lorden window of 40 samples (``on`` a strict part of ``active``) and without one."""
    from fdisyn.evaluation.metrics import MetricsPlan, summarise_runs

    cc = compiled_campaign(WT, {"kalman_uio": wt_built}, scenario)
    seeds = [11, 12, 13]
    chunk = cc.run(seeds)
    plan = MetricsPlan.of(WT.scenario(scenario), wt_built.gain_file, chunk.t)
    plans = [plan]
    if plan.on is not None:
        assert np.any(~plan.quiet & ~plan.active)  # a recovery window
        plans.append(replace(plan, on=plan.active & (np.cumsum(plan.active) <= 40)))
    for p in plans:
        want = summarise_runs(p, chunk.designs["kalman_uio"])
        got = cc.summaries(seeds, {"kalman_uio": p})["kalman_uio"]
        assert_summaries_equal(got, want)
        if p.on is not None:
            assert np.any(want.alarmed_fault > 0) and np.any(want.first_isolation >= 0)
    # the arrays not asked for are not made; those asked for are run()'s
    runs, summaries = cc.summarise(seeds, {"kalman_uio": plan}, keep_batch=True)
    assert runs.designs == {} and runs.batch is not None and runs.batch.Y.shape[0] == 3
    runs, _ = cc.summarise(seeds, {"kalman_uio": plan}, arrays=["kalman_uio"])
    for f in ("r", "J", "alarm", "isolated", "status"):
        assert np.array_equal(getattr(runs.designs["kalman_uio"], f), getattr(chunk.designs["kalman_uio"], f))


def test_the_c_loops_summaries_equal_summarise_runs_for_the_sampled_data_example(tmp_path: Path) -> None:
    from fdisyn.evaluation.built import build
    from fdisyn.evaluation.metrics import MetricsPlan, summarise_runs

    sde = get_problem("sampled_data_example")
    d = sde.default_design
    b = build(sde, d, tmp_path / d)
    for name in sde.scenarios:
        cc = compiled_campaign(sde, {d: b}, name)
        assert cc is not None
        seeds = [1, 2, 3, 4]
        chunk = cc.run(seeds)
        plan = MetricsPlan.of(sde.scenario(name), b.gain_file, chunk.t)
        assert_summaries_equal(cc.summaries(seeds, {d: plan})[d], summarise_runs(plan, chunk.designs[d]))


def test_wind_turbine_metrics_do_not_depend_on_the_chunks(wt_built) -> None:
    """Chunks of 1 and of 5 runs: the same metrics to the last bit (each run's residual sums in sample order)."""
    from fdisyn.evaluation.evaluate import evaluate

    scenarios = {name: WT.scenario(name) for name in ("fault_free", "benchmark_stuck")}
    prob = replace(WT, scenarios=scenarios)
    one = evaluate(prob, {"kalman_uio": wt_built}, runs=5, chunk=1, workers=1, progress=False)
    five = evaluate(prob, {"kalman_uio": wt_built}, runs=5, chunk=5, workers=1, progress=False)
    for name in scenarios:
        assert one.metrics["kalman_uio"][name].to_dict() == five.metrics["kalman_uio"][name].to_dict(), name


# ----------------------------------------------------------------------------- vectors of runs


def test_every_vector_width_gives_the_same_runs(wt_campaign) -> None:
    """Eleven runs (a group of eight and a partial one) through every vector width this CPU runs: identical to the
    last bit, and each run the same as alone (run 9 is lane 1 of the second group, alone it is lane 0)."""
    seeds = list(range(30, 41))
    natural = wt_campaign.vector_level(0)
    try:
        chunks = {}
        for level in range(1, natural + 1):
            assert wt_campaign.vector_level(level) == level
            chunks[level] = wt_campaign.run(seeds, keep_batch=True)
        with pytest.raises(ArgumentError, match="vector level"):
            wt_campaign.vector_level(natural + 1)
    finally:
        wt_campaign.vector_level(0)
    first = chunks[1]
    for chunk in chunks.values():
        assert np.array_equal(chunk.batch.Y, first.batch.Y) and np.array_equal(chunk.batch.U, first.batch.U)
        for f in ("r", "J", "alarm", "isolated", "status"):
            assert np.array_equal(getattr(chunk.designs["kalman_uio"], f), getattr(first.designs["kalman_uio"], f))
    alone = wt_campaign.run([seeds[9]], keep_batch=True)
    assert np.array_equal(alone.batch.Y[0], first.batch.Y[9])
    assert np.array_equal(alone.designs["kalman_uio"].J[0], first.designs["kalman_uio"].J[9])
