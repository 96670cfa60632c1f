"""The Monte Carlo campaign: per-run seeds, the per-run summaries against the stacked reference metrics, chunks,
worker processes and a Dask cluster giving the same metrics to the last bit, a failing run retried and reported,
and the command line's options."""

from __future__ import annotations

import dataclasses
import json
import multiprocessing
import os
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from fdisyn.app.cli import main
from fdisyn.evaluation.built import build
from fdisyn.evaluation.campaign import Campaign, ChunkPlan, ChunkTask, operating_delay, run_seed, run_tasks
from fdisyn.evaluation.evaluate import evaluate
from fdisyn.evaluation.runs import DesignRuns
from fdisyn.evaluation.metrics import ONSET_LAGS, OPERATING_SCALES, MetricsAccumulator, MetricsPlan, operating_plan, scenario_metrics, summarise_runs
from fdisyn.evaluation.progress import quiet
from fdisyn.simulation.problem import Problem, get_problem
from fdisyn.runtime.errors import MonteCarloError
from fdisyn.synthesis.kinds import false_alarm_budget, lorden_bound, lorden_window, onset_lorden_bound, recovery_samples
from hypothesis import given, settings
from hypothesis import strategies as st

SDE = get_problem("sampled_data_example")
RUNS = 7


@pytest.fixture(scope="module")
def sde_built(tmp_path_factory: pytest.TempPathFactory):
    return build(SDE, SDE.default_design, tmp_path_factory.mktemp("sde") / SDE.default_design)


def _doc(ev) -> str:  # noqa: ANN001 - an Evaluation
    return json.dumps(ev.to_dict(), sort_keys=True)


# --------------------------------------------------------------------------- seeds


def test_a_runs_seed_is_its_seed_sequence_word() -> None:
    for seed0, s, i in [(0, 0, 0), (0, 1, 0), (5, 3, 9999), (2**40, 7, 12)]:
        want = int(np.random.SeedSequence([seed0, s, i]).generate_state(2, np.uint64)[0] >> 1)
        assert run_seed(seed0, s, i) == want and 0 <= want < 2**63
    seeds = {run_seed(0, s, i) for s in range(4) for i in range(100)}
    assert len(seeds) == 400  # no two runs of a campaign share a seed


def _eager_tasks(seed0: int, runs: int, scenarios: tuple[tuple[str, int, int], ...]) -> list[ChunkTask]:
    """The chunks as the campaign built them before the plan was lazy: every run's seed drawn up front."""
    tasks = []
    for name, s, size in scenarios:
        for start in range(0, runs, size):
            seeds = tuple(run_seed(seed0, s, i) for i in range(start, min(runs, start + size)))
            tasks.append(ChunkTask(scenario=name, scenario_index=s, start=start, seeds=seeds, keep_batch=start == 0))
    return tasks


@pytest.mark.parametrize(("seed0", "runs", "scenarios"), [
    (0, 1, (("a", 0, 25),)),
    (3, 7, (("fault_free", 0, 3), ("f1", 2, 1), ("f0", 1, 7))),
    (2**40, 103, (("x", 4, 25), ("y", 0, 10))),
])
def test_the_plan_draws_the_seeds_the_eager_list_did(seed0: int, runs: int, scenarios: tuple) -> None:
    plan = ChunkPlan(seed0, runs, scenarios)
    eager = _eager_tasks(seed0, runs, scenarios)
    assert list(plan) == eager and list(plan) == eager  # the same tasks, and the plan can be read again
    assert len(plan) == len(eager)


class _Instant:
    """A campaign whose chunks cost nothing: it records the tasks it was given."""

    def __init__(self) -> None:
        self.seen: list[ChunkTask] = []

    def run_or_locate(self, task: ChunkTask) -> ChunkTask:
        self.seen.append(task)
        return task


