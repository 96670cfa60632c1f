"""The figures every page has where its data allow (statistics against their law, detection against the fault's
size, the residuals' frequency responses, the generators' poles), and the run figures of a problem without its own
report hook."""

from __future__ import annotations

import textwrap
from collections.abc import Mapping
from typing import Any

import numpy as np
from fdisyn.reporting.kit import MIN_FONT_PT, ReportContext, defined, figure_legend, fmt, folded, label, subplots, table
from fdisyn.reporting.plots import ESTIMATE_PREFIX, LAW_PANELS, _law_panels, _sweep_points, plot_detection, plot_laws, plot_trace
from fdisyn.evaluation.metrics import DETECTION_GOAL, ISOLATION_GOAL, ISOLATION_MARGIN, OPERATING_SCALES, isolation_at_size
from fdisyn.simulation.problem import Problem

__all__ = ["run_figures", "standard_figures", "POLE_LEGEND", "OPERATING_TICKS", "operating_curve"]


def run_figures(ctx: ReportContext) -> list[tuple[str, str]]:
    """Figures of a problem without its own report hook (e.g. a TOML plant file).

    For every design and scenario, run 0 through the generated C (:func:`~fdisyn.reporting.plots.plot_trace`):
    each statistic that has a fixed threshold, divided by it (an alarm is above 1), with the alarm instants; the
    isolated fault; and for parameter estimators (``theta_hat_<θ>`` statistics) the estimate beside the simulated
    truth ``true_<θ>``.
    """
    v = ctx.variants[0]
    ex, bt = v.evaluation.examples, v.evaluation.batches
    body = []
    for dname, built in v.built.items():
        gf = built.gain_file
        for sname, res in ex.get(dname, {}).items():
            trace = bt[sname].trace(0)
            fig = plot_trace(gf, trace, res, labels=ctx.problem.labels)
            est = any(n.startswith(ESTIMATE_PREFIX) and f"true_{n[len(ESTIMATE_PREFIX):]}" in trace.extra for n in gf.step.statistic_names)
            body.append(
                ctx.figure(
                    f"{dname}_{sname}",
                    fig,
                    f"{label(ctx.problem, dname)}, scenario {label(ctx.problem, sname)} ({ctx.problem.scenarios[sname].description or 'no description'}): run 0 "
                    "through the generated C — statistics over their thresholds with the alarm instants (red ticks), the isolated fault"
                    + (", the parameter estimates against the truth." if est else "."),
                )
            )
    return [("Figures", "".join(body))] if body else []


def _law_figures(ctx: ReportContext) -> str:
    """Per design, each statistic's fault-free histogram over every run against its law
    (:func:`~fdisyn.reporting.plots.plot_laws`): its density against the closed-form law of its detector where it has
    one (:attr:`fdisyn.detectors.table.Detector.null_law`: χ²(dof) for a χ² statistic); for the others (WSSR, CUSUM,
    GLR, …) the empirical tail P(J ≥ x) against the threshold and the design's P_f."""
    v, problem, out = ctx.variants[0], ctx.problem, []
    for k, (d, b) in enumerate(v.built.items()):
        gf = b.gain_file
        counts, shown = _law_panels(v.evaluation.metrics.get(d, {}), gf, LAW_PANELS)
        if not shown:
            continue
        with_threshold = sum(1 for c in counts if c.size)
        samples = max(int(counts[j].sum()) for j in shown)
        fig = plot_laws(v, d, labels=problem.labels)
        caption = (
            f"{label(problem, d)}: the fault-free samples of every run and scenario ({fmt(samples)} per statistic), binned from "
            "0 to 3 thresholds in steps of a twentieth. χ² statistics: histogram (density) against the χ² density with the "
            "statistic's degrees of freedom (black); other statistics: the empirical tail P(J ≥ x) against the design's P_f "
            "(red, dotted). Dashed: the threshold."
            + (f" The first {len(shown)} of the {with_threshold} statistics with a threshold." if len(shown) < with_threshold else "")
        )
        body = ctx.figure(f"law_{d}", fig, caption)
        out.append(body if k == 0 else folded(body, label(problem, d)))
    return "".join(out)


