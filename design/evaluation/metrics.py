"""FDI performance metrics over Monte Carlo runs of one scenario.

Definitions (per scenario, over ``R`` runs of ``N`` samples): :data:`DEFINITIONS`,
appended below, which the reports render in their "Definitions" section.

The Monte Carlo never holds every run: :func:`summarise_runs` reduces a chunk
of runs to a few numbers per run (:class:`RunSummaries`) where they were
simulated, and :class:`MetricsAccumulator` merges them in run order into the
same :class:`ScenarioMetrics` that :func:`scenario_metrics` computes from the
stacked runs (the reference: equal to the last bit).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from types import SimpleNamespace
from typing import Any

import numpy as np
import scipy.stats

__all__ = [
    "DEFINITIONS",
    "ScenarioMetrics",
    "scenario_metrics",
    "binomial_interval",
    "delay_bound_ratio",
    "poisson_time_interval",
    "HISTOGRAM_EDGES",
    "fault_free_histogram",
    "MetricsPlan",
    "RunSummaries",
    "summarise_runs",
    "extra_values",
    "MetricsAccumulator",
    "DETECTION_GOAL",
    "ISOLATION_GOAL",
    "ISOLATION_MARGIN",
    "IsolationAtSize",
    "isolation_at_size",
    "OPERATING_SCALES",
    "OperatingPlan",
    "operating_plan",
    "COPY_SCALES",
    "within_samples",
    "alarm_level",
    "operating_values",
]

HISTOGRAM_EDGES = np.linspace(0.0, 3.0, 61)
"""Bin edges of the fault-free histograms, in multiples of each statistic's threshold (0 to 3 h by h/20)."""


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
    "warm-up": (
        "samples over which each linear generator, or a Beard filter, estimates its initial state by least squares (the "
        "plant may be moving when the diagnoser starts) before its statistics run (a Beard filter's window then fills); "
        "they are held, and raise no alarm, until then. \"none\": a diagnoser kind without one."
    ),
    "alarm held": (
        "fraction of the fault's active samples (all runs) with the alarm on: 1 − the missed-alarm fraction. A fault "
        "alarmed for two samples and then silent holds its alarm for a small fraction, however fast it was detected."
    ),
    "isolated held": (
        "fraction of the fault's active samples (all runs) with the alarm on and the true fault isolated: the alarm "
        "held times the sample isolation accuracy."
    ),
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
        "change. It takes the fault's whole shift from its first sample on (a step); the onset-aware bound below "
        "follows the residual's transient."
    ),
    "onset-aware bound": (
        "the Lorden bound of a shift that builds up after the onset: the smallest n (interpolated between samples) "
        "with Σ_{ℓ<n} I_j(ℓ) ≥ ln(ARL_j), the smallest over the statistics j, where I_j(ℓ) is the information the "
        "fault's mean residual shift ℓ samples after its onset brings (the same measure as the Lorden bound's, the "
        "shift measured per lag over the Monte Carlo's runs for the first 256 lags, the whole-fault shift beyond); "
        "the non-i.i.d. form of Lorden's bound (Lai, IEEE Transactions on Information Theory 44(7), 1998). Equal to "
        "ln(ARL_j)/I_j for a step."
    ),
    "delay ratio": (
        "the measured mean detection delay over the onset-aware bound (the Lorden bound where a kind has none), both "
        "counted as the faulty samples seen at the alarm (an alarm on the fault's first sample has seen one); the goal "
        "is ≤ 1.2 at the designed size, ≤ 1.5 over whitened shifts from 0.25σ to 4σ."
    ),
    "operating characteristic": (
        "per design, the probability of detection within a stated delay D (runs of the faulty scenarios whose first "
        "alarm came at most D after the onset) against the mean time between false alarms (all scenarios' fault-free "
        "time over the false-alarm episodes), with every threshold scaled by one factor from 0.5 to 2. Computed from "
        "the Monte Carlo's own statistics: each statistic's alarm rule, persistence and hold applied to its J at each "
        "scale, which gives the step's decisions exactly (checked against them at scale 1)."
    ),
    "non-finite samples": "samples whose inputs or outputs held NaN or ±inf; the diagnoser skips them and counts them.",
    "fault-free histogram": (
        "per statistic with a finite positive threshold h, the counts of its fault-free samples in the bins "
        "from 0 to 3 h in steps of h/20: the first count is below 0, the last at or above 3 h (or not a number)."
    ),
}
"""The metrics' definitions, by the name the reports' column headers link to (one source: this module's docstring
and the reports' "Definitions" section both render it)."""

__doc__ = (__doc__ or "") + "\n" + "\n".join(f"{name}\n    {text}" for name, text in DEFINITIONS.items())


def delay_bound_ratio(delay_mean_samples: float | None, lorden: tuple[float, float] | None) -> float | None:
    """The mean detection delay over the Lorden bound, both counted as the faulty samples the detector has seen when
    it alarms: an alarm on the fault's first sample has seen one (the Monte Carlo's delay there is 0), as in the
    bound ``ln(ARL)/I`` (Lorden, Annals of Mathematical Statistics 42(6), 1971).

    Parameters
    ----------
    delay_mean_samples : float or None
        The mean delay in samples from the onset (0: the first faulty sample alarmed).
    lorden : tuple of float or None
        ``(I, ln(ARL)/I)``: the fault's information per sample and the bound in samples.

    Returns
    -------
    float or None
        ``(delay + 1) / bound``; ``None`` without a delay or a bound.

    Examples
    --------
    >>> delay_bound_ratio(0.0, (8.0, 2.0))  # alarmed on the first faulty sample, where the bound is two
    0.5
    """
    if lorden is None or delay_mean_samples is None or not lorden[1] > 0:
        return None
    return (float(delay_mean_samples) + 1.0) / float(lorden[1])


def binomial_interval(n: int, p: float, *, alpha: float = 1e-3) -> tuple[int, int]:
    """Counts ``[lo, hi]`` holding ``Binomial(n, p)`` with probability ≥ ``1 − alpha``.

    Parameters
    ----------
    n : int
        The number of trials (fault-free samples).
    p : float
        The probability of an event per trial (a statistic's ``P_f``).
    alpha : float
        The probability left outside the interval, half on each side.

    Returns
    -------
    tuple of int
        The lowest and highest count of the interval.

    Examples
    --------
    >>> binomial_interval(1000, 0.01)
    (2, 22)
    """
    dist = scipy.stats.binom(n, p)
    return int(dist.ppf(alpha / 2)), int(dist.isf(alpha / 2))


