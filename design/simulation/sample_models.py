"""Sample models: a simulator described one sample at a time, as CasADi functions.

A problem opts in to the compiled Monte Carlo
(:mod:`fdisyn.evaluation.compiled_campaign`) with
:attr:`fdisyn.simulation.problem.Problem.sample_model`: its simulator as a
:class:`SampleModel`, a CasADi function

    ``(x, z, k, p, d) ↦ (x⁺, u, y, e)``

of the simulation's state ``x``, the sample's standard-normal draws ``z``, the
sample index ``k``, the scenario's parameters ``p`` (its fault's sizes)
and the sample's row ``d`` of the scenario's drive table (inputs and
parameters known in advance, the same for every run), giving the next state,
the known inputs, the measurements and the signals kept beside them (true
states, unknown inputs, true parameters). :func:`linear_sample_model`,
:func:`nonlinear_sample_model` and :func:`sampled_data_sample_model` are the
general simulators of :mod:`fdisyn.simulation` written this way; on the same
draws they give the same runs (the input signals and sensor faults of both
come from :mod:`fdisyn.simulation.signals`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np
from fdisyn.models.linear import LinearPlant
from fdisyn.models.nonlinear import NonlinearPlant
from fdisyn.models.sampled_data import SampledDataPlant
from fdisyn.numerics.linalg import psd_factor
from fdisyn.runtime.errors import ArgumentError, ShapeError
from fdisyn.simulation.problem import Scenario
from fdisyn.simulation.nonlinear import kept_variables, noise_factor
from fdisyn.simulation.sampled_data import disturbance_factor
from fdisyn.simulation.signals import SensorFaultSpec, Signal, faulty_measurement_sx, sensor_fault_map, signal_sx

__all__ = [
    "NAMES_IN",
    "NAMES_OUT",
    "SampleModel",
    "clip_sx",
    "linear_parameters",
    "linear_sample_model",
    "nonlinear_sample_model",
    "sampled_data_sample_model",
]

NAMES_IN = ["x", "z", "k", "p", "d"]
"""Port names of a sample model's functions (:class:`SampleModel`)."""
NAMES_OUT = ["x_next", "u", "y", "e"]



@dataclass(frozen=True, eq=False)
class SampleModel:
    """A simulator one sample at a time (module docstring).

    ``step(x, z, k, p, d) → (x⁺, u, y, e)``, and ``faulty`` the same while
    the scenario's fault is active (default: ``step``; two functions, so that
    the samples outside the fault's window skip its arithmetic); ``x0`` the state at ``k = 0``,
    or ``start(z0) → x0`` from ``n0`` standard normals drawn first in each run
    (e.g. the run's random parameters and the equilibrium they give);
    ``parameters(scenario)`` the scenario's ``p``; ``drive(scenario)`` its
    drive table (N × nd; ``None``: nd = 0); ``Ts`` the sample time (a
    scenario has ``round(duration / Ts)`` samples); ``inputs``, ``outputs``
    name ``u`` and ``y`` (a design's gain file must name the same),
    ``extra`` the entries of ``e`` (the batch's extra signals).
    """

    step: ca.Function
    x0: np.ndarray
    parameters: Callable[[Scenario], np.ndarray]
    Ts: float
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    extra: tuple[str, ...] = ()
    drive: Callable[[Scenario], np.ndarray] | None = None
    faulty: ca.Function | None = None
    start: ca.Function | None = None
    nz: int = field(init=False)
    n0: int = field(init=False)

    def __post_init__(self) -> None:
        fn = self.step
        if fn.n_in() != 5 or fn.n_out() != 4:
            raise ShapeError(f"a sample model's step maps (x, z, k, p, d) to (x⁺, u, y, e); got {fn.n_in()} inputs and {fn.n_out()} outputs")
        faulty = fn if self.faulty is None else self.faulty
        object.__setattr__(self, "faulty", faulty)
        sizes = [(fn.size_in(i), faulty.size_in(i)) for i in range(5)] + [(fn.size_out(i), faulty.size_out(i)) for i in range(4)]
        if faulty.n_in() != 5 or faulty.n_out() != 4 or any(a != b for a, b in sizes):
            raise ShapeError("a sample model's faulty step must have the ports of its step")
        nx = fn.size1_in(0)
        want = {"x⁺": (fn.size1_out(0), nx), "u": (fn.size1_out(1), len(self.inputs)), "y": (fn.size1_out(2), len(self.outputs)),
                "e": (fn.size1_out(3), len(self.extra)), "k": (fn.size1_in(2), 1), "x0": (np.size(self.x0), nx)}
        for what, (have, need) in want.items():
            if have != need:
                raise ShapeError(f"a sample model's {what} has {have} entries; expected {need}")
        x0 = np.asarray(self.x0, dtype=float).reshape(-1)
        if not np.all(np.isfinite(x0)):
            raise ArgumentError("a sample model's initial state must be finite")
        start = self.start
        if start is None:  # the constant start: no draw
            start = ca.Function("start", [ca.SX.sym("z0", 0)], [ca.DM(x0)], ["z0"], ["x0"])
        elif start.n_in() != 1 or start.n_out() != 1 or start.size1_out(0) != nx:
            raise ShapeError(f"a sample model's start maps its draws to the {nx} entries of x0")
        object.__setattr__(self, "start", start)
        object.__setattr__(self, "x0", x0)
        object.__setattr__(self, "nz", int(fn.size1_in(1)))
        object.__setattr__(self, "n0", int(start.size1_in(0)))

    def samples(self, scenario: Scenario) -> int:
        return int(round(scenario.duration / self.Ts))

    def window(self, scenario: Scenario) -> tuple[int, int]:
        """``(k_on, k_end)``: the fault is active for ``k_on ≤ k < k_end`` (``scenario.active`` on the sample grid)."""
        on = np.flatnonzero(scenario.active(np.arange(self.samples(scenario)) * self.Ts))
        if on.size and on[-1] - on[0] + 1 != on.size:
            raise ArgumentError(f"scenario {scenario.name!r}: the fault must be active over one interval")
        return (int(on[0]), int(on[-1]) + 1) if on.size else (0, 0)

    def drive_table(self, scenario: Scenario) -> np.ndarray:
        """The scenario's drive table, checked: N × nd, finite."""
        shape = (self.samples(scenario), int(self.step.size1_in(4)))
        table = np.zeros(shape) if self.drive is None else _finite(self.drive(scenario), "the drive table")
        if table.shape != shape:
            raise ShapeError(f"the drive table of scenario {scenario.name!r} has shape {table.shape}; expected {shape}")
        return np.ascontiguousarray(table, dtype=float)


