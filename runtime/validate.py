"""The gain file's validators: every check the reader and :class:`~fdisyn.runtime.gainfile.GainFile` run.

Each refusal is a :class:`~fdisyn.runtime.errors.GainFileError` naming the field, what was expected and what was
found (the rules are listed in :mod:`fdisyn.runtime.gainfile`'s docstring). Sizes are checked first
(:func:`check_limits`), so that nothing costly runs on a file beyond :data:`~fdisyn.runtime.schema.LIMITS`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, NoReturn

import numpy as np
from fdisyn.runtime.errors import GainFileError
from fdisyn.runtime.layout import linear_state_layout
from fdisyn.runtime.names import (
    SHORT_LABEL_MAX,
    check_diagnoser_name,
    check_distinct,
    check_fault_name,
    check_label,
    check_signal_texts,
    check_signal_names,
    shown,
)
from fdisyn.runtime.schema import (
    ACCOUNT_EFFECTS,
    ACCOUNT_FORMAT,
    FORMAT,
    LIMITS,
    MATRIX_KEYS,
    MAX_MAGNITUDE,
    SIGNAL_LABEL_MAX,
    UNIT_MAX,
)
from fdisyn.runtime.statistics import STATISTICS
from fdisyn.runtime.warmup import MAX_WARMUP, warmup_coefficients
from fdisyn.runtime.values import real_number

# The gain file's types (:mod:`fdisyn.runtime.gainfile`) run these checks when they are built, so this module cannot
# import them (that would be an import circle): a ``GainFile``, ``Generator``, ``Evaluator`` or ``Decision`` is
# passed as ``Any`` below, and each function's docstring names which it is.
_GainFile = Any  # a GainFile
_Generator = Any  # a Generator
_Evaluator = Any  # an Evaluator
_Decision = Any  # a Decision

__all__ = [
    "validate_gain_file",
    "validate_generator",
    "validate_account",
    "validate_signals",
    "signal_keys",
    "check_certificate",
    "check_limits",
    "check_magnitudes",
    "step_coefficients",
]


def _fail(msg: str) -> NoReturn:
    raise GainFileError(msg)


def _shape(a: np.ndarray, where: str, shape: tuple[int, int]) -> None:
    if a.shape != shape:
        _fail(f"{where}: expected shape {shape}, found {a.shape}")


def validate_generator(g: _Generator) -> None:
    """A generator's matrices fit together and it reads only the outputs it names (``outputs_used``)."""
    w = f"generator {g.name!r}"
    if g.Ar.ndim != 2 or g.Ar.shape[0] != g.Ar.shape[1]:
        _fail(f"{w}.Ar must be square (the generator's state matrix), found shape {g.Ar.shape}")
    ns, ng, m, p = g.Ar.shape[0], g.Cr.shape[0], g.Bu.shape[1], g.By.shape[1]
    for k, shape in (
        ("Bu", (ns, m)),
        ("By", (ns, p)),
        ("Cr", (ng, ns)),
        ("Du", (ng, m)),
        ("Dy", (ng, p)),
        ("Xu", (ns, m)),
        ("Xy", (ns, p)),
    ):
        _shape(getattr(g, k), f"{w}.{k}", shape)
    if not g.outputs_used or any(not 0 <= j < p for j in g.outputs_used) or len(set(g.outputs_used)) != len(g.outputs_used):
        _fail(f"{w}.outputs_used must be distinct indices in 0..{p - 1}, found {list(g.outputs_used)}")
    unused = [j for j in range(p) if j not in g.outputs_used]
    if unused and (np.any(g.By[:, unused]) or np.any(g.Dy[:, unused])):
        _fail(f"{w} reads outputs {unused} that are not in outputs_used")
    if isinstance(g.warmup, bool) or not isinstance(g.warmup, (int, np.integer)) or not 0 <= g.warmup <= MAX_WARMUP:
        _fail(f"{w}.warmup must be a whole number of samples in 0..{MAX_WARMUP}, found {shown(g.warmup)}")


