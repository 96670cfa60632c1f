"""The fault isolation example of Varga's book: exact and approximate synthesis by the nullspace method.

Varga, *Solving Fault Diagnosis Problems: Linear Synthesis Techniques*, Springer 2017, Examples 5.6 and 5.11 (the
same plant; equation and example numbers below are his), checked against his FaultDetectionTools.jl, whose example
``Ex5_11.jl`` tests ``fdif2ngap(R, S)[1] ≈ [3, Inf]``. The plant, in transfer functions,

    G_u = [(s+1)/(s+2); (s+2)/(s+3)],   G_w = [1/(s+2); 0],   G_f = [(s+1)/(s+2) 0; 0 1],

realised as ``ẋ = diag(−2, −3) x + [1; 1] u + Fx f₁ + w``, ``y = −x + [1; 1] u + Df f₁`` with ``Fx = [1; 0]``,
``Df = [1; 0]`` (Varga's first fault acts on the first sensor with the input's dynamics: a state and a direct part)
and the noise ``w`` of unit intensity on the first state. His second fault is the second sensor's own fault. fdisyn
gives every sensor a fault, so the faults here are ``[y1, y2, f1]``: Varga's structure matrix ``S = I₂`` over
``(f1, y2)`` is the pair of rows ``[1 0 1]`` (sees y1 and f1, decoupled from y2) and ``[0 1 0]`` (sees y2 only) —
the first sensor's fault is seen with f1 by every residual that sees f1, as the analysis finds.

A sensor without noise gives a residual of zero variance, for which no threshold exists: the deployed plant adds
sensor noise of standard deviation 0.01 to both sensors (a choice of this page; Varga's gaps are computed on his
noise alone, as published). Designs: the bank of ``S`` (``nullspace``, approximate synthesis) and the detection
filter of the row that sees every fault (``detection``), both sampled at ``Ts = 0.1 s`` (exact ZOH).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

import fdisyn
from fdisyn.models.linear import LinearPlant
from fdisyn.reporting.kit import Claim, ReportContext, fmt, table
from fdisyn.reporting.structure import bank_structure_section
from fdisyn.runtime.gainfile import GainFile
from fdisyn.simulation.problem import Batch, Problem, Scenario
from fdisyn.simulation.sample_models import SampleModel, linear_sample_model
from fdisyn.simulation.signals import SensorFaultSpec, Signal
from fdisyn.simulation.simulate import simulate_linear
from fdisyn.synthesis.gap import GeneratorPerformance, bank_performance, generator_performance
from fdisyn.synthesis.nullspace import analyse_gaps, least_order_filter, row_filter
from fdisyn.synthesis.structure import analyse_structure

__all__ = ["PROBLEM", "STRUCTURE", "TS", "VARGA_FILTERS", "VARGA_GAPS", "plant"]

TS = 0.1
"""The sample time of the designs (s)."""

SENSOR_NOISE = 0.01
"""The sensors' noise standard deviation of the deployed plant (Varga's model has none)."""

STRUCTURE = ((1, 0, 1), (0, 1, 0))
"""Varga's ``S = I₂`` over ``(f1, y2)`` in fdisyn's fault order ``[y1, y2, f1]``."""

VARGA_POLE = -3.0
"""The poles of Varga's filters (his ``sdeg = −3``)."""

VARGA_FILTERS: Mapping[tuple[int, ...], np.ndarray] = {
    (1, 0, 1): np.array([[2.0, 0.0, -1.0], [1.0, 0.0, -1.0]]),
    (0, 1, 0): np.array([[0.0, 3.0, -2.0], [0.0, 1.0, -1.0]]),
}
"""The numerators of Varga's ``Q[1] = [(s+2)/(s+3) 0 −(s+1)/(s+3)]`` and ``Q[2] = [0 1 −(s+2)/(s+3)]`` (Example 5.11)
over ``[y1, y2, u]``, by powers of ``s`` (rows: s⁰, s¹); their denominator is ``s + 3``."""

VARGA_GAPS: Mapping[tuple[int, ...], float] = {(1, 0, 1): 3.0, (0, 1, 0): math.inf}
"""The gaps of Varga's filters (FaultDetectionTools.jl, ``Ex5_11.jl``: ``fdif2ngap(R, S)[1] ≈ [3, Inf]``)."""

DURATION = 40.0
ONSET = 20.0


