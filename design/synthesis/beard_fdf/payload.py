"""The Beard detection filter's gain-file payload: the filter, writing it and reading it back.

Beard's fault detection filter (Beard, MIT thesis, 1971; Massoumnia, IEEE Transactions on Automatic
Control 31(9), 1986) with the robust decision of He, Zhang & Wu (Journal of Astronautics, c. 1999):
the observer ``x̂⁺ = A x̂ + B u + L ε``, ``ε = y − C x̂ − D u``, whose residual under fault ``i``
stays in the output subspace ``S_i`` (an axis), read through a window RMS (the magnitude test) and
the angle of the window mean to each axis (the cone test).

``extensions["beard_fdf"]`` (format 1) holds the discrete design model and gain, the equilibrium maps,
one orthonormal basis per fault's output subspace, the implicit thresholds ``Y_th`` (radians), the
window, the thresholds ``h`` (on the RMS) and ``explicit_level`` (``ε̄``), the optional fixed ``rho``,
the persistence, the generic ``thresholds``, an informational ``design`` object and, optionally, the
``warmup`` (samples; absent: 0, as in files written before warm-ups). The reader checks
every field (:func:`beard_from_gain_file`) and raises :class:`GainFileError` naming it.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np
from fdisyn.numerics.certificate import Certificate
from fdisyn.runtime.errors import GainFileError
from fdisyn.runtime.gainfile import GainFile, StepSpec
from fdisyn.runtime.jsondata import to_jsonable
from fdisyn.runtime.schema import LIMITS, MAX_MAGNITUDE, SCALAR_STEP_LIMITS
from fdisyn.runtime.validate import check_magnitudes
from fdisyn.runtime.layout import StateLayout
from fdisyn.runtime.names import shown
from fdisyn.runtime.values import real_number
from fdisyn.runtime.warmup import MAX_WARMUP, warmup_coefficients, warmup_constants
from fdisyn.synthesis.linear_diagnoser import provenance

__all__ = [
    "KIND",
    "PAYLOAD_FORMAT",
    "BeardFilter",
    "beard_gain_file",
    "beard_from_gain_file",
    "beard_names",
    "NSTATE_MARGIN",
]

KIND = "beard_fdf"
"""The diagnoser kind (gain file ``kind``) and the key of the payload in ``extensions``."""
PAYLOAD_FORMAT = 1
NSTATE_MARGIN = 8
"""``N·p + n + NSTATE_MARGIN ≤ SCALAR_STEP_LIMITS["nstate"]``: the state holds ``N·p + n + 5`` entries (``n`` more with a
warm-up, which the limit then counts too); the margin is the specification's."""
_ORTHONORMAL_TOL = 1e-9
_EQUILIBRIUM_RTOL = 1e-8
"""Stored ``Xu``, ``Xy`` against their recomputation from ``A B C D L``: a solve with ``I − G`` on another
machine differs by round-off times its condition, far below this; an edit of the numbers does not."""
_FIELDS = (
    "format", "A", "B", "C", "D", "L", "Xu", "Xy", "axes", "Y_th", "window", "h",
    "explicit_level", "rho", "persistence", "thresholds", "design",
)  # fmt: skip
_OPTIONAL = ("warmup",)
"""Fields a payload may leave out: a file written before warm-ups has none (and runs without one)."""


def _jsonable(info: Mapping[str, Any]) -> dict[str, Any]:
    """``info`` as the JSON reader gives it back (tuples → lists, NumPy → Python): the round trip is exact."""
    return json.loads(json.dumps(to_jsonable(dict(info)), allow_nan=False))