def clip_sx(v: ca.SX, lo: float, hi: float) -> ca.SX:
    """``np.clip`` on CasADi expressions, NaN kept (``fmin``/``fmax`` would drop it)."""
    return ca.if_else(v < lo, lo, ca.if_else(v > hi, hi, v))


def _finite(values: Any, what: str) -> np.ndarray:
    a = np.asarray(values, dtype=float)
    if not np.all(np.isfinite(a)):
        raise ArgumentError(f"{what} must be finite to be compiled; got {a.reshape(-1).tolist()}")
    return a


def linear_parameters(plant: LinearPlant, scenario: Scenario) -> np.ndarray:
    """``p`` of :func:`linear_sample_model` for ``scenario``: ``[onset, stuck, value, gain, offset, drift, Fx f, Df f]``.

    Per output, the scenario's sensor faults composed in order into
    ``y ↦ (stuck ? value : gain·y) + offset + drift·(t − onset)``; the
    component faults' ``Fx f`` added to the state and their ``Df f`` to the outputs (before the sensor faults);
    all while the fault is active (:meth:`SampleModel.window`).
    """
    faults = [f if isinstance(f, SensorFaultSpec) else SensorFaultSpec(*f) for f in scenario.params.get("sensor_faults", [])]
    stuck, value, gain, offset, drift = sensor_fault_map(
        faults, plant.outputs, lambda f: float(_finite(f.value, f"the size of the {f.kind} fault on {f.sensor!r}"))
    )
    fvec, fy = np.zeros(plant.n), np.zeros(plant.p)
    for cname, size in scenario.params.get("component_faults", []):
        if cname not in plant.component_faults:
            raise ArgumentError(f"component fault {cname!r}: the plant has {list(plant.component_faults)}")
        j = plant.component_faults.index(cname)
        fvec = fvec + np.asarray(plant.Fx)[:, j] * float(size)
        fy = fy + np.asarray(plant.Df)[:, j] * float(size)
    onset = float(scenario.onset or 0.0)
    return _finite(np.concatenate([[onset], stuck, value, gain, offset, drift, fvec, fy]), "the scenario's fault")


