"""The HTML report of a problem: verdict, metrics, figures, certificates, export checks; and the index of every page.

``write_report`` writes ``reports/<problem>/index.html`` with PNG figures next
to it, the gain files under ``gains/`` and the page's numbers in
``metrics.json``; :func:`write_index` writes ``reports/index.html``, one line
per problem. A page opens with the verdict (:attr:`Problem.claims`, the
paper's claims against ours), then a table of contents, then its sections;
long per-variant detail is folded (``<details>``). Problems add their own
sections (figures in the spirit of the paper) through ``Problem.report``,
written with :mod:`fdisyn.reporting.kit`.

The output is deterministic: no dates or durations in the files, figures saved
without their software stamp, floats in ``metrics.json`` rounded to
:data:`JSON_DIGITS` significant digits.
"""

from __future__ import annotations

import html
import json
import math
import platform
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from fdisyn.codegen.library import CFLAGS
from fdisyn.evaluation.metrics import DEFINITIONS
from fdisyn.reporting.budget import budget_table, detectors_section
from fdisyn.reporting.certificates import certificates_section
from fdisyn.reporting.figures import run_figures, standard_figures
from fdisyn.reporting.kit import (
    Claim, ReportContext, defined, false_alarm_time, false_alarms_pooled, fmt, folded, label, slug, table, variant_name,
)
from fdisyn.runtime.errors import FileError
from fdisyn.runtime.gainfile import without_clock, write_gain_file
from fdisyn.runtime.jsondata import parse_json_data
from fdisyn.simulation.problem import Problem
from fdisyn.synthesis.kinds import recovery_samples, warmup_text