def _first_chunks(runs: int, pulled: int) -> tuple[int, list[ChunkTask], int]:
    """Pull the first chunks of a campaign of ``runs`` runs per scenario: the peak memory allocated meanwhile, the
    tasks run, the chunks planned."""
    campaign = _Instant()
    plan = ChunkPlan(0, runs, (("fault_free", 0, 25), ("fault", 1, 25)))
    tracemalloc.start()
    try:
        results = run_tasks(plan, campaign=campaign, spec=None, workers=1)  # type: ignore[arg-type]
        first = [next(results) for _ in range(pulled)]
        results.close()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert first == campaign.seen[:pulled]
    return peak, campaign.seen, len(plan)


def test_the_first_chunks_of_a_huge_campaign_cost_what_those_of_a_small_one_do() -> None:
    """The chunks are made as they are submitted: 10⁹ runs per scenario (4·10⁷ chunks each) start as 10³ do, with
    the same few tasks made and the same memory, nothing allocated per run of the campaign."""
    small_peak, small_seen, small_len = _first_chunks(10**3, 5)
    huge_peak, huge_seen, huge_len = _first_chunks(10**9, 5)
    assert (small_len, huge_len) == (80, 80_000_000)
    assert huge_seen == small_seen and len(huge_seen) <= 5 + 2  # a task is made when a slot frees, not before
    assert huge_peak < small_peak + 64 * 1024, (small_peak, huge_peak)
    assert len(ChunkPlan(0, 10**12, (("a", 0, 25),))) == 4 * 10**10  # counted, not listed
    assert next(iter(ChunkPlan(0, 10**12, (("a", 0, 25),)))).seeds == tuple(run_seed(0, 0, i) for i in range(25))


# --------------------------------------------------------------------------- the summaries against the reference


def _reference_lorden(gf, on: np.ndarray, r: np.ndarray):  # noqa: ANN001, ANN202 - gain file, (I, bound)
    """The Lorden bound as the Monte Carlo computed it when it kept every run: sums run by run."""
    nr = r.shape[2]
    s_on, s_off, n_on, n_off, off2 = np.zeros(nr), np.zeros(nr), 0, 0, np.zeros((nr, nr))
    for ri in r:
        s_on += np.sum(ri[on], axis=0)
        s_off += np.sum(ri[~on], axis=0)
        n_on += int(on.sum())
        n_off += int((~on).sum())
        off2 += ri[~on].T @ ri[~on]
    if n_on == 0 or n_off < 2:
        return None
    mean_off = s_off / n_off
    return lorden_bound(gf, s_on / n_on - mean_off, (off2 - n_off * np.outer(mean_off, mean_off)) / (n_off - 1))


def _reference_onset(gf, on: np.ndarray, active: np.ndarray, r: np.ndarray):  # noqa: ANN001, ANN202 - gain file, float
    """The onset-aware bound from every run kept: the residual at each of the first lags after the onset summed run
    by run, over the runs, minus the fault-free mean."""
    nr = r.shape[2]
    lags = min(ONSET_LAGS, int(on.sum()))
    idx = np.flatnonzero(active)[:lags]
    s_on, s_off, n_on, n_off, off2, lag = np.zeros(nr), np.zeros(nr), 0, 0, np.zeros((nr, nr)), np.zeros((lags, nr))
    for ri in r:
        s_on += np.sum(ri[on], axis=0)
        s_off += np.sum(ri[~on], axis=0)
        n_on += int(on.sum())
        n_off += int((~on).sum())
        off2 += ri[~on].T @ ri[~on]
        lag += ri[idx]
    if n_on == 0 or n_off < 2 or lags == 0:
        return None
    mean_off = s_off / n_off
    cov = (off2 - n_off * np.outer(mean_off, mean_off)) / (n_off - 1)
    return onset_lorden_bound(gf, lag / len(r) - mean_off, s_on / n_on - mean_off, cov, lag_noise=cov / len(r))


