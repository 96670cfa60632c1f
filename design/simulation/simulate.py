"""Simulation building blocks shared by the problems.

Linear plants are simulated exactly in discrete time (the ZOH model the design
uses), vectorised over Monte Carlo runs; each run draws its noise from its own
seeded generator, so run ``i`` is the same whatever batch it is part of.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.signal
from fdisyn.models.linear import LinearPlant
from fdisyn.simulation.problem import Batch, Scenario
from fdisyn.numerics.linalg import psd_factor
from fdisyn.runtime.errors import ArgumentError, ShapeError

__all__ = ["SensorFaultSpec", "apply_sensor_faults", "gauss_markov", "Signal", "simulate_linear"]

SENSOR_FAULT_KINDS = ("stuck", "gain", "offset", "drift")


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


def apply_sensor_faults(
    y: np.ndarray, outputs: Sequence[str], faults: Sequence[SensorFaultSpec], *, since_onset: float = 0.0
) -> None:
    """Corrupt the measurements ``y`` (runs × outputs) in place."""
    for f in faults:
        if f.sensor not in outputs:
            raise ArgumentError(f"sensor fault on {f.sensor!r}: no such output; outputs are {list(outputs)}")
        j = list(outputs).index(f.sensor)
        if f.kind == "stuck":
            y[:, j] = f.value
        elif f.kind == "gain":
            y[:, j] *= f.value
        elif f.kind == "offset":
            y[:, j] += f.value
        else:
            y[:, j] += f.value * since_onset


def gauss_markov(rng: np.random.Generator, n: int, a: float, z: np.ndarray | None = None) -> np.ndarray:
    """A unit-variance first-order Gauss–Markov sequence ``ζ⁺ = a ζ + √(1−a²) ε``, started stationary
    (``ε``: ``z`` when given, else drawn from ``rng``)."""
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

    KINDS = ("constant", "step", "sine", "square", "prbs", "gauss_markov")

    def __post_init__(self) -> None:
        if self.kind not in self.KINDS:
            raise ArgumentError(f"signal kind {self.kind!r} is not one of {self.KINDS}")
        if self.kind in ("sine", "square", "prbs", "gauss_markov") and not self.period > 0:
            raise ArgumentError(f"a {self.kind} signal needs a positive period, got {self.period}")

    def sample(self, t: np.ndarray, rng: np.random.Generator, Ts: float, z: np.ndarray | None = None) -> np.ndarray:
        """The signal on ``t``; a random one draws from ``rng`` unless given its standard normals ``z``
        (one per sample; a ``prbs`` level is the sign of the draw at each switching instant)."""
        if self.kind == "constant":
            return np.full(t.shape, self.offset)
        if self.kind == "step":
            return self.offset + self.amplitude * (t >= self.start)
        if self.kind == "sine":
            return self.offset + self.amplitude * np.sin(2 * np.pi * t / self.period)
        if self.kind == "square":
            # half-periods counted on the sample grid, so a period of whole samples splits exactly
            half = np.floor(2.0 * t / self.period + 1e-9)
            return self.offset + self.amplitude * np.where(half % 2 == 0, 1.0, -1.0)
        if self.kind == "prbs":
            hold = max(1, int(round(self.period / Ts)))
            levels = rng.choice([-1.0, 1.0], size=len(t) // hold + 1) if z is None else np.where(z[::hold] >= 0, 1.0, -1.0)
            return self.offset + self.amplitude * np.repeat(levels, hold)[: len(t)]
        return self.offset + self.amplitude * gauss_markov(rng, len(t), float(np.exp(-Ts / self.period)), z)


def simulate_linear(
    plant: LinearPlant,
    scenario: Scenario,
    seeds: Sequence[int],
    *,
    x0: np.ndarray,
    inputs: Sequence[Signal],
    unknown_inputs: Sequence[Signal],
    feedback: Callable[[np.ndarray, int], np.ndarray] | None = None,
    draws: np.ndarray | None = None,
) -> Batch:
    """Exact discrete simulation of ``plant`` over ``scenario``, vectorised over seeds.

    ``x⁺ = A x + B u + E d + w``, ``y = C x + D u + v`` with ``w ~ N(0, Q)``,
    ``v ~ N(0, R)`` (the design's covariances), the scenario's sensor faults
    applied to ``y`` and its component faults (steps through ``Fx``) to the
    state. ``u`` comes from ``inputs`` or, when ``feedback`` is
    given, from ``feedback(y_k, k)`` (runs × nu) computed on the (possibly
    faulty) measurements — a controller closing the loop; it needs ``D = 0``.

    ``draws`` (runs × N × nz) replaces the generators' standard normals, laid
    out per sample as ``[w (rank Q), v (rank R), one per prbs or gauss_markov
    signal, inputs first]``: the draws of the compiled simulation
    (:func:`fdisyn.evaluation.compiled_simulation.linear_sample_model`), to
    compare the two on the same noise.
    """
    if not plant.is_discrete:
        raise ArgumentError("simulate_linear needs the discrete plant")
    ts = float(plant.Ts)  # type: ignore[arg-type]
    n = int(round(scenario.duration / ts))
    t = np.arange(n) * ts
    runs = len(seeds)
    a, b, c, d, e = (np.asarray(getattr(plant, k)) for k in ("A", "B", "C", "D", "E"))
    lq, lr = psd_factor(plant.Q, "Q"), psd_factor(plant.R, "R")
    faults = [SensorFaultSpec(*f) if not isinstance(f, SensorFaultSpec) else f for f in scenario.params.get("sensor_faults", [])]
    if feedback is not None and np.any(plant.D):
        raise ArgumentError("a feedback input needs D = 0 (otherwise u and y form an algebraic loop)")
    if len(inputs) != plant.m or len(unknown_inputs) != plant.q:
        raise ShapeError(f"simulation needs {plant.m} input and {plant.q} unknown-input signals")
    w = np.empty((runs, n, plant.n))
    v = np.empty((runs, n, plant.p))
    uu = np.empty((runs, n, plant.m))
    dd = np.empty((runs, n, plant.q))
    nq, nv = lq.shape[1], lr.shape[1]
    slots = np.cumsum([nq + nv] + [s.kind in ("prbs", "gauss_markov") for s in (*inputs, *unknown_inputs)])
    if draws is not None and np.shape(draws) != (runs, n, slots[-1]):
        raise ShapeError(f"draws have shape {np.shape(draws)}; expected {(runs, n, int(slots[-1]))}")
    for i, s in enumerate(seeds):
        rng = np.random.default_rng(int(s))
        given = None if draws is None else np.asarray(draws[i], dtype=float)
        w[i] = (rng.standard_normal((n, nq)) if given is None else given[:, :nq]) @ lq.T
        v[i] = (rng.standard_normal((n, nv)) if given is None else given[:, nq : nq + nv]) @ lr.T
        for j, sig in enumerate((*inputs, *unknown_inputs)):
            z = None if given is None or slots[j + 1] == slots[j] else given[:, slots[j]]
            (uu[i, :, j] if j < len(inputs) else dd[i, :, j - len(inputs)])[:] = sig.sample(t, rng, ts, z)
    active = scenario.active(t)
    onset = scenario.onset or 0.0
    # component faults: steps of the fault inputs while active, entering through Fx (held over the sample)
    fvec = None
    for cname, value in scenario.params.get("component_faults", []):
        if cname not in plant.component_faults:
            raise ArgumentError(f"component fault {cname!r}: the plant has {list(plant.component_faults)}")
        col = np.asarray(plant.Fx)[:, plant.component_faults.index(cname)] * float(value)
        fvec = col if fvec is None else fvec + col
    x = np.tile(np.asarray(x0, dtype=float), (runs, 1))
    Y = np.empty((runs, n, plant.p))
    X = np.empty((runs, n, plant.n))
    for k in range(n):
        y = x @ c.T + v[:, k]
        if feedback is None:
            y += uu[:, k] @ d.T
        if active[k]:
            apply_sensor_faults(y, plant.outputs, faults, since_onset=t[k] - onset)
        if feedback is not None:
            uu[:, k] = feedback(y, k)
        Y[:, k] = y
        X[:, k] = x
        x = x @ a.T + uu[:, k] @ b.T + dd[:, k] @ e.T + w[:, k]
        if active[k] and fvec is not None:
            x = x + fvec
    extra = {name: X[:, :, i] for i, name in enumerate(plant.states)}
    extra.update({name: dd[:, :, j] for j, name in enumerate(plant.unknown_inputs)})
    return Batch(
        scenario=scenario,
        seeds=tuple(int(s) for s in seeds),
        t=t,
        inputs=plant.inputs,
        outputs=plant.outputs,
        U=uu,
        Y=Y,
        extra=extra,
    )
