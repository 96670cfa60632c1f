"""Plots for notebooks and for the report: each function takes a run or a Monte Carlo result and returns a Matplotlib
``Figure``.

- :func:`plot_trace`: one run: the statistics over their thresholds with the alarm instants, the isolated fault, the
  fault-active window (and, on request, measured signals);
- :func:`plot_laws`: one design's fault-free statistics against their laws, from a Monte Carlo;
- :func:`plot_detection`: detection (and isolation) against the fault's size, from the report's fault-size sweep.

The figures are made without ``pyplot`` (:func:`~fdisyn.reporting.kit.subplots`): they work headless, leave the
user's backend alone, and show in a notebook as the cell's value (``display(fig)``) or are saved with
``fig.savefig(path)``. The report's pages draw the same figures with these functions
(:mod:`fdisyn.reporting.figures`).

Names a reader sees (statistics, faults, signals, designs, scenarios) are looked up in ``labels``, a mapping of
internal name to a readable ``"name (unit)"`` (what :attr:`fdisyn.simulation.problem.Problem.labels` holds); a
name not in it is shown as it is.

Examples
--------
>>> gf = fdisyn.design(plant, method="kalman_uio")  # doctest: +SKIP
>>> fig = plot_trace(gf, trace, labels={"h2": "level of tank 2 (m)"}, signals=["h2"])  # doctest: +SKIP
>>> fig.savefig("run.png")  # doctest: +SKIP
"""

from __future__ import annotations

import textwrap
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from fdisyn.detectors.table import DETECTORS
from fdisyn.evaluation.metrics import DETECTION_GOAL, HISTOGRAM_EDGES
from fdisyn.reporting.kit import MIN_FONT_PT, figure_legend, fmt, shade, subplots, timeline
from fdisyn.runtime.errors import ArgumentError
from fdisyn.runtime.gainfile import GainFile
from fdisyn.runtime.monitor import Monitor
from fdisyn.runtime.names import shown as shown_value
from fdisyn.runtime.reference import RunResult
from fdisyn.runtime.trace import Trace
from fdisyn.synthesis.kinds import reference_run
from matplotlib.figure import Figure

__all__ = ["plot_trace", "plot_laws", "plot_detection", "LAW_PANELS"]

Labels = Mapping[str, str] | None

LAW_PANELS = 8
"""Statistics :func:`plot_laws` draws at most (the first ones with fault-free samples), one panel each."""

ESTIMATE_PREFIX = "theta_hat_"
"""A statistic named ``theta_hat_<θ>`` is a parameter estimate; :func:`plot_trace` draws it against the trace's
extra column ``true_<θ>`` when the trace has one."""


def _label(labels: Labels, name: str) -> str:
    """What a reader sees for an internal name: ``labels[name]``, else the name (as :func:`~fdisyn.reporting.kit.label`)."""
    return str((labels or {}).get(name, name))


def _fault_label(labels: Labels, fault: str) -> str:
    """A fault class as a reader sees it: its label, else each member's (a class no generator splits is ``"a|b"``)."""
    got = labels or {}
    if fault in got:
        return str(got[fault])
    return " | ".join(str(got.get(m, m)) for m in fault.split("|"))


def _labels(labels: Any) -> Labels:
    if labels is None or isinstance(labels, Mapping):
        return labels
    raise ArgumentError(f"labels = {shown_value(labels)}: expected a mapping of signal name to its readable name, "
                        "e.g. {'h2': 'level of tank 2 (m)'} (Problem.labels), or None")


_BESIDE: dict[str, Any] = {"loc": "upper left", "bbox_to_anchor": (1.01, 1.0), "borderaxespad": 0.0, "fontsize": MIN_FONT_PT,
                           "frameon": False}
"""A legend beside its panel, never on the data (where the report's pages put every legend)."""


