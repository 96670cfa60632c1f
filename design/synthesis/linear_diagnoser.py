"""Assemble a linear diagnoser: generators + evaluators (χ² or WSSR) + signature decision.

The result is a :class:`~fdisyn.runtime.gainfile.GainFile`, the unit that is
written to disk and to C. Signatures are derived, not typed in: a sensor fault
is expected to raise statistic ``j`` when its sensor is among the outputs of
``j``'s generator, and the certificate checks that the generator is in fact
sensitive to it (a nonzero steady-state gain from the sensor to the residual).

The linear design methods share the bank around their generators: the options
``P_f``, ``persistence``, ``evaluator``, ``window``, ``bank``, ``faults`` (and ``Ts`` to sample a
continuous plant) are defined here once, and :func:`linear_method` registers a
method from the design of one generator.
"""

from __future__ import annotations

import datetime as _dt
import math
import platform
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import scipy.linalg
from fdisyn.detectors.chi2 import chi2_evaluator
from fdisyn.detectors.sequential import MAX_ARL_SAMPLES, lorden_delay, split_budget
from fdisyn.detectors.table import DETECTORS, BankRequest, option_texts, quoted, windowed_kinds
from fdisyn.models.linear import LinearPlant
from fdisyn.numerics.certificate import Certificate, Check
from fdisyn.numerics.linalg import transfer_size
from fdisyn.runtime.errors import ArgumentError, ExistenceError, FdisynError, ShapeError, SolverError
from fdisyn.runtime.gainfile import Decision, Evaluator, GainFile, Generator, StepSpec, signals_block
from fdisyn.runtime.layout import linear_state_layout
from fdisyn.runtime.warmup import MAX_WARMUP, PINV_RTOL, information_pinv, longest_warmup
from fdisyn.runtime.statistics import MAX_WSSR_WINDOW
from fdisyn.runtime.names import check_fault_name, shown
from fdisyn.synthesis.registry import (
    ARL0,
    DETECTOR,
    P_F,
    PERSISTENCE,
    REQUIRED,
    WINDOW,
    Method,
    Option,
    at,
    is_count,
    is_real,
    register,
)
from fdisyn.synthesis.isolation import FALSE_ISOLATION, isolation_design
from fdisyn.synthesis.residual import (
    WHITE_RTOL,
    dc_gain_y,
    fault_steady_state,
    fault_step_response,
    internal_form,
    residual_autocovariances,
    whitened,
    whiteness,
)

__all__ = [
    'BANK_OPTIONS',
    'FALSE_ISOLATION_OPTION',
    'ISOLATION_MEMORY',
    'FaultClass',
    'GeneratorDesign',
    'bank_diagnoser',
    'default_bank',
    'default_bank_size',
    'default_fault_classes',
    'linear_diagnoser',
    'linear_method',
    'provenance',
]


@dataclass(frozen=True)
class FaultClass:
    """A fault class of the decision table: the sensors and component faults it corrupts.

    ``sensors`` name plant outputs (additive sensor faults); ``components``
    name plant component faults (the columns of ``Fx``).
    """

    name: str
    sensors: tuple[str, ...] = ()
    components: tuple[str, ...] = ()




def provenance(**extra: object) -> dict[str, object]:
    """Where a gain file came from: versions, machine, time, design options."""
    import casadi
    import scipy

    out: dict[str, object] = {
        "created_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "python": sys.version.split()[0],
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "casadi": str(getattr(casadi, "__version__", "unknown")),
        "platform": platform.platform(),
    }
    try:
        from importlib.metadata import version

        out["fdisyn"] = version("fdisyn")
    except Exception:  # noqa: BLE001 - an uninstalled checkout has no metadata
        out["fdisyn"] = "unknown"
    out.update(extra)
    return out