def plant(*, sensor_noise: float = SENSOR_NOISE) -> LinearPlant:
    """Varga's plant (module docstring), continuous, with the sensors' noise ``sensor_noise`` (0: Varga's model).

    Parameters
    ----------
    sensor_noise : float
        The sensors' noise standard deviation.

    Returns
    -------
    LinearPlant
        The continuous plant; its faults are ``[y1, y2, f1]``.
    """
    return LinearPlant.create(
        A=np.diag([-2.0, -3.0]), B=[[1.0], [1.0]], C=[[-1.0, 0.0], [0.0, -1.0]], D=[[1.0], [1.0]],
        Fx=[[1.0], [0.0]], Df=[[1.0], [0.0]], Q=np.diag([1.0, 0.0]), R=sensor_noise**2 * np.eye(2),
        states=["x1", "x2"], inputs=["u"], outputs=["y1", "y2"], component_faults=["f1"],
    )


PUBLISHED = plant(sensor_noise=0.0)
DEPLOYED = plant()
DISCRETE = DEPLOYED.discretise(TS)


def _design(structure: Sequence[Sequence[int]] | None, name: str, **options: Any) -> GainFile:
    opts = {"arl0": 3600.0, **{k: v for k, v in options.items() if v is not None}}
    # the faults are persistent: their gains at 0 rad/s against the noise choose each filter (and must not vanish)
    return fdisyn.design(DEPLOYED, method="nullspace", structure=None if structure is None else [list(r) for r in structure], Ts=TS,
                         frequencies=[0.0], name=f"varga_example_{name}", problem="varga_example", **opts)


DESIGNS = {
    "nullspace": lambda **o: _design(STRUCTURE, "nullspace", **o),
    "detection": lambda **o: _design(None, "detection", **o),
}

_INPUT = [Signal(kind="sine", amplitude=1.0, period=5.0)]
X0 = np.array([0.4, -0.3])
"""The plant is moving when the diagnoser starts."""

SCENARIOS = {
    "fault_free": Scenario("fault_free", "u a sine of amplitude 1 and period 5 s, the plant's noise, no fault.", DURATION),
    "f1_step": Scenario("f1_step", f"Varga's first fault f1 a step of 12 at {ONSET:g} s (it enters x1 and y1; its residual settles "
                        "at 6.6 of its standard deviations).", DURATION, fault="y1|f1",
                        onset=ONSET, params={"component_faults": [("f1", 12.0)], "sensor_faults": []}),
    "y2_bias": Scenario("y2_bias", f"Varga's second fault: a bias of 0.15 on y2 (15 σ of its noise; its residual settles at 7.5 of its "
                        f"standard deviations) from {ONSET:g} s.", DURATION, fault="y2",
                        onset=ONSET, params={"sensor_faults": [SensorFaultSpec("y2", "offset", 0.15)], "component_faults": []}),
    "y1_bias": Scenario("y1_bias", f"A bias of 6 on y1 from {ONSET:g} s (its residual settles at 6.6 σ): fdisyn's fault of the first "
                        "sensor, which no residual tells from f1.",
                        DURATION, fault="y1|f1", onset=ONSET, params={"sensor_faults": [SensorFaultSpec("y1", "offset", 6.0)], "component_faults": []}),
}


def _simulate(sc: Scenario, seeds: Sequence[int], draws: np.ndarray | None = None, **_options: object) -> Batch:
    """Exact samples of the plant (continuous noise sampled by Van Loan, the input and fault held)."""
    return simulate_linear(DISCRETE, sc, seeds, x0=X0, inputs=_INPUT, unknown_inputs=[], draws=draws)


def _sample_model(**_options: object) -> SampleModel:
    """:func:`_simulate` one sample at a time, for the compiled Monte Carlo."""
    return linear_sample_model(DISCRETE, x0=X0, inputs=_INPUT, unknown_inputs=[])


def _continuous_filter(row: Sequence[int], synthesis: str = "approximate") -> tuple[np.ndarray, GeneratorPerformance]:
    """The row's least-order filter of the published plant with Varga's pole, and its performance (continuous)."""
    v, _ = row_filter(PUBLISHED, list(row), pole=VARGA_POLE, synthesis=synthesis)
    gen = least_order_filter(PUBLISHED, row, pole=VARGA_POLE, synthesis=synthesis)
    return v, generator_performance(gen, PUBLISHED, frequencies=[0.0])