@dataclass(frozen=True)
class ScenarioMetrics:
    """The Monte Carlo's result for one design in one scenario (definitions: :data:`DEFINITIONS`).

    Rates are fractions in [0, 1]; a figure that does not apply (a detection delay in a fault-free scenario,
    an isolation accuracy for a fault the diagnoser has no class for) is ``None``.

    Attributes
    ----------
    scenario : str
        The scenario's name.
    fault : str or None
        The fault it injects (``None``: fault-free).
    runs : int
        Monte Carlo runs.
    samples_per_run : int
        Samples in each run.
    Ts : float
        The sample time in seconds.
    false_alarm_rate : float
        Fraction of fault-free samples with an alarm.
    false_alarm_runs : float
        Fraction of runs with at least one false alarm.
    missed_detection_rate : float or None
        Fraction of runs with no alarm while the fault is active.
    missed_alarm_fraction : float or None
        Fraction of fault-active samples without alarm.
    detection_delay_mean_s, detection_delay_median_s, detection_delay_max_s : float or None
        The detection delay of the runs that detected, in seconds.
    detection_delay_mean_samples : float or None
        The mean detection delay in samples.
    detection_delay_max_samples : int or None
        The longest detection delay in samples.
    isolation_accuracy : float or None
        Fraction of runs whose most frequent isolation decision names the true fault.
    first_isolation_accuracy : float or None
        The same for each run's first decision.
    sample_isolation_accuracy : float or None
        Among fault-active samples with an alarm, the fraction with the true fault isolated.
    statistic_exceedance : list of float
        Per statistic, the fraction of fault-free samples with ``J > threshold``.
    statistic_exceedance_interval : list of tuple of float
        Per statistic, the two-sided 99.9 % binomial interval of that fraction at its ``P_f``.
    fault_free_samples : int
        Fault-free samples per run (outside the fault and its recovery window).
    nonfinite_samples : int
        Samples whose inputs or outputs held a non-finite value (all runs).
    false_alarm_episodes : int
        False-alarm episodes (all runs).
    mean_time_between_false_alarms_s : float or None
        Fault-free time over the episodes; ``None`` when no false alarm was seen (the interval's lower end
        still bounds it).
    mean_time_between_false_alarms_interval_s : tuple of (float, float or None)
        Garwood's exact 95 % interval of it (upper end ``None`` when no false alarm was seen).
    arl0_budget_s : float or None
        The false-alarm time the design was made for.
    fault_information : float or None
        Largest KL information per sample the fault brings to one generator (nats).
    lorden_bound_samples : float or None
        The Lorden bound on the mean detection delay, in samples: the fault's whole shift from its onset on.
    delay_bound_ratio : float or None
        The mean detection delay over the onset-aware bound :attr:`onset_bound_samples`, or over
        :attr:`lorden_bound_samples` where there is none (:func:`delay_bound_ratio`).
    false_isolation_rate : float or None
        Fraction of runs whose most frequent decision names another fault.
    fault_free_histogram : list of list of int
        Per statistic, its fault-free samples counted in the bins :data:`HISTOGRAM_EDGES` ``× threshold`` (below
        the first edge, each bin, at or above the last); empty for a statistic without a finite positive threshold.
    extra : Mapping of str to object
        Figures beyond detection (``Problem.extra_metrics``, else the diagnoser kind's).
    operating : Mapping of str to object or None
        The operating characteristic's counts (:class:`OperatingPlan`): ``scales``, the false-alarm ``episodes``
        and the runs ``detected_within`` the delay ``delay_s`` at each threshold scale; ``None`` where the step's
        decisions are not a function of its statistics the Monte Carlo knows (another kind, a CUSUM).
    onset_bound_samples : float or None
        The onset-aware Lorden bound in samples: the cumulative information of the fault's measured mean shift lag
        by lag after its onset reaching ``ln(ARL)`` (:func:`fdisyn.synthesis.kinds.onset_lorden_bound`; ``None``:
        the kind has no per-lag information, or the fault-free scenario).
    stationary_bound_ratio : float or None
        The mean detection delay over :attr:`lorden_bound_samples` (the ratio to the step's bound).
    """

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
    mean_time_between_false_alarms_interval_s: tuple[float, float | None] = (0.0, None)
    arl0_budget_s: float | None = None
    fault_information: float | None = None
    lorden_bound_samples: float | None = None
    delay_bound_ratio: float | None = None
    false_isolation_rate: float | None = None
    fault_free_histogram: list[list[int]] = field(default_factory=list)
    extra: Mapping[str, Any] = field(default_factory=dict)
    operating: Mapping[str, Any] | None = None
    onset_bound_samples: float | None = None
    stationary_bound_ratio: float | None = None

    @property
    def alarm_held_fraction(self) -> float | None:
        """Fraction of the fault's active samples with the alarm on (``1 −`` :attr:`missed_alarm_fraction`);
        ``None`` for a fault-free scenario."""
        return None if self.missed_alarm_fraction is None else 1.0 - self.missed_alarm_fraction

    @property
    def isolated_held_fraction(self) -> float | None:
        """Fraction of the fault's active samples with the alarm on and the true fault isolated
        (:attr:`alarm_held_fraction` × :attr:`sample_isolation_accuracy`, whose denominator is the alarmed ones);
        ``None`` where isolation is not measured."""
        held, iso = self.alarm_held_fraction, self.sample_isolation_accuracy
        return None if held is None or iso is None else held * iso

    def to_dict(self) -> dict[str, object]:
        """The metrics as a plain dict (the Monte Carlo's JSON), field by field, with the held fractions."""
        return {**asdict(self), "alarm_held_fraction": self.alarm_held_fraction, "isolated_held_fraction": self.isolated_held_fraction}


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
    operating: OperatingPlan | None = None,
    onset_bound: float | None = None,
    r: np.ndarray | None = None,
) -> ScenarioMetrics:
    """Metrics of one scenario from its stacked runs (the reference :class:`MetricsAccumulator` must equal).

    Parameters
    ----------
    scenario : str
        The scenario's name.
    fault : str or None
        The fault it injects (``None``: fault-free).
    fault_index : int or None
        The true fault's class in the gain file (``None``: none of its classes).
    active : numpy.ndarray
        ``N`` booleans: the samples where the fault is active.
    alarm : numpy.ndarray
        The alarms, ``R × N``.
    isolated : numpy.ndarray
        The isolated classes, ``R × N`` (−1: none).
    J : numpy.ndarray
        The statistics, ``R × N × nj``.
    thresholds : sequence of float
        One threshold per statistic.
    P_f : sequence of float
        Each statistic's per-sample false-alarm probability.
    Ts : float
        The sample time in seconds.
    recovery : int
        Samples after the fault's end that do not count as fault-free.
    nonfinite : int
        Samples that held a non-finite value (all runs).
    budget_s : float, optional
        The design's false-alarm budget in seconds.
    lorden : tuple of float, optional
        ``(I, bound in samples)`` of the fault.
    operating : OperatingPlan, optional
        The operating characteristic's plan (:func:`operating_plan`).
    onset_bound : float, optional
        The onset-aware bound in samples (:func:`fdisyn.synthesis.kinds.onset_lorden_bound`); the delay ratio is
        taken over it when given, over ``lorden``'s bound otherwise.
    r : numpy.ndarray, optional
        The residuals, ``R × N × nr`` (a CUSUM's operating characteristic is run again from them; without them it
        is left out).

    Returns
    -------
    ScenarioMetrics
        The scenario's figures.
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
    ratio = delay_bound_ratio(ds_mean, lorden if onset_bound is None else (float("nan"), onset_bound))
    stationary = delay_bound_ratio(ds_mean, lorden)
    hist = [c.tolist() for c in fault_free_histogram(np.asarray(J)[:, quiet, :].reshape(-1, len(thresholds)), thresholds)]
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
        onset_bound_samples=onset_bound,
        stationary_bound_ratio=stationary,
        false_isolation_rate=false_iso,
        fault_free_histogram=hist,
        operating=_operating_reference(operating, active, quiet, np.asarray(J), None if r is None else np.asarray(r)),
    )


def _operating_reference(op: OperatingPlan | None, active: np.ndarray, quiet: np.ndarray, J: np.ndarray,
                         r: np.ndarray | None) -> dict[str, Any] | None:
    """The operating characteristic's counts of stacked runs, as :class:`MetricsAccumulator` reports them."""
    if op is None or (op.residuals and r is None):
        return None
    plan = MetricsPlan(active=active, quiet=quiet, on=None, fault_index=None, thresholds=(), operating=op)
    values = operating_values(plan, SimpleNamespace(J=J, r=r, status=np.zeros(J.shape[:2], np.int8)))
    assert values is not None
    episodes, first = values
    return {"scales": list(OPERATING_SCALES), "episodes": episodes.sum(axis=0).tolist(),
            "detected_within": np.sum((first >= 0) & (first <= op.within), axis=0).tolist() if active.any() else None,
            "delay_s": op.delay_s}


