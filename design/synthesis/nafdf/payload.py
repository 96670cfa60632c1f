"""The NAFDF's gain-file payload: writing, reading and validating it, and rebuilding the step from it.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np
from fdisyn.detectors.sequential import lorden_delay
from fdisyn.models.casadi_program import function_from_program, model_program
from fdisyn.models.nonlinear import NonlinearPlant
from fdisyn.models.sampling import check_sample_time
from fdisyn.numerics.linalg import as_covariance
from fdisyn.runtime.errors import FdisynError, GainFileError
from fdisyn.runtime.gainfile import GainFile, StepSpec, signals_block
from fdisyn.runtime.validate import check_magnitudes
from fdisyn.runtime.layout import StateLayout
from fdisyn.runtime.names import shown
from fdisyn.runtime.values import real_number
from fdisyn.synthesis.linear_diagnoser import provenance
from fdisyn.synthesis.nafdf.design import NafdfDesign, _design, _init_state, _names_r_J, detector_thresholds
from fdisyn.synthesis.nafdf.settings import _IDENT, _MAX_NAME, DEFAULT_MIN_SHIFT, MAX_DIMENSION, NafdfSettings, _layout, _settings

__all__ = ['PAYLOAD_FORMAT', 'PAYLOAD_VERSION', 'nafdf_budget_seconds', 'nafdf_from_gain_file', 'nafdf_lorden_bound', 'nafdf_lorden_window', 'nafdf_from_payload', 'nafdf_gain_file', 'nafdf_payload', 'nafdf_scaled', 'step_from_payload']

PAYLOAD_FORMAT = "fdisyn.nafdf"
PAYLOAD_VERSION = 4
"""Version 4: the fast detection's statistic is a choice (``settings.detector``: WSSR, CUSUM or GLR, with
``settings.min_shift`` and ``settings.arl0``), its thresholds in ``detector_thresholds``. Version 3 (read as
the WSSR, its table in ``wssr_thresholds``): the convergence of the NF judged against its own covariance (``settings.isolable_jump``, the
statistics ``info_<θ>`` and ``insufficient_excitation``); version 2 bounded the range of θ̂ by
``settings.convergence_tolerance``; both store the model as validated operation lists (version 1 held
CasADi serialised strings)."""
_FORMER_VERSIONS: Mapping[int, str] = {
    1: "the model as CasADi serialised strings",
    2: "the NF's convergence by a fixed tolerance on the range of θ̂, without the information statistics",
}
_READABLE_VERSIONS = (3, PAYLOAD_VERSION)
_NOISE_KEYS: Mapping[str, str] = {"Q": "Q1", "R": "Q2"}
"""The plant's noise covariances → their keys in ``plant`` of the payload: Zhou, Xi & Zhang's letters
(eq. (2.1)), which the payload format (version 2) keeps."""


# --------------------------------------------------------------------------- payload


def nafdf_payload(design: NafdfDesign) -> dict[str, object]:
    """A JSON-able description from which :func:`step_from_payload` rebuilds the identical step.

    The model is stored as data: ``f`` and ``h`` as
    :func:`~fdisyn.models.casadi_program.model_program` operation lists (exact:
    CasADi's own operation sequence, constants to the bit), which the reader
    validates entry by entry before building anything. Expression strings,
    when the plant came from them, are kept alongside for people to read; the
    reader re-parses them and refuses a file where they describe another
    model. The WSSR threshold table is stored as numbers (and checked
    against its rule on reading), so the rebuilt step is bit for bit the
    designed one. CasADi's version is recorded for provenance only.
    """
    pl, s = design.plant, design.settings
    return {
        "format": PAYLOAD_FORMAT,
        "version": PAYLOAD_VERSION,
        "name": design.name,
        "casadi_version": ca.CasadiMeta.version(),
        "plant": {
            "states": list(pl.states),
            "inputs": list(pl.inputs),
            "outputs": list(pl.outputs),
            "parameters": list(pl.parameters),
            "theta_nominal": [float(v) for v in pl.theta_nominal],
            _NOISE_KEYS["Q"]: np.asarray(pl.Q).tolist(),
            _NOISE_KEYS["R"]: np.asarray(pl.R).tolist(),
            "Ts": pl.Ts,
            "f": model_program(pl.f),
            "h": model_program(pl.h),
            "expressions": None if pl.expressions is None else json.loads(json.dumps(pl.expressions)),
            "units": dict(pl.units),
        },
        "settings": s.to_dict(),
        "detector_thresholds": [float(v) for v in design.thresholds],
        "state_layout": [[nm, r, c] for nm, r, c in design.layout.entries],
        "init_state": [float(v) for v in design.init_state()],
        "r_names": list(design.r_names),
        "J_names": list(design.J_names),
        "fault_names": list(design.fault_names),
        "certificate": design.certificate.to_dict(),
    }


_PAYLOAD_FIELDS = frozenset(
    {
        "format",
        "version",
        "name",
        "casadi_version",
        "plant",
        "settings",
        "detector_thresholds",
        "state_layout",
        "init_state",
        "r_names",
        "J_names",
        "fault_names",
        "certificate",
    }
)
_PLANT_FIELDS = frozenset(
    {"states", "inputs", "outputs", "parameters", "theta_nominal", *_NOISE_KEYS.values(), "Ts", "f", "h", "expressions", "units"}
)
_SETTINGS_FIELDS = tuple(NafdfSettings.__dataclass_fields__)
_DETECTOR_SETTINGS = frozenset({"detector", "min_shift", "arl0"})
"""Settings of version 4 (a version 3 file has the WSSR and none of them)."""
_OPTIONAL_SETTINGS = frozenset({"threshold_scale"})
"""Settings a version 4 file holds only when they differ from their default (:meth:`NafdfSettings.to_dict`)."""
# The WSSR table is recomputed on reading and compared at this relative tolerance: SciPy's χ² quantile is
# accurate to ~1e-14, so another SciPy version passes while any edit of the stored numbers is refused.
_TABLE_RTOL = 1e-9


class _Fields:
    """Typed access to one JSON object of a payload; every failure names the field (one line)."""

    def __init__(self, doc: object, where: str, *, required: frozenset[str] | tuple[str, ...], optional: frozenset[str] = frozenset()) -> None:
        if not isinstance(doc, Mapping):
            raise GainFileError(f"{where} must be an object; found {type(doc).__name__}")
        missing = sorted(set(required) - set(doc))
        unknown = sorted(str(k) for k in set(doc) - set(required) - set(optional))
        if missing or unknown:
            raise GainFileError(f"{where}: missing field(s) {missing}, unknown field(s) {shown(unknown)}")
        self.doc, self.where = doc, where

    def fail(self, key: str, expected: str) -> GainFileError:
        return GainFileError(f"{self.where}.{key} must be {expected}; found {shown(self.doc.get(key))}")

    def string(self, key: str) -> str:
        v = self.doc[key]
        if not isinstance(v, str):
            raise self.fail(key, "a string")
        return v

    def integer(self, key: str) -> int:
        v = self.doc[key]
        if isinstance(v, bool) or not isinstance(v, int):
            raise self.fail(key, "an integer")
        return v

    def number(self, key: str, *, allow_none: bool = False) -> float | None:
        v = self.doc[key]
        if v is None and allow_none:
            return None
        return _json_number(v, f"{self.where}.{key}")

    def numbers(self, key: str, size: int, *, allow_none: bool = False) -> np.ndarray:
        """A list of ``size`` finite numbers (``null`` → ±inf for the parameter box's open sides)."""
        v = self.doc[key]
        if not isinstance(v, list) or len(v) != size:
            raise self.fail(key, f"a list of {size} numbers")
        return np.array([np.nan if z is None and allow_none else _json_number(z, f"{self.where}.{key}") for z in v], dtype=float)

    def matrix(self, key: str, rows: int, cols: int) -> np.ndarray:
        v = self.doc[key]
        if not isinstance(v, list) or len(v) != rows or not all(isinstance(r, list) and len(r) == cols for r in v):
            raise self.fail(key, f"a {rows}×{cols} matrix (a list of {rows} rows of {cols} numbers)")
        return np.array([[_json_number(z, f"{self.where}.{key}") for z in r] for r in v], dtype=float).reshape(rows, cols)

    def names(self, key: str, *, allow_empty: bool = False) -> tuple[str, ...]:
        v = self.doc[key]
        if not isinstance(v, list) or not all(isinstance(z, str) for z in v):
            raise self.fail(key, "a list of names")
        if len(v) > MAX_DIMENSION or (not v and not allow_empty):
            raise self.fail(key, f"a list of 1 to {MAX_DIMENSION} names")
        bad = [z for z in v if not _IDENT.fullmatch(z) or len(z) > _MAX_NAME]
        if bad or len(set(v)) != len(v):
            raise self.fail(key, f"a list of distinct identifiers of at most {_MAX_NAME} characters")
        return tuple(v)


def _json_number(v: object, where: str) -> float:
    out = real_number(v)
    if out is None:
        raise GainFileError(f"{where} must hold numbers; found {shown(v)}")
    if not math.isfinite(out):
        raise GainFileError(f"{where} must hold finite numbers; found {shown(v)}")
    check_magnitudes(out, where)  # bounded like every number of a gain file: no check below can overflow
    return out


@dataclass(frozen=True, eq=False)
class _Payload:
    """A validated payload: everything the step is built from, nothing built yet."""

    name: str
    plant: NonlinearPlant
    settings: NafdfSettings
    thresholds: np.ndarray
    layout: StateLayout
    fixed_thresholds: list[float | None] | None


def _wrap(where: str, fn: Any, *args: Any, **kw: Any) -> Any:
    """Call ``fn``; an fdisyn error it raises becomes a :class:`GainFileError` prefixed by ``where``."""
    try:
        return fn(*args, **kw)
    except GainFileError:
        raise
    except FdisynError as exc:
        raise GainFileError(f"{where}: {exc}") from None


def _read_plant(doc: object, where: str) -> NonlinearPlant:
    """The plant of a payload: sizes first, then the model programs, then the plant's own checks."""
    f = _Fields(doc, where, required=_PLANT_FIELDS)
    states, outputs, parameters = f.names("states"), f.names("outputs"), f.names("parameters")
    inputs = f.names("inputs", allow_empty=True)
    n, m, p, l = len(states), len(inputs), len(outputs), len(parameters)
    theta = f.numbers("theta_nominal", l)
    mats = {ours: f.matrix(key, size, size) for (ours, key), size in zip(_NOISE_KEYS.items(), (n, p), strict=True)}
    ts = f.number("Ts", allow_none=True)
    if ts is not None:
        _wrap(f"{where}.Ts", check_sample_time, ts)
    units = f.doc["units"]
    if not isinstance(units, Mapping) or len(units) > 4 * MAX_DIMENSION or not all(
        isinstance(k, str) and isinstance(v, str) and len(k) <= _MAX_NAME and len(v) <= _MAX_NAME for k, v in units.items()
    ):
        raise f.fail("units", f"an object of at most {4 * MAX_DIMENSION} short names and unit strings")
    programs = {
        "f": _wrap(f"{where}.f", function_from_program, f.doc["f"], name="f", in_names=("x", "u", "theta"), in_sizes=(n, m, l), out_name="x_next", out_size=n),
        "h": _wrap(f"{where}.h", function_from_program, f.doc["h"], name="h", in_names=("x", "theta"), in_sizes=(n, l), out_name="y", out_size=p),
    }
    for ours, key in _NOISE_KEYS.items():  # the plant checks them too; here a refusal names the payload's key
        _wrap(where, as_covariance, mats[ours], key, len(mats[ours]), definite=ours == "R")
    common = dict(
        states=states, inputs=inputs, outputs=outputs, parameters=parameters, nominal=dict(zip(parameters, theta.tolist(), strict=True)),
        Q=mats["Q"], R=mats["R"], Ts=ts, units=dict(units),
    )
    expressions = f.doc["expressions"]
    e = None if expressions is None else _Fields(expressions, f"{where}.expressions", required=frozenset({"f", "h", "constants"}))
    plant = _wrap(where, NonlinearPlant.create, f=programs["f"], h=programs["h"], expressions=expressions, **common)
    if e is not None:
        text = _wrap(f"{where}.expressions", NonlinearPlant.from_expressions, f=e.doc["f"], h=e.doc["h"], constants=e.doc["constants"], **common)
        for key in ("f", "h"):
            if model_program(getattr(text, key)) != model_program(getattr(plant, key)):
                raise GainFileError(f"{where}.expressions.{key} describe another model than {where}.{key}; the file was edited")
    return plant


def _read_payload(payload: object, where: str, *, gain_file: bool) -> _Payload:
    """Validate every field of a payload (and nothing built but the model's SX graph)."""
    optional = frozenset() if gain_file else frozenset({"thresholds"})
    required = _PAYLOAD_FIELDS | ({"thresholds"} if gain_file else frozenset())
    if isinstance(payload, Mapping) and payload.get("format") != PAYLOAD_FORMAT:
        raise GainFileError(f"{where}: payload format is {shown(payload.get('format'))}; expected {PAYLOAD_FORMAT!r}")
    version = payload.get("version") if isinstance(payload, Mapping) else None
    if isinstance(payload, Mapping) and (isinstance(version, bool) or version not in _READABLE_VERSIONS):
        former = _FORMER_VERSIONS.get(version) if isinstance(version, int) and not isinstance(version, bool) else None
        held = f" ({former})" if former else ""
        raise GainFileError(
            f"{where}: payload version is {shown(version)}{held}; this fdisyn reads versions "
            f"{', '.join(map(str, _READABLE_VERSIONS))}: design it again"
        )
    v3 = version == 3
    table_key = "wssr_thresholds" if v3 else "detector_thresholds"
    if v3:
        required = (required - {"detector_thresholds"}) | {"wssr_thresholds"}
    top = _Fields(payload, where, required=frozenset(required), optional=optional)
    name = top.string("name")
    if not _IDENT.fullmatch(name) or len(name) > _MAX_NAME:
        raise top.fail("name", f"an identifier of at most {_MAX_NAME} characters")
    top.string("casadi_version")
    plant = _read_plant(top.doc["plant"], f"{where}.plant")
    n, m, l = plant.n, plant.m, plant.l  # noqa: E741 — the paper's letter for dim θ

    sf = _Fields(
        top.doc["settings"], f"{where}.settings",
        required=tuple(k for k in _SETTINGS_FIELDS if not (v3 and k in _DETECTOR_SETTINGS) and k not in _OPTIONAL_SETTINGS),
        optional=frozenset() if v3 else _OPTIONAL_SETTINGS,
    )
    raw: dict[str, Any] = {
        "x0": sf.numbers("x0", n),
        "P0": sf.matrix("P0", n, n),
        "theta0": sf.numbers("theta0", l),
        "R0": sf.matrix("R0", l, l),
        "window": sf.integer("window"),
        "threshold_rule": sf.string("threshold_rule"),
        "false_alarm_probability": sf.number("false_alarm_probability"),
        "beta0": sf.number("beta0", allow_none=True),
        "forgetting_initial": sf.number("forgetting_initial"),
        "forgetting_rate": sf.number("forgetting_rate"),
        "forgetting_final": sf.number("forgetting_final"),
        "theta_lower": np.nan_to_num(sf.numbers("theta_lower", l, allow_none=True), nan=-np.inf),
        "theta_upper": np.nan_to_num(sf.numbers("theta_upper", l, allow_none=True), nan=np.inf),
        "nominal_samples": sf.integer("nominal_samples"),
        "classifier_window": sf.integer("classifier_window"),
        "W1": sf.number("W1"),
        "W2": sf.number("W2"),
        "T1": sf.integer("T1"),
        "isolable_jump": np.nan_to_num(sf.numbers("isolable_jump", l, allow_none=True), nan=np.inf),
        "convergence_level": sf.number("convergence_level"),
        "u0": sf.numbers("u0", m),
    }
    if not v3:
        raw["detector"] = sf.string("detector")
        # the CUSUM's shift; the other detectors record the default, which stands for "not given"
        raw["min_shift"] = sf.number("min_shift")
        if raw["detector"] != "cusum" and raw["min_shift"] == DEFAULT_MIN_SHIFT:
            raw["min_shift"] = None
        raw["arl0"] = sf.number("arl0", allow_none=True)
        if "threshold_scale" in sf.doc:
            raw["threshold_scale"] = sf.number("threshold_scale")
    settings: NafdfSettings = _wrap(f"{where}.settings", _settings, plant, **raw)
    if settings.arl0 is not None and not math.isclose(raw["false_alarm_probability"], settings.false_alarm_probability, rel_tol=_TABLE_RTOL):
        raise GainFileError(
            f"{where}.settings.false_alarm_probability is {raw['false_alarm_probability']!r}; arl0 = {settings.arl0!r} s gives "
            f"{settings.false_alarm_probability!r}"
        )

    table = top.numbers(table_key, settings.window if settings.detector == "wssr" else 1)
    truth = _wrap(f"{where}.settings", detector_thresholds, plant, settings)
    if not np.allclose(table, truth, rtol=_TABLE_RTOL, atol=0.0):
        k = int(np.argmax(np.abs(table - truth) > _TABLE_RTOL * np.abs(truth)))
        raise GainFileError(
            f"{where}.{table_key}[{k}] is {float(table[k])!r}; the settings (detector {settings.detector!r}, rule "
            f"{settings.threshold_rule!r}, P_f {settings.false_alarm_probability!r}, window {settings.window}, threshold scale "
            f"{settings.threshold_scale!r}) give {float(truth[k])!r}"
        )
    layout = _layout(n, l, settings.window, settings.classifier_window, settings.detector, plant.p)
    if top.doc["state_layout"] != [[nm, r, c] for nm, r, c in layout.entries]:
        raise GainFileError(f"{where}.state_layout does not match the layout the settings imply ({layout.size} entries)")
    init = top.numbers("init_state", layout.size)
    expected = _init_state(plant, settings, layout)
    if not np.array_equal(init, expected):
        k = int(np.argmax(init != expected))
        raise GainFileError(
            f"{where}.init_state[{k}] ({layout.component_names()[k]}) is {float(init[k])!r}; the settings give {float(expected[k])!r}"
        )
    r_names, J_names = _names_r_J(plant, settings.detector)
    for key, want in (("r_names", r_names), ("J_names", J_names), ("fault_names", plant.parameters)):
        if top.doc[key] != list(want):
            raise GainFileError(f"{where}.{key} is {shown(top.doc[key])}; the plant implies {shown(list(want))}")
    cert = top.doc["certificate"]
    if not isinstance(cert, Mapping) or cert.get("passed") is not True:
        raise GainFileError(f"{where}.certificate did not pass (passed = {shown(cert.get('passed') if isinstance(cert, Mapping) else cert)}); a design that failed its verification is not built")
    fixed = None
    if "thresholds" in top.doc:
        fixed = _fixed_thresholds(J_names, plant, table, settings.W1)
        if top.doc["thresholds"] != fixed:
            raise GainFileError(
                f"{where}.thresholds is {shown(top.doc['thresholds'])}; expected {len(J_names)} entries "
                f"(the detector's (full-window) threshold on {J_names[0]}, W1 on each d_θ, null elsewhere)"
            )
    return _Payload(name=name, plant=plant, settings=settings, thresholds=table, layout=layout, fixed_thresholds=fixed)


def _fixed_thresholds(J_names: tuple[str, ...], plant: NonlinearPlant, table: np.ndarray, W1: float) -> list[float | None]:
    """The alarm threshold per statistic the C API exports: the detector's (the WSSR's full-window) on its
    statistic (``J_names[0]``), ``W1`` on each ``d_θ``."""
    fixed = {J_names[0]: float(table[-1])} | {f"d_{q}": float(W1) for q in plant.parameters}
    return [fixed.get(j) for j in J_names]


def _build(parsed: _Payload, where: str) -> NafdfDesign:
    """Build and re-certify a validated payload's design (limits and model checks included)."""
    design = _wrap(where, _design, parsed.plant, parsed.settings, name=parsed.name, thresholds=parsed.thresholds)
    if design.layout.entries != parsed.layout.entries:  # the step's own layout: a guard on _build_step itself
        raise GainFileError(f"{where}: the rebuilt step's state layout differs from the payload's")
    return design


def nafdf_from_payload(payload: Mapping[str, object]) -> NafdfDesign:
    """Rebuild the design (plant, settings, step) from :func:`nafdf_payload`'s output alone.

    Every field is validated before the step is built (module docstring);
    the design is then re-certified. Raises :class:`GainFileError` naming the
    field, with what it holds and what was expected.
    """
    return _build(_read_payload(payload, "payload", gain_file=False), "payload")


def nafdf_from_gain_file(gf: GainFile) -> NafdfDesign:
    """The design of a ``kind = "nafdf"`` gain file, validated against the whole file.

    Beyond :func:`nafdf_from_payload`: the file's certificate must have
    passed, and its inputs, outputs, faults, sample time, step sizes, names,
    initial state and exported thresholds must be the ones the payload
    implies (a ``faults`` list that disagrees, an all-zero ``init_state`` or
    a short ``thresholds`` list is refused, not compiled).
    """
    where = "extensions.nafdf"
    if not isinstance(gf.certificate, Mapping) or gf.certificate.get("passed") is not True:
        passed = gf.certificate.get("passed") if isinstance(gf.certificate, Mapping) else None
        raise GainFileError(f"certificate.passed is {shown(passed)}; a design that failed its verification is not built")
    parsed = _read_payload(gf.extensions.get("nafdf"), where, gain_file=True)
    pl = parsed.plant
    r_names, J_names = _names_r_J(pl, parsed.settings.detector)
    init = _init_state(pl, parsed.settings, parsed.layout)
    st = gf.step
    for field_name, found, want in (
        ("inputs", gf.inputs, pl.inputs),
        ("outputs", gf.outputs, pl.outputs),
        ("faults", gf.faults, pl.parameters),
        ("Ts", gf.Ts, float(pl.Ts) if pl.Ts else 1.0),
        ("step.nu", st.nu, pl.m),
        ("step.ny", st.ny, pl.p),
        ("step.nr", st.nr, len(r_names)),
        ("step.nj", st.nj, len(J_names)),
        ("step.nstate", st.nstate, parsed.layout.size),
        ("step.residual_names", st.residual_names, r_names),
        ("step.statistic_names", st.statistic_names, J_names),
    ):
        if found != want:
            raise GainFileError(f"{field_name} is {shown(found)}; {where} implies {shown(want)}")
    if not np.array_equal(st.init_state, init):
        k = int(np.argmax(st.init_state != init))
        raise GainFileError(
            f"step.init_state[{k}] ({parsed.layout.component_names()[k]}) is {float(st.init_state[k])!r}; {where} implies {float(init[k])!r}"
        )
    return _build(parsed, where)


def step_from_payload(payload: Mapping[str, object]) -> ca.Function:
    """The step Function rebuilt from a payload (identical graph to the designed one)."""
    return nafdf_from_payload(payload).step


# --------------------------------------------------------------------------- gain file


def nafdf_gain_file(
    design: NafdfDesign, *, problem: str, design_name: str = "nafdf", name: str | None = None, options: Mapping[str, object] | None = None
) -> GainFile:
    """The gain file (kind ``"nafdf"``) of a design: the common fields plus the payload.

    ``extensions["nafdf"]`` holds :func:`nafdf_payload` and the fixed alarm
    thresholds per statistic (the full-window WSSR threshold on ``wssr``,
    ``W1`` on each Bayes distance ``d_θ``, none elsewhere). A model without a
    physical sample time uses ``Ts = 1`` (time counted in samples).
    """
    pl = design.plant
    payload = nafdf_payload(design)
    payload["thresholds"] = _fixed_thresholds(design.J_names, pl, design.thresholds, design.settings.W1)
    cert = design.certificate.to_dict()
    return GainFile(
        kind="nafdf",
        name=name or f"{problem}_{design_name}",
        problem=problem,
        design=design_name,
        Ts=float(pl.Ts) if pl.Ts else 1.0,
        inputs=tuple(pl.inputs),
        outputs=tuple(pl.outputs),
        faults=tuple(design.fault_names),
        step=StepSpec(
            nu=pl.m,
            ny=pl.p,
            nr=len(design.r_names),
            nj=len(design.J_names),
            nstate=design.nstate,
            init_state=design.init_state(),
            residual_names=tuple(design.r_names),
            statistic_names=tuple(design.J_names),
        ),
        certificate={"passed": bool(cert["passed"]), "nafdf": cert},
        provenance=provenance(options=dict(options or {})),
        extensions={"nafdf": payload},
        signals=signals_block(pl.units, pl.labels, pl.inputs, pl.outputs, design.fault_names),
    )



def nafdf_scaled(gf: GainFile, scale: float, name: str) -> GainFile:
    """A copy of the NAFDF of ``gf`` named ``name`` whose fast-detection thresholds are ``scale`` times its own
    (:attr:`~fdisyn.synthesis.nafdf.settings.NafdfSettings.threshold_scale`, multiplying the scale it has): the
    rest of the filter, its classifier and its dismissal unchanged. Rebuilt and certified as any design.

    Parameters
    ----------
    gf : GainFile
        A ``kind = "nafdf"`` gain file.
    scale : float
        The factor, in :data:`~fdisyn.synthesis.nafdf.settings.THRESHOLD_SCALE_RANGE` once multiplied.
    name : str
        The copy's diagnoser name (an identifier of at most 64 characters).

    Returns
    -------
    GainFile
        The copy; its provenance records the scale among the design's options.
    """
    from dataclasses import replace

    from fdisyn.synthesis.nafdf.settings import _threshold_scale

    design = nafdf_from_gain_file(gf)
    if not _IDENT.fullmatch(name) or len(name) > _MAX_NAME:
        raise FdisynError(f"a scaled copy's name must be an identifier of at most {_MAX_NAME} characters; got {shown(name)}")
    settings = replace(design.settings, threshold_scale=_threshold_scale(_threshold_scale(scale) * design.settings.threshold_scale))
    copy = _design(design.plant, settings, name=name)
    options = dict(gf.provenance.get("options") or {}) if isinstance(gf.provenance, Mapping) else {}
    options["threshold_scale"] = settings.threshold_scale
    return nafdf_gain_file(copy, problem=gf.problem, design_name=gf.design, name=name, options=options)


def _stored_settings(gf: GainFile) -> Mapping[str, Any]:
    payload = gf.extensions.get("nafdf")
    settings = payload.get("settings") if isinstance(payload, Mapping) else None
    if not isinstance(settings, Mapping):
        raise GainFileError("extensions.nafdf.settings is missing; expected the NAFDF's settings")
    return settings


def nafdf_budget_seconds(gf: GainFile) -> float | None:
    """The NAFDF's designed mean time between false alarms (s): its ``arl0``, or for a design by ``P_f``
    ``Ts·(1/P_f + 2 N2)`` — the detector's run length ``1/P_f`` (a bound for the WSSR, whose exceedances come in
    clusters) plus the ``2 N2`` samples of the false alarm's episode. ``None`` for a copy with scaled thresholds
    (:func:`nafdf_scaled`): its time between false alarms is measured, not designed."""
    s = _stored_settings(gf)
    if s.get("threshold_scale", 1.0) != 1.0:  # the budget set the unscaled thresholds: this copy's time is measured
        return None
    if s.get("arl0") is not None:
        return float(s["arl0"])
    return float(gf.Ts) * (1.0 / float(s["false_alarm_probability"]) + 2.0 * float(s["classifier_window"]))


def nafdf_lorden_window(gf: GainFile) -> int:
    """The samples after a fault's onset over which its innovation shift is measured: ``N2``, before the EKF can
    be re-parameterised (that needs an alarm and then ``N2`` samples of the NF), which removes the shift."""
    return int(_stored_settings(gf)["classifier_window"])


def nafdf_lorden_information(gf: GainFile, shifts: np.ndarray, covariance: np.ndarray) -> list[tuple[float, np.ndarray]]:
    """``[(ARL, I)]``: the detector's budget ``1/P_f`` samples and, for each row ``μ`` of ``shifts`` (``m × nr``),
    :func:`nafdf_lorden_bound`'s information ``½ μᵀ Σ⁺ μ`` of the innovation's shift (the first ``p`` residuals);
    an overflowed (non-finite) information is returned as it is."""
    p = len(gf.outputs)
    mu = np.atleast_2d(np.asarray(shifts, dtype=float))[:, :p]
    cov = np.asarray(covariance, dtype=float)[:p, :p]
    if not np.all(np.isfinite(cov)):
        return []
    with np.errstate(over="ignore", invalid="ignore"):
        info = 0.5 * np.einsum("li,ij,lj->l", mu, np.linalg.pinv(cov, rcond=1e-9, hermitian=True), mu)
    return [(1.0 / float(_stored_settings(gf)["false_alarm_probability"]), info)]


def nafdf_lorden_bound(gf: GainFile, shift: np.ndarray, covariance: np.ndarray) -> tuple[float, float] | None:
    """``(I, ln(ARL)/I)`` of a mean shift ``μ`` of the EKF innovation ``γ`` (the first ``p`` residuals):
    ``I = ½ μᵀ Σ⁺ μ`` with ``Σ`` the innovation's covariance measured without the fault (an exact filter's
    innovations are white, so it is also their long-run covariance), ``ARL = 1/P_f`` samples, the detector's
    false-alarm rate. ``None`` when the shift carries no information."""
    p = len(gf.outputs)
    mu = np.asarray(shift, dtype=float)[:p]
    cov = np.asarray(covariance, dtype=float)[:p, :p]
    if not (np.all(np.isfinite(mu)) and np.all(np.isfinite(cov))):
        return None
    with np.errstate(over="ignore", invalid="ignore"):
        info = 0.5 * float(mu @ np.linalg.pinv(cov, rcond=1e-9, hermitian=True) @ mu)
    if not (math.isfinite(info) and info > 0.0):  # an overflowed (inf, NaN) information gives no bound either
        return None
    return info, lorden_delay(1.0 / float(_stored_settings(gf)["false_alarm_probability"]), info)
