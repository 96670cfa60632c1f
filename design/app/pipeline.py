"""The main job: design, verify, export, compile, check, simulate, evaluate, report.

``reproduce_problem`` runs every design of a problem (for each of the
problem's report variants, e.g. parameter sets) through the whole pipeline and
writes ``reports/<problem>/index.html``. The generated C of every design is
checked against the Python references on a 10⁴-sample trace with injected
non-finite samples before any metric is computed: an export that disagrees is
an error, not a footnote.
"""

from __future__ import annotations

import json
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np
from fdisyn.app import WORKDIR
from fdisyn.codegen.step import step_function
from fdisyn.detectors.table import DETECTORS
from fdisyn.evaluation.campaign import problem_source
from fdisyn.evaluation.built import Built, build, threshold_copies
from fdisyn.evaluation.evaluate import Evaluation, evaluate
from fdisyn.evaluation.progress import phase, tracked
from fdisyn.evaluation.metrics import ISOLATION_MARGIN
from fdisyn.simulation.problem import Problem, scaled_scenario
from fdisyn.runtime.errors import ArgumentError, CertificateError
from fdisyn.runtime.gainfile import GainFile
from fdisyn.runtime.layout import linear_state_layout
from fdisyn.runtime.reference import RunResult
from fdisyn.synthesis.kinds import reference_run

__all__ = ["PHASES", "phase_table", "EXPORT_TOL", "ExportCheck", "check_export", "FaultSizeSweep", "fault_size_sweep", "VariantResult", "reproduce_problem"]

EXPORT_TOL = 1e-12
"""Agreement required between the C step and each Python reference over a
10⁴-sample trace, normwise relative to the rounding-error scale of each
output (see :func:`check_export`). The references evaluate the same
arithmetic in another order, so they may differ by a few ulps of that scale:
~1e-15 for the diagnosers here."""


@dataclass(frozen=True)
class ExportCheck:
    """How closely the compiled step reproduced the Python references."""

    samples: int
    nonfinite_samples: int
    references: dict[str, dict[str, float | bool]]

    @property
    def passed(self) -> bool:
        return all(
            v["decisions_equal"] and max(v["r"], v["J"], v["state"]) <= EXPORT_TOL for v in self.references.values()
        )

    def to_dict(self) -> dict[str, Any]:
        return {"samples": self.samples, "nonfinite_samples": self.nonfinite_samples, "tolerance": EXPORT_TOL, "references": self.references, "passed": self.passed}

    def published(self) -> dict[str, Any]:
        """What a committed report keeps: for each reference whether the decisions are equal and every normwise
        difference is within :data:`EXPORT_TOL`. The differences themselves are round-off whose digits change with
        the CPU's BLAS kernel (2·10⁻¹⁷ on one, 4·10⁻¹⁷ on another); the build folder keeps them
        (``export_check.json``)."""
        refs = {
            name: {"decisions_equal": bool(x["decisions_equal"]), "within_tolerance": max(x["r"], x["J"], x["state"]) <= EXPORT_TOL}
            for name, x in self.references.items()
        }
        return {"samples": self.samples, "nonfinite_samples": self.nonfinite_samples, "tolerance": EXPORT_TOL, "references": refs, "passed": self.passed}


RUN_CHUNK = 64
"""Samples per call of the CasADi step's ``mapaccum`` in :func:`_casadi_run`: one call over a whole 10⁴-sample
trace made CasADi hold gigabytes for a large step (the turbofan's GLR bank, 11 533 state entries: 4.9 GB at 10³
samples); chunks keep it to one chunk's outputs at the speed of one call per sample or better."""


