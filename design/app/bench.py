"""``fdisyn bench``: what a step costs, measured, never asserted in tests.

For each problem's designs: the compiled step in a C loop (``bench.c``, the
fastest of 20 replays of a 10⁴-sample trace), the same library called per
sample and per trace through ctypes, the CasADi function called from Python,
and (linear diagnosers) the NumPy reference step. Results go to
``reports/bench.md`` with the machine and the versions; with ``sdp`` (the
full built-in bench, or ``--sdp``) also the SDP solve times of the LMI
toolkit (n = 2 to 32: minutes), which concern no problem in particular; with
``monte_carlo`` (the full built-in bench) the Monte Carlo's throughput (plant
steps per second, one core and every core) and peak memory
(:func:`monte_carlo_section`, alone: ``fdisyn bench --monte-carlo``).
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any
from datetime import datetime, timezone
from pathlib import Path

import casadi as ca
import numpy as np
import scipy.linalg as sla
from fdisyn.codegen.library import CFLAGS, compile_bench, compiler
from fdisyn.codegen.step import step_function
from fdisyn.evaluation.built import build
from fdisyn.evaluation.progress import tracked
from fdisyn.simulation.problem import Problem
from fdisyn.models.sampled_data import SampledDataPlant
from fdisyn.numerics.lmi_norms import h2_norm_lmi, hinf_norm_lmi, hminus_index_lmi
from fdisyn.runtime.reference import LinearReference
from fdisyn.synthesis.lmi_observer import GAIN_SDP_STATES, lmi_diagnostic_observer

__all__ = [
    "run_bench", "run_monte_carlo_bench", "monte_carlo_section", "machine_description", "scaling_section", "step_flops",
    "c_sizes", "matvec_peak", "MAIN_JOB_HEADING", "kept_section", "record_main_job",
]


def machine_description() -> dict[str, str]:
    cpu = platform.processor() or "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    cc = subprocess.run([*compiler(), "--version"], capture_output=True, text=True, check=False).stdout.splitlines()
    return {
        "cpu": cpu,
        "cores": str(os.cpu_count()),
        "os": platform.platform(),
        "compiler": cc[0] if cc else "unknown",
        "python": sys.version.split()[0],
        "numpy": np.__version__,
        "casadi": str(getattr(ca, "__version__", "unknown")),
    }


def _per_call(fn, n: int) -> float:  # noqa: ANN001 - any callable of the sample index
    best = float("inf")
    for _ in range(3):
        t0 = time.perf_counter()
        for k in range(n):
            fn(k)
        best = min(best, (time.perf_counter() - t0) / n)
    return best * 1e9


def run_bench(
    problems: list[Problem], *, out: Path, workdir: Path, sdp: bool = False, monte_carlo: bool = False, scaling: bool = False
) -> Path:
    """Measure and write the benchmark table, with ``sdp`` the SDP solve times (:func:`sdp_timings`), with
    ``monte_carlo`` the Monte Carlo's throughput (:func:`monte_carlo_section`) and with ``scaling`` the steps of
    random plants of 10 to 200 states (:func:`scaling_section`); return its path."""
    import shutil

    from fdisyn.evaluation.progress import phase_seconds

    rows = []
    for prob in problems:
        batch = prob.run("fault_free", [0])
        reps = -(-10_000 // len(batch.t))  # short runs are repeated up to 10⁴ samples
        U, Y = np.tile(batch.U[0], (reps, 1))[:10_000], np.tile(batch.Y[0], (reps, 1))[:10_000]
        for d in tracked(prob.designs, f"bench {prob.name}: build and time", "design"):
            where = workdir / "bench" / prob.name / d
            shutil.rmtree(where, ignore_errors=True)  # compiled afresh: its compile is measured
            before = phase_seconds().get((prob.name, "generate and compile"), 0.0)
            b = build(prob, d, where)
            compile_s = phase_seconds().get((prob.name, "generate and compile"), 0.0) - before
            gf = b.gain_file
            code, tables = c_sizes(b.artifacts.c_dir / f"{gf.name}_casadi.c")
            samples = workdir / "bench" / prob.name / d / "samples.bin"
            np.ascontiguousarray(np.hstack([U, Y]), dtype=np.float64).tofile(samples)
            exe = compile_bench(gf, b.artifacts.c_dir, workdir / "bench" / prob.name / d / "bench")
            proc = subprocess.run([str(exe), str(samples), "20"], capture_output=True, text=True, check=True)
            c_ns = float(proc.stdout.split()[1])
            cd = b.diagnoser
            st = cd.init_state()
            ctypes_ns = _per_call(lambda k, cd=cd, st=st, U=U, Y=Y: cd.step(st, U[k], Y[k]), 2000)
            t0 = time.perf_counter()
            cd.run(U, Y)
            ctypes_run_ns = (time.perf_counter() - t0) / len(Y) * 1e9
            fn = step_function(gf)
            cst = [gf.step.init_state.copy()]

            def casadi_call(k: int, fn=fn, cst=cst, U=U, Y=Y) -> None:  # noqa: ANN001 - bound loop values
                cst[0] = np.asarray(fn(cst[0], U[k], Y[k])[0]).ravel()

            casadi_ns = _per_call(casadi_call, 500)
            numpy_ns = None
            if gf.generators:  # a bank of linear generators: the runtime's NumPy reference step
                ref = LinearReference(gf)
                rst = ref.init_state()
                numpy_ns = _per_call(lambda k, ref=ref, rst=rst, U=U, Y=Y: ref.step(rst, U[k], Y[k]), 2000)
            rows.append((prob.name, d, gf.step, c_ns, ctypes_run_ns, ctypes_ns, casadi_ns, numpy_ns, code, tables, compile_s, step_flops(gf)))
    m = machine_description()
    lines = [
        "# fdisyn benchmark: cost of one diagnoser step",
        "",
        f"Measured by `fdisyn bench` on {datetime.now(timezone.utc).strftime('%Y-%m-%d %H:%M UTC')}.",
        "",
        "| machine | |",
        "|---|---|",
        *(f"| {k} | {v} |" for k, v in m.items()),
        f"| C flags | `{' '.join(CFLAGS)}` |",
        "",
        "Per sample, in nanoseconds. *C loop*: the generated step called from C over a 10⁴-sample trace (fastest of 20 "
        "replays). *ctypes, whole trace*: one call of `<prefix>_run` from Python. *ctypes, per sample*, *CasADi*, *NumPy*: "
        "one Python call per sample (fastest of 3 passes). *C code*: the generated `<prefix>_casadi.c` apart from its "
        "constant tables; *compile*: generating the sources and compiling the library and the replay program (two "
        "compilers side by side); *flops*: the products of one step as its C computes them (linear diagnosers, "
        "`fdisyn.app.bench.step_flops`).",
        "",
        "| problem | design | nu/ny/nr/nj/nstate | C loop | ctypes, whole trace | ctypes, per sample | CasADi Function | NumPy reference "
        "| NumPy / C | C code (KB) | tables (KB) | compile (s) | flops |",
        "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for name, d, spec, c_ns, run_ns, ct_ns, cas_ns, np_ns, code, tables, compile_s, flops in rows:
        dims = f"{spec.nu}/{spec.ny}/{spec.nr}/{spec.nj}/{spec.nstate}"
        np_s = f"{np_ns:,.0f}" if np_ns is not None else "—"
        ratio = f"{np_ns / c_ns:,.0f}×" if np_ns is not None else "—"
        fl = f"{flops:,}" if flops is not None else "—"
        lines.append(f"| {name} | {d} | {dims} | {c_ns:,.1f} | {run_ns:,.1f} | {ct_ns:,.0f} | {cas_ns:,.0f} | {np_s} | {ratio} "
                     f"| {code / 1e3:,.0f} | {tables / 1e3:,.0f} | {compile_s:.1f} | {fl} |")
    if scaling:
        lines += scaling_section(workdir)
    if monte_carlo:
        lines += monte_carlo_section(workdir=workdir)
    if sdp:
        lines += _sdp_section()
    lines += kept_section(out)  # the main job's own section, measured by `fdisyn reproduce`
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return out


MAIN_JOB_HEADING = "## The main job (`fdisyn reproduce`)"
"""The heading of the section of ``bench.md`` that the full main job writes (:func:`record_main_job`) and
:func:`run_bench` carries over."""


def _section(text: str, heading: str) -> tuple[int, int] | None:
    """Where the section under ``heading`` is in ``text`` (up to the next ``## `` heading or the end), or ``None``."""
    start = text.find("\n" + heading + "\n")
    if start < 0:
        return None
    nxt = text.find("\n## ", start + 1)
    return start, len(text) if nxt < 0 else nxt


def kept_section(path: Path, heading: str = MAIN_JOB_HEADING) -> list[str]:
    """The lines of the section under ``heading`` in the file at ``path`` (nothing when the file or the section is
    not there), for a rewrite of the file to keep it.

    Parameters
    ----------
    path : Path
        A Markdown file (``reports/bench.md``).
    heading : str
        The section's heading line.

    Returns
    -------
    list of str
        Its lines, the blank line before the heading first.
    """
    try:
        text = path.read_text(encoding="utf-8")
    except OSError:
        return []
    at = _section(text, heading)
    return [] if at is None else text[at[0] : at[1]].rstrip("\n").split("\n")


def record_main_job(path: Path, problems: Sequence[str]) -> Path:
    """Write the main job's time per problem and phase and its largest process (:func:`~fdisyn.app.pipeline.phase_table`
    of this process) as the section :data:`MAIN_JOB_HEADING` of the Markdown file at ``path`` (``reports/bench.md``),
    replacing that section where the file has one, else appended (the file made where there is none).

    Parameters
    ----------
    path : Path
        The benchmark file.
    problems : sequence of str
        The problems the main job ran, in order.

    Returns
    -------
    Path
        ``path``.
    """
    from fdisyn.app.pipeline import phase_table

    m = machine_description()
    lines = [
        "",
        MAIN_JOB_HEADING,
        "",
        f"Measured by `fdisyn reproduce` (every built-in problem, default runs) on "
        f"{datetime.now(timezone.utc).strftime('%Y-%m-%d %H:%M UTC')}, {m['cores']} cores ({m['cpu']}). Seconds per "
        "problem and phase; *Monte Carlo* includes compiling its fused libraries.",
        "",
        *phase_table(list(problems)).rstrip("\n").split("\n"),
    ]
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        text = "# fdisyn benchmark\n"
    at = _section(text, MAIN_JOB_HEADING)
    if at is not None:
        text = text[: at[0]] + text[at[1] :]
    text = text.rstrip("\n") + "\n" + "\n".join(lines) + "\n"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text, encoding="utf-8")
    return path


