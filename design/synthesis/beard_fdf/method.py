"""Beard's fault detection filter with the robust decision cones as a design method of the registry.

Beard (MIT thesis, 1971) and Massoumnia (IEEE Transactions on Automatic Control 31(9), 1986) for the
filter, He, Zhang & Wu (Journal of Astronautics, c. 1999) for the decision: the residual of fault ``i``
lies in a cone around its output subspace whose half-angle is the implicit threshold ``Y_th,i`` (model
error) plus the explicit one ``X = asin(ε̄/‖m‖)`` (noise).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from fdisyn.runtime.errors import ArgumentError
from fdisyn.runtime.gainfile import GainFile
from fdisyn.synthesis.beard_fdf.options import BEARD_OPTIONS
from fdisyn.synthesis.registry import Method, at, register

__all__ = ["BEARD_OPTIONS", "BEARD_FDF"]


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


BEARD_FDF = register(
    Method(
        name="beard_fdf",
        plant_kind="linear",
        summary="Beard fault detection filter: fault-specific output directions, RMS detection and robust decision cones",
        reference="He, Zhang & Wu, Journal of Astronautics, c. 1999; Beard 1971; Massoumnia, IEEE TAC 31(9), 1986",
        options=BEARD_OPTIONS,
        design=_design,
        diagnoser_kind="beard_fdf",
        check=_check,
        samples_itself=True,
    )
)
