"""The operating characteristic (detection within a delay against the mean time between false alarms, every
threshold scaled by one factor) against truths: the step rerun at the scaled thresholds, the χ² law's tail, and its
own consistency (detection never grows with the threshold, the design's own point is the step's)."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.stats
from fdisyn.evaluation.metrics import (
    OPERATING_SCALES,
    MetricsAccumulator,
    MetricsPlan,
    OperatingPlan,
    binomial_interval,
    operating_values,
    summarise_runs,
)
from fdisyn.runtime.errors import InternalError
from fdisyn.runtime.reference import LinearReference
from fdisyn.synthesis.registry import design

from tests.helpers import random_plant

ONE = OPERATING_SCALES.index(1.0)


def _plan(n: int, onset: int | None, op: OperatingPlan | None, nj: int = 1) -> MetricsPlan:
    active = np.zeros(n, dtype=bool)
    if onset is not None:
        active[onset:] = True
    return MetricsPlan(active=active, quiet=~active, on=None, fault_index=None, thresholds=(1.0,) * nj, operating=op)


def _truth(alarm: np.ndarray, plan: MetricsPlan) -> tuple[np.ndarray, np.ndarray]:
    """Episodes among the quiet samples and the first alarm among the active ones, per run, from alarms."""
    rising = alarm & ~np.concatenate([np.zeros((alarm.shape[0], 1), bool), alarm[:, :-1]], axis=1)
    hit = alarm[:, plan.active]
    first = np.where(hit.any(axis=1), np.argmax(hit, axis=1), -1) if hit.shape[1] else np.full(alarm.shape[0], -1)
    return rising[:, plan.quiet].sum(axis=1), first


def _scaled(gf, s: float):  # noqa: ANN001, ANN202 - a gain file
    return replace(gf, evaluators=tuple(replace(e, threshold=s * e.threshold) for e in gf.evaluators))


def _rerun_agrees(episodes: np.ndarray, first: np.ndarray, plan: MetricsPlan, rerun) -> int:  # noqa: ANN001 - a callable
    """Every fourth scale's curve values equal those of the step ``rerun(s)`` (its alarms, runs × samples) at the
    scaled thresholds; the alarms the comparison saw."""
    checked = 0
    for k in range(0, len(OPERATING_SCALES), 4):
        s = OPERATING_SCALES[k]
        ep, fi = _truth(np.asarray(rerun(s)).astype(bool), plan)
        assert episodes[:, k].tolist() == ep.tolist(), s
        assert first[:, k].tolist() == fi.tolist(), s
        checked += int(ep.sum()) + int((fi >= 0).sum())
    return checked


@pytest.mark.parametrize("detector, options", [("glr", {"window": 6, "arl0": 20.0}), ("chi2", {"persistence": 3, "P_f": 0.02})])
def test_the_curve_is_the_step_rerun_at_the_scaled_thresholds(detector, options):
    """From one run's J at the design's thresholds, the decisions at every scaled threshold equal those of the NumPy
    reference step whose gain file has those thresholds (a GLR's hold down to half its threshold, a χ² persistence
    count of three)."""
    plant = random_plant(3)
    gf = design(plant, "kalman_uio", detector=detector, **options)
    rng = np.random.default_rng(7)
    R, n, onset = 3, 400, 250
    U = rng.standard_normal((R, n, plant.m))
    Y = rng.standard_normal((R, n, plant.p)) * 2.0
    Y[:, onset:, 0] += 1.5  # a bias on the first sensor from the onset
    runs = [LinearReference(gf).run(U[i], Y[i]) for i in range(R)]
    J = np.stack([r.J for r in runs])
    base = SimpleNamespace(J=J, status=np.zeros((R, n), np.int8))
    plan = _plan(n, onset, OperatingPlan(tuple(gf.evaluators), int(gf.decision.persistence), within=20, delay_s=2.0), gf.step.nj)
    episodes, first = operating_values(plan, base)
    checked = _rerun_agrees(episodes, first, plan, lambda s: np.stack([LinearReference(_scaled(gf, s)).run(U[i], Y[i]).alarm for i in range(R)]))
    assert checked > 0  # the comparison saw alarms


@pytest.mark.parametrize("shifts", [None, (0.5, 1.0, 2.0, 4.0)], ids=["one_shift", "multiscale"])
def test_the_cusum_curve_is_the_step_rerun_at_the_scaled_thresholds(shifts):
    """A CUSUM's sums are clamped at twice its threshold, so its ``J`` at one threshold does not give another's: its
    flags are run again from the residuals at each scale. Those decisions equal the NumPy reference step's whose gain
    file has the scaled thresholds, at every scale, in the warm-up and after it."""
    from fdisyn.evaluation.metrics import operating_plan

    plant = random_plant(3)
    gf = design(plant, "kalman_uio", detector="cusum", arl0=20.0, **({} if shifts is None else {"shifts": shifts}))
    op = operating_plan(gf, 20 * gf.Ts)
    assert op is not None and op.residuals and op.within == 20
    assert max(g.warmup for g in gf.generators) > 0  # the rerun skips each generator's warm-up as the step does
    rng = np.random.default_rng(5)
    R, n, onset = 3, 400, 250
    U = rng.standard_normal((R, n, plant.m))
    Y = rng.standard_normal((R, n, plant.p)) * 1.5
    Y[:, onset:, 0] += 1.0
    runs = [LinearReference(gf).run(U[i], Y[i]) for i in range(R)]
    base = SimpleNamespace(J=np.stack([o.J for o in runs]), r=np.stack([o.r for o in runs]), status=np.zeros((R, n), np.int8))
    plan = _plan(n, onset, op, gf.step.nj)
    episodes, first = operating_values(plan, base)
    ep1, fi1 = _truth(np.stack([o.alarm for o in runs]).astype(bool), plan)
    assert episodes[:, ONE].tolist() == ep1.tolist() and first[:, ONE].tolist() == fi1.tolist()
    checked = _rerun_agrees(episodes, first, plan, lambda s: np.stack([LinearReference(_scaled(gf, s)).run(U[i], Y[i]).alarm for i in range(R)]))
    assert checked > 0  # the comparison saw alarms (episodes need not fall with the scale: a lower threshold latches longer)


def test_the_beard_curve_is_the_filter_rerun_at_the_scaled_threshold():
    """A Beard filter's decision is its window's RMS residual against ``h`` over the persistence: its curve from
    ``J`` equals the NumPy reference filter's decisions with ``h`` scaled, at every scale."""
    from fdisyn.evaluation.metrics import operating_plan
    from fdisyn.synthesis.beard_fdf.reference import beard_reference_run

    from tests.design.test_beard_fdf_step import four_state, gain_file, simulate

    flt, F = four_state(window=5, h=0.3, explicit_level=0.05, persistence=3, Y_th=[0.2, 0.2])
    op = operating_plan(gain_file(flt), 20 * 0.01)
    assert op is not None and op.persistence == 3 and op.within == 20
    rng = np.random.default_rng(4)
    R, n, onset = 3, 300, 200
    traces = []
    for _ in range(R):
        mu = np.zeros((n, 2))
        mu[onset:, 0] = 0.2
        traces.append(simulate(flt, F, 0.3 * rng.standard_normal((n, 1)), mu, np.zeros(4), noise=0.25, rng=rng))
    runs = [beard_reference_run(flt, U, Y) for U, Y in traces]
    base = SimpleNamespace(J=np.stack([o.J for o in runs]), status=np.zeros((R, n), np.int8))
    plan = _plan(n, onset, op, 1)
    episodes, first = operating_values(plan, base)
    checked = _rerun_agrees(episodes, first, plan, lambda s: np.stack([beard_reference_run(replace(flt, h=s * flt.h), U, Y).alarm for U, Y in traces]))
    assert checked > 0 and episodes[:, 0].sum() > 0  # alarms seen, false ones among them at half the threshold