def _seconds_axis(ax: Any) -> None:
    """The time axis as an operator reads it: seconds from the trace's times, plain numbers (no offset, no ×10ⁿ)."""
    from matplotlib.ticker import ScalarFormatter

    form = ScalarFormatter(useOffset=False)
    form.set_scientific(False)
    ax.xaxis.set_major_formatter(form)
    ax.set_xlabel("time (s)")


# ----------------------------------------------------------------------------------------------------- one run


def _run(gf: GainFile, trace: Trace, library: str | Path | None) -> RunResult:
    """``trace`` through ``gf`` from its initial state: the compiled ``library`` when one is given, else the
    independent NumPy reference of its kind (:func:`fdisyn.synthesis.kinds.reference_run`)."""
    U, Y = np.asarray(trace.U, dtype=float), np.asarray(trace.Y, dtype=float)
    if library is not None:
        return Monitor(gf, library=library, backend="compiled").run(U, Y)
    res = reference_run(gf, U, Y)
    if res is None:
        raise ArgumentError(
            f"gain file {gf.name!r} is of kind {gf.kind!r}, which has no NumPy reference: pass result= (what "
            "Monitor.run or fdisyn.load(...).run returns on the trace) or library= (the library fdisyn codegen built from it)"
        )
    return res


def _checked_run(gf: Any, trace: Any, result: Any) -> None:
    if not isinstance(gf, GainFile):
        raise ArgumentError(f"gf: expected a GainFile (fdisyn.design or fdisyn.load gives one), got {type(gf).__name__}")
    if not isinstance(trace, Trace):
        raise ArgumentError(f"trace: expected a fdisyn.runtime.trace.Trace (Batch.trace(run), read_trace), got {type(trace).__name__}")
    for what, got, want in (("outputs", trace.outputs, gf.outputs), ("inputs", trace.inputs, gf.inputs)):
        if tuple(got) != tuple(want):
            raise ArgumentError(f"trace {what} {list(got)} do not match gain file {gf.name!r}'s {what} {list(want)}; "
                                "expected the same names in the same order")
    if result is None:
        return
    if not isinstance(result, RunResult):
        raise ArgumentError(f"result: expected a RunResult (Monitor.run gives one) or None, got {type(result).__name__}")
    n, nj = len(trace.t), gf.step.nj
    J, alarm, iso = np.asarray(result.J), np.asarray(result.alarm), np.asarray(result.isolated)
    if J.shape != (n, nj) or alarm.shape[:1] != (n,) or iso.shape[:1] != (n,):
        raise ArgumentError(f"result holds J {J.shape}, alarm {alarm.shape}, isolated {iso.shape}; expected the trace's {n} "
                            f"samples and gain file {gf.name!r}'s {nj} statistics: J ({n}, {nj}), alarm ({n},), isolated ({n},)")