def _merged(plan: MetricsPlan, runs: DesignRuns, cuts: list[int], sc=None, gf=None, **result) -> tuple:  # noqa: ANN001, ANN003
    acc = MetricsAccumulator(plan, runs.alarm.shape[1])
    for a, b in zip([0, *cuts], [*cuts, len(runs.alarm)], strict=True):
        acc.add(summarise_runs(plan, DesignRuns(*(getattr(runs, f.name)[a:b] for f in dataclasses.fields(DesignRuns))), sc, gf))
    return acc, acc.result(**result)


@st.composite
def _campaigns(draw: st.DrawFn) -> tuple:
    R, N, nj, n_cls = draw(st.integers(1, 6)), draw(st.integers(2, 40)), draw(st.integers(1, 3)), draw(st.integers(1, 3))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    onset = draw(st.integers(0, N))
    end = draw(st.integers(onset, N))
    active = np.zeros(N, dtype=bool)
    active[onset:end] = True
    recovery = draw(st.integers(0, 5))
    fidx = draw(st.one_of(st.none(), st.integers(0, n_cls - 1)))
    p_alarm = draw(st.floats(0.0, 1.0))
    runs = DesignRuns(
        r=rng.normal(size=(R, N, 2)),
        J=rng.exponential(size=(R, N, nj)) * 2.0,
        alarm=rng.random((R, N)) < p_alarm,
        isolated=rng.integers(-1, n_cls, size=(R, N)).astype(np.int32),
        status=(rng.random((R, N)) < 0.05).astype(np.int8),
    )
    thresholds = tuple(float(x) for x in rng.uniform(0.5, 4.0, nj))
    cuts = sorted(set(draw(st.lists(st.integers(1, max(R - 1, 1)), max_size=3)))) if R > 1 else []
    return runs, active, recovery, fidx, thresholds, cuts