def test_the_false_alarms_of_an_iid_chi2_statistic_follow_its_tail():
    """J i.i.d. χ²(k): an episode at factor s starts where J > s h follows J ≤ s h, probability q(1 − q) with
    q = P(χ²_k > s h) (q at the first sample); the count lies in the binomial interval (the upcrossings are
    negatively correlated, so it is narrower than that)."""
    k, h = 3, float(scipy.stats.chi2.isf(1e-3, 3))
    rng = np.random.default_rng(11)
    R, n = 40, 5000
    J = rng.chisquare(k, size=(R, n, 1))
    op = OperatingPlan((SimpleNamespace(kind="chi2", threshold=h),), 1, within=0, delay_s=0.0)
    plan = _plan(n, None, op)
    episodes, first = operating_values(plan, SimpleNamespace(J=J, status=np.zeros((R, n), np.int8)))
    assert (first == -1).all()
    for j, s in enumerate(OPERATING_SCALES):
        q = float(scipy.stats.chi2.sf(s * h, k))
        lo, hi = binomial_interval(R * (n - 1), q * (1 - q), alpha=1e-6)
        assert lo - R <= int(episodes[:, j].sum()) <= hi + R, (s, q)
    assert episodes[:, 0].sum() > 1000 and episodes[:, -1].sum() < 5  # a factor 0.5 alarms often, a factor 2 almost never


