"""The gain file: a diagnoser's versioned, self-contained description (JSON).

Format ``fdisyn.gains/1``. Common fields (every diagnoser kind):

``format``, ``kind``, ``name`` (a C identifier: the prefix of the generated C),
``problem``, ``design``, ``Ts``, ``inputs``, ``outputs``, ``faults``,
``step`` {``nu ny nr nj nstate``, ``init_state``, ``residual_names``,
``statistic_names``}, ``certificate``, ``provenance``, ``extensions``.

Linear diagnosers (``kind = "linear"``) add ``plant`` {``A B C D E Q R``: the
discrete model the design used, in its state coordinates}, ``generators`` (the
canonical form ``ξ⁺ = Ar ξ + Bu u + By y``, ``r = Cr ξ + Du u + Dy y`` on the
full ``u``, ``y``, plus the equilibrium maps ``Xu = (I − Ar)⁻¹ Bu``,
``Xy = (I − Ar)⁻¹ By`` used to start the generator at the first valid
sample), ``evaluators`` (``kind = "chi2"``: the statistic ``J = rᵀ W r``,
``W = Σ_r⁺``; ``kind = "wssr"``: its windowed sum over the last ``window``
valid samples, see :class:`Evaluator`) and ``decision`` (a fault signature
table over the statistics).

Matrices are nested lists of floats written with full round-trip precision
(Python's ``repr``); non-finite numbers are refused on writing and reading,
and so are numbers beyond :data:`MAX_MAGNITUDE` (``1e150``) in magnitude,
which could overflow the consistency checks. The document is parsed strictly
(:func:`parse_json_data`: a key repeated in any object is refused). The
reader validates everything and raises :class:`GainFileError` naming the
field, what was expected and what was found:

* names follow :mod:`fdisyn.runtime.names` (``name`` prefixes the C API;
  ``inputs`` and ``outputs`` are signal names, distinct across both lists;
  ``faults`` are fault names; ``problem``, ``design`` and the generator,
  residual and statistic names are labels);
* ``certificate.passed`` must be ``true``: a design that failed its
  verification is neither compiled nor run;
* an evaluator's ``W`` (χ² and WSSR alike) must be symmetric positive
  semidefinite with rank ``dof`` and the pseudo-inverse of ``Sigma_r`` on its
  range (``W Σ_r W = W``), its threshold positive; ``window`` is 1 for a χ²
  evaluator and a whole number in 1..:data:`MAX_WSSR_WINDOW` (required) for a
  WSSR one;
* sizes stay within :data:`LIMITS`, checked before any costly step (the
  generated C grows with the number of coefficients; gcc's time and memory
  with it).

:func:`gain_file_sha256` is the file's content hash (canonical JSON: layout
and whitespace do not matter, every value does); ``fdisyn codegen`` compiles
it into the library so that a library never runs another gain file.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import stat
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, NoReturn

import numpy as np
from fdisyn.runtime.errors import FdisynError, GainFileError
from fdisyn.runtime.layout import StateLayout
from fdisyn.runtime.names import (
    SHORT_LABEL_MAX,
    check_diagnoser_name,
    check_distinct,
    check_fault_name,
    check_label,
    check_signal_names,
    shown,
)
from fdisyn.runtime.values import real_number

__all__ = [
    "FORMAT",
    "Generator",
    "Evaluator",
    "Decision",
    "StepSpec",
    "GainFile",
    "read_gain_file",
    "write_gain_file",
    "linear_state_layout",
    "to_jsonable",
    "LIMITS",
    "check_limits",
    "step_coefficients",
    "gain_file_sha256",
    "read_regular_file",
    "EVALUATOR_KINDS",
    "SEQUENTIAL_KINDS",
    "MAX_WSSR_WINDOW",
    "MAX_GLR_WINDOW",
    "MAX_MAGNITUDE",
    "check_magnitudes",
    "parse_json_data",
    "glr_weights",
    "release_level",
    "ACCOUNT_FORMAT",
    "ACCOUNT_EFFECTS",
]

FORMAT = "fdisyn.gains/1"
_FORMAT_FAMILY = "fdisyn.gains/"
_MATRIX_KEYS = ("Ar", "Bu", "By", "Cr", "Du", "Dy", "Xu", "Xy")
EVALUATOR_KINDS = ("chi2", "wssr", "cusum", "glr")
"""The statistics a linear diagnoser evaluates (:class:`Evaluator`)."""
SEQUENTIAL_KINDS = ("cusum", "glr")
"""Statistics that accumulate evidence over time (:class:`Evaluator`): their alarm holds until the evidence is gone."""
MAX_GLR_WINDOW = 1000
"""Largest GLR onset window accepted: the step updates ``window`` sums per hypothesis and sample."""
MAX_WSSR_WINDOW = 100_000
"""Largest WSSR window accepted in a gain file. The window's ``q`` values are part of the state, so
``nstate`` ≤ :data:`LIMITS` ``["nstate"]`` bounds the windows of a compiled diagnoser further."""

LIMITS: Mapping[str, int] = {
    # every kind
    "inputs": 256,
    "outputs": 256,
    "faults": 256,
    "step_outputs": 1024,
    "file_bytes": 64 * 1024 * 1024,
    # linear kind
    "generators": 64,
    "generator_states": 256,
    "nstate": 2048,
    "residuals": 256,
    "plant_states": 512,
    "unknown_inputs": 256,
    "coefficients": 10_000,
    "persistence": 10**9,
}
"""Size limits of a gain file, checked by the reader before anything costly.

