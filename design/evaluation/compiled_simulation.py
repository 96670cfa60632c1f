"""Compiled Monte Carlo: the plant's simulation and every design's step, fused in one C call per chunk of runs.

A problem opts in with :attr:`fdisyn.simulation.problem.Problem.sample_model`: its
simulator described one sample at a time (:class:`SampleModel`), a CasADi
function

    ``(x, z, k, p, d) ↦ (x⁺, u, y, e)``

of the simulation's state ``x``, the sample's standard-normal draws ``z``, the
sample index ``k``, the scenario's parameters ``p`` (its fault's sizes)
and the sample's row ``d`` of the scenario's drive table (inputs and
parameters known in advance, the same for every run), giving the next state,
the known inputs, the measurements and the signals kept beside them (true
states, unknown inputs, true parameters). The generated C driver
(``campaign.c.in``) runs it for every run of a chunk with the run's own
xoshiro256** generator (Blackman & Vigna, ACM Transactions on Mathematical
Software 47(4), 2021) seeded from
``SeedSequence(seed).generate_state(4, np.uint64)``, Gaussians by the ziggurat
method (Marsaglia & Tsang 2000, Journal of Statistical Software 5(8)), and
feeds each sample to every design's C step, the one ``fdisyn codegen``
compiles: the designs see the same runs (common random numbers), and run ``i``
is the same whatever chunk it is in.

The library is built once per problem options and set of designs (a
scenario only changes ``p``, the drive table, the fault's window and the
number of samples) in
``<work>/campaign/<key>/`` beside the designs' folders, with a build manifest
checked before it is loaded (:mod:`fdisyn.runtime.compiled`).
"""

from __future__ import annotations

import ctypes
import hashlib
import math
import os
import sys
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import casadi as ca
import numpy as np
from fdisyn.codegen import lanes
from fdisyn.codegen.lanes import LANE_PRELUDE, lane_function, scalar_lanes
from fdisyn.codegen.library import (
    CFLAGS,
    _c_double,
    _finish,
    _start,
    c_string_literal,
    casadi_step,
    compiler,
    fill_template,
    fresh_path,
    shared_library_flags,
)
from fdisyn.evaluation.campaign import ChunkRuns, DesignRuns
from fdisyn.evaluation.metrics import HISTOGRAM_EDGES, MetricsPlan, RunSummaries
from fdisyn.simulation.sampled_data import disturbance_factor
from fdisyn.simulation.simulate import SensorFaultSpec, Signal
from fdisyn.models.linear import LinearPlant
from fdisyn.models.nonlinear import NonlinearPlant, noise_factor
from fdisyn.simulation.problem import Batch, Problem, Scenario
from fdisyn.models.sampled_data import SampledDataPlant
from fdisyn.numerics.linalg import psd_factor
from fdisyn.runtime.compiled import _check_before_loading, library_suffix, write_manifest
from fdisyn.runtime.errors import ArgumentError, BuildError, ShapeError
from fdisyn.runtime.gainfile import gain_file_sha256
from fdisyn.runtime.names import check_diagnoser_name

try:
    import fcntl
except ImportError:  # Windows: no advisory locks; concurrent builds of one library are not guarded there
    fcntl = None  # type: ignore[assignment]

if TYPE_CHECKING:
    from fdisyn.evaluation.evaluate import Built

__all__ = [
    "NAMES_IN",
    "NAMES_OUT",
    "SampleModel",
    "clip_sx",
    "linear_sample_model",
    "nonlinear_sample_model",
    "sampled_data_sample_model",
    "ziggurat_tables",
    "generator_state",
    "CompiledCampaign",
    "compiled_campaign",
]

TEMPLATE = Path(__file__).with_name("campaign.c.in")
NAMES_IN = ["x", "z", "k", "p", "d"]
"""Port names of a sample model's functions (:class:`SampleModel`)."""
NAMES_OUT = ["x_next", "u", "y", "e"]

# ----------------------------------------------------------------------------- the generator

ZIGGURAT_R = 3.6541528853610088
"""Right edge of the base layer of the 256-layer ziggurat (Marsaglia & Tsang 2000, Journal of Statistical Software 5(8))."""
ZIGGURAT_V = 4.92867323399e-3
"""Area of each of its layers (same source)."""


