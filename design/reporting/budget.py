"""A design's false-alarm budget as the terminal and the pages show it, the budget table (measured time between
false alarms against the budget, delay against the Lorden bound) and the detectors compared at one budget."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

from fdisyn.reporting.kit import defined, duration, fmt, folded, label, table, variant_name
from fdisyn.detectors.table import DETECTORS
from fdisyn.simulation.problem import Problem
from fdisyn.synthesis.kinds import false_alarm_budget, get_kind

__all__ = ["budget_line", "budget_table", "detectors_section", "RATIO_GOAL", "RANGE_RATIO_GOAL"]


def _design_rates(gf: Any) -> tuple[str | None, list[float]]:
    """What set a gain file's thresholds (``'arl0'``, ``'P_f'`` or None: given thresholds) and its rates per
    statistic and sample, as its data say: a bank's statistics carry their ``P_f`` (its certificate's ``bank`` block
    the ``arl0_s`` it was designed for); another kind's payload its ``settings`` (``false_alarm_probability``,
    ``arl0``) or its ``design`` block (``P_f``, ``arl0_s``)."""
    if gf.evaluators:
        info = (gf.certificate.get("bank") or {}).get("info") or {}
        return ("arl0" if isinstance(info.get("arl0_s"), (int, float)) else "P_f"), [float(e.P_f) for e in gf.evaluators]
    payload = gf.extensions.get(gf.kind)
    if not isinstance(payload, Mapping):
        return None, []
    st = payload.get("settings")
    if isinstance(st, Mapping) and "false_alarm_probability" in st:
        return ("arl0" if st.get("arl0") is not None else "P_f"), [float(st["false_alarm_probability"])]
    info = payload.get("design") or {}
    if isinstance(info, Mapping) and isinstance(info.get("P_f"), (int, float)):
        return ("arl0" if isinstance(info.get("arl0_s"), (int, float)) else "P_f"), [float(info["P_f"])]
    return None, []


def budget_line(gf: Any) -> str:
    """The design's false-alarm budget for the terminal and the page: ``false-alarm budget: one every 1 h (arl0 =
    3600 s); P_f = 1.389·10⁻⁷ per statistic and sample (2 statistics)``, or for a design by ``P_f`` ``…: one every
    5 s (from P_f = 1·10⁻⁴ per statistic and sample, 2 statistics)``; a gain file whose thresholds were given says so.

    Parameters
    ----------
    gf : GainFile
        A certified gain file.

    Returns
    -------
    str
        One line.
    """
    seconds = false_alarm_budget(gf)
    source, rates = _design_rates(gf)
    if seconds is None or source is None:
        return "false-alarm budget: none designed (the thresholds were given)"
    many = f", {len(rates)} statistics" if len(rates) > 1 else ""
    same = all(math.isclose(r, rates[0], rel_tol=1e-9) for r in rates)
    p = f"{fmt(rates[0])}" if same else f"{fmt(min(rates))} to {fmt(max(rates))}"
    per = get_kind(gf.kind).rate_unit
    if source == "arl0":
        return f"false-alarm budget: one every {duration(seconds)} (arl0 = {fmt(seconds)} s); P_f = {p} {per}{many}"
    return f"false-alarm budget: one every {duration(seconds)} (from P_f = {p} {per}{many})"


def _mtbfa(mean_s: float | None, interval: tuple[float, float | None]) -> str:
    """A measured mean time between false alarms with its 95 % interval, as durations (:func:`duration`):
    "2 min [1.33 min, 3.17 min]"; none seen: "none seen (> 6.67 min)", the interval's lower end."""
    lo, hi = interval
    if mean_s is None:
        return f"none seen (> {duration(lo)})"
    return f"{duration(mean_s)} [{duration(lo)}, {duration(hi)}]"


RATIO_GOAL = 1.2
"""The goal of a mean detection delay over its Lorden bound at the fault's designed size (:func:`_ratio`)."""

RANGE_RATIO_GOAL = 1.5
"""The goal of that ratio over whitened shifts from 0.25σ to 4σ: a detector tuned to one size cannot hold
:data:`RATIO_GOAL` at every other."""


def _ratio_bound(m: Any) -> float | None:
    """The bound the delay ratio is over, in samples: the onset-aware bound, else the step's Lorden bound."""
    return m.lorden_bound_samples if getattr(m, "onset_bound_samples", None) is None else m.onset_bound_samples