``coefficients`` — the nonzero entries of every generator's ``Ar Bu By Cr
Du Dy Xu Xy`` and every evaluator's ``W`` — is the one that matters: the
generated C holds one multiply-add per coefficient in straight-line code, and
gcc -O2's memory grows by ~45 kB per coefficient (measured on a 2-core machine
shared with other jobs: 4 974 coefficients took 11 s and 0.20 GB, 9 774 took
14–16 s and 0.44 GB; a dense 400-state generator, ~170 000 coefficients,
would take minutes and gigabytes). ``nstate`` ≤ 2048 keeps the step's copy
of the state on the stack at 16 KiB; ``generator_states`` ≤ 256 bounds the
stability check (an eigenvalue problem per generator); the signal, fault,
generator and residual counts (``step_outputs``: residual and statistic names of any kind) bound the
name tables and the replay program's stack arrays; ``file_bytes`` bounds what
the reader parses at all. ``persistence`` ≤ 10⁹ consecutive exceedances: the
step counts them in a double, and beyond 2⁵³ a count no longer grows, so a
larger one could never alarm (10⁹, like the NAFDF's sample counters, is 11
days of samples at 1 kHz). Other kinds add their own limits to their payload."""

ACCOUNT_FORMAT = 1
"""Format of a gain file's optional ``account`` block (what the design can see; see :func:`_validate_account`)."""
ACCOUNT_EFFECTS = ("zero", "transient", "persistent")
"""A fault's effect on a residual in the ``account`` block: none, its onset only (zero steady-state gain), or lasting."""

MAX_MAGNITUDE = 1e150
"""Largest magnitude of a number in a gain file's matrices and numeric fields (every kind's payload too).

The reader's consistency checks multiply the file's numbers: ``(I − Ar) Xu − Bu``, ``‖Ar‖·‖Xu‖``,
``A − L C`` and its equilibrium solve, ``UᵀU`` of an axis basis. A product of two entries is at most
10³⁰⁰; a sum of them over an inner dimension the :data:`LIMITS` allow (at most 2048) at most ~2·10³⁰³,
and the Frobenius norm of a matrix of at most 2048 × 2048 such sums ~4·10³⁰⁶: below the largest double
(1.8·10³⁰⁸), so no check can overflow to ``inf`` and pass (``gap ≤ tol·inf``). Designed files hold
numbers far below it (the committed designs: at most ~10¹⁰)."""


@dataclass(frozen=True, eq=False)
class Generator:
    """One residual generator in canonical form (see the module docstring)."""

    name: str
    outputs_used: tuple[int, ...]
    Ar: np.ndarray
    Bu: np.ndarray
    By: np.ndarray
    Cr: np.ndarray
    Du: np.ndarray
    Dy: np.ndarray
    Xu: np.ndarray
    Xy: np.ndarray
    method: Mapping[str, Any] = field(default_factory=dict)
    Ts: float | None = None
    """Sample time of the gain file that holds the generator (set by :class:`GainFile`; not written:
    the file's ``Ts`` is)."""

    def __post_init__(self) -> None:
        w = f"generator {self.name!r}"
        if self.Ar.ndim != 2 or self.Ar.shape[0] != self.Ar.shape[1]:
            _fail(f"{w}.Ar must be square (the generator's state matrix), found shape {self.Ar.shape}")
        ns, ng, m, p = self.Ar.shape[0], self.Cr.shape[0], self.Bu.shape[1], self.By.shape[1]
        for k, shape in (
            ("Bu", (ns, m)),
            ("By", (ns, p)),
            ("Cr", (ng, ns)),
            ("Du", (ng, m)),
            ("Dy", (ng, p)),
            ("Xu", (ns, m)),
            ("Xy", (ns, p)),
        ):
            _shape(getattr(self, k), f"{w}.{k}", shape)
        if not self.outputs_used or any(not 0 <= j < p for j in self.outputs_used) or len(set(self.outputs_used)) != len(self.outputs_used):
            _fail(f"{w}.outputs_used must be distinct indices in 0..{p - 1}, found {list(self.outputs_used)}")
        unused = [j for j in range(p) if j not in self.outputs_used]
        if unused and (np.any(self.By[:, unused]) or np.any(self.Dy[:, unused])):
            _fail(f"{w} reads outputs {unused} that are not in outputs_used")

    @classmethod
    def from_canonical(
        cls,
        *,
        name: str,
        outputs_used: Sequence[int],
        Ar: np.ndarray,
        Bu: np.ndarray,
        By: np.ndarray,
        Cr: np.ndarray,
        Du: np.ndarray,
        Dy: np.ndarray,
        method: Mapping[str, Any] | None = None,
    ) -> Generator:
        """A generator from its canonical matrices; the equilibrium maps are computed.

        ``Xu = (I − Ar)⁻¹ Bu``, ``Xy = (I − Ar)⁻¹ By``: the state a generator
        settles to under constant ``u``, ``y`` (it starts there, see the runtime).
        """
        ar = np.array(Ar, dtype=float)
        lhs = np.eye(ar.shape[0]) - ar
        bu, by = np.array(Bu, dtype=float), np.array(By, dtype=float)
        return cls(
            name=name,
            outputs_used=tuple(int(j) for j in outputs_used),
            Ar=ar,
            Bu=bu,
            By=by,
            Cr=np.array(Cr, dtype=float),
            Du=np.array(Du, dtype=float),
            Dy=np.array(Dy, dtype=float),
            Xu=np.linalg.solve(lhs, bu) if ar.size else bu.copy(),
            Xy=np.linalg.solve(lhs, by) if ar.size else by.copy(),
            method=dict(method or {}),
        )

    @property
    def n_state(self) -> int:
        return int(self.Ar.shape[0])

    def to_control(self) -> Any:
        """The generator as a discrete python-control ``StateSpace``.

        ``ξ⁺ = Ar ξ + [Bu By] [u; y]``, ``r = Cr ξ + [Du Dy] [u; y]``: inputs
        ``[u; y]`` (every input, then every output of the gain file), output
        ``r``, ``dt`` the gain file's ``Ts`` (``True``, discrete with an
        unspecified sample time, for a generator outside a gain file).
        python-control is imported here, not with the runtime.
        """
        import control

        return control.ss(
            self.Ar,
            np.hstack([self.Bu, self.By]),
            self.Cr,
            np.hstack([self.Du, self.Dy]),
            dt=True if self.Ts is None else self.Ts,
            name=self.name,
        )

    @property
    def n_residual(self) -> int:
        return int(self.Cr.shape[0])


