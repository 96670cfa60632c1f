"""The HTML report of a problem: verdict, metrics, figures, certificates, export checks.

``write_report`` writes ``reports/<problem>/index.html`` with PNG figures next
to it, the gain files under ``gains/`` and the page's numbers in
``metrics.json``; :func:`write_index` writes ``reports/index.html``, one line
per problem. A page opens with the verdict (:attr:`Problem.claims`, the
paper's claims against ours), then a table of contents, then its sections;
long per-variant detail is folded (``<details>``). Problems add their own
sections (figures in the spirit of the paper) through ``Problem.report``.

Every number on a page goes through :func:`fmt`; every internal name a reader
sees (legends, axes, tables) through :func:`label`. The output is
deterministic: no dates or durations in the files, figures saved without
their software stamp, floats in ``metrics.json`` rounded to
:data:`JSON_DIGITS` significant digits.

Figures are Matplotlib ``Figure`` objects made by :func:`subplots`, not by
``pyplot``: they belong to no window, and saving one as PNG uses Matplotlib's
Agg renderer whatever backend is selected, so importing this module or
writing a report never changes the user's backend (and needs no display).
"""

from __future__ import annotations

import html
import json
import math
import platform
import re
import sys
import textwrap
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from fdisyn.codegen.library import CFLAGS
from fdisyn.evaluation.metrics import DEFINITIONS
from fdisyn.simulation.problem import Problem
from fdisyn.runtime.errors import FileError
from fdisyn.runtime.gainfile import write_gain_file
from fdisyn.runtime.jsondata import parse_json_data
from fdisyn.synthesis.kinds import get_kind, recovery_samples
from matplotlib.figure import Figure