def fault_free_histogram(J: np.ndarray, thresholds: Sequence[float]) -> list[np.ndarray]:
    """Per statistic, the counts of the samples ``J`` (``samples × nj``) in the bins :data:`HISTOGRAM_EDGES` ``× h``
    (see :attr:`ScenarioMetrics.fault_free_histogram`).

    Parameters
    ----------
    J : numpy.ndarray
        The fault-free statistics, ``samples × nj``.
    thresholds : sequence of float
        The threshold ``h`` of each statistic.

    Returns
    -------
    list of numpy.ndarray
        Per statistic, ``len(HISTOGRAM_EDGES) + 1`` counts; empty for a threshold that is not finite and positive.
    """
    out = []
    for j, h in enumerate(thresholds):
        if not (np.isfinite(h) and h > 0):
            out.append(np.zeros(0, dtype=np.int64))
            continue
        bins = np.searchsorted(HISTOGRAM_EDGES * float(h), J[:, j], side="right")  # NaN sorts last: the top bin
        out.append(np.bincount(bins, minlength=len(HISTOGRAM_EDGES) + 1).astype(np.int64))
    return out


def poisson_time_interval(count: int, exposure: float, *, level: float = 0.95) -> tuple[float, float | None]:
    """Garwood's exact interval for the mean time between events, ``count`` events in ``exposure``:
    ``exposure / λ`` over the Poisson interval of the count (upper end ``None`` when no event was seen).

    Parameters
    ----------
    count : int
        The events seen (false-alarm episodes).
    exposure : float
        The time they were seen in (fault-free seconds).
    level : float
        The interval's coverage.

    Returns
    -------
    tuple of (float, float or None)
        The interval's lower and upper ends.
    """
    a = 1.0 - level
    hi_count = float(scipy.stats.chi2.ppf(1.0 - a / 2, 2 * count + 2)) / 2.0
    lo = exposure / hi_count if hi_count > 0 else 0.0
    if count == 0:
        return lo, None
    lo_count = float(scipy.stats.chi2.ppf(a / 2, 2 * count)) / 2.0
    return lo, exposure / lo_count


# --------------------------------------------------------------------------- streaming: per-run summaries, merged


OPERATING_SCALES: tuple[float, ...] = tuple(float(2.0 ** (k / 16)) for k in range(-16, 17))
"""The threshold scales of the operating characteristic: every threshold times 0.5 … 2, ``2^(1/16)`` apart, 1 (the
design itself) exactly in the middle."""


COPY_SCALES: tuple[float, ...] = OPERATING_SCALES[::4]
"""The threshold scales of an operating characteristic measured on copies of the diagnoser, one per scale but 1
(:attr:`fdisyn.synthesis.kinds.DiagnoserKind.threshold_scaled`): every fourth of :data:`OPERATING_SCALES`, 0.5 …
2, ``2^(1/4)`` apart — each copy runs the whole diagnoser again."""


def within_samples(delay_s: float, Ts: float) -> int:
    """The stated delay ``D`` in whole samples: a run is detected within ``D`` when its first alarm is at most
    this many samples after the fault's onset.

    Parameters
    ----------
    delay_s : float
        ``D`` in seconds.
    Ts : float
        The sample time in seconds.

    Returns
    -------
    int
        ``⌊D/Ts⌋`` (a ratio within 1e-9 below a whole number counts as it).
    """
    return int(np.floor(float(delay_s) / float(Ts) + 1e-9))


@dataclass(frozen=True, eq=False)
class OperatingPlan:
    """What the operating characteristic of a linear diagnoser or a Beard filter is taken over (:func:`operating_plan`).

    Attributes
    ----------
    evaluators : tuple
        The gain file's evaluators (kind, threshold, release), one per statistic (a Beard filter's
        :class:`WindowedThreshold`).
    persistence : int
        The decision's persistence.
    within : int
        The stated delay ``D`` in samples: a run is detected within ``D`` when its first alarm is at most ``within``
        samples after the onset.
    delay_s : float
        ``D`` in seconds.
    residuals : tuple
        Per statistic, ``(start, stop, warmup)``: its generator's residuals in the stacked ``r`` and the samples
        before it runs (read by a statistic whose flags are run again from the residuals,
        :attr:`fdisyn.runtime.statistics.Statistic.flags_at`; empty when every statistic has a level).
    """

    evaluators: tuple[Any, ...]
    persistence: int
    within: int
    delay_s: float
    residuals: tuple[tuple[int, int, int], ...] = ()