SDP_SIZES = (2, 4, 8, 16, 24, 32)
"""The state dimensions of the SDP section (:func:`sdp_timings`)."""


def _sdp_section() -> list[str]:
    """SDP solve times of the LMI toolkit for :data:`SDP_SIZES` (the sampled-data design of Qiu, Wen &
    Jiang, Control Theory & Applications 27(8), 2010)."""
    rows = sdp_timings(sizes=SDP_SIZES)
    lines = [
        "",
        "## SDP solve times (cvxpy + Clarabel)",
        "",
        "Random stable sampled-data plants with p = q = n (one input, one fault); Clarabel's own solve time in "
        "milliseconds, wall time including cvxpy's problem setup in parentheses. *Design*: the LMI synthesis of "
        "the diagnostic observer for η = ∞: the observer gain (an SDP up to "
        f"{GAIN_SDP_STATES} states, the predictor's DARE above), then the post-filter SDPs that follow the fault's "
        "peak. Clarabel holds each LMI's cone as a dense block of its k(k + 1)/2 entries squared (k the LMI's "
        "size), so an SDP's time grows like n⁶.",
        "",
        "| n | H∞ norm | H2 norm | H₋ index | design: gain | design (SDPs) |",
        "|---:|---:|---:|---:|:---|---:|",
    ]
    for r in rows:
        lines.append(
            f"| {r.n} | {1e3 * r.hinf_solve:.1f} ({1e3 * r.hinf_wall:.0f}) | {1e3 * r.h2_solve:.1f} | {1e3 * r.hminus_solve:.1f} "
            f"| {'DARE' if r.n > GAIN_SDP_STATES else 'SDP'} "
            f"| {1e3 * r.design_solve:.0f} ({1e3 * r.design_wall:.0f} wall, {r.design_sdps} SDPs) |"
        )
    return lines