def linear_diagnoser(
    *,
    name: str,
    problem: str,
    design: str,
    plant: LinearPlant,
    generators: Sequence[Generator],
    sigma_r: Sequence[np.ndarray],
    P_f: float,
    faults: Sequence[FaultClass],
    certificates: Sequence[Certificate],
    persistence: int = 1,
    evaluator: str = "chi2",
    window: int | None = 1,
    arl0: float | None = None,
    min_fault: Mapping[str, float] | None = None,
    options: Mapping[str, object] | None = None,
    where: str = "",
    shifts: Sequence[float] | None = None,
    false_isolation: float = FALSE_ISOLATION,
    isolation_memory: int | None = None,
) -> GainFile:
    """Build and check the gain file of a bank of linear residual generators.

    ``sigma_r[i]`` is generator ``i``'s steady-state residual covariance (from
    its design); each gets one evaluator: ``evaluator = "chi2"``, the χ²
    statistic (Hu et al. 2013, Acta Automatica Sinica 39(8), eqs. (18)–(19);
    ``window`` must be 1), or ``"wssr"``, its sum over ``window`` samples
    (Long & Wang, Aeroengine 43(5), 2017, section 2) with the threshold from
    the residual's autocovariance on ``plant``; or a sequential statistic,
    ``"cusum"`` or ``"glr"`` (:func:`sequential_evaluators`: each generator is
    whitened first, and ``window`` is the GLR's onset window, ``None`` to
    choose it; ``shifts``, for a detector that reads them, the whitened shifts each hypothesis is tuned to). ``arl0`` (seconds), when given, is the diagnoser's mean time
    between false alarms and sets every threshold in place of ``P_f``: each
    statistic gets an equal share (:func:`~fdisyn.detectors.sequential.split_budget`),
    ``Ts / (n · arl0)`` per sample for χ² and WSSR. ``faults`` name the fault
    classes to isolate; their signatures must be nonzero and distinct. ``where`` prefixes the refusal of a
    budget out of range (:func:`check_budget`: ``PATH [design].arl0``; empty: ``option arl0``). The fault is
    named by the isolation test of :mod:`fdisyn.synthesis.isolation` at the level ``false_isolation``, its
    evidence's memory ``isolation_memory`` samples (``None``: chosen).
    """
    if not plant.is_discrete:
        raise ArgumentError("linear_diagnoser needs the discrete plant the generators were designed on")
    if len(sigma_r) != len(generators) or len(certificates) != len(generators):
        raise ShapeError(f"{len(generators)} generators need as many residual covariances and certificates")
    if int(persistence) < 1:
        raise ArgumentError(f"persistence must be a positive number of samples; got {persistence!r}")
    if evaluator not in DETECTORS:
        raise ArgumentError(f"detector must be one of {quoted(list(DETECTORS))}; got {shown(evaluator)}")
    detector = DETECTORS[evaluator]
    if not detector.windowed and window not in (1, None):
        raise ArgumentError(detector.no_window.format(window=shown(window)))
    if detector.sequential and int(persistence) != 1:
        raise ArgumentError(
            f"persistence = {persistence!r} with detector {evaluator!r}: a sequential statistic accumulates the evidence "
            "itself; use persistence 1 (set the false-alarm budget with arl0)"
        )
    gens = list(generators)
    check_budget(evaluator, P_f, arl0, float(plant.Ts or 1.0), len(gens), where)
    arl_stat = split_budget(arl0 / float(plant.Ts or 1.0), len(gens)) if arl0 is not None else 1.0 / float(P_f)
    request = BankRequest(
        plant=plant,
        generators=gens,
        sigma_r=sigma_r,
        faults=faults,
        arl_samples=arl_stat,
        window=window,
        min_fault=min_fault,
        autocovariances=lambda g, lags: residual_autocovariances(g, plant, lags),
        sequential=lambda d: sequential_evaluators(
            plant, gens, faults, kind=d.kind, arl_samples=arl_stat, window=window, min_fault=min_fault, shifts=shifts
        ),
    )
    evals, gens, sigma_r, sequential_info = detector.evaluators(request)
    weights = [next((ev.W for ev in evals if ev.generator == i), None) for i in range(len(gens))]
    # the warm-ups' constants share their size limit (a slow generator's warm-up is shortened to fit)
    most = longest_warmup([(g.n_state, g.n_residual) for g in gens])
    gens = [replace(g, warmup=warmup_length(g.Ar, g.Cr, w, most=most)) for g, w in zip(gens, weights, strict=True)]
    sig = np.array([[_expected(fault, gens[ev.generator], plant) for ev in evals] for fault in faults], dtype=int)
    checks, sensitivity = _bank_checks(gens, evals, plant)
    info: dict[str, object] = {"min_detectable_bias": sensitivity, "arl_per_statistic_samples": arl_stat,
                               "warmup_samples": {g.name: g.warmup for g in gens}}
    if arl0 is not None:
        info["arl0_s"] = float(arl0)
    if sequential_info:
        checks += sequential_info.pop("checks")
        info["sequential"] = sequential_info
    isolation, iso_info = isolation_design(
        plant, gens, faults, fault_sizes(plant, faults, min_fault, noiseless=1.0), level=false_isolation, memory=isolation_memory,
        windows=[int(e.window) for e in evals],
    )
    info["isolation"] = iso_info
    bank_cert = Certificate.of(f"{problem}/{design} bank", checks, info).require()
    nr = sum(g.n_residual for g in gens)
    decision = Decision(kind="signature_table", signatures=sig, persistence=int(persistence), isolation=isolation)
    lay = linear_state_layout(gens, evals, decision)
    step = StepSpec(
        nu=plant.m,
        ny=plant.p,
        nr=nr,
        nj=len(evals),
        nstate=lay.size,
        init_state=np.zeros(lay.size),
        residual_names=tuple(_residual_names(gens, plant)),
        statistic_names=tuple(f"J_{gens[e.generator].name}" for e in evals),
    )
    return GainFile(
        kind="linear",
        name=name,
        problem=problem,
        design=design,
        Ts=float(plant.Ts),  # type: ignore[arg-type]
        inputs=plant.inputs,
        outputs=plant.outputs,
        faults=tuple(f.name for f in faults),
        step=step,
        plant=plant.matrices(),
        generators=tuple(gens),
        evaluators=tuple(evals),
        decision=decision,
        signals=signals_block(plant.units, plant.labels, plant.inputs, plant.outputs, [f.name for f in faults]),
        certificate={
            "passed": True,
            "generators": [c.to_dict() for c in certificates],
            "bank": bank_cert.to_dict(),
        },
        provenance=provenance(options=dict(options or {})),
    )


VISIBLE_RTOL = 1e-3
"""A fault class whose designed fault brings a generator less than this fraction of the Kullback–Leibler
information of its best-seen class is not one of that generator's sequential hypotheses: it would take over
a thousand times longer to detect, and a CUSUM with so small a drift integrates the plant's model error
(low-frequency residual content the noise model does not have) rather than the fault."""


def _alternatives(f: FaultClass) -> list[FaultClass]:
    """The faults a class stands for: each of its sensors and components alone when it was merged from
    look-alikes (named ``a|b``, one part per sensor or component: :func:`default_fault_classes`), else itself
    (a class such as ``a+b`` corrupts all of them at once)."""
    parts = f.name.split("|")
    members = [*f.sensors, *f.components]
    if len(parts) > 1 and sorted(parts) == sorted(members):
        return [FaultClass(p, sensors=(p,) if p in f.sensors else (), components=(p,) if p in f.components else ()) for p in parts]
    return [f]


def _part_size(whole: tuple[np.ndarray, np.ndarray], f: FaultClass, part: FaultClass, plant: LinearPlant) -> tuple[np.ndarray, np.ndarray]:
    """The designed fault of one alternative of a merged class: the class's size on that sensor or component."""
    sens, comp = np.zeros_like(whole[0]), np.zeros_like(whole[1])
    for s in part.sensors:
        sens[plant.outputs.index(s)] = whole[0][plant.outputs.index(s)]
    for c in part.components:
        comp[plant.component_faults.index(c)] = whole[1][plant.component_faults.index(c)]
    return sens, comp


def fault_sizes(
    plant: LinearPlant, faults: Sequence[FaultClass], min_fault: Mapping[str, float] | None, *, noiseless: float | None = None
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The designed minimum fault of each class: ``(sensor biases, component faults)`` on the plant's outputs and
    ``Fx`` columns. ``min_fault[name]`` is its size in the fault's own units (every sensor or component of the
    class biased by it); by default one standard deviation of each sensor's noise (``sqrt R_ii``) and 1 for a
    component fault. A sensor without noise has no default and is refused, unless ``noiseless`` gives one (the
    isolation test needs directions only)."""
    given = dict(min_fault or {})
    unknown = sorted(set(given) - {f.name for f in faults})
    if unknown:
        raise ArgumentError(f"min_fault names {unknown}, not fault classes of this diagnoser; they are {[f.name for f in faults]}")
    out = {}
    sd = np.sqrt(np.clip(np.diag(plant.R), 0.0, None))
    for f in faults:
        sens = np.zeros(plant.p)
        comp = np.zeros(plant.Fx.shape[1])
        for name in f.sensors:
            j = plant.outputs.index(name)
            sens[j] = float(given.get(f.name, sd[j] if sd[j] > 0 or noiseless is None else noiseless))
            if sens[j] <= 0:
                raise ArgumentError(
                    f"fault {f.name!r}: sensor {name!r} has no noise (R = 0), so no default minimum fault; give min_fault.{f.name}"
                )
        for name in f.components:
            comp[plant.component_faults.index(name)] = float(given.get(f.name, 1.0))
        out[f.name] = (sens, comp)
    return out


WARMUP_RESIDUE = 0.5
"""What a warm-up may leave of a generator's initial error, as the expected weighted residual energy it adds over all
later samples, ``tr((O_∞ − O_N) O_N⁺)`` with ``O_N = Σ_{k<N} Φ_kᵀ W Φ_k`` (a white residual of covariance ``W⁻¹``):
half the mean of one sample's χ² of one degree of freedom, whatever the initial error was."""