@dataclass(frozen=True)
class WindowedThreshold:
    """A Beard filter's decision as the operating characteristic reads it: its first statistic (the window's RMS
    residual) against ``threshold``, raised after ``persistence`` consecutive samples above it — the rule of a
    per-sample statistic of ``kind`` (:func:`fdisyn.runtime.statistics.count_level`)."""

    kind: str
    threshold: float


def operating_plan(gf: Any, delay_s: float | None) -> OperatingPlan | None:
    """The operating characteristic's plan of ``gf``, or ``None`` for a kind other than ``linear`` and ``beard_fdf``
    (a Beard filter's window statistic against its threshold, :class:`WindowedThreshold`) or no delay stated.
    Its decisions at every threshold scale follow from the statistics ``J``
    (:attr:`fdisyn.runtime.statistics.Statistic.level`) or, for a statistic whose ``J`` depends on its threshold
    (a CUSUM's clamp), from the residuals it runs on (:attr:`~fdisyn.runtime.statistics.Statistic.flags_at`).

    Parameters
    ----------
    gf : GainFile
        The diagnoser.
    delay_s : float or None
        The stated delay ``D`` in seconds.

    Returns
    -------
    OperatingPlan or None
        The plan.
    """
    from fdisyn.runtime.statistics import STATISTICS

    if delay_s is None:
        return None
    within = within_samples(delay_s, gf.Ts)
    if gf.kind == "beard_fdf":
        from fdisyn.synthesis.beard_fdf.payload import beard_from_gain_file

        # the window's RMS residual J[0] against h, counted over the persistence: a per-sample statistic's rule
        flt = beard_from_gain_file(gf)
        from fdisyn.runtime.statistics import count_level

        per_sample = next(k for k, st in STATISTICS.items() if st.level is count_level and not st.window_read)
        rule = WindowedThreshold(kind=per_sample, threshold=float(flt.h))
        return OperatingPlan(evaluators=(rule,), persistence=int(flt.persistence), within=within, delay_s=float(delay_s))
    if gf.kind != "linear":
        return None
    evs = tuple(gf.evaluators or ())
    if gf.decision is None or not evs or len(evs) != gf.step.nj:
        return None
    if any(not (np.isfinite(e.threshold) and e.threshold > 0) for e in evs):
        return None
    if any(STATISTICS[e.kind].level is None and STATISTICS[e.kind].flags_at is None for e in evs):
        return None
    residuals: tuple[tuple[int, int, int], ...] = ()
    if any(STATISTICS[e.kind].level is None for e in evs):
        starts = np.cumsum([0] + [g.n_residual for g in gf.generators])
        residuals = tuple((int(starts[e.generator]), int(starts[e.generator + 1]), int(gf.generators[e.generator].warmup)) for e in evs)
    return OperatingPlan(evaluators=evs, persistence=int(gf.decision.persistence), within=within, delay_s=float(delay_s),
                         residuals=residuals)


def alarm_level(op: OperatingPlan, J: np.ndarray) -> np.ndarray:
    """The diagnoser's alarm level, ``runs × samples``: its alarm with every threshold scaled by ``s`` is raised
    exactly where the level is above ``s`` (the largest of its statistics' levels, an alarm being any flag); the
    statistics without a level (:attr:`fdisyn.runtime.statistics.Statistic.flags_at`) are left out.

    Parameters
    ----------
    op : OperatingPlan
        The plan.
    J : numpy.ndarray
        The statistics, ``runs × samples × nj``.

    Returns
    -------
    numpy.ndarray
        The level.
    """
    from fdisyn.runtime.statistics import STATISTICS

    J = np.asarray(J, dtype=float)
    R = J.shape[0]
    level = np.full(J.shape[:2], -np.inf)
    # a level is computed row by row, so the statistics of one kind and release ratio go as one stack of rows
    groups: dict[tuple[str, float], list[int]] = {}
    for j, e in enumerate(op.evaluators):
        if STATISTICS[e.kind].level is None:
            continue
        groups.setdefault((e.kind, float(STATISTICS[e.kind].release(e)) / float(e.threshold)), []).append(j)
    for (kind, _), js in groups.items():
        stat = STATISTICS[kind]
        assert stat.level is not None
        x = np.concatenate([J[:, :, j] / float(op.evaluators[j].threshold) for j in js], axis=0)
        level = np.maximum(level, stat.level(op.evaluators[js[0]], x, op.persistence).reshape(len(js), R, -1).max(axis=0))
    return level


def operating_values(plan: MetricsPlan, runs: Any) -> tuple[np.ndarray, np.ndarray] | None:
    """Per run and threshold scale (:data:`OPERATING_SCALES`): the false-alarm episodes among the fault-free samples
    and the first alarm's position among the fault's samples (−1: none), from the statistics ``J`` alone.

    Parameters
    ----------
    plan : MetricsPlan
        Its ``operating`` (``None``: no values).
    runs : DesignRuns
        The chunk's ``J`` and ``status``.

    Returns
    -------
    tuple of numpy.ndarray or None
        ``(episodes, first)``, each ``runs × len(OPERATING_SCALES)``; ``None`` without a plan, or when a sample of the
        chunk was skipped as non-finite (the counters then hold, which ``J`` does not show).
    """
    op = plan.operating
    if op is None or np.any(np.asarray(runs.status) != 0):
        return None
    if op.residuals:
        return _operating_rerun(plan, op, runs)
    A = alarm_level(op, runs.J)
    R, n = A.shape
    scales = np.asarray(OPERATING_SCALES)
    S = len(scales)
    prev = np.concatenate([np.full((R, 1), -np.inf), A[:, :-1]], axis=1)
    # a quiet sample starts an episode at s when A(k−1) ≤ s < A(k): the scales in [A(k−1), A(k))
    lo, hi = prev[:, plan.quiet], A[:, plan.quiet]
    up = hi > lo
    rows = np.broadcast_to(np.arange(R)[:, None], lo.shape)[up] * (S + 1)
    i_lo = np.searchsorted(scales, lo[up], side="left")
    i_hi = np.searchsorted(scales, hi[up], side="left")
    steps = np.bincount(rows + i_lo, minlength=R * (S + 1)) - np.bincount(rows + i_hi, minlength=R * (S + 1))
    episodes = np.cumsum(steps.reshape(R, S + 1), axis=1)[:, :S].astype(np.int64)
    first = np.full((R, S), -1, dtype=np.int64)
    idx = np.flatnonzero(plan.active)
    if idx.size:
        top = np.maximum.accumulate(A[:, idx], axis=1)
        for i in range(R):
            k = np.searchsorted(top[i], scales, side="right")  # the first fault sample whose running top is above s
            first[i] = np.where(k < idx.size, k, -1)
    return episodes, first


