"""Judge built diagnosers (:mod:`fdisyn.evaluation.built`) by a Monte Carlo through their C step.

Every design of a comparison sees the same simulated runs (common random
numbers): run ``i`` of the scenario at position ``s`` uses the seed
:func:`~fdisyn.evaluation.campaign.run_seed` ``(seed0, s, i)`` whatever the
design, so differences between designs are not noise between draws; the runs
are chunked, spread and merged by :mod:`fdisyn.evaluation.campaign`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from fdisyn.evaluation.built import Built
from fdisyn.evaluation.campaign import (
    Campaign,
    CampaignSpec,
    ChunkPlan,
    chunk_runs,
    extra_hooks,
    load_source,
    local_cores,
    operating_delay,
    problem_source,
    run_tasks,
)
from fdisyn.evaluation.metrics import MetricsAccumulator, MetricsPlan, ScenarioMetrics, within_samples
from fdisyn.evaluation.progress import bar, note
from fdisyn.simulation.problem import Batch, Problem
from fdisyn.runtime.compiled import file_sha256
from fdisyn.runtime.errors import ArgumentError
from fdisyn.runtime.gainfile import GainFile
from fdisyn.runtime.reference import RunResult
from fdisyn.synthesis.kinds import false_alarm_budget, lorden_bound, onset_lorden_bound

__all__ = ["Evaluation", "evaluate", "HUGE_CAMPAIGN"]

PLANT_STEPS_PER_CORE_HOUR = 3.6e10
"""The order of the compiled Monte Carlo's speed (10⁷ plant steps per second on one core, ``reports/bench.md``)."""

HUGE_CAMPAIGN = 10**12
"""Plant steps (runs × samples over every scenario) from which :func:`evaluate` first says on stderr how long the
campaign is (about a core-day): such a campaign is run, its memory flat, not refused."""


@dataclass(frozen=True, eq=False)
class Evaluation:
    """Metrics per design and scenario, and one example run of each for figures."""

    problem: str
    runs: int
    seed0: int
    options: Mapping[str, Any]
    metrics: Mapping[str, Mapping[str, ScenarioMetrics]]
    examples: Mapping[str, Mapping[str, RunResult]] = field(default_factory=dict)
    batches: Mapping[str, Batch] = field(default_factory=dict)
    """Run 0 of each scenario (inputs, outputs, truth) for figures."""

    def to_dict(self) -> dict[str, Any]:
        return {
            "problem": self.problem,
            "runs": self.runs,
            "seed0": self.seed0,
            "options": dict(self.options),
            "designs": {d: {s: m.to_dict() for s, m in per.items()} for d, per in self.metrics.items()},
        }


def _fault_free_law(sums: list[Any] | None) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """From the campaign's residual sums: the mean shift over the fault's whole active time, the fault-free mean and
    the fault-free covariance; ``None`` without sums, faulty samples or two fault-free ones."""
    if sums is None:
        return None
    on, off, n_on, n_off, off2 = sums
    if n_on == 0 or n_off < 2:
        return None
    mean_off = off / n_off
    cov = (off2 - n_off * np.outer(mean_off, mean_off)) / (n_off - 1)
    return on / n_on - mean_off, mean_off, cov


def _lorden(gf: GainFile, sums: list[Any] | None) -> tuple[float, float] | None:
    """The fault's Lorden bound from the mean residual shift it brought over the runs and the residual's covariance
    without it (:func:`fdisyn.synthesis.kinds.lorden_bound` of the gain file's kind)."""
    law = _fault_free_law(sums)
    if law is None:
        return None
    shift, _, cov = law
    return lorden_bound(gf, shift, cov)


def _onset(gf: GainFile, sums: list[Any] | None, lag_sums: np.ndarray, runs: int) -> float | None:
    """The fault's onset-aware Lorden bound (:func:`fdisyn.synthesis.kinds.onset_lorden_bound`): the mean residual
    shift at each lag after the onset, the residual's per-lag sum over the runs over their number minus the
    fault-free mean, then the whole-time shift; the covariance as :func:`_lorden`'s, and over the runs the per-lag
    means' noise, whose information is taken off each lag's."""
    law = _fault_free_law(sums)
    if law is None or lag_sums.size == 0 or runs < 1:
        return None
    shift, mean_off, cov = law
    # each lag's mean is over the runs: its error's covariance is the residual's over their number
    return onset_lorden_bound(gf, lag_sums / runs - mean_off[None, :], shift, cov, lag_noise=cov / runs)