def _sweep_figure(ctx: ReportContext) -> str:
    """Mean detection delay, the share of runs that detect (and that name the true fault) and, where the diagnoser
    has a Lorden bound, the delay over the bound against the fault's size, per design and faulty scenario
    (:func:`~fdisyn.reporting.plots.plot_detection`); below, the isolation goal's table (:func:`_isolation_goal_table`)."""
    from fdisyn.reporting.budget import RATIO_GOAL

    v, problem = ctx.variants[0], ctx.problem
    sweep = getattr(v, "sweep", None)
    if sweep is None or not sweep.scenarios:
        return ""
    designs, factors, metric = _sweep_points(sweep, v.evaluation)
    bounded = any(metric(d, b, f).delay_bound_ratio is not None for d in designs for b, fs in factors.items() for f in fs)
    isolating = any(metric(d, b, f).isolation_accuracy is not None for d in designs for b, fs in factors.items() for f in fs)
    rows, goals = [], []
    for d in designs:
        for base, fs in factors.items():
            ms = [metric(d, base, f) for f in fs]
            rows += [[label(problem, d), label(problem, base), f, m.runs, m.missed_detection_rate, m.detection_delay_mean_s,
                      m.delay_bound_ratio, m.isolation_accuracy] for f, m in zip(fs, ms, strict=True)]
            if isolating:
                goal = isolation_at_size(dict(zip(fs, ms, strict=True)), sweep.detection_grid)
                if goal is not None:
                    goals.append((d, base, ms[0].fault, goal))
    fig = plot_detection(sweep, v.evaluation, labels=problem.labels)
    return ctx.figure(
        "fault_size_sweep",
        fig,
        f"Detection against the fault's size: each faulty scenario with its fault scaled by {', '.join(fmt(f) for f in sweep.factors)} "
        f"({fmt(sweep.evaluation.runs)} runs each; 1 is the scenario itself with the page's runs). Offsets and drifts scale "
        "their value, a gain fault its deviation from 1."
        + (f" Right: the mean delay over the Lorden bound ln(ARL)/I of the fault at that size (black: the bound; red, dotted: "
           f"the goal {fmt(RATIO_GOAL)}); a detector tuned to one size falls behind the bound at the others." if bounded else "")
        + " A hollow point: more than half the runs missed the fault, and the delay is the mean over the few that did not."
        + f" Middle: the share of runs that detected (solid)"
        + (f" and whose most frequent decision names the true fault (dashed, squares)" if isolating else "")
        + f"; red, dotted: {fmt(100 * DETECTION_GOAL)} %.",
    ) + _isolation_goal_table(problem, goals, sweep.detection_grid) + (
        folded(table(["design", "scenario", "size (×)", "runs", defined("missed detection (of runs)", "missed detection"),
                      defined("delay mean (s)", "detection delay"), defined("delay / bound", "delay ratio"),
                      defined("true fault named (of runs)", "isolation accuracy")], rows, left=2))
    )


def _isolation_goal_table(problem: Problem, goals: list[tuple[str, str, str | None, Any]], grid: tuple[float, ...]) -> str:
    """Per isolating design and faulty scenario: the size detected in 95 % of the runs, and whether the true fault
    is named in 95 % of them from 1.5 × that size on (:func:`~fdisyn.evaluation.metrics.isolation_at_size`)."""
    if not goals:
        return ""
    rows = []
    for d, base, fault, g in goals:
        if g.detected_from is None:
            verdict = '<span class="bad">not detected in 95 % at any size</span>'
        elif g.isolation is None:
            verdict = f"not measured beyond {fmt(ISOLATION_MARGIN)} × {fmt(g.detected_from)}"
        else:
            verdict = "met" if g.met else '<span class="bad">short</span>'
        rows.append([label(problem, d), label(problem, base), label(problem, fault) if fault else "—",
                     "—" if g.detected_from is None else f"{fmt(g.detected_from)} ×",
                     "—" if g.isolation is None else f"{fmt(100 * g.isolation)} % at {fmt(g.at)} ×",
                     "—" if g.another is None else f"{fmt(100 * g.another)} %",
                     "—" if g.isolated_from is None else f"{fmt(g.isolated_from)} ×", verdict])
    met = sum(1 for *_, g in goals if g.met)
    return (
        f"<p class=\"small\">Isolation against detection: for each fault class, the smallest size of the grid "
        f"{', '.join(fmt(f) for f in grid)} × the scenario's from which every larger one is detected in "
        f"{fmt(100 * DETECTION_GOAL)} % of the runs, and the true fault's share of the runs at every measured size from "
        f"{fmt(ISOLATION_MARGIN)} × that on (the smallest share shown, with the share naming another fault there; the "
        f"rest named none). Goal: {fmt(100 * ISOLATION_GOAL)} %; met for {met} of {len(goals)}.</p>"
        + table(["design", "scenario", "fault", f"detected in {fmt(100 * DETECTION_GOAL)} % from",
                 f"true fault named from {fmt(ISOLATION_MARGIN)} × that", "another fault named there",
                 f"named in {fmt(100 * ISOLATION_GOAL)} % from", "goal"], rows, left=3)
    )