__all__ = ["JSON_DIGITS", "write_report", "write_index", "summary_table", "variant_tag", "published_gain_name"]


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
.glance{overflow-x:auto}.glance td.l{white-space:nowrap}.glance td{padding:.1em .5em}
"""


JSON_DIGITS = 6
"""Significant digits of the floats in ``metrics.json``: enough for every figure the pages show, few enough that
the last-digit noise of another BLAS kernel does not change the committed file."""


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


def _design_rows(problem: Problem, variant: Any) -> str:
    """The variant's designs in one table (banks of linear generators: generators, dof, threshold, …; others: sizes)."""
    if not all(b.gain_file.generators for b in variant.built.values()):
        rows = []
        for d, b in variant.built.items():
            gf, st = b.gain_file, b.gain_file.step
            rows.append([label(problem, d), gf.kind, gf.name, st.nu, st.ny, st.nr, st.nj, st.nstate, warmup_text(gf) or "none",
                         ", ".join(label(problem, f) for f in gf.faults)])
        return table(["design", "kind", "gain file", "inputs", "outputs", "residual components", "statistics", "state size",
                      defined("warm-up (samples)", "warm-up"), "faults"], rows, left=3)
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
                warmup_text(gf),
                f"{n_checks}/{n_checks}",
            ]
        )
    return table(
        ["design", "gain file", "generators", "dof", "threshold J_th (gen. 0)", "trace Σ_r (gen. 0)", "ρ(F) (gen. 0)",
         "recovery (samples)", defined("warm-up (samples)", "warm-up"), "checks passed"],
        rows,
        left=2,
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
                rows.append([variant_name(v), label(problem, d), ref, chk.samples, chk.nonfinite_samples,
                             *(f"below {fmt(tol, 1)}" if x[k] <= tol else x[k] for k in ("r", "J", "state")),
                             "equal" if x["decisions_equal"] else "DIFFER"])
    if not rows:
        return ""
    flags = " ".join(CFLAGS)
    agree = sum(r[-1] == "equal" for r in rows)
    return (
        f"<p>Each design's step was generated by CasADi, compiled with <code>{html.escape(flags)}</code>, loaded with ctypes and "
        "compared with the CasADi function and, where the diagnoser's kind has one, its independent NumPy reference built from the "
        "gain file alone (linear diagnosers and the Beard filter; the NAFDF's step exists only as CasADi), "
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


GOOD = {"missed": 0.05, "held": 0.9, "isolated": 0.9, "false_isolation": 0.05}
"""When a faulty scenario's figures are good (green on the glance): missed in at most 5 % of the runs, the alarm
held over at least 90 % of the fault's duration, the true fault isolated over at least 90 % of it (where the
diagnoser isolates), another fault named in at most 5 % of the runs."""


def _percent(value: float | None, bad: bool) -> str | None:
    """A fraction as a percentage cell, bold red when ``bad``."""
    if value is None:
        return None
    text = f"{fmt(100.0 * value)}\u00a0%"  # a no-break space: a narrow column keeps the number with its sign
    return f'<span class="bad">{html.escape(text)}</span>' if bad else text


def glance_verdict(m: Any) -> tuple[dict[str, bool], bool]:
    """Which of a faulty scenario's glance figures fall short of :data:`GOOD`, and whether all are good.

    Parameters
    ----------
    m : ScenarioMetrics
        A faulty scenario's metrics.

    Returns
    -------
    tuple
        ``({"missed", "held", "isolated", "false_isolation"} → short of the goal), all good``; a figure that is
        not measured (no isolation) is neither.
    """
    held, iso = m.alarm_held_fraction, m.isolated_held_fraction
    bad = {
        "missed": m.missed_detection_rate is not None and m.missed_detection_rate > GOOD["missed"],
        "held": held is not None and held < GOOD["held"],
        "isolated": iso is not None and iso < GOOD["isolated"],
        "false_isolation": m.false_isolation_rate is not None and m.false_isolation_rate > GOOD["false_isolation"],
    }
    return bad, m.missed_detection_rate is not None and not any(bad.values())


def _glance_section(problem: Problem, variant: Any) -> str:
    """The main variant's detection figures: one row per faulty scenario, the designs side by side (time to first
    alarm, the fraction of the fault's duration with the alarm held and with the true fault isolated, false
    isolations), each design headed by its false alarms pooled over every scenario's fault-free samples; a design's
    figures are green only when all of them are good (:func:`glance_verdict`)."""
    ev = variant.evaluation
    designs = list(ev.metrics)
    faulty = _faulty_scenarios(variant)
    groups = []
    for d in designs:
        groups.append((f'<span>{html.escape(label(problem, d))}<br><span class="small">{defined("false alarms", "mean time between false alarms")}: '
                       f"{html.escape(false_alarms_pooled(ev.metrics[d].values()))}</span></span>", 4))
    rows = []
    for (s, _), lead in zip(faulty, _fault_cells(problem, faulty), strict=True):
        row: list[Any] = list(lead)
        for d in designs:
            m = ev.metrics[d][s]
            bad, good = glance_verdict(m)
            missed = m.missed_detection_rate
            first = "never" if missed == 1.0 else fmt(m.detection_delay_mean_s)
            if missed and missed < 1.0:
                first += f" (missed in {fmt(100.0 * missed)}\u00a0% of runs)"
            cells: list[Any] = [f'<span class="bad">{html.escape(first)}</span>' if bad["missed"] else first,
                     _percent(m.alarm_held_fraction, bad["held"]), _percent(m.isolated_held_fraction, bad["isolated"]),
                     _percent(m.false_isolation_rate, bad["false_isolation"])]
            if good:  # every figure good: the design's cells in green
                cells = [f'<span class="ok">{html.escape(c)}</span>' if isinstance(c, str) else c for c in cells]
            row += cells
        rows.append(row)
    per = [defined("first alarm (s)", "detection delay"), defined("alarm held", "alarm held"),
           defined("isolated", "isolated held"), defined("wrong fault", "false isolation")]
    return (
        f'<p class="small">{fmt(ev.runs)} runs per scenario; every design sees the same runs; false alarms over every '
        "scenario's fault-free samples. First alarm: the mean time from the fault's onset to the first alarm over the runs "
        "that detected. Alarm held and isolated: the share of the fault's duration (all runs) with the alarm on, and with "
        "the true fault named — a fault alarmed briefly and then silent is not counted as found. Wrong fault: the share "
        "of the runs whose most frequent decision names another fault. "
        f"Green: missed in at most {fmt(100 * GOOD['missed'])} % of the runs, alarm held and true fault isolated over at least "
        f"{fmt(100 * GOOD['held'])} % of the fault, another fault named in at most {fmt(100 * GOOD['false_isolation'])} % of the "
        "runs; bold red: the figure that falls short. Each scenario's false alarms and the other figures: "
        '<a href="#monte-carlo-metrics">Monte Carlo metrics</a>.</p>'
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
    out.append(budget_table(problem, [(variant, d) for d in designs], scen))
    extra_keys = sorted({k for d in designs for s in scen for k in ev.metrics[d][s].extra})
    if extra_keys:
        rows = [[label(problem, s), label(problem, d), *(ev.metrics[d][s].extra.get(k) for k in extra_keys)] for s in scen for d in designs]
        out.append("<h4>Problem-specific figures</h4>" + table(["scenario", "design", *(label(problem, k) for k in extra_keys)], rows, left=2))
    if not all(variant.built[d].gain_file.evaluators for d in designs):  # the χ² law of a bank's statistics
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
    items = "".join(f'<dt id="def-{slug(k)}">{html.escape(k)}</dt><dd>{html.escape(v)}</dd>' for k, v in DEFINITIONS.items())
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
    mean delay, isolation accuracy and the fractions of the faults' duration with the alarm held and with the true
    fault isolated (means over the faulty scenarios that have them)."""
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
                "alarm_held_fraction": mean([m.alarm_held_fraction for m in faulty]),
                "isolated_held_fraction": mean([m.isolated_held_fraction for m in faulty]),
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
        anchor, k = slug(title), 2
        while anchor in {"verdict", "contents", *(a for a, _, _ in sections)}:
            anchor, k = f"{slug(title)}-{k}", k + 1
        sections.append((anchor, title, body))

    add("Detection at a glance", _glance_section(problem, main))
    add("Isolation", _isolation_section(problem, main))
    for title, body in problem.report(ctx) if problem.report is not None else run_figures(ctx):
        add(title, body)
    for title, body in standard_figures(ctx):
        add(title, body)
    add("Detectors at one false-alarm budget", detectors_section(problem, variants))
    add("Designs", _designs_section(problem, variants))
    add("Certificates", certificates_section(problem, variants))
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
            write_gain_file(without_clock(b.gain_file), gains_dir / published_gain_name(b.gain_file.name, v.label, taken))
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


def _share(x: float | None) -> str:
    """A fraction of a fault's duration as the terminal shows it: ``97 %``, ``—`` when not measured."""
    return "—" if x is None else f"{fmt(100.0 * x)} %"


def summary_table(reports: Path, names: Sequence[str]) -> str:
    """The end-of-``reproduce`` summary for the terminal: per problem and design, false alarms, missed detections,
    delay, the share of the faults' duration with the alarm held and with the true fault isolated (means over the
    faulty scenarios), and the claims reproduced (from each problem's ``metrics.json``)."""
    header = ["problem", "design", "false alarms", "missed detection", "delay (s)", "alarm held", "isolated held", "claims reproduced"]
    rows = []
    for doc in _documents(reports, names):
        v = doc.get("verdict") or {}
        claims = f"{v['reproduced']}/{v['claims']}" if v.get("claims") else "—"
        for k, r in enumerate(doc.get("summary", [])):
            rows.append([doc["problem"] if k == 0 else "", r["design"], _summary_false_alarms(r), fmt(r["missed_detection_rate"]),
                         fmt(r["detection_delay_mean_s"]), _share(r.get("alarm_held_fraction")),
                         _share(r.get("isolated_held_fraction")), claims if k == 0 else ""])
    widths = [max(len(str(c)) for c in col) for col in zip(header, *rows, strict=False)]
    lines = ["  ".join(str(c).ljust(w) if i < 2 else str(c).rjust(w) for i, (c, w) in enumerate(zip(row, widths, strict=False))) for row in [header, *rows]]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)
