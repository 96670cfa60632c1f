"""The HTML report of a problem: certificates, export checks, metrics, figures.

``write_report`` writes ``reports/<problem>/index.html`` with PNG figures next
to it and the gain files under ``gains/``. Problems add their own sections
(figures in the spirit of the paper) through ``Problem.report``.

Figures are Matplotlib ``Figure`` objects made by :func:`subplots`, not by
``pyplot``: they belong to no window, and saving one as PNG uses Matplotlib's
Agg renderer whatever backend is selected, so importing this module or
writing a report never changes the user's backend (and needs no display).
"""

from __future__ import annotations

import html
import platform
import re
import sys
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np
from fdisyn.codegen.library import CFLAGS
from fdisyn.models.problem import Problem
from fdisyn.runtime.gainfile import write_gain_file
from fdisyn.synthesis.registry import recovery_samples
from matplotlib.figure import Figure

__all__ = ["Claim", "ReportContext", "write_report", "subplots", "table", "fmt", "label"]

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;max-width:1150px;margin:2em auto;padding:0 1em;color:#1b1b1b;line-height:1.45}
h1{font-size:1.6em}h2{border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:2em}h3{margin-top:1.5em}
table{border-collapse:collapse;margin:.8em 0;font-size:.88em}th,td{border:1px solid #d0d0d0;padding:.25em .5em;text-align:right;vertical-align:top}
th{background:#f3f3f3}td.l,th.l{text-align:left}.ok{color:#176b2c}.bad{color:#b00020;font-weight:bold}
figure{margin:1em 0}figcaption{font-size:.88em;color:#444}code{background:#f4f4f4;padding:0 .2em}
.small{font-size:.85em;color:#555}
"""


def fmt(x: Any, digits: int = 4) -> str:
    """A number for a table: ``—`` for None, compact otherwise."""
    if x is None:
        return "—"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, (int, np.integer)):
        return str(int(x))
    v = float(x)
    if v == 0.0:
        return "0"
    if abs(v) >= 1e4 or abs(v) < 1e-3:
        return f"{v:.{digits - 1}e}"
    return f"{v:.{digits}g}"


def label(problem: Problem | None, name: str) -> str:
    """What a reader sees for an internal name: :attr:`Problem.labels` ``[name]``, else the name itself."""
    labels = getattr(problem, "labels", None) or {}
    return str(labels.get(name, name))


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


def table(header: Sequence[str], rows: Iterable[Sequence[Any]], *, left: int = 1) -> str:
    """An HTML table; the first ``left`` columns are left-aligned text."""
    h = "".join(f'<th class="l">{html.escape(c)}</th>' if i < left else f"<th>{html.escape(c)}</th>" for i, c in enumerate(header))
    body = []
    for row in rows:
        cells = []
        for i, c in enumerate(row):
            text = c if isinstance(c, str) and c.startswith("<") else html.escape(c if isinstance(c, str) else fmt(c))
            cells.append(f'<td class="l">{text}</td>' if i < left else f"<td>{text}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return f"<table><thead><tr>{h}</tr></thead><tbody>{''.join(body)}</tbody></table>"


def subplots(nrows: int = 1, ncols: int = 1, *, figsize: tuple[float, float], **kw: Any) -> tuple[Figure, Any]:
    """A figure and its axes, as ``pyplot.subplots`` makes them, without ``pyplot`` (module docstring).

    ``kw`` goes to ``Figure.subplots`` (``sharex``, ``gridspec_kw``, …).
    """
    fig = Figure(figsize=figsize)
    return fig, fig.subplots(nrows, ncols, **kw)


@dataclass
class ReportContext:
    """What a problem's report hook gets: the results and :meth:`figure`, which saves a figure next to the page."""

    problem: Problem
    variants: Sequence[Any]
    directory: Path
    figures: list[str] = field(default_factory=list)

    def figure(self, name: str, fig: Figure, caption: str) -> str:
        """Save ``fig`` as ``<name>.png`` next to the page; return its HTML."""
        path = self.directory / f"{name}.png"
        fig.savefig(path, dpi=110, bbox_inches="tight")
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


def _certificate_table(gf: Any) -> str:
    """One row per check, one value column per generator (banks repeat their checks)."""
    linear = gf.kind == "linear"
    certs = gf.certificate["generators"] if linear else [gf.certificate[gf.kind]]
    names: list[str] = []
    for c in certs:
        for chk in c["checks"]:
            if chk["name"] not in names:
                names.append(chk["name"])
    rows = []
    for name in names:
        found = [next((k for k in c["checks"] if k["name"] == name), None) for c in certs]
        first = next(k for k in found if k is not None)
        ok = all(k is None or k["passed"] for k in found)
        rows.append(
            [
                name,
                *(fmt(k["value"], 3) if k is not None else "—" for k in found),
                f"{_REL[first['relation']]} {fmt(first['bound'], 3)}",
                f'<span class="{"ok" if ok else "bad"}">{"pass" if ok else "FAIL"}</span>',
                first["reason"],
            ]
        )
    head = ["check", *((g.name for g in gf.generators) if linear else [gf.design]), "bound", "", "reason for the bound"]
    return table(head, rows, left=1).replace("<td>" + "reason", "<td class=\"l\">reason")


def _designs_section(variant: Any) -> str:
    if any(b.gain_file.kind != "linear" for b in variant.built.values()):
        return _other_designs_section(variant)
    out = []
    rows = []
    for d, b in variant.built.items():
        gf = b.gain_file
        n_checks = sum(len(c["checks"]) for c in gf.certificate["generators"]) + len(gf.certificate["bank"]["checks"])
        info0 = gf.certificate["generators"][0].get("info", {}) if gf.certificate["generators"] else {}
        rows.append(
            [
                d,
                gf.name,
                len(gf.generators),
                ", ".join(str(e.dof) for e in gf.evaluators),
                fmt(gf.evaluators[0].threshold, 6),
                fmt(float(np.trace(gf.evaluators[0].Sigma_r)), 4),
                fmt(info0.get("spectral_radius_F"), 4),
                recovery_samples(gf),
                f"{n_checks}/{n_checks}",
            ]
        )
    out.append(
        table(
            ["design", "gain file name", "generators", "dof", "threshold J_th", "trace Σ_r (gen. 0)", "ρ(F) (gen. 0)", "recovery samples", "checks passed"],
            rows,
            left=2,
        )
    )
    for d, b in variant.built.items():
        gf = b.gain_file
        out.append(f"<h4>{html.escape(d)}: certificate</h4>")
        out.append(_certificate_table(gf))
        bank = gf.certificate["bank"]
        mdb = bank.get("info", {}).get("min_detectable_bias", {})
        if mdb:
            sensors = sorted({s for row in mdb.values() for s in row})
            out.append(
                '<p class="small">Smallest constant sensor bias that crosses the threshold on its own at steady state '
                + ("(<code>sqrt(J_th / gᵀWg)</code>" if all(e.window == 1 for e in gf.evaluators) else "(<code>sqrt(J_th / (N gᵀWg))</code>, N the WSSR window")
                + ", sensor units). \"not used\": the generator does not read that sensor; \"∞ (steady state)\": it reads "
                "it, but a constant bias on it has no steady-state effect on the residual (e.g. a bias that looks like a "
                "constant unknown input, which the generator decouples): only the bias's onset transient shows.</p>"
            )
            cells = [[g, *(_bias_cell(row, s) for s in sensors)] for g, row in mdb.items()]
            out.append(table(["generator", *sensors], cells))
    return "".join(out)


def _bias_cell(row: dict[str, float | None], sensor: str) -> str:
    """A cell of the smallest-detectable-bias table: the bias, "not used" (no key), "∞ (steady state)" (``None``)."""
    if sensor not in row:
        return "not used"
    value = row[sensor]
    return "∞ (steady state)" if value is None else fmt(value)


def _other_designs_section(variant: Any) -> str:
    out = []
    for d, b in variant.built.items():
        gf = b.gain_file
        st = gf.step
        out.append(
            f"<h4>{html.escape(d)} ({html.escape(gf.kind)}, gain file {html.escape(gf.name)})</h4>"
            f'<p class="small">{st.nu} inputs, {st.ny} outputs, {st.nr} residual components, {st.nj} statistics, '
            f"a state vector of {st.nstate} numbers; faults: {html.escape(', '.join(gf.faults))}.</p>"
        )
        out.append(_certificate_table(gf))
    return "".join(out)


def _export_section(variant: Any) -> str:
    rows = []
    for d, chk in variant.exports.items():
        for ref, v in chk.references.items():
            rows.append([d, ref, chk.samples, chk.nonfinite_samples, v["r"], v["J"], v["state"], "equal" if v["decisions_equal"] else "DIFFER"])
    flags = " ".join(CFLAGS)
    return (
        f"<p>Each design's step was generated by CasADi, compiled with <code>{html.escape(flags)}</code>, loaded with ctypes and "
        "compared with the CasADi function and (linear diagnosers) the independent NumPy reference built from the gain file alone. "
        "Normwise relative differences over the check trace (with injected NaN/±inf samples):</p>"
        + table(["design", "reference", "samples", "non-finite", "r", "J", "state", "alarm/isolated/status"], rows, left=2)
    )


def _metrics_section(variant: Any) -> str:
    ev = variant.evaluation
    designs = list(ev.metrics)
    scen = list(next(iter(ev.metrics.values())))
    out = [f'<p class="small">{ev.runs} runs per scenario, seeds {ev.seed0}–{ev.seed0 + ev.runs - 1}; every design sees the same runs.</p>']
    rows = []
    for s in scen:
        for d in designs:
            m = ev.metrics[d][s]
            rows.append(
                [
                    s,
                    d,
                    m.fault or "none",
                    m.false_alarm_rate,
                    m.false_alarm_runs,
                    m.missed_detection_rate,
                    m.missed_alarm_fraction,
                    m.detection_delay_mean_s,
                    m.detection_delay_max_s,
                    m.isolation_accuracy,
                    m.first_isolation_accuracy,
                    m.sample_isolation_accuracy,
                ]
            )
    out.append(
        table(
            [
                "scenario",
                "design",
                "fault",
                "false-alarm rate",
                "runs with false alarm",
                "missed detection",
                "missed-alarm fraction",
                "delay mean (s)",
                "delay max (s)",
                "isolation acc.",
                "first-decision acc.",
                "sample isolation acc.",
            ],
            rows,
            left=3,
        )
    )
    out.append(
        "<p class=\"small\">Definitions: false-alarm rate per fault-free sample (excluding each design's recovery window after a fault); "
        "missed detection = runs without any alarm while the fault is active; delay from onset to the first alarm; "
        "isolation accuracy = runs whose most frequent isolated fault during the fault is the true one.</p>"
    )
    out.append(_budget_table([(variant, d) for d in designs], scen))
    extra_keys = sorted({k for d in designs for s in scen for k in ev.metrics[d][s].extra})
    if extra_keys:
        rows = [[s, d, *(ev.metrics[d][s].extra.get(k) for k in extra_keys)] for s in scen for d in designs]
        out.append("<h4>Problem-specific figures</h4>" + table(["scenario", "design", *extra_keys], rows, left=2))
    if any(variant.built[d].gain_file.kind != "linear" for d in designs):
        return "".join(out)
    rows = []
    for d in designs:
        m = ev.metrics[d][scen[0]]
        gf = variant.built[d].gain_file
        for j, rate in enumerate(m.statistic_exceedance):
            lo, hi = m.statistic_exceedance_interval[j]
            inside = lo <= rate <= hi
            rows.append(
                [
                    d,
                    gf.step.statistic_names[j],
                    gf.evaluators[j].P_f,
                    rate,
                    f"[{fmt(lo)}, {fmt(hi)}]",
                    f'<span class="{"ok" if inside else "bad"}">{"inside" if inside else "outside"}</span>',
                ]
            )
    out.append(
        f"<h4>χ² law on fault-free data ({html.escape(scen[0])})</h4>"
        "<p class=\"small\">Exceedance rate of each statistic against its design false-alarm probability, with the two-sided "
        "99.9 % binomial interval for independent samples. White residuals (minimum-variance designs) give independent samples; "
        "coloured residuals cluster their exceedances, which widens the real spread beyond this interval.</p>"
        + table(["design", "statistic", "P_f", "observed", "binomial 99.9 %", ""], rows, left=2)
    )
    return "".join(out)


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
            axes[1].set_yticks(range(-1, len(gf.faults)), ["none", *gf.faults])
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
                    f"{dname}, scenario {sname} ({ctx.problem.scenarios[sname].description or 'no description'}): run 0 "
                    "through the generated C — statistics over their thresholds, the isolated fault"
                    + (", the parameter estimates against the truth." if est else "."),
                )
            )
    return [("Figures", "".join(body))] if body else []


def _mtbfa(m: Any) -> str:
    """The measured mean time between false alarms with its 95 % interval: "120 [80, 190]", "> 400" for none seen."""
    lo, hi = m.mean_time_between_false_alarms_interval_s
    if m.mean_time_between_false_alarms_s is None:
        return f"none seen (> {fmt(lo)})"
    return f"{fmt(m.mean_time_between_false_alarms_s)} [{fmt(lo)}, {fmt(hi)}]"


def _ratio(m: Any) -> str:
    """Mean delay over the Lorden bound, with a class when it meets the goal (≤ 1.2); "—" when the bound is
    under one sample (a fault so large that any detector needs the onset sample: the ratio says nothing)."""
    if m.delay_bound_ratio is None or m.lorden_bound_samples is None or m.lorden_bound_samples < 1.0:
        return "—"
    if m.delay_bound_ratio < 0.5:  # faster than the bound allows: the fault is no persistent mean shift
        return "no mean shift"
    ok = m.delay_bound_ratio <= 1.2
    return f'<span class="{"ok" if ok else "bad"}">{m.delay_bound_ratio:.2f}</span>'


def _variant_name(v: Any) -> str:
    """A compared variant by its label without the budget all of them share: "CUSUM", "paper parameter set, GLR"."""
    return re.sub(r" at arl0 = [^,]*$", "", str(v.label))


def _budget_table(pairs: Sequence[tuple[Any, str]], scen: Sequence[str], *, label: bool = False) -> str:
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
            head = [s, _variant_name(v), d] if label else [s, d]
            rows.append(
                [
                    *head, _mtbfa(m), m.arl0_budget_s, m.missed_detection_rate, m.detection_delay_mean_s, bound_s, _ratio(m),
                    m.isolation_accuracy, m.false_isolation_rate,
                ]
            )
    if not rows:
        return ""
    header = ["scenario", *(["detector"] if label else []), "design", "time between false alarms (s) [95 %]", "budget (s)",
              "missed detection", "delay mean (s)", "Lorden bound (s)", "delay / bound", "isolation acc.", "false isolation"]
    if {v.built[d].gain_file.kind for v, d in pairs} == {"nafdf"}:
        return "<h4>False-alarm budget and the Lorden bound</h4>" + _NAFDF_BUDGET_TEXT + table(header, rows, left=3 if label else 2)
    return (
        "<h4>False-alarm budget and the Lorden bound</h4>"
        '<p class="small">Time between false alarms: fault-free time over the number of false-alarm episodes, with Garwood\'s '
        "exact 95 % Poisson interval; budget: the design's arl0, or Ts/Σ P_f for a design by P_f. A bank splits its budget "
        "equally over its statistics (Bonferroni), so it is met or exceeded. Lorden bound: ln(ARL)/I, the smallest over the "
        "statistics of ln of each one's share of the budget (in samples) over the Kullback–Leibler information per sample the "
        "fault brought to its generator's residual (measured mean shift, long-run covariance; Lorden, Annals of Mathematical "
        "Statistics 42(6), 1971): no detector with that budget is faster on average for a persistent change. The ratio is "
        "shown where the bound is at least one sample; the goal is ≤ 1.2. \"No mean shift\": detected more than twice "
        "as fast as the bound allows, so the fault is not the persistent mean change the bound is for (a gain fault on a "
        "varying signal, whose residual effect averages out). Isolation is the bank's alarm pattern (the "
        "signature table) over the statistics' held alarms; false isolation: runs whose most frequent decision names "
        "another fault.</p>"
        + table(header, rows, left=3 if label else 2)
    )


_NAFDF_BUDGET_TEXT = (
    '<p class="small">Time between false alarms: fault-free time over the number of alarm episodes, with Garwood\'s exact '
    "95 % Poisson interval; budget: the design's arl0, or Ts·(1/P_f + 2·N2) for a design by P_f — the detector's run "
    "length plus the 2·N2 samples a false alarm's episode lasts before its dismissal. The WSSR's per-sample P_f ignores "
    "that its exceedances come in clusters, so its budget is met many times over. Lorden bound: ln(ARL)/I (Lorden, Annals "
    "of Mathematical Statistics 42(6), 1971), ARL = 1/P_f the detector's run length in samples, I = ½ μᵀ Σ⁻¹ μ with μ the "
    "mean shift of the EKF innovation over the N2 samples after the onset (before the EKF can be re-parameterised) and Σ "
    "its fault-free covariance. A parameter jump's innovation shift builds up through the plant's dynamics over several "
    "samples, while the bound is for a mean that steps at once: a ratio above 1 measures that build-up as much as the "
    "detector. Isolation is the NAFDF's classifier (eq. (2.7)); false isolation: runs whose most frequent decision names "
    "another parameter.</p>"
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


def _detectors_section(variants: Sequence[Any]) -> str:
    """The detectors side by side at the same false-alarm budget (the variants with an ``arl0`` option)."""
    same = [v for v in variants if v.options.get("arl0") is not None]
    if len(same) < 2:
        return ""
    scen: list[str] = []
    for v in same:
        for s in next(iter(v.evaluation.metrics.values())):
            if s not in scen:
                scen.append(s)
    pairs = [(v, d) for v in same for d in v.evaluation.metrics]
    return _budget_table(pairs, scen, label=True)


def write_report(problem: Problem, variants: Sequence[Any], directory: Path) -> Path:
    """Write the problem's report page (and its figures and gain files)."""
    directory.mkdir(parents=True, exist_ok=True)
    ctx = ReportContext(problem=problem, variants=variants, directory=directory)
    parts = [
        f"<!doctype html><html><head><meta charset='utf-8'><title>fdisyn — {html.escape(problem.name)}</title><style>{_CSS}</style></head><body>",
        f"<h1>{html.escape(problem.title)}</h1>",
        f"<p>{html.escape(problem.summary)}</p>",
        f'<p class="small">Generated by <code>fdisyn report {html.escape(problem.name)}</code> on '
        f"{datetime.now(timezone.utc).strftime('%Y-%m-%d %H:%M UTC')}; {html.escape(_versions())}.</p>",
    ]
    if problem.notes:
        parts.append("<h2>Modelling choices</h2><ul>" + "".join(f"<li>{html.escape(n)}</li>" for n in problem.notes) + "</ul>")
    if problem.claims is not None:
        claims = list(problem.claims(ctx))
        parts.append(
            "<h2>The paper's claims against ours</h2>"
            + table(
                ["claim", "paper", "fdisyn", "verdict", "why"],
                [[c.claim, c.paper, c.ours, c.verdict, c.why] for c in claims],
                left=5,
            )
        )
    sections = problem.report(ctx) if problem.report is not None else _run_figures(ctx)
    for title, body in sections:
        parts.append(f"<h2>{html.escape(title)}</h2>{body}")
    compared = _detectors_section(variants)
    if compared:
        nafdf = {b.gain_file.kind for v in variants for b in v.built.values()} == {"nafdf"}
        what = (
            "The NAFDF's fast detection on the EKF innovations: the WSSR (Zhou, Xi & Zhang c. 1991, eq. (2.4)), and CUSUM "
            "(Page, Biometrika 41(1/2), 1954) and windowed GLR (Willsky & Jones, IEEE Transactions on Automatic Control "
            "21(1), 1976) on the normalised innovations, the rest of the filter unchanged"
            if nafdf
            else f"{_compared_detectors(variants)} statistics of the same generators"
        )
        parts.append(
            f"<h2>Detectors at one false-alarm budget</h2><p>{what}, each designed for the same mean time between false "
            "alarms arl0.</p>" + compared
        )
    gains_dir = directory / "gains"
    for v in variants:
        label = "" if v.label == "default" else f" — {v.label}"
        opts = ", ".join(f"{k} = {val!r}" for k, val in v.options.items())
        parts.append(f"<h2>Designs and certificates{html.escape(label)}</h2>")
        if opts:
            parts.append(f'<p class="small">Problem options: {html.escape(opts)}.</p>')
        parts.append(_designs_section(v))
        parts.append(f"<h2>Generated C{html.escape(label)}</h2>{_export_section(v)}")
        parts.append(f"<h2>Monte Carlo metrics{html.escape(label)}</h2>{_metrics_section(v)}")
        for b in v.built.values():
            write_gain_file(b.gain_file, gains_dir / f"{b.gain_file.name}.json")
    parts.append(
        '<p class="small">Gain files of every design are in <a href="gains/">gains/</a>; the numbers of this page in '
        '<a href="metrics.json">metrics.json</a>.</p></body></html>'
    )
    page = directory / "index.html"
    page.write_text("\n".join(parts), encoding="utf-8")
    return page


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