def _shift_figure(ctx: ReportContext) -> str:
    """Each sequential design's mean delay over the onset-aware Lorden bound (and, thin and dashed, over the step's
    bound ``ln(ARL)/I``), and its missed detections, against the whitened shift its fault brings (the variants' :attr:`~fdisyn.app.pipeline.VariantResult.shifts`)."""
    from fdisyn.reporting.budget import RANGE_RATIO_GOAL
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    problem = ctx.problem
    swept = [v for v in ctx.variants if getattr(v, "shifts", None) is not None]
    if not swept:
        return ""
    fig, axes = subplots(1, 2, figsize=(13.0, 3.8), squeeze=False)  # wide: the legend names design and variant
    rows, handles, texts = [], [], []
    for v in swept:
        sw = v.shifts
        for d, per in sw.metrics.items():
            sig = list(sw.sigmas)
            ms = [per[s] for s in sig]
            ratios = [np.nan if m.delay_bound_ratio is None else m.delay_bound_ratio for m in ms]
            name = f"{label(problem, d)}, {v.label}"
            (line,) = axes[0, 0].plot(sig, ratios, "o-", lw=1.0, ms=3)
            steps = [np.nan if m.stationary_bound_ratio is None else m.stationary_bound_ratio for m in ms]
            axes[0, 0].plot(sig, steps, "--", lw=0.6, alpha=0.6, color=line.get_color())
            lucky = [j for j, m in enumerate(ms) if m.missed_detection_rate > 0.5]
            axes[0, 0].plot([sig[j] for j in lucky], [ratios[j] for j in lucky], "o", ms=5, mfc="white", color=line.get_color())
            axes[0, 1].plot(sig, [m.missed_detection_rate for m in ms], "o-", lw=1.0, ms=3, color=line.get_color())
            handles.append(line)
            texts.append(name)
            rows += [[label(problem, d), v.label, s, sw.factors[d][s], m.runs, m.missed_detection_rate,
                      None if m.lorden_bound_samples is None else m.lorden_bound_samples * m.Ts,
                      None if m.onset_bound_samples is None else m.onset_bound_samples * m.Ts, m.detection_delay_mean_s,
                      m.stationary_bound_ratio, m.delay_bound_ratio] for s, m in zip(sig, ms, strict=True)]
    ax = axes[0, 0]
    ax.axhline(1.0, color="k", lw=0.8)
    ax.axhline(RANGE_RATIO_GOAL, color="tab:red", ls=":", lw=1.0)
    ax.set_yscale("log")
    ax.yaxis.set_major_locator(LogLocator(subs=(1.0, 1.5, 2.0, 5.0)))
    ax.yaxis.set_major_formatter(FuncFormatter(lambda x, _: fmt(x)))
    ax.yaxis.set_minor_formatter(NullFormatter())
    ax.set_ylabel("delay / onset-aware bound")
    axes[0, 1].set_ylabel("missed detection")
    axes[0, 1].set_ylim(-0.03, 1.03)
    sigmas = list(swept[0].shifts.sigmas)
    for a in axes[0]:
        a.set_xscale("log")
        a.set_xticks(sigmas, [fmt(x) for x in sigmas])
        a.minorticks_off()
        a.grid(alpha=0.3)
        a.set_xlabel("whitened mean shift (σ)")
    figure_legend(fig, handles, texts)
    first = swept[0].shifts
    return ctx.figure(
        "shift_sweep",
        fig,
        f"Delay against the size of the fault, in σ of the whitened residual: {label(problem, first.scenario)} with its "
        f"fault scaled, for each design with sequential statistics, until it shifts the residual by "
        f"{', '.join(fmt(x) for x in sigmas)} σ (√(2 I), I the fault's information per sample as the Monte Carlo measured it; "
        f"{fmt(first.runs)} runs each; the fault acts for at least five Lorden bounds of the smallest shift, the scenario lengthened "
        "where it is shorter). Left, solid: the mean delay over the onset-aware Lorden bound, the smallest n whose "
        "cumulative information Σ_{ℓ<n} I(ℓ) reaches ln(ARL), I(ℓ) the information of the fault's mean residual shift ℓ "
        "samples after its onset as the Monte Carlo measured it lag by lag (Lai, IEEE Transactions on Information Theory "
        "44(7), 1998): it follows the residual's transient after the onset, and is ln(ARL)/I for a step. Thin, dashed: "
        "over the step's bound ln(ARL)/I (Lorden, Annals of Mathematical Statistics 42(6), 1971), which takes the whole "
        "steady shift from the first faulty sample on and so is too low where the residual builds up over samples the "
        "bound counts (the largest shifts). Both counted as the faulty "
        f"samples seen at the alarm (black: the bound; red, dotted: the goal {fmt(RANGE_RATIO_GOAL)} over the range, on the "
        "onset-aware ratio). A hollow point: more than half the runs missed the fault. A CUSUM tuned to one shift falls "
        "behind the bound away from it; the multi-scale CUSUM, tuned to each of the shifts at once, should not. A residual "
        "that overshoots its steady shift after the onset is detected faster than the step's bound (a ratio below 1).",
    ) + folded(
        table(["design", "variant", "shift (σ)", "size (× scenario's)", "runs", defined("missed detection (of runs)", "missed detection"),
               defined("Lorden bound (s)", "Lorden bound"), defined("onset-aware bound (s)", "onset-aware bound"),
               defined("delay mean (s)", "detection delay"), "delay / Lorden bound",
               defined("delay / onset-aware bound", "delay ratio")], rows, left=2)
    )