def _operating_rerun(plan: MetricsPlan, op: OperatingPlan, runs: Any) -> tuple[np.ndarray, np.ndarray]:
    """:func:`operating_values` of a diagnoser with a statistic whose decisions are run again from its residuals at
    each scale (:attr:`fdisyn.runtime.statistics.Statistic.flags_at`); the others' flags from their levels."""
    from fdisyn.runtime.statistics import STATISTICS

    scales = np.asarray(OPERATING_SCALES)
    J = np.asarray(runs.J, dtype=float)
    R, n = J.shape[:2]
    alarm = alarm_level(op, J)[:, None, :] > scales[None, :, None]
    r = np.asarray(runs.r, dtype=float)
    for e, (start, stop, warm) in zip(op.evaluators, op.residuals, strict=True):
        stat = STATISTICS[e.kind]
        # a flag counts one and is raised at the persistence: above 1, a sequential statistic's never is
        if stat.level is None and stat.flags_at is not None and op.persistence <= 1 and warm < n:
            alarm[:, :, warm:] |= stat.flags_at(e, r[:, warm:, start:stop], scales)
    rising = alarm & ~np.concatenate([np.zeros((R, len(scales), 1), dtype=bool), alarm[:, :, :-1]], axis=2)
    episodes = rising[:, :, plan.quiet].sum(axis=2).astype(np.int64)
    hit = alarm[:, :, np.flatnonzero(plan.active)]
    first = np.where(hit.any(axis=2), np.argmax(hit, axis=2), -1).astype(np.int64) if hit.shape[2] else np.full((R, len(scales)), -1, np.int64)
    return episodes, first


ONSET_LAGS = 256
"""The lags after a fault's onset over which the Monte Carlo measures its mean residual shift lag by lag (the
onset-aware bound's; beyond them the fault's whole-time shift)."""


@dataclass(frozen=True, eq=False)
class MetricsPlan:
    """What the per-run summaries of one design in one scenario are taken over (same for every run).

    ``active``: the fault's samples; ``quiet``: the fault-free ones (outside the
    fault and its recovery window); ``on``: the samples whose residual mean
    measures the fault's shift (Lorden bound; ``None``: fault-free scenario);
    ``fault_index``: the true fault's class in the gain file (``None``: none of
    its classes). ``extra``: the extra figures' per-run part and reduction.

    Attributes
    ----------
    active : numpy.ndarray
        ``N`` booleans: the fault's samples.
    quiet : numpy.ndarray
        ``N`` booleans: the fault-free samples (outside the fault and its recovery window).
    on : numpy.ndarray or None
        ``N`` booleans: the samples whose residual mean measures the fault's shift (``None``: fault-free).
    fault_index : int or None
        The true fault's class in the gain file.
    thresholds : tuple of float
        One threshold per statistic.
    extra : object
        The extra figures' per-run part and reduction (``None``: none).
    operating : OperatingPlan or None
        The operating characteristic's plan (``None``: none).
    lags : int
        The fault's first active samples whose residual is summed per lag after the onset (the onset-aware bound's
        measured shift; at most :data:`ONSET_LAGS` and the ``on`` samples; 0: fault-free).
    """

    active: np.ndarray
    quiet: np.ndarray
    on: np.ndarray | None
    fault_index: int | None
    thresholds: tuple[float, ...]
    extra: Any = None
    operating: OperatingPlan | None = None
    lags: int = 0

    @classmethod
    def of(cls, scenario: Any, gf: Any, t: np.ndarray, extra: Any = None, delay_s: float | None = None) -> MetricsPlan:
        """The plan of ``gf``'s diagnoser in ``scenario`` at times ``t``.

        Parameters
        ----------
        scenario : Scenario
            The scenario (:class:`~fdisyn.simulation.problem.Scenario`).
        gf : GainFile
            The diagnoser (its kind gives the recovery and Lorden windows).
        t : numpy.ndarray
            The sample times.
        extra : object, optional
            The extra figures' per-run part and reduction.
        delay_s : float, optional
            The operating characteristic's stated delay ``D`` (:func:`operating_plan`; ``None``: none).

        Returns
        -------
        MetricsPlan
            The plan.
        """
        from fdisyn.synthesis.kinds import lorden_window, recovery_samples

        active = scenario.active(np.asarray(t))
        quiet = ~active
        if active.any():
            last = int(np.flatnonzero(active)[-1])
            quiet[last + 1 : min(len(t), last + 1 + recovery_samples(gf))] = False
        on = None
        if scenario.fault is not None:
            window = lorden_window(gf) or np.iinfo(np.int64).max
            on = active & (np.cumsum(active) <= window)
        fidx = gf.faults.index(scenario.fault) if scenario.fault in gf.faults else None
        return cls(active=active, quiet=quiet, on=on, fault_index=fidx, thresholds=tuple(float(h) for h in gf.thresholds), extra=extra,
                   operating=operating_plan(gf, delay_s), lags=0 if on is None else min(ONSET_LAGS, int(on.sum())))


