"""The ``beard_fdf`` diagnoser kind: Beard's fault detection filter with the robust decision cones read back from its
gain file (Beard, MIT thesis, 1971; He, Zhang & Wu, Journal of Astronautics, c. 1999): its step, recovery window and
false-alarm budget."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from fdisyn.runtime.gainfile import GainFile
from fdisyn.synthesis.beard_fdf.payload import beard_from_gain_file
from fdisyn.synthesis.beard_fdf.step import beard_step_function
from fdisyn.synthesis.kinds import DiagnoserKind, register_kind

__all__ = ["BEARD_KIND", "SETTLED", "settling_samples", "beard_budget_seconds", "beard_recovery_samples"]


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


def _certified(gf: GainFile) -> list[Mapping[str, Any]]:
    return [gf.certificate[gf.kind]]


def _describe(gf: GainFile) -> str:
    return f"a {gf.kind} step with {gf.step.nstate} states"


BEARD_KIND = register_kind(
    DiagnoserKind(
        name="beard_fdf",
        summary="a Beard fault detection filter: fault-specific output directions, a window RMS and robust decision cones",
        step_builder=beard_step_function,
        certified=_certified,
        describe=_describe,
        recovery_samples=beard_recovery_samples,
        false_alarm_budget=beard_budget_seconds,
    )
)
"""The ``beard_fdf`` kind, produced by the method ``beard_fdf`` (:mod:`fdisyn.synthesis.beard_fdf.method`)."""