@settings(max_examples=150, deadline=None)
@given(_campaigns())
def test_merged_summaries_equal_the_reference_on_the_stacked_runs(case: tuple) -> None:
    """Random alarms, isolations and statistics, cut into random chunks: every field of the merged metrics equals
    :func:`scenario_metrics` on the stacked arrays (floats included: the same operations on the same numbers)."""
    runs, active, recovery, fidx, thresholds, cuts = case
    quiet_ = ~active
    if active.any():
        last = int(np.flatnonzero(active)[-1])
        quiet_[last + 1 : last + 1 + recovery] = False
    plan = MetricsPlan(active=active, quiet=quiet_, on=active, fault_index=fidx, thresholds=thresholds, lags=min(3, int(active.sum())))
    P_f = [0.01] * len(thresholds)
    acc, got = _merged(plan, runs, cuts, scenario="s", fault="f", P_f=P_f, Ts=0.1, budget_s=5.0, lorden=(0.5, 2.0))
    lag = np.zeros((plan.lags, runs.r.shape[2]))
    for ri in runs.r:  # the per-lag sums, run by run in run order
        lag += ri[np.flatnonzero(active)[: plan.lags]]
    np.testing.assert_array_equal(acc.lag_sums if plan.lags else lag, lag)
    want = scenario_metrics(
        scenario="s", fault="f", fault_index=fidx, active=active, alarm=runs.alarm, isolated=runs.isolated, J=runs.J,
        thresholds=thresholds, P_f=P_f, Ts=0.1, recovery=recovery, nonfinite=int(np.sum(runs.status == 1)), budget_s=5.0,
        lorden=(0.5, 2.0),
    )
    assert got.to_dict() == want.to_dict()


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "python"])
def test_a_real_campaign_equals_the_reference_on_its_stacked_runs(sde_built, compiled: bool) -> None:
    """sampled_data_example, every scenario, on the compiled and on the Python path: the streamed metrics (chunks
    of 3) equal the reference metrics of the same runs simulated and diagnosed at once, Lorden bound and onset-aware
    bound included, to the last bit."""
    d, gf = SDE.default_design, sde_built.gain_file
    if compiled:
        ev = evaluate(SDE, {d: sde_built}, runs=RUNS, chunk=3, workers=1, progress=False)
    else:
        ev = evaluate(SDE, {d: sde_built}, runs=RUNS, chunk=3, workers=1, progress=False, compiled=False)
    campaign = Campaign(SDE, {d: sde_built}, SDE.check_options({}), compiled=compiled)
    for s, name in enumerate(SDE.scenarios):
        sc = SDE.scenario(name)
        chunk = campaign.chunk(sc, ChunkTask(name, s, 0, tuple(run_seed(0, s, i) for i in range(RUNS)), keep_batch=True))
        runs = chunk.designs[d]
        active = sc.active(chunk.t)
        lorden = onset = None
        if sc.fault is not None:
            on = active & (np.cumsum(active) <= (lorden_window(gf) or np.iinfo(np.int64).max))
            lorden = _reference_lorden(gf, on, runs.r)
            onset = _reference_onset(gf, on, active, runs.r)
            assert onset is not None
        want = scenario_metrics(
            scenario=name, fault=sc.fault, fault_index=gf.faults.index(sc.fault) if sc.fault in gf.faults else None,
            active=active, alarm=runs.alarm, isolated=runs.isolated, J=runs.J, thresholds=list(gf.thresholds),
            P_f=[e.P_f for e in gf.evaluators], Ts=gf.Ts, recovery=recovery_samples(gf),
            nonfinite=int(np.sum(runs.status == 1)), budget_s=false_alarm_budget(gf), lorden=lorden,
            operating=operating_plan(gf, operating_delay(SDE)), onset_bound=onset,
        )
        assert want.operating is not None and want.operating["episodes"][OPERATING_SCALES.index(1.0)] == want.false_alarm_episodes
        assert ev.metrics[d][name].to_dict() == want.to_dict(), name
        assert sum(want.fault_free_histogram[0]) == want.fault_free_samples
        assert chunk.batch is not None
        np.testing.assert_array_equal(ev.batches[name].Y[0], chunk.batch.Y[0])
        np.testing.assert_array_equal(ev.examples[d][name].J, runs.J[0])


def test_the_extra_figures_stream_run_by_run(monkeypatch) -> None:  # noqa: ANN001
    """The NAFDF's figures from the per-run values equal those of the stacked runs (its hook called on them)."""
    from types import SimpleNamespace

    from fdisyn.synthesis import kinds
    from fdisyn.synthesis.nafdf.design import nafdf_extra_metrics

    # a kind without a recovery or a Lorden window: the plan's windows are the scenario's alone
    plain = kinds.DiagnoserKind(name="no_kind", summary="", step_builder=None)  # type: ignore[arg-type]
    monkeypatch.setitem(kinds._KINDS, "no_kind", plain)

    names = ("fault_class_a", "fault_size_a", "insufficient_excitation")
    gf = SimpleNamespace(faults=("a",), Ts=1.0, step=SimpleNamespace(statistic_names=names), thresholds=(np.inf,) * 3)
    rng = np.random.default_rng(4)
    J = rng.random((6, 12, 3))
    J[:, -1, 0] = [1, 0, 1, 1, 0, 1]
    iso = np.where(rng.random((6, 12)) < 0.3, 0, -1)
    sc = SimpleNamespace(fault="a", onset=3.0, params={"fault_size": {"a": 0.2}}, active=lambda t: t >= 3.0)
    runs = DesignRuns(r=np.zeros((6, 12, 1)), J=J, alarm=rng.random((6, 12)) < 0.5, isolated=iso.astype(np.int32),
                      status=np.zeros((6, 12), dtype=np.int8))
    plan = MetricsPlan.of(sc, SimpleNamespace(**vars(gf), kind="no_kind"), np.arange(12.0), nafdf_extra_metrics)
    acc, _ = _merged(plan, runs, [2, 5], sc, gf, scenario="s", fault="a", P_f=[0.0] * 3, Ts=1.0)
    stacked = {"alarm": runs.alarm.astype(int), "isolated": iso, "J": J}
    assert nafdf_extra_metrics.reduce(sc, gf, acc.extra) == nafdf_extra_metrics(sc, gf, stacked)


