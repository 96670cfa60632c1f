"""The kit a problem's page is written with: numbers and names as every page shows them, HTML tables and folds,
the paper's claims, figures and the context a problem's report hooks get.

Every number on a page goes through :func:`fmt`; every internal name a reader sees (legends, axes, tables) through
:func:`label`. Figures are Matplotlib ``Figure`` objects made by :func:`subplots`, not by ``pyplot``: they belong to
no window, and saving one as PNG (:meth:`ReportContext.figure`) uses Matplotlib's Agg renderer whatever backend is
selected, so importing this module or writing a report never changes the user's backend (and needs no display).
"""

from __future__ import annotations

import html
import math
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from fdisyn.evaluation.metrics import DEFINITIONS
from fdisyn.simulation.problem import Problem
from matplotlib.figure import Figure

__all__ = ["SIGNIFICANT_DIGITS", "fmt", "duration", "false_alarm_time", "false_alarms_pooled", "label", "slug", "defined", "table",
           "folded", "VERDICTS", "Claim", "subplots", "FIGURE_DPI", "FIGURE_WIDTH", "MIN_FONT_PT", "tidy", "figure_legend",
           "ReportContext", "ROUND_OFF_MARGIN", "ROUND_OFF_BOUND", "below_margin", "variant_name", "timeline", "shade"]


SIGNIFICANT_DIGITS = 4
"""Significant digits of every number on a page (:func:`fmt`)."""


_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def fmt(x: Any, digits: int = SIGNIFICANT_DIGITS, *, interval: tuple[Any, Any] | None = None) -> str:
    """A number as every page shows it: ``digits`` significant digits, positional for ``1e-3 ≤ |x| < 1e5``
    (``34480``, ``0.01235``), otherwise ``3.448·10⁵``; trailing zeros dropped; ``—`` for None; whole numbers
    (Python or NumPy ints) exactly below 10⁵. ``interval=(lo, hi)`` appends ``[lo, hi]`` in the same format."""
    if interval is not None:
        return f"{fmt(x, digits)} [{fmt(interval[0], digits)}, {fmt(interval[1], digits)}]"
    if x is None:
        return "—"
    if isinstance(x, (bool, np.bool_)):
        return "yes" if x else "no"
    if isinstance(x, (int, np.integer)) and abs(int(x)) < 10**5:
        return str(int(x)).replace("-", "−")
    v = float(x)
    if math.isnan(v):
        return "NaN"
    if math.isinf(v):
        return "∞" if v > 0 else "−∞"
    if v == 0.0:
        return "0"
    sign = "−" if v < 0 else ""
    mantissa, exp_text = f"{abs(v):.{digits - 1}e}".split("e")
    exponent = int(exp_text)
    if -3 <= exponent < 5:
        text = f"{abs(v):.{max(digits - 1 - exponent, 0)}f}"
        return sign + (text.rstrip("0").rstrip(".") if "." in text else text)
    mantissa = mantissa.rstrip("0").rstrip(".") if "." in mantissa else mantissa
    return f"{sign}{mantissa}·10{str(exponent).translate(_SUPERSCRIPT)}"


_DURATION_UNITS = (("s", 1.0), ("min", 60.0), ("h", 3600.0), ("days", 86400.0), ("years", 365.25 * 86400.0))
"""The units a duration is shown in (:func:`duration`), each from one of itself up."""


def duration(seconds: float | None, digits: int = 3) -> str:
    """A time as an operator reads it, in the largest unit of which it is at least one: ``0.25 s``, ``4.12 s``,
    ``15 min``, ``1 h``, ``1 day``, ``3.5 days``, ``2 years``; numbers by :func:`fmt` with ``digits`` significant
    digits, ``—`` for None, ``∞`` for an infinite time.

    Parameters
    ----------
    seconds : float or None
        The duration (s), at least 0.
    digits : int
        Significant digits of the number.

    Returns
    -------
    str
        The number and its unit.
    """
    if seconds is None:
        return "—"
    v = float(seconds)
    if math.isinf(v):
        return "∞"
    unit, size = next(((u, k) for u, k in reversed(_DURATION_UNITS) if abs(v) >= k), _DURATION_UNITS[0])
    text = fmt(v / size, digits)
    if text == "1" and unit in ("days", "years"):
        unit = unit[:-1]
    return f"{text} {unit}"