__all__ = ["Claim", "ReportContext", "write_report", "write_index", "summary_table", "subplots", "table", "folded", "fmt", "duration",
           "false_alarm_time", "false_alarms_pooled", "budget_line", "label"]

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;max-width:1150px;margin:2em auto;padding:0 1em;color:#1b1b1b;line-height:1.45}
h1{font-size:1.6em}h2{border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:2em}h3{margin-top:1.5em}
table{border-collapse:collapse;margin:.8em 0;font-size:.88em}th,td{border:1px solid #d0d0d0;padding:.25em .5em;text-align:right;vertical-align:top}
th{background:#f3f3f3}td.l,th.l{text-align:left}td.g,th.g{border-left:2px solid #888}th.g[colspan]{text-align:center}.ok{color:#176b2c}.bad{color:#b00020;font-weight:bold}
th a{color:inherit;text-decoration:underline dotted}
figure{margin:1em 0}figcaption{font-size:.88em;color:#444}code{background:#f4f4f4;padding:0 .2em}
.small{font-size:.85em;color:#555}nav.toc ol{columns:2;font-size:.92em}
details{margin:.6em 0;border-left:3px solid #e3e3e3;padding-left:.8em}summary{cursor:pointer;font-weight:600}
dl.defs{display:grid;grid-template-columns:max-content 1fr;gap:.3em 1em}dl.defs dt{font-weight:600}dl.defs dd{margin:0}
.glance td.l{white-space:nowrap}.glance td{padding:.1em .5em}
"""

SIGNIFICANT_DIGITS = 4
"""Significant digits of every number on a page (:func:`fmt`)."""

JSON_DIGITS = 6
"""Significant digits of the floats in ``metrics.json``: enough for every figure the pages show, few enough that
the last-digit noise of another BLAS kernel does not change the committed file."""

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


def _design_rates(gf: Any) -> tuple[str | None, list[float]]:
    """What set a gain file's thresholds (``'arl0'``, ``'P_f'`` or None: given thresholds) and its rates per
    statistic and sample."""
    if gf.kind == "linear":
        info = (gf.certificate.get("bank") or {}).get("info") or {}
        return ("arl0" if isinstance(info.get("arl0_s"), (int, float)) else "P_f"), [float(e.P_f) for e in gf.evaluators]
    payload = gf.extensions.get(gf.kind)
    if gf.kind == "nafdf" and isinstance(payload, Mapping):
        st = payload.get("settings") or {}
        return ("arl0" if st.get("arl0") is not None else "P_f"), [float(st["false_alarm_probability"])]
    if gf.kind == "beard_fdf" and isinstance(payload, Mapping):
        info = payload.get("design") or {}
        if isinstance(info.get("P_f"), (int, float)):
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
    from fdisyn.synthesis.kinds import false_alarm_budget

    seconds = false_alarm_budget(gf)
    source, rates = _design_rates(gf)
    if seconds is None or source is None:
        return "false-alarm budget: none designed (the thresholds were given)"
    many = f", {len(rates)} statistics" if len(rates) > 1 else ""
    same = all(math.isclose(r, rates[0], rel_tol=1e-9) for r in rates)
    p = f"{fmt(rates[0])}" if same else f"{fmt(min(rates))} to {fmt(max(rates))}"
    per = "per statistic and sample" if gf.kind == "linear" else "per sample"
    if source == "arl0":
        return f"false-alarm budget: one every {duration(seconds)} (arl0 = {fmt(seconds)} s); P_f = {p} {per}{many}"
    return f"false-alarm budget: one every {duration(seconds)} (from P_f = {p} {per}{many})"


def label(problem: Problem | None, name: str) -> str:
    """What a reader sees for an internal name: :attr:`Problem.labels` ``[name]``, else the name itself."""
    labels = getattr(problem, "labels", None) or {}
    return str(labels.get(name, name))


def _slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-") or "section"


def defined(header: str, term: str) -> str:
    """A column header linked to the definition of ``term`` (a key of
    :data:`fdisyn.evaluation.metrics.DEFINITIONS`) in the page's "Definitions" section."""
    if term not in DEFINITIONS:
        raise KeyError(f"no definition of {term!r}; defined: {sorted(DEFINITIONS)}")
    return f'<a href="#def-{_slug(term)}" title="{html.escape(DEFINITIONS[term])}">{html.escape(header)}</a>'


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


def _tidy(fig: Figure, problem: Problem | None) -> None:
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


def _figure_legend(fig: Figure, handles: Sequence[Any], texts: Sequence[str]) -> None:
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
        """Save ``fig`` as ``<name>.png`` next to the page (tidied by :func:`_tidy`, without the software
        stamp, so the bytes depend on the figure alone); return its HTML."""
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        FigureCanvasAgg(fig)
        _tidy(fig, self.problem)
        path = self.directory / f"{name}.png"
        fig.savefig(path, dpi=FIGURE_DPI, bbox_inches="tight", metadata={"Software": None})
        self.figures.append(path.name)
        return f'<figure><img src="{path.name}" alt="{html.escape(caption)}" style="max-width:100%"><figcaption>{html.escape(caption)}</figcaption></figure>'


def _versions() -> str:
    import casadi
    import cvxpy
    import scipy

    items = [
        ("python", sys.version.split()[0]),
        ("numpy", np.__version__),
        ("scipy", scipy.__version__),
        ("casadi", str(getattr(casadi, "__version__", "unknown"))),
        ("cvxpy", cvxpy.__version__),
        ("platform", platform.platform()),
    ]
    return ", ".join(f"{k} {v}" for k, v in items)


_REL = {"<=": "≤", ">=": "≥"}

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


def _certified(gf: Any) -> list[Mapping[str, Any]]:
    """The certificates whose checks a page shows: a linear diagnoser's one per generator, another's its own."""
    return list(gf.certificate["generators"]) if gf.kind == "linear" else [gf.certificate[gf.kind]]


CERTIFICATE_COLUMNS = 6
"""Generators a certificate table shows side by side, one column each; a bank of more shows one row per generator."""


def _certificate_table(gf: Any, problem: Problem | None = None) -> str:
    """Every check with the reason for its bound, its bound and whether every generator passes it, and its value per
    generator (banks repeat their checks): one column per generator, or for a bank of more than
    :data:`CERTIFICATE_COLUMNS` the checks in one table and the values in another, one row per generator."""
    linear = gf.kind == "linear"
    certs = _certified(gf)
    owners = [label(problem, g.name) for g in gf.generators] if linear else [label(problem, gf.design)]
    names: list[str] = []
    for c in certs:
        for chk in c["checks"]:
            if chk["name"] not in names:
                names.append(chk["name"])
    found = {name: [next((k for k in c["checks"] if k["name"] == name), None) for c in certs] for name in names}

    def value(k: Mapping[str, Any] | None) -> str:
        return below_margin(k["value"], k["bound"], k["relation"]) if k is not None else "—"

    wide = len(certs) <= CERTIFICATE_COLUMNS
    rows = []
    for name in names:
        first = next(k for k in found[name] if k is not None)
        ok = all(k is None or k["passed"] for k in found[name])
        verdict = f'<span class="{"ok" if ok else "bad"}">{"pass" if ok else "FAIL"}</span>'
        bound = f"{_REL[first['relation']]} {fmt(first['bound'], 3)}"
        rows.append([name, first["reason"], *((value(k) for k in found[name]) if wide else []), bound, verdict])
    if wide:
        return table(["check", "reason for the bound", *owners, "bound", ""], rows, left=2)
    values = [[owner, *(value(found[name][i]) for name in names)] for i, owner in enumerate(owners)]
    return (table(["check", "reason for the bound", "bound", "every generator"], rows, left=2)
            + table(["generator", *names], values, left=1))


def _design_rows(problem: Problem, variant: Any) -> str:
    """The variant's designs in one table (linear diagnosers: generators, dof, threshold, …; others: sizes)."""
    if any(b.gain_file.kind != "linear" for b in variant.built.values()):
        rows = []
        for d, b in variant.built.items():
            gf, st = b.gain_file, b.gain_file.step
            rows.append([label(problem, d), gf.kind, gf.name, st.nu, st.ny, st.nr, st.nj, st.nstate, ", ".join(label(problem, f) for f in gf.faults)])
        return table(["design", "kind", "gain file", "inputs", "outputs", "residual components", "statistics", "state size", "faults"], rows, left=3)
    rows = []
    for d, b in variant.built.items():
        gf = b.gain_file
        n_checks = sum(len(c["checks"]) for c in gf.certificate["generators"]) + len(gf.certificate["bank"]["checks"])
        info0 = gf.certificate["generators"][0].get("info", {}) if gf.certificate["generators"] else {}
        rows.append(
            [
                label(problem, d),
                gf.name,
                len(gf.generators),
                ", ".join(str(e.dof) for e in gf.evaluators),
                gf.evaluators[0].threshold,
                float(np.trace(gf.evaluators[0].Sigma_r)),
                info0.get("spectral_radius_F"),
                recovery_samples(gf),
                f"{n_checks}/{n_checks}",
            ]
        )
    return table(
        ["design", "gain file", "generators", "dof", "threshold J_th (gen. 0)", "trace Σ_r (gen. 0)", "ρ(F) (gen. 0)",
         "recovery (samples)", "checks passed"],
        rows,
        left=2,
    )


def _account_html(gf: Any, problem: Problem | None = None) -> str:
    """What the design can see (the gain file's ``account`` block), folded: per fault its effect, smallest detectable
    size and the generators that see it, then the faults the bank cannot tell apart; for a kind without an account,
    why (:attr:`fdisyn.synthesis.kinds.DiagnoserKind.account_note`)."""
    acc = getattr(gf, "account", None)
    if acc is None:
        why = get_kind(gf.kind).account_note
        return f'<p class="small">What the design can see: not computed — {html.escape(why)}.</p>' if why else ""
    kinds = sorted({s["kind"] for s in acc["statistics"]})
    rules = {
        "chi2": "χ²: the statistic exceeds its threshold with probability 95 % (50 %) on a sample",
        "wssr": "WSSR: with probability 95 % (50 %) over a window (four-moment law of Liu, Tang &amp; Zhang 2009)",
        "glr": "GLR: its full-window term alone exceeds the threshold with probability 95 % (50 %)",
        "cusum": "CUSUM: the size above which its sum drifts upward, so the fault is detected with probability 1",
        "rms": "window RMS: exceeds h with probability 95 % (50 %) over a window",
    }
    rows = []
    for e in acc["faults"]:
        unit = e.get("unit") or f"units of {label(problem, e['name'])}"
        size = {"zero": "undetectable", "transient": "none at steady state"}.get(e["effect"])
        rows.append(
            [
                f"{label(problem, e['name'])} ({e['type']})",
                e["effect"],
                size or (f"{fmt(e['size'])} ({unit})" if e["size"] is not None else "—"),
                "—" if e.get("size_50") is None or size else fmt(e["size_50"]),
                ", ".join(label(problem, g) for g in e["seen_by"]) or "no generator",
            ]
        )
    body = (
        '<p class="small">A step (bias) fault in steady state, before any Monte Carlo. Effect: zero (its transfer to '
        "every residual cancels, to round-off), transient (only its onset shows: zero steady-state gain) or "
        "persistent. Smallest detectable size, at the design's own statistics and thresholds — "
        + "; ".join(rules[k] for k in kinds)
        + ".</p>"
        + table(["fault", "effect", "smallest size (95 %)", "50 %", "seen by"], rows, left=2)
    )
    groups = acc["classes"]["groups"]
    body += '<p class="small">' + (
        "Faults the bank cannot tell apart: " + "; ".join(html.escape(g["reason"]) for g in groups) + "."
        if groups
        else "Every fault it sees has its own signature."
    )
    if acc["classes"].get("unseen"):
        body += " No generator sees " + ", ".join(html.escape(label(problem, n)) for n in acc["classes"]["unseen"]) + "."
    body += "".join(f" {html.escape(n)}." for n in acc.get("notes", [])) + "</p>"
    return folded(body, "What the design can see")


def _certificate_html(gf: Any, problem: Problem | None = None) -> str:
    """A design's certificate table, with the smallest detectable biases of a linear bank and what it can see."""
    out = [_certificate_table(gf, problem), _account_html(gf, problem)]
    if gf.kind != "linear":
        return "".join(out)
    mdb = gf.certificate["bank"].get("info", {}).get("min_detectable_bias", {})
    if mdb:
        sensors = sorted({s for row in mdb.values() for s in row})
        out.append(
            '<p class="small">Smallest constant sensor bias that crosses the threshold on its own at steady state '
            + ("(<code>sqrt(J_th / gᵀWg)</code>" if all(e.window == 1 for e in gf.evaluators) else "(<code>sqrt(J_th / (N gᵀWg))</code>, N the WSSR window")
            + ", sensor units). \"not used\": the generator does not read that sensor; \"∞ (steady state)\": it reads "
            "it, but a constant bias on it has no steady-state effect on the residual (e.g. a bias that looks like a "
            "constant unknown input, which the generator decouples): only the bias's onset transient shows.</p>"
        )
        cells = [[label(problem, g), *(_bias_cell(row, s) for s in sensors)] for g, row in mdb.items()]
        out.append(table(["generator", *(label(problem, s) for s in sensors)], cells))
    return "".join(out)


def _bias_cell(row: Mapping[str, float | None], sensor: str) -> str:
    """A cell of the smallest-detectable-bias table: the bias, "not used" (no key), "∞ (steady state)" (``None``)."""
    if sensor not in row:
        return "not used"
    value = row[sensor]
    return "∞ (steady state)" if value is None else fmt(value)


def _certificates_section(problem: Problem, variants: Sequence[Any]) -> str:
    """Each distinct certificate once (folded), with the designs (and variants) that share it and its checks passed."""
    owners: dict[str, list[str]] = {}
    checks: dict[str, list[bool]] = {}
    for v in variants:
        for d, b in v.built.items():
            body = _certificate_html(b.gain_file, problem)
            owners.setdefault(body, []).append(label(problem, d) if v.label == "default" else f"{label(problem, d)} ({_variant_name(v)})")
            checks[body] = [bool(k["passed"]) for c in _certified(b.gain_file) for k in c["checks"]]
    out = []
    for k, (body, users) in enumerate(owners.items(), start=1):
        passed = checks[body]
        verdict = "every one passes" if all(passed) else f"{len(passed) - sum(passed)} FAIL"
        summary = f"Certificate {k}: {', '.join(users)} — {len(passed)} checks, {verdict}"
        out.append(f'<details id="certificate-{k}"><summary>{html.escape(summary)}</summary>{body}</details>')
    listed = "".join(out)
    return (
        f'<p class="small">{len(owners)} distinct certificate(s) for {sum(len(u) for u in owners.values())} design(s); designs '
        "that share a certificate are listed under it.</p>" + (listed if len(out) <= 3 else folded(listed, f"The {len(out)} certificates"))
    )


def _designs_section(problem: Problem, variants: Sequence[Any]) -> str:
    out = []
    for v in variants:
        opts = ", ".join(f"{k} = {val!r}" for k, val in v.options.items())
        body = (f'<p class="small">Problem options: {html.escape(opts)}.</p>' if opts else "") + _design_rows(problem, v)
        if v.label == "default":
            out.append(body)
        else:
            out.append(folded(body, f"Variant {v.label}"))
    return "".join(out)


def _export_section(problem: Problem, variants: Sequence[Any]) -> str:
    """The export checks' table: decisions equal and differences within the tolerance, per design and reference."""
    rows, tol = [], 0.0
    for v in variants:
        for d, chk in v.exports.items():
            tol = chk.published()["tolerance"]
            for ref, x in chk.references.items():
                rows.append([_variant_name(v), label(problem, d), ref, chk.samples, chk.nonfinite_samples,
                             *(f"below {fmt(tol, 1)}" if x[k] <= tol else x[k] for k in ("r", "J", "state")),
                             "equal" if x["decisions_equal"] else "DIFFER"])
    if not rows:
        return ""
    flags = " ".join(CFLAGS)
    agree = sum(r[-1] == "equal" for r in rows)
    return (
        f"<p>Each design's step was generated by CasADi, compiled with <code>{html.escape(flags)}</code>, loaded with ctypes and "
        "compared with the CasADi function and (linear diagnosers) the independent NumPy reference built from the gain file alone, "
        f"over a check trace with injected NaN/±inf samples: {agree} of {len(rows)} comparisons make the same decisions, every "
        f"one within the export tolerance {fmt(tol, 1)} (a failing one stops the job). The differences themselves are "
        "round-off whose digits change with the CPU's BLAS kernel; the build folder keeps them (<code>export_check.json</code>).</p>"
        + folded(table(["variant", "design", "reference", "samples", defined("non-finite", "non-finite samples"), "r", "J", "state",
                        "alarm/isolated/status"], rows, left=3), "Normwise relative differences")
    )


def _faulty_scenarios(variant: Any) -> list[tuple[str, str]]:
    """The main variant's faulty scenarios with their faults, in the evaluation's order."""
    ev = variant.evaluation
    first = next(iter(ev.metrics.values()))
    return [(s, m.fault) for s, m in first.items() if m.fault is not None]


def _fault_cells(problem: Problem, faulty: Sequence[tuple[str, str]]) -> list[list[str]]:
    """``[scenario, fault]`` per faulty scenario, the fault named on the first of the consecutive scenarios it shares."""
    return [[label(problem, s), label(problem, f) if k == 0 or faulty[k - 1][1] != f else ""] for k, (s, f) in enumerate(faulty)]


def _most(value: float | None, bad: bool) -> Any:
    """A rate as a table cell, bold red when ``bad`` (the glance's "in most runs")."""
    return f'<span class="bad">{fmt(value)}</span>' if value is not None and bad else value


def _glance_section(problem: Problem, variant: Any) -> str:
    """The main variant's detection figures: one row per faulty scenario, the designs side by side (missed detection,
    delay, isolation), each design headed by its false alarms pooled over every scenario's fault-free samples."""
    ev = variant.evaluation
    designs = list(ev.metrics)
    faulty = _faulty_scenarios(variant)
    groups = []
    for d in designs:
        groups.append((f'<span>{html.escape(label(problem, d))}<br><span class="small">{defined("false alarms", "mean time between false alarms")}: '
                       f"{html.escape(false_alarms_pooled(ev.metrics[d].values()))}</span></span>", 3))
    rows = []
    for (s, _), lead in zip(faulty, _fault_cells(problem, faulty), strict=True):
        row = list(lead)
        for d in designs:
            m = ev.metrics[d][s]
            missed, iso = m.missed_detection_rate, m.isolation_accuracy
            row += [_most(missed, missed is not None and missed > 0.5), m.detection_delay_mean_s, _most(iso, iso is not None and iso < 0.5)]
        rows.append(row)
    per = [defined("missed (of runs)", "missed detection"), defined("delay mean (s)", "detection delay"),
           defined("isolated (of runs)", "isolation accuracy")]
    return (
        f'<p class="small">{fmt(ev.runs)} runs per scenario; every design sees the same runs; false alarms over every '
        "scenario's fault-free samples. Bold red: missed, or not isolated, in more than half of the runs. Each scenario's "
        'false alarms and the other figures: <a href="#monte-carlo-metrics">Monte Carlo metrics</a>.</p>'
        + f'<div class="glance">{table(["scenario", "fault", *(per * len(designs))], rows, left=2, groups=groups)}</div>'
    )


_ISOLATION_COLOURS = (("true fault", "#2e7d32"), ("another fault", "#c62828"), ("not isolated", "#9e9e9e"))


def _isolation_bar(parts: Sequence[float]) -> str:
    """One stacked bar of the isolation decisions (fractions of runs, :data:`_ISOLATION_COLOURS`) with the true
    fault's percentage beside it."""
    bar = "".join(
        f'<span title="{name} {fmt(100 * p)} %" style="display:inline-block;height:.9em;width:{100 * p:.1f}%;background:{colour}"></span>'
        for (name, colour), p in zip(_ISOLATION_COLOURS, parts, strict=True)
    )
    return (f'<div style="white-space:nowrap"><div style="display:inline-block;vertical-align:middle;width:7em;background:#eee;'
            f'line-height:0">{bar}</div> {fmt(100 * parts[0])} %</div>')


def _isolation_section(problem: Problem, variant: Any) -> str:
    """Per faulty scenario and design, the runs' most frequent decision: the true fault, another fault, or none
    (% of runs): one stacked bar per design, the numbers folded."""
    ev = variant.evaluation
    designs = [d for d in ev.metrics if any(m.fault is not None and m.isolation_accuracy is not None for m in ev.metrics[d].values())]
    faulty = [(s, f) for s, f in _faulty_scenarios(variant) if any(ev.metrics[d][s].isolation_accuracy is not None for d in designs)]
    if not faulty:
        return ""
    bars, rows = [], []
    for (s, _), lead in zip(faulty, _fault_cells(problem, faulty), strict=True):
        cells = []
        for d in designs:
            m = ev.metrics[d][s]
            if m.isolation_accuracy is None:
                cells.append("—")
                continue
            parts = [m.isolation_accuracy, m.false_isolation_rate or 0.0]
            parts.append(max(0.0, 1.0 - parts[0] - parts[1]))
            cells.append(_isolation_bar(parts))
            rows.append([label(problem, s), label(problem, m.fault), label(problem, d), *(100.0 * p for p in parts)])
        bars.append([*lead, *cells])
    legend = " ".join(f'<span style="color:{c}">■</span> {n}' for n, c in _ISOLATION_COLOURS)
    return (
        "<p class=\"small\">The most frequent isolation decision of each run while the fault is active "
        f"({defined('definitions', 'isolation accuracy')}): {legend}; the number is the true fault's share of the runs.</p>"
        + f'<div class="glance">{table(["scenario", "fault", *(label(problem, d) for d in designs)], bars, left=2)}</div>'
        + folded(table(["scenario", "true fault", "design", "true fault (% of runs)", "another fault (% of runs)",
                        "not isolated (% of runs)"], rows, left=3))
    )


def _metrics_details(problem: Problem, variant: Any) -> str:
    """Every metric of one variant (the full tables, folded on the page)."""
    ev = variant.evaluation
    designs = list(ev.metrics)
    scen = list(next(iter(ev.metrics.values())))
    out = [f'<p class="small">{fmt(ev.runs)} runs per scenario, run i of the s-th scenario seeded by SeedSequence([{ev.seed0}, s, i]); every design sees the same runs.</p>']
    rows = []
    for s in scen:
        for d in designs:
            m = ev.metrics[d][s]
            rows.append([label(problem, s), label(problem, d), label(problem, m.fault) if m.fault else "none",
                         false_alarm_time(m.false_alarm_episodes, m.fault_free_samples * m.Ts), m.false_alarm_rate, m.false_alarm_runs,
                         m.missed_detection_rate, m.missed_alarm_fraction, m.detection_delay_mean_s, m.detection_delay_max_s,
                         m.isolation_accuracy, m.first_isolation_accuracy, m.sample_isolation_accuracy, m.nonfinite_samples])
    out.append(
        table(
            ["scenario", "design", "fault", defined("false alarms", "mean time between false alarms"),
             defined("false-alarm rate (per sample)", "false-alarm rate"),
             defined("false-alarm runs (of runs)", "false-alarm runs"), defined("missed detection (of runs)", "missed detection"),
             defined("missed-alarm fraction (of samples)", "missed-alarm fraction"), defined("delay mean (s)", "detection delay"),
             defined("delay max (s)", "detection delay"), defined("isolation acc.", "isolation accuracy"),
             defined("first-decision acc.", "first isolation accuracy"), defined("sample isolation acc.", "sample isolation accuracy"),
             defined("non-finite samples", "non-finite samples")],
            rows,
            left=3,
        )
    )
    out.append(_budget_table(problem, [(variant, d) for d in designs], scen))
    extra_keys = sorted({k for d in designs for s in scen for k in ev.metrics[d][s].extra})
    if extra_keys:
        rows = [[label(problem, s), label(problem, d), *(ev.metrics[d][s].extra.get(k) for k in extra_keys)] for s in scen for d in designs]
        out.append("<h4>Problem-specific figures</h4>" + table(["scenario", "design", *(label(problem, k) for k in extra_keys)], rows, left=2))
    if any(variant.built[d].gain_file.kind != "linear" for d in designs):
        return "".join(out)
    rows = []
    for d in designs:
        m = ev.metrics[d][scen[0]]
        gf = variant.built[d].gain_file
        for j, rate in enumerate(m.statistic_exceedance):
            lo, hi = m.statistic_exceedance_interval[j]
            inside = lo <= rate <= hi
            rows.append([label(problem, d), label(problem, gf.step.statistic_names[j]), gf.evaluators[j].P_f, rate, f"[{fmt(lo)}, {fmt(hi)}]",
                         f'<span class="{"ok" if inside else "bad"}">{"inside" if inside else "outside"}</span>'])
    out.append(
        f"<h4>χ² law on fault-free data ({html.escape(label(problem, scen[0]))})</h4>"
        "<p class=\"small\">Exceedance rate of each statistic against its design false-alarm probability, with the two-sided "
        "99.9 % binomial interval for independent samples. White residuals (minimum-variance designs) give independent samples; "
        "coloured residuals cluster their exceedances, which widens the real spread beyond this interval.</p>"
        + table(["design", "statistic", "P_f (per sample)", defined("observed (per sample)", "statistic exceedance"), "binomial 99.9 %", ""], rows, left=2)
    )
    return "".join(out)


def _definitions_section() -> str:
    items = "".join(f'<dt id="def-{_slug(k)}">{html.escape(k)}</dt><dd>{html.escape(v)}</dd>' for k, v in DEFINITIONS.items())
    return f'<p class="small">Per scenario, over R runs of N samples; the column headers link here.</p><dl class="defs">{items}</dl>'


def _verdict_section(claims: Sequence[Claim]) -> str:
    if not claims:
        return '<p class="small">This problem states no claims of its paper to check.</p>'
    n = sum(c.verdict == "reproduced" for c in claims)
    rows = [
        [c.claim, c.paper, c.ours, f'<span class="{"ok" if c.verdict == "reproduced" else "bad"}">{c.verdict}</span>', c.why or "—"]
        for c in claims
    ]
    return f"<p><strong>{n} of {len(claims)} claims reproduced.</strong></p>" + table(["claim", "paper", "ours", "verdict", "why"], rows, left=5)


def _toc(sections: Sequence[tuple[str, str, str]]) -> str:
    items = "".join(f'<li><a href="#{anchor}">{html.escape(title)}</a></li>' for anchor, title, _ in sections)
    return f'<nav class="toc"><h2 id="contents">Contents</h2><ol>{items}</ol></nav>'


def _run_figures(ctx: ReportContext) -> list[tuple[str, str]]:
    """Figures of a problem without its own report hook (e.g. a TOML plant file).

    For every design and scenario, run 0 through the generated C: each
    statistic that has a fixed threshold, divided by it (an alarm is above 1);
    the isolated fault; and for parameter estimators (``theta_hat_<θ>``
    statistics) the estimate beside the simulated truth ``true_<θ>``.
    """
    v = ctx.variants[0]
    ex, bt = v.evaluation.examples, v.evaluation.batches
    body = []
    for dname, built in v.built.items():
        gf = built.gain_file
        names = list(gf.step.statistic_names)
        thr = np.asarray(gf.thresholds, dtype=float)
        fixed = [j for j in range(len(names)) if np.isfinite(thr[j]) and thr[j] > 0]
        for sname, res in ex.get(dname, {}).items():
            b = bt[sname]
            est = [(j, nm[len("theta_hat_") :]) for j, nm in enumerate(names) if nm.startswith("theta_hat_")]
            est = [(j, q) for j, q in est if f"true_{q}" in b.extra]
            rows = 2 + bool(est)
            fig, axes = subplots(rows, 1, figsize=(9, 2.2 * rows + 0.6), sharex=True)
            timeline(axes[0], b.t, res.J[:, fixed] / thr[fixed], [names[j] for j in fixed], threshold=1.0)
            axes[0].set_ylabel("J / threshold")
            shade(axes[0], b.t, b.active)
            axes[0].legend(fontsize=7, ncol=3)
            axes[1].step(b.t, res.isolated, where="post", lw=0.9)
            axes[1].set_yticks(range(-1, len(gf.faults)), ["none", *(label(ctx.problem, f) for f in gf.faults)])
            axes[1].set_ylabel("isolated")
            axes[1].grid(alpha=0.3)
            shade(axes[1], b.t, b.active)
            for j, q in est:
                axes[2].plot(b.t, res.J[:, j], lw=0.8, label=f"estimate of {q}")
                axes[2].plot(b.t, b.extra[f"true_{q}"][0], "k--", lw=0.8, label=f"true {q}" if len(est) > 1 else "truth")
            if est:
                axes[2].set_ylabel("parameters")
                axes[2].legend(fontsize=7, ncol=2)
                axes[2].grid(alpha=0.3)
            axes[-1].set_xlabel("t (s)")
            body.append(
                ctx.figure(
                    f"{dname}_{sname}",
                    fig,
                    f"{label(ctx.problem, dname)}, scenario {label(ctx.problem, sname)} ({ctx.problem.scenarios[sname].description or 'no description'}): run 0 "
                    "through the generated C — statistics over their thresholds, the isolated fault"
                    + (", the parameter estimates against the truth." if est else "."),
                )
            )
    return [("Figures", "".join(body))] if body else []


def _mtbfa(mean_s: float | None, interval: tuple[float, float | None]) -> str:
    """A measured mean time between false alarms with its 95 % interval, as durations (:func:`duration`):
    "2 min [1.33 min, 3.17 min]"; none seen: "none seen (> 6.67 min)", the interval's lower end."""
    lo, hi = interval
    if mean_s is None:
        return f"none seen (> {duration(lo)})"
    return f"{duration(mean_s)} [{duration(lo)}, {duration(hi)}]"


RATIO_GOAL = 1.2
"""The goal of a mean detection delay over its Lorden bound (:func:`_ratio`)."""


def _meets_goal(m: Any) -> bool | None:
    """Whether the mean delay is within :data:`RATIO_GOAL` times the Lorden bound; None where the ratio says nothing:
    the bound under one sample (a fault so large that any detector needs the onset sample), or a delay under half
    the bound (faster than the bound allows: the fault is no persistent mean shift)."""
    if m.delay_bound_ratio is None or m.lorden_bound_samples is None or m.lorden_bound_samples < 1.0 or m.delay_bound_ratio < 0.5:
        return None
    return bool(m.delay_bound_ratio <= RATIO_GOAL)


def _ratio(m: Any) -> str:
    """Mean delay over the Lorden bound, with a class when it meets the goal (:func:`_meets_goal`); "no mean shift"
    under half the bound, "—" where the bound is under one sample."""
    ok = _meets_goal(m)
    if ok is None:
        shown = m.delay_bound_ratio is not None and m.lorden_bound_samples is not None and m.lorden_bound_samples >= 1.0
        return "no mean shift" if shown else "—"
    return f'<span class="{"ok" if ok else "bad"}">{fmt(m.delay_bound_ratio, 3)}</span>'


def _variant_name(v: Any) -> str:
    """A compared variant by its label without the budget all of them share: "CUSUM", "paper parameter set, GLR"."""
    return re.sub(r" at arl0 = [^,]*$", "", str(v.label))


def _budget_table(problem: Problem, pairs: Sequence[tuple[Any, str]], scen: Sequence[str], *, by_variant: bool = False) -> str:
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
            head = [label(problem, s), _variant_name(v), label(problem, d)] if by_variant else [label(problem, s), label(problem, d)]
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
    if {v.built[d].gain_file.kind for v, d in pairs} == {"nafdf"}:
        return "<h4>False-alarm budget and the Lorden bound</h4>" + get_kind("nafdf").budget_text + table(header, rows, left=3 if by_variant else 2)
    return (
        "<h4>False-alarm budget and the Lorden bound</h4>"
        '<p class="small">Time between false alarms: fault-free time over the number of false-alarm episodes, with Garwood\'s '
        "exact 95 % Poisson interval; budget: the design's arl0, or Ts/Σ P_f for a design by P_f. A bank splits its budget "
        "equally over its statistics (Bonferroni), so it is met or exceeded. Lorden bound: ln(ARL)/I, the smallest over the "
        "statistics of ln of each one's share of the budget (in samples) over the Kullback–Leibler information per sample the "
        "fault brought to its generator's residual (measured mean shift, long-run covariance; Lorden, Annals of Mathematical "
        "Statistics 42(6), 1971): no detector with that budget is faster on average for a persistent change. The ratio is "
        f"shown where the bound is at least one sample; the goal is ≤ {fmt(RATIO_GOAL)}. \"No mean shift\": detected more than twice "
        "as fast as the bound allows, so the fault is not the persistent mean change the bound is for (a gain fault on a "
        "varying signal, whose residual effect averages out). Isolation is the bank's alarm pattern (the "
        "signature table) over the statistics' held alarms; false isolation: runs whose most frequent decision names "
        "another fault.</p>"
        + table(header, rows, left=3 if by_variant else 2)
    )


_DETECTOR_NAMES = {
    "chi2": "per-sample χ²",
    "wssr": "WSSR (Long & Wang, Aeroengine 43(5), 2017, section 2)",
    "cusum": "CUSUM (Page, Biometrika 41(1/2), 1954)",
    "glr": "windowed GLR (Willsky & Jones, IEEE Transactions on Automatic Control 21(1), 1976)",
}
"""The detectors of the comparison as its introduction names them, in its order."""


def _compared_detectors(variants: Sequence[Any]) -> str:
    """The detectors of the variants with an ``arl0``, named for the comparison's first sentence: "WSSR (…) and CUSUM (…)"."""
    used = {v.options.get("detector") for v in variants if v.options.get("arl0") is not None}
    named = [name for key, name in _DETECTOR_NAMES.items() if key in used]
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
        rows.append([_variant_name(v), label(problem, d), mtbfa, duration(ms[0].arl0_budget_s), mean(m.missed_detection_rate for m in faulty),
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


def _detectors_section(problem: Problem, variants: Sequence[Any]) -> str:
    """The detectors side by side at the same false-alarm budget (the variants with an ``arl0`` option): one row per
    detector, every scenario folded."""
    same = [v for v in variants if v.options.get("arl0") is not None]
    if len(same) < 2:
        return ""
    scen: list[str] = []
    for v in same:
        for s in next(iter(v.evaluation.metrics.values())):
            if s not in scen:
                scen.append(s)
    pairs = [(v, d) for v in same for d in v.evaluation.metrics]
    full = _budget_table(problem, pairs, scen, by_variant=True)
    if not full:
        return ""
    return _budget_summary(problem, pairs) + folded(full, "Every scenario")


def _fault_free_counts(variant: Any, design: str, nj: int) -> list[np.ndarray]:
    """Per statistic, its fault-free samples of every run and scenario counted in the bins
    :data:`~fdisyn.evaluation.metrics.HISTOGRAM_EDGES` ``× threshold`` (empty: the statistic has no threshold)."""
    total: list[np.ndarray] = [np.zeros(0, dtype=np.int64)] * nj
    for m in variant.evaluation.metrics.get(design, {}).values():
        for j, c in enumerate(m.fault_free_histogram[:nj]):
            c = np.asarray(c, dtype=np.int64)
            if c.size:
                total[j] = c if total[j].size == 0 else total[j] + c
    return total


def _law_figures(ctx: ReportContext) -> str:
    """Per design, each statistic's fault-free histogram over every run against its law: χ²(dof) for a χ² statistic;
    for the others (WSSR, CUSUM, GLR, …) the empirical tail P(J ≥ x) against the threshold and the design's P_f."""
    import scipy.stats
    from fdisyn.evaluation.metrics import HISTOGRAM_EDGES
    from matplotlib.ticker import MaxNLocator

    v, problem, out = ctx.variants[0], ctx.problem, []
    for k, (d, b) in enumerate(v.built.items()):
        gf = b.gain_file
        names = list(gf.step.statistic_names)
        counts = _fault_free_counts(v, d, len(names))
        shown = [j for j, c in enumerate(counts) if c.size and c.sum() > 0][:8]
        if not shown:
            continue
        with_threshold = sum(1 for c in counts if c.size)
        cols = min(4, len(shown))
        rows = -(-len(shown) // cols)
        fig, axes = subplots(rows, cols, figsize=(2.6 * cols, 2.9 * rows + 0.4), squeeze=False)
        thr = np.asarray(gf.thresholds, dtype=float)
        samples = 0
        for j, ax in zip(shown, axes.ravel(), strict=False):
            c, h = counts[j], float(thr[j])
            n = int(c.sum())
            samples = max(samples, n)
            edges = HISTOGRAM_EDGES * h
            ev = gf.evaluators[j] if j < len(gf.evaluators) else None
            if ev is not None and ev.kind == "chi2":
                dens = c[1:-1] / (n * np.diff(edges))
                ax.stairs(np.where(dens > 0, dens, np.nan), edges, fill=True, color="tab:blue", alpha=0.6)
                grid = np.linspace(edges[-1] / 400, edges[-1], 400)
                ax.plot(grid, scipy.stats.chi2.pdf(grid, ev.dof), "k", lw=1.0)
                ax.set_ylabel("density")
                ax.set_ylim(bottom=0.3 / (n * (edges[1] - edges[0])))  # below one sample per bin the law is not seen
                law = f"χ²({ev.dof})"
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
            ax.set_title(textwrap.fill(label(problem, names[j]), 30) + f"\n{law}", fontsize=MIN_FONT_PT)
            ax.set_xlabel("J")
            ax.xaxis.set_major_locator(MaxNLocator(4))  # a narrow panel: a few ticks that do not run into each other
            ax.ticklabel_format(axis="x", style="sci", scilimits=(-2, 3), useMathText=True)  # 2·10⁻⁴, not 0.0002
            ax.grid(alpha=0.3)
        for ax in axes.ravel()[len(shown):]:
            ax.set_visible(False)
        fig.tight_layout()
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
    """Mean detection delay and missed detections against the fault's size, per design and faulty scenario."""
    v, problem = ctx.variants[0], ctx.problem
    sweep = getattr(v, "sweep", None)
    if sweep is None or not sweep.scenarios:
        return ""
    designs = list(v.evaluation.metrics)
    fig, axes = subplots(len(designs), 2, figsize=(9.0, 2.2 * len(designs) + 0.4), squeeze=False)
    rows = []
    for i, d in enumerate(designs):
        for base, by_factor in sweep.scenarios.items():
            pts = []
            for f in sorted({1.0, *by_factor}):
                m = v.evaluation.metrics[d][base] if f == 1.0 else sweep.evaluation.metrics[d][by_factor[f]]
                pts.append((f, m.detection_delay_mean_s, m.missed_detection_rate))
                rows.append([label(problem, d), label(problem, base), f, m.runs, m.missed_detection_rate, m.detection_delay_mean_s])
            f_, delay, missed = zip(*pts, strict=False)
            axes[i, 0].plot(f_, [np.nan if x is None else x for x in delay], "o-", lw=1.0, ms=3)
            axes[i, 1].plot(f_, missed, "o-", lw=1.0, ms=3, label=label(problem, base))
        axes[i, 0].set_title(label(problem, d), loc="left", fontsize=MIN_FONT_PT)
        axes[i, 0].set_ylabel("mean delay (s)")
        axes[i, 1].set_ylabel("missed detection")
        axes[i, 1].set_ylim(-0.03, 1.03)
        ticks = sorted({1.0, *sweep.factors})
        for ax in axes[i]:
            ax.set_xscale("log")
            ax.set_xticks(ticks, [fmt(f) for f in ticks])
            ax.minorticks_off()
            ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("fault size (× the scenario's)")
    _figure_legend(fig, *axes[0, 1].get_legend_handles_labels())
    return ctx.figure(
        "fault_size_sweep",
        fig,
        f"Detection against the fault's size: each faulty scenario with its fault scaled by {', '.join(fmt(f) for f in sweep.factors)} "
        f"({fmt(sweep.evaluation.runs)} runs each; 1 is the scenario itself with the page's runs). Offsets and drifts scale "
        "their value, a gain fault its deviation from 1.",
    ) + (
        folded(table(["design", "scenario", "size (×)", "runs", defined("missed detection (of runs)", "missed detection"),
                      defined("delay mean (s)", "detection delay")], rows, left=2))
    )


def _discrete_model(problem: Problem, variant: Any, gf: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, np.ndarray]] | None:
    """``(A, E, C, fault directions)`` of the design model in discrete time: each fault of the gain file that is a
    component fault (a column of ``Fx``, into the state) or a single sensor (into the output)."""
    if problem.model is None:
        return None
    model = problem.model(**dict(variant.options))
    if hasattr(model, "A_D"):  # a sampled-data plant: exact sampling of the disturbance, the fault held
        A, E, C, Fx = model.A_D, model.E_J, model.C, model.Fx_D
        comp = list(gf.faults) if Fx.shape[1] == len(gf.faults) else []
        outputs: list[str] = list(gf.outputs)
    else:
        plant = model if model.is_discrete else model.discretise(gf.Ts)
        A, E, C, Fx = plant.A, plant.E, plant.C, plant.Fx
        comp, outputs = list(plant.component_faults), list(plant.outputs)
    if C.shape[0] != len(gf.outputs):
        return None
    dirs: dict[str, np.ndarray] = {}
    for f in gf.faults:
        if f in comp:
            dirs[f] = np.concatenate([Fx[:, comp.index(f)], np.zeros(C.shape[0])])
        elif f in outputs:
            dirs[f] = np.concatenate([np.zeros(A.shape[0]), np.eye(C.shape[0])[outputs.index(f)]])
    return A, E, C, dirs


def _responses(A: np.ndarray, E: np.ndarray, C: np.ndarray, dirs: Mapping[str, np.ndarray], gen: Any, w: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """σ̄(G_rd(e^{jω})) and |G_rf(e^{jω})| per fault of one generator driven by the plant (state and sensor inputs)."""
    n, ns = A.shape[0], gen.Ar.shape[0]
    Acl = np.block([[A, np.zeros((n, ns))], [gen.By @ C, gen.Ar]])
    Ccl = np.hstack([gen.Dy @ C, gen.Cr])
    Bd = np.vstack([E, np.zeros((ns, E.shape[1]))])
    rd = np.zeros(w.size)
    rf = {f: np.zeros(w.size) for f in dirs}
    for i, z in enumerate(np.exp(1j * w)):
        M = z * np.eye(n + ns) - Acl
        rd[i] = np.linalg.norm(Ccl @ np.linalg.solve(M, Bd), 2) if E.shape[1] else 0.0
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
        if gf.kind != "linear" or not gf.generators:
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
        _figure_legend(fig, handles, texts)
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
    linear = [(d, b.gain_file) for d, b in v.built.items() if b.gain_file.kind == "linear" and b.gain_file.generators]
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


def _standard_figures(ctx: ReportContext) -> list[tuple[str, str]]:
    """The figures every page has where its data allow: statistics against their law, detection against the fault's
    size, the residuals' frequency responses, the generators' poles."""
    return [
        ("Fault-free statistics against their law", _law_figures(ctx)),
        ("Detection against fault size", _sweep_figure(ctx)),
        ("Residual frequency responses", _frequency_figures(ctx)),
        ("Generator poles", _pole_figure(ctx)),
    ]


def _rounded(x: Any) -> Any:
    """``x`` with every float rounded to :data:`JSON_DIGITS` significant digits (tuples become lists)."""
    if isinstance(x, (bool, np.bool_)) or x is None or isinstance(x, str):
        return bool(x) if isinstance(x, np.bool_) else x
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        v = float(x)
        return v if not math.isfinite(v) or v == 0.0 else float(f"{v:.{JSON_DIGITS}g}")
    if isinstance(x, Mapping):
        return {str(k): _rounded(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_rounded(v) for v in x]
    if isinstance(x, np.ndarray):
        return _rounded(x.tolist())
    return x


def _summary_rows(problem: Problem, variant: Any) -> list[dict[str, Any]]:
    """Per design of the main variant: false alarms (rate over every fault-free sample), missed detections,
    mean delay and isolation accuracy (means over the faulty scenarios that have them)."""
    out = []
    for d, per in variant.evaluation.metrics.items():
        ms = list(per.values())
        n = sum(m.fault_free_samples for m in ms)
        faulty = [m for m in ms if m.fault is not None]

        def mean(values: list[Any]) -> float | None:
            vals = [float(v) for v in values if v is not None]
            return sum(vals) / len(vals) if vals else None

        out.append(
            {
                "design": d,
                "false_alarm_rate": sum(m.false_alarm_rate * m.fault_free_samples for m in ms) / n if n else None,
                "false_alarm_episodes": sum(m.false_alarm_episodes for m in ms),
                "fault_free_time_s": sum(m.fault_free_samples * m.Ts for m in ms),
                "missed_detection_rate": mean([m.missed_detection_rate for m in faulty]),
                "detection_delay_mean_s": mean([m.detection_delay_mean_s for m in faulty]),
                "isolation_accuracy": mean([m.isolation_accuracy for m in faulty]),
            }
        )
    return out


def _metrics_document(problem: Problem, variants: Sequence[Any], claims: Sequence[Claim]) -> dict[str, Any]:
    return _rounded(
        {
            "problem": problem.name,
            "significant_digits": JSON_DIGITS,
            "verdict": {"title": problem.title, "claims": len(claims), "reproduced": sum(c.verdict == "reproduced" for c in claims)},
            "summary": _summary_rows(problem, variants[0]),
            "variants": [
                {
                    "label": v.label,
                    "options": dict(v.options),
                    "exports": {d: c.published() for d, c in v.exports.items()},
                    "evaluation": v.evaluation.to_dict(),
                }
                for v in variants
            ],
        }
    )


_CLOCK_KEYS = re.compile(r"created_utc|(^|_)(solve_)?time(_|$)|seconds")
"""Keys of a gain file's provenance and certificate information that hold a date or a duration."""


def _without_clock(x: Any) -> Any:
    if isinstance(x, Mapping):
        return {k: _without_clock(v) for k, v in x.items() if not _CLOCK_KEYS.search(str(k))}
    if isinstance(x, list):
        return [_without_clock(v) for v in x]
    return x


def _published(gf: Any) -> Any:
    """The gain file as a report publishes it: without its creation date or solver durations (the committed
    files stay the same from one run to the next; the build folder keeps the full file)."""
    return replace(gf, provenance=_without_clock(dict(gf.provenance)), certificate=_without_clock(dict(gf.certificate)))


def variant_tag(label: str) -> str:
    """A report variant's label as a file or folder name: its characters other than letters and digits written
    ``_`` (``"persistence 3"`` → ``persistence_3``)."""
    return "".join(ch if ch.isalnum() else "_" for ch in label)


def published_gain_name(name: str, label: str, taken: set[str]) -> str:
    """The file name under a report's ``gains/`` of the gain file ``name`` of the variant ``label``.

    ``<name>.json``; a name an earlier variant already published (a variant that changes an option the gain
    file's name does not carry, such as ``persistence``) gets the variant's label: ``<name>-<label>.json``, the
    label's characters other than letters and digits written ``_``. ``taken`` (the names published so far) is
    updated.

    Parameters
    ----------
    name : str
        The gain file's name.
    label : str
        The report variant's label (``"default"`` for the main one).
    taken : set of str
        The file names already published for this report; the returned one is added.

    Returns
    -------
    str
        The file name.
    """
    file = f"{name}.json"
    if file in taken:
        file = f"{name}-{variant_tag(label)}.json"
    taken.add(file)
    return file


def write_report(problem: Problem, variants: Sequence[Any], directory: Path) -> Path:
    """Write the problem's page, its figures, its gain files and ``metrics.json``; return the page's path."""
    directory.mkdir(parents=True, exist_ok=True)
    ctx = ReportContext(problem=problem, variants=variants, directory=directory)
    claims = list(problem.claims(ctx)) if problem.claims is not None else []
    main = variants[0]
    sections: list[tuple[str, str, str]] = []

    def add(title: str, body: str) -> None:
        if not body:
            return
        anchor, k = _slug(title), 2
        while anchor in {"verdict", "contents", *(a for a, _, _ in sections)}:
            anchor, k = f"{_slug(title)}-{k}", k + 1
        sections.append((anchor, title, body))

    add("Detection at a glance", _glance_section(problem, main))
    add("Isolation", _isolation_section(problem, main))
    for title, body in problem.report(ctx) if problem.report is not None else _run_figures(ctx):
        add(title, body)
    for title, body in _standard_figures(ctx):
        add(title, body)
    compared = _detectors_section(problem, variants)
    if compared:
        nafdf = {b.gain_file.kind for v in variants for b in v.built.values()} == {"nafdf"}
        what = (
            "The NAFDF's fast detection on the EKF innovations: the WSSR (Zhou, Xi & Zhang c. 1991, eq. (2.4)), and CUSUM "
            "(Page, Biometrika 41(1/2), 1954) and windowed GLR (Willsky & Jones, IEEE Transactions on Automatic Control "
            "21(1), 1976) on the normalised innovations, the rest of the filter unchanged"
            if nafdf
            else f"{_compared_detectors(variants)} statistics of the same generators"
        )
        add("Detectors at one false-alarm budget",
            f"<p>{what}, each designed for the same mean time between false alarms arl0.</p>" + compared)
    add("Designs", _designs_section(problem, variants))
    add("Certificates", _certificates_section(problem, variants))
    add("Generated C", _export_section(problem, variants))
    add(
        "Monte Carlo metrics",
        "".join(
            f"<details{' open' if len(variants) == 1 else ''}><summary>{html.escape('main designs' if v.label == 'default' else str(v.label))}"
            f"</summary>{_metrics_details(problem, v)}</details>"
            for v in variants
        ),
    )
    if problem.notes:
        add("Modelling choices", "<ul>" + "".join(f"<li>{html.escape(n)}</li>" for n in problem.notes) + "</ul>")
    add("Definitions", _definitions_section())
    add(
        "Provenance",
        f'<p class="small">Generated by <code>fdisyn report {html.escape(problem.name)}</code> with {html.escape(_versions())}. '
        'Gain files of every design are in <a href="gains/">gains/</a>; the numbers of this page in '
        f'<a href="metrics.json">metrics.json</a> ({JSON_DIGITS} significant digits).</p>',
    )
    parts = [
        f"<!doctype html><html><head><meta charset='utf-8'><title>fdisyn — {html.escape(problem.name)}</title><style>{_CSS}</style></head><body>",
        '<p class="small"><a href="../index.html">All problems</a></p>',
        f"<h1>{html.escape(problem.title)}</h1>",
        f"<p>{html.escape(problem.summary)}</p>",
        f'<h2 id="verdict">Verdict</h2>{_verdict_section(claims)}',
        _toc(sections),
        *(f'<h2 id="{anchor}">{html.escape(title)}</h2>{body}' for anchor, title, body in sections),
        "</body></html>",
    ]
    gains_dir, taken = directory / "gains", set[str]()
    for v in variants:
        for b in v.built.values():
            write_gain_file(_published(b.gain_file), gains_dir / published_gain_name(b.gain_file.name, v.label, taken))
    (directory / "metrics.json").write_text(json.dumps(_metrics_document(problem, variants, claims), indent=1) + "\n", encoding="utf-8")
    page = directory / "index.html"
    page.write_text("\n".join(parts) + "\n", encoding="utf-8")
    return page


def _documents(reports: Path, names: Sequence[str] | None = None) -> list[dict[str, Any]]:
    """The ``metrics.json`` of every problem under ``reports`` (or of ``names``), by name."""
    paths = [reports / n / "metrics.json" for n in names] if names is not None else sorted(reports.glob("*/metrics.json"))
    return [parse_json_data(p.read_text(encoding="utf-8"), str(p), "a report's metrics", error=FileError) for p in paths if p.is_file()]


def _verdict_line(doc: Mapping[str, Any]) -> str:
    v = doc.get("verdict")
    if not v:
        return "no verdict (written by an older fdisyn)"
    return f"{v['reproduced']} of {v['claims']} claims reproduced" if v["claims"] else "no claims stated"


def write_index(reports: Path) -> Path:
    """``reports/index.html``: every problem's page under ``reports`` with its one-line verdict."""
    rows = []
    for doc in _documents(reports):
        name = doc["problem"]
        title = (doc.get("verdict") or {}).get("title", name)
        rows.append([f'<a href="{html.escape(name)}/index.html">{html.escape(name)}</a>', title, _verdict_line(doc)])
    page = reports / "index.html"
    page.write_text(
        f"<!doctype html><html><head><meta charset='utf-8'><title>fdisyn — reports</title><style>{_CSS}</style></head><body>"
        "<h1>fdisyn reports</h1><p>One page per reference problem: the paper's claims against ours first, then the "
        "Monte Carlo metrics, figures, certificates and the checks of the generated C.</p>"
        + table(["problem", "paper", "verdict"], rows, left=3)
        + "</body></html>\n",
        encoding="utf-8",
    )
    return page


def _summary_false_alarms(row: Mapping[str, Any]) -> str:
    """A summary row's false alarms: the time between them with the rate per sample beside it
    (:func:`false_alarm_time`); a summary written before it held the time shows the rate alone."""
    rate = row.get("false_alarm_rate")
    episodes, exposure = row.get("false_alarm_episodes"), row.get("fault_free_time_s")
    if not isinstance(episodes, int) or not isinstance(exposure, (int, float)):
        return "—" if rate is None else f"{fmt(rate)} per sample"
    text = false_alarm_time(episodes, float(exposure))
    return text if episodes == 0 or rate is None else f"{text} ({fmt(rate)} per sample)"


def summary_table(reports: Path, names: Sequence[str]) -> str:
    """The end-of-``reproduce`` summary for the terminal: per problem and design, false alarms, missed detections,
    delay, isolation and the claims reproduced (from each problem's ``metrics.json``)."""
    header = ["problem", "design", "false alarms", "missed detection", "delay (s)", "isolation", "claims reproduced"]
    rows = []
    for doc in _documents(reports, names):
        v = doc.get("verdict") or {}
        claims = f"{v['reproduced']}/{v['claims']}" if v.get("claims") else "—"
        for k, r in enumerate(doc.get("summary", [])):
            rows.append([doc["problem"] if k == 0 else "", r["design"], _summary_false_alarms(r), fmt(r["missed_detection_rate"]),
                         fmt(r["detection_delay_mean_s"]), fmt(r["isolation_accuracy"]), claims if k == 0 else ""])
    widths = [max(len(str(c)) for c in col) for col in zip(header, *rows, strict=False)]
    lines = ["  ".join(str(c).ljust(w) if i < 2 else str(c).rjust(w) for i, (c, w) in enumerate(zip(row, widths, strict=False))) for row in [header, *rows]]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


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

