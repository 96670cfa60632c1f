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
and so are numbers beyond :data:`~fdisyn.runtime.schema.MAX_MAGNITUDE` (``1e150``) in magnitude,
which could overflow the consistency checks. The document is parsed strictly
(:func:`~fdisyn.runtime.jsondata.parse_json_data`: a key repeated in any object is refused). The
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
  evaluator and a whole number in 1..:data:`~fdisyn.runtime.statistics.MAX_WSSR_WINDOW` (required) for a
  WSSR one;
* sizes stay within :data:`~fdisyn.runtime.schema.LIMITS`, checked before any costly step (the
  generated C grows with the number of coefficients; gcc's time and memory
  with it).

:func:`gain_file_sha256` is the file's content hash (canonical JSON: layout
and whitespace do not matter, every value does); ``fdisyn codegen`` compiles
it into the library so that a library never runs another gain file.

The format's constants and limits live in :mod:`fdisyn.runtime.schema`, the checks in
:mod:`fdisyn.runtime.validate`, the state layout in :mod:`fdisyn.runtime.layout` and the strict JSON
reading in :mod:`fdisyn.runtime.jsondata`; this module holds the types and the reader and writer.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from fdisyn.runtime.errors import GainFileError
from fdisyn.runtime.jsondata import parse_json_data, read_regular_file, to_jsonable
from fdisyn.runtime.names import shown
from fdisyn.runtime.schema import FORMAT, FORMAT_FAMILY, LIMITS, MATRIX_KEYS
from fdisyn.runtime.statistics import STATISTICS
from fdisyn.runtime.validate import check_certificate, check_magnitudes, signal_keys, validate_gain_file, validate_generator
from fdisyn.runtime.values import real_number

__all__ = [
    "CLOCK_KEYS",
    "without_clock",
    "Generator",
    "Evaluator",
    "Decision",
    "Isolation",
    "StepSpec",
    "GainFile",
    "read_gain_file",
    "write_gain_file",
    "gain_file_from_dict",
    "gain_file_sha256",
    "release_level",
    "signals_block",
]