# --------------------------------------------------------------------------- chunks, processes, Dask: the same bits


@pytest.fixture(scope="module")
def serial(sde_built):
    return evaluate(SDE, {SDE.default_design: sde_built}, runs=RUNS, seed0=3, workers=1, progress=False)


def test_a_runs_metrics_do_not_depend_on_its_chunk_or_the_workers(sde_built, serial) -> None:
    built = {SDE.default_design: sde_built}
    assert _doc(evaluate(SDE, built, runs=RUNS, seed0=3, chunk=1, workers=1, progress=False)) == _doc(serial)
    assert _doc(evaluate(SDE, built, runs=RUNS, seed0=3, chunk=2, workers=2, progress=False)) == _doc(serial)
    # fewer runs: the same first runs (a scenario's runs do not depend on how many follow)
    few = evaluate(SDE, built, runs=2, seed0=3, chunk=1, workers=1, progress=False)
    for name in SDE.scenarios:
        np.testing.assert_array_equal(few.batches[name].Y, serial.batches[name].Y)


def test_a_dask_cluster_gives_the_same_metrics(sde_built, serial) -> None:
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            ev = evaluate(SDE, {SDE.default_design: sde_built}, runs=RUNS, seed0=3, client=client, progress=False)
    assert _doc(ev) == _doc(serial)


# --------------------------------------------------------------------------- a failing run


_FAILING_RUN = 4


def _failing_simulate(sc, seeds, **options):  # noqa: ANN001, ANN003, ANN202 - a Problem's simulate
    bad = run_seed(0, list(SDE.scenarios).index(sc.name), _FAILING_RUN)
    if bad in seeds:
        raise FloatingPointError(f"the integrator diverged (seed {bad})")
    return SDE.simulate(sc, seeds, **options)


FAILING = dataclasses.replace(SDE, simulate=_failing_simulate, sample_model=None)
"""sampled_data_example on its Python simulator, whose run 4 of every scenario raises."""

_CALLS: list[int] = []


def _flaky_simulate(sc, seeds, **options):  # noqa: ANN001, ANN003, ANN202 - a Problem's simulate
    _CALLS.append(1)
    if len(_CALLS) == 2:
        raise OSError("a worker's file system hiccuped")
    return SDE.simulate(sc, seeds, **options)


@pytest.mark.parametrize("workers", [1, 2])
def test_a_failing_run_is_retried_then_reported(sde_built, workers: int) -> None:
    with pytest.raises(MonteCarloError) as err:
        evaluate(FAILING, {SDE.default_design: sde_built}, runs=6, chunk=3, workers=workers, progress=False,
                 source=f"{__name__}:FAILING")
    first = next(iter(SDE.scenarios))
    msg = str(err.value)
    assert msg.startswith("a Monte Carlo run failed twice: ")
    assert f"scenario {first!r}, run {_FAILING_RUN} (seed {run_seed(0, 0, _FAILING_RUN)}): FloatingPointError: the integrator diverged" in msg


def _dying_simulate(sc, seeds, **options):  # noqa: ANN001, ANN003, ANN202 - a Problem's simulate
    if multiprocessing.parent_process() is not None and run_seed(0, list(SDE.scenarios).index(sc.name), 1) in seeds:
        os._exit(3)  # a worker process killed (out of memory, a signal) while it runs run 1
    return SDE.simulate(sc, seeds, **options)


DYING = dataclasses.replace(SDE, simulate=_dying_simulate, sample_model=None)