def validate_gain_file(gf: _GainFile) -> None:
    """Every check of a gain file (:class:`~fdisyn.runtime.gainfile.GainFile` runs it on construction)."""
    if gf.format != FORMAT:
        _fail(f"format {gf.format!r}; expected {FORMAT!r}")
    check_limits(gf)  # sizes first: nothing costly runs on a file beyond them
    _validate_names(gf)
    if not (math.isfinite(gf.Ts) and 0 < gf.Ts <= MAX_MAGNITUDE):
        _fail(f"Ts must be a positive sample time in seconds of at most {MAX_MAGNITUDE:g}, found {gf.Ts!r}")
    st = gf.step
    if st.nu != len(gf.inputs) or st.ny != len(gf.outputs):
        _fail(f"step sizes nu={st.nu}, ny={st.ny} do not match {len(gf.inputs)} inputs and {len(gf.outputs)} outputs")
    if st.init_state.shape != (st.nstate,):
        _fail(f"step.init_state has {st.init_state.size} entries; nstate is {st.nstate}")
    check_magnitudes(st.init_state, "step.init_state")
    if len(st.residual_names) != st.nr or len(st.statistic_names) != st.nj:
        _fail(f"step names: {len(st.residual_names)} residual and {len(st.statistic_names)} statistic names for nr={st.nr}, nj={st.nj}")
    if gf.kind == "linear":
        _validate_linear(gf)
    elif gf.kind not in gf.extensions:
        _fail(f"diagnoser kind {gf.kind!r} needs its payload in extensions[{gf.kind!r}]")
    else:
        _validate_extension_thresholds(gf)
    if gf.account is not None:
        validate_account(gf)
    if gf.signals is not None:
        validate_signals(gf)


SIGNAL_TEXTS = {"units": UNIT_MAX, "labels": SIGNAL_LABEL_MAX}
"""The tables of the optional ``signals`` block and the longest text each holds."""


def signal_keys(inputs: Sequence[str], outputs: Sequence[str], faults: Sequence[str]) -> tuple[str, ...]:
    """The names a gain file's ``signals`` block may describe: its inputs, its outputs and the other signals its faults
    name (component faults; a fault ``a+b`` or ``a|b`` names ``a`` and ``b``), in that order."""
    named = dict.fromkeys(part for f in faults for alt in f.split("|") for part in alt.split("+"))
    return (*inputs, *outputs, *(nm for nm in named if nm not in inputs and nm not in outputs))


def validate_signals(gf: _GainFile) -> None:
    """The optional ``signals`` block: ``{"units": {name: text}, "labels": {name: text}}``, each table optional.

    A key is an input, an output or a signal a fault of the file names (:func:`signal_keys`); a unit is at most
    :data:`~fdisyn.runtime.schema.UNIT_MAX` printable characters on one line, a label at most
    :data:`~fdisyn.runtime.schema.SIGNAL_LABEL_MAX` (:func:`~fdisyn.runtime.names.check_text`). Anything else is
    refused naming the field.
    """
    block = gf.signals
    if not isinstance(block, Mapping):
        _fail(f"signals must be an object with 'units' and/or 'labels', found {type(block).__name__} {shown(block)}")
    other = [k for k in block if k not in SIGNAL_TEXTS]
    if other:
        _fail(f"signals holds {shown(other)}; expected only the tables 'units' and 'labels' (text by signal name)")
    keys = signal_keys(gf.inputs, gf.outputs, gf.faults)
    for table, longest in SIGNAL_TEXTS.items():
        if table in block:
            check_signal_texts(block[table], f"signals.{table}", keys, max_length=longest, owner="the gain file", error=GainFileError)


_RULE_MAX = 400
"""Longest definition of a statistic's smallest size in the ``account`` block (one clause, shown on a page)."""