def ziggurat_tables() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``k`` (uint64), ``w``, ``f`` of the 256-layer ziggurat for 52-bit magnitudes.

    The recursion of Marsaglia & Tsang 2000 (their ``zigset``, ``m1 = 2⁵²``):
    ``x_{i}`` from ``x_{i+1}`` by ``x_i = √(−2 log(v/x_{i+1} + f(x_{i+1})))``;
    layer ``i`` draws ``x = rabs·w[i]`` and accepts it at once when
    ``rabs < k[i]`` (the part of the layer under the density); layer 0 is the
    base strip with the tail.
    """
    m1 = 2.0**52
    r, v = ZIGGURAT_R, ZIGGURAT_V
    q = v / math.exp(-0.5 * r * r)
    k = np.zeros(256, dtype=np.uint64)
    w = np.zeros(256)
    f = np.zeros(256)
    k[0] = int(r / q * m1)
    w[0], w[255] = q / m1, r / m1
    f[0], f[255] = 1.0, math.exp(-0.5 * r * r)
    dn = tn = r
    for i in range(254, 0, -1):
        dn = math.sqrt(-2.0 * math.log(v / dn + math.exp(-0.5 * dn * dn)))
        k[i + 1] = int(dn / tn * m1)
        tn = dn
        f[i] = math.exp(-0.5 * dn * dn)
        w[i] = dn / m1
    return k, w, f


def generator_state(seed: int) -> np.ndarray:
    """The four xoshiro256** words of run seed ``seed``: ``SeedSequence(seed).generate_state(4, np.uint64)``."""
    return np.random.SeedSequence(int(seed)).generate_state(4, np.uint64)


# ----------------------------------------------------------------------------- sample models


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


def _signal_sx(sig: Signal, t: ca.SX, k: ca.SX, ts: float, z: ca.SX | None, memory: ca.SX | None) -> tuple[ca.SX, ca.SX | None]:
    """One sample of ``sig`` (:meth:`fdisyn.simulation.simulate.Signal.sample` with given draws), and its next memory."""
    _finite([sig.offset, sig.amplitude, sig.period, sig.start], f"the numbers of a {sig.kind} signal")
    if sig.kind == "constant":
        return ca.SX(sig.offset), None
    if sig.kind == "step":
        return sig.offset + sig.amplitude * (t >= sig.start), None
    if sig.kind == "sine":
        return sig.offset + sig.amplitude * ca.sin(2 * np.pi * t / sig.period), None
    if sig.kind == "square":
        half = ca.floor(2.0 * t / sig.period + 1e-9)
        return sig.offset + sig.amplitude * ca.if_else(ca.fmod(half, 2) == 0, 1.0, -1.0), None
    assert z is not None and memory is not None
    if sig.kind == "prbs":
        hold = max(1, int(round(sig.period / ts)))
        level = ca.if_else(ca.fmod(k, hold) == 0, ca.if_else(z >= 0, 1.0, -1.0), memory)
        return sig.offset + sig.amplitude * level, level
    a = float(np.exp(-ts / sig.period))
    s = float(np.sqrt(1.0 - a * a))
    zeta = ca.if_else(k == 0, z, s * z + a * memory)
    return sig.offset + sig.amplitude * zeta, zeta


def linear_parameters(plant: LinearPlant, scenario: Scenario) -> np.ndarray:
    """``p`` of :func:`linear_sample_model` for ``scenario``: ``[onset, stuck, value, gain, offset, drift, Fx f]``.

    Per output, the scenario's sensor faults composed in order into
    ``y ↦ (stuck ? value : gain·y) + offset + drift·(t − onset)``; the
    component faults' ``Fx f`` added to the state; both while the fault is
    active (:meth:`SampleModel.window`).
    """
    p = plant.p
    stuck, value, gain, offset, drift = np.zeros(p), np.zeros(p), np.ones(p), np.zeros(p), np.zeros(p)
    for f in scenario.params.get("sensor_faults", []):
        f = f if isinstance(f, SensorFaultSpec) else SensorFaultSpec(*f)
        if f.sensor not in plant.outputs:
            raise ArgumentError(f"sensor fault on {f.sensor!r}: no such output; outputs are {list(plant.outputs)}")
        j = plant.outputs.index(f.sensor)
        v = float(_finite(f.value, f"the size of the {f.kind} fault on {f.sensor!r}"))
        if f.kind == "stuck":
            stuck[j], value[j], gain[j], offset[j], drift[j] = 1.0, v, 1.0, 0.0, 0.0
        elif f.kind == "gain":
            value[j], gain[j], offset[j], drift[j] = value[j] * v, gain[j] * v, offset[j] * v, drift[j] * v
        elif f.kind == "offset":
            offset[j] += v
        else:
            drift[j] += v
    fvec = np.zeros(plant.n)
    for cname, size in scenario.params.get("component_faults", []):
        if cname not in plant.component_faults:
            raise ArgumentError(f"component fault {cname!r}: the plant has {list(plant.component_faults)}")
        fvec = fvec + np.asarray(plant.Fx)[:, plant.component_faults.index(cname)] * float(size)
    onset = float(scenario.onset or 0.0)
    return _finite(np.concatenate([[onset], stuck, value, gain, offset, drift, fvec]), "the scenario's fault")


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
    a, b, c, d, e = (_finite(getattr(plant, k), f"the plant's {k}") for k in ("A", "B", "C", "D", "E"))
    if feedback is not None and np.any(d):
        raise ArgumentError("a feedback input needs D = 0 (otherwise u and y form an algebraic loop)")
    ts = float(plant.Ts)  # type: ignore[arg-type]
    lq, lr = psd_factor(plant.Q, "Q"), psd_factor(plant.R, "R")
    nq, nv, n, p = lq.shape[1], lr.shape[1], plant.n, plant.p
    signals = list(inputs) + list(unknown_inputs)
    random = [j for j, s in enumerate(signals) if s.kind in ("prbs", "gauss_markov")]
    x = ca.SX.sym("x", n + len(random))
    z = ca.SX.sym("z", nq + nv + len(random))
    k = ca.SX.sym("k")
    par = ca.SX.sym("p", 1 + 5 * p + n)
    t = k * ts
    values: list[ca.SX] = []
    memory: list[ca.SX] = []
    for j, sig in enumerate(signals):
        slot = random.index(j) if j in random else None
        v, mem = _signal_sx(sig, t, k, ts, None if slot is None else z[nq + nv + slot], None if slot is None else x[n + slot])
        values.append(v)
        if mem is not None:
            memory.append(mem)
    xs = x[:n]
    dd = ca.vertcat(*values[plant.m :]) if plant.q else ca.SX(0, 1)

    def sample(faulty: bool) -> list[ca.SX]:
        """The sample's outputs outside the fault's window, or inside it (``faulty``)."""
        y = ca.mtimes(ca.DM(c), xs) + ca.mtimes(ca.DM(lr), z[nq : nq + nv])
        u = ca.vertcat(*values[: plant.m]) if plant.m else ca.SX(0, 1)
        if feedback is None and plant.m:
            y = y + ca.mtimes(ca.DM(d), u)
        if faulty:
            stuck, value, gain, offset, drift = (par[1 + i * p : 1 + (i + 1) * p] for i in range(5))
            y = ca.if_else(stuck > 0.5, value, y * gain) + offset + drift * (t - par[0])
        if feedback is not None:
            u = ca.SX(feedback(y.T, k)).T
            if u.shape != (plant.m, 1):
                raise ShapeError(f"the feedback gives {u.shape[1]}×{u.shape[0]}; expected 1×{plant.m}")
        nxt = ca.mtimes(ca.DM(a), xs) + ca.mtimes(ca.DM(b), u) + ca.mtimes(ca.DM(e), dd) + ca.mtimes(ca.DM(lq), z[:nq])
        if faulty:
            nxt = nxt + par[1 + 5 * p :]
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
    """:meth:`fdisyn.models.nonlinear.NonlinearPlant.simulate` one sample at a time.

    ``drive(scenario)`` gives the scenario's inputs ``u`` (N × m; ``None``
    with ``signals``) and parameters ``θ`` (N × l; row ``k`` drives
    ``x(k) → x(k+1)``), the same for every run; ``signals`` (one per input)
    draws the inputs per run instead, as a nonlinear plant file does;
    ``extra`` maps each kept signal's name to a state or parameter of the
    plant. The draws of a sample are ``[v (n), e (p), one per prbs or
    gauss_markov signal]``, the layout of ``simulate``'s ``draws``.
    """
    n, m, l, p = plant.n, plant.m, plant.l, plant.p
    keep = dict(extra or {})
    unknown = sorted(set(keep.values()) - set(plant.states) - set(plant.parameters))
    if unknown:
        raise ArgumentError(f"kept signals {unknown} are neither states {list(plant.states)} nor parameters {list(plant.parameters)}")
    if signals is not None and len(signals) != m:
        raise ShapeError(f"simulation needs {m} input signals, got {len(signals)}")
    random = [j for j, sg in enumerate(signals or ()) if sg.kind in ("prbs", "gauss_markov")]
    fq, fr = noise_factor(_finite(plant.Q, "Q")), noise_factor(_finite(plant.R, "R"))
    x, z, k = ca.SX.sym("x", n + len(random)), ca.SX.sym("z", n + p + len(random)), ca.SX.sym("k")
    d = ca.SX.sym("d", l if signals is not None else m + l)
    xs, memory = x[:n], []
    if signals is not None:
        values = []
        for j, sg in enumerate(signals):
            slot = random.index(j) if j in random else None
            v, mem = _signal_sx(sg, k * Ts, k, Ts, None if slot is None else z[n + p + slot], None if slot is None else x[n + slot])
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


# ----------------------------------------------------------------------------- the fused library

LIBRARY_FLAGS = (*shared_library_flags(), *(("-fno-semantic-interposition",) if sys.platform.startswith("linux") else ()))
"""Beside :data:`fdisyn.codegen.library.CFLAGS`: a shared library where calls between its own functions (a
design's step and CasADi's helpers) are direct and may be inlined, as in a program (on Linux: 14 % fewer
instructions per wind-turbine sample; the same arithmetic, so the steps stay bit for bit those of ``fdisyn
codegen``'s library)."""
LIBRARY = f"libfdisyn_campaign{library_suffix()}"

_U64 = ctypes.POINTER(ctypes.c_uint64)
_D = ctypes.POINTER(ctypes.c_double)
_P = ctypes.POINTER(ctypes.c_void_p)


class _Plan(ctypes.Structure):
    """``struct campaign_plan`` of ``campaign.c.in``: one design's summaries to accumulate in the C loop."""

    _fields_ = [(name, ctypes.c_void_p) for name in ("quiet", "active", "on", "thresholds", "edges", "binned")] + [
        ("nedges", ctypes.c_long), ("fault", ctypes.c_long)] + [(name, ctypes.c_void_p) for name in ("counts", "sums", "histogram")]


SUMMARY_COUNTS = ("quiet_alarms", "episodes", "first_alarm", "alarmed_fault", "first_isolation", "mode_isolation",
                  "correct_isolated", "nonfinite")
"""The per-run counts the C loop writes, in its order (``CAMPAIGN_COUNTS`` of ``campaign.c.in``), then ``exceed``."""


def _design_code(prefixes: Sequence[str]) -> dict[str, str]:
    """The per-design lines of ``campaign.c.in`` (prefixes are checked diagnoser names: they form identifiers)."""
    inc, decl, init, step, end = [], [], [], [], []
    for i, pre in enumerate(prefixes):
        check_diagnoser_name(pre, "name", error=BuildError)
        P = pre.upper()
        inc.append(f'#include "{pre}.h"\n#include "{pre}_casadi.h"')
        decl.append(f"    double st{i}[CAMPAIGN_SZ({P}_NSTATE) * L], nx{i}[CAMPAIGN_SZ({P}_NSTATE) * L], st1_{i}[CAMPAIGN_SZ({P}_NSTATE)];\n"
                    f"    double lr{i}[CAMPAIGN_SZ({P}_NR) * L], lj{i}[CAMPAIGN_SZ({P}_NJ) * L], la{i}[L], liso{i}[L], lst{i}[L];\n"
                    f"    double rb{i}[CAMPAIGN_SZ({P}_NR)], jb{i}[CAMPAIGN_SZ({P}_NJ)];\n"
                    f"    int64_t md{i}[CAMPAIGN_SZ({P}_NFAULTS) * L];\n"
                    f"    struct campaign_acc acc{i}[L];\n"
                    f"    const int kept{i} = r && r[{i}];")
        init.append(f"            {pre}_init(st1_{i});\n"
                    f"            for (j = 0; j < {P}_NSTATE; ++j) st{i}[j * L + l] = st1_{i}[j];\n"
                    f"            if (plans && l < m)\n"
                    f"                campaign_begin(plans + {i}, &acc{i}[l], md{i} + l * CAMPAIGN_SZ({P}_NFAULTS), i0 + l, {P}_NR, {P}_NJ,\n"
                    f"                               {P}_NFAULTS);")
        step.append(
            f"            larg[0] = st{i};\n"
            f"            larg[1] = u;\n"
            f"            larg[2] = y;\n"
            f"            lres[0] = nx{i};\n"
            f"            lres[1] = lr{i};\n"
            f"            lres[2] = lj{i};\n"
            f"            lres[3] = la{i};\n"
            f"            lres[4] = liso{i};\n"
            f"            lres[5] = lst{i};\n"
            f"            if (campaign_lane_step{i}(larg, lres, level) != 0) return -1;\n"
            f"            memcpy(st{i}, nx{i}, sizeof st{i});\n"
            f"            if (kept{i} || plans)\n"
            f"                for (l = 0; l < m; ++l) {{ /* as {pre}_step reads the step's outputs */\n"
            f"                    const long at = (i0 + l) * n + k;\n"
            f"                    const int a = la{i}[l] > 0.5, iso = liso{i}[l] < 0.0 ? -1 : (int)(liso{i}[l] + 0.5), rc = lst{i}[l] > 0.5;\n"
            f"                    double *rl = kept{i} && {P}_NR ? r[{i}] + at * {P}_NR : rb{i};\n"
            f"                    double *jl = kept{i} && {P}_NJ ? J[{i}] + at * {P}_NJ : jb{i};\n"
            f"                    for (j = 0; j < {P}_NR; ++j) rl[j] = lr{i}[j * L + l];\n"
            f"                    for (j = 0; j < {P}_NJ; ++j) jl[j] = lj{i}[j * L + l];\n"
            f"                    if (kept{i}) {{\n"
            f"                        alarm[{i}][at] = (unsigned char)a;\n"
            f"                        isolated[{i}][at] = (int32_t)iso;\n"
            f"                        status[{i}][at] = (signed char)rc;\n"
            f"                    }}\n"
            f"                    if (plans && campaign_observe(plans + {i}, &acc{i}[l], k, a, iso, rc, rl, jl, {P}_NR, {P}_NJ, {P}_NFAULTS) != 0)\n"
            f"                        return -2;\n"
            f"                }}"
        )
        end.append(f"            if (plans) campaign_end(plans + {i}, &acc{i}[l], {P}_NR, {P}_NFAULTS);")
    return {"DESIGN_INCLUDES": "\n".join(inc), "DESIGN_DECLS": "\n".join(decl), "DESIGN_INITS": "\n".join(init),
            "DESIGN_STEPS": "\n".join(step), "DESIGN_ENDS": "\n".join(end)}


def _lane_code(model: SampleModel, built: Mapping[str, Built]) -> tuple[str, list[str]]:
    """The lane functions of the campaign (:mod:`fdisyn.codegen.lanes`): the simulation's and every design's step,
    as vectors where the function has a lane form, else CasADi's scalar C per lane; and the names of the latter."""
    sim, faulty, _ = _sim_functions(model)
    functions = [("campaign_lane_sim", "fdisyn_sim", sim), ("campaign_lane_sim_faulty", "fdisyn_sim_faulty", faulty)]
    functions += [(f"campaign_lane_step{i}", f"{b.gain_file.name}_casadi_step", casadi_step(b.gain_file))
                  for i, b in enumerate(built.values())]
    code, scalar = [], []
    for name, symbol, fn in functions:
        text = lane_function(fn, name)
        if text is None:
            scalar.append(symbol)
            text = scalar_lanes(fn, name, symbol)
        code.append(text)
    return "\n".join(code), scalar


def _sim_functions(model: SampleModel) -> list[ca.Function]:
    """The model's step as ``fdisyn_sim``, its faulty step as ``fdisyn_sim_faulty`` and its start as ``fdisyn_sim_start``:
    the functions the C is generated from."""
    assert model.faulty is not None and model.start is not None  # filled in by SampleModel
    out = []
    for name, fn in (("fdisyn_sim", model.step), ("fdisyn_sim_faulty", model.faulty), ("fdisyn_sim_start", model.start)):
        ins = fn.sx_in()
        out.append(ca.Function(name, ins, fn.call(ins), list(fn.name_in()), list(fn.name_out())))
    return out


def _sim_source(model: SampleModel, c_dir: Path) -> None:
    """``fdisyn_sim.c``: :func:`_sim_functions` in CasADi's C."""
    for generated in ("fdisyn_sim.c", "fdisyn_sim.h"):
        fresh_path(c_dir / generated)
    cg = ca.CodeGenerator("fdisyn_sim.c", {"with_header": True, "with_export": False, "verbose": False})
    for fn in _sim_functions(model):
        cg.add(fn)
    cg.generate(str(c_dir) + os.sep)


@dataclass(frozen=True, eq=False)
class CampaignSpec:
    """Everything a process needs to load a built campaign library and run a scenario (plain data: picklable)."""

    library: Path
    key: str
    scenario: Scenario
    designs: tuple[tuple[str, int, int], ...]
    """(design, nr, nj) in the library's order."""
    parameters: np.ndarray
    drive: np.ndarray
    window: tuple[int, int]
    samples: int
    Ts: float
    nz: int
    n0: int
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    extra: tuple[str, ...]


class CompiledCampaign:
    """A scenario's runs through the fused library: :meth:`run` gives a chunk's :class:`ChunkRuns`.

    Pickled as its :class:`CampaignSpec`: a worker process loads the library
    again from its path (after the manifest checks), never a ctypes handle.
    """

    def __init__(self, spec: CampaignSpec) -> None:
        _check_before_loading(spec.library, spec.key)
        try:
            lib = ctypes.CDLL(str(spec.library.resolve()))
        except OSError as exc:
            raise BuildError(f"cannot load {spec.library}: {exc}") from exc
        key_fn = lib.fdisyn_campaign_key
        key_fn.argtypes, key_fn.restype = [], ctypes.c_char_p
        if (key_fn() or b"").decode("ascii", "replace") != spec.key:
            raise BuildError(f"this process already runs another build of {spec.library}; start a new process")
        self._run = lib.fdisyn_campaign_run
        self._run.argtypes = [ctypes.c_long, ctypes.c_long, ctypes.c_long, ctypes.c_long, _U64, _D, _D, _D, _D, _D, _P, _P, _P, _P, _P,
                              ctypes.POINTER(_Plan)]
        self._run.restype = ctypes.c_int
        layout = lib.fdisyn_campaign_summary_layout
        layout.argtypes, layout.restype = [], ctypes.c_int
        if layout() != len(SUMMARY_COUNTS):
            raise BuildError(f"{spec.library} writes {layout()} counts per run; this fdisyn reads {len(SUMMARY_COUNTS)}")
        self._draws = lib.fdisyn_campaign_draws
        self._draws.argtypes = [ctypes.c_long, ctypes.c_long, _U64, _D]
        self._draws.restype = None
        self._set_level = lib.fdisyn_campaign_set_level
        self._set_level.argtypes, self._set_level.restype = [ctypes.c_int], None
        self._level = lib.fdisyn_campaign_level
        self._level.argtypes, self._level.restype = [], ctypes.c_int
        self._normals = lib.fdisyn_campaign_normals
        self._normals.argtypes = [_U64, ctypes.c_long, _D]
        self._normals.restype = None
        self.spec = spec
        self._lib = lib

    def __reduce__(self) -> tuple[Any, ...]:
        return (CompiledCampaign, (self.spec,))

    @staticmethod
    def _states(seeds: Sequence[int]) -> np.ndarray:
        bad = [s for s in seeds if isinstance(s, bool) or not isinstance(s, (int, np.integer)) or s < 0]
        if bad:
            raise ArgumentError(f"seeds must be whole numbers ≥ 0; got {bad[:5]}")
        return np.ascontiguousarray(np.stack([generator_state(int(s)) for s in seeds]) if seeds else np.zeros((0, 4), np.uint64))

    def vector_level(self, level: int | None = None) -> int:
        """The vectors the runs go through: 3 AVX-512, 2 AVX2, 1 the baseline (see :mod:`fdisyn.codegen.lanes`);
        ``level`` forces one for this process's library (0: the widest this CPU runs), for tests. Results do not
        depend on it."""
        if level is not None:
            self._set_level(0)
            if level not in range(self._level() + 1):
                raise ArgumentError(f"vector level must be 0 … {self._level()} on this CPU; got {level!r}")
            self._set_level(int(level))
        return int(self._level())

    def normals(self, seed: int, count: int) -> np.ndarray:
        """``count`` standard normals of run seed ``seed``'s generator (the kernel's law, for tests)."""
        out = np.zeros(max(int(count), 1))
        self._normals(self._states([seed])[0].ctypes.data_as(_U64), int(count), out.ctypes.data_as(_D))
        return out[: int(count)]

    def draws(self, seeds: Sequence[int]) -> np.ndarray:
        """The standard-normal draws the simulation of each run reads per sample: runs × N × nz (the Python
        simulator's ``draws``; :meth:`start_draws` has those its start reads before them)."""
        sp = self.spec
        return self._all_draws(seeds)[:, sp.n0 :].reshape(len(seeds), sp.samples, sp.nz)

    def start_draws(self, seeds: Sequence[int]) -> np.ndarray:
        """The standard normals each run's start reads (runs × n0), drawn before :meth:`draws`."""
        return self._all_draws(seeds)[:, : self.spec.n0]

    def _all_draws(self, seeds: Sequence[int]) -> np.ndarray:
        sp = self.spec
        out = np.zeros((len(seeds), sp.n0 + sp.samples * sp.nz))
        if out.size:
            self._draws(len(seeds), sp.samples, self._states(seeds).ctypes.data_as(_U64), out.ctypes.data_as(_D))
        return out

    def run(self, seeds: Sequence[int], *, keep_batch: bool = False) -> ChunkRuns:
        """Simulate run seed ``seeds[i]`` for every ``i`` and diagnose it with every design, in one C call."""
        return self._call(seeds, keep_batch=keep_batch, arrays=[d for d, _, _ in self.spec.designs], plans=None)[0]

    def summaries(self, seeds: Sequence[int], plans: Mapping[str, MetricsPlan]) -> Mapping[str, RunSummaries]:
        """Each design's :class:`RunSummaries` of runs ``seeds`` (:func:`~fdisyn.evaluation.metrics.summarise_runs`
        of :meth:`run`'s arrays, accumulated in the C loop without them; ``extra`` left ``None``, see :meth:`summarise`)."""
        return self.summarise(seeds, plans)[1]

    def summarise(
        self, seeds: Sequence[int], plans: Mapping[str, MetricsPlan], *, keep_batch: bool = False, arrays: Sequence[str] = ()
    ) -> tuple[ChunkRuns, dict[str, RunSummaries]]:
        """The runs ``seeds`` of every design summarised in the C loop (``plans``: one per design); the
        :class:`ChunkRuns` holds the arrays of the designs in ``arrays`` only (e.g. those with extra figures, which
        read them) and the batch when ``keep_batch``. The residual sums are each run's own, in sample order: a run's
        summary does not depend on its chunk."""
        missing = [d for d, _, _ in self.spec.designs if d not in plans]
        if missing:
            raise ArgumentError(f"no metrics plan for design(s) {missing}")
        chunk, out = self._call(seeds, keep_batch=keep_batch, arrays=arrays, plans=plans)
        assert out is not None
        return chunk, out

    def _call(
        self, seeds: Sequence[int], *, keep_batch: bool, arrays: Sequence[str], plans: Mapping[str, MetricsPlan] | None
    ) -> tuple[ChunkRuns, dict[str, RunSummaries] | None]:
        sp = self.spec
        seeds = tuple(int(s) for s in seeds)
        states = self._states(seeds)
        runs, n = len(seeds), sp.samples
        outs = {d: DesignRuns(
            r=np.zeros((runs, n, nr)), J=np.zeros((runs, n, nj)), alarm=np.zeros((runs, n), bool),
            isolated=np.full((runs, n), -1, np.int32), status=np.zeros((runs, n), np.int8),
        ) for d, nr, nj in sp.designs if d in arrays}
        keep = [np.zeros((runs, n, m)) for m in (len(sp.inputs), len(sp.outputs), len(sp.extra))] if keep_batch else None

        def ptrs(field_name: str) -> Any:
            return (ctypes.c_void_p * len(sp.designs))(*[getattr(outs[d], field_name).ctypes.data if d in outs else None
                                                         for d, _, _ in sp.designs])

        def opt(a: np.ndarray | None) -> Any:
            return None if a is None or a.size == 0 else a.ctypes.data_as(_D)

        c_plans, held = None, []
        if plans is not None:
            c_plans = (_Plan * max(len(sp.designs), 1))()
            for i, (d, nr, nj) in enumerate(sp.designs):
                plan = plans[d]
                h = np.ascontiguousarray(plan.thresholds, dtype=float)
                if h.shape != (nj,) or plan.quiet.shape != (n,) or plan.active.shape != (n,):
                    raise ShapeError(f"design {d!r}: its metrics plan is not for {n} samples and {nj} statistics")
                binned = (np.isfinite(h) & (h > 0)).astype(np.uint8)
                # a statistic without a finite positive threshold has no histogram (its edges are never read)
                edges = np.ascontiguousarray([HISTOGRAM_EDGES * (float(x) if ok else 1.0) for x, ok in zip(h, binned, strict=True)])
                edges = edges.reshape(nj, len(HISTOGRAM_EDGES))
                bufs = {
                    "quiet": np.ascontiguousarray(plan.quiet, dtype=np.uint8),
                    "active": np.ascontiguousarray(plan.active, dtype=np.uint8),
                    "on": None if plan.on is None else np.ascontiguousarray(plan.on, dtype=np.uint8),
                    "thresholds": h, "edges": edges, "binned": binned,
                    "counts": np.zeros((runs, len(SUMMARY_COUNTS) + nj), np.int64),
                    "sums": np.zeros((runs, 2 * nr + nr * nr)),
                    "histogram": np.zeros((nj, len(HISTOGRAM_EDGES) + 1), np.int64),
                }
                held.append(bufs)
                for name, a in bufs.items():
                    setattr(c_plans[i], name, None if a is None or a.size == 0 else a.ctypes.data)
                c_plans[i].nedges = len(HISTOGRAM_EDGES)
                c_plans[i].fault = -1 if plan.fault_index is None else int(plan.fault_index)
        if runs and n:
            rc = self._run(
                runs, n, *sp.window, states.ctypes.data_as(_U64), opt(sp.parameters), opt(sp.drive),
                *(opt(None if keep is None else a) for a in keep or (None, None, None)),
                ptrs("r"), ptrs("J"), ptrs("alarm"), ptrs("isolated"), ptrs("status"), c_plans,
            )
            if rc == -2:
                raise BuildError(f"the compiled campaign {sp.library}: a design isolated a class it does not have")
            if rc != 0:
                raise BuildError(f"the compiled campaign {sp.library} reported an internal error ({rc})")
        t = np.arange(n) * sp.Ts
        batch = None
        if keep is not None:
            U, Y, E = keep
            batch = Batch(scenario=sp.scenario, seeds=seeds, t=t, inputs=sp.inputs, outputs=sp.outputs, U=U, Y=Y,
                          extra={name: E[:, :, i] for i, name in enumerate(sp.extra)})
        chunk = ChunkRuns(seeds=seeds, t=t, designs=outs, batch=batch)
        if plans is None:
            return chunk, None
        summaries = {}
        for (d, nr, nj), bufs in zip(sp.designs, held, strict=True):
            counts, sums = bufs["counts"], bufs["sums"]
            fields = {name: counts[:, i].copy() for i, name in enumerate(SUMMARY_COUNTS)}
            summaries[d] = RunSummaries(
                **fields,
                exceed=counts[:, len(SUMMARY_COUNTS):].copy(),
                r_on=sums[:, :nr].copy(),
                r_off=sums[:, nr : 2 * nr].copy(),
                rr_off=sums[:, 2 * nr :].reshape(runs, nr, nr).copy(),
                histogram=[bufs["histogram"][j].copy() if bufs["binned"][j] else np.zeros(0, dtype=np.int64) for j in range(nj)],
            )
        return chunk, summaries


def _key(texts: Sequence[bytes]) -> str:
    h = hashlib.sha256()
    for b in texts:
        h.update(hashlib.sha256(b).digest())
    return h.hexdigest()


def build_library(model: SampleModel, built: Mapping[str, Built], directory: Path) -> tuple[Path, str]:
    """Generate and compile (unless already built) the fused library of ``model`` and ``built``; its path and key."""
    prefixes = []
    for name, b in built.items():
        gf = b.gain_file
        if tuple(gf.inputs) != tuple(model.inputs) or tuple(gf.outputs) != tuple(model.outputs):
            raise ArgumentError(
                f"design {name!r} reads inputs {list(gf.inputs)} and outputs {list(gf.outputs)}; "
                f"the simulation gives {list(model.inputs)} and {list(model.outputs)}"
            )
        prefixes.append(gf.name)
    if len(set(prefixes)) != len(prefixes):
        raise ArgumentError(f"two designs share a diagnoser name: {prefixes}")
    directory.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=directory, prefix=".staging-") as staging:
        _sim_source(model, Path(staging))
        sim_c = (Path(staging) / "fdisyn_sim.c").read_bytes()
    design_files = []
    for b in built.values():
        c_dir = Path(b.artifacts.c_dir)
        design_files += [c_dir / f"{b.gain_file.name}{s}" for s in (".c", ".h", "_casadi.c", "_casadi.h")]
    key = _key([sim_c, TEMPLATE.read_bytes(), Path(lanes.__file__).read_bytes(), " ".join([*compiler(), *CFLAGS, *LIBRARY_FLAGS]).encode()]
               + [gain_file_sha256(b.gain_file).encode() for b in built.values()] + [p.read_bytes() for p in design_files])
    out = directory / key[:16]
    lib = out / LIBRARY
    out.mkdir(exist_ok=True)
    with (out / ".lock").open("a") as lock:
        if fcntl is not None:  # processes building the same library wait for the first one's
            fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            _check_before_loading(lib, key)
        except BuildError:
            _compile(model, built, prefixes, out, key)
    return lib, key