def false_alarm_time(episodes: int, exposure_s: float) -> str:
    """The observed mean time between false alarms as an operator reads it: ``one every 4.12 s`` (``exposure_s``
    of fault-free data over ``episodes`` false-alarm episodes), ``none in 17 min of fault-free data`` when none
    was seen (a lower bound, not a time between alarms), ``—`` without fault-free data."""
    if not exposure_s > 0:
        return "—"
    if episodes <= 0:
        return f"none in {duration(exposure_s)} of fault-free data"
    return f"one every {duration(exposure_s / episodes)}"


def false_alarms_pooled(metrics: Iterable[Any]) -> str:
    """The false alarms of a design over every scenario's fault-free samples (scenario metrics with ``Ts``,
    ``fault_free_samples``, ``false_alarm_episodes`` and ``false_alarm_rate``): the time between them
    (:func:`false_alarm_time`) with the rate per sample beside it: ``one every 4.12 s (2.5·10⁻⁴ per sample)``."""
    ms = list(metrics)
    n = sum(m.fault_free_samples for m in ms)
    if not n:
        return "—"
    exposure = sum(m.fault_free_samples * m.Ts for m in ms)
    episodes = sum(m.false_alarm_episodes for m in ms)
    rate = sum(m.false_alarm_rate * m.fault_free_samples for m in ms) / n
    text = false_alarm_time(episodes, exposure)
    return text if episodes == 0 else f"{text} ({fmt(rate)} per sample)"


def label(problem: Problem | None, name: str) -> str:
    """What a reader sees for an internal name: :attr:`Problem.labels` ``[name]``, else the name itself."""
    labels = getattr(problem, "labels", None) or {}
    return str(labels.get(name, name))


def slug(text: str) -> str:
    """An HTML anchor for ``text``: its letters and digits in lower case, the rest written ``-``."""
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-") or "section"


def defined(header: str, term: str) -> str:
    """A column header linked to the definition of ``term`` (a key of
    :data:`fdisyn.evaluation.metrics.DEFINITIONS`) in the page's "Definitions" section."""
    if term not in DEFINITIONS:
        raise KeyError(f"no definition of {term!r}; defined: {sorted(DEFINITIONS)}")
    return f'<a href="#def-{slug(term)}" title="{html.escape(DEFINITIONS[term])}">{html.escape(header)}</a>'


def table(header: Sequence[str], rows: Iterable[Sequence[Any]], *, left: int = 1, groups: Sequence[tuple[str, int]] = ()) -> str:
    """An HTML table; the first ``left`` columns are left-aligned text. Numbers go through :func:`fmt`;
    a string cell or header that starts with ``<`` is HTML (e.g. from :func:`defined`), any other is escaped.

    ``groups``: ``(title, columns)`` pairs heading the last columns in groups (e.g. the designs side by side, each
    over the same figures); the columns before them span both header rows, a rule separates the groups."""

    def cell(c: Any) -> str:
        return c if isinstance(c, str) and c.startswith("<") else html.escape(c if isinstance(c, str) else fmt(c))

    first = len(header) - sum(n for _, n in groups)
    starts = set(np.cumsum([first, *(n for _, n in groups)])[:-1].tolist()) if groups else set()

    def attrs(i: int) -> str:
        cls = " ".join(c for c, on in (("l", i < left), ("g", i in starts)) if on)
        return f' class="{cls}"' if cls else ""

    if groups:
        span = ' rowspan="2"'
        top = "".join(f"<th{attrs(i)}{span}>{cell(c)}</th>" for i, c in enumerate(header[:first]))
        top += "".join(f'<th class="g" colspan="{n}">{cell(t)}</th>' for t, n in groups)
        h = top + "</tr><tr>" + "".join(f"<th{attrs(i)}>{cell(c)}</th>" for i, c in enumerate(header) if i >= first)
    else:
        h = "".join(f"<th{attrs(i)}>{cell(c)}</th>" for i, c in enumerate(header))
    body = []
    for row in rows:
        cells = [f"<td{attrs(i)}>{cell(c)}</td>" for i, c in enumerate(row)]
        body.append("<tr>" + "".join(cells) + "</tr>")
    return f"<table><thead><tr>{h}</tr></thead><tbody>{''.join(body)}</tbody></table>"


