"""Build (design → gain file → C) and judge (Monte Carlo through the C step).

Every design of a comparison sees the same simulated runs (common random
numbers): run ``i`` of a scenario uses seed ``seed0 + i`` whatever the design,
so differences between designs are not noise between draws.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from fdisyn.codegen.library import CodegenResult, codegen
from fdisyn.evaluation.metrics import ScenarioMetrics, scenario_metrics
from fdisyn.models.problem import Batch, Problem, Scenario
from fdisyn.runtime.compiled import CompiledDiagnoser
from fdisyn.runtime.errors import ArgumentError
from fdisyn.runtime.gainfile import GainFile, write_gain_file
from fdisyn.runtime.reference import RunResult
from fdisyn.synthesis.registry import extra_metrics, false_alarm_budget, lorden_bound, lorden_window, recovery_samples

__all__ = ["Built", "build", "Evaluation", "evaluate", "progress_printer"]

Progress = Callable[[str], None]


def progress_printer(prefix: str) -> Progress:
    """Progress lines on stderr (long runs must show that they are alive)."""

    def say(msg: str) -> None:
        print(f"[{prefix}] {msg}", file=sys.stderr, flush=True)

    return say


def _quiet(msg: str) -> None:
    return None


@dataclass(frozen=True, eq=False)
class Built:
    """A designed, written and compiled diagnoser."""

    gain_file: GainFile
    directory: Path
    artifacts: CodegenResult
    diagnoser: CompiledDiagnoser


def build(problem: Problem, design: str, directory: str | Path, **options: Any) -> Built:
    """Design, write ``DIR/gains.json``, generate and compile the C, load it."""
    d = Path(directory)
    gf = problem.design(design, **options)
    write_gain_file(gf, d / "gains.json")
    art = codegen(d)
    return Built(gain_file=gf, directory=d, artifacts=art, diagnoser=CompiledDiagnoser(art.library, gf))


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
            "seeds": [self.seed0, self.seed0 + self.runs - 1],
            "options": dict(self.options),
            "designs": {d: {s: m.to_dict() for s, m in per.items()} for d, per in self.metrics.items()},
        }


MONTE_CARLO_MEMORY = 4 * 2**30
"""Bytes the per-run results of one scenario may take: every run's alarm flags,
isolated faults and statistics are kept for the metrics (16 + 8·nj bytes per
sample and design). 4 GiB fits a laptop; larger campaigns are refused with the
number of runs that fits, instead of running out of memory hours in."""


def _lorden(gf: GainFile, sums: list[Any]) -> tuple[float, float] | None:
    """The fault's Lorden bound from the mean residual shift it brought over the runs and the residual's covariance
    without it (:func:`fdisyn.synthesis.registry.lorden_bound` of the gain file's kind)."""
    on, off, n_on, n_off, off2 = sums
    if n_on == 0 or n_off < 2:
        return None
    mean_off = off / n_off
    cov = (off2 - n_off * np.outer(mean_off, mean_off)) / (n_off - 1)
    return lorden_bound(gf, on / n_on - mean_off, cov)


def evaluate(
    problem: Problem,
    built: Mapping[str, Built],
    *,
    runs: int,
    seed0: int = 0,
    scenarios: Sequence[str] | None = None,
    chunk: int = 25,
    progress: Progress = _quiet,
    **options: Any,
) -> Evaluation:
    """Monte Carlo of every scenario through every built diagnoser's C step."""
    if isinstance(runs, bool) or not isinstance(runs, int) or runs < 1:
        raise ArgumentError(f"runs must be a whole number ≥ 1; got {runs!r}")
    if isinstance(seed0, bool) or not isinstance(seed0, int) or seed0 < 0:
        raise ArgumentError(f"seed0 must be a whole number ≥ 0 (NumPy seeds are non-negative); got {seed0!r}")
    names = list(scenarios) if scenarios is not None else list(problem.scenarios)
    for sname in names:  # refuse a campaign whose kept results cannot fit before simulating anything
        duration = problem.scenario(sname).duration
        per_run = sum((int(duration / b.gain_file.Ts) + 1) * (16 + 8 * b.gain_file.step.nj) for b in built.values())
        if runs * per_run > MONTE_CARLO_MEMORY:
            raise ArgumentError(
                f"runs = {runs}: scenario {sname!r} would keep {runs * per_run / 2**30:.1f} GiB of per-run results "
                f"(alarm, isolated fault and statistics of every sample); expected at most "
                f"{MONTE_CARLO_MEMORY // per_run} runs ({MONTE_CARLO_MEMORY // 2**30} GiB)"
            )
    metrics: dict[str, dict[str, ScenarioMetrics]] = {d: {} for d in built}
    examples: dict[str, dict[str, RunResult]] = {d: {} for d in built}
    batches: dict[str, Batch] = {}
    for sname in names:
        sc: Scenario = problem.scenario(sname)
        acc: dict[str, dict[str, list[np.ndarray]]] = {d: {"alarm": [], "isolated": [], "J": []} for d in built}
        # residual sums while the fault is active and while it is not: the mean shift the fault brings (Lorden bound)
        shift: dict[str, list[Any]] = {
            d: [np.zeros(b.gain_file.step.nr), np.zeros(b.gain_file.step.nr), 0, 0, np.zeros((b.gain_file.step.nr,) * 2)] for d, b in built.items()
        }
        nonfinite = {d: 0 for d in built}
        windows = {d: lorden_window(b.gain_file) or np.iinfo(np.int64).max for d, b in built.items()}
        t = active = None
        for start in range(0, runs, chunk):
            seeds = range(seed0 + start, seed0 + min(runs, start + chunk))
            batch = problem.run(sc, seeds, **options)
            t, active = batch.t, batch.active
            if start == 0:
                batches[sname] = _first_run(batch)
            for dname, b in built.items():
                for i in range(len(batch.seeds)):
                    res = b.diagnoser.run(batch.U[i], batch.Y[i])
                    acc[dname]["alarm"].append(res.alarm)
                    acc[dname]["isolated"].append(res.isolated)
                    acc[dname]["J"].append(res.J)
                    if sc.fault is not None:
                        on = batch.active & (np.cumsum(batch.active) <= windows[dname])
                        sums = shift[dname]
                        sums[0] += np.sum(res.r[on], axis=0)
                        sums[1] += np.sum(res.r[~on], axis=0)
                        sums[2] += int(on.sum())
                        sums[3] += int((~on).sum())
                        sums[4] += res.r[~on].T @ res.r[~on]
                    nonfinite[dname] += res.nonfinite_samples
                    if start == 0 and i == 0:
                        examples[dname][sname] = res
            progress(f"{sname}: {min(runs, start + chunk)}/{runs} runs")
        assert t is not None and active is not None
        for dname, b in built.items():
            gf = b.gain_file
            # a fault outside the gain file's classes (e.g. two parameters at once) has no single index
            fidx = gf.faults.index(sc.fault) if sc.fault in gf.faults else None
            stacked = {k: np.stack(v) for k, v in acc[dname].items()}
            m = scenario_metrics(
                scenario=sname,
                fault=sc.fault,
                fault_index=fidx,
                active=active,
                alarm=stacked["alarm"],
                isolated=stacked["isolated"],
                J=stacked["J"],
                thresholds=list(gf.thresholds),
                P_f=[e.P_f for e in gf.evaluators],
                Ts=gf.Ts,
                recovery=recovery_samples(gf),
                nonfinite=nonfinite[dname],
                budget_s=false_alarm_budget(gf),
                lorden=_lorden(gf, shift[dname]),
            )
            extra = problem.extra_metrics or extra_metrics(gf.kind)
            if extra is not None:
                m = replace(m, extra=dict(extra(sc, gf, stacked)))
            metrics[dname][sname] = m
    return Evaluation(
        problem=problem.name,
        runs=runs,
        seed0=seed0,
        options=problem.check_options(options),
        metrics=metrics,
        examples=examples,
        batches=batches,
    )


def _first_run(batch: Batch) -> Batch:
    return Batch(
        scenario=batch.scenario,
        seeds=batch.seeds[:1],
        t=batch.t,
        inputs=batch.inputs,
        outputs=batch.outputs,
        U=batch.U[:1],
        Y=batch.Y[:1],
        extra={k: v[:1] for k, v in batch.extra.items()},
    )