@dataclass(frozen=True, eq=False)
class BeardFilter:
    """A Beard detection filter with its robust decision: everything the step is built from.

    ``A, B, C, D`` the discrete design model, ``L`` the gain (``G = A − L C`` keeps each fault's
    detection space invariant); ``axes[i]`` an orthonormal basis (``p × d_i``) of fault ``i``'s output
    subspace ``S_i``; ``Y_th[i]`` its implicit threshold (radians, the model-error part of the cone's
    half-angle); ``window`` ``N``; ``h`` the threshold of the window RMS; ``explicit_level`` ``ε̄``, the
    fault-free bound of the window mean's norm; ``rho`` ``None`` (the cone widens by
    ``asin(ε̄/‖m‖)`` online) or a fixed ratio ``> 1``; ``persistence`` consecutive RMS exceedances
    before an alarm; ``design_info`` informational (eigenvalues, σ, P_f, …), kept as JSON; ``warmup`` the
    samples over which the filter's initial error is estimated by least squares before its window fills
    (:mod:`fdisyn.runtime.warmup` on ``A − L C`` and ``C``; 0: none, the filter starts at its first valid
    sample's equilibrium).
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    L: np.ndarray
    axes: tuple[np.ndarray, ...]
    Y_th: np.ndarray
    window: int
    h: float
    explicit_level: float
    rho: float | None = None
    persistence: int = 1
    design_info: Mapping[str, Any] = field(default_factory=dict)
    warmup: int = 0

    def __post_init__(self) -> None:
        for key in ("A", "B", "C", "D", "L"):
            object.__setattr__(self, key, np.array(getattr(self, key), dtype=float))
        object.__setattr__(self, "axes", tuple(np.array(a, dtype=float).reshape(self.p, -1) for a in self.axes))
        object.__setattr__(self, "Y_th", np.array(self.Y_th, dtype=float).reshape(-1))
        object.__setattr__(self, "window", int(self.window))
        object.__setattr__(self, "h", float(self.h))
        object.__setattr__(self, "explicit_level", float(self.explicit_level))
        object.__setattr__(self, "rho", None if self.rho is None else float(self.rho))
        object.__setattr__(self, "persistence", int(self.persistence))
        object.__setattr__(self, "warmup", int(self.warmup))
        object.__setattr__(self, "design_info", _jsonable(self.design_info))

    @cached_property
    def G(self) -> np.ndarray:
        """``A − L C``: the error dynamics ``e⁺ = G e + f_i μ_i``."""
        return self.A - self.L @ self.C

    @cached_property
    def warmup_gains(self) -> tuple[np.ndarray, np.ndarray]:
        """``(G, M)`` of the warm-up (:func:`fdisyn.runtime.warmup.warmup_constants`, its information scaled to a
        unit diagonal: the states of a user's plant may be in any units): the residual moves with the estimate's
        error ``x̂ − x`` through ``Φ_k = −C (A − L C)^k``."""
        return warmup_constants(self.G, -self.C, self.warmup, None, equilibrate=True)

    @cached_property
    def Xu(self) -> np.ndarray:
        """``(I − G)⁻¹ (B − L D)``: with :attr:`Xy`, the equilibrium ``x̂ = Xu u + Xy y`` the filter starts at."""
        return np.linalg.solve(np.eye(self.n) - self.G, self.B - self.L @ self.D)

    @cached_property
    def Xy(self) -> np.ndarray:
        """``(I − G)⁻¹ L``."""
        return np.linalg.solve(np.eye(self.n) - self.G, self.L)

    @property
    def n(self) -> int:
        return int(self.A.shape[0])

    @property
    def m(self) -> int:
        return int(self.B.shape[1])

    @property
    def p(self) -> int:
        return int(self.C.shape[0])

    @property
    def k(self) -> int:
        """The number of faults (cones)."""
        return len(self.axes)

    @property
    def layout(self) -> StateLayout:
        """``xhat`` (n), ``ready`` (valid samples since the filter started, counted to ``warmup + 1``),
        ``buffer`` (``p × N``: column ``j`` one residual of the ring), ``head`` (the column written next),
        ``count`` (samples in the window, saturating at ``N``), ``counter`` (consecutive RMS exceedances,
        saturating at ``persistence``), ``nonfinite`` (samples skipped); with a warm-up, ``acc`` (n): its
        accumulated ``Σ Φ_kᵀ ε_k``."""
        return StateLayout(
            (
                ("xhat", self.n, 1),
                ("ready", 1, 1),
                ("buffer", self.p, self.window),
                ("head", 1, 1),
                ("count", 1, 1),
                ("counter", 1, 1),
                ("nonfinite", 1, 1),
                *((("acc", self.n, 1),) if self.warmup else ()),
            ),
            scalars=frozenset({"ready", "head", "count", "counter", "nonfinite"}),
            matrices=frozenset({"buffer"}),
        )

    def init_state(self) -> np.ndarray:
        """All zeros: not ready (``x̂`` starts at the first valid sample's equilibrium), an empty window."""
        return np.zeros(self.layout.size)


def beard_names(outputs: Sequence[str], faults: Sequence[str]) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The residual names ``eps_<output>`` and statistic names ``rms, rho, angle_<fault>…, cone_<fault>…``."""
    return (
        tuple(f"eps_{o}" for o in outputs),
        ("rms", "rho", *(f"angle_{f}" for f in faults), *(f"cone_{f}" for f in faults)),
    )


def _thresholds(flt: BeardFilter) -> list[float | None]:
    """The fixed alarm threshold per statistic: ``h`` on ``rms``, 1 on ``rho`` (``ε̄`` reached), none on the angles."""
    return [flt.h, 1.0, *([None] * (2 * flt.k))]


def _payload(flt: BeardFilter) -> dict[str, Any]:
    return {
        "format": PAYLOAD_FORMAT,
        **{key: getattr(flt, key).tolist() for key in ("A", "B", "C", "D", "L", "Xu", "Xy")},
        "axes": [a.tolist() for a in flt.axes],
        "Y_th": flt.Y_th.tolist(),
        "window": flt.window,
        "h": flt.h,
        "explicit_level": flt.explicit_level,
        "rho": flt.rho,
        "persistence": flt.persistence,
        "thresholds": _thresholds(flt),
        "design": dict(flt.design_info),
        **({"warmup": flt.warmup} if flt.warmup else {}),
    }


def beard_gain_file(
    flt: BeardFilter,
    *,
    name: str,
    problem: str,
    design_name: str,
    Ts: float,
    inputs: Sequence[str],
    outputs: Sequence[str],
    faults: Sequence[str],
    certificate: Certificate,
    options: Mapping[str, object] | None = None,
    signals: Mapping[str, Mapping[str, str]] | None = None,
) -> GainFile:
    """The gain file (kind ``"beard_fdf"``) of a filter: the common fields plus the payload.

    ``signals`` is the file's optional block of units and labels (:func:`~fdisyn.runtime.gainfile.signals_block`).

    The certificate is stored as ``{"passed": …, "beard_fdf": certificate}``, the design options in the
    provenance. The file is read back before it is returned (:func:`beard_from_gain_file`): what this
    writes, the reader accepts, and the filter it rebuilds is this one to the bit.
    """
    r_names, j_names = beard_names(outputs, faults)
    cert = certificate.to_dict()
    gf = GainFile(
        kind=KIND,
        name=name,
        problem=problem,
        design=design_name,
        Ts=float(Ts),
        inputs=tuple(inputs),
        outputs=tuple(outputs),
        faults=tuple(faults),
        step=StepSpec(
            nu=len(inputs),
            ny=len(outputs),
            nr=len(r_names),
            nj=len(j_names),
            nstate=flt.layout.size,
            init_state=flt.init_state(),
            residual_names=r_names,
            statistic_names=j_names,
        ),
        certificate={"passed": bool(cert["passed"]), KIND: cert},
        provenance=provenance(options=dict(options or {})),
        extensions={KIND: _payload(flt)},
        signals=signals,
    )
    beard_from_gain_file(gf)
    return gf


# --------------------------------------------------------------------------- reading


class _Reader:
    """Typed access to the payload; every failure is one line naming the field, what was expected and what was found."""

    def __init__(self, doc: Mapping[str, Any], where: str) -> None:
        self.doc, self.where = doc, where

    def fail(self, key: str, expected: str, found: object = ...) -> GainFileError:
        value = self.doc.get(key) if found is ... else found
        return GainFileError(f"{self.where}.{key} must be {expected}; found {shown(value)}")

    def number(self, key: str, expected: str) -> float:
        v = real_number(self.doc[key])
        if v is None or not math.isfinite(v):
            raise self.fail(key, expected)
        check_magnitudes(v, f"{self.where}.{key}")
        return v

    def integer(self, key: str, lo: int, hi: int) -> int:
        v = self.doc[key]
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise self.fail(key, f"a whole number in {lo}..{hi}")
        return v

    def matrix(self, key: str, rows: int, cols: int | None = None, *, value: object = ...) -> np.ndarray:
        """A ``rows × cols`` matrix of finite numbers (``cols=None``: any common row length ≥ 1)."""
        v: Any = self.doc[key] if value is ... else value
        shape = f"{rows}×{'d' if cols is None else cols}"
        ok = isinstance(v, list) and len(v) == rows and all(isinstance(r, list) for r in v)
        width = cols if cols is not None else (len(v[0]) if ok and rows else 0)
        if not ok or any(len(r) != width for r in v) or (cols is None and width < 1):
            raise self.fail(key, f"a {shape} matrix (a list of {rows} rows of numbers)", v)
        nums = [real_number(z) for r in v for z in r]
        if any(z is None or not math.isfinite(z) for z in nums):
            raise self.fail(key, f"a {shape} matrix of finite numbers", v)
        out = np.array(nums, dtype=float).reshape(rows, width)
        check_magnitudes(out, f"{self.where}.{key}")  # bounded: the checks below multiply the entries
        return out


def beard_from_gain_file(gf: GainFile) -> BeardFilter:
    """The filter of a ``kind = "beard_fdf"`` gain file, every field validated.

    Shapes against the common fields (``nu``, ``ny``, ``faults``), finite numbers within
    :data:`~fdisyn.runtime.schema.MAX_MAGNITUDE` (so that no check below overflows), orthonormal axes
    (to 1e-9), ``0 ≤ Y_th ≤ π/2``, ``A − L C`` Schur stable, the equilibrium maps, the window within
    :data:`~fdisyn.runtime.schema.LIMITS` (``N·p + n + 8 ≤ nstate``), ``h, ε̄ > 0``, ``rho`` null or
    ``> 1``, the persistence, the warm-up (0 to :data:`~fdisyn.runtime.warmup.MAX_WARMUP`), the thresholds, and
    the step's sizes, names and initial state. Raises
    :class:`GainFileError` with one line naming the field, what was expected and what was found.
    """
    where = f"extensions.{KIND}"
    if gf.kind != KIND:
        raise GainFileError(f"kind is {shown(gf.kind)}; expected {KIND!r}")
    passed = gf.certificate.get("passed") if isinstance(gf.certificate, Mapping) else None
    if passed is not True:
        raise GainFileError(f"certificate.passed is {shown(passed)}; a design that failed its verification is not built")
    doc = gf.extensions.get(KIND)
    if not isinstance(doc, Mapping):
        raise GainFileError(f"{where} must be an object; found {shown(doc)}")
    missing = [k for k in _FIELDS if k not in doc]
    unknown = sorted(str(k) for k in doc if k not in _FIELDS + _OPTIONAL)
    if missing or unknown:
        raise GainFileError(f"{where}: missing field(s) {missing}, unknown field(s) {shown(unknown)}")
    rd = _Reader(doc, where)
    if type(doc["format"]) is not int or doc["format"] != PAYLOAD_FORMAT:
        raise rd.fail("format", f"{PAYLOAD_FORMAT} (this fdisyn reads payload format {PAYLOAD_FORMAT})")
    m, p, k = len(gf.inputs), len(gf.outputs), len(gf.faults)
    if k < 1 or p < 1:
        what, names = ("faults", gf.faults) if k < 1 else ("outputs", gf.outputs)
        raise GainFileError(f"{what} is {shown(list(names))}; a {KIND} diagnoser needs at least one fault and one output")

    # sizes first: nothing costly runs on a file beyond the limits
    a_doc = doc["A"]
    n = len(a_doc) if isinstance(a_doc, list) else 0
    most = min(SCALAR_STEP_LIMITS["plant_states"], SCALAR_STEP_LIMITS["nstate"] - NSTATE_MARGIN - p)
    if not 1 <= n <= most:
        raise rd.fail("A", f"a square matrix of 1 to {most} rows")
    warmup = rd.integer("warmup", 0, MAX_WARMUP) if "warmup" in doc else 0
    acc = n if warmup else 0  # the warm-up's accumulator
    window = rd.integer("window", 1, max(1, (SCALAR_STEP_LIMITS["nstate"] - NSTATE_MARGIN - n - acc) // p))
    persistence = rd.integer("persistence", 1, LIMITS["persistence"])
    A = rd.matrix("A", n, n)
    B = rd.matrix("B", n, m)
    C = rd.matrix("C", p, n)
    D = rd.matrix("D", p, m)
    L = rd.matrix("L", n, p)

    coefficients = sum(int(np.count_nonzero(x)) for x in (A, B, C, D, L)) + 2 * n * (m + p)
    if coefficients > SCALAR_STEP_LIMITS["coefficients"]:
        raise GainFileError(
            f"{where}: A B C D L and the equilibrium maps hold up to {coefficients} coefficients; at most "
            f"{SCALAR_STEP_LIMITS['coefficients']} are supported (the generated C has one multiply-add per coefficient)"
        )
    if warmup_coefficients(warmup, n, p) > SCALAR_STEP_LIMITS["warmup_coefficients"]:
        raise rd.fail("warmup", f"at most {max(0, (SCALAR_STEP_LIMITS['warmup_coefficients'] - n * n) // (n * p))} samples for {n} states and "
                      f"{p} outputs (its constants, {SCALAR_STEP_LIMITS['warmup_coefficients']} at most, are multiply-adds of the generated C)")
    G = A - L @ C  # finite: entries within MAX_MAGNITUDE (see check_magnitudes)
    try:
        with np.errstate(over="ignore", invalid="ignore"):
            radius = float(np.max(np.abs(np.linalg.eigvals(G))))
    except np.linalg.LinAlgError:
        radius = math.nan
    if not radius < 1.0:  # NaN (eigenvalues that cannot be computed) fails too
        raise GainFileError(f"{where}.L must make A − L C Schur stable (spectral radius < 1); found spectral radius {radius!r}")

    axes_doc = doc["axes"]
    if not isinstance(axes_doc, list) or len(axes_doc) != k:
        raise rd.fail("axes", f"a list of {k} matrices (one per fault)")
    axes = []
    for i, ax in enumerate(axes_doc):
        a = rd.matrix("axes", p, None, value=ax)
        if a.shape[1] > p:
            raise GainFileError(f"{where}.axes[{i}] must have 1 to {p} columns; found {a.shape[1]}")
        gap = float(np.max(np.abs(a.T @ a - np.eye(a.shape[1]))))
        if not gap <= _ORTHONORMAL_TOL:
            raise GainFileError(f"{where}.axes[{i}] must have orthonormal columns (|UᵀU − I| ≤ {_ORTHONORMAL_TOL:g}); found a deviation {gap!r}")
        axes.append(a)

    y_doc = doc["Y_th"]
    y_th = [real_number(v) for v in y_doc] if isinstance(y_doc, list) else []
    if not isinstance(y_doc, list) or len(y_doc) != k or any(v is None or not 0.0 <= v <= math.pi / 2 for v in y_th):
        raise rd.fail("Y_th", f"a list of {k} angles in [0, π/2] (radians)")
    h = rd.number("h", "a positive finite number")
    level = rd.number("explicit_level", "a positive finite number")
    if not h > 0:
        raise rd.fail("h", "a positive finite number")
    if not level > 0:
        raise rd.fail("explicit_level", "a positive finite number")
    rho: float | None = None
    if doc["rho"] is not None:
        rho = rd.number("rho", "null (online) or a finite number > 1")
        if not rho > 1.0:
            raise rd.fail("rho", "null (online) or a finite number > 1")
    if not isinstance(doc["design"], Mapping):
        raise rd.fail("design", "an object (informational)")

    flt = BeardFilter(
        A=A, B=B, C=C, D=D, L=L, axes=tuple(axes), Y_th=np.array(y_th, dtype=float), window=window, h=h,
        explicit_level=level, rho=rho, persistence=persistence, design_info=doc["design"], warmup=warmup,
    )  # fmt: skip
    for key in ("Xu", "Xy"):
        try:
            with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
                want = getattr(flt, key)
        except np.linalg.LinAlgError:
            want = np.full((n, m if key == "Xu" else p), math.nan)
        got = rd.matrix(key, n, want.shape[1])
        if not np.all(np.abs(want) <= MAX_MAGNITUDE):  # large entries or I − G near singular: beyond the bound, inf or NaN
            raise GainFileError(
                f"{where}.{key}: A B C D L give an equilibrium map with entries up to {float(np.max(np.abs(want))):.3g}, beyond "
                f"{MAX_MAGNITUDE:g} (their numbers are too large or I − (A − L C) is too close to singular); expected a "
                "filter whose equilibrium a gain file can hold"
            )
        scale = float(np.max(np.abs(want))) if want.size else 0.0
        gap = float(np.max(np.abs(got - want))) if want.size else 0.0
        if not (math.isfinite(gap) and gap <= _EQUILIBRIUM_RTOL * scale):
            raise GainFileError(
                f"{where}.{key} must be the equilibrium map (I − G)⁻¹{'(B − L D)' if key == 'Xu' else ' L'} of A B C D L "
                f"(to {_EQUILIBRIUM_RTOL:g} relative); found it {gap!r} away"
            )
    if doc["thresholds"] != _thresholds(flt):
        raise rd.fail("thresholds", f"[h, 1.0] and {2 * k} nulls ({shown(_thresholds(flt))})")

    r_names, j_names = beard_names(gf.outputs, gf.faults)
    st, lay = gf.step, flt.layout
    for key, found, want in (
        ("step.nr", st.nr, p),
        ("step.nj", st.nj, 2 + 2 * k),
        ("step.nstate", st.nstate, lay.size),
        ("step.residual_names", st.residual_names, r_names),
        ("step.statistic_names", st.statistic_names, j_names),
    ):
        if found != want:
            raise GainFileError(f"{key} is {shown(found)}; {where} implies {shown(want)}")
    if not np.array_equal(st.init_state, flt.init_state()):
        j = int(np.argmax(st.init_state != flt.init_state()))
        raise GainFileError(f"step.init_state[{j}] ({lay.component_names()[j]}) is {float(st.init_state[j])!r}; {where} implies 0.0")
    return flt
