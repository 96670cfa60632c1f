"""Beard's fault detection filter with the robust decision cones as a design method of the registry.

Beard (MIT thesis, 1971) and Massoumnia (IEEE Transactions on Automatic Control 31(9), 1986) for the
filter, He, Zhang & Wu (Journal of Astronautics, c. 1999) for the decision: the residual of fault ``i``
lies in a cone around its output subspace whose half-angle is the implicit threshold ``Y_th,i`` (model
error) plus the explicit one ``X = asin(ε̄/‖m‖)`` (noise).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from fdisyn.runtime.errors import ArgumentError
from fdisyn.runtime.gainfile import GainFile
from fdisyn.synthesis.beard_fdf.options import BEARD_OPTIONS
from fdisyn.synthesis.beard_fdf.payload import beard_from_gain_file
from fdisyn.synthesis.beard_fdf.step import beard_step_function
from fdisyn.synthesis.registry import Method, at, register

__all__ = ["BEARD_OPTIONS", "BEARD_FDF", "beard_budget_seconds", "beard_recovery_samples"]


SETTLED = 1e-3
"""The error dynamics have settled when ``‖G^j‖₂ ≤ SETTLED`` (the start's error reduced a thousandfold)."""
_MAX_SETTLING = 10**6


def _design(plant: Any, *, name: str, problem: str | None = None, record: Mapping[str, object] | None = None, where: str = "", **options: Any) -> GainFile:
    from fdisyn.synthesis.beard_fdf.design import design_beard_fdf

    return design_beard_fdf(plant, name=name, problem=problem, record=record, where=where, **options)


def _check(plant: Any, options: Mapping[str, Any], where: str) -> None:
    """Options that would be read for nothing: ``fault_free`` records only estimate ``h`` and ``explicit_level``."""
    if options.get("fault_free") is not None and options.get("h") is not None and options.get("explicit_level") is not None:
        raise ArgumentError(
            f"{at(where, 'fault_free')}: the records only estimate h and explicit_level, and both are given; "
            "remove fault_free, or leave out h or explicit_level to estimate it from the records"
        )


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


BEARD_FDF = register(
    Method(
        name="beard_fdf",
        plant_kind="linear",
        summary="Beard fault detection filter: fault-specific output directions, RMS detection and robust decision cones",
        reference="He, Zhang & Wu, Journal of Astronautics, c. 1999; Beard 1971; Massoumnia, IEEE TAC 31(9), 1986",
        options=BEARD_OPTIONS,
        design=_design,
        diagnoser_kind="beard_fdf",
        step_builder=beard_step_function,
        recovery_samples=beard_recovery_samples,
        false_alarm_budget=beard_budget_seconds,
        check=_check,
        samples_itself=True,
    )
)