def linear_sample_model(
    plant: LinearPlant,
    *,
    x0: np.ndarray,
    inputs: Sequence[Signal],
    unknown_inputs: Sequence[Signal],
    feedback: Callable[[ca.SX, ca.SX], ca.SX] | None = None,
    scenario_map: Callable[[Scenario], Scenario] | None = None,
) -> SampleModel:
    """:func:`fdisyn.simulation.simulate.simulate_linear` one sample at a time.

    Same arguments, except ``feedback(y, k)``: the controller on one sample's
    (possibly faulty) measurements as CasADi expressions (``y``: a 1 × ny SX,
    one run of ``simulate_linear``'s runs × ny) giving ``u`` (1 × nu). ``scenario_map`` turns a scenario into the one
    ``simulate_linear`` receives (e.g. a fault given in noise standard
    deviations). The draws of a sample are laid out ``[w (rank Q), v (rank R),
    one per prbs or gauss_markov signal, inputs first]``: the layout of
    ``simulate_linear``'s ``draws``.
    """
    if not plant.is_discrete:
        raise ArgumentError("a linear sample model needs the discrete plant")
    if len(inputs) != plant.m or len(unknown_inputs) != plant.q:
        raise ShapeError(f"simulation needs {plant.m} input and {plant.q} unknown-input signals")
    a, b, c, d, e, d_d = (_finite(getattr(plant, k), f"the plant's {k}") for k in ("A", "B", "C", "D", "E", "Dd"))
    if feedback is not None and np.any(d):
        raise ArgumentError("a feedback input needs D = 0 (otherwise u and y form an algebraic loop)")
    ts = float(plant.Ts)  # type: ignore[arg-type]
    lq, lr = psd_factor(plant.Q, "Q"), psd_factor(plant.R, "R")
    nq, nv, n, p = lq.shape[1], lr.shape[1], plant.n, plant.p
    signals = list(inputs) + list(unknown_inputs)
    random = [j for j, s in enumerate(signals) if s.random]
    x = ca.SX.sym("x", n + len(random))
    z = ca.SX.sym("z", nq + nv + len(random))
    k = ca.SX.sym("k")
    par = ca.SX.sym("p", 1 + 5 * p + n + p)
    t = k * ts
    values: list[ca.SX] = []
    memory: list[ca.SX] = []
    for j, sig in enumerate(signals):
        slot = random.index(j) if j in random else None
        v, mem = signal_sx(sig, t, k, ts, None if slot is None else z[nq + nv + slot], None if slot is None else x[n + slot])
        values.append(v)
        if mem is not None:
            memory.append(mem)
    xs = x[:n]
    dd = ca.vertcat(*values[plant.m :]) if plant.q else ca.SX(0, 1)

    def sample(faulty: bool) -> list[ca.SX]:
        """The sample's outputs outside the fault's window, or inside it (``faulty``)."""
        y = ca.mtimes(ca.DM(c), xs) + ca.mtimes(ca.DM(lr), z[nq : nq + nv])
        if plant.q and np.any(d_d):
            y = y + ca.mtimes(ca.DM(d_d), dd)
        u = ca.vertcat(*values[: plant.m]) if plant.m else ca.SX(0, 1)
        if feedback is None and plant.m:
            y = y + ca.mtimes(ca.DM(d), u)
        if faulty:
            y = y + par[1 + 5 * p + n :]
            stuck, value, gain, offset, drift = (par[1 + i * p : 1 + (i + 1) * p] for i in range(5))
            y = faulty_measurement_sx(y, stuck, value, gain, offset, drift, t, par[0])
        if feedback is not None:
            u = ca.SX(feedback(y.T, k)).T
            if u.shape != (plant.m, 1):
                raise ShapeError(f"the feedback gives {u.shape[1]}×{u.shape[0]}; expected 1×{plant.m}")
        nxt = ca.mtimes(ca.DM(a), xs) + ca.mtimes(ca.DM(b), u) + ca.mtimes(ca.DM(e), dd) + ca.mtimes(ca.DM(lq), z[:nq])
        if faulty:
            nxt = nxt + par[1 + 5 * p : 1 + 5 * p + n]
        return [ca.vertcat(nxt, *memory), u, y, ca.vertcat(xs, dd)]

    ins = [x, z, k, par, ca.SX(0, 1)]
    mapped = scenario_map or (lambda sc: sc)
    return SampleModel(
        step=ca.Function("sample", ins, sample(False), NAMES_IN, NAMES_OUT),
        faulty=ca.Function("sample_faulty", ins, sample(True), NAMES_IN, NAMES_OUT),
        x0=np.concatenate([_finite(x0, "x0").reshape(-1), np.zeros(len(random))]),
        parameters=lambda sc: linear_parameters(plant, mapped(sc)),
        Ts=ts,
        inputs=plant.inputs,
        outputs=plant.outputs,
        extra=plant.states + plant.unknown_inputs,
    )