def _compile(model: SampleModel, built: Mapping[str, Built], prefixes: Sequence[str], out: Path, key: str) -> None:
    lib = out / LIBRARY
    c_dir = out / "c"
    c_dir.mkdir(parents=True, exist_ok=True)
    _sim_source(model, c_dir)
    zk, zw, zf = ziggurat_tables()
    fn = model.step
    subs = {
        "NX": str(fn.size1_in(0)), "NZ": str(model.nz), "NU": str(len(model.inputs)), "NY": str(len(model.outputs)),
        "NE": str(len(model.extra)), "NP": str(fn.size1_in(3)), "ND": str(fn.size1_in(4)), "N0": str(model.n0),
        "ZIG_R": _c_double(ZIGGURAT_R),
        "ZIG_K": ", ".join(f"UINT64_C({int(v)})" for v in zk),
        "ZIG_W": ", ".join(_c_double(v) for v in zw),
        "ZIG_F": ", ".join(_c_double(v) for v in zf),
        "KEY": c_string_literal(key),
        **_design_code(prefixes),
        "LANE_PRELUDE": LANE_PRELUDE,
        "LANE_CODE": _lane_code(model, built)[0],
    }
    source = fresh_path(c_dir / "fdisyn_campaign.c")
    source.write_text(fill_template(TEMPLATE.read_text(encoding="utf-8"), subs, TEMPLATE.name), encoding="utf-8")
    includes = sorted({f"-I{Path(b.artifacts.c_dir).absolute()}" for b in built.values()})
    wrappers = [str(Path(b.artifacts.c_dir).absolute() / f"{b.gain_file.name}.c") for b in built.values()]
    tmp = fresh_path(out / f"{LIBRARY}.part")
    argv = [*compiler(), *CFLAGS, *LIBRARY_FLAGS, f"-I{c_dir.absolute()}", *includes, str(source.absolute()), *wrappers,
            "-o", str(tmp.absolute()), "-lm"]
    _finish(_start(argv, str(lib)), argv, str(lib))
    os.replace(tmp, fresh_path(lib))
    write_manifest(lib, key)


