"""The input-signal kinds and sensor-fault kinds of a simulation, each described once.

A kind has two evaluations side by side: the NumPy one the Python simulators
use (a whole run at a time) and the CasADi one the sample models use (one
sample at a time, :mod:`fdisyn.simulation.sample_models`, compiled into the C
Monte Carlo). Both are the same operations in the same order, so the Python
and the compiled simulation of a run agree on the same draws:

- a deterministic signal (``constant``, ``step``, ``sine``, ``square``) is one
  expression of the sample time written against an operation table
  (:data:`NUMPY_OPS`, :data:`CASADI_OPS`) and evaluated on an array of times
  and on a CasADi symbol;
- a random signal (``prbs``, ``gauss_markov``) reads one standard normal per
  sample and keeps one number between samples: the NumPy side draws the whole
  run, the CasADi side gives the sample and its next memory;
- a sensor fault corrupts a measurement while the fault is active: NumPy in
  place on the runs' measurements (:func:`apply_sensor_faults`), CasADi as one
  affine map ``y ↦ (stuck ? value : gain·y) + offset + drift·(t − onset)``
  into which a scenario's faults are composed in order
  (:func:`sensor_fault_map`, :func:`faulty_measurement_sx`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import casadi as ca
import numpy as np
import scipy.signal
from fdisyn.runtime.errors import ArgumentError

__all__ = [
    "CASADI_OPS",
    "NUMPY_OPS",
    "SENSOR_FAULT_KINDS",
    "SENSOR_FAULT_TABLE",
    "SIGNAL_KINDS",
    "SIGNAL_TABLE",
    "SensorFaultKind",
    "SensorFaultSpec",
    "Signal",
    "SignalKind",
    "apply_sensor_faults",
    "faulty_measurement_sx",
    "gauss_markov",
    "sensor_fault_map",
    "signal_sx",
]

NUMPY_OPS = SimpleNamespace(full=lambda t, v: np.full(t.shape, v), sin=np.sin, floor=np.floor, mod=np.mod, where=np.where)
"""The operations of a deterministic signal's expression on an array of sample times."""
CASADI_OPS = SimpleNamespace(full=lambda t, v: ca.SX(v), sin=ca.sin, floor=ca.floor, mod=ca.fmod, where=ca.if_else)
"""The same operations on a CasADi symbol (``mod``: C's ``fmod``, equal to NumPy's for the times ``t ≥ 0``)."""


# ----------------------------------------------------------------------------- input signals


@dataclass(frozen=True)
class SignalKind:
    """One input-signal kind: its NumPy evaluation over a run and its CasADi evaluation of one sample.

    Attributes
    ----------
    name : str
        The kind's name in a :class:`Signal` and a plant file.
    periodic : bool
        Whether it reads ``period`` (which must then be positive).
    random : bool
        Whether it reads one standard normal per sample and keeps one number of memory between samples.
    numpy : callable
        ``numpy(sig, t, rng, Ts, z)``: the signal over the sample times ``t`` (``z``: the run's standard normals,
        else drawn from ``rng``).
    casadi : callable
        ``casadi(sig, t, k, Ts, z, memory)``: the sample at time ``t`` (sample ``k``) and the next memory (``None``
        for a deterministic kind).
    """

    name: str
    periodic: bool
    random: bool
    numpy: Callable[..., np.ndarray]
    casadi: Callable[..., tuple[Any, Any]]


def _deterministic(name: str, expression: Callable[[Signal, Any, SimpleNamespace], Any], *, periodic: bool) -> SignalKind:
    """A kind given by one expression of ``(sig, t, ops)``, evaluated with :data:`NUMPY_OPS` and :data:`CASADI_OPS`."""
    return SignalKind(
        name=name,
        periodic=periodic,
        random=False,
        numpy=lambda sig, t, rng, ts, z: expression(sig, t, NUMPY_OPS),
        casadi=lambda sig, t, k, ts, z, memory: (expression(sig, t, CASADI_OPS), None),
    )


def _square(sig: Signal, t: Any, ops: SimpleNamespace) -> Any:
    # half-periods counted on the sample grid, so a period of whole samples splits exactly
    half = ops.floor(2.0 * t / sig.period + 1e-9)
    return sig.offset + sig.amplitude * ops.where(ops.mod(half, 2) == 0, 1.0, -1.0)


