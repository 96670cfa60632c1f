"""FDI performance metrics over Monte Carlo runs of one scenario.

Definitions (per scenario, over ``R`` runs of ``N`` samples):

false-alarm rate
    fraction of fault-free samples with ``alarm = 1``. Fault-free samples are
    those before the fault and those more than ``recovery`` samples after it
    ends (the residual generator needs that long to forget the fault).
false-alarm runs
    fraction of runs with at least one false alarm.
missed-detection rate
    fraction of runs with no alarm while the fault is active.
missed-alarm fraction
    fraction of fault-active samples without alarm.
detection delay
    first alarm at or after the fault onset, minus the onset (runs that
    detected only); mean, median and max, in samples and seconds.
isolation accuracy
    fraction of runs whose most frequent isolation decision (``isolated ≥ 0``)
    while the fault is active names the true fault; runs that never isolate
    count as wrong. ``first isolation accuracy``: the same for the first
    decision (harsh for multi-sensor faults, whose pattern builds up over a
    few samples). ``sample isolation accuracy``: among fault-active samples
    with an alarm, the fraction with the true fault isolated.
statistic exceedance
    per statistic, the fraction of fault-free samples with ``J > threshold``
    (to compare with its ``P_f``), with a two-sided 99.9 % binomial interval.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import scipy.stats

__all__ = ["ScenarioMetrics", "scenario_metrics", "binomial_interval"]


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
) -> ScenarioMetrics:
    """Metrics of one scenario. ``alarm``, ``isolated``: ``R × N``; ``J``: ``R × N × nj``."""
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
    md = maf = d_mean = d_med = d_max = ds_mean = iso_acc = first_acc = siso = None
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
            n_alarmed = int(hit.sum())
            siso = float(np.sum((iso_win == fault_index) & hit) / n_alarmed) if n_alarmed else 0.0
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
    )
