"""The options of the method ``beard_fdf``: plant-file ``[design]`` keys and keywords of ``fdisyn.design``."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from fdisyn.runtime.errors import ArgumentError
from fdisyn.runtime.schema import MAX_MAGNITUDE, SCALAR_STEP_LIMITS
from fdisyn.runtime.names import shown
from fdisyn.synthesis.linear_diagnoser import TS
from fdisyn.synthesis.registry import ARL0, DEFAULT_ARL0, P_F, PERSISTENCE, WINDOW, Option, at, is_count, is_real

__all__ = ["BEARD_OPTIONS", "MAX_DRAWS", "MAX_NOISE_GAIN", "MAX_WINDOW"]

MAX_WINDOW = SCALAR_STEP_LIMITS["nstate"] - 9
"""Largest window whatever the plant: the state holds ``N·p + n + 5`` entries and the gain file allows
``N·p + n + 8 ≤ SCALAR_STEP_LIMITS["nstate"]`` (one state, one output); the design checks ``⌊(nstate − 8 − n)/p⌋`` for its plant."""

MAX_NOISE_GAIN = 1e6
"""Largest ``noise_gain``: the optimised filter's noise bound ``noise_gain² ×`` the plain one's residual variance
enters the NLP as a constraint; beyond a millionfold it bounds nothing and only spoils the NLP's scaling."""

MAX_DRAWS = 10_000
"""Most random model errors drawn to check the implicit bound: each costs a matrix exponential and an
eigendecomposition of the plant's ``A`` (tens of milliseconds for a few states), so 10 000 draws take minutes."""


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


def _level(v: Any) -> bool:
    """A positive number the gain file can hold (at most :data:`~fdisyn.runtime.schema.MAX_MAGNITUDE`)."""
    return is_real(v) and 0 < v <= MAX_MAGNITUDE


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
           "the free eigenstructure: 'optimised' (the NLP minimising the implicit cone half-angles, never worse than "
           "'plain': it keeps the plain one and says so when it finds nothing better) or 'plain' (every eigenvalue at "
           "the decay bound, spread below it where a block cannot take it more than once)", "'optimised' or 'plain'", lambda v: v in ("optimised", "plain")),
    Option("sigma", 0.0, "model-error bound ‖δA‖₂ ≤ sigma on the plant's A (the implicit thresholds)", "a number ≥ 0",
           lambda v: is_real(v) and v >= 0),
    Option("rho", None, "a fixed ratio ‖m‖/ε̄ at which the cones are taken (X_th = asin(1/rho)); default: monitored online",
           f"a number > 1, at most {MAX_MAGNITUDE:g}", lambda v: is_real(v) and 1 < v <= MAX_MAGNITUDE),
    Option("explicit_level", None, "ε̄: bound on the fault-free window-mean residual norm; default: its 1 − P_f quantile "
           "from fault_free records or from the law under the design noise", f"a positive number, at most {MAX_MAGNITUDE:g}", _level),
    Option("h", None, "magnitude threshold on the window RMS of the residual; default: its 1 − P_f quantile (as explicit_level)",
           f"a positive number, at most {MAX_MAGNITUDE:g}", _level),
    replace(WINDOW, default=20, doc="window N (samples) of the RMS and the mean of the residual",
            expected=f"a whole number of samples in 1..{MAX_WINDOW} (at most (2040 − states) / outputs: the state limit)",
            accepts=lambda v: is_count(v) and v <= MAX_WINDOW),
    replace(P_F, doc="false-alarm probability per sample of the magnitude test, and the quantile of the explicit level, "
            "given instead of arl0 (the per-sample choice; default: none, the budget is arl0)"),
    replace(ARL0, doc="the filter's mean time between false alarms (s): the magnitude test's rate Ts/arl0 per sample, "
            "and the quantile of the explicit level (read where h or explicit_level is left to the design; default: "
            f"{DEFAULT_ARL0:g} s, one hour, unless P_f is given; give one of arl0 and P_f)",
            expected="a positive number of seconds, more than Ts"),
    PERSISTENCE,
    Option("noise_gain", 2.0, "the optimised filter's residual RMS under the design noise at most noise_gain × the plain one's",
           f"a number in [1, {MAX_NOISE_GAIN:g}]", lambda v: is_real(v) and 1 <= v <= MAX_NOISE_GAIN),
    Option("separation", 0.02, "the optimised eigenvalues are real and at least this far apart (z-plane; at most (noise_gain − 1)(1 − "
           "e^(−decay_rate·Ts)) / the detection spaces' dimension); the plain ones this far apart where spread", "a number in (0, 1)",
           lambda v: is_real(v) and 0 < v < 1),
    Option("sensor_faults", (), "outputs whose sensor faults the filter also isolates (each a plane of residual directions)",
           "a list of output names", lambda v: isinstance(v, (list, tuple)) and all(isinstance(s, str) for s in v),
           refine=_sensor_faults),
    Option("fault_free", None, "fault-free records [(U, Y), …] to estimate h and explicit_level from (Python API)",
           "a non-empty list of (U, Y) array pairs", lambda v: isinstance(v, (list, tuple)) and len(v) > 0),
    Option("draws", 200, "random model errors drawn to check the implicit bound", f"a whole number in 0..{MAX_DRAWS}",
           lambda v: isinstance(v, int) and not isinstance(v, bool) and 0 <= v <= MAX_DRAWS),
)
