"""Compiled Monte Carlo: the plant's simulation and every design's step, fused in one C call per chunk of runs.

A problem opts in with :attr:`fdisyn.simulation.problem.Problem.sample_model`: its
simulator described one sample at a time
(:class:`fdisyn.simulation.sample_models.SampleModel`), a CasADi function
``(x, z, k, p, d) ↦ (x⁺, u, y, e)``. The generated C driver
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
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np
from fdisyn.codegen import lanes
from fdisyn.codegen.lanes import build_widths, lane_function, lane_prelude, scalar_lanes
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
    local_cores,
    shared_library_flags,
)
from fdisyn.evaluation.built import Built
from fdisyn.evaluation.metrics import HISTOGRAM_EDGES, MetricsPlan, RunSummaries
from fdisyn.evaluation.runs import ChunkRuns, DesignRuns
from fdisyn.runtime.compiled import _check_before_loading, library_suffix, write_manifest
from fdisyn.runtime.errors import ArgumentError, BuildError, ShapeError
from fdisyn.runtime.gainfile import gain_file_sha256
from fdisyn.runtime.names import check_diagnoser_name
from fdisyn.simulation.problem import Batch, Problem, Scenario
from fdisyn.simulation.sample_models import SampleModel

try:
    import fcntl
except ImportError:  # Windows: no advisory locks; concurrent builds of one library are not guarded there
    fcntl = None  # type: ignore[assignment]

__all__ = [
    "ziggurat_tables",
    "generator_state",
    "CompiledCampaign",
    "compiled_campaign",
]

TEMPLATE = Path(__file__).with_name("campaign.c.in")

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
        ("nedges", ctypes.c_long), ("fault", ctypes.c_long)] + [(name, ctypes.c_void_p) for name in ("counts", "sums", "histogram")] + [
        ("nlag", ctypes.c_long)]


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


def _lane_code(model: SampleModel, built: Mapping[str, Built], scalar_designs: Collection[str] = ()) -> tuple[str, list[str]]:
    """The lane functions of the campaign (:mod:`fdisyn.codegen.lanes`): the simulation's and every design's step,
    as vectors where the function has a lane form and the design is not in ``scalar_designs``, else CasADi's scalar
    C per lane; and the names of the latter."""
    sim, faulty, _ = _sim_functions(model)
    functions = [("campaign_lane_sim", "fdisyn_sim", sim, True), ("campaign_lane_sim_faulty", "fdisyn_sim_faulty", faulty, True)]
    functions += [(f"campaign_lane_step{i}", f"{b.gain_file.name}_casadi_step", casadi_step(b.gain_file), d not in scalar_designs)
                  for i, (d, b) in enumerate(built.items())]
    code, scalar = [], []
    for name, symbol, fn, vector in functions:
        text = lane_function(fn, name, build_widths()) if vector else None
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
class LibraryScenario:
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

    Pickled as its :class:`LibraryScenario`: a worker process loads the library
    again from its path (after the manifest checks), never a ctypes handle.
    """

    def __init__(self, spec: LibraryScenario) -> None:
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
                    "sums": np.zeros((runs, 2 * nr + nr * nr + plan.lags * nr)),
                    "histogram": np.zeros((nj, len(HISTOGRAM_EDGES) + 1), np.int64),
                }
                held.append(bufs)
                for name, a in bufs.items():
                    setattr(c_plans[i], name, None if a is None or a.size == 0 else a.ctypes.data)
                c_plans[i].nedges = len(HISTOGRAM_EDGES)
                c_plans[i].nlag = int(plan.lags)
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
                rr_off=sums[:, 2 * nr : 2 * nr + nr * nr].reshape(runs, nr, nr).copy(),
                r_lag=sums[:, 2 * nr + nr * nr :].reshape(runs, plans[d].lags, nr).copy(),
                histogram=[bufs["histogram"][j].copy() if bufs["binned"][j] else np.zeros(0, dtype=np.int64) for j in range(nj)],
            )
        return chunk, summaries


def _key(texts: Sequence[bytes]) -> str:
    h = hashlib.sha256()
    for b in texts:
        h.update(hashlib.sha256(b).digest())
    return h.hexdigest()


def build_library(model: SampleModel, built: Mapping[str, Built], directory: Path, scalar: Collection[str] = ()) -> tuple[Path, str]:
    """Generate and compile (unless already built) the fused library of ``model`` and ``built``; its path and key.
    The designs in ``scalar`` call their CasADi step once per run (:func:`_lane_code`)."""
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
               + [gain_file_sha256(b.gain_file).encode() for b in built.values()] + [p.read_bytes() for p in design_files]
               + [repr([d in scalar for d in built]).encode(), repr(build_widths()).encode()])
    out = directory / key[:16]
    lib = out / LIBRARY
    out.mkdir(exist_ok=True)
    with (out / ".lock").open("a") as lock:
        if fcntl is not None:  # processes building the same library wait for the first one's
            fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            _check_before_loading(lib, key)
        except BuildError:
            _compile(model, built, prefixes, out, key, scalar)
    return lib, key