def plot_trace(
    gf: GainFile, trace: Trace, result: RunResult | None = None, *, labels: Mapping[str, str] | None = None,
    signals: Sequence[str] = (), library: str | Path | None = None,
) -> Figure:
    """One run of a diagnoser: its statistics over their thresholds, its alarms and the fault it isolates, over time.

    Panels, from the top: each of ``signals`` (a measured input or output of the trace, on its own axis); every
    statistic with a fixed threshold divided by it (log scale; an alarm is above the dashed line at 1), with a tick
    at the top of the panel at every sample where the diagnoser's alarm holds; the isolated fault (``none``: no
    alarm, or detected but not isolated); and, for a parameter estimator (statistics ``theta_hat_<θ>``), each
    estimate against the trace's ``true_<θ>`` column. Where the trace carries ``fault_active`` (as
    :meth:`fdisyn.simulation.problem.Batch.trace` writes it) its window is shaded. Time is the trace's ``t``, in
    seconds.

    Parameters
    ----------
    gf : GainFile
        The diagnoser.
    trace : Trace
        The run: ``t``, inputs and outputs named as in ``gf`` (:meth:`~fdisyn.simulation.problem.Batch.trace`,
        :func:`~fdisyn.runtime.trace.read_trace`).
    result : RunResult, optional
        The diagnoser's outputs over ``trace`` (:meth:`fdisyn.runtime.monitor.Monitor.run`, from its initial
        state). ``None``: ``trace`` is run here from the initial state, through ``library`` when one is given,
        else through the independent NumPy reference of the gain file's kind (the one its generated C is checked
        against; :func:`fdisyn.synthesis.kinds.reference_run`); a kind without one then needs ``result`` or
        ``library``.
    labels : Mapping of str to str, optional
        Readable names with units by internal name (:attr:`~fdisyn.simulation.problem.Problem.labels`):
        statistics, faults, signals.
    signals : Sequence of str
        Inputs or outputs of the trace to draw above the statistics, one panel each.
    library : str or Path, optional
        The compiled library built from ``gf`` (``fdisyn codegen``), run when ``result`` is None.

    Returns
    -------
    matplotlib.figure.Figure
        The figure (not shown, not saved).

    Raises
    ------
    ArgumentError
        ``gf`` is not a gain file, ``trace`` not a trace, its inputs or outputs are not ``gf``'s, ``result`` does
        not have the trace's samples and ``gf``'s statistics, a name of ``signals`` is not in the trace, or
        ``result`` is None for a gain file whose kind has no NumPy reference and no ``library``.
    BuildError
        ``library`` was not built from ``gf`` (:class:`~fdisyn.runtime.monitor.Monitor` checks it before loading).

    Examples
    --------
    >>> fig = plot_trace(gf, batch.trace(0), labels=problem.labels, signals=["h2"])  # doctest: +SKIP
    """
    labels = _labels(labels)
    _checked_run(gf, trace, result)
    if isinstance(signals, str):
        signals = [signals]
    known = [*trace.inputs, *trace.outputs]
    for s in signals:
        if s not in known:
            raise ArgumentError(f"signals: {s!r} is not a signal of the trace; expected some of {known}")
    res = _run(gf, trace, library) if result is None else result
    t = np.asarray(trace.t, dtype=float)
    active = trace.extra.get("fault_active")
    active = None if active is None else np.asarray(active) > 0.5
    names = list(gf.step.statistic_names)
    thr = np.asarray(gf.thresholds, dtype=float)
    J = np.asarray(res.J, dtype=float)
    fixed = [j for j in range(len(names)) if np.isfinite(thr[j]) and thr[j] > 0]
    est = [(j, nm[len(ESTIMATE_PREFIX):]) for j, nm in enumerate(names) if nm.startswith(ESTIMATE_PREFIX)]
    est = [(j, q) for j, q in est if f"true_{q}" in trace.extra]
    rows = len(signals) + 2 + bool(est)
    heights = [1.4] * len(signals) + [2.2] * (rows - len(signals))
    fig, axes = subplots(rows, 1, figsize=(9, sum(heights) + 0.6), sharex=True, squeeze=False,
                         gridspec_kw={"height_ratios": heights})
    axes = axes[:, 0]
    for ax, s in zip(axes, signals, strict=False):
        k = list(trace.inputs).index(s) if s in trace.inputs else None
        values = trace.U[:, k] if k is not None else trace.Y[:, list(trace.outputs).index(s)]
        ax.plot(t, values, lw=0.8, color="0.25")
        ax.set_ylabel(_label(labels, s))
        ax.grid(alpha=0.3)
        if active is not None:
            shade(ax, t, active)
    ax_j, ax_i = axes[len(signals)], axes[len(signals) + 1]
    timeline(ax_j, t, J[:, fixed] / thr[fixed], [_label(labels, names[j]) for j in fixed], threshold=1.0)
    ax_j.set_ylabel("J / threshold")
    alarm = np.asarray(res.alarm).reshape(len(t), -1).any(axis=1)  # one flag per sample (any statistic's)
    # the alarm instants: a tick in a strip above the statistics at each sample whose alarm holds (x in data, y in
    # the axes' height)
    low, high = ax_j.get_ylim()
    ax_j.set_ylim(low, high * (high / low) ** 0.15)
    ax_j.plot(t[alarm], np.full(int(alarm.sum()), 0.94), "|", ms=7, mew=1.0, color="tab:red", ls="none",
              transform=ax_j.get_xaxis_transform(), label="alarm")
    if active is not None:
        shade(ax_j, t, active)
    ax_j.legend(**_BESIDE)
    ax_i.step(t, np.asarray(res.isolated), where="post", lw=0.9)
    ax_i.set_yticks(range(-1, len(gf.faults)), ["none", *(_fault_label(labels, f) for f in gf.faults)])
    ax_i.set_ylabel("isolated")
    ax_i.grid(alpha=0.3)
    if active is not None:
        shade(ax_i, t, active)
    if est:
        ax_e = axes[-1]
        for j, q in est:
            ax_e.plot(t, J[:, j], lw=0.8, label=f"estimate of {_label(labels, q)}")
            ax_e.plot(t, np.asarray(trace.extra[f"true_{q}"]), "k--", lw=0.8, label=f"true {_label(labels, q)}" if len(est) > 1 else "truth")
        ax_e.set_ylabel("parameters")
        ax_e.legend(**_BESIDE)
        ax_e.grid(alpha=0.3)
    for ax in axes[:-1]:
        ax.set_xlabel("")
    _seconds_axis(axes[-1])
    fig.align_ylabels(list(axes))
    fig.tight_layout()  # the legends beside the axes and the labels inside the figure: fig.savefig(path) keeps them
    return fig