def validate_account(gf: _GainFile) -> None:
    """The optional ``account`` block: informational, but what a page and a terminal show of it must be sound.

    ``format`` :data:`ACCOUNT_FORMAT`; ``faults`` one entry per fault (at most the file's outputs and
    :data:`LIMITS` ``["faults"]`` component faults), each with a fault ``name``, ``type`` ``"sensor"`` (an output of
    the file) or ``"component"``, ``unit`` text or null, ``effect`` one of :data:`ACCOUNT_EFFECTS`, ``size`` and
    ``size_50`` null or finite non-negative numbers, ``seen_by`` and ``persistent_in`` lists of generator labels, and
    per generator ``effect``, ``peak_gain`` and ``dc_gain`` (null or finite ≥ 0); ``statistics`` objects with a
    ``name`` and a ``kind`` (labels) and optionally a ``rule`` (one printable line); ``classes.groups`` lists of fault
    names of the block with a ``reason``, ``classes.unseen`` fault names. Anything else is refused naming the field.
    """
    acc = gf.account
    w = "account"
    if not isinstance(acc, Mapping):
        _fail(f"{w} must be an object, found {type(acc).__name__}")
    if acc.get("format") != ACCOUNT_FORMAT or isinstance(acc.get("format"), bool):
        _fail(f"{w}.format must be {ACCOUNT_FORMAT}, found {shown(acc.get('format'))}; write the file again with `fdisyn design`")
    faults = acc.get("faults")
    if not isinstance(faults, list) or len(faults) > len(gf.outputs) + LIMITS["faults"]:
        _fail(f"{w}.faults must be a list of at most {len(gf.outputs) + LIMITS['faults']} faults, found {shown(faults)}")

    def number(v: object, where: str) -> None:
        x = real_number(v) if type(v) in (int, float) else None
        if v is not None and (x is None or not 0.0 <= x <= MAX_MAGNITUDE):
            _fail(f"{where} must be null or a finite number ≥ 0, found {shown(v)}")

    def labels(v: object, where: str) -> list[str]:
        if not isinstance(v, list) or not all(isinstance(s, str) for s in v):
            _fail(f"{where} must be a list of names, found {shown(v)}")
        for i, s in enumerate(v):
            check_label(s, f"{where}[{i}]", error=GainFileError)
        return v

    names: list[str] = []
    for i, f in enumerate(faults):
        fw = f"{w}.faults[{i}]"
        if not isinstance(f, Mapping):
            _fail(f"{fw} must be an object, found {type(f).__name__}")
        name = check_fault_name(f.get("name"), f"{fw}.name", error=GainFileError)
        names.append(name)
        if f.get("type") not in ("sensor", "component") or (f.get("type") == "sensor" and name not in gf.outputs):
            _fail(f"{fw}.type must be 'sensor' (an output of the file) or 'component', found {shown(f.get('type'))} for {shown(name)}")
        if f.get("unit") is not None and not isinstance(f.get("unit"), str):
            _fail(f"{fw}.unit must be text or null, found {shown(f.get('unit'))}")
        if f.get("effect") not in ACCOUNT_EFFECTS:
            _fail(f"{fw}.effect must be one of {', '.join(map(repr, ACCOUNT_EFFECTS))}, found {shown(f.get('effect'))}")
        for key in ("size", "size_50"):
            number(f.get(key), f"{fw}.{key}")
        labels(f.get("seen_by"), f"{fw}.seen_by")
        labels(f.get("persistent_in"), f"{fw}.persistent_in")
        gens = f.get("generators")
        if not isinstance(gens, Mapping):
            _fail(f"{fw}.generators must be an object, found {shown(gens)}")
        for g, v in gens.items():
            if not isinstance(v, Mapping) or v.get("effect") not in ACCOUNT_EFFECTS:
                _fail(f"{fw}.generators.{shown(g)} must hold an effect of {', '.join(map(repr, ACCOUNT_EFFECTS))}, found {shown(v)}")
            number(v.get("peak_gain"), f"{fw}.generators.{shown(g)}.peak_gain")
            number(v.get("dc_gain"), f"{fw}.generators.{shown(g)}.dc_gain")
    if len(set(names)) != len(names):
        _fail(f"{w}.faults names a fault twice: {sorted({n for n in names if names.count(n) > 1})}")
    stats = acc.get("statistics", [])
    if not isinstance(stats, list):
        _fail(f"{w}.statistics must be a list, found {shown(stats)}")
    for i, st in enumerate(stats):
        sw = f"{w}.statistics[{i}]"
        if not isinstance(st, Mapping) or not all(isinstance(st.get(k), str) for k in ("name", "kind")):
            _fail(f"{sw} must be an object with a 'name' and a 'kind', found {shown(st)}")
        check_label(st["name"], f"{sw}.name", error=GainFileError)
        check_label(st["kind"], f"{sw}.kind", error=GainFileError)
        rule = st.get("rule")
        if rule is not None and not (isinstance(rule, str) and 0 < len(rule) <= _RULE_MAX and rule.isprintable()):
            _fail(f"{sw}.rule must be one line of at most {_RULE_MAX} printable characters, found {shown(rule)}")
    classes = acc.get("classes")
    if not isinstance(classes, Mapping) or not isinstance(classes.get("groups"), list):
        _fail(f"{w}.classes must be an object with a list 'groups', found {shown(classes)}")
    for i, grp in enumerate(classes["groups"]):
        if not isinstance(grp, Mapping) or not isinstance(grp.get("reason"), str):
            _fail(f"{w}.classes.groups[{i}] must be an object with 'faults' and a 'reason', found {shown(grp)}")
        members = labels(grp.get("faults"), f"{w}.classes.groups[{i}].faults")
        if len(members) < 2 or any(m not in names for m in members):
            _fail(f"{w}.classes.groups[{i}].faults must name two or more faults of {w}.faults, found {shown(members)}")
    for m in labels(classes.get("unseen", []), f"{w}.classes.unseen"):
        if m not in names:
            _fail(f"{w}.classes.unseen names {shown(m)}, not a fault of {w}.faults")