def _compile(model: SampleModel, built: Mapping[str, Built], prefixes: Sequence[str], out: Path, key: str, scalar: Collection[str]) -> None:
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
        "LANE_PRELUDE": lane_prelude(build_widths()),
        "LANE_CODE": _lane_code(model, built, scalar)[0],
    }
    source = fresh_path(c_dir / "fdisyn_campaign.c")
    source.write_text(fill_template(TEMPLATE.read_text(encoding="utf-8"), subs, TEMPLATE.name), encoding="utf-8")
    includes = sorted({f"-I{Path(b.artifacts.c_dir).absolute()}" for b in built.values()})
    wrappers = [Path(b.artifacts.c_dir).absolute() / f"{b.gain_file.name}.c" for b in built.values()]
    # one object per source, compiled side by side on this process's cores, then linked: the same translation units
    # as one compiler command would make, so the same code
    objects = out / "obj"
    objects.mkdir(exist_ok=True)
    compile_flags = [f for f in LIBRARY_FLAGS if f not in LINK_ONLY_FLAGS]
    jobs = []
    for i, src in enumerate([source.absolute(), *wrappers]):
        obj = fresh_path(objects / f"{i}.o")
        argv = [*compiler(), *CFLAGS, *compile_flags, f"-I{c_dir.absolute()}", *includes, "-c", str(src), "-o", str(obj.absolute())]
        jobs.append((argv, obj, objects / f"{i}.log"))
    running: list[tuple[Any, list[str], Path]] = []
    try:
        for argv, obj, log in jobs:
            if len(running) >= local_cores():
                _wait(running.pop(0), str(lib))
            running.append((_start(argv, str(lib)), argv, log))
        while running:
            _wait(running.pop(0), str(lib))
    finally:
        for proc, _, _ in running:  # a compile failed or was interrupted: none is left running
            proc.kill()
            proc.wait()
    tmp = fresh_path(out / f"{LIBRARY}.part")
    argv = [*compiler(), *LIBRARY_FLAGS, *(str(obj.absolute()) for _, obj, _ in jobs), "-o", str(tmp.absolute()), "-lm"]
    _finish(_start(argv, str(lib)), argv, str(lib), log=c_dir / "build.log")
    os.replace(tmp, fresh_path(lib))
    write_manifest(lib, key)


LINK_ONLY_FLAGS = ("-shared", "-dynamiclib")
"""The flags of :data:`LIBRARY_FLAGS` that only the link reads (a compiler may warn of them beside ``-c``)."""


def _wait(job: tuple[Any, list[str], Path], what: str) -> None:
    """Wait for one object's compile (:func:`~fdisyn.codegen.library._finish`), its output in its own log."""
    proc, argv, log = job
    _finish(proc, argv, what, log=log)


_LIBRARIES: dict[tuple[Any, ...], tuple[Any, SampleModel, Path, str]] = {}
"""Per process, the sample model and built library of each (sample model, options, folder, designs); the sample
model's function is kept with them, so its ``id`` in the key is never reused by another."""


def compiled_campaign(
    problem: Problem, built: Mapping[str, Built], scenario: str | Scenario, *, directory: str | Path | None = None,
    scalar: Collection[str] = (), **options: Any,
) -> CompiledCampaign | None:
    """The fused simulation and diagnosis of ``scenario`` for ``built``'s designs, or ``None`` when ``problem``
    has no sample model (its runs stay on the Python path).

    ``options`` are the problem's options (as for ``problem.run``); the
    library goes in ``directory`` (default: ``campaign/`` beside the first
    design's folder) under its content hash, and is reused when already built.
    With no design (``built`` empty) it only simulates (``directory`` needed). The designs in ``scalar`` call
    their CasADi step once per run rather than through a vector form (:func:`_lane_code`).
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
            tuple((d, gain_file_sha256(b.gain_file), str(Path(b.directory).absolute()), d in scalar) for d, b in built.items()),
            build_widths())
    if memo not in _LIBRARIES:
        model = problem.sample_model(**checked)
        _LIBRARIES[memo] = (problem.sample_model, model, *build_library(model, built, where, scalar))
    _, model, lib, key = _LIBRARIES[memo]
    parameters = np.ascontiguousarray(model.parameters(sc), dtype=float).reshape(-1)
    if parameters.size != model.step.size1_in(3):
        raise ShapeError(f"scenario {sc.name!r} has {parameters.size} parameters; the sample model reads {model.step.size1_in(3)}")
    spec = LibraryScenario(
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
