"""``fdisyn bench``: what a step costs, measured, never asserted in tests.

For each problem's designs: the compiled step in a C loop (``bench.c``, the
fastest of 20 replays of a 10⁴-sample trace), the same library called per
sample and per trace through ctypes, the CasADi function called from Python,
and (linear diagnosers) the NumPy reference step. Results go to
``reports/bench.md`` with the machine and the versions; with ``sdp`` (the
full built-in bench, or ``--sdp``) also the SDP solve times of the LMI
toolkit, which take seconds and concern no problem in particular; with
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
from fdisyn.synthesis.lmi_observer import lmi_diagnostic_observer

__all__ = ["run_bench", "run_monte_carlo_bench", "monte_carlo_section", "machine_description"]


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


def run_bench(problems: list[Problem], *, out: Path, workdir: Path, sdp: bool = False, monte_carlo: bool = False) -> Path:
    """Measure and write the benchmark table, with ``sdp`` the SDP solve times (:func:`sdp_timings`) and with
    ``monte_carlo`` the Monte Carlo's throughput (:func:`monte_carlo_section`); return its path."""
    rows = []
    for prob in problems:
        batch = prob.run("fault_free", [0])
        reps = -(-10_000 // len(batch.t))  # short runs are repeated up to 10⁴ samples
        U, Y = np.tile(batch.U[0], (reps, 1))[:10_000], np.tile(batch.Y[0], (reps, 1))[:10_000]
        for d in tracked(prob.designs, f"bench {prob.name}: build and time", "design"):
            b = build(prob, d, workdir / "bench" / prob.name / d)
            gf = b.gain_file
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
            rows.append((prob.name, d, gf.step, c_ns, ctypes_run_ns, ctypes_ns, casadi_ns, numpy_ns))
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
        "one Python call per sample (fastest of 3 passes).",
        "",
        "| problem | design | nu/ny/nr/nj/nstate | C loop | ctypes, whole trace | ctypes, per sample | CasADi Function | NumPy reference | NumPy / C |",
        "|---|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    for name, d, spec, c_ns, run_ns, ct_ns, cas_ns, np_ns in rows:
        dims = f"{spec.nu}/{spec.ny}/{spec.nr}/{spec.nj}/{spec.nstate}"
        np_s = f"{np_ns:,.0f}" if np_ns is not None else "—"
        ratio = f"{np_ns / c_ns:,.0f}×" if np_ns is not None else "—"
        lines.append(f"| {name} | {d} | {dims} | {c_ns:,.1f} | {run_ns:,.1f} | {ct_ns:,.0f} | {cas_ns:,.0f} | {np_s} | {ratio} |")
    if monte_carlo:
        lines += monte_carlo_section(workdir=workdir)
    if sdp:
        lines += _sdp_section()
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return out


def _sdp_section() -> list[str]:
    """SDP solve times of the LMI toolkit for n = 2, 4, 8, 16 (the sampled-data design of Qiu, Wen &
    Jiang, Control Theory & Applications 27(8), 2010)."""
    rows = sdp_timings(sizes=(2, 4, 8, 16))
    lines = [
        "",
        "## SDP solve times (cvxpy + Clarabel)",
        "",
        "Random stable sampled-data plants with p = q = n (one input, one fault); Clarabel's own solve time in "
        "milliseconds, wall time including cvxpy's problem setup in parentheses. *Design*: the LMI synthesis of "
        "the diagnostic observer for η = ∞ (an observer-gain SDP and the post-filter SDPs).",
        "",
        "| n | H∞ norm | H2 norm | H₋ index | design (SDPs) |",
        "|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(
            f"| {r.n} | {1e3 * r.hinf_solve:.1f} ({1e3 * r.hinf_wall:.0f}) | {1e3 * r.h2_solve:.1f} | {1e3 * r.hminus_solve:.1f} "
            f"| {1e3 * r.design_solve:.0f} ({1e3 * r.design_wall:.0f} wall, {r.design_sdps} SDPs) |"
        )
    if len(rows) >= 2 and rows[-2].design_solve > 0:
        growth = np.log(rows[-1].design_solve / rows[-2].design_solve) / np.log(rows[-1].n / rows[-2].n)
        lines += ["", f"From n = {rows[-2].n} to {rows[-1].n} the design's solve time grows like n^{growth:.1f}."]
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