OPERATING_COLUMNS = 3
"""Panels per row of the operating characteristic (one panel per report variant)."""

OPERATING_TICKS = (1.0, 10.0, 60.0, 600.0, 3600.0, 36000.0, 86400.0, 7 * 86400.0, 30 * 86400.0, 365.25 * 86400.0)
"""Where the operating characteristic's time axis is labelled (1 s, 10 s, 1 min, 10 min, 1 h, 10 h, 1 day, 7 days,
30 days, 1 year)."""


def operating_curve(metrics: Mapping[str, Any]) -> dict[str, Any] | None:
    """A design's operating characteristic pooled over the scenarios of one Monte Carlo
    (:attr:`~fdisyn.evaluation.metrics.ScenarioMetrics.operating`).

    Parameters
    ----------
    metrics : Mapping of str to ScenarioMetrics
        The design's metrics, by scenario.

    Returns
    -------
    dict or None
        ``scales``; ``mtbfa_s`` (fault-free time over the episodes at each scale, ``inf`` where none was seen);
        ``exposure_s`` (that time); ``pd`` (runs of the faulty scenarios detected within ``delay_s``, over them);
        ``runs`` (those runs); ``delay_s``. ``None`` when a scenario has no counts or none is faulty.
    """
    ms = list(metrics.values())
    if not ms or any(m.operating is None for m in ms):
        return None
    faulty = [m for m in ms if m.operating["detected_within"] is not None]
    runs = sum(m.runs for m in faulty)
    exposure = sum(m.fault_free_samples * m.Ts for m in ms)
    if not runs or not exposure > 0:
        return None
    episodes = np.sum([m.operating["episodes"] for m in ms], axis=0)
    within = np.sum([m.operating["detected_within"] for m in faulty], axis=0)
    with np.errstate(divide="ignore"):
        mtbfa = np.where(episodes > 0, exposure / np.maximum(episodes, 1), np.inf)
    return {"scales": list(ms[0].operating["scales"]), "mtbfa_s": mtbfa, "exposure_s": exposure, "pd": within / runs,
            "runs": runs, "delay_s": float(ms[0].operating["delay_s"])}