def _casadi_run(fn: ca.Function, init: np.ndarray, U: np.ndarray, Y: np.ndarray, rows: np.ndarray | None = None) -> tuple[RunResult, np.ndarray]:
    """The CasADi step over a trace, ``mapaccum`` threading the state through chunks of :data:`RUN_CHUNK` samples; also
    the state each sample starts from, its ``rows`` (default all), ``len(rows) × N``."""
    n = Y.shape[0]
    rows = np.arange(len(init)) if rows is None else np.asarray(rows, dtype=int)
    acc = fn.mapaccum("run", min(RUN_CHUNK, max(n, 1)))
    state = np.asarray(init, dtype=float)
    before = np.empty((len(rows), n))
    parts: list[list[np.ndarray]] = [[] for _ in range(5)]
    for k0 in range(0, n, RUN_CHUNK):
        k1 = min(k0 + RUN_CHUNK, n)
        if k1 - k0 != acc.size2_in(1):  # the last, shorter chunk
            acc = fn.mapaccum("run", k1 - k0)
        out = acc(state, U[k0:k1].T, Y[k0:k1].T)
        states = np.asarray(out[0])
        before[:, k0] = state[rows]
        before[:, k0 + 1 : k1] = states[rows, :-1]
        state = states[:, -1]
        for q in range(5):
            parts[q].append(np.asarray(out[q + 1]))
    res = RunResult(
        r=np.hstack(parts[0]).T,
        J=np.hstack(parts[1]).T,
        alarm=np.hstack(parts[2]).ravel().astype(int),
        isolated=np.rint(np.hstack(parts[3]).ravel()).astype(int),
        status=np.hstack(parts[4]).ravel().astype(int),
        state=state,
    )
    return res, before


def _scale_rows(gf: GainFile) -> np.ndarray:
    """The state entries :func:`_rounding_scale` reads: each generator's state and its ready count."""
    if not gf.generators:
        return np.zeros(0, dtype=int)
    lay = linear_state_layout(gf.generators, gf.evaluators, gf.decision)
    names = ["ready", *(f"xi{g}" for g in range(len(gf.generators)))]
    return np.concatenate([np.arange(lay[nm].start, lay[nm].stop) for nm in names])