def test_a_worker_process_that_dies_is_replaced_then_reported(sde_built) -> None:
    with pytest.raises(MonteCarloError, match=r"failed twice: scenario 'fault_free', runs 0–1: BrokenProcessPool"):
        evaluate(DYING, {SDE.default_design: sde_built}, runs=4, chunk=2, workers=2, progress=False, source=f"{__name__}:DYING")
    # the next campaign gets a working pool
    ev = evaluate(SDE, {SDE.default_design: sde_built}, runs=4, chunk=2, workers=2, progress=False)
    assert ev.metrics[SDE.default_design]["fault_free"].runs == 4


def test_a_run_that_fails_once_is_retried(sde_built, serial) -> None:
    flaky: Problem = dataclasses.replace(SDE, simulate=_flaky_simulate, sample_model=None)
    _CALLS.clear()
    ev = evaluate(flaky, {SDE.default_design: sde_built}, runs=RUNS, seed0=3, workers=1, progress=False)
    python = evaluate(SDE, {SDE.default_design: sde_built}, runs=RUNS, seed0=3, workers=1, progress=False, compiled=False)
    assert _doc(ev) == _doc(python) and len(_CALLS) > 2


def test_a_problem_that_is_not_built_in_needs_its_source_for_workers(sde_built) -> None:
    from fdisyn.runtime.errors import ArgumentError

    with pytest.raises(ArgumentError, match="is not built in: give source="):
        evaluate(FAILING, {SDE.default_design: sde_built}, runs=2, workers=2, progress=False)
    with pytest.raises(ArgumentError, match="workers must be a whole number ≥ 1"):
        evaluate(SDE, {SDE.default_design: sde_built}, runs=2, workers=0)


# --------------------------------------------------------------------------- the command line


def _one_line(capsys: pytest.CaptureFixture[str], argv: list[str], *parts: str) -> str:
    assert main(argv) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and all(p in lines[0] for p in parts), lines
    return lines[0]


def test_the_monte_carlo_options_and_their_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch) -> None:
    import fdisyn.evaluation.campaign as campaign

    cores = campaign.local_cores()
    monkeypatch.setattr(campaign, "local_cores", lambda: max(2, cores))  # --workers 2 below is no more than the cores
    base = ["evaluate", "sampled_data_example", "--runs", "2", "--out", str(tmp_path / "m.json"), "--workdir", str(tmp_path / "b")]
    _one_line(capsys, [*base, "--workers", "0"], "fdisyn evaluate: error: argument --workers", "worker processes ≥ 1")
    _one_line(capsys, [*base, "--scheduler", "spark"], "argument --scheduler: invalid choice")
    _one_line(capsys, [*base, "--address", "tcp://127.0.0.1:9"], "--address tcp://127.0.0.1:9 needs --scheduler dask")
    _one_line(capsys, [*base, "--scheduler", "dask", "--address", "tcp://127.0.0.1:9"],
              "fdisyn evaluate: error: --address tcp://127.0.0.1:9: cannot reach a Dask scheduler there")
    assert not (tmp_path / "m.json").exists()
    assert main(["--quiet", *base, "--workers", "1"]) == 0
    one = json.loads((tmp_path / "m.json").read_text())
    assert main([*base[:-1], str(tmp_path / "b2"), "--workers", "2"]) == 0  # a new build: a library loads once per path
    assert json.loads((tmp_path / "m.json").read_text()) == one
    assert capsys.readouterr().err == ""  # no bar where stderr is not a terminal
    assert quiet()