def _operating_figure(ctx: ReportContext) -> str:
    """Each design's probability of detection within the stated delay against its mean time between false alarms,
    every threshold scaled by one factor (:func:`operating_curve`), its own thresholds marked: one panel per report
    variant with curves."""
    from fdisyn.reporting.kit import duration

    problem = ctx.problem
    panels: list[tuple[Any, list[tuple[Any, str, Any]]]] = []
    missing: list[tuple[Any, str, Any]] = []
    for v in ctx.variants:
        got: list[tuple[Any, str, Any]] = []
        for d, per in v.evaluation.metrics.items():
            c = operating_curve(per)
            (got if c is not None else missing).append((v, d, c))
        if got:
            panels.append((v, got))
    if not panels:
        why = (" (a fault-free Monte Carlo, no stated delay, or a run with a skipped non-finite sample, whose held "
               "counters the statistics do not show)")
        return f'<p class="small">No operating characteristic: no design has one{why}.</p>' if missing else ""
    several = len(ctx.variants) > 1
    ncols = min(OPERATING_COLUMNS, len(panels))
    nrows = -(-len(panels) // ncols)
    fig, axes = subplots(nrows, ncols, figsize=(4.4 * ncols + 3.0, 3.0 * nrows + 0.9), squeeze=False, sharex=True, sharey=True)
    colors: dict[str, Any] = {}
    handles: dict[str, Any] = {}
    rows = []
    first = panels[0][1][0][2]
    for ax, (v, got) in zip(axes.flat, panels):
        drawn: list[tuple[np.ndarray, np.ndarray]] = []
        for _, d, c in got:
            name = label(problem, d)
            one = c["scales"].index(1.0)
            seen = np.isfinite(c["mtbfa_s"])
            x, pd = c["mtbfa_s"], c["pd"]
            kw = {} if name not in colors else {"color": colors[name]}
            # a curve equal to one drawn before in the panel is dashed over it, so both show
            twin = any(np.array_equal(pd, q) and np.array_equal(x, y) for q, y in drawn)
            drawn.append((pd, x))
            (line,) = ax.plot(x[seen], pd[seen], "--" if twin else "-", lw=1.2, **kw)
            colors[name] = line.get_color()
            handles.setdefault(name, line)
            if not seen.all():  # the first scale without a false alarm: its time is beyond the time watched
                k = int(np.argmin(seen))
                if k > 0:
                    ax.plot([x[k - 1], c["exposure_s"]], [pd[k - 1], pd[k]], ":", lw=1.0, color=colors[name])
                ax.plot([c["exposure_s"]], [pd[k]], "o", ms=4, mfc="white", color=colors[name])
            ax.plot([c["exposure_s"] if not seen[one] else x[one]], [pd[one]], "*", ms=12, color=colors[name], mec="k", mew=0.6)
            mt = x[one]
            rows.append([name, *([v.label] if several else []), c["runs"], pd[one],
                         duration(mt) if np.isfinite(mt) else f"none in {duration(c['exposure_s'])}", float(pd[0]), float(pd[-1])])
        exposure = max(c["exposure_s"] for _, _, c in got)
        ax.axvline(exposure, color="0.5", ls="-.", lw=0.9)
        ax.set_xscale("log")
        ax.set_ylim(-0.03, 1.03)
        ax.grid(alpha=0.3)
        if several:
            ax.set_title("main designs" if v.label == "default" else str(v.label), loc="left", fontsize=MIN_FONT_PT)
    for ax in axes.flat[len(panels):]:
        ax.set_visible(False)
    lo, hi = axes[0, 0].get_xlim()
    ticks = [t for t in OPERATING_TICKS if lo <= t <= hi]
    if len(ticks) > 4:  # at most four labels a panel, far enough apart that they never meet: 1 s, 1 min, 1 h, …
        kept = [ticks[0]]
        for t in ticks[1:]:
            if t >= 30.0 * kept[-1]:
                kept.append(t)
        ticks = kept
    axes[0, 0].set_xticks(ticks, [duration(t) for t in ticks])
    axes[0, 0].minorticks_off()
    for ax in axes.flat[len(panels) - ncols : len(panels)]:
        ax.xaxis.set_tick_params(labelbottom=True)
    fig.set_layout_engine("constrained")
    fig.supxlabel("mean time between false alarms (log scale)", fontsize=MIN_FONT_PT + 1)
    fig.supylabel(f"P(detected within {duration(first['delay_s'])} of the onset)", fontsize=MIN_FONT_PT + 1)
    # above the panels: the designs' names are long, and a legend beside them would squeeze the panels
    fig.legend(list(handles.values()), list(handles), loc="outside upper center", fontsize=MIN_FONT_PT, ncol=1, frameon=False)
    groups = []
    for v in ctx.variants:
        lost = [d for w, d, _ in missing if w is v]
        if lost and len(lost) == len(v.evaluation.metrics):
            groups.append(f"the {'main designs' if v.label == 'default' else str(v.label)} variant" if several else "any design")
        elif lost:
            groups.append(", ".join(label(problem, d) for d in lost) + (f" ({v.label})" if several else ""))
    absent = (
        f" No curve for {'; '.join(groups)}: its Monte Carlo does not give its decisions at other thresholds (a run "
        "with a skipped non-finite sample holds counters its statistics do not show, or no delay is stated)."
        if groups else ""
    )
    counts = sorted({len(c["scales"]) for _, got in panels for _, _, c in got}, reverse=True)
    rerun = any(len(c["scales"]) != len(OPERATING_SCALES) for _, got in panels for _, _, c in got)
    from_statistics = any(len(c["scales"]) == len(OPERATING_SCALES) for _, got in panels for _, _, c in got)
    how = []
    if from_statistics:
        how.append(
            "Exact, from the Monte Carlo's own runs, not a second simulation: each statistic's alarm rule (a "
            "persistence count of J above its threshold, a Beard filter's window RMS residual included, or a GLR's alarm held "
            "until J falls below half of it) applied to the statistic's J at every factor gives the step's decisions at "
            "those thresholds, J being the same at every threshold; a CUSUM, whose sums are clamped at twice its threshold, "
            "is run again from the runs' residuals at every factor; at the design's own thresholds they are checked equal "
            "to the step's own alarms."
        )
    if rerun:
        how.append(
            "A NAFDF restarts its learning and its nominal filter after every alarm, so each later decision depends on "
            "the threshold and one run does not give the others: its curve is measured on copies of the diagnoser whose "
            "fast-detection thresholds (the WSSR's table, the CUSUM's or the GLR's) are scaled, each copy's generated C "
            "run on the same simulated runs as the design (common random numbers), its other tests (dismissal, "
            "convergence, classifier) unchanged; the star is the design's own runs. Its alarm holds until the "
            "episode is dismissed or the filter re-parameterised, so at a low factor false alarms merge into longer "
            "episodes: fewer are counted and the curve can turn back."
        )
    factors = f"{counts[0]} factors" + (f"; {counts[-1]} for a diagnoser run again per factor" if len(counts) > 1 else "")
    return ctx.figure(
        "operating_characteristic",
        fig,
        f"Operating characteristic: the probability that a fault is detected within D = {duration(first['delay_s'])} of "
        "its onset (the runs of every faulty scenario of the Monte Carlo, pooled) against the mean time between false "
        "alarms (every scenario's fault-free time over its false-alarm episodes; log scale), as the alarm thresholds of a "
        f"design are scaled by one factor from {fmt(first['scales'][0])} to {fmt(first['scales'][-1])} "
        f"({factors}). Star: the design's own thresholds. Grey, dash-dotted: the fault-free time "
        "watched; a hollow point on it: the smallest factor without a false alarm, whose time is only known to be longer "
        "(dotted to it). A dashed curve lies on an earlier design's equal one. " + " ".join(how)
        + absent,
    ) + folded(
        table(["design", *(["variant"] if several else []), "faulty runs", "P(detected within D), own thresholds",
               defined("mean time between false alarms, own thresholds", "mean time between false alarms"),
               f"P(detected within D), thresholds × {fmt(first['scales'][0])}", f"… × {fmt(first['scales'][-1])}"],
              rows, left=2 if several else 1)
    )


def _discrete_model(problem: Problem, variant: Any, gf: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, np.ndarray]] | None:
    """``(A, [E; Dd], C, fault directions)`` of the design model in discrete time: each fault of the gain file that is
    a component fault (a column of ``Fx`` into the state, of ``Df`` into the outputs) or a single sensor (into the
    output); the unknown inputs' entry stacked over their feed-through to the outputs."""
    if problem.model is None:
        return None
    model = problem.model(**dict(variant.options))
    if hasattr(model, "A_D"):  # a sampled-data plant: exact sampling of the disturbance, the fault held
        A, E, C, Fx = model.A_D, model.E_J, model.C, model.Fx_D
        Dd, Df = np.zeros((C.shape[0], E.shape[1])), np.zeros((C.shape[0], Fx.shape[1]))
        comp = list(gf.faults) if Fx.shape[1] == len(gf.faults) else []
        outputs: list[str] = list(gf.outputs)
    else:
        plant = model if model.is_discrete else model.discretise(gf.Ts)
        A, E, C, Fx, Dd, Df = plant.A, plant.E, plant.C, plant.Fx, plant.Dd, plant.Df
        comp, outputs = list(plant.component_faults), list(plant.outputs)
    if C.shape[0] != len(gf.outputs):
        return None
    dirs: dict[str, np.ndarray] = {}
    # each fault of each class: a class of faults no generator tells apart ("y1|f1") shows its members one by one
    for f in dict.fromkeys(m for cls in gf.faults for m in cls.split("|")):
        if f in comp:
            dirs[f] = np.concatenate([Fx[:, comp.index(f)], Df[:, comp.index(f)]])
        elif f in outputs:
            dirs[f] = np.concatenate([np.zeros(A.shape[0]), np.eye(C.shape[0])[outputs.index(f)]])
    return A, np.vstack([E, Dd]), C, dirs