def _validate_names(gf: _GainFile) -> None:
    """Every name of the file against the grammar of :mod:`fdisyn.runtime.names` (they reach C and CSV headers)."""
    check_diagnoser_name(gf.name, "name", error=GainFileError)
    check_label(gf.problem, "problem", max_length=SHORT_LABEL_MAX, error=GainFileError)
    check_label(gf.design, "design", max_length=SHORT_LABEL_MAX, error=GainFileError)
    check_signal_names(gf.inputs, "inputs", error=GainFileError)
    check_signal_names(gf.outputs, "outputs", error=GainFileError)
    # the replay reads inputs and outputs from the columns of one CSV header
    check_distinct({"inputs": gf.inputs, "outputs": gf.outputs}, why="the replay reads both from one CSV header", error=GainFileError)
    for i, f in enumerate(gf.faults):
        check_fault_name(f, f"faults[{i}]", error=GainFileError)
    if len(set(gf.faults)) != len(gf.faults):
        _fail(f"faults must be unique; repeated: {sorted({f for f in gf.faults if gf.faults.count(f) > 1})}")
    st = gf.step
    for what, labels in (("step.residual_names", st.residual_names), ("step.statistic_names", st.statistic_names)):
        for i, lb in enumerate(labels):
            check_label(lb, f"{what}[{i}]", error=GainFileError)


def _validate_extension_thresholds(gf: _GainFile) -> None:
    """The generic part of another kind's payload: an object, and its ``thresholds`` (read by the C generator)."""
    ext = gf.extensions[gf.kind]
    if not isinstance(ext, Mapping):
        _fail(f"extensions[{gf.kind!r}] must be an object, found {type(ext).__name__}")
    thr = ext.get("thresholds")
    if thr is None:
        return
    if not isinstance(thr, (list, tuple)) or len(thr) != gf.step.nj:
        _fail(f"extensions[{gf.kind!r}].thresholds must list one threshold (or null) per statistic ({gf.step.nj}), found {shown(thr)}")
    for j, v in enumerate(thr):
        if v is not None and type(v) not in (int, float):
            _fail(f"extensions[{gf.kind!r}].thresholds[{j}] must be a number or null, found {shown(v)}")
        if v is not None:
            check_magnitudes(real_number(v), f"extensions[{gf.kind!r}].thresholds[{j}]")


def step_coefficients(generators: Sequence[_Generator], evaluators: Sequence[_Evaluator]) -> int:
    """Nonzero coefficients a linear step multiplies by, each a multiply-add per sample (the warm-ups' constants are
    counted apart: :func:`fdisyn.runtime.warmup.warmup_coefficients`)."""
    count = sum(int(np.count_nonzero(getattr(g, k))) for g in generators for k in MATRIX_KEYS)
    return count + sum(int(np.count_nonzero(e.W)) + (int(np.count_nonzero(e.directions)) if e.directions is not None else 0) for e in evaluators)


def check_limits(gf: _GainFile) -> None:
    """Refuse a gain file beyond :data:`LIMITS` (:class:`GainFileError` naming the size and its limit).

    Called by the reader before the costly checks (eigenvalues) and by the
    C generator before it generates anything.
    """
    st = gf.step
    generic = (
        ("inputs", "inputs", len(gf.inputs)),
        ("outputs", "outputs", len(gf.outputs)),
        ("faults", "faults", len(gf.faults)),
        ("step_outputs", "residual names (step.residual_names)", len(st.residual_names)),
        ("step_outputs", "statistic names (step.statistic_names)", len(st.statistic_names)),
    )
    for key, what, count in generic:
        if count > LIMITS[key]:
            _fail(f"{what}: {count}; at most {LIMITS[key]} are supported (see the size limits)")
    if gf.kind != "linear":
        return
    sizes = (
        ("generators", "generators", len(gf.generators)),
        ("generator_states", "states in one generator", max((g.n_state for g in gf.generators), default=0)),
        ("nstate", "step.nstate (state entries)", gf.step.nstate),
        ("residuals", "residual components (step.nr)", sum(g.n_residual for g in gf.generators)),
        ("generators", "evaluators", len(gf.evaluators)),
        ("plant_states", "plant dimensions (states, or rows or columns of a plant matrix)", max((max(a.shape, default=0) for a in gf.plant.values()), default=0)),
        ("unknown_inputs", "plant unknown inputs (columns of plant.E)", gf.plant["E"].shape[1] if "E" in gf.plant else 0),
    )
    for key, what, count in sizes:
        if count > LIMITS[key]:
            _fail(f"{what}: {count}; at most {LIMITS[key]} are supported (see the size limits)")
    if gf.decision is not None and gf.decision.persistence > LIMITS["persistence"]:
        _fail(
            f"decision.persistence: {gf.decision.persistence}; at most {LIMITS['persistence']} consecutive exceedances are "
            "supported (the step counts them in a double: a larger persistence could never alarm)"
        )
    warm = sum(warmup_coefficients(int(g.warmup), g.n_state, g.n_residual) for g in gf.generators)
    if warm > LIMITS["warmup_coefficients"]:
        _fail(
            f"the generators' warm-ups hold {warm} constants; at most {LIMITS['warmup_coefficients']} are supported (each "
            "a constant table entry of the generated C): expected shorter warm-ups (generators[*].warmup)"
        )
    iso = None if gf.decision is None else gf.decision.isolation
    if iso is not None:
        held = int(np.asarray(iso.basis).size + np.asarray(iso.directions).size)
        if held > LIMITS["isolation_coefficients"]:
            _fail(
                f"decision.isolation holds {held} coefficients (basis and directions); at most "
                f"{LIMITS['isolation_coefficients']} are supported (each a multiply-add per sample): expected "
                "fewer residuals or fault classes, or a design without the isolation test"
            )
    coeffs = step_coefficients(gf.generators, gf.evaluators)
    if coeffs > LIMITS["coefficients"]:
        _fail(
            f"the generators and evaluators hold {coeffs} nonzero coefficients; at most {LIMITS['coefficients']} are "
            "supported (each a multiply-add per sample and 8 bytes of the generated C's tables): expected a smaller bank or "
            "plant"
        )