def folded(body: str, summary: str = "The numbers") -> str:
    """``body`` folded under ``summary`` (closed): the numbers behind a figure, a long table."""
    return f"<details><summary>{html.escape(summary)}</summary>{body}</details>"


VERDICTS = ("reproduced", "differs")


@dataclass(frozen=True)
class Claim:
    """One of the paper's claims against ours, a row of the verdict each page opens with.

    ``claim``: the paper's statement, cited; ``paper``: its figure or number; ``ours``: our measured figure
    (formatted with :func:`fmt`); ``verdict``: ``"reproduced"`` or ``"differs"``; ``why``: one or two sentences,
    required when it differs.
    """

    claim: str
    paper: str
    ours: str
    verdict: str
    why: str = ""

    def __post_init__(self) -> None:
        if self.verdict not in VERDICTS:
            raise ValueError(f"a claim's verdict is one of {VERDICTS}; got {self.verdict!r} for {self.claim!r}")
        if self.verdict == "differs" and not self.why.strip():
            raise ValueError(f"the claim {self.claim!r} differs from the paper: say why (Claim.why)")


def subplots(nrows: int = 1, ncols: int = 1, *, figsize: tuple[float, float], **kw: Any) -> tuple[Figure, Any]:
    """A figure and its axes, as ``pyplot.subplots`` makes them, without ``pyplot`` (module docstring).

    ``kw`` goes to ``Figure.subplots`` (``sharex``, ``gridspec_kw``, …).
    """
    fig = Figure(figsize=figsize)
    return fig, fig.subplots(nrows, ncols, **kw)


FIGURE_DPI = 110
"""Pixels per inch of the saved figures: a figure of :data:`FIGURE_WIDTH` inches fills the page's width
(1100 px), so its type appears at the size it was set."""


FIGURE_WIDTH = 10.0
"""Inches a figure may take with its legends beside the axes (wider ones are narrowed: the page would shrink them)."""


MIN_FONT_PT = 9.0
"""The smallest type on a figure, in points at the page's width."""


def tidy(fig: Figure, problem: Problem | None) -> None:
    """Make a figure readable on the page: internal names through :func:`label` (legends, axis labels), every
    legend beside its axes (never on the data), no type under :data:`MIN_FONT_PT`, and no wider than
    :data:`FIGURE_WIDTH` (the axes narrow, the type keeps its size)."""
    from matplotlib.layout_engine import ConstrainedLayoutEngine
    from matplotlib.text import Text

    legends = []
    for ax in fig.axes:
        ax.set_xlabel(label(problem, ax.get_xlabel()))
        ax.set_ylabel(label(problem, ax.get_ylabel()))
        leg = ax.get_legend()
        if leg is None:
            continue
        handles = list(getattr(leg, "legend_handles", None) or getattr(leg, "legendHandles", []))
        legends.append((ax, handles, [label(problem, t.get_text()) for t in leg.get_texts()]))
        leg.remove()
    if len(legends) > 1 and len({tuple(t) for _, _, t in legends}) == 1:
        # the same legend on every panel: once, beside the top right panel, not over its neighbours
        legends = [max(legends, key=lambda e: (e[0].get_position().x1, e[0].get_position().y1))]
    for ax, handles, texts in legends:
        ax.legend(handles, texts, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, fontsize=MIN_FONT_PT,
                  ncol=1 if len(texts) <= 12 else 2, frameon=False)
    for t in fig.findobj(Text):
        if t.get_text() and float(t.get_fontsize()) < MIN_FONT_PT:
            t.set_fontsize(MIN_FONT_PT)
    if legends and not isinstance(fig.get_layout_engine(), ConstrainedLayoutEngine):
        fig.tight_layout()  # legends beside inner panels need the room between the panels
    for _ in range(3):
        renderer = fig.canvas.get_renderer() if hasattr(fig.canvas, "get_renderer") else None
        if renderer is None:
            from matplotlib.backends.backend_agg import FigureCanvasAgg

            renderer = FigureCanvasAgg(fig).get_renderer()
        width = fig.get_tightbbox(renderer).width
        w, h = fig.get_size_inches()
        if width <= FIGURE_WIDTH + 0.05:
            break
        fig.set_size_inches(max(w - (width - FIGURE_WIDTH), 3.0), h)
        if legends and not isinstance(fig.get_layout_engine(), ConstrainedLayoutEngine):
            fig.tight_layout()  # narrower panels, the legends keep their size: lay out again