# ------------------------------------------------------------------------------------------ fault-free laws


def _fault_free_counts(metrics: Mapping[str, Any], nj: int) -> list[np.ndarray]:
    """Per statistic, its fault-free samples of every run and scenario (``metrics``: one design's scenario metrics by
    scenario) counted in the bins :data:`~fdisyn.evaluation.metrics.HISTOGRAM_EDGES` ``× threshold`` (empty: the
    statistic has no threshold)."""
    total: list[np.ndarray] = [np.zeros(0, dtype=np.int64)] * nj
    for m in metrics.values():
        for j, c in enumerate(m.fault_free_histogram[:nj]):
            c = np.asarray(c, dtype=np.int64)
            if c.size:
                total[j] = c if total[j].size == 0 else total[j] + c
    return total


def _law_source(source: Any, design: Any, gain_file: Any) -> tuple[Mapping[str, Any], GainFile]:
    """One design's scenario metrics and its gain file, from a report variant or an ``Evaluation``."""
    evaluation = getattr(source, "evaluation", source)
    metrics = getattr(evaluation, "metrics", None)
    if not isinstance(metrics, Mapping):
        raise ArgumentError(f"plot_laws takes a Monte Carlo result (an Evaluation, or a report variant holding one), got {type(source).__name__}")
    if not isinstance(design, str) or design not in metrics:
        raise ArgumentError(f"design = {shown_value(design)}: expected the name of a design of this Monte Carlo, one of {sorted(metrics)}")
    if gain_file is None:
        built = getattr(source, "built", None)
        if not isinstance(built, Mapping) or design not in built:
            raise ArgumentError(f"plot_laws({type(source).__name__}, {design!r}) needs the design's gain file: "
                                "pass gain_file= (an Evaluation holds the metrics, not the gain files)")
        gain_file = built[design].gain_file
    if not isinstance(gain_file, GainFile):
        raise ArgumentError(f"gain_file: expected the design's GainFile, got {type(gain_file).__name__}")
    return metrics[design], gain_file


def _law_panels(metrics: Mapping[str, Any], gf: GainFile, panels: int) -> tuple[list[np.ndarray], list[int]]:
    """The fault-free counts of every statistic and the ones drawn: the first ``panels`` with samples."""
    counts = _fault_free_counts(metrics, gf.step.nj)
    return counts, [j for j, c in enumerate(counts) if c.size and c.sum() > 0][:panels]