def test_detection_never_grows_with_the_threshold_and_the_designs_point_is_the_steps():
    """Detected within D falls (weakly) as every threshold grows; at factor 1 the counts are the step's own, and
    the accumulator refuses a chunk whose factor 1 disagrees with the step."""
    plant = random_plant(5)
    gf = design(plant, "kalman_uio", detector="glr", window=8, arl0=50.0)
    rng = np.random.default_rng(2)
    R, n, onset = 6, 300, 150
    U = rng.standard_normal((R, n, plant.m))
    Y = rng.standard_normal((R, n, plant.p))
    Y[:, onset:, :] += 0.8
    outs = [LinearReference(gf).run(U[i], Y[i]) for i in range(R)]
    runs = SimpleNamespace(J=np.stack([o.J for o in outs]), r=np.stack([o.r for o in outs]), alarm=np.stack([o.alarm for o in outs]),
                           isolated=np.stack([o.isolated for o in outs]), status=np.stack([o.status for o in outs]))
    op = OperatingPlan(tuple(gf.evaluators), 1, within=10, delay_s=10 * gf.Ts)
    plan = _plan(n, onset, op, gf.step.nj)
    summary = summarise_runs(plan, runs)
    acc = MetricsAccumulator(plan, n)
    acc.add(summary)
    m = acc.result(scenario="bias", fault="f", P_f=[e.P_f for e in gf.evaluators], Ts=gf.Ts)
    within = np.asarray(m.operating["detected_within"])
    assert (np.diff(within) <= 0).all() and within[0] > within[-1]
    assert m.operating["episodes"][ONE] == m.false_alarm_episodes
    first = summary.first_alarm
    assert within[ONE] == int(np.sum((first >= 0) & (first <= 10)))
    bad = replace(summary, first_alarm=np.where(summary.first_alarm >= 0, summary.first_alarm + 1, 0))
    with pytest.raises(InternalError, match="differ from the step's"):
        MetricsAccumulator(plan, n).add(bad)


def test_a_skipped_sample_gives_no_curve():
    """A chunk with a non-finite sample has no values (the counters hold there, J does not show it)."""
    from fdisyn.evaluation.metrics import operating_plan

    plant = random_plant(3)
    gf = design(plant, "kalman_uio", detector="glr", window=6, arl0=20.0)
    op = operating_plan(gf, 1.0)
    assert op is not None and op.within == round(1.0 / gf.Ts)
    status = np.zeros((1, 50), np.int8)
    status[0, 10] = 1
    plan = _plan(50, 25, op, gf.step.nj)
    assert operating_values(plan, SimpleNamespace(J=np.zeros((1, 50, gf.step.nj)), status=status)) is None