@dataclass(frozen=True, eq=False)
class RunSummaries:
    """A chunk of ``R`` runs of one design in one scenario, a few numbers per run (arrays over the runs).

    ``quiet_alarms``: alarmed fault-free samples; ``episodes``: false-alarm
    episodes; ``exceed``: fault-free samples above each threshold (``R × nj``);
    ``first_alarm``: position of the first alarm among the fault's samples
    (−1: none); ``alarmed_fault``: alarmed fault samples; ``first_isolation``:
    the first isolation decision in the fault (−1: none); ``mode_isolation``:
    the class isolated most often in the fault (the lowest of a tie; −1: none);
    ``correct_isolated``: alarmed fault samples with the true fault isolated;
    ``r_on``, ``r_off``: residual sums with the fault's shift and without
    (``R × nr``), ``rr_off``: the outer products without (``R × nr × nr``);
    ``nonfinite``: samples with a non-finite input; ``histogram``: the chunk's
    fault-free histogram (:func:`fault_free_histogram`); ``extra``: each run's
    value of the extra figures (``None`` without them).

    Attributes
    ----------
    quiet_alarms, episodes : numpy.ndarray
        Alarmed fault-free samples and false-alarm episodes, per run.
    exceed : numpy.ndarray
        Fault-free samples above each threshold (``R × nj``).
    first_alarm : numpy.ndarray
        Position of the first alarm among the fault's samples (−1: none).
    alarmed_fault : numpy.ndarray
        Alarmed fault samples.
    first_isolation, mode_isolation : numpy.ndarray
        The first and the most frequent isolation decision in the fault (−1: none).
    correct_isolated : numpy.ndarray
        Alarmed fault samples with the true fault isolated.
    r_on, r_off : numpy.ndarray
        Residual sums with the fault's shift and without (``R × nr``).
    rr_off : numpy.ndarray
        The residuals' outer products without it (``R × nr × nr``).
    nonfinite : numpy.ndarray
        Samples with a non-finite input.
    histogram : list of numpy.ndarray
        The chunk's fault-free histogram.
    extra : list or None
        Each run's value of the extra figures.
    operating : tuple of numpy.ndarray or None
        Each run's false-alarm episodes and first alarm at each threshold scale (:func:`operating_values`).
    r_lag : numpy.ndarray or None
        The residual at each of the fault's first ``plan.lags`` active samples (``R × lags × nr``; ``None``: none).
    """

    quiet_alarms: np.ndarray
    episodes: np.ndarray
    exceed: np.ndarray
    first_alarm: np.ndarray
    alarmed_fault: np.ndarray
    first_isolation: np.ndarray
    mode_isolation: np.ndarray
    correct_isolated: np.ndarray
    r_on: np.ndarray
    r_off: np.ndarray
    rr_off: np.ndarray
    nonfinite: np.ndarray
    histogram: list[np.ndarray]
    extra: list[Any] | None = None
    operating: tuple[np.ndarray, np.ndarray] | None = None
    r_lag: np.ndarray | None = None

    @property
    def runs(self) -> int:
        """The number of runs in the chunk."""
        return len(self.quiet_alarms)


def summarise_runs(plan: MetricsPlan, runs: Any, scenario: Any = None, gf: Any = None) -> RunSummaries:
    """The summaries of a chunk of runs.

    Parameters
    ----------
    plan : MetricsPlan
        What the summaries are taken over.
    runs : DesignRuns
        A :class:`~fdisyn.evaluation.runs.DesignRuns`, or anything with its ``r``, ``J``, ``alarm``,
        ``isolated``, ``status``.
    scenario, gf : optional
        The scenario and the gain file, for the extra figures.

    Returns
    -------
    RunSummaries
        A few numbers per run.
    """
    alarm = np.asarray(runs.alarm, dtype=bool)
    isolated = np.asarray(runs.isolated, dtype=np.int64)
    J = np.asarray(runs.J, dtype=float)
    r = np.asarray(runs.r, dtype=float)
    R, n = alarm.shape
    quiet, active = plan.quiet, plan.active
    rising = alarm & ~np.concatenate([np.zeros((R, 1), dtype=bool), alarm[:, :-1]], axis=1)
    exceed = np.sum(J[:, quiet, :] > np.asarray(plan.thresholds)[None, None, :], axis=1).astype(np.int64)
    idx = np.flatnonzero(active)
    hit = alarm[:, idx]
    first_alarm = np.where(hit.any(axis=1), np.argmax(hit, axis=1), -1).astype(np.int64) if idx.size else np.full(R, -1, dtype=np.int64)
    first_iso = np.full(R, -1, dtype=np.int64)
    mode_iso = np.full(R, -1, dtype=np.int64)
    correct = np.zeros(R, dtype=np.int64)
    if plan.fault_index is not None and idx.size:
        iso_win = isolated[:, idx]
        decided = iso_win >= 0
        first_iso = np.where(decided.any(axis=1), iso_win[np.arange(R), np.argmax(decided, axis=1)], -1).astype(np.int64)
        mode_iso = np.array([int(np.bincount(row[row >= 0]).argmax()) if np.any(row >= 0) else -1 for row in iso_win], dtype=np.int64)
        correct = np.sum((iso_win == plan.fault_index) & hit, axis=1).astype(np.int64)
    nr = r.shape[2]
    r_on, r_off, rr_off = np.zeros((R, nr)), np.zeros((R, nr)), np.zeros((R, nr, nr))
    if plan.on is not None:
        on = plan.on
        for i in range(R):  # as the reference sums them: each run's own sum, its rows in sample order
            r_on[i] = np.sum(r[i][on], axis=0)
            off = r[i][~on]
            r_off[i] = np.sum(off, axis=0)
            rr_off[i] = off.T @ off
    r_lag = r[:, idx[: plan.lags], :].copy() if plan.lags else None
    return RunSummaries(
        quiet_alarms=np.sum(alarm[:, quiet], axis=1).astype(np.int64),
        episodes=np.sum(rising[:, quiet], axis=1).astype(np.int64),
        exceed=exceed,
        first_alarm=first_alarm,
        alarmed_fault=np.sum(hit, axis=1).astype(np.int64),
        first_isolation=first_iso,
        mode_isolation=mode_iso,
        correct_isolated=correct,
        r_on=r_on,
        r_off=r_off,
        rr_off=rr_off,
        nonfinite=np.sum(np.asarray(runs.status) == 1, axis=1).astype(np.int64),
        histogram=fault_free_histogram(J[:, quiet, :].reshape(-1, J.shape[2]), plan.thresholds),
        extra=extra_values(plan, runs, scenario, gf),
        operating=operating_values(plan, runs),
        r_lag=r_lag,
    )


def extra_values(plan: MetricsPlan, runs: Any, scenario: Any = None, gf: Any = None) -> list[Any] | None:
    """Each run's value of the plan's extra figures (``None`` without them).

    Parameters
    ----------
    plan : MetricsPlan
        Its ``extra`` computes the figures.
    runs : DesignRuns
        As :func:`summarise_runs` takes them.
    scenario, gf : optional
        The scenario and the gain file.

    Returns
    -------
    list or None
        One value per run.
    """
    if plan.extra is None:
        return None
    rows = {"alarm": np.asarray(runs.alarm, dtype=bool).astype(np.int64), "isolated": np.asarray(runs.isolated, dtype=np.int64),
            "J": np.asarray(runs.J, dtype=float), "r": np.asarray(runs.r, dtype=float)}
    return [plan.extra.per_run(scenario, gf, {k: v[i] for k, v in rows.items()}) for i in range(len(rows["alarm"]))]