@dataclass(frozen=True, eq=False)
class Evaluator:
    """A statistic of one generator's residual ``r``, alarm when ``J > threshold``.

    ``kind = "chi2"``: ``J(k) = q(k) = r(k)ᵀ W r(k)`` (Hu, Sun, Jiang, He & Zhang, Acta Automatica Sinica
    39(8), 2013, eq. (18)). ``kind = "wssr"``: the windowed weighted sum of squared residuals of Long & Wang
    (Aeroengine 43(5), 2017, section 2), ``J(k) = Σ_{l<N} q(k − l)`` over the last ``N = window`` samples the
    generator evaluated (a sample it skips — a non-finite input, an overflow — does not enter); until ``N``
    such samples have been seen, ``J`` sums those there are and is compared with the same full-window
    threshold (conservative at start-up). ``window = 1`` is the χ² statistic.

    Sequential kinds (the generator's residual is white, with covariance ``Sigma_r``; ``W`` its pseudo-inverse):

    * ``"cusum"`` (Page, Biometrika 41(1/2), 1954): two CUSUMs per row ``a_i`` of ``directions``
      (``a_i = μ_iᵀ W`` for a fault of steady-state residual signature ``μ_i``), one per sign of the fault,
      with ``drift[i] = ½ μ_iᵀ W μ_i``: ``S_i^±(k) = min(max(0, S_i^±(k−1) ± a_i r(k) − drift[i]), 2·threshold)``
      and ``J = max_i max(S_i^+, S_i^−)``.
    * ``"glr"`` (Willsky & Jones, IEEE Transactions on Automatic Control 21(1), 1976): ``directions`` holds
      ``M = window`` rows per hypothesis, row ``i·M + ℓ`` being ``ρ_i(ℓ)ᵀ W`` for the residual signature
      ``ρ_i(ℓ)`` ``ℓ`` samples after a unit step fault, and ``information[i·M + n − 1] = c_i(n) =
      Σ_{ℓ<n} ρ_i(ℓ)ᵀ W ρ_i(ℓ)``. The state holds ``d_i(n) = Σ_{ℓ<n} ρ_i(ℓ)ᵀ W r(k − n + 1 + ℓ)`` for the onsets
      ``n = 1 … M`` samples ago; ``J = max_{i,n} d_i(n)² / (2 c_i(n))`` over the onsets whose information is
      above ``1e-12`` of the hypothesis's largest (:func:`glr_weights`). At start-up the onsets older than
      the first sample see zeros for the samples before it (their ``d`` sums fewer terms than ``c`` counts:
      conservative).

    A sequential statistic's alarm, once raised, holds until the evidence is gone, so that one excursion is one
    alarm: for the CUSUM each sum that crossed the threshold holds a latch until it returns to 0 (the end of
    its excursion; the alarm is any latch), for the GLR the alarm holds while ``J`` stays above half the
    threshold (:func:`release_level`); ``persistence`` must be 1. ``P_f`` is the
    per-sample false-alarm probability whose mean run length ``1/P_f`` the threshold was designed for.
    """

    kind: str
    generator: int
    P_f: float
    dof: int
    threshold: float
    Sigma_r: np.ndarray
    W: np.ndarray
    window: int = 1
    directions: np.ndarray | None = None
    drift: np.ndarray | None = None
    information: np.ndarray | None = None
    hypotheses: tuple[str, ...] = ()
    """The fault classes a sequential statistic tests, one per hypothesis (labels; classes alike in this
    generator are tested as one and named ``a|b``)."""


def glr_weights(information: np.ndarray | None, window: int) -> np.ndarray:
    """``1 / (2 c_i(n))`` for each onset, 0 where ``c_i(n)`` is below ``1e-12`` of hypothesis ``i``'s largest
    (an onset too recent for the fault to have shown: ``d_i(n)`` is then 0 too, and the term is left out)."""
    if information is None:
        raise GainFileError("a GLR evaluator needs its information")
    c = np.asarray(information, dtype=float).reshape(-1, int(window))
    top = np.max(c, axis=1, keepdims=True)
    with np.errstate(divide="ignore"):
        return np.where(c > 1e-12 * top, 0.5 / np.where(c > 0, c, 1.0), 0.0).reshape(-1)


def release_level(e: Evaluator) -> float:
    """Where a raised sequential alarm ends: each latched CUSUM sum at 0; the GLR's ``J`` at half the threshold."""
    return 0.0 if e.kind == "cusum" else 0.5 * float(e.threshold)


@dataclass(frozen=True, eq=False)
class Decision:
    """Signature-table isolation over the statistics' alarm flags.

    ``signatures[f][j] = 1`` when fault ``f`` is expected to raise statistic
    ``j``. A statistic's flag is set after ``persistence`` consecutive samples
    with ``J > threshold`` (1: the current sample decides, the default). The
    isolated fault is the one whose signature equals the flag pattern exactly,
    −1 when none does.
    """

    kind: str
    signatures: np.ndarray
    persistence: int = 1


@dataclass(frozen=True, eq=False)
class StepSpec:
    """Sizes and initial state of the step function (the C API's macros)."""

    nu: int
    ny: int
    nr: int
    nj: int
    nstate: int
    init_state: np.ndarray
    residual_names: tuple[str, ...]
    statistic_names: tuple[str, ...]