def _rounding_scale(gf: GainFile, before: np.ndarray, res: RunResult, U: np.ndarray, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per sample and component, the magnitudes whose rounding errors make ``r`` and ``J``; ``before``: the state
    entries :func:`_scale_rows` names at the start of each sample (:func:`_casadi_run`).

    A linear generator computes ``r = Cr ξ + Du u + Dy y``, whose rounding
    error is bounded by a few ulps of ``s_r = |Cr||ξ| + |Du||u| + |Dy||y|``;
    ``J = rᵀ W r`` then errs by up to ``s_J = |r|ᵀ|W|(|r| + 2 s_r)`` times
    the same factor; a windowed statistic (WSSR) sums that scale over its window (the
    last ``window`` samples its generator evaluated). A residual that is a
    small difference of large terms (an integrating state, a large operating
    point) is compared against its terms, not against itself. A CUSUM or GLR
    statistic is a sum clamped to ``[0, 2h]`` or over a window, of terms of
    its own size, ``|J| + h``, each computed from the residuals: the terms'
    scales (that of ``rᵀ W r``) add up since the CUSUM last restarted from 0,
    or over the GLR's window (:func:`_sum_memory`). A diagnoser without linear
    generators: ``|r|`` and ``|J|``.
    """
    if not gf.generators:
        return np.abs(res.r), np.abs(res.J)
    lay = linear_state_layout(gf.generators, gf.evaluators, gf.decision)
    at = {int(r): i for i, r in enumerate(_scale_rows(gf))}

    def entries(name: str) -> np.ndarray:
        return before[[at[r] for r in range(lay[name].start, lay[name].stop)]]

    us, ys = np.nan_to_num(U, nan=0.0, posinf=0.0, neginf=0.0), np.nan_to_num(Y, nan=0.0, posinf=0.0, neginf=0.0)
    s_r = np.zeros_like(res.r)
    s_j = np.zeros_like(res.J)
    k = 0
    for g, gen in enumerate(gf.generators):
        ready = entries("ready")[g] != 0.0
        xi = np.where(ready[None, :], entries(f"xi{g}"), gen.Xu @ us.T + gen.Xy @ ys.T)
        block = (np.abs(gen.Cr) @ np.abs(xi) + np.abs(gen.Du) @ np.abs(us.T) + np.abs(gen.Dy) @ np.abs(ys.T)).T
        rows = slice(k, k + gen.n_residual)
        s_r[:, rows] = block
        r_abs = np.abs(res.r[:, rows])
        for j, ev in enumerate(gf.evaluators):
            if ev.generator == g:
                s_j[:, j] = np.einsum("ki,ij,kj->k", r_abs, np.abs(ev.W), r_abs + 2.0 * block)
                detector = DETECTORS[ev.kind]
                if detector.sequential:
                    # clamped (CUSUM) or windowed (GLR) sums of terms of the size of J and h, each term computed from
                    # the residuals: its own rounding, of |J| + h, and the residuals' errors the terms carry (their
                    # first-order part, 2 |r|ᵀ|W| s_r) added up over the sum's memory
                    carried = 2.0 * np.einsum("ki,ij,kj->k", r_abs, np.abs(ev.W), block)
                    memory = _sum_memory(carried, res.J[:, j], ev.window if detector.windowed else None, 2.0 * ev.threshold)
                    s_j[:, j] = np.abs(res.J[:, j]) + ev.threshold + memory
                elif detector.windowed:  # a sum of q over the window (WSSR): the window's errors add up
                    valid = np.all(np.isfinite(U), axis=1) & np.all(np.isfinite(Y[:, list(gen.outputs_used)]), axis=1)
                    summed = np.convolve(s_j[valid, j], np.ones(ev.window))[: int(np.sum(valid))]
                    s_j[:, j] = 0.0
                    s_j[valid, j] = summed
        k += gen.n_residual
    return s_r, s_j


def _sum_memory(terms: np.ndarray, J: np.ndarray, window: int | None, clamp: float) -> np.ndarray:
    """The rounding scale a sequential statistic carries from its past terms (``terms``: each sample's, from the
    residuals): their sum over the last ``window`` samples (GLR), or since the statistic was last clamped (a CUSUM
    at 0 or at its ceiling ``clamp``, twice its threshold, holds no error there)."""
    if window is not None:
        return np.convolve(terms, np.ones(int(window)))[: len(terms)]
    out, total = np.empty_like(terms), 0.0
    for k, (term, value) in enumerate(zip(terms, J, strict=True)):
        total = 0.0 if value in (0.0, clamp) else total + term
        out[k] = total
    return out


def _relative(a: np.ndarray, b: np.ndarray, scale: np.ndarray) -> float:
    ns = float(np.linalg.norm(scale))
    return float(np.linalg.norm(a - b)) / ns if ns > 0 else float(np.linalg.norm(a - b))


def _state_scale(gf: GainFile, state: np.ndarray, r: np.ndarray) -> np.ndarray:
    """The rounding-error scale of the final state: its magnitude, and for the isolation test's evidence
    ``z ← λ z + B r`` the forgotten sum of the scales it adds, ``Σ λ^{n−k} |B| s_r(k)`` with ``r`` the residuals'
    rounding scale ``s_r`` of :func:`_rounding_scale` (the evidence may be a small difference of large terms)."""
    scale = np.abs(np.asarray(state, dtype=float))
    iso = None if gf.decision is None else gf.decision.isolation
    if iso is None:
        return scale
    lay = linear_state_layout(gf.generators, gf.evaluators, gf.decision)
    basis = np.abs(np.asarray(iso.basis))
    acc = np.zeros(basis.shape[0])
    for row in np.abs(np.nan_to_num(r, nan=0.0, posinf=0.0, neginf=0.0)):
        acc = iso.forgetting * acc + basis @ row
    ev = lay["evidence"]
    scale[ev] = np.maximum(scale[ev], acc)
    return scale


def check_export(b: Built, U: np.ndarray, Y: np.ndarray) -> ExportCheck:
    """Compare the compiled step with the CasADi step and with its kind's independent NumPy reference, where it has one
    (:func:`fdisyn.synthesis.kinds.reference_run`).

    ``r`` and ``J``: ``‖C − reference‖ / ‖s‖`` over the whole trace, ``s`` the
    rounding-error scale of :func:`_rounding_scale`; ``state``: normwise
    relative after the last sample (to :func:`_state_scale`). Alarms, isolations and the per-sample
    status must be equal.
    """
    gf = b.gain_file
    c_res = b.diagnoser.run(U, Y)
    cas, states = _casadi_run(step_function(gf), gf.step.init_state, U, Y, _scale_rows(gf))
    refs: dict[str, RunResult] = {"casadi": cas}
    numpy_run = reference_run(gf, U, Y)
    if numpy_run is not None:
        refs["numpy"] = numpy_run
    s_r, s_j = _rounding_scale(gf, states, cas, U, Y)
    table: dict[str, dict[str, float | bool]] = {}
    for name, ref in refs.items():
        table[name] = {
            "r": _relative(c_res.r, ref.r, s_r),
            "J": _relative(c_res.J, ref.J, s_j),
            "state": _relative(c_res.state, ref.state, _state_scale(gf, ref.state, s_r)),
            "decisions_equal": bool(
                np.array_equal(c_res.alarm, ref.alarm)
                and np.array_equal(c_res.isolated, ref.isolated)
                and np.array_equal(c_res.status, ref.status)
            ),
        }
    return ExportCheck(samples=len(Y), nonfinite_samples=c_res.nonfinite_samples, references=table)


def export_trace(problem: Problem, samples: int = 10_000, **options: Any) -> tuple[np.ndarray, np.ndarray]:
    """A 10⁴-sample check trace: the first faulty scenario (else fault-free), seed 0,
    with NaN and ±inf written into a few inputs and outputs."""
    faulty = [s for s in problem.scenarios.values() if s.fault is not None]
    sc = faulty[0] if faulty else next(iter(problem.scenarios.values()))
    batch = problem.run(sc, [0], **options)
    U, Y = batch.U[0].copy(), batch.Y[0].copy()
    if len(Y) < samples:
        reps = -(-samples // len(Y))
        U, Y = np.tile(U, (reps, 1)), np.tile(Y, (reps, 1))
    U, Y = U[:samples].copy(), Y[:samples].copy()
    rng = np.random.default_rng(12345)
    for k in rng.choice(samples, size=min(6, samples), replace=False):
        j = int(rng.integers(Y.shape[1]))
        Y[k, j] = [np.nan, np.inf, -np.inf][int(rng.integers(3))]
    if U.shape[1]:
        U[int(rng.integers(samples)), 0] = np.nan
    return U, Y


SWEEP_DETECTION_GRID = (0.25, 0.5, 1.0, 2.0)
"""The sizes on which the sweep seeks the smallest size detected in 95 % of the runs (multiples of each faulty
scenario's; 1 is the scenario itself)."""

SWEEP_FACTORS = tuple(sorted({*SWEEP_DETECTION_GRID, *(ISOLATION_MARGIN * f for f in SWEEP_DETECTION_GRID)} - {1.0}))
"""Fault sizes of the report's sweep: the detection grid and each of its sizes times the isolation margin
(:func:`~fdisyn.evaluation.metrics.isolation_at_size`), 0.25–3 × each faulty scenario's (1, the scenario itself,
is the page's own Monte Carlo)."""

SWEEP_RUNS = 20
"""Runs per scaled scenario of the sweep (at most the page's runs)."""


@dataclass(frozen=True, eq=False)
class FaultSizeSweep:
    """The faulty scenarios with their fault scaled: ``scenarios[base][factor]`` names the scaled copy of
    ``base`` in ``evaluation``."""

    factors: tuple[float, ...]
    scenarios: Mapping[str, Mapping[float, str]]
    evaluation: Evaluation
    detection_grid: tuple[float, ...] = SWEEP_DETECTION_GRID


def fault_size_sweep(
    problem: Problem, built: Mapping[str, Built], *, runs: int, scenarios: Sequence[str] | None = None, workers: int | None = None,
    client: Any = None, source: str | Path | None = None, **options: Any
) -> FaultSizeSweep | None:
    """Monte Carlo of each faulty scenario scaled by :data:`SWEEP_FACTORS` (``Problem.scaled``, else
    :func:`~fdisyn.simulation.problem.scaled_scenario`); ``None`` when no scenario's fault has a size. ``workers``,
    ``client``, ``source``: where it runs (:func:`~fdisyn.evaluation.evaluate.evaluate`)."""
    scale = problem.scaled or scaled_scenario
    copies: dict[str, Any] = {}
    by_base: dict[str, dict[float, str]] = {}
    for name in scenarios if scenarios is not None else list(problem.scenarios):
        sc = problem.scenario(name)
        for k in SWEEP_FACTORS:
            scaled = scale(sc, k) if sc.fault is not None else None
            if scaled is None:
                break
            copies[scaled.name] = scaled
            by_base.setdefault(name, {})[k] = scaled.name
    if not copies:
        return None
    src = problem_source(problem) if source is None else source  # the workers rebuild the scaled scenarios from the spec
    ev = evaluate(replace(problem, scenarios=copies), built, runs=runs, workers=workers, client=client, source=src, **options)
    return FaultSizeSweep(factors=SWEEP_FACTORS, scenarios=by_base, evaluation=ev)


SHIFT_SIGMAS = (0.25, 0.5, 1.0, 2.0, 4.0)
"""Whitened mean shifts (σ of the residual, ``√(2 I)`` with ``I`` the fault's information per sample) of the
report's delay-against-shift sweep."""

SHIFT_RUNS = 20
"""Runs per fault size of that sweep (at most the variant's runs)."""

SHIFT_SPAN = 5.0
"""The fault of that sweep acts for at least this many Lorden bounds at its smallest shift (the scenario is
lengthened where it is shorter): a detector within 1.5 bounds then detects in nearly every run."""


@dataclass(frozen=True, eq=False)
class ShiftSweep:
    """One variant's sequential designs on ``scenario`` at the fault sizes that shift their whitened residual by
    ``sigmas``: ``metrics[design][σ]``, each design with its own sizes (``factors[design][σ]``, × the scenario's)."""

    scenario: str
    sigmas: tuple[float, ...]
    factors: Mapping[str, Mapping[float, float]]
    metrics: Mapping[str, Mapping[float, Any]]
    runs: int


def shift_sweep(
    problem: Problem, built: Mapping[str, Built], evaluation: Evaluation, *, runs: int, workers: int | None = None,
    client: Any = None, source: str | Path | None = None, **options: Any
) -> ShiftSweep | None:
    """The delay of each design with sequential statistics (CUSUM, GLR) against the shift of its whitened residual.

    The fault of :attr:`Problem.shift_scenario` shifts the residual by ``s₁ = √(2 I)`` σ in ``evaluation`` (``I``
    the information per sample the Monte Carlo measured); a bias scaled by ``k`` shifts it by ``k s₁``, so each
    design runs the scenario at ``k = s / s₁`` for ``s`` in :data:`SHIFT_SIGMAS`.

    Parameters
    ----------
    problem : Problem
        The problem (its ``shift_scenario`` names the scenario; ``None``: no sweep).
    built : Mapping of str to Built
        The variant's designs.
    evaluation : Evaluation
        The variant's Monte Carlo, which ran the scenario.
    runs : int
        Runs per size.
    workers, client, source
        Where it runs (:func:`~fdisyn.evaluation.evaluate.evaluate`).
    **options
        The variant's options.

    Returns
    -------
    ShiftSweep or None
        ``None`` without a scenario, or when no design has sequential statistics that see its fault.
    """
    name = problem.shift_scenario
    if name is None:
        return None
    scale = problem.scaled or scaled_scenario
    base = problem.scenario(name)
    src = problem_source(problem) if source is None else source
    factors: dict[str, dict[float, float]] = {}
    metrics: dict[str, dict[float, Any]] = {}
    for d, b in built.items():
        evs = b.gain_file.evaluators or ()
        if not any(DETECTORS[ev.kind].sequential for ev in evs) or name not in evaluation.metrics.get(d, {}):
            continue
        info = evaluation.metrics[d][name].fault_information
        if not info or info <= 0:
            continue
        s1 = float(np.sqrt(2.0 * info))
        # the fault acts for at least SHIFT_SPAN Lorden bounds at the smallest shift (the bound grows as 1/s²)
        bound1 = evaluation.metrics[d][name].lorden_bound_samples
        active = (base.end if base.end is not None else base.duration) - float(base.onset or 0.0)
        need = SHIFT_SPAN * float(bound1 or 0.0) * (s1 / min(SHIFT_SIGMAS)) ** 2 * float(b.gain_file.Ts)
        longer = max(0.0, need - active)
        copies = {}
        for s in SHIFT_SIGMAS:
            sc = scale(base, s / s1)
            if sc is None:
                break
            copies[s] = replace(sc, name=f"{name}_{s:g}sigma", duration=sc.duration + longer,
                                end=None if sc.end is None else sc.end + longer)
        if len(copies) < len(SHIFT_SIGMAS):
            continue
        ev = evaluate(replace(problem, scenarios={c.name: c for c in copies.values()}), {d: b}, runs=runs, workers=workers,
                      client=client, source=src, **options)
        factors[d] = {s: s / s1 for s in copies}
        metrics[d] = {s: ev.metrics[d][c.name] for s, c in copies.items()}
    if not metrics:
        return None
    return ShiftSweep(scenario=name, sigmas=SHIFT_SIGMAS, factors=factors, metrics=metrics, runs=runs)


@dataclass(frozen=True, eq=False)
class VariantResult:
    """One report variant (e.g. a parameter set): its builds, checks and evaluation."""

    label: str
    options: Mapping[str, Any]
    built: Mapping[str, Built]
    exports: Mapping[str, ExportCheck]
    evaluation: Evaluation
    seconds: float
    sweep: FaultSizeSweep | None = None
    """Detection against the fault's size (the main variant only)."""
    shifts: ShiftSweep | None = None
    """The sequential designs' delay against their whitened shift (:func:`shift_sweep`)."""


def variant_specs(
    problem: Problem, runs: int, given: int | None = None
) -> list[tuple[str, dict[str, Any], Sequence[str] | None, list[str], int]]:
    """The report variants of ``problem`` as the main job runs them: ``(label, options, scenarios, designs, runs)``.

    The main variant (``"default"``) first, with every design and ``runs``; then each of ``problem.variants``,
    which may name its own designs, scenarios (``None``: every one) and runs (``given``, the user's ``--runs``,
    wins over a variant's own).

    Parameters
    ----------
    problem : Problem
        The built-in problem.
    runs : int
        Monte Carlo runs per scenario of the main variant (and of a variant that names none).
    given : int or None
        The runs the user asked for, if any.

    Returns
    -------
    list of tuple
        One ``(label, options, scenarios, designs, runs)`` per variant, in the report's order.
    """
    return [("default", {}, None, list(problem.designs), runs)] + [
        (v["label"], dict(v.get("options", {})), v.get("scenarios"), list(v.get("designs", list(problem.designs))), int(given or v.get("runs", runs)))
        for v in problem.variants
    ]


def reproduce_problem(
    problem: Problem, *, runs: int | None = None, reports: Path = Path("reports"), workdir: Path = WORKDIR,
    variants: Sequence[str] | None = None, workers: int | None = None, client: Any = None, source: str | Path | None = None,
) -> Path:
    """Run the whole pipeline for ``problem`` and write its report; return the page's path.

    ``variants``: the labels of the report variants to run (``"default"`` the main one; ``None``: all);
    ``workers``, ``client``, ``source``: where the Monte Carlo runs (:func:`~fdisyn.evaluation.evaluate.evaluate`)."""
    from fdisyn.reporting.page import variant_tag, write_index, write_report

    given = runs
    runs = problem.monte_carlo_runs if runs is None else runs  # 0 is refused by evaluate, not replaced
    if isinstance(runs, bool) or not isinstance(runs, int) or runs < 1:
        raise ArgumentError(f"runs must be a whole number ≥ 1 (or None for the problem's {problem.monte_carlo_runs}); got {runs!r}")
    spec = variant_specs(problem, runs, given)
    labels = [v[0] for v in spec]
    if variants is not None:
        unknown = [v for v in variants if v not in labels]
        if unknown or not variants:
            raise ArgumentError(f"problem {problem.name!r} has no report variant(s) {unknown}; its variants are {labels}")
        spec = [v for v in spec if v[0] in variants]
    results = []
    for label, opts, scen, names, n_runs in spec:
        t0 = time.perf_counter()
        tag = variant_tag(label)
        steps = tracked(names, f"{problem.name} {label}: design, verify, export, compile", "design")
        built = {d: build(problem, d, workdir / problem.name / tag / d, **opts) for d in steps}
        with phase(problem.name, "export check"):
            U, Y = export_trace(problem, **opts)
        exports = {}
        for d, b in built.items():
            with phase(problem.name, "export check"):
                chk = check_export(b, U, Y)
            if not chk.passed:
                raise CertificateError(f"{problem.name}/{d}: the generated C disagrees with the Python references: {chk.to_dict()}")
            exports[d] = chk
            (workdir / problem.name / tag / d).mkdir(parents=True, exist_ok=True)
            (workdir / problem.name / tag / d / "export_check.json").write_text(json.dumps(chk.to_dict(), indent=1) + "\n", encoding="utf-8")
        where = {"workers": workers, "client": client, "source": source}
        # a diagnoser whose decisions at other thresholds its own runs do not give: copies with scaled thresholds
        with phase(problem.name, "generate and compile"):
            copies = threshold_copies(built, workdir / problem.name / tag / "threshold_copies")
        with phase(problem.name, "Monte Carlo"):
            ev = evaluate(problem, built, runs=n_runs, scenarios=scen, copies=copies, **where, **opts)
            sweep = None
            if label == "default":
                sweep = fault_size_sweep(problem, built, runs=min(n_runs, SWEEP_RUNS), scenarios=scen, **where, **opts)
            shifts = shift_sweep(problem, built, ev, runs=min(n_runs, SHIFT_RUNS), **where, **opts)
        seconds = time.perf_counter() - t0
        results.append(
            VariantResult(label=label, options=ev.options, built=built, exports=exports, evaluation=ev, seconds=seconds, sweep=sweep,
                          shifts=shifts)
        )
    with phase(problem.name, "report"):
        page = write_report(problem, results, reports / problem.name)
        write_index(reports)
    return page


PHASES = ("design", "generate and compile", "export check", "Monte Carlo", "report")
"""The phases of the main job, in the order a problem goes through them (:func:`~fdisyn.evaluation.progress.phase`;
"Monte Carlo" holds the compile of its fused libraries, "generate and compile" the diagnosers' and their threshold
copies')."""


def phase_table(problems: Sequence[str]) -> str:
    """The main job's time per problem and phase so far in this process, and its largest process, as a Markdown table.

    Parameters
    ----------
    problems : sequence of str
        The problems, in the order they ran.

    Returns
    -------
    str
        The table (seconds), a total row, then the peak resident memory of this process and of its largest finished
        child (a compiler or a Monte Carlo worker).
    """
    from fdisyn.evaluation.progress import peak_memory_bytes, phase_seconds

    sec = phase_seconds()
    rows = ["| problem | " + " | ".join(PHASES) + " | total |", "|---" * (len(PHASES) + 2) + "|"]
    totals = [0.0] * len(PHASES)
    for p in problems:
        vals = [sec.get((p, ph), 0.0) for ph in PHASES]
        totals = [a + b for a, b in zip(totals, vals, strict=True)]
        rows.append(f"| {p} | " + " | ".join(f"{v:.0f}" for v in vals) + f" | {sum(vals):.0f} |")
    rows.append("| all | " + " | ".join(f"{v:.0f}" for v in totals) + f" | {sum(totals):.0f} |")
    own, child = peak_memory_bytes()
    return "\n".join(rows) + f"\n\nlargest process: {own / 2**30:.2f} GiB (this one), {child / 2**30:.2f} GiB (a finished child)\n"