@dataclass(frozen=True, eq=False)
class Generator:
    """One residual generator in canonical form (see the module docstring).

    ``ξ⁺ = Ar ξ + Bu u + By y``, ``r = Cr ξ + Du u + Dy y`` on the gain file's full ``u`` and ``y``.

    Attributes
    ----------
    name : str
        The generator's label.
    outputs_used : tuple of int
        The outputs it reads (indices into the gain file's ``outputs``); ``By`` and ``Dy`` are zero elsewhere.
    Ar, Bu, By, Cr, Du, Dy : numpy.ndarray
        The canonical matrices.
    Xu, Xy : numpy.ndarray
        The equilibrium maps ``(I − Ar)⁻¹ Bu`` and ``(I − Ar)⁻¹ By``: the generator starts at
        ``Xu u + Xy y`` of its first valid sample.
    method : Mapping
        What the design method records about it (informational).
    warmup : int
        Valid samples over which the step estimates its initial state by least squares before its statistics
        run (:mod:`fdisyn.runtime.warmup`); 0: none, it starts at the equilibrium of its first valid sample.
    Ts : float or None
        Sample time of the gain file that holds the generator (set by :class:`GainFile`; not written:
        the file's ``Ts`` is).
    input_names, output_names, residual_names : tuple of str
        The names of its inputs ``u`` and outputs ``y`` (the gain file's ``inputs`` and ``outputs``) and of its
        residuals (its rows of the file's ``step.residual_names``); set by :class:`GainFile`, not written (the
        file's lists are); empty for a generator outside a gain file.

    Raises
    ------
    GainFileError
        Matrices whose shapes do not fit together, or ``outputs_used`` that are not distinct output
        indices or leave out an output the matrices read.
    """

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
    warmup: int = 0
    input_names: tuple[str, ...] = ()
    output_names: tuple[str, ...] = ()
    residual_names: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        validate_generator(self)

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

        Parameters
        ----------
        name : str
            The generator's label.
        outputs_used : sequence of int
            The outputs it reads.
        Ar, Bu, By, Cr, Du, Dy : numpy.ndarray
            The canonical matrices (copied as float arrays).
        method : Mapping, optional
            What the design method records about it.

        Returns
        -------
        Generator
            With ``Xu`` and ``Xy`` computed.

        Raises
        ------
        GainFileError
            Matrices whose shapes do not fit together (see :class:`Generator`).
        numpy.linalg.LinAlgError
            ``I − Ar`` is singular (``Ar`` has an eigenvalue 1: no equilibrium); the design side checks
            stability before it builds a generator.
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
        """The generator's state dimension (rows of ``Ar``)."""
        return int(self.Ar.shape[0])

    def to_control(self) -> Any:
        """The generator as a discrete python-control ``StateSpace``.

        ``ξ⁺ = Ar ξ + [Bu By] [u; y]``, ``r = Cr ξ + [Du Dy] [u; y]``: inputs
        ``[u; y]`` (every input, then every output of the gain file), output
        ``r``, ``dt`` the gain file's ``Ts`` (``True``, discrete with an
        unspecified sample time, for a generator outside a gain file).
        The system's signals are named after the gain file: its inputs are
        the file's ``inputs`` then ``outputs`` (e.g. ``u``, ``y1``), its
        outputs the generator's residual names (``step.residual_names``)
        without the generator's name before a ``.``: python-control refuses a
        ``.`` in a signal name (it addresses ``system.signal``, and the system
        is named after the generator), so ``g0.y1`` is the output ``y1`` of the
        system ``g0`` and any other ``.`` is written ``_``. A generator outside
        a gain file keeps python-control's ``u[i]``, ``y[i]``. python-control
        is imported here, not with the runtime.

        Returns
        -------
        control.StateSpace
            The generator, discrete, with named signals.
        """
        import control

        named = {}
        if len(self.input_names) + len(self.output_names) == self.Bu.shape[1] + self.By.shape[1]:
            named["inputs"] = [*self.input_names, *self.output_names]
        if self.residual_names and len(self.residual_names) == self.Cr.shape[0]:
            own = f"{self.name}."
            named["outputs"] = [(r[len(own):] if r.startswith(own) else r).replace(".", "_") for r in self.residual_names]
        return control.ss(
            self.Ar,
            np.hstack([self.Bu, self.By]),
            self.Cr,
            np.hstack([self.Du, self.Dy]),
            dt=True if self.Ts is None else self.Ts,
            name=self.name,
            **named,
        )

    @property
    def n_residual(self) -> int:
        """The residual's dimension (rows of ``Cr``)."""
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
      above ``1e-12`` of the hypothesis's largest (:func:`~fdisyn.runtime.statistics.glr_weights`). At start-up the onsets older than
      the first sample see zeros for the samples before it (their ``d`` sums fewer terms than ``c`` counts:
      conservative).

    A sequential statistic's alarm, once raised, holds until the evidence is gone, so that one excursion is one
    alarm: for the CUSUM each sum that crossed the threshold holds a latch until it returns to 0 (the end of
    its excursion; the alarm is any latch), for the GLR the alarm holds while ``J`` stays above half the
    threshold (:func:`release_level`); ``persistence`` must be 1. ``P_f`` is the
    per-sample false-alarm probability whose mean run length ``1/P_f`` the threshold was designed for.

    Attributes
    ----------
    kind : {"chi2", "wssr", "cusum", "glr"}
        The statistic (:data:`~fdisyn.runtime.schema.EVALUATOR_KINDS`).
    generator : int
        Index of the generator whose residual it evaluates.
    P_f : float
        The per-sample false-alarm probability the threshold was designed for.
    dof : int
        Degrees of freedom: the rank of ``W``.
    threshold : float
        The alarm threshold on ``J``.
    Sigma_r : numpy.ndarray
        The residual's covariance.
    W : numpy.ndarray
        The weight, the pseudo-inverse of ``Sigma_r`` on its range.
    window : int
        The WSSR window or the GLR's onset window, in samples; 1 for χ² and CUSUM.
    directions : numpy.ndarray or None
        A sequential statistic's rows ``μᵀ W`` (CUSUM) or ``ρ(ℓ)ᵀ W`` (GLR); ``None`` otherwise.
    drift : numpy.ndarray or None
        The CUSUM's drifts, one per direction.
    information : numpy.ndarray or None
        The GLR's cumulative informations ``c_i(n)``, one per direction.
    hypotheses : tuple of str
        The fault classes a sequential statistic tests, one per hypothesis (labels; classes alike in this
        generator are tested as one and named ``a|b``).
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