@dataclass(frozen=True)
class TimingRow:
    """Solve times (seconds, Clarabel's clock; wall includes cvxpy) for one state dimension."""

    n: int
    hinf_solve: float
    hinf_wall: float
    h2_solve: float
    hminus_solve: float
    design_solve: float
    design_wall: float
    design_sdps: int


def sdp_timings(*, sizes: Sequence[int] = (2, 4, 8, 16), seed: int = 0) -> list[TimingRow]:
    """Measure SDP solve times for the norm LMIs and the design, per state dimension.

    For each ``n``: a seeded random stable plant (:func:`random_sampled_data_plant`) with ``p = n`` outputs and ``q = n``
    disturbances (so that κ stays moderate at n = 16), the H∞/H2/H₋ LMIs of
    ``G_dJ`` and the full design (:func:`lmi_diagnostic_observer`,
    ``η = "inf"``: the observer-gain SDP plus the peak-following post-filter
    SDPs). ``η = "-"`` is not timed: with a scalar fault the lifted fault
    channel is nearly rank one at n ≥ 8 (J*₋ ~ 1e7) and the SDP is ill posed.
    Times are not asserted anywhere; they are reported.
    """
    rng = np.random.default_rng(seed)
    rows = []
    for n in sizes:
        pl = random_sampled_data_plant(n=int(n), p=int(n), q=int(n), rng=rng)
        gd = pl.G_d()
        t0 = time.perf_counter()
        hi = hinf_norm_lmi(gd)
        hw = time.perf_counter() - t0
        h2 = h2_norm_lmi(gd)
        hm = hminus_index_lmi(gd.transpose())
        t0 = time.perf_counter()
        des = lmi_diagnostic_observer(plant=pl, eta="inf")
        dw = time.perf_counter() - t0
        rows.append(
            TimingRow(
                n=int(n),
                hinf_solve=hi.stats.solve_time if hi.stats else 0.0,
                hinf_wall=hw,
                h2_solve=h2.stats.solve_time if h2.stats else 0.0,
                hminus_solve=hm.stats.solve_time if hm.stats else 0.0,
                design_solve=float(sum(s.solve_time for s in des.stats)),
                design_wall=dw,
                design_sdps=len(des.stats),
            )
        )
    return rows


