"""The options of the method ``beard_fdf``: plant-file ``[design]`` keys and keywords of ``fdisyn.design``."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from fdisyn.runtime.errors import ArgumentError
from fdisyn.runtime.names import shown
from fdisyn.synthesis.linear_diagnoser import TS
from fdisyn.synthesis.registry import P_F, PERSISTENCE, WINDOW, Option, at, is_real

__all__ = ["BEARD_OPTIONS"]


def _number(v: Any) -> bool:
    return is_real(v) or (isinstance(v, (list, tuple)) and len(v) == 2 and all(is_real(x) for x in v))


def _eigenvalues(value: Any, where: str, plant: Any) -> Any:
    """Lists of numbers (complex ones as ``[re, im]``) to lists of complex numbers."""
    return [[complex(z[0], z[1]) if isinstance(z, (list, tuple)) else complex(z) for z in block] for block in value]


def _sensor_faults(value: Any, where: str, plant: Any) -> Any:
    if plant is not None:
        bad = [s for s in value if s not in plant.outputs]
        if bad:
            raise ArgumentError(f"{at(where, 'sensor_faults')}: {shown(bad)} are not outputs; expected names from {list(plant.outputs)}")
    if len(set(value)) != len(value):
        raise ArgumentError(f"{at(where, 'sensor_faults')}: {shown(value)} names a sensor twice")
    return tuple(value)


def _positive_or_none(v: Any) -> bool:
    return is_real(v) and v > 0


BEARD_OPTIONS: tuple[Option, ...] = (
    TS,
    Option("decay_rate", None, "every eigenvalue of A − L C inside |z| ≤ e^(−decay_rate·Ts) (1/s); needed unless eigenvalues are given",
           "a positive number (1/s)", _positive_or_none),
    Option("eigenvalues", None,
           "eigenvalues of A − L C: one list per fault's detection space, then the rest (s-plane for a continuous plant, "
           "z-plane for a discrete one; complex ones as [re, im])",
           "a list of lists of numbers or [re, im] pairs",
           lambda v: isinstance(v, (list, tuple)) and all(isinstance(b, (list, tuple)) and all(_number(z) for z in b) for b in v),
           refine=_eigenvalues),
    Option("eigenstructure", "optimised",
           "the free eigenstructure: 'optimised' (the NLP minimising the implicit cone half-angles) or 'plain' (every "
           "eigenvalue at the decay bound)", "'optimised' or 'plain'", lambda v: v in ("optimised", "plain")),
    Option("sigma", 0.0, "model-error bound ‖δA‖₂ ≤ sigma on the plant's A (the implicit thresholds)", "a number ≥ 0",
           lambda v: is_real(v) and v >= 0),
    Option("rho", None, "a fixed ratio ‖m‖/ε̄ at which the cones are taken (X_th = asin(1/rho)); default: monitored online",
           "a number > 1", lambda v: is_real(v) and v > 1),
    Option("explicit_level", None, "ε̄: bound on the fault-free window-mean residual norm; default: its 1 − P_f quantile "
           "from fault_free records or from the law under the design noise", "a positive number", _positive_or_none),
    Option("h", None, "magnitude threshold on the window RMS of the residual; default: its 1 − P_f quantile (as explicit_level)",
           "a positive number", _positive_or_none),
    replace(WINDOW, default=20, doc="window N (samples) of the RMS and the mean of the residual"),
    replace(P_F, doc="false-alarm probability per sample of the magnitude test, and the quantile of the explicit level"),
    PERSISTENCE,
    Option("noise_gain", 2.0, "the optimised filter's residual RMS under the design noise at most noise_gain × the plain one's",
           "a number ≥ 1", lambda v: is_real(v) and v >= 1),
    Option("separation", 0.02, "the optimised eigenvalues are real and at least this far apart (z-plane)", "a number in (0, 1)",
           lambda v: is_real(v) and 0 < v < 1),
    Option("sensor_faults", (), "outputs whose sensor faults the filter also isolates (each a plane of residual directions)",
           "a list of output names", lambda v: isinstance(v, (list, tuple)) and all(isinstance(s, str) for s in v),
           refine=_sensor_faults),
    Option("fault_free", None, "fault-free records [(U, Y), …] to estimate h and explicit_level from (Python API)",
           "a list of (U, Y) array pairs", lambda v: isinstance(v, (list, tuple))),
    Option("draws", 200, "random model errors drawn to check the implicit bound", "a whole number ≥ 0",
           lambda v: isinstance(v, int) and not isinstance(v, bool) and v >= 0),
)