def _prbs_hold(sig: Signal, ts: float) -> int:
    """Samples a prbs level is held: ``period`` on the sample grid, at least one."""
    return max(1, int(round(sig.period / ts)))


def _prbs_numpy(sig: Signal, t: np.ndarray, rng: np.random.Generator, ts: float, z: np.ndarray | None) -> np.ndarray:
    hold = _prbs_hold(sig, ts)
    levels = rng.choice([-1.0, 1.0], size=len(t) // hold + 1) if z is None else np.where(z[::hold] >= 0, 1.0, -1.0)
    return sig.offset + sig.amplitude * np.repeat(levels, hold)[: len(t)]


def _prbs_casadi(sig: Signal, t: ca.SX, k: ca.SX, ts: float, z: ca.SX, memory: ca.SX) -> tuple[ca.SX, ca.SX]:
    hold = _prbs_hold(sig, ts)
    level = ca.if_else(ca.fmod(k, hold) == 0, ca.if_else(z >= 0, 1.0, -1.0), memory)
    return sig.offset + sig.amplitude * level, level


def _gauss_markov_pole(sig: Signal, ts: float) -> float:
    """``a = e^{−Ts/period}``: the pole of the Gauss–Markov sequence."""
    return float(np.exp(-ts / sig.period))


def _gauss_markov_numpy(sig: Signal, t: np.ndarray, rng: np.random.Generator, ts: float, z: np.ndarray | None) -> np.ndarray:
    return sig.offset + sig.amplitude * gauss_markov(rng, len(t), _gauss_markov_pole(sig, ts), z)


def _gauss_markov_casadi(sig: Signal, t: ca.SX, k: ca.SX, ts: float, z: ca.SX, memory: ca.SX) -> tuple[ca.SX, ca.SX]:
    a = _gauss_markov_pole(sig, ts)
    s = float(np.sqrt(1.0 - a * a))
    zeta = ca.if_else(k == 0, z, s * z + a * memory)
    return sig.offset + sig.amplitude * zeta, zeta


SIGNAL_TABLE: dict[str, SignalKind] = {
    kind.name: kind
    for kind in (
        _deterministic("constant", lambda sig, t, ops: ops.full(t, sig.offset), periodic=False),
        _deterministic("step", lambda sig, t, ops: sig.offset + sig.amplitude * (t >= sig.start), periodic=False),
        _deterministic("sine", lambda sig, t, ops: sig.offset + sig.amplitude * ops.sin(2 * np.pi * t / sig.period), periodic=True),
        _deterministic("square", _square, periodic=True),
        SignalKind("prbs", periodic=True, random=True, numpy=_prbs_numpy, casadi=_prbs_casadi),
        SignalKind("gauss_markov", periodic=True, random=True, numpy=_gauss_markov_numpy, casadi=_gauss_markov_casadi),
    )
}
"""Every input-signal kind by name."""
SIGNAL_KINDS = tuple(SIGNAL_TABLE)
"""The input-signal kinds' names."""


def gauss_markov(rng: np.random.Generator, n: int, a: float, z: np.ndarray | None = None) -> np.ndarray:
    """A unit-variance first-order Gauss–Markov sequence ``ζ⁺ = a ζ + √(1−a²) ε``, started stationary.

    Parameters
    ----------
    rng : numpy.random.Generator
        Draws ``ε`` when ``z`` is not given.
    n : int
        Samples.
    a : float
        The pole, ``0 ≤ a < 1``.
    z : numpy.ndarray, optional
        The ``n`` standard normals ``ε``.

    Returns
    -------
    numpy.ndarray
        The ``n`` samples.
    """
    eps = rng.standard_normal(n) if z is None else np.array(z, dtype=float)
    eps[1:] *= np.sqrt(1.0 - a * a)
    return scipy.signal.lfilter([1.0], [1.0, -a], eps)


@dataclass(frozen=True)
class Signal:
    """A known or unknown input signal of a TOML problem.

    ``constant``: ``offset``; ``step``: ``offset`` + ``amplitude`` from ``start``;
    ``sine``: ``offset + amplitude·sin(2πt/period)``; ``square``: ``offset +
    amplitude`` for the first half of each period, ``offset − amplitude`` for
    the second (from ``t = 0``); ``prbs``: ``offset ±
    amplitude`` switching at random multiples of ``period`` (per run);
    ``gauss_markov``: ``offset + amplitude·ζ`` with correlation time ``period``.
    """

    kind: str = "constant"
    offset: float = 0.0
    amplitude: float = 0.0
    period: float = 1.0
    start: float = 0.0

    KINDS = SIGNAL_KINDS

    def __post_init__(self) -> None:
        if self.kind not in self.KINDS:
            raise ArgumentError(f"signal kind {self.kind!r} is not one of {self.KINDS}")
        if SIGNAL_TABLE[self.kind].periodic and not self.period > 0:
            raise ArgumentError(f"a {self.kind} signal needs a positive period, got {self.period}")

    @property
    def random(self) -> bool:
        """Whether the signal reads one standard normal per sample (``prbs``, ``gauss_markov``)."""
        return SIGNAL_TABLE[self.kind].random

    def sample(self, t: np.ndarray, rng: np.random.Generator, Ts: float, z: np.ndarray | None = None) -> np.ndarray:
        """The signal on the sample times ``t``.

        Parameters
        ----------
        t : numpy.ndarray
            The sample times ``k·Ts``.
        rng : numpy.random.Generator
            Draws a random signal's standard normals unless ``z`` is given.
        Ts : float
            The sample time.
        z : numpy.ndarray, optional
            A random signal's standard normals, one per sample (a ``prbs`` level is the sign of the draw at each
            switching instant).

        Returns
        -------
        numpy.ndarray
            One value per sample time.
        """
        return SIGNAL_TABLE[self.kind].numpy(self, t, rng, Ts, z)


def signal_sx(sig: Signal, t: ca.SX, k: ca.SX, Ts: float, z: ca.SX | None, memory: ca.SX | None) -> tuple[ca.SX, ca.SX | None]:
    """One sample of ``sig`` as a CasADi expression (:meth:`Signal.sample` with given draws).

    Parameters
    ----------
    sig : Signal
        The signal; its numbers must be finite.
    t, k : casadi.SX
        The sample's time ``k·Ts`` and index ``k``.
    Ts : float
        The sample time.
    z, memory : casadi.SX or None
        A random signal's standard normal of this sample and its memory from the previous one (``None`` for a
        deterministic signal).

    Returns
    -------
    tuple
        The sample and the next memory (``None`` for a deterministic signal).

    Raises
    ------
    ArgumentError
        A number of the signal is not finite, or a random signal is given no draw or memory.
    """
    numbers = np.asarray([sig.offset, sig.amplitude, sig.period, sig.start], dtype=float)
    if not np.all(np.isfinite(numbers)):
        raise ArgumentError(f"the numbers of a {sig.kind} signal must be finite to be compiled; got {numbers.tolist()}")
    kind = SIGNAL_TABLE[sig.kind]
    if kind.random and (z is None or memory is None):
        raise ArgumentError(f"a {sig.kind} signal reads one draw and one number of memory per sample; none was given")
    return kind.casadi(sig, t, k, Ts, z, memory)


# ----------------------------------------------------------------------------- sensor faults


@dataclass(frozen=True)
class SensorFaultKind:
    """One sensor-fault kind: its NumPy corruption of a measurement and its composition into the affine map.

    Attributes
    ----------
    name : str
        The kind's name in a :class:`SensorFaultSpec` and a plant file.
    apply : callable
        ``apply(y, j, value, since_onset)``: corrupts column ``j`` of the runs' measurements ``y`` in place.
    compose : callable
        ``compose((stuck, value, gain, offset, drift), v)``: the map of :func:`faulty_measurement_sx` after this
        fault of size ``v`` follows the faults already in it.
    """

    name: str
    apply: Callable[[np.ndarray, int, float, float], None]
    compose: Callable[[tuple[Any, ...], float], tuple[Any, ...]]


def _stuck_apply(y: np.ndarray, j: int, value: float, since: float) -> None:
    y[:, j] = value


def _gain_apply(y: np.ndarray, j: int, value: float, since: float) -> None:
    y[:, j] *= value


def _offset_apply(y: np.ndarray, j: int, value: float, since: float) -> None:
    y[:, j] += value


def _drift_apply(y: np.ndarray, j: int, value: float, since: float) -> None:
    y[:, j] += value * since


SENSOR_FAULT_TABLE: dict[str, SensorFaultKind] = {
    kind.name: kind
    for kind in (
        SensorFaultKind("stuck", _stuck_apply, lambda m, v: (1.0, v, 1.0, 0.0, 0.0)),
        SensorFaultKind("gain", _gain_apply, lambda m, v: (m[0], m[1] * v, m[2] * v, m[3] * v, m[4] * v)),
        SensorFaultKind("offset", _offset_apply, lambda m, v: (m[0], m[1], m[2], m[3] + v, m[4])),
        SensorFaultKind("drift", _drift_apply, lambda m, v: (m[0], m[1], m[2], m[3], m[4] + v)),
    )
}
"""Every sensor-fault kind by name."""
SENSOR_FAULT_KINDS = tuple(SENSOR_FAULT_TABLE)
"""The sensor-fault kinds' names."""

IDENTITY_MAP = (0.0, 0.0, 1.0, 0.0, 0.0)
"""``(stuck, value, gain, offset, drift)`` of a sound sensor: ``y ↦ y``."""


@dataclass(frozen=True)
class SensorFaultSpec:
    """How a fault corrupts one sensor while active.

    ``stuck``: the sensor reads ``value``; ``gain``: it reads ``value`` times
    its measurement; ``offset``: ``value`` is added; ``drift``: ``value`` per
    second is added, growing from the onset.
    """

    sensor: str
    kind: str
    value: float

    def __post_init__(self) -> None:
        if self.kind not in SENSOR_FAULT_KINDS:
            raise ArgumentError(f"sensor fault kind {self.kind!r} is not one of {SENSOR_FAULT_KINDS}")


def _sensor_index(f: SensorFaultSpec, outputs: Sequence[str]) -> int:
    if f.sensor not in outputs:
        raise ArgumentError(f"sensor fault on {f.sensor!r}: no such output; outputs are {list(outputs)}")
    return list(outputs).index(f.sensor)


def apply_sensor_faults(
    y: np.ndarray, outputs: Sequence[str], faults: Sequence[SensorFaultSpec], *, since_onset: float = 0.0
) -> None:
    """Corrupt the measurements in place, the faults in order.

    Parameters
    ----------
    y : numpy.ndarray
        One sample's measurements, runs × outputs.
    outputs : sequence of str
        The outputs' names.
    faults : sequence of SensorFaultSpec
        The scenario's sensor faults.
    since_onset : float
        Time since the fault's onset (a drift's growth).

    Raises
    ------
    ArgumentError
        A fault names no output.
    """
    for f in faults:
        SENSOR_FAULT_TABLE[f.kind].apply(y, _sensor_index(f, outputs), f.value, since_onset)


def sensor_fault_map(faults: Sequence[SensorFaultSpec], outputs: Sequence[str], size: Callable[[SensorFaultSpec], float]) -> np.ndarray:
    """The faults composed in order into one affine map per output, the parameters of :func:`faulty_measurement_sx`.

    Parameters
    ----------
    faults : sequence of SensorFaultSpec
        The scenario's sensor faults.
    outputs : sequence of str
        The outputs' names.
    size : callable
        A fault's size as a float (e.g. checked finite).

    Returns
    -------
    numpy.ndarray
        ``5 × p``: the rows ``stuck``, ``value``, ``gain``, ``offset``, ``drift``.

    Raises
    ------
    ArgumentError
        A fault names no output.
    """
    rows = np.array([[x] * len(outputs) for x in IDENTITY_MAP], dtype=float)
    for f in faults:
        j = _sensor_index(f, outputs)
        v = size(f)
        rows[:, j] = SENSOR_FAULT_TABLE[f.kind].compose(tuple(rows[:, j]), v)
    return rows


def faulty_measurement_sx(
    y: ca.SX, stuck: ca.SX, value: ca.SX, gain: ca.SX, offset: ca.SX, drift: ca.SX, t: ca.SX, onset: ca.SX
) -> ca.SX:
    """``(stuck ? value : gain·y) + offset + drift·(t − onset)``: the faulty measurement of :func:`sensor_fault_map`'s map.

    Parameters
    ----------
    y : casadi.SX
        The sound measurements.
    stuck, value, gain, offset, drift : casadi.SX
        The map's rows, one entry per output.
    t, onset : casadi.SX
        The sample's time and the fault's onset.

    Returns
    -------
    casadi.SX
        The faulty measurements.
    """
    return ca.if_else(stuck > 0.5, value, y * gain) + offset + drift * (t - onset)