def _normalised(a: np.ndarray, where: str) -> tuple[np.ndarray, float]:
    """``a / s`` and ``s = max |a_ij|``, after checking that ``a`` is symmetric (relative to ``s``).

    Working on ``a / s`` keeps every check finite however large the entries.
    """
    scale = float(np.max(np.abs(a))) if a.size else 0.0
    if scale == 0.0:
        return a, 0.0
    b = a / scale
    asym = float(np.max(np.abs(b - b.T)))
    # the writer stores exactly symmetrised matrices; 1e-10 admits a file rounded to ~10 digits by hand
    if not asym <= 1e-10:
        _fail(f"{where} is not symmetric (max |{where} − {where}ᵀ| = {asym * scale:.3g})")
    return 0.5 * (b + b.T), scale


def _eigenvalues(b: np.ndarray, where: str) -> np.ndarray:
    try:
        return np.linalg.eigvalsh(b) if b.size else np.zeros(0)
    except np.linalg.LinAlgError:
        _fail(f"{where}: its eigenvalues cannot be computed")


# Relative size below which an eigenvalue counts as zero: round-off leaves ~1e-16 of the largest, while
# the design keeps residual directions down to 1e-6 of the largest variance (chi2_evaluator's rank rule),
# i.e. W eigenvalues down to 1e-6 of its largest; 1e-9 sits three decades from either.
_RANK_RTOL = 1e-9


def _validate_chi2_weight(e: _Evaluator, w: str) -> None:
    """``J = rᵀ W r`` must be a χ² statistic with ``dof`` degrees of freedom for residuals of covariance ``Σ_r``.

    ``Σ_r`` symmetric PSD; ``W`` symmetric PSD (a negative direction makes a
    statistic that can never alarm) of rank ``dof``, and the pseudo-inverse
    of ``Σ_r`` on its range: ``W Σ_r W = W``. Checked on the normalised
    matrices, and written so that a check that cannot be evaluated fails.
    """
    ng = e.W.shape[0]
    if not 1 <= e.dof <= ng:
        _fail(f"{w}.dof must be between 1 and the residual size {ng}, found {e.dof}")
    sn, ss = _normalised(e.Sigma_r, f"{w}.Sigma_r")
    wn, sw = _normalised(e.W, f"{w}.W")
    lam_s = _eigenvalues(sn, f"{w}.Sigma_r")
    lam_w = _eigenvalues(wn, f"{w}.W")
    if ss == 0.0 or not lam_s[0] >= -_RANK_RTOL * float(np.max(np.abs(lam_s))):
        _fail(f"{w}.Sigma_r must be a nonzero covariance (symmetric positive semidefinite); eigenvalues {(lam_s * ss).tolist()}")
    top_w = float(np.max(np.abs(lam_w))) if sw else 0.0
    if sw == 0.0 or not lam_w[0] >= -_RANK_RTOL * top_w:
        _fail(
            f"{w}.W must be positive semidefinite and nonzero (smallest eigenvalue {lam_w[0] * sw:.3g}, largest "
            f"{lam_w[-1] * sw:.3g}); a statistic with a negative direction may never alarm"
        )
    rank = int(np.sum(lam_w > _RANK_RTOL * top_w))
    if rank != e.dof:
        _fail(f"{w}.W has rank {rank} but dof is {e.dof}; the threshold is the χ²({e.dof}) quantile")
    # W Σ W − W = sw·((sw·ss) Wn Sn Wn − Wn): relative to ‖W‖ = sw‖Wn‖
    with np.errstate(over="ignore", invalid="ignore"):
        gap = float(np.linalg.norm((sw * ss) * (wn @ sn @ wn) - wn)) / float(np.linalg.norm(wn))
    # round-off of W Σ W is ~eps·cond(Σ_r on W's range) ≤ 1e-16·1e6 relative (the design's rank rule);
    # 1e-6 leaves margin yet refuses a W scaled by 1 + 1e-6 or built from another Σ_r
    if not gap <= 1e-6:
        _fail(
            f"{w}.W is not the pseudo-inverse of Sigma_r on its range (‖W Σ_r W − W‖ / ‖W‖ = {gap:.3g}); "
            f"J would not be χ²({e.dof}) and the threshold would not give P_f"
        )