def test_more_workers_than_cores_run_as_many_as_the_cores_said_in_one_line(tmp_path: Path, capsys, monkeypatch) -> None:
    """``--workers`` above the cores this process may run on is run as that many processes, said in one line on
    stderr (none with --quiet); the campaign's own chunks bound them again (below)."""
    from types import SimpleNamespace

    import fdisyn.evaluation.built as built
    import fdisyn.evaluation.campaign as campaign
    import fdisyn.evaluation.evaluate as evaluation

    seen: list = []
    monkeypatch.setattr(campaign, "local_cores", lambda: 3)
    monkeypatch.setattr(built, "build", lambda *a, **k: SimpleNamespace(gain_file=SimpleNamespace(name="g")))
    monkeypatch.setattr(evaluation, "evaluate", lambda prob, built, **kw: seen.append(kw) or SimpleNamespace(to_dict=dict))
    argv = ["evaluate", "sampled_data_example", "--runs", "2", "--out", str(tmp_path / "m.json"), "--workdir", str(tmp_path / "b")]
    assert main([*argv, "--workers", "8"]) == 0
    assert capsys.readouterr().err == (
        "fdisyn evaluate: note: --workers 8 is more than the 3 cores this process may run on; running 3 worker processes\n"
    )
    assert main(["--quiet", *argv, "--workers", "8"]) == 0
    assert main([*argv, "--workers", "3"]) == 0
    assert main(argv) == 0
    assert capsys.readouterr().err == ""
    assert [kw["workers"] for kw in seen] == [3, 3, 3, None]


def test_a_pool_has_no_more_processes_than_chunks(monkeypatch) -> None:
    import fdisyn.evaluation.campaign as campaign

    sizes: list[int] = []

    class Pool(campaign._Serial):
        def __init__(self, spec, workers: int) -> None:  # noqa: ANN001 - a CampaignSpec
            sizes.append(workers)
            super().__init__(_Instant())  # type: ignore[arg-type]

    monkeypatch.setattr(campaign, "_Processes", Pool)
    plan = ChunkPlan(0, 30, (("a", 0, 25), ("b", 1, 25)))  # 4 chunks
    spec = campaign.CampaignSpec("sampled_data_example", (), ())
    assert len(list(run_tasks(plan, campaign=None, spec=spec, workers=18))) == 4  # type: ignore[arg-type]
    assert len(list(run_tasks(plan, campaign=None, spec=spec, workers=2))) == 4  # type: ignore[arg-type]
    assert sizes == [4, 2]


def test_the_merged_metrics_hold_as_much_after_many_runs_as_after_few() -> None:
    """The detection delays are kept as a count per delay: the accumulator of 10⁴ runs is the size of that of 10."""
    import pickle

    rng = np.random.default_rng(5)
    R, N = 10, 60
    active = np.zeros(N, dtype=bool)
    active[20:50] = True
    alarm = rng.random((R, N)) < 0.1
    runs = DesignRuns(r=rng.normal(size=(R, N, 2)), J=rng.random((R, N, 1)), alarm=alarm,
                      isolated=np.where(alarm, 0, -1).astype(np.int32), status=np.zeros((R, N), dtype=np.int8))
    plan = MetricsPlan(active=active, quiet=~active, on=active, fault_index=0, thresholds=(0.5,))
    summary = summarise_runs(plan, runs)
    acc = MetricsAccumulator(plan, N)
    acc.add(summary)
    few = len(pickle.dumps(acc))
    for _ in range(999):
        acc.add(summary)
    assert len(pickle.dumps(acc)) < few + 100 and acc.runs == 10_000  # counters a few bytes longer, nothing per run
    got = acc.result(scenario="s", fault="f", P_f=[0.01], Ts=0.5)
    stacked = DesignRuns(*(np.concatenate([getattr(runs, f.name)] * 1000) for f in dataclasses.fields(DesignRuns)))
    want = scenario_metrics(scenario="s", fault="f", fault_index=0, active=active, alarm=stacked.alarm, isolated=stacked.isolated,
                            J=stacked.J, thresholds=[0.5], P_f=[0.01], Ts=0.5, recovery=0, nonfinite=0)
    for key in ("detection_delay_mean_samples", "detection_delay_median_s", "detection_delay_max_s", "detection_delay_mean_s"):
        assert got.to_dict()[key] == want.to_dict()[key], key