def _responses(A: np.ndarray, E: np.ndarray, C: np.ndarray, dirs: Mapping[str, np.ndarray], gen: Any, w: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """σ̄(G_rd(e^{jω})) and |G_rf(e^{jω})| per fault of one generator driven by the plant (state and sensor inputs)."""
    n, ns = A.shape[0], gen.Ar.shape[0]
    Acl = np.block([[A, np.zeros((n, ns))], [gen.By @ C, gen.Ar]])
    Ccl = np.hstack([gen.Dy @ C, gen.Cr])
    Bd = np.vstack([E[:n], gen.By @ E[n:]])
    Dd = gen.Dy @ E[n:]
    rd = np.zeros(w.size)
    rf = {f: np.zeros(w.size) for f in dirs}
    for i, z in enumerate(np.exp(1j * w)):
        M = z * np.eye(n + ns) - Acl
        rd[i] = np.linalg.norm(Ccl @ np.linalg.solve(M, Bd) + Dd, 2) if E.shape[1] else 0.0
        for f, v in dirs.items():
            bx, by = v[:n], v[n:]
            B = np.concatenate([bx, gen.By @ by])
            rf[f][i] = float(np.linalg.norm(Ccl @ np.linalg.solve(M, B) + gen.Dy @ by))
    return rd, rf


def _frequency_figures(ctx: ReportContext) -> str:
    """Per design, each generator's |G_rf| per fault against σ̄ G_rd: one panel per generator, a fault in the same
    colour on every panel, one legend (up to four panels a row for a large bank)."""
    from matplotlib import colormaps
    from matplotlib.lines import Line2D

    v, problem, out = ctx.variants[0], ctx.problem, []
    for k, (d, b) in enumerate(v.built.items()):
        gf = b.gain_file
        if not gf.generators:  # the responses of a bank of linear generators
            continue
        got = _discrete_model(problem, v, gf)
        if got is None:
            continue
        A, E, C, dirs = got
        w = np.logspace(-3, 0, 300) * np.pi
        gens = list(gf.generators)
        cols = min(2 if len(gens) <= 4 else 4, len(gens))
        rows = -(-len(gens) // cols)
        palette = colormaps["tab10" if len(dirs) <= 10 else "tab20"]
        colour = {f: palette(i % palette.N) for i, f in enumerate(dirs)}
        seen: set[str] = set()
        fig, axes = subplots(rows, cols, figsize=(4.6 * cols, 2.6 * rows + 0.4) if cols <= 2 else (2.6 * cols, 1.8 * rows + 0.4),
                             squeeze=False)
        for gen, ax in zip(gens, axes.ravel(), strict=False):
            rd, rf = _responses(A, E, C, dirs, gen, w)
            om = w / gf.Ts
            if E.shape[1]:
                ax.loglog(om, np.maximum(rd, 1e-12), "k", lw=1.2)
            for f, r in rf.items():
                if np.max(r) > 1e-9:
                    ax.loglog(om, np.maximum(r, 1e-12), lw=1.0, color=colour[f])
                    seen.add(f)
            ax.set_title(textwrap.fill(label(problem, gen.name), 34 if cols <= 2 else 22), fontsize=MIN_FONT_PT)
            lo, hi = ax.get_ylim()
            if hi < 10 * lo:  # under a decade: a linear axis reads better than log ticks
                ax.set_yscale("linear")
            ax.grid(alpha=0.3, which="both")
        for ax in axes.ravel()[max(len(gens) - cols, 0) : len(gens)]:  # the lowest panel of each column
            ax.set_xlabel("ω (rad/s)")
        handles = ([Line2D([], [], color="k", lw=1.2)] if E.shape[1] else []) + [Line2D([], [], color=colour[f], lw=1.0) for f in dirs if f in seen]
        texts = (["σ̄ G_rd (disturbance)"] if E.shape[1] else []) + [f"|G_rf| {label(problem, f)}" for f in dirs if f in seen]
        for ax in axes.ravel()[len(gens):]:
            ax.set_visible(False)
        figure_legend(fig, handles, texts)
        body = ctx.figure(
            f"frequency_{d}",
            fig,
            f"{label(problem, d)}: the residual's response to each fault it sees (|G_rf(e^(jωTs))|, Euclidean norm over the residual) "
            "against the largest singular value of its response to the disturbance (σ̄ G_rd), per generator, up to the Nyquist "
            "frequency, from the design model and the gain file's generators.",
        )
        out.append(body if k == 0 else folded(body, label(problem, d)))
    return "".join(out)


POLE_LEGEND = 8
"""Generators of a bank whose poles the pole figure tells apart, one colour each; a larger bank's share one."""


def _pole_figure(ctx: ReportContext) -> str:
    v, problem = ctx.variants[0], ctx.problem
    linear = [(d, b.gain_file) for d, b in v.built.items() if b.gain_file.generators]  # banks of linear generators
    if not linear:
        return ""
    fig, axes = subplots(1, len(linear), figsize=(3.4 * len(linear) + 1.6, 3.6), squeeze=False)
    plant_poles = None
    if problem.model is not None:
        got = _discrete_model(problem, v, linear[0][1])
        plant_poles = None if got is None else np.linalg.eigvals(got[0])
    th = np.linspace(0, 2 * np.pi, 400)
    rows = []
    for (d, gf), ax in zip(linear, axes[0], strict=False):
        ax.plot(np.cos(th), np.sin(th), "k", lw=0.8)
        if plant_poles is not None:
            ax.plot(plant_poles.real, plant_poles.imag, "x", color="0.4", ms=6, label="plant")
        for gen in gf.generators:
            ev = np.linalg.eigvals(gen.Ar) if gen.Ar.size else np.zeros(0)
            if len(gf.generators) <= POLE_LEGEND:
                ax.plot(ev.real, ev.imag, "o", ms=4, fillstyle="none", label=label(problem, gen.name) if len(gf.generators) > 1 else "generator")
            else:  # a large bank: its generators in one colour (their spectral radii in the table)
                ax.plot(ev.real, ev.imag, "o", ms=4, fillstyle="none", color="tab:blue", label="generators" if gen is gf.generators[0] else None)
            rows.append([label(problem, d), label(problem, gen.name), gen.Ar.shape[0], float(np.max(np.abs(ev))) if ev.size else None])
        ax.set_aspect("equal")
        ax.set_title(textwrap.fill(label(problem, d), 28), fontsize=MIN_FONT_PT)
        ax.set_xlabel("Re z")
        ax.grid(alpha=0.3)
    for ax in axes[0]:
        if ax.get_legend_handles_labels()[0]:
            ax.legend()
    axes[0, 0].set_ylabel("Im z")
    fig.tight_layout()
    return ctx.figure(
        "generator_poles",
        fig,
        "The generators' poles (eigenvalues of Ar) against the unit circle"
        + (", with the design model's poles (×)." if plant_poles is not None else "."),
    ) + folded(table(["design", "generator", "order", "spectral radius of Ar"], rows, left=2))


def standard_figures(ctx: ReportContext) -> list[tuple[str, str]]:
    """The figures every page has where its data allow: statistics against their law, detection against the fault's
    size, the residuals' frequency responses, the generators' poles."""
    return [
        ("Fault-free statistics against their law", _law_figures(ctx)),
        ("Detection against fault size", _sweep_figure(ctx)),
        ("Delay against the whitened shift", _shift_figure(ctx)),
        ("Operating characteristic", _operating_figure(ctx)),
        ("Residual frequency responses", _frequency_figures(ctx)),
        ("Generator poles", _pole_figure(ctx)),
    ]