def _copies_operating(own: MetricsAccumulator, copies: Mapping[float, MetricsAccumulator], delay_s: float, Ts: float) -> dict[str, Any]:
    """A design's operating characteristic from its own runs (scale 1) and its copies' with scaled thresholds
    (:attr:`~fdisyn.evaluation.metrics.ScenarioMetrics.operating`'s fields)."""
    runs = {1.0: own, **copies}
    scales = sorted(runs)
    within = within_samples(delay_s, Ts)
    active = bool(own.plan.active.any())
    return {"scales": scales, "episodes": [int(runs[s].episodes) for s in scales],
            "detected_within": [runs[s].detected_within(within) for s in scales] if active else None, "delay_s": float(delay_s)}


def evaluate(
    problem: Problem,
    built: Mapping[str, Built],
    *,
    runs: int,
    seed0: int = 0,
    scenarios: Sequence[str] | None = None,
    chunk: int | None = None,
    workers: int | None = None,
    client: Any = None,
    source: str | Path | None = None,
    progress: bool = True,
    compiled: bool = True,
    copies: Mapping[str, Mapping[float, Built]] | None = None,
    **options: Any,
) -> Evaluation:
    """Monte Carlo of every scenario through every built diagnoser's C step.

    ``chunk``: runs simulated at once (default :func:`~fdisyn.evaluation.campaign.chunk_runs`, from the runs'
    length). ``workers``: local processes (default: every core; ``1``: here); ``client``: a
    ``dask.distributed.Client`` to run on instead. Worker processes rebuild the problem from ``source`` (a plant
    file's path or ``module:attribute``; a built-in problem needs none): without one, a plant file's problem runs
    here. The metrics are the same, to the last bit, however the runs are spread. ``progress``: a bar per
    scenario (:mod:`fdisyn.evaluation.progress`). ``compiled``: simulate and diagnose each chunk in one generated C
    call where the problem has a sample model (``False``: its Python simulator, NumPy's random numbers).
    ``copies``: per design, its copies with scaled thresholds (:func:`~fdisyn.evaluation.built.threshold_copies`),
    run beside it on the same runs; its metrics' ``operating`` is then their false-alarm episodes and runs detected
    within the problem's :func:`~fdisyn.evaluation.campaign.operating_delay`, scale by scale, its own at 1.

    The chunks are planned lazily (:class:`~fdisyn.evaluation.campaign.ChunkPlan`): each chunk's seeds are drawn
    when it is submitted, so memory does not grow with ``runs`` and the first chunk starts at once; a campaign of
    :data:`HUGE_CAMPAIGN` plant steps or more is announced in one line on stderr first (with ``progress``, unless
    :func:`~fdisyn.evaluation.progress.set_quiet`). ``workers`` is bounded by the campaign's chunks, not by the
    cores (the command line caps it there). Interrupted (Ctrl-C) or failing, the campaign's chunks in flight are
    dropped and its worker processes ended before the exception propagates.
    """
    if isinstance(runs, bool) or not isinstance(runs, int) or runs < 1:
        raise ArgumentError(f"runs must be a whole number ≥ 1; got {runs!r}")
    if isinstance(seed0, bool) or not isinstance(seed0, int) or seed0 < 0:
        raise ArgumentError(f"seed0 must be a whole number ≥ 0 (NumPy seeds are non-negative); got {seed0!r}")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise ArgumentError(f"workers must be a whole number ≥ 1 (or None: every core); got {workers!r}")
    if chunk is not None and (isinstance(chunk, bool) or not isinstance(chunk, int) or chunk < 1):
        raise ArgumentError(f"chunk must be a whole number ≥ 1 (or None); got {chunk!r}")
    names = list(scenarios) if scenarios is not None else list(problem.scenarios)
    order = list(problem.scenarios)
    for sname in names:
        problem.scenario(sname)
    checked = problem.check_options(options)
    copies = {d: dict(c) for d, c in (copies or {}).items() if c}
    unknown = sorted(set(copies) - set(built))
    if unknown:
        raise ArgumentError(f"copies of design(s) {unknown} that are not among the designs {sorted(built)}")
    bad = sorted({repr(s) for c in copies.values() for s in c
                  if isinstance(s, bool) or not isinstance(s, (int, float)) or not (math.isfinite(s) and s > 0) or s == 1})
    if bad:
        raise ArgumentError(f"copies are keyed by their threshold scale, a positive finite number other than 1 (the design "
                            f"itself); got {', '.join(bad)}")
    copy_keys = {d: {s: f"{d}@{s!r}" for s in c} for d, c in copies.items()}
    runs_built = {**built, **{copy_keys[d][s]: b for d, c in copies.items() for s, b in c.items()}}
    src = problem_source(problem) if source is None else str(Path(source).absolute() if Path(source).is_file() else source)
    if src is not None and source is not None and load_source(src).name != problem.name:
        raise ArgumentError(f"source {src!r} is problem {load_source(src).name!r}, not {problem.name!r}")
    spec = None
    if src is not None:
        spec = CampaignSpec(
            source=src,
            options=tuple(sorted(options.items())),
            built=tuple((d, str(b.directory.absolute()), file_sha256(b.directory / "gains.json")) for d, b in runs_built.items()),
            scenarios=tuple(problem.scenario(n) for n in names),
            compiled=compiled,
            copies=tuple(k for keys in copy_keys.values() for k in keys.values()),
        )
    elif workers is not None and workers > 1 or client is not None:
        raise ArgumentError(
            f"problem {problem.name!r} is not built in: give source= (its plant file) to run it on workers, or workers=1"
        )
    if not (compiled and problem.sample_model is not None):
        for b in runs_built.values():  # the Python path runs each copy's own library: compiled here, before a worker loads it
            b.diagnoser
    copy_names = tuple(k for keys in copy_keys.values() for k in keys.values())
    campaign = Campaign(problem, runs_built, options, extra_hooks(problem, built), compiled=compiled, copies=copy_names)
    ts = min((b.gain_file.Ts for b in built.values()), default=1.0)
    delay_s = operating_delay(problem)
    samples = {sname: int(problem.scenario(sname).duration / ts) + 1 for sname in names}
    tasks = ChunkPlan(seed0, runs, tuple((sname, order.index(sname), chunk or chunk_runs(samples[sname])) for sname in names))
    steps = runs * sum(samples.values())
    if progress and steps >= HUGE_CAMPAIGN:
        note(f"{problem.name}: {runs:,} runs of each of {len(names)} scenarios, {steps:.1e} plant steps in all, about "
             f"{steps / PLANT_STEPS_PER_CORE_HOUR:,.0f} core-hours at 10⁷ steps per second and core; memory stays flat, "
             "Ctrl-C stops it")
    metrics: dict[str, dict[str, ScenarioMetrics]] = {d: {} for d in built}
    examples: dict[str, dict[str, RunResult]] = {d: {} for d in built}
    batches: dict[str, Batch] = {}
    acc: dict[str, MetricsAccumulator] = {}
    done = {sname: 0 for sname in names}
    results = run_tasks(tasks, campaign=campaign, spec=spec, workers=local_cores() if workers is None else workers, client=client)
    try:
        for sname in names:
            sc = problem.scenario(sname)
            with bar(runs, f"{problem.name} {sname}", "run", shown=progress) as shown:
                while done[sname] < runs:
                    res = next(results)
                    assert res.task.scenario == sname, "chunks arrive in task order"
                    if res.batch is not None:
                        batches[sname] = res.batch
                        for d, b in built.items():
                            examples[d][sname] = b.diagnoser.run(res.batch.U[0], res.batch.Y[0])
                    for d, summary in res.summaries.items():
                        if d not in acc:
                            acc[d] = MetricsAccumulator(campaign.plan(sc, d, res.t), len(res.t))
                        acc[d].add(summary)
                    done[sname] += len(res.task.seeds)
                    shown.update(len(res.task.seeds))
            for d, b in built.items():
                gf = b.gain_file
                a = acc.pop(d)
                m = a.result(scenario=sname, fault=sc.fault, P_f=[e.P_f for e in gf.evaluators], Ts=gf.Ts,
                             budget_s=false_alarm_budget(gf), lorden=_lorden(gf, a.sums),
                             onset_bound=_onset(gf, a.sums, a.lag_sums, a.runs))
                hook = campaign.extra.get(d)
                if hook is not None:
                    m = replace(m, extra=dict(hook.reduce(sc, gf, a.extra)))
                if d in copies and delay_s is not None:
                    m = replace(m, operating=_copies_operating(a, {s: acc.pop(k) for s, k in copy_keys[d].items()}, delay_s, gf.Ts))
                metrics[d][sname] = m
            for k in [k for k in acc if k not in built]:  # the copies of a design without a stated delay
                acc.pop(k)
        leftover = next(results, None)  # the generator ends: the pool is kept for the next campaign
        assert leftover is None, "every chunk was merged"
    finally:
        results.close()  # stopped early (Ctrl-C, an error): the chunks in flight dropped, the workers ended
    return Evaluation(
        problem=problem.name,
        runs=runs,
        seed0=seed0,
        options=checked,
        metrics=metrics,
        examples=examples,
        batches=batches,
    )
