"""The ``beard_fdf`` diagnoser kind: Beard's fault detection filter with the robust decision cones read back from its
gain file (Beard, MIT thesis, 1971; He, Zhang & Wu, Journal of Astronautics, c. 1999): its step, recovery window and
false-alarm budget."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np
from fdisyn.detectors.wssr import SIZE_LAW as WSSR_SIZE_LAW
from fdisyn.numerics.account import BankView
from fdisyn.runtime.gainfile import GainFile, Generator
from fdisyn.runtime.reference import RunResult
from fdisyn.synthesis.beard_fdf.payload import beard_from_gain_file
from fdisyn.synthesis.beard_fdf.reference import beard_reference_run
from fdisyn.synthesis.beard_fdf.step import beard_step_function
from fdisyn.synthesis.kinds import DiagnoserKind, register_kind, step_states, warmup_text

__all__ = ["BEARD_KIND", "SETTLED", "settling_samples", "beard_budget_seconds", "beard_recovery_samples", "beard_account_view", "beard_kind_reference"]


SETTLED = 1e-3
"""The error dynamics have settled when ``‖G^j‖₂ ≤ SETTLED`` (the start's error reduced a thousandfold)."""
_MAX_SETTLING = 10**6


def settling_samples(G: np.ndarray, level: float = SETTLED) -> int:
    """The first ``j`` with ``‖G^j‖₂ ≤ level`` (at most :data:`_MAX_SETTLING`).

    ``‖G^j‖ ≥ ρ(G)^j``, so no ``j`` below ``log(level)/log ρ(G)`` qualifies: the search starts there and
    walks on (a non-normal ``G`` may take longer than its spectral radius says).
    """
    radius = float(np.max(np.abs(np.linalg.eigvals(G)))) if G.size else 0.0
    j = 0 if radius == 0.0 else max(0, int(np.floor(np.log(level) / np.log(radius))))
    j = min(j, _MAX_SETTLING)
    power = np.linalg.matrix_power(G, j)
    while j < _MAX_SETTLING and np.linalg.norm(power, 2) > level:
        power, j = power @ G, j + 1
    return j


def beard_recovery_samples(gf: GainFile) -> int:
    """Samples after a fault's end during which the statistics still carry it: the filter's error settles
    (:func:`settling_samples` of ``G = A − L C``), then the last faulty residual leaves the window."""
    flt = beard_from_gain_file(gf)
    return flt.window + settling_samples(flt.G)


def beard_budget_seconds(gf: GainFile) -> float | None:
    """The filter's designed mean time between false alarms (s): its ``arl0``, or ``Ts/P_f`` for a design by ``P_f``;
    None when ``h`` was given (its false-alarm rate is the user's, not the design's)."""
    payload = gf.extensions.get("beard_fdf", {})
    info = payload.get("design", {}) if isinstance(payload, Mapping) else {}
    if not isinstance(info, Mapping):
        return None
    if isinstance(info.get("arl0_s"), (int, float)):
        return float(info["arl0_s"])
    if isinstance(info.get("P_f"), (int, float)) and info["P_f"] > 0:
        return float(gf.Ts) / float(info["P_f"])
    return None


def _beard_generator(gf: GainFile) -> Generator:
    """The Beard filter as a canonical generator: ``x̂⁺ = (A − L C) x̂ + (B − L D) u + L y``, ``ε = y − C x̂ − D u``."""
    p = gf.extensions[gf.kind]
    a, b, c, d, lg = (np.asarray(p[k], dtype=float) for k in ("A", "B", "C", "D", "L"))
    return Generator.from_canonical(
        name="filter", outputs_used=range(c.shape[0]), Ar=a - lg @ c, Bu=b - lg @ d, By=lg, Cr=-c, Du=-d, Dy=np.eye(c.shape[0])
    )


class _RmsStatistic:
    """The Beard filter's window RMS as a window sum: ``Σ_{l<N} ‖ε‖² > N h²`` (``W = I``)."""

    generator = 0

    def __init__(self, window: int, h: float, nr: int) -> None:
        self.window, self.threshold, self.W, self.dof = window, window * h * h, np.eye(nr), nr


_RMS_LAW = replace(WSSR_SIZE_LAW, name="rms", rule="window RMS: P(RMS > h) = 95 % (50 %) over a window")
"""The window RMS's smallest detectable fault: the WSSR's law of its window sum ``N·RMS²`` against ``N h²``."""


def _beard_classes(gf: GainFile, entries: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """A Beard filter's classes are its component faults, told apart by the direction of the residual (each fault's
    output subspace and its decision cone): those whose cones overlap (the design's cone geometry) merge."""
    pay = gf.extensions[gf.kind]
    cones = (pay.get("design") or {}).get("cones") or {}
    angles = cones.get("axis_angles_deg") or []
    merged = []
    for i, j in cones.get("overlapping_pairs") or []:
        a, b = gf.faults[int(i)], gf.faults[int(j)]
        apart = f", output directions {float(angles[i][j]):.3g}° apart" if angles else ""
        merged.append({"faults": [a, b], "reason": f"'{a}' and '{b}': their decision cones overlap{apart}"})
    names = {e["name"] for e in entries}
    merged = [g for g in merged if all(f in names for f in g["faults"])]
    unseen = [e["name"] for e in entries if not e["seen_by"]]
    return {"groups": merged, "unseen": unseen, "decision": [{"name": f, "statistics": []} for f in gf.faults]}


def beard_account_view(gf: GainFile) -> BankView:
    """The Beard filter as the account sees it: one generator (the filter's output error), its window RMS as a
    WSSR-like statistic, the design model ``A``, ``C`` (the noise comes from the plant given), its cones' classes.

    Parameters
    ----------
    gf : GainFile
        A ``beard_fdf`` gain file.

    Returns
    -------
    BankView
    """
    pay = gf.extensions[gf.kind]
    gen = _beard_generator(gf)
    return BankView(
        generators=[gen],
        statistics=[_RmsStatistic(int(pay["window"]), float(pay["h"]), gen.n_residual)],
        statistic_names=[gf.step.statistic_names[0]],
        laws=[_RMS_LAW],
        model={k: np.asarray(pay[k], dtype=float) for k in ("A", "C")},
        persistence=int(pay.get("persistence", 1)),
        classes=_beard_classes,
        no_noise="no smallest sizes: the Beard filter's gain file holds no noise model (give its plant)",
    )


def beard_kind_reference(gf: GainFile, U: np.ndarray, Y: np.ndarray) -> RunResult:
    """A ``beard_fdf`` gain file's run over a trace by the filter's NumPy twin
    (:func:`fdisyn.synthesis.beard_fdf.reference.beard_reference_run`) on the filter its payload rebuilds.

    Parameters
    ----------
    gf : GainFile
        A ``beard_fdf`` gain file.
    U : numpy.ndarray
        Inputs, ``T × nu``.
    Y : numpy.ndarray
        Outputs, ``T × ny``.

    Returns
    -------
    RunResult
        From the filter's initial state.
    """
    return beard_reference_run(beard_from_gain_file(gf), U, Y)


def _warmups(gf: GainFile) -> tuple[int, ...]:
    """The filter's warm-up (0 in a file written before warm-ups)."""
    return (beard_from_gain_file(gf).warmup,)


def _describe(gf: GainFile) -> str:
    span = warmup_text(gf)
    return step_states(gf) + ("" if span in (None, "0") else f", a warm-up of {span} samples before its window fills")


BEARD_KIND = register_kind(
    DiagnoserKind(
        name="beard_fdf",
        summary="a Beard fault detection filter: fault-specific output directions, a window RMS and robust decision cones",
        step_builder=beard_step_function,
        recovery_samples=beard_recovery_samples,
        false_alarm_budget=beard_budget_seconds,
        account_view=beard_account_view,
        reference=beard_kind_reference,
        warmups=_warmups,
        describe=_describe,
    )
)
"""The ``beard_fdf`` kind, produced by the method ``beard_fdf`` (:mod:`fdisyn.synthesis.beard_fdf.method`)."""