def _validate_sequential(e: _Evaluator, w: str, ng: int, decision: _Decision | None) -> None:
    """A CUSUM or GLR statistic: its directions lie in ``W``'s range (they are ``μᵀ W``), its drifts and
    information are positive where they must be, and it decides without persistence."""
    assert e.directions is not None
    rows = e.directions.shape[0]
    _shape(e.directions, f"{w}.directions", (rows, ng))
    check_magnitudes(e.directions, f"{w}.directions")
    stat = STATISTICS[e.kind]
    per = stat.rows_per_hypothesis(e)
    if rows == 0 or rows % per:
        _fail(f"{w}.directions must hold {per} row(s) per fault hypothesis and at least one hypothesis, found {rows} rows")
    for name in stat.vectors:
        assert getattr(e, name) is not None
        check_magnitudes(getattr(e, name), f"{w}.{name}")
    refusal = stat.check_vectors(e, w, rows, per) if stat.check_vectors is not None else ""
    if refusal:
        _fail(refusal)
    if decision is not None and decision.persistence != 1:
        _fail(f"decision.persistence must be 1 with a sequential ({e.kind!r}) evaluator, found {decision.persistence}")
    if len(e.hypotheses) != rows // per:
        _fail(f"{w}.hypotheses must name the {rows // per} hypotheses of its directions, found {len(e.hypotheses)} names")
    for i, h in enumerate(e.hypotheses):
        check_label(h, f"{w}.hypotheses[{i}]", error=GainFileError)


def check_magnitudes(values: object, where: str) -> None:
    """Refuse a number that is not finite or is beyond :data:`MAX_MAGNITUDE` in magnitude.

    Parameters
    ----------
    values
        A number or an array of numbers (any shape) of the field ``where``.
    where
        The field, as the refusal names it (``generators[0].Bu``).

    Raises
    ------
    GainFileError
        One line naming the field, the first offending entry (its index) and the bound.
    """
    a = np.asarray(values, dtype=float)
    with np.errstate(invalid="ignore"):
        bad = ~(np.abs(a) <= MAX_MAGNITUDE)  # NaN fails the comparison, so it is bad too
    if np.any(bad):
        idx = np.unravel_index(int(np.argmax(bad)), a.shape) if a.ndim else ()
        at = "".join(f"[{int(i)}]" for i in idx)
        _fail(
            f"{where}{at} is {float(a[idx])!r}; a gain file's numbers must be finite and at most {MAX_MAGNITUDE:g} in "
            "magnitude (larger ones overflow its consistency checks): write the file again with `fdisyn design`"
        )