def plot_laws(
    source: Any, design: str, *, gain_file: GainFile | None = None, labels: Mapping[str, str] | None = None,
    panels: int = LAW_PANELS,
) -> Figure:
    """One design's fault-free statistics against their laws, from a Monte Carlo.

    Per statistic with a threshold (the first ``panels`` of them), its fault-free samples of every run and scenario
    binned from 0 to 3 thresholds in steps of a twentieth: for a detector with a closed-form fault-free law
    (:attr:`fdisyn.detectors.table.Detector.null_law`, e.g. χ² with the statistic's degrees of freedom) the
    histogram's density against that density (black); for the others (WSSR, CUSUM, GLR, …) the empirical tail
    P(J ≥ x) against the design's P_f (red, dotted). Dashed: the threshold.

    Parameters
    ----------
    source : Evaluation or report variant
        The Monte Carlo: a :class:`~fdisyn.evaluation.evaluate.Evaluation`, or a report variant holding one and its
        built designs (``.evaluation``, ``.built``).
    design : str
        The design's name in the Monte Carlo.
    gain_file : GainFile, optional
        The design's gain file; needed when ``source`` is an ``Evaluation`` (it holds no gain files).
    labels : Mapping of str to str, optional
        Readable names by internal name: the statistics (panel titles).
    panels : int
        The most statistics drawn.

    Returns
    -------
    matplotlib.figure.Figure
        One panel per statistic, up to four a row.

    Raises
    ------
    ArgumentError
        ``source`` holds no Monte Carlo, ``design`` is not one of its designs, its gain file is missing, or no
        statistic has a fault-free sample with a threshold (a Monte Carlo without fault-free time).

    Examples
    --------
    >>> ev = evaluate(problem, built, runs=20)  # doctest: +SKIP
    >>> fig = plot_laws(ev, "kalman", gain_file=built["kalman"].gain_file)  # doctest: +SKIP
    """
    from matplotlib.ticker import MaxNLocator

    labels = _labels(labels)
    if isinstance(panels, bool) or not isinstance(panels, int) or panels < 1:
        raise ArgumentError(f"panels = {shown_value(panels)}: expected a whole number ≥ 1")
    metrics, gf = _law_source(source, design, gain_file)
    names = list(gf.step.statistic_names)
    counts, drawn = _law_panels(metrics, gf, panels)
    if not drawn:
        raise ArgumentError(f"design {design!r} has no fault-free sample of a statistic with a threshold in this Monte Carlo; "
                            "expected a Monte Carlo with fault-free time (a fault-free scenario, or time before a fault's onset)")
    cols = min(4, len(drawn))
    rows = -(-len(drawn) // cols)
    fig, axes = subplots(rows, cols, figsize=(2.6 * cols, 2.9 * rows + 0.4), squeeze=False)
    thr = np.asarray(gf.thresholds, dtype=float)
    for j, ax in zip(drawn, axes.ravel(), strict=False):
        c, h = counts[j], float(thr[j])
        n = int(c.sum())
        edges = HISTOGRAM_EDGES * h
        ev = gf.evaluators[j] if j < len(gf.evaluators) else None
        null = None if ev is None or DETECTORS.get(ev.kind) is None else DETECTORS[ev.kind].null_law
        if null is not None:  # a closed-form fault-free law: the histogram's density against it
            density, law = null(ev)
            dens = c[1:-1] / (n * np.diff(edges))
            ax.stairs(np.where(dens > 0, dens, np.nan), edges, fill=True, color="tab:blue", alpha=0.6)
            grid = np.linspace(edges[-1] / 400, edges[-1], 400)
            ax.plot(grid, density(grid), "k", lw=1.0)
            ax.set_ylabel("density")
            ax.set_ylim(bottom=0.3 / (n * (edges[1] - edges[0])))  # below one sample per bin the law is not seen
        else:
            # P(J ≥ edge): the samples in the bins from that edge up, over all
            tail = np.cumsum(c[::-1])[::-1][1:] / n
            ax.step(edges, np.where(tail > 0, tail, np.nan), where="post", color="tab:blue")
            ax.set_ylabel("P(J ≥ x)")
            ax.set_ylim(bottom=0.3 / n)
            if ev is not None and ev.P_f is not None and ev.P_f > 0:
                ax.axhline(ev.P_f, color="tab:red", ls=":", lw=1.0)
            law = "empirical tail"
        ax.set_yscale("log")
        ax.axvline(h, color="k", ls="--", lw=0.9)
        # the statistic's name above its panel (wrapped), the axis only "J": long names side by side overlap
        ax.set_title(textwrap.fill(_label(labels, names[j]), 30) + f"\n{law}", fontsize=MIN_FONT_PT)
        ax.set_xlabel("J")
        ax.xaxis.set_major_locator(MaxNLocator(4))  # a narrow panel: a few ticks that do not run into each other
        ax.ticklabel_format(axis="x", style="sci", scilimits=(-2, 3), useMathText=True)  # 2·10⁻⁴, not 0.0002
        ax.grid(alpha=0.3)
    for ax in axes.ravel()[len(drawn):]:
        ax.set_visible(False)
    fig.tight_layout()
    return fig


# ------------------------------------------------------------------------------------------ fault-size sweep


def _sweep_points(sweep: Any, evaluation: Any = None) -> tuple[list[str], dict[str, list[float]], Callable[[str, str, float], Any]]:
    """The sweep's designs, each faulty scenario's sizes (× the scenario's; 1 only with ``evaluation``, the
    scenario itself) and the metrics of a design in a scenario at a size."""
    for a in ("scenarios", "evaluation", "detection_grid"):
        if not hasattr(sweep, a):
            raise ArgumentError(f"plot_detection takes a fault-size sweep (FaultSizeSweep: .scenarios, .evaluation, "
                                f".detection_grid), got {type(sweep).__name__} without .{a}")
    if not sweep.scenarios:
        raise ArgumentError("the fault-size sweep holds no scenario: expected a problem with a faulty scenario whose fault has a size")
    if evaluation is not None and not isinstance(getattr(evaluation, "metrics", None), Mapping):
        raise ArgumentError(f"evaluation: expected the Monte Carlo of the scenarios themselves (an Evaluation) or None, got {type(evaluation).__name__}")
    main = evaluation.metrics if evaluation is not None else None
    designs = list(main if main is not None else sweep.evaluation.metrics)

    def metric(d: str, base: str, f: float) -> Any:
        return main[d][base] if f == 1.0 and main is not None else sweep.evaluation.metrics[d][sweep.scenarios[base][f]]

    extra = {1.0} if main is not None else set()
    factors = {base: sorted({*extra, *by_factor}) for base, by_factor in sweep.scenarios.items()}
    return designs, factors, metric


def plot_detection(sweep: Any, evaluation: Any = None, *, labels: Mapping[str, str] | None = None) -> Figure:
    """Detection against the fault's size: per design (a row) and faulty scenario (a colour), the mean detection delay,
    the share of runs that detect (solid) and whose most frequent decision names the true fault (dashed, squares),
    and, where the diagnoser has a Lorden bound, the mean delay over the bound (black: 1; red, dotted: the goal).

    A hollow point: more than half the runs missed the fault, and the delay is the mean over the few that did not.

    Parameters
    ----------
    sweep : FaultSizeSweep
        The faulty scenarios with their fault scaled and their Monte Carlo (what ``fdisyn reproduce`` runs for the
        report, ``fault_size_sweep``): ``.scenarios[base][factor]`` names the scaled copy of ``base`` in
        ``.evaluation``, ``.detection_grid`` the sizes labelled on the axis.
    evaluation : Evaluation, optional
        The Monte Carlo of the scenarios themselves: their points at size 1 (without it, the sweep's sizes only).
    labels : Mapping of str to str, optional
        Readable names by internal name: the designs (row titles) and scenarios (legend).

    Returns
    -------
    matplotlib.figure.Figure
        One row per design; the fault's size (× the scenario's, log scale) on the x axis.

    Raises
    ------
    ArgumentError
        ``sweep`` is not a fault-size sweep or holds no scenario, or ``evaluation`` is not a Monte Carlo.

    Examples
    --------
    >>> fig = plot_detection(variant.sweep, variant.evaluation, labels=problem.labels)  # doctest: +SKIP
    """
    from fdisyn.reporting.budget import RATIO_GOAL
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    labels = _labels(labels)
    designs, factors, metric = _sweep_points(sweep, evaluation)
    bounded = any(metric(d, b, f).delay_bound_ratio is not None for d in designs for b, fs in factors.items() for f in fs)
    isolating = any(metric(d, b, f).isolation_accuracy is not None for d in designs for b, fs in factors.items() for f in fs)
    cols = 2 + bounded
    fig, axes = subplots(len(designs), cols, figsize=(4.5 * cols, 2.2 * len(designs) + 0.4), squeeze=False)
    for i, d in enumerate(designs):
        for base, fs in factors.items():
            ms = [metric(d, base, f) for f in fs]
            delays = [np.nan if m.detection_delay_mean_s is None else m.detection_delay_mean_s for m in ms]
            (line,) = axes[i, 0].plot(fs, delays, "o-", lw=1.0, ms=3)
            axes[i, 1].plot(fs, [1.0 - m.missed_detection_rate for m in ms], "o-", lw=1.0, ms=3, label=_label(labels, base))
            ratios = [np.nan if m.delay_bound_ratio is None else m.delay_bound_ratio for m in ms]
            if bounded:
                axes[i, 2].plot(fs, ratios, "o-", lw=1.0, ms=3, color=line.get_color())
            if isolating:
                named = [np.nan if m.isolation_accuracy is None else m.isolation_accuracy for m in ms]
                axes[i, 1].plot(fs, named, "s--", lw=1.0, ms=3, color=line.get_color())
            # a mean delay over the few runs that detected at all flatters: hollow where more than half missed
            lucky = [j for j, m in enumerate(ms) if m.missed_detection_rate > 0.5]
            for col, ys in ((0, delays), *(((2, ratios),) if bounded else ())):
                axes[i, col].plot([fs[j] for j in lucky], [ys[j] for j in lucky], "o", ms=5, mfc="white", color=line.get_color())
        axes[i, 0].set_title(_label(labels, d), loc="left", fontsize=MIN_FONT_PT).set_in_layout(False)  # it spans the row
        axes[i, 0].set_ylabel("mean delay (s)")
        axes[i, 1].set_ylabel("detected" + (" / named" if isolating else "") + " (of runs)")
        axes[i, 1].axhline(DETECTION_GOAL, color="tab:red", ls=":", lw=1.0)
        axes[i, 1].set_ylim(-0.03, 1.03)
        if bounded:
            axes[i, 2].set_ylabel("delay / Lorden bound")
            axes[i, 2].axhline(1.0, color="k", lw=0.8)
            axes[i, 2].axhline(RATIO_GOAL, color="tab:red", ls=":", lw=1.0)
            axes[i, 2].set_yscale("log")
            axes[i, 2].yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))  # 1, 2, 5, 10: a ratio is read, not a decade
            axes[i, 2].yaxis.set_major_formatter(FuncFormatter(lambda x, _: fmt(x)))
            axes[i, 2].yaxis.set_minor_formatter(NullFormatter())
        ticks = sorted({1.0, *sweep.detection_grid})
        for ax in axes[i]:
            ax.set_xscale("log")
            ax.set_xticks(ticks, [fmt(f) for f in ticks])
            ax.minorticks_off()
            ax.grid(alpha=0.3)
    fig.supxlabel("fault size (× the scenario's)", fontsize=MIN_FONT_PT + 1)
    figure_legend(fig, *axes[0, 1].get_legend_handles_labels())
    return fig
