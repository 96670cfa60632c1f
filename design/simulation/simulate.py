"""The linear simulator shared by the problems (its signals and sensor faults: :mod:`fdisyn.simulation.signals`).

Linear plants are simulated exactly in discrete time (the ZOH model the design
uses), vectorised over Monte Carlo runs; each run draws its noise from its own
seeded generator, so run ``i`` is the same whatever batch it is part of.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from fdisyn.models.linear import LinearPlant
from fdisyn.numerics.linalg import psd_factor
from fdisyn.runtime.errors import ArgumentError, ShapeError
from fdisyn.simulation.problem import Batch, Scenario
from fdisyn.simulation.signals import SensorFaultSpec, Signal, apply_sensor_faults

__all__ = ["simulate_linear"]


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

    ``x⁺ = A x + B u + E d + w``, ``y = C x + D u + Dd d + v`` with ``w ~ N(0, Q)``,
    ``v ~ N(0, R)`` (the design's covariances), the scenario's component faults
    (steps through ``Fx`` into the state and ``Df`` into the outputs) and then its
    sensor faults applied to ``y``. ``u`` comes from ``inputs`` or, when ``feedback`` is
    given, from ``feedback(y_k, k)`` (runs × nu) computed on the (possibly
    faulty) measurements — a controller closing the loop; it needs ``D = 0``.

    ``draws`` (runs × N × nz) replaces the generators' standard normals, laid
    out per sample as ``[w (rank Q), v (rank R), one per prbs or gauss_markov
    signal, inputs first]``: the draws of the compiled simulation
    (:func:`fdisyn.simulation.sample_models.linear_sample_model`), to
    compare the two on the same noise.
    """
    if not plant.is_discrete:
        raise ArgumentError("simulate_linear needs the discrete plant")
    ts = float(plant.Ts)  # type: ignore[arg-type]
    n = int(round(scenario.duration / ts))
    t = np.arange(n) * ts
    runs = len(seeds)
    a, b, c, d, e, d_d = (np.asarray(getattr(plant, k)) for k in ("A", "B", "C", "D", "E", "Dd"))
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
    slots = np.cumsum([nq + nv] + [s.random for s in (*inputs, *unknown_inputs)])
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
    # component faults: steps of the fault inputs while active, entering through Fx (held over the sample) and Df
    fvec, fy = None, None
    for cname, value in scenario.params.get("component_faults", []):
        if cname not in plant.component_faults:
            raise ArgumentError(f"component fault {cname!r}: the plant has {list(plant.component_faults)}")
        j = plant.component_faults.index(cname)
        col, row = np.asarray(plant.Fx)[:, j] * float(value), np.asarray(plant.Df)[:, j] * float(value)
        fvec = col if fvec is None else fvec + col
        fy = row if fy is None else fy + row
    x = np.tile(np.asarray(x0, dtype=float), (runs, 1))
    Y = np.empty((runs, n, plant.p))
    X = np.empty((runs, n, plant.n))
    for k in range(n):
        y = x @ c.T + v[:, k] + dd[:, k] @ d_d.T
        if feedback is None:
            y += uu[:, k] @ d.T
        if active[k] and fy is not None:
            y += fy
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