@dataclass(frozen=True, eq=False)
class GainFile:
    """A validated gain file. Build with :func:`read_gain_file` or the design side."""

    kind: str
    name: str
    problem: str
    design: str
    Ts: float
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    faults: tuple[str, ...]
    step: StepSpec
    plant: Mapping[str, np.ndarray] = field(default_factory=dict)
    generators: tuple[Generator, ...] = ()
    evaluators: tuple[Evaluator, ...] = ()
    decision: Decision | None = None
    certificate: Mapping[str, Any] = field(default_factory=dict)
    provenance: Mapping[str, Any] = field(default_factory=dict)
    extensions: Mapping[str, Any] = field(default_factory=dict)
    format: str = FORMAT
    account: Mapping[str, Any] | None = None
    """What the design can see (optional; written by the design side, ``fdisyn.numerics.account``): each fault's
    effect on the residuals, its smallest detectable size and the fault classes the diagnoser can tell apart.
    A file without it (written before it existed) reads and hashes as before."""

    def __post_init__(self) -> None:
        _validate(self)
        ts = float(self.Ts)
        object.__setattr__(self, "generators", tuple(g if g.Ts == ts else replace(g, Ts=ts) for g in self.generators))

    @property
    def thresholds(self) -> np.ndarray:
        """One alarm threshold per statistic; ``inf`` where a statistic has no fixed one.

        Linear kind: the evaluators' thresholds (χ² or WSSR). Other kinds list theirs in
        ``extensions[kind]["thresholds"]`` (``null`` for none).
        """
        if self.kind == "linear":
            return np.array([e.threshold for e in self.evaluators], dtype=float)
        listed = self.extensions.get(self.kind, {}).get("thresholds") or [None] * self.step.nj
        return np.array([math.inf if v is None else float(v) for v in listed], dtype=float)

    def to_dict(self) -> dict[str, Any]:
        """The JSON document (plain lists, floats, strings)."""
        doc: dict[str, Any] = {
            "format": self.format,
            "kind": self.kind,
            "name": self.name,
            "problem": self.problem,
            "design": self.design,
            "Ts": float(self.Ts),
            "inputs": list(self.inputs),
            "outputs": list(self.outputs),
            "faults": list(self.faults),
            "step": {
                "nu": self.step.nu,
                "ny": self.step.ny,
                "nr": self.step.nr,
                "nj": self.step.nj,
                "nstate": self.step.nstate,
                "init_state": to_jsonable(self.step.init_state),
                "residual_names": list(self.step.residual_names),
                "statistic_names": list(self.step.statistic_names),
            },
        }
        if self.kind == "linear":
            doc["plant"] = {k: to_jsonable(v) for k, v in self.plant.items()}
            doc["generators"] = [
                {
                    "name": g.name,
                    "outputs_used": list(g.outputs_used),
                    **{k: to_jsonable(getattr(g, k)) for k in _MATRIX_KEYS},
                    "method": to_jsonable(dict(g.method)),
                }
                for g in self.generators
            ]
            doc["evaluators"] = [
                {
                    "kind": e.kind,
                    "generator": e.generator,
                    "P_f": float(e.P_f),
                    "dof": int(e.dof),
                    "threshold": float(e.threshold),
                    "Sigma_r": to_jsonable(e.Sigma_r),
                    "W": to_jsonable(e.W),
                    # a χ² evaluator's window is 1 and not written: its files stay as they were
                    **({"window": int(e.window)} if e.kind != "chi2" else {}),
                    **({"directions": to_jsonable(e.directions)} if e.directions is not None else {}),
                    **({"drift": to_jsonable(e.drift)} if e.drift is not None else {}),
                    **({"information": to_jsonable(e.information)} if e.information is not None else {}),
                    **({"hypotheses": list(e.hypotheses)} if e.kind in SEQUENTIAL_KINDS else {}),
                }
                for e in self.evaluators
            ]
            assert self.decision is not None  # guaranteed by _validate
            doc["decision"] = {
                "kind": self.decision.kind,
                "signatures": np.asarray(self.decision.signatures, dtype=int).tolist(),
                "persistence": int(self.decision.persistence),
            }
        doc["certificate"] = to_jsonable(dict(self.certificate))
        doc["provenance"] = to_jsonable(dict(self.provenance))
        doc["extensions"] = to_jsonable(dict(self.extensions))
        if self.account is not None:  # absent: the document (and its content hash) is what it was without the block
            doc["account"] = to_jsonable(dict(self.account))
        return doc


def linear_state_layout(generators: Sequence[Generator], evaluators: Sequence[Evaluator]) -> StateLayout:
    """Where each part of a linear diagnoser's state vector lives.

    ``xi<g>``: generator ``g``'s state; ``counters``: one persistence counter
    per statistic; ``ready``: one flag per generator (0 until its first valid
    sample has initialised it at equilibrium); ``nonfinite``: the number of
    samples that held a non-finite input or output; ``window<j>``: for each
    WSSR statistic ``j``, the ``q`` of its generator's last ``window`` valid
    samples, newest first (a shift register: each valid sample shifts it by
    one and writes ``q`` at the top; zeros not yet overwritten are the samples
    not seen yet, so ``J`` — the sum of the register — needs no fill count,
    and the step has no index arithmetic, which the symbolic step would spell
    out as one comparison per entry anyway); ``sequential<j>``: for each CUSUM
    statistic its sums ``S_i^+``, ``S_i^−`` then their latches (1 from crossing the
    threshold until the sum returns to 0), for each GLR statistic its onset sums ``d_i(n)``
    (hypothesis-major, ``n = 1 … M``). A sequential statistic's persistence
    counter holds its raised alarm (1) or 0.
    """
    blocks = [(f"xi{g}", gen.n_state, 1) for g, gen in enumerate(generators)]
    blocks += [("counters", len(evaluators), 1), ("ready", len(generators), 1), ("nonfinite", 1, 1)]
    blocks += [(f"window{j}", int(e.window), 1) for j, e in enumerate(evaluators) if e.kind == "wssr"]
    blocks += [
        (f"sequential{j}", int(e.directions.shape[0]) * (4 if e.kind == "cusum" else 1), 1)
        for j, e in enumerate(evaluators)
        if e.kind in SEQUENTIAL_KINDS and e.directions is not None
    ]
    return StateLayout(tuple(blocks), scalars=frozenset({"nonfinite"}))


