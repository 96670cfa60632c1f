"""FDI performance metrics over Monte Carlo runs of one scenario.

Definitions (per scenario, over ``R`` runs of ``N`` samples): :data:`DEFINITIONS`,
appended below, which the reports render in their "Definitions" section.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import scipy.stats

__all__ = ["DEFINITIONS", "ScenarioMetrics", "scenario_metrics", "binomial_interval", "poisson_time_interval"]


DEFINITIONS: dict[str, str] = {
    "false-alarm rate": (
        "fraction of fault-free samples with alarm = 1. Fault-free samples are those before the fault and those more "
        "than recovery samples after it ends (the residual generator needs that long to forget the fault)."
    ),
    "false-alarm runs": "fraction of runs with at least one false alarm.",
    "missed detection": "fraction of runs with no alarm while the fault is active.",
    "missed-alarm fraction": "fraction of fault-active samples without alarm.",
    "detection delay": (
        "first alarm at or after the fault onset, minus the onset (runs that detected only); mean, median and max, "
        "in samples and seconds."
    ),
    "isolation accuracy": (
        "fraction of runs whose most frequent isolation decision (isolated ≥ 0) while the fault is active names the "
        "true fault; runs that never isolate count as wrong."
    ),
    "false isolation": (
        "fraction of runs whose most frequent decision names another fault (a run that never isolates is not counted: "
        "detected, not isolated)."
    ),
    "first isolation accuracy": (
        "the isolation accuracy of the first decision (harsh for multi-sensor faults, whose pattern builds up over a "
        "few samples)."
    ),
    "sample isolation accuracy": "among fault-active samples with an alarm, the fraction with the true fault isolated.",
    "statistic exceedance": (
        "per statistic, the fraction of fault-free samples with J > threshold (to compare with its P_f), with a "
        "two-sided 99.9 % binomial interval for independent samples."
    ),
    "mean time between false alarms": (
        "fault-free time (all runs) divided by the number of false-alarm episodes (an episode starts at a fault-free "
        "sample that alarms after one that did not), with Garwood's exact 95 % Poisson interval on the count."
    ),
    "budget": (
        "the false-alarm time the design was made for: its arl0, or for a design by P_f the budget it implies, "
        "Ts / Σ_j P_f,j."
    ),
    "Lorden bound": (
        "ln(ARL_j) / I_j samples, the smallest over the statistics j, with ARL_j statistic j's share of the budget and "
        "I_j the Kullback–Leibler information per sample the fault brings to its generator's residual (Lorden, Annals "
        "of Mathematical Statistics 42(6), 1971): no detector with that budget is faster on average for a persistent "
        "change."
    ),
    "delay ratio": "the measured mean detection delay over the Lorden bound (the goal is ≤ 1.2).",
    "non-finite samples": "samples whose inputs or outputs held NaN or ±inf; the diagnoser skips them and counts them.",
}
"""The metrics' definitions, by the name the reports' column headers link to (one source: this module's docstring
and the reports' "Definitions" section both render it)."""

__doc__ = (__doc__ or "") + "\n" + "\n".join(f"{name}\n    {text}" for name, text in DEFINITIONS.items())


def binomial_interval(n: int, p: float, *, alpha: float = 1e-3) -> tuple[int, int]:
    """Counts ``[lo, hi]`` holding ``Binomial(n, p)`` with probability ≥ ``1 − alpha``."""
    dist = scipy.stats.binom(n, p)
    return int(dist.ppf(alpha / 2)), int(dist.isf(alpha / 2))


@dataclass(frozen=True)
class ScenarioMetrics:
    scenario: str
    fault: str | None
    runs: int
    samples_per_run: int
    Ts: float
    false_alarm_rate: float
    false_alarm_runs: float
    missed_detection_rate: float | None
    missed_alarm_fraction: float | None
    detection_delay_mean_s: float | None
    detection_delay_median_s: float | None
    detection_delay_max_s: float | None
    detection_delay_mean_samples: float | None
    detection_delay_max_samples: int | None
    isolation_accuracy: float | None
    first_isolation_accuracy: float | None
    sample_isolation_accuracy: float | None
    statistic_exceedance: list[float]
    statistic_exceedance_interval: list[tuple[float, float]]
    fault_free_samples: int
    nonfinite_samples: int
    false_alarm_episodes: int = 0
    mean_time_between_false_alarms_s: float | None = None
    """``None`` when no false alarm was seen (the interval's lower end still bounds it)."""
    mean_time_between_false_alarms_interval_s: tuple[float, float | None] = (0.0, None)
    arl0_budget_s: float | None = None
    fault_information: float | None = None
    """Largest KL information per sample the fault brings to one generator (nats)."""
    lorden_bound_samples: float | None = None
    delay_bound_ratio: float | None = None
    false_isolation_rate: float | None = None
    extra: Mapping[str, Any] = field(default_factory=dict)
    """Figures beyond detection (``Problem.extra_metrics``, else the diagnoser kind's)."""

    def to_dict(self) -> dict[str, object]:
        return asdict(self)


def scenario_metrics(
    *,
    scenario: str,
    fault: str | None,
    fault_index: int | None,
    active: np.ndarray,
    alarm: np.ndarray,
    isolated: np.ndarray,
    J: np.ndarray,
    thresholds: Sequence[float],
    P_f: Sequence[float],
    Ts: float,
    recovery: int,
    nonfinite: int = 0,
    budget_s: float | None = None,
    lorden: tuple[float, float] | None = None,
) -> ScenarioMetrics:
    """Metrics of one scenario. ``alarm``, ``isolated``: ``R × N``; ``J``: ``R × N × nj``.

    ``budget_s``: the design's false-alarm budget; ``lorden``: ``(I, bound in samples)`` of the fault.
    """
    alarm = np.asarray(alarm, dtype=bool)
    isolated = np.asarray(isolated, dtype=int)
    runs, n = alarm.shape
    active = np.asarray(active, dtype=bool)
    quiet = ~active
    if active.any():
        last = int(np.flatnonzero(active)[-1])
        quiet[last + 1 : min(n, last + 1 + recovery)] = False
    n_quiet = int(quiet.sum())
    far = float(alarm[:, quiet].mean()) if n_quiet else 0.0
    far_runs = float(np.mean(alarm[:, quiet].any(axis=1))) if n_quiet else 0.0
    exceed = np.asarray(J)[:, quiet, :] > np.asarray(thresholds)[None, None, :]
    exc_rate = [float(exceed[:, :, j].mean()) if n_quiet else 0.0 for j in range(exceed.shape[2])]
    intervals = []
    for pf in P_f:
        lo, hi = binomial_interval(runs * n_quiet, float(pf))
        total = max(runs * n_quiet, 1)
        intervals.append((lo / total, hi / total))
    md = maf = d_mean = d_med = d_max = ds_mean = iso_acc = first_acc = siso = false_iso = None
    ds_max: int | None = None
    if active.any():
        idx = np.flatnonzero(active)
        onset = int(idx[0])
        hit = alarm[:, idx]
        detected = hit.any(axis=1)
        md = float(1.0 - detected.mean())
        maf = float(1.0 - hit.mean())
        if detected.any():
            first = np.argmax(hit, axis=1)[detected]
            delays = idx[first] - onset
            ds_mean = float(delays.mean())
            ds_max = int(delays.max())
            d_mean, d_med, d_max = ds_mean * Ts, float(np.median(delays)) * Ts, ds_max * Ts
        if fault_index is not None:
            iso_win = isolated[:, idx]
            decided = iso_win >= 0
            firsts = np.where(decided.any(axis=1), iso_win[np.arange(runs), np.argmax(decided, axis=1)], -1)
            first_acc = float(np.mean(firsts == fault_index))
            modes = [int(np.bincount(row[row >= 0]).argmax()) if np.any(row >= 0) else -1 for row in iso_win]
            iso_acc = float(np.mean(np.asarray(modes) == fault_index))
            false_iso = float(np.mean((np.asarray(modes) >= 0) & (np.asarray(modes) != fault_index)))
            n_alarmed = int(hit.sum())
            siso = float(np.sum((iso_win == fault_index) & hit) / n_alarmed) if n_alarmed else 0.0
    onset = alarm & ~np.concatenate([np.zeros((runs, 1), dtype=bool), alarm[:, :-1]], axis=1)
    episodes = int(onset[:, quiet].sum())
    exposure = runs * n_quiet * Ts
    mtbfa_lo, mtbfa_hi = poisson_time_interval(episodes, exposure)
    ratio = None
    if lorden is not None and ds_mean is not None and lorden[1] > 0:
        ratio = ds_mean / lorden[1]
    return ScenarioMetrics(
        scenario=scenario,
        fault=fault,
        runs=runs,
        samples_per_run=n,
        Ts=Ts,
        false_alarm_rate=far,
        false_alarm_runs=far_runs,
        missed_detection_rate=md,
        missed_alarm_fraction=maf,
        detection_delay_mean_s=d_mean,
        detection_delay_median_s=d_med,
        detection_delay_max_s=d_max,
        detection_delay_mean_samples=ds_mean,
        detection_delay_max_samples=ds_max,
        isolation_accuracy=iso_acc,
        first_isolation_accuracy=first_acc,
        sample_isolation_accuracy=siso,
        statistic_exceedance=exc_rate,
        statistic_exceedance_interval=intervals,
        fault_free_samples=n_quiet * runs,
        nonfinite_samples=int(nonfinite),
        false_alarm_episodes=episodes,
        mean_time_between_false_alarms_s=exposure / episodes if episodes else None,
        mean_time_between_false_alarms_interval_s=(mtbfa_lo, mtbfa_hi),
        arl0_budget_s=budget_s,
        fault_information=None if lorden is None else lorden[0],
        lorden_bound_samples=None if lorden is None else lorden[1],
        delay_bound_ratio=ratio,
        false_isolation_rate=false_iso,
    )


def poisson_time_interval(count: int, exposure: float, *, level: float = 0.95) -> tuple[float, float | None]:
    """Garwood's exact interval for the mean time between events, ``count`` events in ``exposure``:
    ``exposure / λ`` over the Poisson interval of the count (upper end ``None`` when no event was seen)."""
    a = 1.0 - level
    hi_count = float(scipy.stats.chi2.ppf(1.0 - a / 2, 2 * count + 2)) / 2.0
    lo = exposure / hi_count if hi_count > 0 else 0.0
    if count == 0:
        return lo, None
    lo_count = float(scipy.stats.chi2.ppf(a / 2, 2 * count)) / 2.0
    return lo, exposure / lo_count