def random_sampled_data_plant(
    *, n: int, p: int, rng: np.random.Generator, q: int = 1, Ts: float = 0.5, stable: bool = True
) -> SampledDataPlant:
    """A random continuous plant with ``n`` states, ``p`` outputs, 1 input, ``q`` disturbances, 1 fault.

    With ``q = 1`` the lifted disturbance barely excites some directions within
    a sample and κ = cond(C X Cᵀ) can pass 1e10 already at ``n = p = 3``;
    ``q = n`` keeps it moderate (≤ ~1e6 at n = 16 in the timing runs).

    Eigenvalues ``−U(0.3, 2)`` or ``−U(0.3, 2) ± j·U(0.1, 1.5)`` in a random
    basis of condition ≤ 4; with ``|Im λ| < 1.5`` and ``Ts = 0.5`` the sampling is
    never pathological (that needs ``Ts·|Im(λ_i − λ_j)| = 2πk``).
    ``stable=False`` makes the first mode unstable (real part ``+U(0.06, 0.4)``).
    """
    blocks, k = [], 0
    while k < n:
        s = rng.uniform(0.3, 2.0) * (1 if stable or k else -0.2)
        if n - k >= 2 and rng.random() < 0.5:
            w = rng.uniform(0.1, 1.5)
            blocks.append(np.array([[-s, w], [-w, -s]]))
            k += 2
        else:
            blocks.append(np.array([[-s]]))
            k += 1
    qm, _ = np.linalg.qr(rng.standard_normal((n, n)))
    t = qm @ np.diag(rng.uniform(0.5, 2.0, n))
    a = t @ sla.block_diag(*blocks) @ np.linalg.inv(t)
    return SampledDataPlant.create(
        A=a,
        B=rng.standard_normal((n, 1)),
        E=rng.standard_normal((n, q)),
        Fx=rng.standard_normal((n, 1)),
        C=rng.standard_normal((p, n)),
        Ts=Ts,
    )