def _validate_linear(gf: _GainFile) -> None:
    m, p = len(gf.inputs), len(gf.outputs)
    pl = gf.plant
    for k, a in pl.items():
        check_magnitudes(a, f"plant.{k}")
    for i, gen in enumerate(gf.generators):
        for k in MATRIX_KEYS:
            check_magnitudes(getattr(gen, k), f"generators[{i}].{k}")
    for j, ev in enumerate(gf.evaluators):
        check_magnitudes(ev.Sigma_r, f"evaluators[{j}].Sigma_r")
        check_magnitudes(ev.W, f"evaluators[{j}].W")
    if set(pl) != {"A", "B", "C", "D", "E", "Q", "R"}:
        _fail(f"plant must hold A, B, C, D, E, Q, R; found {sorted(pl)}")
    n = pl["A"].shape[0]
    for k, shape in (("A", (n, n)), ("B", (n, m)), ("C", (p, n)), ("D", (p, m)), ("Q", (n, n)), ("R", (p, p))):
        _shape(pl[k], f"plant.{k}", shape)
    if pl["E"].shape[0] != n:
        _fail(f"plant.E: expected {n} rows, found {pl['E'].shape[0]}")
    if not gf.generators:
        _fail("a linear diagnoser needs at least one generator")
    nr = 0
    for i, g in enumerate(gf.generators):
        check_label(g.name, f"generators[{i}].name", error=GainFileError)
        w = f"generators[{i}] ({g.name})"
        ns = g.n_state
        if g.Bu.shape[1] != m or g.By.shape[1] != p:
            _fail(f"{w} is for {g.Bu.shape[1]} inputs and {g.By.shape[1]} outputs; the file has {m} and {p}")
        if ns:
            try:
                with np.errstate(over="ignore", invalid="ignore"):
                    rho = float(np.max(np.abs(np.linalg.eigvals(g.Ar))))
            except np.linalg.LinAlgError:
                rho = math.inf
            if not rho < 1.0:
                _fail(f"{w}.Ar is not Schur stable (spectral radius {rho:.6g}); the generator would diverge")
            # the equilibrium maps must solve (I − Ar) X = B: catches edited or corrupted files. The entries are
            # within MAX_MAGNITUDE, so both sides stay finite; a non-finite one (NaN or inf) fails all the same
            for xk, bk in (("Xu", "Bu"), ("Xy", "By")):
                x, b = getattr(g, xk), getattr(g, bk)
                with np.errstate(over="ignore", invalid="ignore"):
                    res = float(np.linalg.norm((np.eye(ns) - g.Ar) @ x - b))
                    bound = 1e-8 * (float(np.linalg.norm(b)) + float(np.linalg.norm(g.Ar)) * float(np.linalg.norm(x)) + 1e-300)
                if not (math.isfinite(res) and math.isfinite(bound) and res <= bound):
                    _fail(f"{w}.{xk} is not (I − Ar)⁻¹ {bk} (residual {res:.3g}, allowed {bound:.3g}); the file is inconsistent")
        nr += g.n_residual
    if len(gf.evaluators) == 0:
        _fail("a linear diagnoser needs at least one evaluator")
    for j, e in enumerate(gf.evaluators):
        w = f"evaluators[{j}]"
        if e.kind not in STATISTICS:  # the table read live: a statistic added to it is known everywhere at once
            _fail(f"{w}.kind {e.kind!r} is not supported (supported: {', '.join(map(repr, STATISTICS))})")
        stat = STATISTICS[e.kind]
        refusal = stat.window_rule(e, w)
        if refusal:
            _fail(refusal)
        if stat.sequential != (e.directions is not None):
            kinds = " or ".join(repr(k) for k, s in STATISTICS.items() if s.sequential)
            _fail(f"{w}.directions: {'required' if stat.sequential else 'only allowed'} for a {kinds} evaluator")
        if not 0 <= e.generator < len(gf.generators):
            _fail(f"{w}.generator {e.generator} is not a generator index (0..{len(gf.generators) - 1})")
        ng = gf.generators[e.generator].n_residual
        _shape(e.Sigma_r, f"{w}.Sigma_r", (ng, ng))
        _shape(e.W, f"{w}.W", (ng, ng))
        if not 0.0 < e.P_f < 1.0:
            _fail(f"{w}.P_f must be a probability in (0, 1), found {e.P_f}")
        check_magnitudes(e.threshold, f"{w}.threshold")
        if not e.threshold > 0:
            _fail(f"{w}.threshold must be positive, found {e.threshold}")
        _validate_chi2_weight(e, w)
        if stat.sequential:
            _validate_sequential(e, w, ng, gf.decision)
    d = gf.decision
    if d is None:
        _fail("a linear diagnoser needs a decision")
        return
    if d.kind != "signature_table":
        _fail(f"decision.kind {d.kind!r} is not supported (supported: 'signature_table')")
    _shape(d.signatures, "decision.signatures", (len(gf.faults), len(gf.evaluators)))
    sig = np.asarray(d.signatures)
    if not np.all((sig == 0) | (sig == 1)):
        _fail("decision.signatures must hold only 0 and 1")
    rows = [tuple(r) for r in sig.astype(int)]
    for f, row in enumerate(rows):
        if not any(row):
            _fail(f"decision.signatures: fault {gf.faults[f]!r} has an all-zero signature (it would be undetectable)")
        if rows.count(row) > 1:
            _fail(f"decision.signatures: fault {gf.faults[f]!r} shares its signature {list(row)} with another fault")
    if d.isolation is not None:
        _validate_isolation(d.isolation, len(gf.faults), nr)
    st = gf.step
    lay = linear_state_layout(gf.generators, gf.evaluators, gf.decision)
    if st.nr != nr or st.nj != len(gf.evaluators) or st.nstate != lay.size:
        _fail(
            f"step sizes nr={st.nr}, nj={st.nj}, nstate={st.nstate} do not match the generators "
            f"(nr={nr}, nj={len(gf.evaluators)}, nstate={lay.size})"
        )
    # the linear step starts from zero: no generator ready (each starts at the equilibrium of its first
    # valid sample), no persistence counted, no sample skipped; anything else is an edited file
    if np.any(st.init_state != 0.0):
        _fail(f"step.init_state of a linear diagnoser must be all zeros; entries {np.flatnonzero(st.init_state).tolist()[:8]} are not")