def test_the_page_pools_the_scenarios_and_states_d(tmp_path):
    """The curve pools every scenario's fault-free time and the faulty scenarios' runs; the figure states D in
    operator's units, stars the design's own point and names a design without a curve."""
    from fdisyn.reporting.figures import _operating_figure, operating_curve
    from fdisyn.reporting.kit import ReportContext
    from fdisyn.problems.sampled_data_example import PROBLEM

    S = len(OPERATING_SCALES)
    episodes = np.maximum(0, 40 - 2 * np.arange(S))  # none from factor 2^(20/16) on

    def metrics(fault, runs, within):
        op = {"scales": list(OPERATING_SCALES), "episodes": episodes.tolist(), "detected_within": within, "delay_s": 10.0}
        return SimpleNamespace(runs=runs, fault_free_samples=3600 * runs, Ts=1.0, operating=op)

    per = {"fault_free": metrics(None, 10, None), "bias": metrics("f", 20, list(range(20, 20 - S, -1)))}
    c = operating_curve(per)
    assert c is not None and c["exposure_s"] == 3600 * 30 and c["runs"] == 20
    assert c["mtbfa_s"][ONE] == pytest.approx(3600 * 30 / (2 * episodes[ONE]))
    assert c["pd"][ONE] == pytest.approx((20 - ONE) / 20) and np.isinf(c["mtbfa_s"][-1])
    lost = {"bias": SimpleNamespace(operating=None)}
    variant = SimpleNamespace(label="default", evaluation=SimpleNamespace(metrics={"direct": per, "lmi": lost}))
    page = _operating_figure(ReportContext(problem=PROBLEM, variants=[variant], directory=tmp_path))
    assert "D = 10 s" in page and "No curve for" in page and "LMI design" in page.split("No curve for")[1]
    assert (tmp_path / "operating_characteristic.png").stat().st_size > 0


# --------------------------------------------------------------------------- copies with scaled thresholds (NAFDF)


@pytest.fixture(scope="module")
def ship_copies(tmp_path_factory: pytest.TempPathFactory):
    """The ship's NAFDF built with copies at thresholds × 0.5 and × 2 (a NAFDF's decisions at other thresholds do
    not follow from one run: its alarm restarts its learning)."""
    from fdisyn.evaluation.built import build, threshold_copies
    from fdisyn.simulation.problem import get_problem

    problem = get_problem("ship_propulsion")
    short = {n: replace(problem.scenario(n), duration=1500.0) for n in ("fault_free", "paper_a_half")}
    problem = replace(problem, scenarios=short)
    root = tmp_path_factory.mktemp("ship_copies")
    built = {"nafdf": build(problem, "nafdf", root / "nafdf")}
    return problem, built, threshold_copies(built, root / "copies", scales=(0.5, 1.0, 2.0))


def test_copies_scale_only_the_fast_detection_thresholds(ship_copies) -> None:
    """A copy's detector thresholds are the design's times its scale, to the bit; everything else in its settings is
    the design's; its gain file reads back (the table checked against the scaled rule), its budget is not claimed,
    and the design's own gain file does not mention the scale."""
    from fdisyn.runtime.gainfile import read_gain_file
    from fdisyn.synthesis.kinds import false_alarm_budget

    _, built, copies = ship_copies
    gf = built["nafdf"].gain_file
    own = gf.extensions["nafdf"]
    assert "threshold_scale" not in own["settings"]
    assert set(copies["nafdf"]) == {0.5, 2.0}  # 1 is the design itself
    for s, b in copies["nafdf"].items():
        pay = read_gain_file(b.directory / "gains.json").extensions["nafdf"]
        assert pay["detector_thresholds"] == [s * v for v in own["detector_thresholds"]]
        assert pay["settings"].pop("threshold_scale") == s
        assert pay["settings"] == own["settings"]
        assert b.gain_file.name != gf.name and b.gain_file.faults == gf.faults
        assert false_alarm_budget(b.gain_file) is None
    assert false_alarm_budget(gf) is not None