def warmup_length(
    Ar: np.ndarray, Cr: np.ndarray, weight: np.ndarray | None, *, most: int = MAX_WARMUP, equilibrate: bool = False
) -> int:
    """The warm-up of a generator (:mod:`fdisyn.runtime.warmup`): the fewest samples ``N`` whose least-squares
    estimate of its initial error sees every direction the residual will ever see and leaves at most
    :data:`WARMUP_RESIDUE` of it.

    Parameters
    ----------
    Ar, Cr : numpy.ndarray
        The error dynamics (Schur stable) and the residual's map of the state: a linear generator's ``Ar, Cr``,
        a Beard filter's ``A − L C, C``.
    weight : numpy.ndarray or None
        Its first statistic's ``W`` (``None``: the identity).
    most : int
        The longest warm-up allowed (each sample is ``n_state × n_residual`` constants of the step).
    equilibrate : bool
        Count the directions seen, and invert the information, scaled to a unit diagonal (as
        :func:`~fdisyn.runtime.warmup.warmup_constants` with ``equilibrate``).

    Returns
    -------
    int
        ``N`` (0 for a generator without state), at most ``most``.
    """
    ns, nr = Ar.shape[0], Cr.shape[0]
    if ns == 0 or most < 1:
        return 0
    w = np.eye(nr) if weight is None else np.asarray(weight, dtype=float)
    total = scipy.linalg.solve_discrete_lyapunov(Ar.T, Cr.T @ w @ Cr)
    total = 0.5 * (total + total.T)
    d = np.diag(total)
    s = np.where(d > 0, 1.0 / np.sqrt(np.where(d > 0, d, 1.0)), 0.0) if equilibrate else np.ones(ns)
    lam = np.linalg.eigvalsh(s[:, None] * total * s[None, :])
    top = float(np.max(lam)) if lam.size else 0.0
    if not top > 0:
        return 0  # the residual never sees the state
    seen = int(np.sum(lam > PINV_RTOL * top))
    info, power = np.zeros((ns, ns)), np.eye(ns)
    for n in range(1, most + 1):
        phi = Cr @ power
        info += phi.T @ w @ phi
        power = Ar @ power
        sym = 0.5 * (info + info.T)
        lam = np.linalg.eigvalsh(s[:, None] * sym * s[None, :])
        if int(np.sum(lam > PINV_RTOL * top)) < seen:
            continue
        left = float(np.trace((total - info) @ information_pinv(sym, equilibrate=equilibrate)))
        if left <= WARMUP_RESIDUE:
            return n
    return most


def sequential_evaluators(
    plant: LinearPlant,
    generators: Sequence[Generator],
    faults: Sequence[FaultClass],
    *,
    kind: str,
    arl_samples: float,
    window: int | None,
    min_fault: Mapping[str, float] | None,
    shifts: Sequence[float] | None = None,
) -> tuple[list[Evaluator], list[Generator], list[np.ndarray], dict[str, Any]]:
    """CUSUM or GLR statistics for a bank: ``(evaluators, whitened generators, their covariances, information)``.

    Each generator is whitened (:func:`fdisyn.synthesis.residual.whitened`). Its hypotheses are the fault
    classes of the signature table that reach it, each as the designed minimum fault (:func:`fault_sizes`):
    the CUSUM on its steady-state residual signature (the step response after the generator has settled,
    ``G_rf(1) f``), the GLR on its transient signature over the onset window. A class whose steady-state
    signature carries less than :data:`VISIBLE_RTOL` of the generator's largest information is left out (a
    bias that looks like the decoupled unknown input, say: only its onset shows). ``window`` (GLR)
    ``None``: twice the Lorden delay of the weakest hypothesis, clipped to 25…100 samples. The information
    returned holds, per generator and class, the steady-state Kullback–Leibler information per sample of the
    designed fault and its Lorden delay ``ln(ARL) / I`` at this statistic's share of the budget. ``shifts``: the
    whitened shift sizes a detector that reads them (:attr:`~fdisyn.detectors.table.Detector.reads_shifts`) tunes
    each hypothesis to, along its designed fault's signature (``None``: the designed fault itself).
    """
    detector = DETECTORS[kind]
    sizes = fault_sizes(plant, faults, min_fault)
    # a class merged from look-alikes ("a|b": a or b) is tested as each of its alternatives, each from its own size
    tested = [(f, part) for f in faults for part in _alternatives(f)]
    sizes.update({p.name: _part_size(sizes[f.name], f, p, plant) for f, p in tested if p is not f})
    gens = [whitened(g, plant) for g in generators]
    sigmas = [residual_autocovariances(g, plant, 0)[0] for g in gens]
    checks = [
        Check(
            f"{g.name}: residual white (largest lag-1…50 autocorrelation)",
            whiteness(g, plant),
            1e3 * WHITE_RTOL,
            "<=",
            "CUSUM and GLR thresholds assume independent samples; an innovation's autocorrelations are round-off",
        )
        for g in gens
    ]
    evals: list[Evaluator] = []
    table: dict[str, object] = {}
    for gi, (gen, sig) in enumerate(zip(gens, sigmas, strict=True)):
        rho_max = float(np.max(np.abs(np.linalg.eigvals(gen.Ar)))) if gen.n_state else 0.0
        settle = 1 if rho_max <= 0 else min(20_000, max(1, math.ceil(math.log(1e-9) / math.log(rho_max))))
        w_pinv = chi2_evaluator(gi, sig, 0.5).W
        hyp: dict[str, np.ndarray] = {}  # the steady-state signature of each class that reaches the generator
        for _whole, part in tested:
            if not _expected(part, generators[gi], plant):
                continue
            steady = fault_steady_state(gen, plant, *sizes[part.name])
            hyp[part.name] = steady if steady is not None else fault_step_response(gen, plant, *sizes[part.name], settle + 1)[-1]
        infos = {k: 0.5 * float(v @ w_pinv @ v) for k, v in hyp.items()}
        top = max(infos.values(), default=0.0)
        visible = [k for k in hyp if infos[k] > VISIBLE_RTOL * top]
        if not visible:
            raise ExistenceError(
                f"generator {gen.name!r} sees no fault class at steady state; a {kind} statistic has nothing to test there "
                "(use detector 'chi2' or 'wssr', or name fault classes it reads)"
            )
        table[gen.name] = {
            "hypotheses": visible,
            "faults": {k: {"information": infos[k], "lorden_samples": lorden_delay(arl_samples, infos[k])} for k in visible},
        }
        response = lambda k, m, gen=gen: fault_step_response(gen, plant, *sizes[k], m)  # noqa: E731
        assert detector.hypotheses is not None  # a sequential detector builds its hypotheses
        evals.append(detector.hypotheses(gi, sig, visible, hyp, infos, arl_samples, window, response, shifts))
    extra = {"shifts": [float(x) for x in shifts]} if shifts is not None else {}
    return evals, gens, sigmas, {"kind": kind, "generators": table, "min_fault": {k: [a.tolist(), b.tolist()] for k, (a, b) in sizes.items()}, **extra, "checks": checks}