def _meets_goal(m: Any) -> bool | None:
    """Whether the mean delay is within :data:`RATIO_GOAL` times the Lorden bound; None where the ratio says nothing:
    the bound under one sample (a fault so large that any detector needs the onset sample), or a delay under half
    the bound (faster than the bound allows: the fault is no persistent mean shift)."""
    bound = _ratio_bound(m)
    if m.delay_bound_ratio is None or bound is None or bound < 1.0 or m.delay_bound_ratio < 0.5:
        return None
    return bool(m.delay_bound_ratio <= RATIO_GOAL)


def _ratio(m: Any) -> str:
    """Mean delay over the Lorden bound, with a class when it meets the goal (:func:`_meets_goal`); "no mean shift"
    under half the bound, "—" where the bound is under one sample."""
    ok = _meets_goal(m)
    if ok is None:
        bound = _ratio_bound(m)
        shown = m.delay_bound_ratio is not None and bound is not None and bound >= 1.0
        return "no mean shift" if shown else "—"
    return f'<span class="{"ok" if ok else "bad"}">{fmt(m.delay_bound_ratio, 3)}</span>'


def budget_table(problem: Problem, pairs: Sequence[tuple[Any, str]], scen: Sequence[str], *, by_variant: bool = False) -> str:
    """Per design (and variant) and scenario: the false-alarm time against the budget, the delay against the
    Lorden bound."""
    rows = []
    for s in scen:
        for v, d in pairs:
            if s not in v.evaluation.metrics[d]:
                continue
            m = v.evaluation.metrics[d][s]
            if m.arl0_budget_s is None:
                continue
            bound_s = None if m.lorden_bound_samples is None else m.lorden_bound_samples * m.Ts
            head = [label(problem, s), variant_name(v), label(problem, d)] if by_variant else [label(problem, s), label(problem, d)]
            rows.append(
                [
                    *head, _mtbfa(m.mean_time_between_false_alarms_s, m.mean_time_between_false_alarms_interval_s), duration(m.arl0_budget_s), m.missed_detection_rate, m.detection_delay_mean_s, bound_s, _ratio(m),
                    m.isolation_accuracy, m.false_isolation_rate,
                ]
            )
    if not rows:
        return ""
    header = ["scenario", *(["detector"] if by_variant else []), "design",
              defined("time between false alarms [95 %]", "mean time between false alarms"), defined("budget", "budget"),
              defined("missed detection (of runs)", "missed detection"), defined("delay mean (s)", "detection delay"),
              defined("Lorden bound (s)", "Lorden bound"), defined("delay / bound", "delay ratio"),
              defined("isolation acc.", "isolation accuracy"), defined("false isolation", "false isolation")]
    own = {get_kind(v.built[d].gain_file.kind).budget_text for v, d in pairs}
    shared = next(iter(own)) if len(own) == 1 else None
    if shared is not None:  # the designs' kinds share their own prose
        return "<h4>False-alarm budget and the Lorden bound</h4>" + shared + table(header, rows, left=3 if by_variant else 2)
    return (
        "<h4>False-alarm budget and the Lorden bound</h4>"
        '<p class="small">Time between false alarms: fault-free time over the number of false-alarm episodes, with Garwood\'s '
        "exact 95 % Poisson interval; budget: the design's arl0, or Ts/Σ P_f for a design by P_f. A bank splits its budget "
        "equally over its statistics (Bonferroni), so it is met or exceeded. Lorden bound: ln(ARL)/I, the smallest over the "
        "statistics of ln of each one's share of the budget (in samples) over the Kullback–Leibler information per sample the "
        "fault brought to its generator's residual (measured mean shift, long-run covariance; Lorden, Annals of Mathematical "
        "Statistics 42(6), 1971): no detector with that budget is faster on average for a persistent change. The ratio is "
        "over the onset-aware bound, the time the cumulative information of the fault's measured shift lag by lag after the "
        "onset takes to reach ln(ARL) (Lai, IEEE Transactions on Information Theory 44(7), 1998; the Lorden bound for a step), "
        f"shown where the bound is at least one sample; the goal is ≤ {fmt(RATIO_GOAL)}. \"No mean shift\": detected more than twice "
        "as fast as the bound allows, so the fault is not the persistent mean change the bound is for (a gain fault on a "
        "varying signal, whose residual effect averages out). Isolation is the bank's hypothesis test across the fault "
        "classes (a GLR on the residuals' exponentially weighted sum, each class kept or rejected at the design's "
        "false-isolation level, the name held while the alarm is raised); false isolation: runs whose most frequent "
        "decision names another fault.</p>"
        + table(header, rows, left=3 if by_variant else 2)
    )