# --------------------------------------------------------------------------- steps that scale with the plant

_MATVEC = r"""
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <time.h>
#define N 256
static double a[N * N], x[N], y[N];
int main(void) {
    int i, j, r, reps = 2000;
    struct timespec t0, t1;
    double best = 1e30, s;
    for (i = 0; i < N * N; ++i) a[i] = 1e-3 * (i % 97);
    for (i = 0; i < N; ++i) x[i] = 1.0 + 1e-3 * i;
    for (r = 0; r < 5; ++r) {
        clock_gettime(CLOCK_MONOTONIC, &t0);
        for (s = 0; s < reps; ++s) {
            for (i = 0; i < N; ++i) y[i] = 0.0;
            for (j = 0; j < N; ++j) for (i = 0; i < N; ++i) y[i] += a[i + j * N] * x[j];
            x[(int)s % N] += 1e-12 * y[0];
        }
        clock_gettime(CLOCK_MONOTONIC, &t1);
        s = (t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec);
        if (s < best) best = s;
    }
    printf("%.6g\n", 2.0 * N * N * reps / best);
    return 0;
}
"""


def matvec_peak(workdir: Path) -> float:
    """Floating-point operations per second of a dense 256 × 256 matrix–vector product, column by column, compiled
    with the generated C's flags: the rate a table step's products can reach on this machine (its kernel is the
    same loop, ``casadi_mtimes_dense``), so ``flops / rate`` bounds a step's time from below.

    Parameters
    ----------
    workdir : Path
        Where the probe is compiled.

    Returns
    -------
    float
        Flop/s (the best of five timings).
    """
    d = Path(workdir) / "bench" / "matvec"
    d.mkdir(parents=True, exist_ok=True)
    (d / "matvec.c").write_text(_MATVEC, encoding="utf-8")
    subprocess.run([*compiler(), *CFLAGS, str(d / "matvec.c"), "-o", str(d / "matvec")], check=True, capture_output=True)
    return float(subprocess.run([str(d / "matvec")], check=True, capture_output=True, text=True).stdout)


def step_flops(gf: Any) -> int | None:
    """Floating-point operations of the products of one step of a linear diagnoser, as its C computes them: dense
    products (two flops per entry) in a table step, one multiply-add per nonzero in a straight-line step; the
    generators' products (with their equilibrium, computed every sample), a warm-up's gain, the statistics' weights
    and directions, the isolation test's basis and directions. ``None`` for other kinds.

    Parameters
    ----------
    gf : GainFile
        The diagnoser.

    Returns
    -------
    int or None
        The count.
    """
    from fdisyn.synthesis.linear_step import linear_step_function

    if not gf.generators:  # not a bank of linear generators
        return None
    dense = linear_step_function(gf).is_a("MXFunction")

    def cost(m: Any) -> int:
        a = np.asarray(m, dtype=float)
        return 2 * (a.size if dense and np.any(a) else int(np.count_nonzero(a)))

    total = 0
    for g in gf.generators:
        total += sum(cost(getattr(g, k)) for k in ("Ar", "Bu", "By", "Cr", "Du", "Dy", "Xu", "Xy"))
        if g.warmup:
            total += 2 * g.n_state * g.n_residual
    for e in gf.evaluators:
        total += cost(e.W) if e.W is not None else 0
        total += cost(e.directions) if getattr(e, "directions", None) is not None else 0
    iso = None if gf.decision is None else gf.decision.isolation
    if iso is not None:
        total += cost(iso.basis) + cost(iso.directions)
    return int(total)