def default_fault_classes(plant: LinearPlant, generators: Sequence[Generator]) -> list[FaultClass]:
    """One class per sensor and per component fault that reaches the bank; classes the
    bank cannot tell apart (equal signatures) are merged and named ``"a|b"``."""
    singles = [FaultClass(o, sensors=(o,)) for o in plant.outputs] + [
        FaultClass(c, components=(c,)) for c in plant.component_faults
    ]
    merged: dict[tuple[int, ...], list[FaultClass]] = {}
    for fault in singles:
        sig = tuple(_expected(fault, g, plant) for g in generators)
        if any(sig):
            merged.setdefault(sig, []).append(fault)
    return [
        FaultClass(
            "|".join(f.name for f in group),
            sensors=tuple(s for f in group for s in f.sensors),
            components=tuple(c for f in group for c in f.components),
        )
        for group in merged.values()
    ]


def _residual_names(gens: Sequence[Generator], plant: LinearPlant) -> list[str]:
    """``generator.output`` when a residual has one component per sensor it reads, else ``generator.r<k>``."""
    out: list[str] = []
    for g in gens:
        if g.n_residual == len(g.outputs_used):
            out.extend(f"{g.name}.{plant.outputs[j]}" for j in g.outputs_used)
        else:
            out.extend(f"{g.name}.r{k}" for k in range(g.n_residual))
    return out


def _expected(fault: FaultClass, gen: Generator, plant: LinearPlant) -> int:
    """1 when ``fault`` reaches ``gen``'s residual: it corrupts a sensor the generator
    reads, or a component fault's transfer to the residual is not identically zero."""
    for s in fault.sensors:
        if s not in plant.outputs:
            raise ArgumentError(f"fault {fault.name!r} names sensor {s!r}; sensors are {list(plant.outputs)}")
    for c in fault.components:
        if c not in plant.component_faults:
            raise ArgumentError(f"fault {fault.name!r} names component fault {c!r}; the plant has {list(plant.component_faults)}")
    if {plant.outputs.index(s) for s in fault.sensors} & set(gen.outputs_used):
        return 1
    form = internal_form(gen, plant)
    for c in fault.components:
        j = plant.component_faults.index(c)
        # round-off of an exactly decoupled transfer is ~1e-16; 1e-8 separates "reaches" from "cancels"
        if transfer_size(form.A, form.Bf[:, [j]], form.C, form.Df[:, [j]]) > 1e-8:
            return 1
    return 0


def _bank_checks(
    generators: Sequence[Generator], evals: Sequence[Evaluator], plant: LinearPlant
) -> tuple[list[Check], dict[str, dict[str, float | None]]]:
    """Every sensor of the signature table must reach the statistic; how well, at steady state.

    Check: the transfer from an additive fault on sensor ``s`` to the residual
    (``Ar, By[:, s], Cr, Dy[:, s]``) is not identically zero (normalised Markov
    parameters above round-off). Information: the smallest constant bias that
    crosses the threshold on its own at steady state, ``b_min = sqrt(J_th / (N gᵀ W g))``
    with ``g`` the DC gain column and ``N`` the window (1 for χ²) (∞ when a bias is invisible at steady state,
    e.g. on a sensor of an integrating state: only its onset transient shows;
    reported as ``None``).
    """
    checks: list[Check] = []
    table: dict[str, dict[str, float | None]] = {}
    for ev in evals:
        gen = generators[ev.generator]
        dc = dc_gain_y(gen)
        row: dict[str, float | None] = {}
        for j in gen.outputs_used:
            g = dc[:, j]
            energy = float(g @ ev.W @ g)
            scale = float(np.linalg.norm(gen.Dy[:, j]) + np.linalg.norm(gen.Cr) * np.linalg.norm(gen.By[:, j]))
            visible = energy > 1e-20 * scale**2 * np.linalg.norm(ev.W, 2)  # a DC gain cancelled to round-off
            if not DETECTORS[ev.kind].sequential:  # a sequential statistic's sensitivity is its hypotheses' information
                row[plant.outputs[j]] = float(np.sqrt(ev.threshold / (ev.window * energy))) if visible else None
            checks.append(
                Check(
                    f"{gen.name}: sensor {plant.outputs[j]} reaches the residual",
                    transfer_size(gen.Ar, gen.By[:, [j]], gen.Cr, gen.Dy[:, [j]]),
                    1e-8,
                    ">=",
                    "a sensor in the signature table must move the residual; a transfer cancelled to round-off "
                    "(~1e-16) would make its faults invisible",
                )
            )
        if row:
            table[gen.name] = row
    return checks, table


# --------------------------------------------------------------------------- the bank around a linear method


def _sensor_indices(group: Any, plant: LinearPlant, where: str, *, empty: bool = False) -> list[int]:
    """Indices of a list of distinct output names (a bank group, a fault class's sensors)."""
    if not isinstance(group, (list, tuple)) or (not group and not empty):
        raise ArgumentError(f"{where} must be a {'' if empty else 'non-empty '}list of output names, got {shown(group)}")
    idx: list[int] = []
    for j, o in enumerate(group):
        if not isinstance(o, str) or o not in plant.outputs:
            raise ArgumentError(f"{where}[{j}]: no output {shown(o)}; outputs are {list(plant.outputs)}")
        if plant.outputs.index(o) in idx:
            raise ArgumentError(f"{where} names output {o!r} twice")
        idx.append(plant.outputs.index(o))
    return idx


def _bank(value: Any, where: str, plant: LinearPlant) -> dict[str, tuple[int, ...]]:
    """``bank``: generator name → indices of the outputs it reads."""
    label = at(where, "bank")
    if len(value) == 0:  # not replaced by the default: an empty bank is a mistake
        raise ArgumentError(
            f"{label} is empty; expected groups of outputs, one observer each ({[list(plant.outputs)]} for one on all "
            "outputs), or no key for one per sensor on the other outputs"
        )
    if isinstance(value, Mapping):
        out: dict[str, tuple[int, ...]] = {}
        for gname, group in value.items():
            if not isinstance(gname, str) or not gname.isidentifier():
                raise ArgumentError(f"{label}: generator name {shown(gname)} is not an identifier")
            out[gname] = tuple(_sensor_indices(group, plant, f"{label}.{gname}"))
        return out
    groups = [tuple(_sensor_indices(g, plant, f"{label}[{gi}]")) for gi, g in enumerate(value)]
    return {f"g{gi}_" + "_".join(plant.outputs[i] for i in idx): idx for gi, idx in enumerate(groups)}