def test_a_copy_at_scale_one_is_the_design(ship_copies, tmp_path) -> None:
    """Copying changes nothing but the thresholds: at scale 1 the copy's C gives the design's outputs bit for bit."""
    from fdisyn.codegen.library import codegen
    from fdisyn.runtime.compiled import CompiledDiagnoser
    from fdisyn.runtime.gainfile import write_gain_file
    from fdisyn.synthesis.nafdf.payload import nafdf_scaled

    problem, built, _ = ship_copies
    gf = built["nafdf"].gain_file
    same = nafdf_scaled(gf, 1.0, "ship_same")
    write_gain_file(same, tmp_path / "gains.json")
    copy = CompiledDiagnoser(codegen(tmp_path).library, same)
    batch = problem.run("paper_a_half", [3])
    a, b = built["nafdf"].diagnoser.run(batch.U[0], batch.Y[0]), copy.run(batch.U[0], batch.Y[0])
    assert np.array_equal(a.J, b.J) and np.array_equal(a.alarm, b.alarm) and np.array_equal(a.isolated, b.isolated)
    assert a.alarm.any()  # the comparison saw the fault's alarm


def test_copies_are_compiled_only_where_they_run(ship_copies, tmp_path) -> None:
    """A copy is written as C sources only: the fused Monte Carlo compiles them into its own library, so the copy's
    own library is built on the first use of its diagnoser (the Python path), then gives the fused run's alarms."""
    from fdisyn.evaluation.built import threshold_copies
    from fdisyn.evaluation.evaluate import evaluate

    problem, built, _ = ship_copies
    copy = threshold_copies(built, tmp_path, scales=(2.0,))["nafdf"][2.0]
    assert (copy.artifacts.c_dir / f"{copy.gain_file.name}_casadi.c").is_file() and not copy.artifacts.library.exists()
    ev = evaluate(problem, built, runs=1, scenarios=["paper_a_half"], workers=1, progress=False, copies={"nafdf": {2.0: copy}})
    assert not copy.artifacts.library.exists()  # the fused library ran it
    op = ev.metrics["nafdf"]["paper_a_half"].operating
    batch = problem.run("paper_a_half", [0])
    assert copy.diagnoser.run(batch.U[0], batch.Y[0]).alarm.shape == (batch.Y.shape[1],)
    assert copy.artifacts.library.is_file() and op is not None and op["scales"] == [1.0, 2.0]
    # the design changed: its copy's sources are written again and the library of the earlier ones is gone
    other = threshold_copies(built, tmp_path, scales=(1.5,))["nafdf"][1.5]
    assert other.directory == copy.directory and not other.artifacts.library.exists()
    # compiled on demand, the new library passes the loader's checks for the new gain file (loading it here is
    # refused: this process already loaded that path)
    from fdisyn.codegen.library import codegen
    from fdisyn.runtime.compiled import _check_before_loading
    from fdisyn.runtime.gainfile import gain_file_sha256

    lib = codegen(other.directory, reuse=True).library
    _check_before_loading(lib, gain_file_sha256(other.gain_file), gain_file=other.directory / "gains.json", marked=True)


@pytest.mark.parametrize("scale", [0.0, -1.0, float("nan"), float("inf"), 1e4, "2"])
def test_a_scale_out_of_range_is_refused(ship_copies, scale) -> None:
    from fdisyn.runtime.errors import FdisynError
    from fdisyn.synthesis.nafdf.payload import nafdf_scaled

    _, built, _ = ship_copies
    with pytest.raises(FdisynError, match="threshold_scale must be a number in"):
        nafdf_scaled(built["nafdf"].gain_file, scale, "ship_bad")  # type: ignore[arg-type]