# --------------------------------------------------------------------------- I/O
def write_gain_file(gf: GainFile, path: str | Path) -> Path:
    """Write ``gf`` as JSON (floats with full round-trip precision)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    if p.is_symlink():  # a link planted in a received folder would be followed and its target overwritten
        p.unlink()
    try:
        text = json.dumps(gf.to_dict(), indent=1, allow_nan=False)
    except ValueError as exc:
        raise GainFileError(f"gain file {gf.name!r} holds a non-finite number: {exc}") from exc
    p.write_text(text + "\n", encoding="utf-8")
    return p


def gain_file_sha256(gf: GainFile) -> str:
    """The content hash of ``gf``: sha256 (hex) of its canonical JSON.

    Canonical: :meth:`GainFile.to_dict` with sorted keys, no blanks, ASCII
    escapes and Python's round-trip float repr — so a file re-indented or
    re-ordered by hand keeps its hash, while any changed value (a threshold,
    a name, the provenance's time stamp) changes it. A gain file read back
    from disk hashes like the object it was written from.
    """
    try:
        text = json.dumps(gf.to_dict(), sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise GainFileError(f"gain file {gf.name!r} cannot be serialised canonically: {exc}") from exc
    return hashlib.sha256(text.encode("ascii")).hexdigest()


def read_regular_file(path: str | Path, limit: int, what: str, *, error: type[FdisynError] = GainFileError) -> bytes:
    """The bytes of ``path``, which must be a regular file of at most ``limit`` bytes.

    A file is data a user may have received: a name that leads (perhaps by a
    symbolic link) to a device such as ``/dev/zero`` would be read without
    end, a FIFO would block, so anything but a regular file is refused, and
    no more than ``limit + 1`` bytes are ever read (a file that grows while
    it is read cannot exceed it either). ``error`` names ``what`` the file
    is; a missing file keeps its ``FileNotFoundError`` and other system
    refusals their ``OSError`` for the caller to word.
    """
    p = Path(path)
    fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))  # a FIFO opens without waiting for a writer
    with os.fdopen(fd, "rb") as fh:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise error(f"{p} is not a regular file (a device, a FIFO or a directory); expected {what}")
        data = fh.read(limit + 1)
    if len(data) > limit:
        raise error(f"{p} has {max(st.st_size, len(data))} bytes; {what} may have at most {limit} (see the size limits)")
    return data


def read_gain_file(path: str | Path) -> GainFile:
    """Read and validate a gain file; refuse other formats and versions."""
    p = Path(path)
    try:
        text = read_regular_file(p, LIMITS["file_bytes"], "a gain file").decode("utf-8")
    except FileNotFoundError:
        raise GainFileError(f"no gain file at {p}") from None
    except IsADirectoryError:
        raise GainFileError(f"{p} is a directory; expected a gain file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise GainFileError(f"cannot read gain file {p}: {exc}") from exc
    return gain_file_from_dict(parse_json_data(text, str(p), "a gain file"), source=str(p))


class _DuplicateKey(dict[str, Any]):
    """An object of a JSON document that repeated ``key`` (marked by the parser, found by :func:`parse_json_data`)."""

    key: str


class _NonFinite(ValueError):
    pass


def _refuse_constant(name: str) -> float:
    raise _NonFinite(name)


def parse_json_data(text: str, source: str, what: str, *, error: type[FdisynError] = GainFileError) -> Any:
    """Parse a JSON document fdisyn reads as data (a gain file, a build manifest), strictly.

    Python's :func:`json.loads` keeps the last of a repeated key (``"passed": false, …, "passed": true``
    reads as ``true``) and reads ``NaN`` and ``Infinity``; a document that repeats a key in any object, or
    holds such a constant, is refused here instead, as is one that is not JSON or is nested too deeply.

    Parameters
    ----------
    text
        The document.
    source
        What the refusal names first (the file's path).
    what
        What the document should be, with its article (``"a gain file"``).
    error
        The exception type raised (:class:`GainFileError`, or e.g. ``BuildError`` for a manifest).

    Returns
    -------
    Any
        The parsed document: dicts, lists, strings, numbers, booleans and ``None``.

    Raises
    ------
    FdisynError
        ``error``, one line: the position of a syntax error, the repeated key and the object that holds
        it (``generators[0].method``, or the top level), the non-finite constant, or the nesting.
    """
    marked: list[_DuplicateKey] = []

    def unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
        obj = dict(pairs)
        if len(obj) == len(pairs):
            return obj
        dup, seen = _DuplicateKey(obj), set()
        for k, _ in pairs:
            if k in seen:
                dup.key = k
                break
            seen.add(k)
        marked.append(dup)
        return dup

    try:
        doc = json.loads(text, parse_constant=_refuse_constant, object_pairs_hook=unique_keys)
    except json.JSONDecodeError as exc:
        raise error(f"{source} is not valid JSON (line {exc.lineno}, column {exc.colno}): {exc.msg}") from None
    except _NonFinite as exc:
        raise error(f"{source}: non-finite number {exc} in {what}; expected finite numbers only") from None
    except RecursionError:
        raise error(f"{source}: its JSON is nested too deeply to be {what}") from None
    except ValueError as exc:  # an integer of more digits than Python converts
        raise error(f"{source} is not readable as {what}: {exc}") from None
    if marked:
        where, key = _first_duplicate(doc) or ("in an object", marked[0].key)
        raise error(
            f"{source}: key {shown(key)} appears more than once {where}; {what} holds each key once (a JSON reader "
            "would keep only one of the values): remove the repeated entry or write the file again"
        )
    return doc


def _first_duplicate(doc: object) -> tuple[str, str] | None:
    """Where the first object marked by :func:`parse_json_data` is (``in generators[0].method``, ``at the top
    level``) and its repeated key; ``None`` if there is none."""
    stack: list[tuple[str, object]] = [("", doc)]
    while stack:  # depth first, in document order, without recursion
        path, node = stack.pop()
        if isinstance(node, _DuplicateKey):
            return (f"in {path}" if path else "at the top level"), node.key
        if isinstance(node, dict):
            keys = [k if k.isidentifier() else shown(k, 40) for k in node]  # a key may hold anything, a line break too
            stack.extend((f"{path}.{k}" if path else k, v) for k, v in reversed(list(zip(keys, node.values(), strict=True))))
        elif isinstance(node, list):
            stack.extend((f"{path}[{i}]", v) for i, v in reversed(list(enumerate(node))))
    return None


def gain_file_from_dict(doc: object, *, source: str = "gain file") -> GainFile:
    """Validate a parsed JSON document and build the :class:`GainFile`.

    Besides the content (see the module docstring), the file must record a
    passed verification: ``certificate.passed`` is ``true``. This reader is
    what ``fdisyn codegen``, ``fdisyn replay`` and :class:`~fdisyn.runtime.monitor.Monitor` load
    gain files with, so a design that failed its certificate is never
    compiled or run.
    """
    if not isinstance(doc, dict):
        raise GainFileError(f"{source} is not an fdisyn gain file: the top level is a {type(doc).__name__}, expected an object")
    fmt = doc.get("format")
    if fmt is None:
        raise GainFileError(f"{source} is not an fdisyn gain file: it has no 'format' field (expected {FORMAT!r})")
    if not isinstance(fmt, str) or not fmt.startswith(_FORMAT_FAMILY):
        raise GainFileError(f"{source} is not an fdisyn gain file: format {fmt!r} (expected {FORMAT!r})")
    if fmt != FORMAT:
        raise GainFileError(
            f"{source} has gain file format version {fmt[len(_FORMAT_FAMILY):]!r} ({fmt!r}); "
            f"this fdisyn reads {FORMAT!r} only"
        )
    r = _Reader(doc, source)
    certificate = r.obj("certificate")
    if "passed" not in certificate:
        raise GainFileError(
            f"{source}: certificate has no 'passed' field; a gain file must record that its design passed "
            "verification (certificate.passed = true)"
        )
    if certificate["passed"] is not True:
        raise GainFileError(
            f"{source}: certificate.passed is {shown(certificate['passed'])}, not true: the design did not pass its "
            "verification, so it is neither compiled nor run; re-run `fdisyn design` and read the certificate's failed checks"
        )
    _check_certificate_checks(certificate, f"{source}: certificate")
    kind = r.string("kind")
    step_doc = r.obj("step")
    sr = _Reader(step_doc, f"{source}: step")
    step = StepSpec(
        nu=sr.integer("nu", minimum=0),
        ny=sr.integer("ny", minimum=1),
        nr=sr.integer("nr", minimum=0),
        nj=sr.integer("nj", minimum=0),
        nstate=sr.integer("nstate", minimum=1),
        init_state=sr.vector("init_state"),
        residual_names=sr.strings("residual_names"),
        statistic_names=sr.strings("statistic_names"),
    )
    kwargs: dict[str, Any] = {}
    if kind == "linear":
        pl = r.obj("plant")
        pr = _Reader(pl, f"{source}: plant")
        kwargs["plant"] = {k: pr.matrix(k) for k in ("A", "B", "C", "D", "E", "Q", "R")}
        gens = []
        for i, gd in enumerate(r.array("generators")):
            gr = _Reader(gd, f"{source}: generators[{i}]")
            # the reader's refusals name the generator already; the generator's own checks are prefixed here
            matrices: dict[str, Any] = {k: gr.matrix(k) for k in _MATRIX_KEYS}
            name, outputs_used, method = gr.string("name"), tuple(gr.integers("outputs_used")), gr.obj("method")
            try:
                gens.append(Generator(name=name, outputs_used=outputs_used, **matrices, method=method))
            except GainFileError as exc:
                raise GainFileError(f"{source}: generators[{i}]: {exc}") from None
        kwargs["generators"] = tuple(gens)
        evs = []
        for i, ed in enumerate(r.array("evaluators")):
            er = _Reader(ed, f"{source}: evaluators[{i}]")
            ev_kind = er.string("kind")
            # a χ² evaluator's window is 1 when not written (the files of earlier versions); a WSSR one needs it
            window = er.integer("window") if ev_kind in ("wssr", "glr") or "window" in er.doc else 1
            sequential = ev_kind in SEQUENTIAL_KINDS
            evs.append(
                Evaluator(
                    kind=ev_kind,
                    generator=er.integer("generator", minimum=0),
                    P_f=er.number("P_f"),
                    dof=er.integer("dof", minimum=0),
                    threshold=er.number("threshold"),
                    Sigma_r=er.matrix("Sigma_r"),
                    W=er.matrix("W"),
                    window=window,
                    directions=er.matrix("directions") if sequential else None,
                    drift=er.vector("drift") if ev_kind == "cusum" else None,
                    information=er.vector("information") if ev_kind == "glr" else None,
                    hypotheses=er.strings("hypotheses") if sequential else (),
                )
            )
        kwargs["evaluators"] = tuple(evs)
        dd = _Reader(r.obj("decision"), f"{source}: decision")
        kwargs["decision"] = Decision(
            kind=dd.string("kind"), signatures=dd.matrix("signatures"), persistence=dd.integer("persistence", minimum=1)
        )
    try:
        return GainFile(
            kind=kind,
            name=r.string("name"),
            problem=r.string("problem"),
            design=r.string("design"),
            Ts=r.number("Ts"),
            inputs=r.strings("inputs"),
            outputs=r.strings("outputs"),
            faults=r.strings("faults"),
            step=step,
            certificate=certificate,
            provenance=r.obj("provenance"),
            extensions=r.obj("extensions") if "extensions" in doc else {},
            account=r.obj("account") if "account" in doc else None,
            **kwargs,
        )
    except GainFileError as exc:
        raise GainFileError(f"{source}: {exc}") from None


def _check_holds(value: object, bound: object, relation: object) -> bool:
    """``value <relation> bound`` with both finite numbers (:func:`~fdisyn.runtime.values.real_number`)."""
    v, b = real_number(value), real_number(bound)
    if v is None or b is None or not (math.isfinite(v) and math.isfinite(b)):
        return False
    if relation == "<=":
        return v <= b
    return relation == ">=" and v >= b


def _check_certificate_checks(node: object, where: str, depth: int = 0) -> None:
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
            _check_certificate_checks(v, f"{where}.{k}", depth + 1)
    elif isinstance(node, list):
        for i, v in enumerate(node):
            _check_certificate_checks(v, f"{where}[{i}]", depth + 1)


class _Reader:
    """Typed field access that names the field on every failure."""

    def __init__(self, doc: object, where: str) -> None:
        if not isinstance(doc, dict):
            raise GainFileError(f"{where}: expected an object, found {type(doc).__name__}")
        self.doc = doc
        self.where = where

    def _get(self, key: str) -> object:
        if key not in self.doc:
            raise GainFileError(f"{self.where}: missing field {key!r}")
        return self.doc[key]

    def string(self, key: str) -> str:
        v = self._get(key)
        if not isinstance(v, str):
            raise GainFileError(f"{self.where}: field {key!r} must be a string, found {type(v).__name__}")
        return v

    def number(self, key: str) -> float:
        v = self._get(key)
        x = real_number(v)
        if x is None or not math.isfinite(x):
            raise GainFileError(f"{self.where}: field {key!r} must be a finite number, found {shown(v)}")
        check_magnitudes(x, f"{self.where}: {key}")
        return x

    def integer(self, key: str, *, minimum: int | None = None) -> int:
        v = self._get(key)
        if isinstance(v, bool) or not isinstance(v, int):
            raise GainFileError(f"{self.where}: field {key!r} must be an integer, found {shown(v)}")
        if minimum is not None and v < minimum:
            raise GainFileError(f"{self.where}: field {key!r} must be ≥ {minimum}, found {shown(v)}")
        return v

    def obj(self, key: str) -> dict[str, Any]:
        v = self._get(key)
        if not isinstance(v, dict):
            raise GainFileError(f"{self.where}: field {key!r} must be an object, found {type(v).__name__}")
        return v

    def array(self, key: str) -> list[Any]:
        v = self._get(key)
        if not isinstance(v, list):
            raise GainFileError(f"{self.where}: field {key!r} must be a list, found {type(v).__name__}")
        return v

    def strings(self, key: str) -> tuple[str, ...]:
        v = self.array(key)
        if not all(isinstance(s, str) for s in v):
            raise GainFileError(f"{self.where}: field {key!r} must be a list of strings")
        return tuple(v)

    def integers(self, key: str) -> list[int]:
        v = self.array(key)
        if not all(isinstance(s, int) and not isinstance(s, bool) for s in v):
            raise GainFileError(f"{self.where}: field {key!r} must be a list of integers")
        return list(v)

    def vector(self, key: str) -> np.ndarray:
        v = self.array(key)
        if not all(type(x) in (int, float) for x in v):  # NumPy would convert "1.5" and true silently
            raise GainFileError(f"{self.where}: field {key!r} must be a list of numbers")
        try:
            a = np.asarray(v, dtype=float)
        except (TypeError, ValueError, OverflowError):
            raise GainFileError(f"{self.where}: field {key!r} must be a list of numbers") from None
        if a.ndim != 1 or not np.all(np.isfinite(a)):
            raise GainFileError(f"{self.where}: field {key!r} must be a flat list of finite numbers")
        check_magnitudes(a, f"{self.where}: {key}")
        return a

    def matrix(self, key: str) -> np.ndarray:
        v = self.array(key)
        rows = len(v)
        if rows and not all(isinstance(row, list) for row in v):
            raise GainFileError(f"{self.where}: field {key!r} must be a list of rows (a matrix)")
        if not all(type(x) in (int, float) for row in v for x in row):  # NumPy would convert "1.5" and true silently
            raise GainFileError(f"{self.where}: matrix {key!r} holds something that is not a number")
        widths = {len(row) for row in v}
        if len(widths) > 1:
            raise GainFileError(f"{self.where}: matrix {key!r} has rows of different lengths {sorted(widths)}")
        try:
            a = np.asarray(v, dtype=float).reshape(rows, widths.pop() if widths else 0)
        except (TypeError, ValueError, OverflowError):
            raise GainFileError(f"{self.where}: matrix {key!r} holds something that is not a number") from None
        if not np.all(np.isfinite(a)):
            raise GainFileError(f"{self.where}: matrix {key!r} holds a non-finite number")
        check_magnitudes(a, f"{self.where}: {key}")
        return a


# ----------------------------------------------------------------- validation
def _fail(msg: str) -> NoReturn:
    raise GainFileError(msg)


def _shape(a: np.ndarray, where: str, shape: tuple[int, int]) -> None:
    if a.shape != shape:
        _fail(f"{where}: expected shape {shape}, found {a.shape}")


def _validate(gf: GainFile) -> None:
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
        _validate_account(gf)


def _validate_account(gf: GainFile) -> None:
    """The optional ``account`` block: informational, but what a page and a terminal show of it must be sound.

    ``format`` :data:`ACCOUNT_FORMAT`; ``faults`` one entry per fault (at most the file's outputs and
    :data:`LIMITS` ``["faults"]`` component faults), each with a fault ``name``, ``type`` ``"sensor"`` (an output of
    the file) or ``"component"``, ``unit`` text or null, ``effect`` one of :data:`ACCOUNT_EFFECTS`, ``size`` and
    ``size_50`` null or finite non-negative numbers, ``seen_by`` and ``persistent_in`` lists of generator labels, and
    per generator ``effect``, ``peak_gain`` and ``dc_gain`` (null or finite ≥ 0); ``classes.groups`` lists of fault
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


def _validate_names(gf: GainFile) -> None:
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


def _validate_extension_thresholds(gf: GainFile) -> None:
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


def step_coefficients(generators: Sequence[Generator], evaluators: Sequence[Evaluator]) -> int:
    """Nonzero coefficients a linear step multiplies by: the generated C has one multiply-add per coefficient."""
    count = sum(int(np.count_nonzero(getattr(g, k))) for g in generators for k in _MATRIX_KEYS)
    return count + sum(int(np.count_nonzero(e.W)) + (int(np.count_nonzero(e.directions)) if e.directions is not None else 0) for e in evaluators)


def check_limits(gf: GainFile) -> None:
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
    coeffs = step_coefficients(gf.generators, gf.evaluators)
    if coeffs > LIMITS["coefficients"]:
        _fail(
            f"the generators and evaluators hold {coeffs} nonzero coefficients; at most {LIMITS['coefficients']} are "
            "supported (the generated C has one multiply-add per coefficient and gcc's time and memory grow with them)"
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


def _validate_chi2_weight(e: Evaluator, w: str) -> None:
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


def _validate_sequential(e: Evaluator, w: str, ng: int, decision: Decision | None) -> None:
    """A CUSUM or GLR statistic: its directions lie in ``W``'s range (they are ``μᵀ W``), its drifts and
    information are positive where they must be, and it decides without persistence."""
    assert e.directions is not None
    rows = e.directions.shape[0]
    _shape(e.directions, f"{w}.directions", (rows, ng))
    check_magnitudes(e.directions, f"{w}.directions")
    per = int(e.window) if e.kind == "glr" else 1
    if rows == 0 or rows % per:
        _fail(f"{w}.directions must hold {per} row(s) per fault hypothesis and at least one hypothesis, found {rows} rows")
    if e.kind == "cusum":
        assert e.drift is not None
        check_magnitudes(e.drift, f"{w}.drift")
        if e.drift.shape != (rows,) or not np.all(e.drift > 0):
            _fail(f"{w}.drift must hold one positive number per direction ({rows}), found {shown(e.drift.tolist())}")
    else:
        assert e.information is not None
        check_magnitudes(e.information, f"{w}.information")
        c = e.information.reshape(-1, per) if e.information.shape == (rows,) else None
        if c is None or not np.all(c >= 0) or not np.all(np.diff(c, axis=1) >= -1e-9 * c[:, -1:]) or not np.all(c[:, -1] > 0):
            _fail(f"{w}.information must hold, per hypothesis, {per} nondecreasing cumulative informations ending positive")
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


def _validate_linear(gf: GainFile) -> None:
    m, p = len(gf.inputs), len(gf.outputs)
    pl = gf.plant
    for k, a in pl.items():
        check_magnitudes(a, f"plant.{k}")
    for i, gen in enumerate(gf.generators):
        for k in _MATRIX_KEYS:
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
        if e.kind not in EVALUATOR_KINDS:
            _fail(f"{w}.kind {e.kind!r} is not supported (supported: {', '.join(map(repr, EVALUATOR_KINDS))})")
        if e.kind == "chi2" and not (type(e.window) is int and e.window == 1):
            _fail(f"{w}.window must be 1 for a 'chi2' evaluator (one sample), found {shown(e.window)}; use kind 'wssr' for a window")
        if e.kind == "wssr" and not (type(e.window) is int and 1 <= e.window <= MAX_WSSR_WINDOW):
            _fail(f"{w}.window must be a whole number of samples in 1..{MAX_WSSR_WINDOW}, found {shown(e.window)}")
        if e.kind == "cusum" and not (type(e.window) is int and e.window == 1):
            _fail(f"{w}.window must be 1 for a 'cusum' evaluator (it has no window), found {shown(e.window)}")
        if e.kind == "glr" and not (type(e.window) is int and 1 <= e.window <= MAX_GLR_WINDOW):
            _fail(f"{w}.window must be a whole number of onsets in 1..{MAX_GLR_WINDOW} for a 'glr' evaluator, found {shown(e.window)}")
        if (e.kind in SEQUENTIAL_KINDS) != (e.directions is not None):
            _fail(f"{w}.directions: {'required' if e.kind in SEQUENTIAL_KINDS else 'only allowed'} for a 'cusum' or 'glr' evaluator")
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
        if e.kind in SEQUENTIAL_KINDS:
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
    st = gf.step
    lay = linear_state_layout(gf.generators, gf.evaluators)
    if st.nr != nr or st.nj != len(gf.evaluators) or st.nstate != lay.size:
        _fail(
            f"step sizes nr={st.nr}, nj={st.nj}, nstate={st.nstate} do not match the generators "
            f"(nr={nr}, nj={len(gf.evaluators)}, nstate={lay.size})"
        )
    # the linear step starts from zero: no generator ready (each starts at the equilibrium of its first
    # valid sample), no persistence counted, no sample skipped; anything else is an edited file
    if np.any(st.init_state != 0.0):
        _fail(f"step.init_state of a linear diagnoser must be all zeros; entries {np.flatnonzero(st.init_state).tolist()[:8]} are not")


def to_jsonable(obj: object) -> object:
    """Numbers, strings, lists and dicts only (NumPy scalars/arrays and complex numbers converted).

    A non-finite number becomes the string ``"inf"``, ``"-inf"`` or ``"nan"``:
    informational fields (a performance that is infinite, say) may hold one;
    matrices may not, and the gain file's validation refuses them before this.
    """
    if isinstance(obj, (float, np.floating)) and not math.isfinite(float(obj)):
        return "nan" if math.isnan(float(obj)) else ("inf" if obj > 0 else "-inf")
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Mapping):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, (np.floating, np.integer, np.bool_)):
        return to_jsonable(obj.item())
    if isinstance(obj, complex):
        return [to_jsonable(obj.real), to_jsonable(obj.imag)]
    return obj