def _faults(value: Any, where: str, plant: LinearPlant) -> list[FaultClass]:
    """``faults``: named classes of sensors (outputs) and component faults, names checked and unique."""
    label = at(where, "faults")
    out: list[FaultClass] = []
    for i, f in enumerate(value):
        w = f"{label}[{i}]"
        if isinstance(f, FaultClass):
            f = {"name": f.name, "sensors": list(f.sensors), "components": list(f.components)}
        if not isinstance(f, Mapping):
            raise ArgumentError(f"{w} must be a table {{ name, sensors, components }}, got {shown(f)}")
        unknown = sorted(set(f) - {"name", "sensors", "components"})
        if unknown:
            raise ArgumentError(f"{w}: unknown key(s) {unknown}; allowed: ['components', 'name', 'sensors']")
        if "name" not in f:
            raise ArgumentError(f"{w}: missing key 'name'")
        fname = check_fault_name(f["name"], f"{w}.name", error=ArgumentError)
        if any(c.name == fname for c in out):
            raise ArgumentError(f"{w}.name {fname!r} names another fault class too; fault names must be unique")
        sensors = tuple(plant.outputs[j] for j in _sensor_indices(f.get("sensors", []), plant, f"{w}.sensors", empty=True))
        components = f.get("components", [])
        if not isinstance(components, (list, tuple)):
            raise ArgumentError(f"{w}.components must be a list of component-fault names, got {shown(components)}")
        for j, c in enumerate(components):
            if not isinstance(c, str) or c not in plant.component_faults:
                raise ArgumentError(f"{w}.components[{j}]: no component fault {shown(c)}; the plant has {list(plant.component_faults)}")
        if len(set(components)) != len(components):
            raise ArgumentError(f"{w}.components names a component fault twice: {list(components)}")
        if not sensors and not components:
            raise ArgumentError(f"{w} names no sensor and no component fault")
        out.append(FaultClass(fname, sensors, tuple(components)))
    return out


def _listed(v: Any) -> bool:
    return isinstance(v, (list, tuple, Mapping))


BANK = Option(
    "bank",
    None,
    "the outputs of each generator: a list of groups (generators named like g0_y1_y2) or a table name → group; "
    "default: one per sensor on every other output, which isolates each sensor's fault (a sensor without one is named "
    "with the reason; with none, one on all outputs); one group of all outputs for a single generator",
    "a list of lists of output names, or a table of them",
    _listed,
    lambda v, where, plant: _bank(v, where, plant),
)
FAULTS = Option(
    "faults",
    None,
    "fault classes { name, sensors, components }; default one per sensor and component fault, merged when alike",
    "a list of tables { name, sensors, components }",
    lambda v: isinstance(v, (list, tuple)),
    lambda v, where, plant: _faults(v, where, plant),
)
TS = Option(
    "Ts",
    None,
    "sample time (s) of the diagnoser: ZOH-samples a continuous plant (a discrete plant has its own)",
    "a positive sample time in seconds",
    lambda v: is_real(v) and v > 0,
    plant_file="[model].Ts",
)
EVALUATOR = Option(
    "evaluator",
    None,
    "the statistic of each generator (the same option as detector, its earlier name; default 'chi2')",
    option_texts()["kinds"],
    lambda v: v in DETECTORS,  # read live: a registered detector is accepted
)
MIN_FAULT = Option(
    "min_fault",
    None,
    f"the designed minimum fault of each class for {option_texts()['sequential']}, in the fault's units (default: one "
    "noise standard deviation of each sensor, 1 for a component fault)",
    "a table fault-class name → positive size",
    lambda v: isinstance(v, Mapping) and all(isinstance(k, str) and is_real(x) and x > 0 for k, x in v.items()),
)
MAX_SHIFTS = 8
"""Most shifts of a multi-scale sequential statistic: each adds a pair of sums per hypothesis to the step."""
SHIFTS = Option(
    "shifts",
    None,
    "the whitened mean shifts (in residual standard deviations, along each fault class's signature) a sequential "
    "statistic is tuned to: one pair of sums per shift and hypothesis under one threshold, a multi-scale CUSUM whose "
    "delay stays near the Lorden bound over their range, e.g. [0.25, 0.5, 1, 2, 4] (default: the designed minimum "
    f"fault alone); read by {quoted([k for k, d in DETECTORS.items() if d.reads_shifts], 'and')}",
    f"a list of 1 to {MAX_SHIFTS} distinct positive numbers, each at most 100",
    lambda v: isinstance(v, (list, tuple)) and 1 <= len(v) <= MAX_SHIFTS and all(is_real(x) and 0 < x <= 100 for x in v)
    and len({float(x) for x in v}) == len(v),
)
LINEAR_WINDOW = replace(
    WINDOW,
    default=None,
    expected=f"a whole number of samples in 1..{MAX_WSSR_WINDOW}",
    accepts=lambda v: is_count(v) and v <= MAX_WSSR_WINDOW,
    doc=f"{option_texts()['window']}; default {option_texts()['window_default']}",
)
FALSE_ISOLATION_OPTION = Option(
    "false_isolation",
    FALSE_ISOLATION,
    "the isolation test's level: the probability that the true fault class is rejected at one sample (the fault is "
    "named from the residuals by a GLR across the classes' hypotheses, held until the evidence rejects it)",
    "a probability in (0, 0.5)",
    lambda v: is_real(v) and 0.0 < v < 0.5,
)
ISOLATION_MEMORY = Option(
    "isolation_memory",
    None,
    "the isolation evidence's memory in samples (its exponential forgetting 1 − 1/memory; default: ten times the "
    "slowest generator's time constant and four statistics' windows, within 50…2000)",
    "a whole number of samples in 2..1000000",
    lambda v: is_count(v) and 2 <= v <= 10**6,
)
BANK_OPTIONS: tuple[Option, ...] = (P_F, ARL0, PERSISTENCE, DETECTOR, EVALUATOR, LINEAR_WINDOW, MIN_FAULT, SHIFTS, BANK, FAULTS,
                                    FALSE_ISOLATION_OPTION, ISOLATION_MEMORY)
"""The options of every linear method: the bank and its evaluation (χ²: Hu et al. 2013, Acta Automatica Sinica 39(8),
eq. (20); WSSR: Long & Wang, Aeroengine 43(5), 2017, section 2)."""

GeneratorDesign = Callable[..., tuple[Generator, np.ndarray, Certificate]]
"""``(plant, outputs_used, name, **options) -> (generator on all outputs, residual covariance, certificate)``."""