_LIBRARIES: dict[tuple[Any, ...], tuple[Any, SampleModel, Path, str]] = {}
"""Per process, the sample model and built library of each (sample model, options, folder, designs); the sample
model's function is kept with them, so its ``id`` in the key is never reused by another."""


def compiled_campaign(
    problem: Problem, built: Mapping[str, Built], scenario: str | Scenario, *, directory: str | Path | None = None, **options: Any
) -> CompiledCampaign | None:
    """The fused simulation and diagnosis of ``scenario`` for ``built``'s designs, or ``None`` when ``problem``
    has no sample model (its runs stay on the Python path).

    ``options`` are the problem's options (as for ``problem.run``); the
    library goes in ``directory`` (default: ``campaign/`` beside the first
    design's folder) under its content hash, and is reused when already built.
    With no design (``built`` empty) it only simulates (``directory`` needed).
    """
    if problem.sample_model is None:
        return None
    sc = problem.scenario(scenario) if isinstance(scenario, str) else scenario
    checked = problem.check_options(options)
    if directory is None and not built:
        raise ArgumentError("a compiled campaign without designs (simulation only) needs a directory for its library")
    where = Path(directory) if directory is not None else Path(next(iter(built.values())).directory).parent / "campaign"
    # one sample model and one library serve every scenario: generated, hashed and checked once per process
    memo = (id(problem.sample_model), repr(sorted(checked.items())), str(where.absolute()),
            tuple((d, gain_file_sha256(b.gain_file), str(Path(b.directory).absolute())) for d, b in built.items()))
    if memo not in _LIBRARIES:
        model = problem.sample_model(**checked)
        _LIBRARIES[memo] = (problem.sample_model, model, *build_library(model, built, where))
    _, model, lib, key = _LIBRARIES[memo]
    parameters = np.ascontiguousarray(model.parameters(sc), dtype=float).reshape(-1)
    if parameters.size != model.step.size1_in(3):
        raise ShapeError(f"scenario {sc.name!r} has {parameters.size} parameters; the sample model reads {model.step.size1_in(3)}")
    spec = CampaignSpec(
        library=lib,
        key=key,
        scenario=sc,
        designs=tuple((d, b.gain_file.step.nr, b.gain_file.step.nj) for d, b in built.items()),
        parameters=parameters,
        drive=model.drive_table(sc),
        window=model.window(sc),
        samples=model.samples(sc),
        Ts=model.Ts,
        nz=model.nz,
        n0=model.n0,
        inputs=tuple(model.inputs),
        outputs=tuple(model.outputs),
        extra=tuple(model.extra),
    )
    return CompiledCampaign(spec)