def _scaled_like(v: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """``v`` scaled so that its entry where ``ref`` is largest equals that entry of ``ref``."""
    at = np.unravel_index(int(np.argmax(np.abs(ref))), ref.shape)
    return v * (ref[at] / v[at])


def _poly(v: np.ndarray) -> str:
    """``[y1 y2 u]`` numerators as polynomials in s."""
    def one(c: np.ndarray) -> str:
        c = np.round(np.where(np.abs(c) < 1e-9, 0.0, c), 9)
        if not np.any(c):
            return "0"
        terms = []
        if c[1]:
            terms.append(("" if abs(c[1]) == 1 else fmt(abs(c[1]))) + "s")
        if c[0]:
            terms.append(fmt(abs(c[0])))
        body = " + ".join(terms) if np.sign(c[1] or c[0]) == np.sign(c[0] or c[1]) else " − ".join(terms)
        return ("−" if (c[1] or c[0]) < 0 else "") + (f"({body})" if len(terms) > 1 else body)
    return "[" + ", ".join(one(v[:, i]) for i in range(v.shape[1])) + "]/(s + 3)"


def _gap(x: float) -> str:
    return "∞" if math.isinf(x) else fmt(x)


def _claims(ctx: ReportContext) -> list[Claim]:
    """Varga 2017, Example 5.11: the achievable structure, the least-order filters, their gaps; and the bank."""
    rows = {tuple(int(x) for x in r) for r in fdisyn.structure_matrices(PUBLISHED)}
    out = [Claim(
        "S = I₂ over (f1, y2) is achievable by two scalar residuals (Varga 2017, Example 5.11)",
        "achievable",
        f"rows over [y1, y2, f1]: {sorted(rows, reverse=True)}; S is [1 0 1], [0 1 0]",
        "reproduced" if set(STRUCTURE) <= rows else "differs",
        "",
    )]
    for i, row in enumerate(STRUCTURE, start=1):
        v, perf = _continuous_filter(row)
        same = bool(np.allclose(_scaled_like(v, VARGA_FILTERS[row]), VARGA_FILTERS[row], atol=1e-9))
        out.append(Claim(
            f"The least-order filter Q[{i}] of row {list(row)} over [y1, y2, u], its pole at −3 (Varga 2017, Example 5.11)",
            _poly(VARGA_FILTERS[row]),
            _poly(_scaled_like(v, VARGA_FILTERS[row])),
            "reproduced" if same else "differs",
            "",
        ))
        want = VARGA_GAPS[row]
        ok = math.isinf(perf.gap) if math.isinf(want) else abs(perf.gap - want) <= 1e-9 * want
        out.append(Claim(
            f"The fault-to-noise gap of Q[{i}], ‖R_f‖∞₋/‖R_w‖∞ (FaultDetectionTools.jl Ex5_11.jl: fdif2ngap(R, S) ≈ [3, Inf])",
            _gap(want),
            _gap(perf.gap),
            "reproduced" if ok else "differs",
            "",
        ))
    v = ctx.variants[0]
    built = v.built.get("nullspace")
    if built is not None:
        achieved = bank_performance(built.gain_file.generators, DISCRETE, frequencies=[0.0])
        got = [list(p.weak) for p in achieved]
        strong = [list(p.strong or ()) for p in achieved]
        orders = [g.n_state for g in built.gain_file.generators]
        ok = got == [list(r) for r in STRUCTURE] and strong == got and orders == [1, 1]
        out.append(Claim(
            "The bank designed for S has S as its weak and strong (at 0 rad/s) structure, each filter of the least order",
            "S, orders 1 and 1",
            f"weak {got}, strong {strong}, orders {orders}",
            "reproduced" if ok else "differs",
            "",
        ))
        m = v.evaluation.metrics.get("nullspace", {})
        for scen, cls in (("f1_step", "y1|f1"), ("y2_bias", "y2")):
            mm = m.get(scen)
            if mm is None or mm.missed_detection_rate is None:
                continue
            iso = mm.isolation_accuracy or 0.0
            good = mm.missed_detection_rate == 0.0 and iso >= 0.95
            out.append(Claim(
                f"The bank detects and isolates {cls} in simulation ({scen}; not in the book, which designs only)",
                "detected, isolated",
                f"runs missed {fmt(100 * mm.missed_detection_rate)} %, isolated in {fmt(100 * iso)} %, delay mean "
                f"{fmt(mm.detection_delay_mean_s)} s",
                "reproduced" if good else "differs",
                "" if good else "some runs miss the fault or name another class",
            ))
    return out


def _report(ctx: ReportContext) -> list[tuple[str, str]]:
    """The analysis (continuous, Varga's noise and pole; discrete, the deployed plant and the designs' pole) and the
    designed banks' structure, orders and gaps."""
    cont = analyse_gaps(analyse_structure(PUBLISHED), PUBLISHED, pole=VARGA_POLE)
    disc = analyse_gaps(analyse_structure(DISCRETE), DISCRETE, pole=0.5)
    dgaps = {tuple(int(x) for x in r): g for r, g in zip(disc.rows, disc.gaps or (), strict=True)}
    rows = [[*(str(int(x)) for x in r), lo, _gap(g), _gap(dgaps.get(tuple(int(x) for x in r), math.nan)), ", ".join(dec) or "—"]
            for r, lo, g, dec in zip(cont.rows, cont.least_orders, cont.gaps or (), cont.decoupled, strict=True)]
    analysis = table([*cont.faults, "least order", "gap, continuous, pole −3, Varga's noise", f"gap, sampled at {fmt(TS)} s, pole 0.5, sensor noise", "decouples"], rows, left=0)
    sections = [("The achievable specifications and their gaps", (
        '<p class="small">Every row of a structure matrix a scalar residual decoupled from u can have (1: it sees the '
        "fault), the least order of its filter, and the fault-to-noise gap of the least-order filter of the largest "
        "gap: min over the faults it sees of ‖R_fj‖∞ over ‖R_w‖∞ (Varga's H∞₋ index over the noise's H∞ norm). A "
        "gap depends on the filter's denominator and on the noise: the continuous one is Varga's (his pole −3, his "
        "noise only), the sampled one the deployed plant's (sensor noise added, so the row seeing y2 alone has a "
        "finite gap).</p>" + analysis))]
    sections.append(bank_structure_section(ctx, DISCRETE, intro=(
        f"The designs on the plant sampled at {fmt(TS)} s with its sensor noise. The H₋ index is zero here whenever a "
        "residual sees two faults (one output cannot separate two inputs at every frequency).")))
    return sections


LABELS: Mapping[str, str] = {
    "u": "input u (–)",
    "y1": "output y1 (–)",
    "y2": "output y2 (–)",
    "x1": "state x1 (–)",
    "x2": "state x2 (–)",
    "f1": "Varga's fault f1 (on x1 and y1)",
    "nullspace": "nullspace bank of S = I₂ over (f1, y2) (approximate synthesis)",
    "detection": "nullspace detection filter (every fault)",
}
"""Readable names of the signals, faults and designs the page shows (Varga's plant has no units)."""

NOTES = (
    "Varga's model is continuous; fdisyn designs on its exact sampling at Ts = 0.1 s (ZOH input and fault, the noise "
    "of unit intensity sampled by Van Loan). The continuous filters and gaps of the claims are computed on the "
    "continuous plant itself (the polynomial null vectors of its pencil over (s + 3)); H∞ norms of continuous "
    "filters through the bilinear map, which keeps them.",
    "fdisyn gives every sensor a fault: y1's fault is seen with f1 by every residual that sees f1 (f1 enters y1 "
    "through (s+1)/(s+2), y1's fault directly; decoupling one from the other leaves only y2), so the designs' fault "
    "classes are 'y1|f1' and 'y2'.",
    "Sensor noise of σ = 0.01 on both sensors is this page's addition: without it the residual that sees only y2 "
    "has zero variance and no threshold; Varga's gap ∞ for that row is of his model.",
    "The faults are persistent: each filter is designed with the strong structure at 0 rad/s (every fault it sees "
    "shows at DC, certified) and its null-vector combination and pole chosen for the gap at 0 rad/s (Varga's gap with "
    "freq = 0); its pole from 0, 0.1, …, 0.9.",
    "Budget: one false alarm per hour of the whole bank (arl0 = 3600 s); the plant starts away from rest "
    "(x0 = [0.4, −0.3]), the input is a sine of amplitude 1 and period 5 s.",
)


def _model(**_options: object) -> LinearPlant:
    """The deployed continuous plant (its frequency responses and poles on the page)."""
    return DEPLOYED


PROBLEM = Problem(
    name="varga_example",
    title="Fault isolation by the nullspace method: Varga's Example 5.11",
    summary=(
        "Which faults two sensors can tell apart, least-order residual filters for a structure matrix, and their "
        "fault-to-noise gaps (Varga, Solving Fault Diagnosis Problems, Springer 2017, Examples 5.6 and 5.11), checked "
        "against the book and FaultDetectionTools.jl, then sampled, thresholded, compiled and run."
    ),
    designs=DESIGNS,
    default_design="nullspace",
    scenarios=SCENARIOS,
    simulate=_simulate,
    sample_model=_sample_model,
    options={"arl0": None, "P_f": None},
    monte_carlo_runs=100,
    report=_report,
    claims=_claims,
    labels=LABELS,
    model=_model,
    notes=NOTES,
)