def bank_diagnoser(
    plant: LinearPlant,
    generator: GeneratorDesign,
    *,
    name: str,
    design: str,
    problem: str | None = None,
    record: Mapping[str, object] | None = None,
    where: str = "",
    P_f: float,
    persistence: int,
    bank: Mapping[str, Sequence[int]] | None,
    evaluator: str | None = None,
    window: int | None = None,
    detector: str | None = None,
    arl0: float | None = None,
    min_fault: Mapping[str, float] | None = None,
    shifts: Sequence[float] | None = None,
    faults: Sequence[FaultClass] | None,
    Ts: float | None = None,
    sampled_data: bool = False,
    false_isolation: float = FALSE_ISOLATION,
    isolation_memory: int | None = None,
    **options: Any,
) -> GainFile:
    """One generator per group of ``bank`` (``generator`` designs each), evaluators (``evaluator``, ``window``), signatures.

    ``sampled_data``: ``generator`` gets the continuous plant (sampled every
    ``Ts`` by the method itself); otherwise the discrete plant (a continuous
    one ZOH-sampled at ``Ts``). Errors of one generator name its group.
    """
    discrete = plant if plant.is_discrete else plant.discretise(Ts)  # type: ignore[arg-type]

    def one(gname: str, idx: Sequence[int]) -> tuple[Generator, np.ndarray, Certificate]:
        if sampled_data:
            return generator(plant, tuple(idx), gname, Ts=Ts, **options)
        return generator(discrete, tuple(idx), gname, **options)

    kind = chosen_detector(detector, evaluator, where)

    def one_sequential(gname: str, idx: Sequence[int]) -> tuple[Generator, np.ndarray, Certificate]:
        """A generator of the default bank whose statistic is a CUSUM or a GLR: its residual must whiten (the
        bank's certificate checks it for every generator; here a generator that fails is left out, not the bank)."""
        gen, sig, cert = one(gname, idx)
        white = whiteness(whitened(gen, discrete), discrete)
        if not white <= 1e3 * WHITE_RTOL:
            raise SolverError(f"its residual does not whiten for the {kind} (largest lag-1…50 autocorrelation of the "
                              f"whitened residual {shown(white)}, at most {shown(1e3 * WHITE_RTOL)} expected)")
        return gen, sig, cert

    chosen: dict[str, object] | None = None
    if bank is None and plant.p >= 2:
        designed, chosen = default_bank(discrete, one_sequential if is_sequential(kind) else one, faults, where)
    else:
        groups = bank if bank is not None else {"g0_" + "_".join(plant.outputs): tuple(range(plant.p))}
        designed = []
        for gi, (gname, idx) in enumerate(groups.items()):
            try:
                designed.append(one(gname, idx))
            except FdisynError as exc:  # the same error, naming the group of the bank it concerns
                raise type(exc)(f"{at(where, f'bank[{gi}]')}: {exc}") from exc
    gens = [d[0] for d in designed]
    sigmas = [d[1] for d in designed]
    certs = [d[2] for d in designed]
    gf = linear_diagnoser(
        name=name,
        problem=problem or name,
        design=design,
        plant=discrete,
        generators=gens,
        sigma_r=sigmas,
        P_f=P_f,
        faults=faults if faults is not None else default_fault_classes(discrete, gens),
        certificates=certs,
        persistence=persistence,
        evaluator=kind,
        window=window,
        arl0=arl0,
        min_fault=min_fault,
        options=record,
        where=where,
        shifts=shifts,
        false_isolation=false_isolation,
        isolation_memory=isolation_memory,
    )
    if chosen is None:
        return gf
    return replace(gf, provenance={**gf.provenance, "bank": chosen})


def default_bank_size(plant: Any) -> int:
    """The generators of a linear method's bank when no ``bank`` is given, before any is designed: one per sensor
    (:func:`default_bank`) on a plant of two or more outputs, else one (fewer when some cannot be designed, one
    more when the generator on all outputs is kept; the design checks the budget again on the bank it built)."""
    p = int(getattr(plant, "p", 1) or 1)
    return p if p >= 2 else 1


def _without(sensor: str, reason: FdisynError) -> str:
    """Why the generator without ``sensor`` is not in the bank, in one phrase."""
    verb = "does not exist" if isinstance(reason, ExistenceError) else "could not be designed"
    return f"the generator without {sensor} {verb}: {str(reason).rstrip('.')}"