def c_sizes(c_file: Path) -> tuple[int, int]:
    """The bytes of a generated ``<prefix>_casadi.c`` that are code, and those that are its constant tables (the
    ``static const`` arrays of numbers and sparsity patterns).

    Parameters
    ----------
    c_file : Path
        The file.

    Returns
    -------
    tuple of int
        ``(code, tables)``.
    """
    import re

    text = c_file.read_text(encoding="utf-8")
    tables = sum(len(t) for t in re.findall(r"static const casadi_(?:real|int) casadi_[cs]\d+\[\d+\] = \s*\{[^}]*\};", text))
    return len(text) - tables, tables


def scaling_plant(n: int, seed: int = 0, *, sensors: int | None = None, generators: int = 10) -> tuple[Any, dict[str, list[str]]]:
    """A seeded random stable plant and a bank of minimum-variance UIOs on it, each on every sensor but two (a
    generalised observer scheme).

    Parameters
    ----------
    n : int
        States.
    seed : int
        With ``n``, the random draws' seed.
    sensors : int, optional
        Outputs (default ``max(5, n // 5)``).
    generators : int
        The bank's generators; the ``i``-th leaves out sensors ``2i`` and ``2i + 1`` (modulo the sensors).

    Returns
    -------
    tuple
        ``(plant, bank)``: a :class:`~fdisyn.models.linear.LinearPlant` with 3 inputs and 2 unknown inputs, and the
        bank as ``fdisyn.design(..., bank=...)`` takes it.
    """
    from fdisyn.models.linear import LinearPlant

    rng = np.random.default_rng(seed + n)
    p = max(5, n // 5) if sensors is None else int(sensors)
    a = rng.standard_normal((n, n))
    a *= 0.95 / max(abs(np.linalg.eigvals(a)))
    mq, mr = rng.standard_normal((n, n)), rng.standard_normal((p, p))
    plant = LinearPlant.create(
        A=a, B=rng.standard_normal((n, 3)), C=rng.standard_normal((p, n)), E=rng.standard_normal((n, 2)),
        Q=mq @ mq.T / n + 0.05 * np.eye(n), R=mr @ mr.T / p + 0.05 * np.eye(p), Ts=0.1,
    )
    out = plant.outputs
    bank = {f"g{i}": [o for k, o in enumerate(out) if k not in (2 * i % p, (2 * i + 1) % p)] for i in range(generators)}
    return plant, bank


def scaling_section(workdir: Path, sizes: Sequence[int] = (10, 50, 100, 200)) -> list[str]:
    """Design, generate, compile and run a minimum-variance UIO bank on seeded random plants of ``sizes`` states
    (:func:`scaling_plant`): the times, the C's code and tables, the step's time beside its flop count and the flop
    bound at this machine's dense matrix–vector rate (:func:`matvec_peak`), and the largest process.

    Parameters
    ----------
    workdir : Path
        Where the builds go.
    sizes : sequence of int
        The plants' states.

    Returns
    -------
    list of str
        Markdown lines.
    """
    import resource

    import fdisyn
    from fdisyn.codegen.library import codegen
    from fdisyn.runtime.compiled import CompiledDiagnoser
    from fdisyn.runtime.gainfile import write_gain_file
    from fdisyn.runtime.validate import step_coefficients
    from fdisyn.runtime.warmup import warmup_coefficients

    peak = matvec_peak(workdir)
    rows = []
    for n in sizes:
        plant, bank = scaling_plant(int(n))
        t0 = time.perf_counter()
        gf = fdisyn.design(plant, method="kalman_uio", bank=bank, name=f"scaling{n}")
        t_design = time.perf_counter() - t0
        d = Path(workdir) / "bench" / "scaling" / str(n)
        write_gain_file(gf, d / "gains.json")
        t0 = time.perf_counter()
        art = codegen(d)
        t_build = time.perf_counter() - t0
        code, tables = c_sizes(art.c_dir / f"{gf.name}_casadi.c")
        U = np.random.default_rng(1).standard_normal((10_000, gf.step.nu))
        Y = np.random.default_rng(2).standard_normal((10_000, gf.step.ny))
        samples = d / "samples.bin"
        np.ascontiguousarray(np.hstack([U, Y]), dtype=np.float64).tofile(samples)
        exe = compile_bench(gf, art.c_dir, d / "bench")
        c_ns = float(subprocess.run([str(exe), str(samples), "5"], capture_output=True, text=True, check=True).stdout.split()[1])
        CompiledDiagnoser(art.library, gf).run(U[:100], Y[:100])
        flops = step_flops(gf) or 0
        warm = sum(warmup_coefficients(int(g.warmup), g.n_state, g.n_residual) for g in gf.generators)
        rows.append((n, plant.p, len(gf.generators), step_coefficients(gf.generators, gf.evaluators), warm, gf.step.nstate,
                     t_design, t_build, code, tables, c_ns, flops))
    rss = max(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
    lines = [
        "",
        "## Steps that scale with the plant",
        "",
        "A bank of 10 minimum-variance UIOs (each on every sensor but two) on seeded random stable plants with 3 inputs "
        "and 2 unknown inputs (`fdisyn.app.bench.scaling_plant`): the design (the Riccati gain above 16 reduced states), "
        "generating and compiling the library and the replay program, the C (code apart from its constant tables), and "
        "the step in a C loop (fastest of 5 replays of 10⁴ samples) beside its flop count and the flop bound at this "
        f"machine's dense matrix–vector rate at the same flags ({peak / 1e9:.2f} GFlop/s).",
        "",
        "| states | sensors | generators | coefficients | warm-up constants | nstate | design (s) | generate + compile (s) "
        "| C code (KB) | tables (MB) | step (µs) | flops | flop bound (µs) | step / bound |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for n, p, ng, coeffs, warm, nstate, td, tb, code, tables, c_ns, flops in rows:
        bound = flops / peak * 1e6
        lines.append(
            f"| {n} | {p} | {ng} | {coeffs:,} | {warm:,} | {nstate:,} | {td:.1f} | {tb:.1f} | {code / 1e3:.0f} | "
            f"{tables / 1e6:.1f} | {c_ns / 1e3:.2f} | {flops:,} | {bound:.2f} | {c_ns / 1e3 / bound:.1f}× |"
        )
    lines += ["", f"Largest process of the section: {rss / 2**20:.2f} GiB."]
    return lines


# --------------------------------------------------------------------------- Monte Carlo throughput

_RSS_CHILD = """
import json, resource, sys, time
from fdisyn.evaluation.built import load_built
from fdisyn.evaluation.evaluate import evaluate
from fdisyn.simulation.problem import get_problem
name, design, directory, scenario, runs = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4], int(sys.argv[5])
prob = get_problem(name)
t0 = time.perf_counter()
ev = evaluate(prob, {design: load_built(directory)}, runs=runs, scenarios=[scenario], workers=1, progress=False)
m = ev.metrics[design][scenario]
print(json.dumps({"seconds": time.perf_counter() - t0, "steps": m.runs * m.samples_per_run,
                  "maxrss_kib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss}))
"""


def monte_carlo_section(
    *, workdir: Path, runs: int = 100, rss_runs: Sequence[int] = (100, 10_000), problem: str = "wind_turbine",
    design: str = "kalman_uio", rss_scenario: str = "fault_free",
) -> list[str]:
    """Plant-steps per second of ``problem``/``design``'s Monte Carlo (simulation, compiled diagnoser and streaming
    metrics) over every scenario, on one core and on every core; and the peak resident memory of a campaign of each
    of ``rss_runs`` runs of ``rss_scenario`` on one core, measured in a child process of its own."""
    from fdisyn.evaluation.campaign import local_cores
    from fdisyn.evaluation.evaluate import evaluate
    from fdisyn.simulation.problem import get_problem

    prob = get_problem(problem)
    b = build(prob, design, workdir / "bench" / "monte_carlo" / problem / design)
    cores = local_cores()
    # the worker processes start and load the campaign here, a chunk of one run each
    evaluate(prob, {design: b}, runs=2 * cores, scenarios=[rss_scenario], chunk=1, workers=cores, progress=False)
    rates = []
    for workers in dict.fromkeys((1, cores)):
        t0 = time.perf_counter()
        ev = evaluate(prob, {design: b}, runs=runs, workers=workers)
        seconds = time.perf_counter() - t0
        steps = sum(m.runs * m.samples_per_run for m in ev.metrics[design].values())
        rates.append((workers, steps, seconds))
    from fdisyn.evaluation.compiled_campaign import compiled_campaign

    fused = compiled_campaign(prob, {design: b}, rss_scenario)
    vectors = {3: "AVX-512", 2: "AVX2", 1: "the baseline (SSE2 on x86-64)"}[fused.vector_level()] if fused else "none"
    rss = []
    for n in rss_runs:
        proc = subprocess.run(
            [sys.executable, "-c", _RSS_CHILD, problem, design, str(b.directory.absolute()), rss_scenario, str(n)],
            capture_output=True, text=True, check=True,
        )
        rss.append((n, json.loads(proc.stdout.strip().splitlines()[-1])))
    lines = [
        "",
        "## Monte Carlo throughput",
        "",
        f"`{problem}` / `{design}`, {runs} runs of each of its {len(prob.scenarios)} scenarios: simulation, the compiled "
        "diagnoser and the streaming metrics, per plant step (one sample of one run); the worker processes were started "
        "before the clock. The runs went eight at a time through "
        f"vectors of {vectors}.",
        "",
        "| processes | plant steps | seconds | plant steps / s |",
        "|---:|---:|---:|---:|",
        *(f"| {w} | {s:,} | {sec:,.1f} | {s / sec:,.0f} |" for w, s, sec in rates),
        "",
        f"Peak resident memory of a campaign of `{rss_scenario}` alone on one core, in a process of its own "
        "(`getrusage` `ru_maxrss`, imports and the compiled library included).",
        "",
        "| runs | plant steps | seconds | peak RSS (MiB) |",
        "|---:|---:|---:|---:|",
        *(f"| {n:,} | {r['steps']:,} | {r['seconds']:,.1f} | {r['maxrss_kib'] / 1024:,.0f} |" for n, r in rss),
    ]
    return lines


def run_monte_carlo_bench(*, out: Path, workdir: Path, runs: int = 100, rss_runs: Sequence[int] = (100, 10_000)) -> Path:
    """``fdisyn bench --monte-carlo``: the machine and the Monte Carlo throughput section alone; return the path."""
    lines = [
        "# fdisyn benchmark: Monte Carlo throughput",
        "",
        f"Measured by `fdisyn bench --monte-carlo` on {datetime.now(timezone.utc).strftime('%Y-%m-%d %H:%M UTC')}.",
        "",
        "| machine | |",
        "|---|---|",
        *(f"| {k} | {v} |" for k, v in machine_description().items()),
        *monte_carlo_section(workdir=workdir, runs=runs, rss_runs=rss_runs),
    ]
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return out
