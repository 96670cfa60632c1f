"""The notebook plots (:mod:`fdisyn.reporting.plots`) draw what the run and the Monte Carlo hold.

On two tanks in cascade whose second level sensor takes a bias (ARCHITECTURE.md's worked problem, written out
here), designed with ``kalman_uio``: every function returns a Figure whose lines are checked against numbers
computed here independently (the threshold at 1 on the J / threshold axis, the alarm ticks at exactly the samples
whose alarm holds, the histogram against ``numpy.histogram`` of the fault-free statistics, the detected share against
the runs' own alarms), and the user's labels with their units reach the axes.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import scipy.stats
from fdisyn.evaluation.evaluate import Evaluation
from fdisyn.evaluation.metrics import DETECTION_GOAL, HISTOGRAM_EDGES, scenario_metrics
from fdisyn.models.linear import LinearPlant
from fdisyn.reporting.plots import plot_detection, plot_laws, plot_trace
from fdisyn.runtime.errors import ArgumentError
from fdisyn.runtime.gainfile import GainFile
from fdisyn.runtime.monitor import Monitor
from fdisyn.runtime.reference import RunResult
from fdisyn.runtime.trace import Trace
from fdisyn.simulation.problem import Batch, Scenario
from fdisyn.simulation.simulate import SensorFaultSpec, Signal, simulate_linear
from matplotlib.figure import Figure

TS = 1.0
A1, A2, B = 0.05, 0.04, 0.02
PLANT = LinearPlant.create(
    A=[[1 - A1 * TS, 0.0], [A1 * TS, 1 - A2 * TS]], B=[[B * TS], [0.0]], C=np.eye(2),
    Q=np.diag([1e-6, 1e-6]), R=np.diag([1e-4, 1e-4]), Ts=TS, inputs=["pump"], outputs=["h1", "h2"],
)
PUMP = Signal("square", amplitude=1.0, period=600.0)
X0 = np.linalg.solve(np.eye(2) - PLANT.A, PLANT.B[:, 0])
LABELS = {"h1": "level of tank 1 (m)", "h2": "level of tank 2 (m)", "pump": "pump command (1)", "kalman": "Kalman bank",
          "bias": "h2 reads high"}
DURATION, ONSET, BIAS = 600.0, 300.0, 0.05  # s, s, m
RUNS = 4
FACTORS = (0.25, 0.5, 2.0)


def _scenario(size: float | None) -> Scenario:
    if size is None:
        return Scenario("nominal", "no fault", duration=DURATION)
    return Scenario(f"bias_x{size:g}", f"h2 reads {BIAS * size:g} m high", duration=DURATION, fault="h2", onset=ONSET,
                    params={"sensor_faults": [SensorFaultSpec("h2", "offset", BIAS * size)]})


def _batch(size: float | None, runs: int = RUNS) -> Batch:
    return simulate_linear(PLANT, _scenario(size), list(range(11, 11 + runs)), x0=X0, inputs=[PUMP], unknown_inputs=[])


def _runs(gf: GainFile, batch: Batch) -> list[RunResult]:
    return [Monitor(gf, backend="reference").run(batch.U[i], batch.Y[i]) for i in range(len(batch.seeds))]


def _metrics(gf: GainFile, batch: Batch, runs: list[RunResult]) -> object:
    sc = batch.scenario
    return scenario_metrics(
        scenario=sc.name, fault=sc.fault, fault_index=None if sc.fault is None else list(gf.faults).index(sc.fault),
        active=batch.active, alarm=np.stack([r.alarm for r in runs]), isolated=np.stack([r.isolated for r in runs]),
        J=np.stack([r.J for r in runs]), thresholds=list(gf.thresholds), P_f=[e.P_f for e in gf.evaluators], Ts=gf.Ts,
        recovery=0,
    )


@pytest.fixture(scope="module")
def gf() -> GainFile:
    import fdisyn

    return fdisyn.design(PLANT, method="kalman_uio", name="kalman", arl0=600.0)


@pytest.fixture(scope="module")
def faulty(gf: GainFile) -> tuple[Batch, list[RunResult]]:
    b = _batch(1.0)
    return b, _runs(gf, b)


@pytest.fixture(scope="module")
def campaign(gf: GainFile, faulty: tuple[Batch, list[RunResult]]) -> SimpleNamespace:
    """A Monte Carlo as ``fdisyn reproduce`` keeps it, run here through the NumPy reference: the scenarios at their
    own size (``evaluation``) and the bias scaled (``sweep``, duck-typed as the report's sweep), with each run."""
    nominal = _batch(None)
    nominal_runs = _runs(gf, nominal)
    b1, r1 = faulty
    main = Evaluation(problem="tanks", runs=RUNS, seed0=0, options={},
                      metrics={"kalman": {"nominal": _metrics(gf, nominal, nominal_runs), "bias": _metrics(gf, b1, r1)}})
    scaled, runs = {}, {1.0: (b1, r1)}
    for f in FACTORS:
        b = _batch(f)
        runs[f] = (b, _runs(gf, b))
        scaled[f"bias_x{f:g}"] = _metrics(gf, b, runs[f][1])
    sweep = SimpleNamespace(
        factors=FACTORS, scenarios={"bias": {f: f"bias_x{f:g}" for f in FACTORS}},
        evaluation=Evaluation(problem="tanks", runs=RUNS, seed0=0, options={}, metrics={"kalman": scaled}),
        detection_grid=(0.25, 0.5, 1.0, 2.0),
    )
    variant = SimpleNamespace(evaluation=main, built={"kalman": SimpleNamespace(gain_file=gf)}, sweep=sweep)
    return SimpleNamespace(main=main, sweep=sweep, variant=variant, nominal=(nominal, nominal_runs), runs=runs)


# ---------------------------------------------------------------------------------------------------- plot_trace


def test_the_trace_shows_statistics_over_thresholds_alarms_and_isolation(gf: GainFile, faulty) -> None:
    batch, results = faulty
    trace, res = batch.trace(0), results[0]
    alarm = np.asarray(res.alarm, dtype=bool)
    assert 0 < alarm.sum() < alarm.size  # alarms after the onset, none for most of the fault-free half
    fig = plot_trace(gf, trace, res)
    assert isinstance(fig, Figure)
    ax_j, ax_i = fig.axes
    thr = np.asarray(gf.thresholds)
    lines = {ln.get_label(): ln for ln in ax_j.get_lines()}
    # each statistic over its threshold: an alarm is above 1, the dashed line at exactly 1
    for j, name in enumerate(gf.step.statistic_names):
        np.testing.assert_allclose(lines[name].get_ydata(), np.maximum(res.J[:, j] / thr[j], 1e-6))
    threshold = next(ln for ln in ax_j.get_lines() if ln.get_label().startswith("threshold"))
    assert list(threshold.get_ydata()) == [1.0, 1.0]
    # the alarm ticks at exactly the samples whose alarm holds
    ticks = lines["alarm"]
    np.testing.assert_array_equal(ticks.get_xdata(), trace.t[alarm])
    assert ticks.get_linestyle() == "None"
    # the isolated fault over time, the gain file's faults on the axis
    assert [t.get_text() for t in ax_i.get_yticklabels()] == ["none", *gf.faults]
    np.testing.assert_array_equal(ax_i.get_lines()[0].get_ydata(), res.isolated)
    # the fault-active window shaded from the onset to the end
    (span,) = [p for p in ax_j.patches if p.get_label() == "fault active"]
    x0, x1 = span.get_x(), span.get_x() + span.get_width()
    assert (x0, x1) == (trace.t[batch.active][0], trace.t[-1]) and x0 == ONSET
    assert ax_i.get_xlabel() == "time (s)" and ax_j.get_ylabel() == "J / threshold"


def test_the_trace_is_run_through_the_reference_when_no_result_is_given(gf: GainFile, faulty) -> None:
    batch, results = faulty
    fig = plot_trace(gf, batch.trace(0))
    ticks = next(ln for ln in fig.axes[0].get_lines() if ln.get_label() == "alarm")
    np.testing.assert_array_equal(ticks.get_xdata(), batch.t[np.asarray(results[0].alarm, dtype=bool)])
    np.testing.assert_array_equal(fig.axes[1].get_lines()[0].get_ydata(), results[0].isolated)


def test_the_trace_shows_the_users_names_and_units(gf: GainFile, faulty) -> None:
    batch, results = faulty
    fig = plot_trace(gf, batch.trace(0), results[0], labels=LABELS, signals=["h2", "pump"])
    ax_h2, ax_pump, _, ax_i = fig.axes
    assert ax_h2.get_ylabel() == "level of tank 2 (m)" and ax_pump.get_ylabel() == "pump command (1)"
    np.testing.assert_array_equal(ax_h2.get_lines()[0].get_ydata(), batch.Y[0][:, 1])
    assert [t.get_text() for t in ax_i.get_yticklabels()] == ["none", *(LABELS[f] for f in gf.faults)]


def test_the_trace_refuses_what_does_not_match_the_gain_file(gf: GainFile, faulty) -> None:
    batch, results = faulty
    tr = batch.trace(0)
    swapped = Trace(t=tr.t, inputs=tr.inputs, outputs=tr.outputs[::-1], U=tr.U, Y=tr.Y)
    with pytest.raises(ArgumentError, match=r"trace outputs \['h2', 'h1'\] do not match"):
        plot_trace(gf, swapped, results[0])
    short = RunResult(r=results[0].r[:5], J=results[0].J[:5], alarm=results[0].alarm[:5], isolated=results[0].isolated[:5],
                      status=results[0].status[:5], state=results[0].state)
    with pytest.raises(ArgumentError, match="expected the trace's 600 samples"):
        plot_trace(gf, tr, short)
    with pytest.raises(ArgumentError, match="not a signal of the trace"):
        plot_trace(gf, tr, results[0], signals=["h3"])
    with pytest.raises(ArgumentError, match="expected a fdisyn.runtime.trace.Trace"):
        plot_trace(gf, batch, results[0])  # type: ignore[arg-type]


# ----------------------------------------------------------------------------------------------------- plot_laws


def test_the_laws_are_the_fault_free_histograms_against_chi2(gf: GainFile, campaign) -> None:
    fig = plot_laws(campaign.main, "kalman", gain_file=gf, labels=LABELS)
    assert isinstance(fig, Figure)
    panels = [ax for ax in fig.axes if ax.get_visible()]
    assert len(panels) == len(gf.step.statistic_names)
    # the fault-free samples, counted here: the nominal runs whole and the faulty runs before the onset
    nominal, nominal_runs = campaign.nominal
    b1, r1 = campaign.runs[1.0]
    for j, (ax, ev) in enumerate(zip(panels, gf.evaluators, strict=True)):
        J = np.concatenate([r.J[:, j] for r in nominal_runs] + [r.J[~b1.active, j] for r in r1])
        h = float(gf.thresholds[j])
        (stairs,) = ax.patches
        data = stairs.get_data()
        values, edges = data.values, data.edges
        np.testing.assert_allclose(edges, HISTOGRAM_EDGES * h)
        counts, _ = np.histogram(J, bins=edges)
        density = counts / (J.size * np.diff(edges))
        np.testing.assert_allclose(np.nan_to_num(values), density, rtol=1e-12)
        (law,) = [ln for ln in ax.get_lines() if ln.get_linestyle() == "-"]  # the law, drawn solid over the bins
        np.testing.assert_allclose(law.get_ydata(), scipy.stats.chi2.pdf(law.get_xdata(), ev.dof))
        assert [ln.get_xdata()[0] for ln in ax.get_lines() if ln.get_linestyle() == "--"] == [h]  # the threshold
        assert gf.step.statistic_names[j] in ax.get_title() and f"χ²({ev.dof})" in ax.get_title()


def test_the_laws_from_a_report_variant_and_their_refusals(gf: GainFile, campaign) -> None:
    fig = plot_laws(campaign.variant, "kalman", labels={gf.step.statistic_names[0]: "first residual's χ² (1)"})
    assert fig.axes[0].get_title().startswith("first residual's χ² (1)")
    with pytest.raises(ArgumentError, match=r"expected the name of a design of this Monte Carlo, one of \['kalman'\]"):
        plot_laws(campaign.main, "luenberger", gain_file=gf)
    with pytest.raises(ArgumentError, match="pass gain_file="):
        plot_laws(campaign.main, "kalman")
    with pytest.raises(ArgumentError, match="takes a Monte Carlo result"):
        plot_laws(object(), "kalman", gain_file=gf)


# ------------------------------------------------------------------------------------------------ plot_detection


def test_detection_against_size_is_the_share_of_runs_that_alarm(gf: GainFile, campaign) -> None:
    fig = plot_detection(campaign.sweep, campaign.main, labels=LABELS)
    assert isinstance(fig, Figure)
    ax_delay, ax_share = fig.axes[:2]
    sizes = sorted(campaign.runs)
    solid, dashed = [ln for ln in ax_share.get_lines() if ln.get_linestyle() in ("-", "--") and len(ln.get_xdata()) == len(sizes)]
    np.testing.assert_array_equal(solid.get_xdata(), sizes)
    # detected: a run with an alarm while the fault is active; named: its most frequent decision then is h2
    detected, named = [], []
    for f in sizes:
        b, rs = campaign.runs[f]
        detected.append(np.mean([r.alarm[b.active].any() for r in rs]))
        named.append(np.mean([np.bincount(r.isolated[b.active & (r.alarm == 1)] + 1, minlength=len(gf.faults) + 1)[1:].argmax()
                              == gf.faults.index("h2") if (r.alarm[b.active] == 1).any() else False for r in rs]))
    np.testing.assert_allclose(solid.get_ydata(), detected)
    assert detected[-1] == 1.0 and detected[0] < 1.0  # a quarter of the bias is not always seen, twice it always
    np.testing.assert_allclose(dashed.get_ydata(), named)
    goal = [ln for ln in ax_share.get_lines() if ln.get_linestyle() == ":"]
    assert [g.get_ydata()[0] for g in goal] == [DETECTION_GOAL]
    assert ax_delay.get_title(loc="left") == "Kalman bank"
    assert [t.get_text() for t in fig.legends[0].get_texts()] == ["h2 reads high"]
    assert ax_delay.get_ylabel() == "mean delay (s)"


def test_detection_without_the_scenarios_own_runs_and_its_refusals(campaign) -> None:
    fig = plot_detection(campaign.sweep)
    xs = fig.axes[1].get_lines()[0].get_xdata()
    np.testing.assert_array_equal(xs, sorted(FACTORS))
    with pytest.raises(ArgumentError, match="takes a fault-size sweep"):
        plot_detection(campaign.main)
    with pytest.raises(ArgumentError, match="holds no scenario"):
        plot_detection(SimpleNamespace(scenarios={}, evaluation=campaign.main, detection_grid=(1.0,)))


# ----------------------------------------------------------------------------------------------------- the report


def test_the_report_draws_these_figures(tmp_path, gf: GainFile, faulty, campaign) -> None:
    """The page's run, law and fault-size figures are these functions' figures, saved as the page saves any."""
    from fdisyn.reporting import figures
    from fdisyn.reporting.kit import ReportContext

    batch, results = faulty
    main = Evaluation(problem="tanks", runs=RUNS, seed0=0, options={}, metrics=campaign.main.metrics,
                      examples={"kalman": {"bias": results[0]}}, batches={"bias": batch})
    variant = SimpleNamespace(evaluation=main, built=campaign.variant.built, sweep=campaign.sweep, label="default")
    problem = SimpleNamespace(name="tanks", labels=LABELS, scenarios={"bias": batch.scenario})
    page = ReportContext(problem=problem, variants=[variant], directory=tmp_path / "page")  # type: ignore[arg-type]
    own = ReportContext(problem=problem, variants=[variant], directory=tmp_path / "own")  # type: ignore[arg-type]
    page.directory.mkdir()
    own.directory.mkdir()
    figures.run_figures(page)
    figures._law_figures(page)
    figures._sweep_figure(page)
    own.figure("kalman_bias", plot_trace(gf, batch.trace(0), results[0], labels=LABELS), "")
    own.figure("law_kalman", plot_laws(variant, "kalman", labels=LABELS), "")
    own.figure("fault_size_sweep", plot_detection(campaign.sweep, main, labels=LABELS), "")
    assert sorted(page.figures) == sorted(own.figures) == ["fault_size_sweep.png", "kalman_bias.png", "law_kalman.png"]
    for name in own.figures:
        assert (page.directory / name).read_bytes() == (own.directory / name).read_bytes(), name