class MetricsAccumulator:
    """The metrics of one design in one scenario, merged chunk by chunk in run order (:meth:`add`, :meth:`result`).

    It holds counts (the detection delays as a count per delay), the residual
    sums and, per run, the extra figures' value (designs with extra figures
    only): its size does not grow with the runs but by those values. Sums of floating-point numbers are added run
    by run in run order, so the result does not depend on how the runs were
    chunked or where they ran.

    Parameters
    ----------
    plan : MetricsPlan
        What every chunk's summaries were taken over.
    samples : int
        Samples per run.
    """

    def __init__(self, plan: MetricsPlan, samples: int) -> None:
        self.plan = plan
        self.samples = samples
        self.runs = 0
        nj = len(plan.thresholds)
        self.quiet_alarms = self.quiet_runs = self.episodes = 0
        self.exceed = np.zeros(nj, dtype=np.int64)
        self.detected = self.alarmed_fault = self.first_correct = self.mode_correct = self.mode_wrong = self.correct_isolated = 0
        active = np.flatnonzero(plan.active)
        self.delays = np.zeros(int(active[-1] - active[0] + 1) if active.size else 0, dtype=np.int64)
        """How many runs first alarmed ``k`` samples after the fault's onset, for each ``k``: a size set by the
        samples, not the runs."""
        self.sums: list[Any] | None = None
        self.lag_sums = np.zeros((0, 0))
        """The residual summed over the runs at each lag after the fault's onset (``plan.lags × nr``)."""
        self.nonfinite = 0
        self.histogram: list[np.ndarray] | None = None
        self.extra: list[Any] = []
        self.operating: list[np.ndarray] | None = None
        """The false-alarm episodes and the runs detected within the stated delay, per threshold scale (``None``: no
        operating characteristic, or a chunk without its values)."""
        if plan.operating is not None:
            self.operating = [np.zeros(len(OPERATING_SCALES), dtype=np.int64), np.zeros(len(OPERATING_SCALES), dtype=np.int64)]

    def add(self, s: RunSummaries) -> None:
        """Merge the next chunk's summaries (the chunks in run order).

        Parameters
        ----------
        s : RunSummaries
            The next chunk's summaries.
        """
        p = self.plan
        self.runs += s.runs
        self.quiet_alarms += int(s.quiet_alarms.sum())
        self.quiet_runs += int(np.sum(s.quiet_alarms > 0))
        self.episodes += int(s.episodes.sum())
        self.exceed += s.exceed.sum(axis=0)
        self.detected += int(np.sum(s.first_alarm >= 0))
        self.alarmed_fault += int(s.alarmed_fault.sum())
        idx = np.flatnonzero(p.active)
        if idx.size:
            self.delays += np.bincount(idx[s.first_alarm[s.first_alarm >= 0]] - idx[0], minlength=self.delays.size)
        if p.fault_index is not None:
            self.first_correct += int(np.sum(s.first_isolation == p.fault_index))
            self.mode_correct += int(np.sum(s.mode_isolation == p.fault_index))
            self.mode_wrong += int(np.sum((s.mode_isolation >= 0) & (s.mode_isolation != p.fault_index)))
            self.correct_isolated += int(s.correct_isolated.sum())
        if p.on is not None:
            if self.sums is None:
                nr = s.r_on.shape[1]
                self.sums = [np.zeros(nr), np.zeros(nr), 0, 0, np.zeros((nr, nr))]
            n_on = int(p.on.sum())
            for i in range(s.runs):
                self.sums[0] += s.r_on[i]
                self.sums[1] += s.r_off[i]
                self.sums[2] += n_on
                self.sums[3] += len(p.on) - n_on
                self.sums[4] += s.rr_off[i]
            if p.lags and s.r_lag is not None:
                if self.lag_sums.size == 0:
                    self.lag_sums = np.zeros((p.lags, s.r_lag.shape[2]))
                for i in range(s.runs):
                    self.lag_sums += s.r_lag[i]
        self.nonfinite += int(s.nonfinite.sum())
        self.histogram = list(s.histogram) if self.histogram is None else [a + b for a, b in zip(self.histogram, s.histogram, strict=True)]
        if s.extra is not None:
            self.extra += s.extra
        if self.operating is not None:
            if s.operating is None:
                self.operating = None
            else:
                episodes, first = s.operating
                one = OPERATING_SCALES.index(1.0)  # the design itself: its decisions as the step made them
                if not (np.array_equal(episodes[:, one], s.episodes) and np.array_equal(first[:, one], s.first_alarm)):
                    from fdisyn.runtime.errors import InternalError

                    raise InternalError("the operating characteristic's decisions at the design's own thresholds differ from the step's")
                assert p.operating is not None
                self.operating[0] += episodes.sum(axis=0)
                self.operating[1] += np.sum((first >= 0) & (first <= p.operating.within), axis=0)

    def detected_within(self, within: int) -> int:
        """The runs whose first alarm came at most ``within`` samples after the fault's onset.

        Parameters
        ----------
        within : int
            Samples after the onset (:func:`within_samples`).

        Returns
        -------
        int
            The runs.
        """
        return int(self.delays[: max(int(within), -1) + 1].sum())

    def result(
        self, *, scenario: str, fault: str | None, P_f: Sequence[float], Ts: float, budget_s: float | None = None,
        lorden: tuple[float, float] | None = None, onset_bound: float | None = None,
    ) -> ScenarioMetrics:
        """The merged :class:`ScenarioMetrics`.

        Parameters
        ----------
        scenario : str
            The scenario's name.
        fault : str or None
            The fault it injects.
        P_f : sequence of float
            Each statistic's per-sample false-alarm probability.
        Ts : float
            The sample time in seconds.
        budget_s : float, optional
            The design's false-alarm budget in seconds.
        lorden : tuple of float, optional
            ``(I, bound in samples)`` of the fault, from :attr:`sums`.
        onset_bound : float, optional
            The onset-aware bound in samples, from :attr:`sums` and :attr:`lag_sums`
            (:func:`fdisyn.synthesis.kinds.onset_lorden_bound`).

        Returns
        -------
        ScenarioMetrics
            Equal to the last bit to :func:`scenario_metrics` of the stacked runs.
        """
        p, runs, n = self.plan, self.runs, self.samples
        n_quiet = int(p.quiet.sum())
        far = self.quiet_alarms / (runs * n_quiet) if n_quiet else 0.0
        far_runs = self.quiet_runs / runs if n_quiet else 0.0
        exc_rate = [int(c) / (runs * n_quiet) if n_quiet else 0.0 for c in self.exceed]
        intervals = []
        for pf in P_f:
            lo, hi = binomial_interval(runs * n_quiet, float(pf))
            total = max(runs * n_quiet, 1)
            intervals.append((lo / total, hi / total))
        md = maf = d_mean = d_med = d_max = ds_mean = iso_acc = first_acc = siso = false_iso = None
        ds_max: int | None = None
        n_active = int(p.active.sum())
        if n_active:
            md = 1.0 - self.detected / runs
            maf = 1.0 - self.alarmed_fault / (runs * n_active)
            count = int(self.delays.sum())
            if count:  # what mean, median and max of the delays give, from their counts (sums of integers: exact)
                ks = np.flatnonzero(self.delays)
                ds_mean = float(np.float64(int(ks @ self.delays[ks])) / np.float64(count))
                ds_max = int(ks[-1])
                below = np.cumsum(self.delays)
                lo, hi = (int(np.searchsorted(below, m, side="right")) for m in ((count - 1) // 2, count // 2))
                d_mean, d_med, d_max = ds_mean * Ts, float((np.float64(lo) + np.float64(hi)) / 2) * Ts, ds_max * Ts
            if p.fault_index is not None:
                first_acc = self.first_correct / runs
                iso_acc = self.mode_correct / runs
                false_iso = self.mode_wrong / runs
                siso = self.correct_isolated / self.alarmed_fault if self.alarmed_fault else 0.0
        exposure = runs * n_quiet * Ts
        mtbfa_lo, mtbfa_hi = poisson_time_interval(self.episodes, exposure)
        ratio = delay_bound_ratio(ds_mean, lorden if onset_bound is None else (float("nan"), onset_bound))
        stationary = delay_bound_ratio(ds_mean, lorden)
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
            nonfinite_samples=self.nonfinite,
            false_alarm_episodes=self.episodes,
            mean_time_between_false_alarms_s=exposure / self.episodes if self.episodes else None,
            mean_time_between_false_alarms_interval_s=(mtbfa_lo, mtbfa_hi),
            arl0_budget_s=budget_s,
            fault_information=None if lorden is None else lorden[0],
            lorden_bound_samples=None if lorden is None else lorden[1],
            delay_bound_ratio=ratio,
        onset_bound_samples=onset_bound,
        stationary_bound_ratio=stationary,
            false_isolation_rate=false_iso,
            fault_free_histogram=[c.tolist() for c in self.histogram or []],
            operating=None if self.operating is None or p.operating is None else {
                "scales": list(OPERATING_SCALES), "episodes": self.operating[0].tolist(),
                "detected_within": self.operating[1].tolist() if n_active else None, "delay_s": p.operating.delay_s,
            },
        )


DETECTION_GOAL = 0.95
"""The share of runs that must detect for a fault size to count as detected (:func:`isolation_at_size`)."""
ISOLATION_GOAL = 0.95
"""The share of runs that must name the true fault from :data:`ISOLATION_MARGIN` × the detected size on."""
ISOLATION_MARGIN = 1.5
"""Isolation is asked of every size from this multiple of the smallest size detected in :data:`DETECTION_GOAL`
of the runs."""


@dataclass(frozen=True)
class IsolationAtSize:
    """Detection and isolation of one fault class against its size (:func:`isolation_at_size`).

    Attributes
    ----------
    detected_from : float or None
        The smallest size of the detection grid from which every measured size is detected in at least
        :data:`DETECTION_GOAL` of the runs (``None``: not even the largest).
    isolated_from : float or None
        The smallest measured size from which every larger one names the true fault in at least
        :data:`ISOLATION_GOAL` of the runs (``None``: not even the largest).
    isolation : float or None
        The smallest share of runs naming the true fault over the sizes from ``ISOLATION_MARGIN × detected_from``
        on (``None`` when no size was measured there).
    another : float or None
        At the size where ``isolation`` is smallest, the share of runs whose most frequent decision names
        another fault; the rest named none.
    at : float or None
        That size.
    met : bool
        ``isolation ≥ ISOLATION_GOAL``.
    """

    detected_from: float | None
    isolated_from: float | None
    isolation: float | None
    another: float | None
    at: float | None
    met: bool


def isolation_at_size(points: Mapping[float, ScenarioMetrics], detection_grid: Sequence[float]) -> IsolationAtSize | None:
    """Whether a fault class is isolated from :data:`ISOLATION_MARGIN` × the size at which it is detected.

    Parameters
    ----------
    points : Mapping of float to ScenarioMetrics
        The Monte Carlo of one faulty scenario at each size (a multiple of the scenario's own).
    detection_grid : Sequence of float
        The sizes on which the detected size is sought; each times :data:`ISOLATION_MARGIN` must be among the
        measured sizes for the check to see its first size.

    Returns
    -------
    IsolationAtSize or None
        ``None`` where the diagnoser does not isolate (no isolation measured).
    """
    sizes = sorted(points)
    if any(points[f].isolation_accuracy is None for f in sizes):
        return None

    def detects(f: float) -> bool:
        missed = points[f].missed_detection_rate
        return missed is not None and 1.0 - missed >= DETECTION_GOAL

    def names(f: float) -> bool:
        return (points[f].isolation_accuracy or 0.0) >= ISOLATION_GOAL

    grid = [f for f in sorted(detection_grid) if f in points]
    detected = next((f for f in grid if all(detects(g) for g in sizes if g >= f)), None)
    isolated = next((f for i, f in enumerate(sizes) if all(names(g) for g in sizes[i:])), None)
    if detected is None:
        return IsolationAtSize(None, isolated, None, None, None, False)
    asked = [f for f in sizes if f >= ISOLATION_MARGIN * detected * (1.0 - 1e-9)]  # the margin's product rounds
    if not asked:
        return IsolationAtSize(detected, isolated, None, None, None, False)
    worst = min(asked, key=lambda f: (points[f].isolation_accuracy or 0.0, f))
    iso = points[worst].isolation_accuracy or 0.0
    return IsolationAtSize(detected, isolated, iso, points[worst].false_isolation_rate, worst, iso >= ISOLATION_GOAL)