def figure_legend(fig: Figure, handles: Sequence[Any], texts: Sequence[str]) -> None:
    """One legend for every panel, to the right of them all: a legend beside one panel of a grid as tall as several
    panels would push the grid's rows apart."""
    fig.set_layout_engine("constrained")
    fig.legend(handles, texts, loc="outside right upper", fontsize=MIN_FONT_PT, ncol=1 if len(texts) <= 12 else 2, frameon=False)


@dataclass
class ReportContext:
    """What a problem's report hooks get: the results and :meth:`figure`, which saves a figure next to the page."""

    problem: Problem
    variants: Sequence[Any]
    directory: Path
    figures: list[str] = field(default_factory=list)

    def figure(self, name: str, fig: Figure, caption: str) -> str:
        """Save ``fig`` as ``<name>.png`` next to the page (tidied by :func:`tidy`, without the software
        stamp, so the bytes depend on the figure alone); return its HTML."""
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        FigureCanvasAgg(fig)
        tidy(fig, self.problem)
        path = self.directory / f"{name}.png"
        fig.savefig(path, dpi=FIGURE_DPI, bbox_inches="tight", metadata={"Software": None})
        self.figures.append(path.name)
        return f'<figure><img src="{path.name}" alt="{html.escape(caption)}" style="max-width:100%"><figcaption>{html.escape(caption)}</figcaption></figure>'


ROUND_OFF_MARGIN = 1e-3
"""A check's value below this fraction of its upper bound is shown as a bound (:func:`below_margin`)."""


ROUND_OFF_BOUND = 1e-3
"""The largest upper bound that is a tolerance on round-off (a residual, a difference of two solutions); a larger
one (a condition number, a spectral radius) keeps its value's digits (:func:`below_margin`)."""


def below_margin(value: Any, bound: Any, relation: str = "<=") -> str:
    """A certificate check's value as a page shows it (3 significant digits), or, for a value below
    :data:`ROUND_OFF_MARGIN` of an upper bound that is a round-off tolerance (at most :data:`ROUND_OFF_BOUND`), that
    margin rounded up to its decade (``below 1·10⁻¹²``).

    Such a value passes by three orders of magnitude, and its own digits are round-off: a residual of an exact
    identity (1e-16 on one CPU, 5e-15 on another, as the BLAS kernel sums in another order). The bound is what
    holds on every CPU, so a committed page shows it and stays the same wherever the main job runs.

    Parameters
    ----------
    value, bound : float
        The check's value and its bound.
    relation : str
        ``"<="`` (an upper bound: the rule applies) or ``">="`` (the value is shown as it is).

    Returns
    -------
    str
        The cell's text.
    """
    v, b = float(value), float(bound)
    if relation == "<=" and math.isfinite(v) and 0 < b <= ROUND_OFF_BOUND and abs(v) < ROUND_OFF_MARGIN * b:
        return "below " + fmt(10.0 ** math.ceil(math.log10(ROUND_OFF_MARGIN * b) - 1e-9), 1)
    return fmt(value, 3)


def variant_name(v: Any) -> str:
    """A compared variant by its label without the budget all of them share: "CUSUM", "paper parameter set, GLR"."""
    return re.sub(r" at arl0 = [^,]*$", "", str(v.label))


def timeline(ax: Any, t: np.ndarray, values: np.ndarray, labels: Sequence[str], *, threshold: float | None = None, log: bool = True) -> None:
    """Plot statistics over time with the threshold (shared by problem hooks)."""
    for j in range(values.shape[1]):
        ax.plot(t, np.maximum(values[:, j], 1e-6) if log else values[:, j], lw=0.7, label=labels[j])
    if threshold is not None:
        ax.axhline(threshold, color="k", ls="--", lw=1.0, label=f"threshold {threshold:.4g}")
    if log:
        ax.set_yscale("log")
    ax.set_xlabel("t (s)")
    ax.grid(alpha=0.3)


def shade(ax: Any, t: np.ndarray, active: np.ndarray, label: str = "fault active") -> None:
    """Shade where ``active`` holds."""
    if not np.any(active):
        return
    idx = np.flatnonzero(active)
    ax.axvspan(t[idx[0]], t[idx[-1]], color="tab:red", alpha=0.08, label=label)