def _validate_isolation(iso: Any, nf: int, nr: int) -> None:
    """The isolation test's fields: sizes, a probability, a forgetting factor, positive levels and a nesting
    relation with a zero diagonal."""
    w = "decision.isolation"
    if not 0.0 < iso.level < 0.5:
        _fail(f"{w}.level must be a probability in (0, 0.5), found {iso.level}")
    if not 0.0 <= iso.forgetting < 1.0:
        _fail(f"{w}.forgetting must be in [0, 1), found {iso.forgetting}")
    basis = np.asarray(iso.basis)
    if basis.ndim != 2 or basis.shape[1] != nr or not 1 <= basis.shape[0] <= nr:
        _fail(f"{w}.basis: expected shape (k, {nr}) with 1 ≤ k ≤ {nr} (the residuals), found {basis.shape}")
    k = basis.shape[0]
    ranks = np.asarray(iso.ranks)
    if ranks.shape != (nf,) or np.any(ranks < 0) or np.any(ranks > k):
        _fail(f"{w}.ranks must hold {nf} integers in 0..{k} (one per fault), found {ranks.tolist()}")
    _shape(np.asarray(iso.directions), f"{w}.directions", (int(ranks.sum()), k))
    for key in ("accept", "reject"):
        v = np.asarray(getattr(iso, key))
        if v.shape != (nf,) or not np.all(v > 0):
            _fail(f"{w}.{key} must hold {nf} positive numbers (one per fault), found {v.tolist()}")
    if not 1 <= int(iso.settle) <= 10**6:
        _fail(f"{w}.settle must be a whole number of samples in 1..1000000, found {iso.settle}")
    _shape(iso.nested, f"{w}.nested", (nf, nf))
    nested = np.asarray(iso.nested)
    if not np.all((nested == 0) | (nested == 1)) or np.any(np.diag(nested) != 0):
        _fail(f"{w}.nested must hold only 0 and 1 with a zero diagonal")
    check_magnitudes(iso.basis, f"{w}.basis")
    check_magnitudes(iso.directions, f"{w}.directions")


def _check_holds(value: object, bound: object, relation: object) -> bool:
    """``value <relation> bound`` with both finite numbers (:func:`~fdisyn.runtime.values.real_number`)."""
    v, b = real_number(value), real_number(bound)
    if v is None or b is None or not (math.isfinite(v) and math.isfinite(b)):
        return False
    if relation == "<=":
        return v <= b
    return relation == ">=" and v >= b


def check_certificate(node: object, where: str, depth: int = 0) -> None:
    """Every verdict inside the certificate must be a pass, and every check must hold by its own numbers.

    ``certificate.passed = true`` alone is one flag: an edited file could keep
    it while a generator's or a check's ``passed`` is false, or while a check's
    ``value`` no longer meets its ``bound``. So every object in the tree that
    holds ``passed`` must hold ``true``, and every check (an object with
    ``relation``) must have finite numbers ``value`` and ``bound`` that satisfy
    it — the rule of ``fdisyn.numerics.certificate.Check``. The writer nests a
    few levels; a tree deeper than 64 is refused before it could exhaust
    Python's recursion limit.
    """
    if depth > 64:
        _fail(f"{where}: the certificate is nested more than 64 levels deep; expected the structure `fdisyn design` writes")
    if isinstance(node, dict):
        if "passed" in node and node["passed"] is not True:
            _fail(
                f"{where}.passed is {shown(node['passed'])}, not true: the design did not pass this part of its "
                "verification, so it is neither compiled nor run; re-run `fdisyn design`"
            )
        if "relation" in node:
            v, b, rel = node.get("value"), node.get("bound"), node.get("relation")
            if not _check_holds(v, b, rel):
                _fail(
                    f"{where} ({shown(node.get('name'))}): value {shown(v)} {shown(rel)} bound {shown(b)} does not hold; "
                    "expected finite numbers meeting the relation '<=' or '>=' (an edited certificate)"
                )
        for k, v in node.items():
            check_certificate(v, f"{where}.{k}", depth + 1)
    elif isinstance(node, list):
        for i, v in enumerate(node):
            check_certificate(v, f"{where}[{i}]", depth + 1)