def _compared_detectors(variants: Sequence[Any]) -> str:
    """The detectors of the variants with an ``arl0``, named for the comparison's first sentence: "WSSR (…) and CUSUM (…)"."""
    used = {v.options.get("detector") for v in variants if v.options.get("arl0") is not None}
    named = [d.cited for key, d in DETECTORS.items() if key in used]  # in the table's order
    listed = (", ".join(named[:-1]) + " and " + named[-1] if len(named) > 1 else "".join(named)) or "the"
    return listed[:1].upper() + listed[1:]


def _budget_summary(problem: Problem, pairs: Sequence[tuple[Any, str]]) -> str:
    """One row per detector and design: the time between false alarms over every scenario's fault-free samples
    against the budget, and the faulty scenarios' missed detections, delays, delay/bound goals and isolation."""
    from fdisyn.evaluation.metrics import poisson_time_interval

    def mean(values: Iterable[Any]) -> float | None:
        vals = [float(x) for x in values if x is not None]
        return sum(vals) / len(vals) if vals else None

    rows = []
    for v, d in pairs:
        ms = [m for m in v.evaluation.metrics[d].values() if m.arl0_budget_s is not None]
        if not ms:
            continue
        episodes = sum(m.false_alarm_episodes for m in ms)
        exposure = sum(m.fault_free_samples * m.Ts for m in ms)
        mtbfa = _mtbfa(exposure / episodes if episodes else None, poisson_time_interval(episodes, exposure))
        faulty = [m for m in ms if m.fault is not None]
        goals = [g for g in (_meets_goal(m) for m in faulty) if g is not None]
        rows.append([variant_name(v), label(problem, d), mtbfa, duration(ms[0].arl0_budget_s), mean(m.missed_detection_rate for m in faulty),
                     mean(m.detection_delay_mean_s for m in faulty), f"{sum(goals)} of {len(goals)}" if goals else "—",
                     mean(m.isolation_accuracy for m in faulty), mean(m.false_isolation_rate for m in faulty)])
    if not rows:
        return ""
    return (
        '<p class="small">One row per detector: the time between false alarms over every scenario\'s fault-free samples '
        "[95 %] against the budget; missed detection, delay and isolation: means over the faulty scenarios; delay within "
        f"{fmt(RATIO_GOAL)} × bound: the faulty scenarios whose mean delay is within {fmt(RATIO_GOAL)} times the Lorden bound, "
        "of those that show the ratio. Every scenario and the columns' meaning: folded below.</p>"
        + table(["detector", "design", defined("time between false alarms [95 %]", "mean time between false alarms"),
                 defined("budget", "budget"), defined("missed detection (of runs, mean)", "missed detection"),
                 defined("delay mean (s)", "detection delay"), defined(f"delay within {fmt(RATIO_GOAL)} × bound", "delay ratio"),
                 defined("isolation acc. (mean)", "isolation accuracy"), defined("false isolation (mean)", "false isolation")],
                rows, left=2)
    )


def detectors_section(problem: Problem, variants: Sequence[Any]) -> str:
    """The page's section on the detectors side by side at the same false-alarm budget (the variants with an ``arl0``
    option): which detectors (the kind's :attr:`~fdisyn.synthesis.kinds.DiagnoserKind.detectors_text` when every
    design's kind gives the same one, else those the variants name), one row per detector, every scenario folded.

    Parameters
    ----------
    problem : Problem
        The problem (its labels).
    variants : sequence of VariantResult
        The report's variants.

    Returns
    -------
    str
        The section's HTML; empty with fewer than two variants at a budget.
    """
    same = [v for v in variants if v.options.get("arl0") is not None]
    if len(same) < 2:
        return ""
    scen: list[str] = []
    for v in same:
        for s in next(iter(v.evaluation.metrics.values())):
            if s not in scen:
                scen.append(s)
    pairs = [(v, d) for v in same for d in v.evaluation.metrics]
    full = budget_table(problem, pairs, scen, by_variant=True)
    if not full:
        return ""
    own = {get_kind(b.gain_file.kind).detectors_text for v in variants for b in v.built.values()}
    what = own.pop() if len(own) == 1 and None not in own else f"{_compared_detectors(variants)} statistics of the same generators"
    return (f"<p>{what}, each designed for the same mean time between false alarms arl0.</p>"
            + _budget_summary(problem, pairs) + folded(full, "Every scenario"))