def release_level(e: Evaluator) -> float:
    """Where a raised sequential alarm ends: each latched CUSUM sum at 0; the GLR's ``J`` at half the threshold.

    Parameters
    ----------
    e : Evaluator
        A sequential (``"cusum"`` or ``"glr"``) evaluator.

    Returns
    -------
    float
        The release level.
    """
    return STATISTICS[e.kind].release(e)


@dataclass(frozen=True, eq=False)
class Decision:
    """The decision: the statistics' alarm flags, their signature table and the isolation test.

    ``signatures[f][j] = 1`` when fault ``f`` is expected to raise statistic
    ``j``. A statistic's flag is set after ``persistence`` consecutive samples
    with ``J > threshold`` (1: the current sample decides, the default). The
    isolated fault is named by the ``isolation`` test; without one, it is the
    fault whose signature equals the flag pattern exactly, −1 when none does.

    Attributes
    ----------
    kind : {"signature_table"}
        The decision rule.
    signatures : numpy.ndarray
        0/1, one row per fault and one column per statistic; rows distinct and nonzero.
    persistence : int
        Consecutive exceedances before a statistic's flag is set (1 with a sequential statistic).
    isolation : Isolation or None
        The hypothesis test that names the fault from the residuals (:class:`Isolation`); ``None`` (a file written
        before it existed): the fault whose signature equals the flag pattern.
    """

    kind: str
    signatures: np.ndarray
    persistence: int = 1
    isolation: Isolation | None = None


@dataclass(frozen=True, eq=False)
class Isolation:
    """Isolation by a generalised likelihood ratio test across the fault classes, with a held decision.

    The step keeps the evidence ``z ← λ z + B r``: ``r`` the stacked residual of the generators whose statistics
    ran, ``B`` (``basis``) a basis of the union of the fault classes' residual spans, orthonormal in the metric of
    the residuals' noise, so that without a fault ``z`` is Gaussian with unit covariance once stationary (exactly,
    from the residuals' autocovariances on the design's noise model). Fault class ``f`` is the hypothesis that
    ``E[z]`` lies in its span, whose orthonormal basis is ``A_f`` (``ranks[f]`` rows of ``directions``); its
    evidence is ``g_f = |A_f z|²`` (the GLR of a shift of unknown size in that span) and its misfit
    ``e_f = |z|² − g_f``, χ² with ``len(z) − ranks[f]`` degrees of freedom when ``f`` is the fault (Basseville &
    Nikiforov, *Detection of Abrupt Changes*, 1993, section 4.2.8; Nyberg, Linköping Studies in Science and
    Technology, Dissertation 591, 1999: the diagnosis is the hypotheses the data do not reject). Class ``f`` is
    *plausible* when ``e_f ≤ reject[f]`` and *supported* when also ``g_f ≥ accept[f]`` (the ``1 − level``
    quantiles of those χ² laws). While the alarm is raised, the named class is the supported one that every other
    plausible class contains (``nested[f][k] = 1``: class ``k`` corrupts every sensor and component ``f`` does),
    once the alarm has been raised for ``settle`` samples (the time the classes' transients take to enter their
    spans), or before any is named the class whose signature equals the flag pattern. It is held: it changes
    only when the test names another class (one the named class contains, when the named one is still plausible:
    the name narrows to what the evidence singles out), and it is cleared (−1) when the alarm falls. So "not isolated" while alarmed means that classes that do not contain one another are all
    still plausible: the data cannot tell them apart yet.

    Attributes
    ----------
    level : float
        The test's size: the probability that the true class is rejected at one sample.
    forgetting : float
        ``λ`` in ``[0, 1)``: the evidence's memory is about ``1/(1 − λ)`` samples.
    basis : numpy.ndarray
        ``B``, ``k × nr`` (``k ≤ nr``): the evidence's coordinates.
    directions : numpy.ndarray
        ``Σ ranks × k``: the rows of ``A_f``, class after class, orthonormal within a class.
    ranks : numpy.ndarray
        Per class, the dimension of its hypothesis (0: the residuals do not see it; it is never named by the test).
    accept, reject : numpy.ndarray
        Per class, the evidence needed and the misfit allowed.
    nested : numpy.ndarray
        0/1, ``nf × nf``: ``nested[f][k] = 1`` when class ``k`` contains class ``f`` (zero diagonal).
    settle : int
        Alarmed samples before the test may name a class (at least 1).
    """

    level: float
    forgetting: float
    basis: np.ndarray
    directions: np.ndarray
    ranks: np.ndarray
    accept: np.ndarray
    reject: np.ndarray
    nested: np.ndarray
    settle: int = 1


