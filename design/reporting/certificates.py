"""A design's certificate as a page shows it: every check with its bound and values, what the design can see, a
linear bank's smallest detectable biases; and the page's section listing each distinct certificate once."""

from __future__ import annotations

import html
from collections.abc import Mapping, Sequence
from typing import Any

from fdisyn.numerics.account import size_rules
from fdisyn.reporting.kit import below_margin, fmt, folded, label, table, variant_name
from fdisyn.simulation.problem import Problem
from fdisyn.synthesis.kinds import get_kind

__all__ = ["CERTIFICATE_COLUMNS", "certificates_section"]


_REL = {"<=": "≤", ">=": "≥"}


CERTIFICATE_COLUMNS = 6
"""Generators a certificate table shows side by side, one column each; a bank of more shows one row per generator."""


def _certificate_table(gf: Any, problem: Problem | None = None) -> str:
    """Every check with the reason for its bound, its bound and whether every generator passes it, and its value per
    generator (banks repeat their checks): one column per generator, or for a bank of more than
    :data:`CERTIFICATE_COLUMNS` the checks in one table and the values in another, one row per generator."""
    certs = get_kind(gf.kind).certified(gf)  # a bank's: one per generator
    owners = [label(problem, g.name) for g in gf.generators] if gf.generators else [label(problem, gf.design)]
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


def _account_html(gf: Any, problem: Problem | None = None) -> str:
    """What the design can see (the gain file's ``account`` block), folded: per fault its effect, smallest detectable
    size and the generators that see it, then the faults the bank cannot tell apart; for a kind without an account,
    why (:attr:`fdisyn.synthesis.kinds.DiagnoserKind.account_note`)."""
    acc = getattr(gf, "account", None)
    if acc is None:
        why = get_kind(gf.kind).account_note
        return f'<p class="small">What the design can see: not computed — {html.escape(why)}.</p>' if why else ""
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
        + html.escape(size_rules(acc))
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
    bank = gf.certificate.get("bank")
    mdb = bank.get("info", {}).get("min_detectable_bias", {}) if isinstance(bank, Mapping) else {}
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


def certificates_section(problem: Problem, variants: Sequence[Any]) -> str:
    """Each distinct certificate once (folded), with the designs (and variants) that share it and its checks passed."""
    owners: dict[str, list[str]] = {}
    checks: dict[str, list[bool]] = {}
    for v in variants:
        for d, b in v.built.items():
            body = _certificate_html(b.gain_file, problem)
            owners.setdefault(body, []).append(label(problem, d) if v.label == "default" else f"{label(problem, d)} ({variant_name(v)})")
            checks[body] = [bool(k["passed"]) for c in get_kind(b.gain_file.kind).certified(b.gain_file) for k in c["checks"]]
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