def default_bank(
    plant: LinearPlant,
    design_one: Callable[[str, Sequence[int]], tuple[Generator, np.ndarray, Certificate]],
    faults: Sequence[FaultClass] | None,
    where: str = "",
) -> tuple[list[tuple[Generator, np.ndarray, Certificate]], dict[str, object]]:
    """The bank a linear method builds when no ``bank`` is given: the one that isolates what the sensors allow.

    The dedicated/generalised observer scheme (Frank, Automatica 26(3), 1990): for each sensor ``k``, one generator
    ``g<k>_<outputs>`` on every output but ``k``, designed by the method. A sensor fault then raises every statistic
    but its own, so the sensors' faults have distinct signatures and are isolated. A sensor whose generator does not
    exist (the method's existence condition fails on the other outputs: :class:`ExistenceError`) or cannot be
    designed (:class:`SolverError`) is kept in the bank's other generators, and said: its fault then shares the
    signature of every fault all generators see. A generator whose residual does not depend on some of its outputs
    (decoupled with the unknown input: their transfer to the residual is below 1e-8, the bank certificate's rule) reads
    the others only (renamed after them; left out when another generator reads the same). When no sensor has a
    generator, the bank is the one generator on all outputs (``g0_<outputs>``), as with ``bank = [all outputs]``.

    The generator on all outputs is added to a bank of sensor generators only when it isolates more: when the plant
    has component faults (or ``faults`` names classes) that the sensor generators leave unseen or cannot tell apart,
    and with it the fault classes have more distinct signatures. It never separates sensor faults (it reads every
    sensor), so on a plant without component faults it is not designed at all.

    Parameters
    ----------
    plant : LinearPlant
        The discrete design model (its outputs name the sensors).
    design_one : callable
        ``design_one(name, output_indices) -> (generator, residual covariance, certificate)``: the method's design of
        one generator.
    faults : sequence of FaultClass or None
        The fault classes asked for (``None``: one per sensor and component fault).
    where : str
        Prefixes the refusal when no generator can be designed at all (see :func:`fdisyn.synthesis.registry.at`).

    Returns
    -------
    designed : list of tuple
        ``(generator, residual covariance, certificate)`` per generator of the bank.
    chosen : dict
        What the bank is and why, stored in the gain file's provenance (key ``bank``): ``rule``, ``generators``,
        ``left_out`` (per sensor without its generator: ``sensor``, ``outputs``, ``reason``), ``narrowed`` (per
        sensor whose generator reads fewer outputs: the same keys) and ``all_outputs`` (whether the generator on all
        outputs is in the bank, and why).

    Raises
    ------
    FdisynError
        The generator on all outputs, when no sensor generator exists, fails (its error, naming ``bank``).
    """
    names = list(plant.outputs)
    everything = tuple(range(plant.p))
    all_name = "g0_" + "_".join(names)
    designed: list[tuple[Generator, np.ndarray, Certificate]] = []
    left_out: list[dict[str, object]] = []
    narrowed: list[dict[str, object]] = []
    for k, sensor in enumerate(names):
        idx = tuple(j for j in everything if j != k)
        try:
            gen, sig, cert = design_one(f"g{k}_" + "_".join(names[j] for j in idx), idx)
        except (ExistenceError, SolverError) as exc:  # this sensor's generator only; the others stand
            left_out.append({"sensor": sensor, "outputs": [names[j] for j in idx], "reason": _without(sensor, exc)})
            continue
        # an output decoupled with the unknown input does not reach the residual (the bank's certificate rule): the
        # generator reads the others only, and its signature must say so
        deaf = [j for j in gen.outputs_used if not transfer_size(gen.Ar, gen.By[:, [j]], gen.Cr, gen.Dy[:, [j]]) >= 1e-8]
        if deaf:
            keep = [j for j in gen.outputs_used if j not in deaf]
            why = (f"the generator without {sensor} reads {', '.join(names[j] for j in keep) or 'no output'} only: "
                   f"{', '.join(names[j] for j in deaf)} {'does' if len(deaf) == 1 else 'do'} not reach its residual "
                   "(decoupled with the unknown input)")
            twin = next((d[0].name for d in designed if tuple(d[0].outputs_used) == tuple(keep)), None)
            if not keep or twin is not None:
                left_out.append({"sensor": sensor, "outputs": [names[j] for j in idx],
                                 "reason": why + (f", as {twin} does" if twin else "")})
                continue
            by, dy = gen.By.copy(), gen.Dy.copy()
            by[:, deaf], dy[:, deaf] = 0.0, 0.0  # their transfer to the residual is zero: the residual is unchanged
            gen = Generator.from_canonical(
                name=f"g{k}_" + "_".join(names[j] for j in keep), outputs_used=keep, Ar=gen.Ar, Bu=gen.Bu, By=by, Cr=gen.Cr,
                Du=gen.Du, Dy=dy, method=gen.method,
            )
            narrowed.append({"sensor": sensor, "outputs": [names[j] for j in keep], "reason": why})
        designed.append((gen, sig, cert))
    chosen: dict[str, object] = {
        "rule": "one generator per sensor on the other outputs (generalised observer scheme)",
        "left_out": left_out,
        "narrowed": narrowed,
    }
    if not designed:
        try:
            designed.append(design_one(all_name, everything))
        except FdisynError as exc:
            raise type(exc)(
                f"{at(where, 'bank')}: none given, and no sensor has a generator on the other outputs; the generator on all "
                f"outputs: {exc}"
            ) from exc
        chosen["all_outputs"] = {"kept": True, "why": "no sensor has a generator on the other outputs"}
        chosen["generators"] = [all_name]
        return designed, chosen
    classes = list(faults) if faults is not None else [FaultClass(o, sensors=(o,)) for o in names] + [
        FaultClass(c, components=(c,)) for c in plant.component_faults
    ]
    gens = [d[0] for d in designed]

    def distinct(bank: Sequence[Generator]) -> set[tuple[int, ...]]:
        return {sig for f in classes if any(sig := tuple(_expected(f, g, plant) for g in bank))}

    before = distinct(gens)
    if not any(f.components for f in classes):
        kept = {"kept": False, "why": "it reads every sensor, so it would tell no sensor faults apart"}
    elif len(before) == len(classes):
        kept = {"kept": False, "why": "every fault class has its own signature without it"}
    else:
        whole = f"g{plant.p}_" + "_".join(names)
        try:
            extra = design_one(whole, everything)
        except (ExistenceError, SolverError) as exc:
            verb = "does not exist" if isinstance(exc, ExistenceError) else "could not be designed"
            kept = {"kept": False, "why": f"it {verb}: {str(exc).rstrip('.')}"}
        else:
            after = distinct([*gens, extra[0]])
            if len(after) > len(before):
                designed.append(extra)
                kept = {"kept": True, "why": f"with it the bank tells {len(after)} fault classes apart, {len(before)} without it"}
            else:
                kept = {"kept": False, "why": f"it tells no more fault classes apart ({len(before)} without it)"}
    chosen["all_outputs"] = kept
    chosen["generators"] = [d[0].name for d in designed]
    return designed, chosen


def chosen_detector(detector: str | None, evaluator: str | None, where: str, default: str = "chi2") -> str:
    """The statistic of a linear method's bank, from its two names.

    ``detector`` and ``evaluator`` (its earlier name) are one option: ``None`` means not given, and neither given
    is the method's ``default``. Both given and different is refused, whichever of them equals the default (a
    default written out is no weaker a choice than another value).

    Parameters
    ----------
    detector : str or None
        The option ``detector`` as given.
    evaluator : str or None
        The option ``evaluator`` as given.
    where : str
        Prefixes the message (see :func:`fdisyn.synthesis.registry.at`).
    default : str
        The statistic when neither is given (``'chi2'``; ``'wssr'`` for ``kalman_uio_gos``).

    Returns
    -------
    str
        The chosen statistic.

    Raises
    ------
    ArgumentError
        ``detector`` and ``evaluator`` both given and different.
    """
    if detector is not None and evaluator is not None and detector != evaluator:
        raise ArgumentError(
            f"{at(where, 'detector')} = {shown(detector)} but evaluator = {shown(evaluator)}: they are the same option, give one"
        )
    return detector if detector is not None else evaluator if evaluator is not None else default


def check_budget(kind: str, P_f: float, arl0: float | None, Ts: float, statistics: int, where: str) -> None:
    """Refuse a false-alarm budget whose thresholds cannot be computed, naming the option as the user wrote it.

    Each statistic's share is ``statistics · arl0 / Ts`` samples (:func:`~fdisyn.detectors.sequential.split_budget`),
    or ``1/P_f``; a share beyond :data:`~fdisyn.detectors.sequential.MAX_ARL_SAMPLES` (a false-alarm rate of
    1e-300 per sample), or of at most one sample with ``arl0``, is refused with the largest (smallest) ``arl0`` or
    the smallest ``P_f`` that works.

    Parameters
    ----------
    kind : str
        The detector (``'chi2'``, ``'wssr'``, ``'cusum'`` or ``'glr'``).
    P_f : float
        The false-alarm probability per statistic and sample (read when ``arl0`` is None).
    arl0 : float or None
        The diagnoser's mean time between false alarms (s).
    Ts : float
        The diagnoser's sample time (s).
    statistics : int
        The statistics that share the budget (one per generator).
    where : str
        Prefixes the message (see :func:`fdisyn.synthesis.registry.at`; empty: ``option arl0``).

    Raises
    ------
    ArgumentError
        The budget is outside the domain the thresholds are computed on.
    """
    label = (lambda key: at(where, key)) if where else (lambda key: f"option {key}")
    most = MAX_ARL_SAMPLES
    if arl0 is not None:
        share = statistics * (float(arl0) / Ts)  # inf when it overflows: refused below, the value shown as given
        if not 1.0 < share <= most:
            low = share <= 1.0
            raise ArgumentError(
                f"{label('arl0')} = {shown(arl0)} s gives each of the {statistics} statistics a mean run length of "
                f"{'more than ' + format(most, 'g') if share > most else format(share, '.3g')} samples at Ts = {Ts:g} s; expected "
                + (f"arl0 > {Ts / statistics:.6g} s (one sample per statistic)" if low else
                   f"arl0 ≤ {most * Ts / statistics:.6g} s (thresholds are computed up to {most:g} samples per statistic)")
            )
    elif is_sequential(kind) and not float(P_f) * most >= 1.0:
        raise ArgumentError(
            f"{label('P_f')} = {shown(P_f)} with detector {kind!r} is a mean run length of more than {most:g} samples; "
            f"expected P_f ≥ {1.0 / most:g} (the thresholds are computed up to {most:g} samples)"
        )