@dataclass(frozen=True, eq=False)
class StepSpec:
    """Sizes and initial state of the step function (the C API's macros).

    Attributes
    ----------
    nu, ny : int
        Inputs and outputs per sample.
    nr, nj : int
        Residuals and statistics per sample.
    nstate : int
        Entries of the state vector.
    init_state : numpy.ndarray
        The state before the first sample (``nstate`` entries).
    residual_names, statistic_names : tuple of str
        A label per residual and per statistic (the replay CSV's columns).
    """

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
    """A validated gain file. Build with :func:`read_gain_file` or the design side.

    Construction validates everything (the rules of the module docstring) and refuses a file that breaks
    one with :class:`~fdisyn.runtime.errors.GainFileError`.

    Attributes
    ----------
    kind : str
        The diagnoser kind (``"linear"``, ``"nafdf"``, ``"beard_fdf"``, …); another kind than ``"linear"``
        keeps its payload in ``extensions[kind]``.
    name : str
        The diagnoser's name, a C identifier: the prefix of its C API.
    problem, design : str
        Labels of the problem and the design it came from.
    Ts : float
        The sample time in seconds.
    inputs, outputs : tuple of str
        The signal names of ``u`` and ``y``, in order.
    faults : tuple of str
        The fault names, in the order ``isolated`` indexes them.
    step : StepSpec
        The step function's sizes, names and initial state.
    plant : Mapping of str to numpy.ndarray
        Linear kind: the discrete model ``A B C D E Q R`` the design used.
    generators : tuple of Generator
        Linear kind: the residual generators.
    evaluators : tuple of Evaluator
        Linear kind: the statistics, one per column of ``decision.signatures``.
    decision : Decision or None
        Linear kind: the isolation rule.
    certificate : Mapping
        The design's verification; ``passed`` is true.
    provenance : Mapping
        Where and when the design was made (informational).
    extensions : Mapping
        Other kinds' payloads, by kind.
    format : str
        The format version, :data:`~fdisyn.runtime.schema.FORMAT`.
    account : Mapping or None
        What the design can see (optional; written by the design side, ``fdisyn.numerics.account``): each fault's
        effect on the residuals, its smallest detectable size and the fault classes the diagnoser can tell apart.
        A file without it (written before it existed) reads and hashes as before.
    signals : Mapping or None
        Readable texts of the file's signals (optional): ``{"units": {name: unit}, "labels": {name: label}}``, each
        table optional, keyed by the file's inputs, outputs and the component faults its faults name
        (:func:`~fdisyn.runtime.validate.validate_signals`); written by the design side from the plant's ``units``
        and ``labels`` (:func:`signals_block`). A file without it reads and hashes as before.

    Raises
    ------
    GainFileError
        A field that breaks the format's rules, named with what was expected and what was found.
    """

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
    signals: Mapping[str, Mapping[str, str]] | None = None

    def __post_init__(self) -> None:
        validate_gain_file(self)
        if self.signals is not None:
            object.__setattr__(self, "signals", {table: dict(texts) for table, texts in self.signals.items()})
        ts = float(self.Ts)
        offsets = np.cumsum([0, *(g.n_residual for g in self.generators)])
        names = self.step.residual_names if self.kind == "linear" and offsets[-1] == len(self.step.residual_names) else None
        gens = []
        for k, g in enumerate(self.generators):
            own: dict[str, Any] = {
                "Ts": ts,
                "input_names": tuple(self.inputs),
                "output_names": tuple(self.outputs),
                "residual_names": () if names is None else tuple(names[offsets[k] : offsets[k + 1]]),
            }
            gens.append(g if all(getattr(g, key) == v for key, v in own.items()) else replace(g, **own))
        object.__setattr__(self, "generators", tuple(gens))

    @property
    def units(self) -> dict[str, str]:
        """The unit of each signal the file describes (its ``signals.units``; empty without the block)."""
        return dict((self.signals or {}).get("units", {}))

    @property
    def labels(self) -> dict[str, str]:
        """The readable name of each signal the file describes (its ``signals.labels``; empty without the block)."""
        return dict((self.signals or {}).get("labels", {}))

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
                    **{k: to_jsonable(getattr(g, k)) for k in MATRIX_KEYS},
                    "method": to_jsonable(dict(g.method)),
                    **({"warmup": int(g.warmup)} if g.warmup else {}),  # absent: a file as it was before warm-ups
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
                    **({"window": int(e.window)} if STATISTICS[e.kind].window_written else {}),
                    **({"directions": to_jsonable(e.directions)} if e.directions is not None else {}),
                    **({"drift": to_jsonable(e.drift)} if e.drift is not None else {}),
                    **({"information": to_jsonable(e.information)} if e.information is not None else {}),
                    **({"hypotheses": list(e.hypotheses)} if STATISTICS[e.kind].sequential else {}),
                }
                for e in self.evaluators
            ]
            assert self.decision is not None  # guaranteed by validate_gain_file
            doc["decision"] = {
                "kind": self.decision.kind,
                "signatures": np.asarray(self.decision.signatures, dtype=int).tolist(),
                "persistence": int(self.decision.persistence),
            }
            iso = self.decision.isolation
            if iso is not None:  # absent: a file of the flag-pattern decision reads and hashes as before
                doc["decision"]["isolation"] = {
                    "level": float(iso.level),
                    "forgetting": float(iso.forgetting),
                    "basis": to_jsonable(iso.basis),
                    "directions": to_jsonable(np.asarray(iso.directions, dtype=float).reshape(-1, np.asarray(iso.basis).shape[0])),
                    "ranks": np.asarray(iso.ranks, dtype=int).tolist(),
                    "accept": to_jsonable(iso.accept),
                    "reject": to_jsonable(iso.reject),
                    "nested": np.asarray(iso.nested, dtype=int).tolist(),
                    "settle": int(iso.settle),
                }
        doc["certificate"] = to_jsonable(dict(self.certificate))
        doc["provenance"] = to_jsonable(dict(self.provenance))
        doc["extensions"] = to_jsonable(dict(self.extensions))
        if self.account is not None:  # absent: the document (and its content hash) is what it was without the block
            doc["account"] = to_jsonable(dict(self.account))
        if self.signals is not None:  # absent: the document (and its content hash) is what it was without the block
            doc["signals"] = {table: dict(texts) for table, texts in self.signals.items()}
        return doc