def nonlinear_sample_model(
    plant: NonlinearPlant,
    *,
    x0: Any,
    drive: Callable[[Scenario], tuple[np.ndarray | None, np.ndarray]],
    Ts: float,
    extra: Mapping[str, str] | None = None,
    signals: Sequence[Signal] | None = None,
) -> SampleModel:
    """:func:`fdisyn.simulation.nonlinear.simulate_nonlinear_runs` one sample at a time (the same arguments).

    ``drive(scenario)`` gives the scenario's inputs ``u`` (N × m; ``None``
    with ``signals``) and parameters ``θ`` (N × l; row ``k`` drives
    ``x(k) → x(k+1)``), the same for every run; ``signals`` (one per input)
    draws the inputs per run instead, as a nonlinear plant file does;
    ``extra`` maps each kept signal's name to a state or parameter of the
    plant. The draws of a sample are ``[v (n), e (p), one per prbs or
    gauss_markov signal]``, the layout of ``simulate_nonlinear_runs``'s ``draws``.
    """
    n, m, l, p = plant.n, plant.m, plant.l, plant.p
    keep = kept_variables(plant, extra)
    if signals is not None and len(signals) != m:
        raise ShapeError(f"simulation needs {m} input signals, got {len(signals)}")
    random = [j for j, sg in enumerate(signals or ()) if sg.random]
    fq, fr = noise_factor(_finite(plant.Q, "Q")), noise_factor(_finite(plant.R, "R"))
    x, z, k = ca.SX.sym("x", n + len(random)), ca.SX.sym("z", n + p + len(random)), ca.SX.sym("k")
    d = ca.SX.sym("d", l if signals is not None else m + l)
    xs, memory = x[:n], []
    if signals is not None:
        values = []
        for j, sg in enumerate(signals):
            slot = random.index(j) if j in random else None
            v, mem = signal_sx(sg, k * Ts, k, Ts, None if slot is None else z[n + p + slot], None if slot is None else x[n + slot])
            values.append(v)
            if mem is not None:
                memory.append(mem)
        u, theta = (ca.vertcat(*values) if m else ca.SX(0, 1)), d
    else:
        u, theta = d[:m], d[m:]
    nxt = plant.f(xs, u, theta) + ca.mtimes(ca.DM(fq), z[:n])
    y = plant.h(xs, theta) + ca.mtimes(ca.DM(fr), z[n : n + p])
    kept = [xs[plant.states.index(v)] if v in plant.states else theta[plant.parameters.index(v)] for v in keep.values()]
    step = ca.Function("sample", [x, z, k, ca.SX(0, 1), d], [ca.vertcat(nxt, *memory), u, y, ca.vertcat(*kept) if kept else ca.SX(0, 1)],
                       NAMES_IN, NAMES_OUT)

    def table(sc: Scenario) -> np.ndarray:
        uu, th = drive(sc)
        th = np.asarray(th, dtype=float).reshape(-1, l)
        return th if signals is not None else np.hstack([np.asarray(uu, dtype=float).reshape(-1, m), th])

    return SampleModel(
        step=step, x0=np.concatenate([_finite(x0, "x0").reshape(-1), np.zeros(len(random))]), parameters=lambda sc: np.zeros(0),
        Ts=float(Ts), inputs=plant.inputs, outputs=plant.outputs, extra=tuple(keep), drive=table,
    )


def sampled_data_sample_model(
    plant: SampledDataPlant,
    *,
    drive: Callable[[Scenario], tuple[np.ndarray, np.ndarray]],
    inputs: Sequence[str],
    outputs: Sequence[str],
    states: Sequence[str],
    x0: Any | None = None,
    intensity: Any | None = None,
) -> SampleModel:
    """:func:`fdisyn.simulation.sampled_data.simulate_sampled_data` one sample at a time.

    ``drive(scenario)`` gives ``v`` (N × m, held) and ``f`` (N × n_f), the same
    for every run; ``y = ψ = C x``; the states are kept as ``states``. The draws
    of a sample are the disturbance's (its covariance's rank), the layout of
    ``simulate_sampled_data``'s ``draws``.
    """
    fac = disturbance_factor(plant, intensity)
    n, m, nf = plant.n, plant.m, plant.Fx.shape[1]
    x, z, k, d = ca.SX.sym("x", n), ca.SX.sym("z", fac.shape[1]), ca.SX.sym("k"), ca.SX.sym("d", m + nf)
    a_d, b_d, fx_d, c = (_finite(getattr(plant, name), name) for name in ("A_D", "B_D", "Fx_D", "C"))
    nxt = ca.mtimes(ca.DM(a_d), x) + ca.mtimes(ca.DM(b_d), d[:m]) + ca.mtimes(ca.DM(fx_d), d[m:]) + ca.mtimes(ca.DM(fac), z)
    step = ca.Function("sample", [x, z, k, ca.SX(0, 1), d], [nxt, d[:m], ca.mtimes(ca.DM(c), x), x], NAMES_IN, NAMES_OUT)

    def table(sc: Scenario) -> np.ndarray:
        v, f = drive(sc)
        return np.hstack([np.asarray(v, dtype=float).reshape(-1, m), np.asarray(f, dtype=float).reshape(-1, nf)])

    return SampleModel(
        step=step, x0=np.zeros(n) if x0 is None else _finite(x0, "x0"), parameters=lambda sc: np.zeros(0), Ts=float(plant.Ts),
        inputs=tuple(inputs), outputs=tuple(outputs), extra=tuple(states), drive=table,
    )