def test_a_tampered_scale_is_refused(ship_copies) -> None:
    """A gain file whose stored scale does not give its stored table is refused where it is read."""
    import copy as copying

    from fdisyn.runtime.errors import GainFileError
    from fdisyn.synthesis.nafdf.payload import nafdf_from_gain_file

    _, _, copies = ship_copies
    gf = copies["nafdf"][2.0].gain_file
    ext = copying.deepcopy(gf.extensions)
    ext["nafdf"]["settings"]["threshold_scale"] = 1.5
    with pytest.raises(GainFileError, match="threshold scale 1.5"):
        nafdf_from_gain_file(replace(gf, extensions=ext))


def test_operating_characteristic_from_copies_is_the_copies_alarms(ship_copies, tmp_path) -> None:
    """The fused Monte Carlo's operating characteristic of a design with copies equals, scale by scale, the false-alarm
    episodes and the runs first alarmed within D counted from each copy's own alarms on the same runs (the copy's own
    library run alone, per run, on the campaign's simulation; the fused library calls each copy's scalar step)."""
    from fdisyn.evaluation.campaign import operating_delay
    from fdisyn.evaluation.compiled_campaign import compiled_campaign
    from fdisyn.evaluation.evaluate import evaluate
    from fdisyn.evaluation.metrics import within_samples

    problem, built, copies = ship_copies
    runs = 3
    ev = evaluate(problem, built, runs=runs, workers=1, progress=False, copies=copies)
    by_scale = {1.0: built["nafdf"], **copies["nafdf"]}
    delay = operating_delay(problem)
    seen = 0
    for sname, m in ev.metrics["nafdf"].items():
        op = m.operating
        assert op is not None and op["scales"] == sorted(by_scale) and op["delay_s"] == delay
        sc = problem.scenario(sname)
        # the compiled campaign's own simulation of the runs (its generator, not NumPy's)
        batch = compiled_campaign(problem, {}, sc, directory=tmp_path).run(_seeds(sname, runs, problem), keep_batch=True).batch
        plan = MetricsPlan.of(sc, built["nafdf"].gain_file, batch.t, None, delay)
        for k, s in enumerate(op["scales"]):
            alarm = np.stack([by_scale[s].diagnoser.run(batch.U[i], batch.Y[i]).alarm for i in range(runs)]).astype(bool)
            episodes, first = _truth(alarm, plan)
            assert op["episodes"][k] == int(episodes.sum()), (sname, s)
            if sc.fault is None:
                assert op["detected_within"] is None
            else:
                onset = np.flatnonzero(plan.active)
                late = onset[np.maximum(first, 0)] - onset[0]
                assert op["detected_within"][k] == int(np.sum((first >= 0) & (late <= within_samples(delay, batch.t[1] - batch.t[0])))), (sname, s)
            seen += int(episodes.sum()) + int((first >= 0).sum())
    assert seen > 0  # the comparison saw alarms


def _seeds(scenario: str, runs: int, problem) -> list[int]:  # noqa: ANN001 - a Problem
    from fdisyn.evaluation.campaign import run_seed

    return [run_seed(0, list(problem.scenarios).index(scenario), i) for i in range(runs)]


@pytest.mark.parametrize("scale", [1.0, 0.0, -2.0, float("nan"), True, "2"])
def test_copies_keyed_by_anything_but_a_scale_other_than_one_are_refused(ship_copies, scale) -> None:
    from fdisyn.evaluation.evaluate import evaluate
    from fdisyn.runtime.errors import ArgumentError

    problem, built, copies = ship_copies
    with pytest.raises(ArgumentError, match="keyed by their threshold scale"):
        evaluate(problem, built, runs=1, workers=1, progress=False, copies={"nafdf": {scale: copies["nafdf"][2.0]}})


def test_copies_of_an_unknown_design_are_refused(ship_copies) -> None:
    from fdisyn.evaluation.evaluate import evaluate
    from fdisyn.runtime.errors import ArgumentError

    problem, built, copies = ship_copies
    with pytest.raises(ArgumentError, match="not among the designs"):
        evaluate(problem, built, runs=1, workers=1, progress=False, copies={"other": copies["nafdf"]})