def signals_block(
    units: Mapping[str, str], labels: Mapping[str, str], inputs: Sequence[str], outputs: Sequence[str], faults: Sequence[str]
) -> dict[str, dict[str, str]] | None:
    """The ``signals`` block of a gain file from a plant's ``units`` and ``labels``: the entries of the file's names.

    Parameters
    ----------
    units, labels : Mapping of str to str
        A unit and a readable name per signal of the plant (checked by the plant).
    inputs, outputs, faults : sequence of str
        The gain file's names; entries of other signals (states, unknown inputs) are left out.

    Returns
    -------
    dict or None
        ``{"units": {…}, "labels": {…}}`` with the tables that have an entry; ``None`` when neither has one (the file
        then has no block, and reads and hashes as a file written before the block existed).
    """
    keys = signal_keys(tuple(inputs), tuple(outputs), tuple(faults))
    block = {}
    for table, texts in (("units", units), ("labels", labels)):
        kept = {k: texts[k] for k in keys if k in texts}
        if kept:
            block[table] = kept
    return block or None


# --------------------------------------------------------------------------- I/O
def write_gain_file(gf: GainFile, path: str | Path) -> Path:
    """Write ``gf`` as JSON (floats with full round-trip precision).

    Parameters
    ----------
    gf : GainFile
        The diagnoser.
    path : str or Path
        The file to write (its folder is created; a symbolic link there is replaced, not followed).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    GainFileError
        ``gf`` holds a non-finite number where JSON cannot hold one.
    OSError
        The file cannot be written (the caller words it).
    """
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