def check_window(kind: str, window: object, where: str) -> None:
    """Refuse a window for a detector that has none (:attr:`fdisyn.detectors.table.Detector.windowed`).

    Parameters
    ----------
    kind : str
        The chosen detector (:func:`chosen_detector`).
    window : object
        The option ``window`` as given (``None``: not given; 1 is every detector's).
    where : str
        Prefixes the message (see :func:`fdisyn.synthesis.registry.at`).

    Raises
    ------
    ArgumentError
        A window other than 1 for a detector without one.
    """
    if kind in DETECTORS and not DETECTORS[kind].windowed and window not in (None, 1):
        raise ArgumentError(
            f"{at(where, 'window')} = {shown(window)} needs detector = {quoted(windowed_kinds())} "
            f"(the {kind!r} statistic has no window)"
        )


def is_sequential(kind: str) -> bool:
    """Whether ``kind`` is a registered sequential detector (:attr:`fdisyn.detectors.table.Detector.sequential`).

    Parameters
    ----------
    kind : str
        A detector's kind, possibly not one.

    Returns
    -------
    bool
        True for a sequential detector.
    """
    return kind in DETECTORS and DETECTORS[kind].sequential


def check_min_fault(kind: str, min_fault: object, where: str) -> None:
    """Refuse ``min_fault`` for a detector that does not read it.

    Parameters
    ----------
    kind : str
        The chosen detector (:func:`chosen_detector`).
    min_fault : object
        The option as given (``None``: not given).
    where : str
        Prefixes the message (see :func:`fdisyn.synthesis.registry.at`).

    Raises
    ------
    ArgumentError
        ``min_fault`` given with ``'chi2'`` or ``'wssr'``: only the sequential detectors are designed for a fault size.
    """
    _refuse_unread("min_fault", min_fault, kind, where, lambda d: d.sequential, "the detectors {readers} (their designed fault sizes)")


def check_shifts(kind: str, shifts: object, where: str) -> None:
    """Refuse ``shifts`` for a detector that does not read them.

    Parameters
    ----------
    kind : str
        The chosen detector (:func:`chosen_detector`).
    shifts : object
        The option as given (``None``: not given).
    where : str
        Prefixes the message (see :func:`fdisyn.synthesis.registry.at`).

    Raises
    ------
    ArgumentError
        ``shifts`` given with a detector whose :attr:`~fdisyn.detectors.table.Detector.reads_shifts` is false.
    """
    _refuse_unread("shifts", shifts, kind, where, lambda d: d.reads_shifts, "{readers} (the shifts its sums are tuned to)")


def _refuse_unread(name: str, value: object, kind: str, where: str, reads: Callable[[Any], bool], readers_text: str) -> None:
    """Refuse option ``name`` given (not ``None``) with a detector that does not ``reads`` it, naming those that do
    (``readers_text`` with ``{readers}`` standing for them)."""
    if value is not None and not (kind in DETECTORS and reads(DETECTORS[kind])):
        readers = [k for k, d in DETECTORS.items() if reads(d)]
        raise ArgumentError(
            f"{at(where, name)} is read only by {readers_text.format(readers=quoted(readers, 'and'))}; the detector here is "
            f"{kind!r}: remove {name}, or choose detector = {quoted(readers)}"
        )


def _check_ts(plant: Any, options: Mapping[str, Any], where: str) -> None:
    if isinstance(plant, LinearPlant) and plant.is_discrete and options.get("Ts") is not None:
        raise ArgumentError(f"{at(where, 'Ts')} = {options['Ts']!r}: the plant is discrete (Ts = {plant.Ts}); give Ts for a continuous plant only")
    if isinstance(plant, LinearPlant) and not plant.is_discrete and options.get("Ts") is None:
        raise ArgumentError(f"{where}: missing option 'Ts': expected {TS.expected} to sample the continuous plant")


def linear_method(
    name: str,
    *,
    summary: str,
    reference: str,
    generator: GeneratorDesign,
    options: Sequence[Option] = (),
    sampled_data: bool = False,
    check: Callable[[Any, Mapping[str, Any], str], None] | None = None,
) -> Method:
    """Register the linear method ``name``: ``generator`` designs one generator, the bank does the rest.

    ``sampled_data``: a continuous plant designed as a sampled-data plant
    (plant kind ``"continuous"``, ``Ts`` required); otherwise a discrete plant,
    or a continuous one with ``Ts`` (ZOH).
    """

    def checks(plant: Any, opts: Mapping[str, Any], where: str) -> None:
        kind = chosen_detector(opts.get("detector"), opts.get("evaluator"), where)
        check_window(kind, opts.get("window"), where)
        if is_sequential(kind) and opts.get("persistence", 1) != 1:
            raise ArgumentError(
                f"{at(where, 'persistence')} = {shown(opts['persistence'])} with detector {kind!r}: a sequential statistic "
                "accumulates the evidence itself; use persistence 1 (set the false-alarm budget with arl0)"
            )
        check_min_fault(kind, opts.get("min_fault"), where)
        check_shifts(kind, opts.get("shifts"), where)
        if not sampled_data:
            _check_ts(plant, opts, where)
        ts = opts.get("Ts") if not (isinstance(plant, LinearPlant) and plant.is_discrete) else plant.Ts
        if ts is not None:
            bank = opts.get("bank")
            count = len(bank) if bank else (1 if bank is not None else default_bank_size(plant))
            check_budget(kind, opts.get("P_f", P_F.default), opts.get("arl0"), float(ts), count, where)
        if check is not None:
            check(plant, opts, where)

    def design(plant: LinearPlant, *, name: str, problem: str | None = None, record: Mapping[str, object] | None = None, where: str = "", **opts: Any) -> GainFile:
        return bank_diagnoser(plant, generator, name=name, design=method.name, problem=problem, record=record, where=where, sampled_data=sampled_data, **opts)

    ts = replace(TS, default=REQUIRED, doc="sample time (s) of the sampled-data diagnoser") if sampled_data else TS
    method = Method(
        name=name,
        plant_kind="continuous" if sampled_data else "linear",
        summary=summary,
        reference=reference,
        options=(*BANK_OPTIONS, ts, *options),
        design=design,
        diagnoser_kind="linear",
        generator=generator,
        check=checks,
    )
    return register(method)
