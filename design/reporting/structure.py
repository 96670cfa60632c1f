"""The structure and the fault-to-noise gaps of a page's banks of linear generators, side by side.

Each generator of each design on the design model: its order, the faults it sees (its weak row, Varga's ``fditspec``)
and at 0 rad/s (its strong row, ``fdisspec``), Varga's gap ``min_j ‖R_fj‖∞ / ‖R_w‖∞`` (``fdif2ngap``) and the H∞₋
index and noise norm it is the ratio of, and fdisyn's H₋ index ``inf_ω σ_min(R_f)`` over the faults it sees, all
computed from the gain file's matrices and the model (:mod:`fdisyn.synthesis.gap`). It is the same for any method's
bank, so a nullspace bank and an observer bank of the same signatures compare on one table.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from fdisyn.reporting.kit import ReportContext, fmt, label, table
from fdisyn.synthesis.gap import bank_performance

__all__ = ["bank_structure_section"]


def _gap(x: float) -> str:
    return "∞" if math.isinf(x) else fmt(x)


def bank_structure_section(ctx: ReportContext, plant: Any, *, designs: Sequence[str] | None = None, intro: str = "") -> tuple[str, str]:
    """The section ``("The banks' structure and gaps", html)`` of a page.

    Parameters
    ----------
    ctx : ReportContext
        The page's context; its first variant's built designs are tabled.
    plant : LinearPlant
        The discrete model the designs were made for (its fault order: the sensors, then the component faults).
    designs : sequence of str, optional
        The designs to table, in this order (default: every built design with linear generators).
    intro : str
        A sentence (HTML) put before the table's standard explanation.

    Returns
    -------
    tuple of str
        The section's title and body.
    """
    v = ctx.variants[0]
    names = [d for d in (designs or list(v.built)) if d in v.built and v.built[d].gain_file.generators]
    faults = list(plant.outputs) + list(plant.component_faults)
    rows = []
    for d in names:
        gf = v.built[d].gain_file
        for g, p in zip(gf.generators, bank_performance(gf.generators, plant, frequencies=[0.0]), strict=True):
            seen = ", ".join(f for f, s in zip(faults, p.weak, strict=True) if s) or "—"
            lost = ", ".join(f for f, s, w in zip(faults, p.strong or (), p.weak, strict=True) if w and not s)
            at0 = "—" if p.gap_at is None else _gap(p.gap_at)
            rows.append([label(ctx.problem, d), g.name, g.n_state, seen, lost or "—", _gap(p.gap), at0, fmt(p.hinf_minus), fmt(p.noise_norm), fmt(p.hminus)])
    body = (
        f'<p class="small">{intro + " " if intro else ""}Each generator on the design model, from its gain file\'s '
        "matrices: its order, the faults it sees (its weak row; Varga's fditspec), those among them with no response at "
        "0 rad/s (not in its strong row; fdisspec), its fault-to-noise gap — Varga's H∞₋ index, the smallest H∞ norm "
        "over the faults it sees, over the H∞ norm from the plant's noise (fdif2ngap), and the same with the faults' "
        "least gain at 0 rad/s in place of their H∞ norm (fdif2ngap with freq = 0: what a persistent fault meets) — "
        "and fdisyn's H₋ index, the "
        "smallest singular value of its fault response over frequency: a different quantity, zero whenever a residual "
        "has fewer components than the faults it sees.</p>"
        + table(["design", "generator", "order", "sees", "not at 0 rad/s", "gap", "gap at 0 rad/s", "H∞₋ index", "‖R_w‖∞", "H₋ index"], rows, left=5)
    )
    return "The banks' structure and gaps", body