CLOCK_KEYS = re.compile(r"created_utc|(^|_)(solve_)?time(_|$)|seconds")
"""Keys of a gain file's provenance and certificate information that hold a date or a duration."""


def _without_clock(x: Any) -> Any:
    if isinstance(x, Mapping):
        return {k: _without_clock(v) for k, v in x.items() if not CLOCK_KEYS.search(str(k))}
    if isinstance(x, list):
        return [_without_clock(v) for v in x]
    return x


def without_clock(gf: GainFile) -> GainFile:
    """``gf`` without its creation date or solver durations (:data:`CLOCK_KEYS`): what two designs of the same
    diagnoser share, and what a report publishes (the committed files stay the same from one run to the next).

    Parameters
    ----------
    gf : GainFile
        The diagnoser.

    Returns
    -------
    GainFile
        The same diagnoser, its ``provenance`` and ``certificate`` without those keys.
    """
    return replace(gf, provenance=_without_clock(dict(gf.provenance)), certificate=_without_clock(dict(gf.certificate)))


def gain_file_sha256(gf: GainFile) -> str:
    """The content hash of ``gf``: sha256 (hex) of its canonical JSON.

    Canonical: :meth:`GainFile.to_dict` with sorted keys, no blanks, ASCII
    escapes and Python's round-trip float repr — so a file re-indented or
    re-ordered by hand keeps its hash, while any changed value (a threshold,
    a name, the provenance's time stamp) changes it. A gain file read back
    from disk hashes like the object it was written from.

    Parameters
    ----------
    gf : GainFile
        The diagnoser.

    Returns
    -------
    str
        64 hexadecimal digits.

    Raises
    ------
    GainFileError
        ``gf`` cannot be serialised canonically (a value JSON cannot hold).
    """
    try:
        text = json.dumps(gf.to_dict(), sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise GainFileError(f"gain file {gf.name!r} cannot be serialised canonically: {exc}") from exc
    return hashlib.sha256(text.encode("ascii")).hexdigest()



def read_gain_file(path: str | Path) -> GainFile:
    """Read and validate a gain file; refuse other formats and versions.

    Parameters
    ----------
    path : str or Path
        The gain file (``gains.json``), a regular file of at most :data:`~fdisyn.runtime.schema.LIMITS`
        ``["file_bytes"]`` bytes.

    Returns
    -------
    GainFile
        The validated diagnoser.

    Raises
    ------
    GainFileError
        No file, a file that cannot be read, or one that is not a valid gain file of this format (the
        message names the file, the field, what was expected and what was found).
    """
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



def gain_file_from_dict(doc: object, *, source: str = "gain file") -> GainFile:
    """Validate a parsed JSON document and build the :class:`GainFile`.

    Besides the content (see the module docstring), the file must record a
    passed verification: ``certificate.passed`` is ``true``. This reader is
    what ``fdisyn codegen``, ``fdisyn replay`` and :class:`~fdisyn.runtime.monitor.Monitor` load
    gain files with, so a design that failed its certificate is never
    compiled or run.

    Parameters
    ----------
    doc : object
        The parsed document (:func:`~fdisyn.runtime.jsondata.parse_json_data`).
    source : str
        What refusals name first (the file's path).

    Returns
    -------
    GainFile
        The validated diagnoser.

    Raises
    ------
    GainFileError
        A document that is not a valid gain file of this format.
    """
    if not isinstance(doc, dict):
        raise GainFileError(f"{source} is not an fdisyn gain file: the top level is a {type(doc).__name__}, expected an object")
    fmt = doc.get("format")
    if fmt is None:
        raise GainFileError(f"{source} is not an fdisyn gain file: it has no 'format' field (expected {FORMAT!r})")
    if not isinstance(fmt, str) or not fmt.startswith(FORMAT_FAMILY):
        raise GainFileError(f"{source} is not an fdisyn gain file: format {fmt!r} (expected {FORMAT!r})")
    if fmt != FORMAT:
        raise GainFileError(
            f"{source} has gain file format version {fmt[len(FORMAT_FAMILY):]!r} ({fmt!r}); "
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
    check_certificate(certificate, f"{source}: certificate")
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
            matrices: dict[str, Any] = {k: gr.matrix(k) for k in MATRIX_KEYS}
            name, outputs_used, method = gr.string("name"), tuple(gr.integers("outputs_used")), gr.obj("method")
            try:
                warmup = gr.integer("warmup", minimum=0) if "warmup" in gr.doc else 0
                gens.append(Generator(name=name, outputs_used=outputs_used, **matrices, method=method, warmup=warmup))
            except GainFileError as exc:
                raise GainFileError(f"{source}: generators[{i}]: {exc}") from None
        kwargs["generators"] = tuple(gens)
        evs = []
        for i, ed in enumerate(r.array("evaluators")):
            er = _Reader(ed, f"{source}: evaluators[{i}]")
            ev_kind = er.string("kind")
            # a χ² evaluator's window is 1 when not written (the files of earlier versions); a WSSR one needs it
            stat = STATISTICS.get(ev_kind)  # an unknown kind is refused by the validator, naming it
            window = er.integer("window") if (stat is not None and stat.window_read) or "window" in er.doc else 1
            sequential = stat is not None and stat.sequential
            vectors = stat.vectors if stat is not None else ()
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
                    drift=er.vector("drift") if "drift" in vectors else None,
                    information=er.vector("information") if "information" in vectors else None,
                    hypotheses=er.strings("hypotheses") if sequential else (),
                )
            )
        kwargs["evaluators"] = tuple(evs)
        dd = _Reader(r.obj("decision"), f"{source}: decision")
        isolation = None
        if "isolation" in dd.doc:
            ir = _Reader(dd.obj("isolation"), f"{source}: decision.isolation")
            ranks = ir.integers("ranks")
            basis = ir.matrix("basis")
            isolation = Isolation(
                level=ir.number("level"),
                forgetting=ir.number("forgetting"),
                basis=basis,
                # no class of rank > 0 leaves no rows: the matrix is read with its width
                directions=ir.matrix("directions") if sum(ranks) else np.zeros((0, basis.shape[0])),
                ranks=np.asarray(ranks, dtype=int),
                accept=ir.vector("accept"),
                reject=ir.vector("reject"),
                nested=ir.matrix("nested"),
                settle=ir.integer("settle", minimum=1),
            )
        kwargs["decision"] = Decision(
            kind=dd.string("kind"), signatures=dd.matrix("signatures"), persistence=dd.integer("persistence", minimum=1),
            isolation=isolation,
        )
    signals = r.obj("signals") if "signals" in doc else None  # its refusal names the source already
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
            signals=signals,
            **kwargs,
        )
    except GainFileError as exc:
        raise GainFileError(f"{source}: {exc}") from None



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
