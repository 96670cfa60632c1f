"""``SPEC``: a built-in problem name, or a TOML plant file describing a new problem.

The TOML format (every key is validated; errors name the key)::

    name = "my_plant"                 # problem name; prefixes the C API
    title = "..."                     # optional

    [signals]                         # all optional: default names x0…, u0…, d0…, y0…
                                      # (a letter, then letters, digits, _; distinct: fdisyn.runtime.names)
    states = ["x1", "x2"]
    inputs = ["u"]
    unknown_inputs = ["d"]
    outputs = ["y1", "y2", "y3"]
    labels = { y1 = "rotor speed" }   # readable names and units by signal name (pages, gain files)
    units = { y1 = "rad/s", u = "N·m" }

    [model]
    time = "continuous"               # or "discrete"
    Ts = 0.01                         # sample time (s); continuous models are ZOH-sampled
    A = [[...]]                       # n × n
    B = [[...]]                       # n × m (optional)
    C = [[...]]                       # p × n
    D = [[...]]                       # p × m (optional)
    E = [[...]]                       # n × q unknown-input directions
    Fx = [[...]]                      # n × f component-fault directions (optional; names in [signals].component_faults)
    Q_intensity = [[...]]             # process noise of a continuous model: white noise intensity (PSD);
                                      # Q_sample = [[...]] for a discrete one: covariance per sample
                                      # (Q alone: the one the model's time implies)
    R = [[...]]                       # sensor noise covariance per sample
    state_scale = [...]               # optional typical state magnitudes (conditioning)

    [design]                          # the method and its options (``fdisyn methods NAME``)
    method = "kalman_uio"             # default; a linear method (sampled_data_observer, lmi: continuous models)
    arl0 = 3600.0                     # mean time between false alarms of the diagnoser (s; default one hour),
                                      # or P_f = 1e-6: per statistic and sample (give one of them)
    persistence = 1                   # consecutive exceedances before a statistic alarms
    bank = [["y1", "y2"], ["y1", "y3"]]   # one generator per group (default: all outputs)
    faults = [{ name = "y1", sensors = ["y1"] }, { name = "f", components = ["f"] }]
                                      # default: one per sensor and component fault, merged when alike
    poles = [0.5, 0.6]                # an option of one method (here uio_pole_placement)

    [[designs]]                       # instead of [design]: several designs, compared on one page
    name = "kalman"                   # the design's name: the diagnoser is <name>_<design name>
    method = "kalman_uio"             # and the keys of [design]
    [[designs]]
    name = "poles"
    method = "uio_pole_placement"
    poles = [0.5, 0.6]

The problem's options (``--option KEY=VALUE``, ``Problem.design(NAME, **options)``) are the design keys: a
value given overrides the file's in every design whose method reads it (``P_f`` replaces ``arl0`` and the
other way round), validated like the file.

The generalised UIO bank (``method = "kalman_uio_gos"``, Long & Wang,
Aeroengine 43(5), 2017) reads, besides ``arl0`` (or ``P_f``), ``persistence``, ``faults``::

    groups = "auto"                   # or [["y1", "y2"], ["y2", "y3"]]: one UIO per sensor in each group,
                                      # fed the group's other sensors; "auto": fewest groups of independent
                                      # outputs covering the sensors, best conditioned
    sensors = ["y1", "y2", "y3"]      # the sensors to diagnose (default: all)
    evaluator = "wssr"                # default; or "chi2"
    window = 25                       # WSSR window in samples (default 25)
    training = "train.csv"            # estimate E from a fault-free trace (path relative to this file):
                                      # columns t, the inputs, the outputs and the virtual outputs' states
                                      # (in the model's state coordinates); needs time = "continuous";
                                      # without it [model].E is decoupled
    virtual_outputs = "auto"          # or ["x3", "x4"]: states completing group 1 to rank n while E is estimated
    E_rank = 2                        # optional: the rank of E (default: from the singular-value gap)
    rank_gap = 10.0                   # smallest σ_q/σ_(q+1) accepted as that gap
    d_rate = 1.0                      # the estimator's random-walk rate of d₁, state magnitudes per second

With ``training`` and no ``[model].Q``, the process noise becomes the
mismatch ``E`` leaves out (its low-frequency power, as white noise).

For the UIO methods ``E`` holds unknown inputs to decouple; for the
sampled-data methods (Qiu, Wen & Jiang, Control Theory & Applications 27(8),
2010) it holds the disturbance, continuous white noise of unit intensity, and
``Fx`` the faults to be sensitive to. That paper's names (its eq. (1)) are
accepted too: ``Bu``, ``Bd``, ``Bf`` and ``h`` for ``B``, ``E``,
``Fx`` and ``Ts`` (one name per matrix in a file).

    [simulation]                      # for simulate / evaluate / report
    duration = 100.0                  # of the fault-free scenario (s)
    x0 = [...]                        # initial state (default 0)
    inputs = [{ kind = "sine", amplitude = 1.0, period = 10.0 }]      # one per input
    unknown_inputs = [{ kind = "gauss_markov", amplitude = 0.5, period = 2.0 }]

    [[scenarios]]                     # faulty scenarios (a fault-free one, "fault_free", is always added)
    name = "y1_offset"
    duration = 100.0
    fault = "y1"                      # the fault class the diagnoser should isolate
    onset = 50.0
    end = 80.0                        # optional
    sensor_faults = [{ sensor = "y1", kind = "offset", value = 0.5 }]   # stuck | gain | offset | drift
    component_faults = [{ fault = "f", value = 10.0 }]                   # a step of the fault input

Every duration lasts at least one sample and at most 10⁶ samples
(:data:`MAX_SAMPLES`); a scenario with a fault has an onset inside it (and an
end after the onset), and scenario names are unique.

Signal kinds: constant (offset), step (offset, amplitude, start), sine (offset,
amplitude, period), square (offset ± amplitude, period), prbs (offset,
amplitude, period = hold time), gauss_markov (offset, amplitude, period =
correlation time). For the sampled-data methods the disturbance is white
noise of unit intensity, sampled exactly by the simulator
([simulation].unknown_inputs is not used).

A nonlinear plant (Zhou, Xi & Zhang, Shanghai Jiao Tong University, c. 1991,
eq. (2.1): ``x(k+1) = f(x, u, θ) + v``, ``y = h(x, θ) + e``)
is written with ``time = "nonlinear"`` and designed by the NAFDF::

    [signals]
    states = ["x"]; inputs = ["u"]; outputs = ["y"]; parameters = ["a", "b"]
    [model]
    time = "nonlinear"
    Ts = 1.0                          # optional (default: time counted in samples)
    f = { x = "0.1*a*x^2 + x + 0.1*b*u" }     # one expression per state
    h = { y = "x" }                   # one per output; no inputs
    nominal = { a = -0.58, b = 0.2 }  # every parameter
    constants = { g = 9.81 }          # optional
    Q = [[0.0]]                       # covariance of v per sample (scalar, diagonal or matrix)
    R = [[0.01]]                      # covariance of e per sample (the paper's Q1 and Q2 are accepted too)
    [design]
    method = "nafdf"                  # the options of the method nafdf (``fdisyn methods``);
    P_f = 1e-4                        # per sample (default: arl0, one hour); x0 defaults to [simulation].x0; per-parameter ones
    window = 10                       # as a list or a table by name
    theta0 = { a = 0.0, b = 0.0 }
    [simulation]
    duration = 20000; x0 = [0.0]; inputs = [{ kind = "square", offset = 5.0, amplitude = 4.0, period = 50 }]
    [[scenarios]]
    name = "a_half"; duration = 2000; onset = 701   # end optional
    parameter_faults = [{ parameter = "a", scale = 0.5 }]   # θ → scale·θ0, or value = θ_faulty

A scenario's fault is its jumping parameters joined by "+"; the jump drives
the transitions from the onset sample on.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from fdisyn.simulation.nonlinear import simulate_nonlinear_runs
from fdisyn.simulation.sample_models import SampleModel, linear_sample_model, nonlinear_sample_model
from fdisyn.simulation.signals import SENSOR_FAULT_KINDS, SensorFaultSpec, Signal
from fdisyn.simulation.simulate import simulate_linear
from fdisyn.models.linear import LinearPlant
from fdisyn.simulation.problem import Batch, DesignFn, Problem, Scenario, get_problem
from fdisyn.models.sampling import van_loan
from fdisyn.runtime.errors import ArgumentError, FdisynError, ShapeError, SpecError
from fdisyn.runtime.gainfile import GainFile
from fdisyn.runtime.jsondata import read_regular_file
from fdisyn.runtime.schema import LIMITS
from fdisyn.runtime.names import (
    DIAGNOSER_NAME_MAX,
    SHORT_LABEL_MAX,
    check_diagnoser_name,
    check_distinct,
    check_label,
    check_signal_names,
    shown,
)
from fdisyn.runtime.values import real_number
from fdisyn.synthesis.registry import Method, all_methods, check_options, check_plant, get_method

__all__ = ["load_spec", "problem_from_toml", "problem_from_document", "signal_labels"]

SAMPLED_DATA_LETTERS = {"Bu": "B", "Bd": "E", "Bf": "Fx", "h": "Ts"}
"""Qiu, Wen & Jiang 2010 (eq. (1)) write a sampled-data plant as ``ẋ = A x + Bu u + Bd d + Bf f``,
``y = C x`` sampled every ``h``: those names are accepted for ``B``, ``E``,
``Fx`` and ``Ts``."""
NONLINEAR_LETTERS = {"Q1": "Q", "Q2": "R"}
"""Zhou, Xi & Zhang 1991 (eq. (2.1)) call the covariances of ``v`` and ``e`` ``Q1`` and ``Q2``: those
names are accepted for ``Q`` and ``R`` of a nonlinear plant."""
NOISE_KEYS = {"Q_intensity": "continuous", "Q_sample": "discrete"}
"""The process noise by what it is: ``Q_intensity``, the power spectral density of continuous white noise (a
continuous model; its covariance per sample is about ``Q_intensity·Ts``), or ``Q_sample``, the covariance per sample
(a discrete or nonlinear model). ``Q`` alone means the one the model's time implies."""
SIGNAL_TEXTS = ("units", "labels")
"""``[signals]`` tables of text per signal name: its unit (``"rad/s"``) and its readable name (``"rotor speed"``)."""


def _process_noise(mod: _Section, time: str) -> None:
    """Read ``Q_intensity`` or ``Q_sample`` as ``Q`` where it fits the model's time; one of the three keys at most."""
    given = [k for k in ("Q", *NOISE_KEYS) if k in mod.doc]
    if len(given) > 1:
        raise SpecError(f"{mod.where} gives {' and '.join(given)}: they are the same process noise, give one")
    for key, kind in NOISE_KEYS.items():
        if key not in mod.doc:
            continue
        if (kind == "continuous") != (time == "continuous"):
            other = "Q_intensity" if time == "continuous" else "Q_sample"
            what = "an intensity (continuous white noise)" if time == "continuous" else "a covariance per sample"
            raise SpecError(f"{mod.where}.{key} does not fit time = {time!r}, whose process noise is {what}: write it as {other}")
        mod.doc = {**{k: v for k, v in mod.doc.items() if k != key}, "Q": mod.doc[key]}
        mod.aliases["Q"] = key


def _signal_texts(sig: _Section) -> dict[str, dict[str, str]]:
    """``[signals].units`` and ``.labels``: tables of text by signal name (the plant checks the names and the text)."""
    out = {}
    for key in SIGNAL_TEXTS:
        v = sig.get(key)
        if v is None:
            continue
        if not isinstance(v, Mapping):
            raise SpecError(f"{sig.where}.{key} must be a table of text by signal name, e.g. {{ y1 = \"rad/s\" }}; got {shown(v)}")
        for name, text in v.items():
            if not isinstance(text, str):
                raise SpecError(f"{sig.where}.{key}.{name} must be text in quotes, e.g. {name} = \"rad/s\"; got {shown(text)}")
        out[key] = dict(v)
    return out


def signal_labels(plant: Any) -> dict[str, str]:
    """What a page calls each of ``plant``'s named signals: its label and unit, ``"rotor speed (rad/s)"``.

    Parameters
    ----------
    plant : LinearPlant or NonlinearPlant
        A plant with ``labels`` and ``units`` (signal name → text).

    Returns
    -------
    dict
        The signals with a label or a unit: the label (else the name) followed by the unit in parentheses.
    """
    labels, units = dict(getattr(plant, "labels", {}) or {}), dict(getattr(plant, "units", {}) or {})
    return {k: labels.get(k, k) + (f" ({units[k]})" if k in units else "") for k in sorted(set(labels) | set(units))}

def load_spec(spec: str | Path) -> Problem:
    """A built-in problem by name, or the problem a ``.toml`` file describes.

    ``SPEC`` comes from the command line: a path that exists but is not a file
    (a directory, a device) is refused by name instead of being looked up as a
    problem, and a string no file system accepts (a NUL byte, a name too long)
    is an unknown problem, not an OSError.
    """
    s = str(spec)
    try:
        is_file, exists = Path(s).is_file(), Path(s).exists()
    except (OSError, ValueError):
        is_file = exists = False
    if s.endswith(".toml") or is_file:
        return problem_from_toml(Path(s))
    if exists and s.strip():  # "" is the current directory to pathlib, but no SPEC at all
        raise SpecError(f"{s} is not a file: SPEC must be a TOML plant file or a built-in problem name (fdisyn list)")
    return get_problem(s)


MAX_SAMPLES = 10**6
"""Most samples one simulated run of a plant file may have. A run is simulated,
diagnosed and kept whole in memory: the Monte Carlo simulates 25 runs at a
time with every state, input, output and noise sample (8 bytes each), so at
10⁶ samples a ten-signal plant already needs ~2 GB per batch. Longer
durations are refused where they are read instead of failing in NumPy's
allocator."""


class _Section:
    def __init__(self, doc: Any, where: str, allowed: set[str]) -> None:
        if not isinstance(doc, Mapping):
            raise SpecError(f"{where} must be a table (key = value pairs), got {shown(doc)}")
        unknown = sorted(set(doc) - allowed)
        if unknown:
            raise SpecError(f"{where}: unknown key(s) {unknown}; allowed: {sorted(allowed)}")
        self.doc, self.where = doc, where
        self.aliases: dict[str, str] = {}
        """Key read → key the file wrote (``Bu``, ``Bd``, ``Bf``, ``h``), for error messages."""

    def accept_letters(self, letters: Mapping[str, str]) -> None:
        """Read a paper's names (``letters``: theirs → ours) as fdisyn's keys; a file gives one of the two."""
        for theirs, ours in letters.items():
            if theirs in self.doc and ours in self.doc:
                raise SpecError(f"{self.where} gives both {theirs!r} and {ours!r}: they are the same matrix, give one")
            if theirs in self.doc:
                self.doc = {**self.doc, ours: self.doc[theirs]}
                self.aliases[ours] = theirs

    def get(self, key: str, default: Any = None, *, required: bool = False) -> Any:
        if key not in self.doc:
            if required:
                raise SpecError(f"{self.where}: missing key {key!r}")
            return default
        return self.doc[key]

    def text(self, key: str, default: str) -> str:
        """A string (``default`` when the key is absent): a number, a list or a table is refused, never turned into text."""
        v = self.get(key, default)
        if not isinstance(v, str):
            raise SpecError(f"{self.where}.{key} must be a string (text in quotes), got {type(v).__name__} {shown(v)}")
        return v

    def entries(self, key: str) -> list[Any]:
        """A list (default empty), e.g. of tables."""
        v = self.get(key, [])
        if not isinstance(v, list):
            raise SpecError(f"{self.where}.{key} must be a list, got {v!r}")
        return v

    def duration(self, key: str, default: float | None = None, *, Ts: float | None = None) -> float:
        """A positive, finite length of time (required when ``default`` is None).

        With the sample time ``Ts``: at least one sample (a shorter run has no
        data to diagnose) and at most :data:`MAX_SAMPLES` samples.
        """
        v = self.number(key, default, required=default is None)
        if v is None or v <= 0:
            raise SpecError(f"{self.where}.{key} must be a positive, finite time, got {v!r}")
        if Ts is not None:
            samples = v / Ts
            if samples < 1.0 - 1e-9:  # 1e-9: a duration written as exactly Ts may round below it
                raise SpecError(f"{self.where}.{key} = {v:g} s is shorter than one sample: expected at least Ts = {Ts:g} s")
            if samples > MAX_SAMPLES:
                raise SpecError(
                    f"{self.where}.{key} = {v:g} s is {samples:.3g} samples at Ts = {Ts:g} s: "
                    f"expected at most {MAX_SAMPLES:.0e} samples per run ({MAX_SAMPLES * Ts:g} s)"
                )
        return v

    def number(self, key: str, default: float | None = None, *, required: bool = False) -> float | None:
        """A finite number (TOML's ``nan`` and ``inf`` are refused: no setting of a
        plant file means either, and a NaN would pass every ``<`` check after it)."""
        v = self.get(key, default, required=required)
        if v is None:
            return None
        label = f"{self.where}.{self.aliases.get(key, key)}"
        x = real_number(v)
        if x is None:
            raise SpecError(f"{label} must be a number, got {shown(v)}")
        if not math.isfinite(x):
            raise SpecError(f"{label} must be a finite number, got {shown(v)}")
        return x

    def vector(self, key: str, size: int) -> np.ndarray:
        """A list of ``size`` finite numbers (default: zeros)."""
        v = self.get(key, [0.0] * size)
        if not isinstance(v, list) or not all(_is_number(x) for x in v):
            raise SpecError(f"{self.where}.{key} must be a list of {size} numbers, got {shown(v)}")
        try:
            a = np.asarray(v, dtype=float)
        except OverflowError:
            raise SpecError(f"{self.where}.{key} must hold finite numbers, got {shown(v)}") from None
        if a.shape != (size,):
            raise SpecError(f"{self.where}.{key} must have {size} entries, got {a.size}")
        if not np.all(np.isfinite(a)):
            raise SpecError(f"{self.where}.{key} must hold finite numbers, got {shown(v)}")
        return a

    def matrix(self, key: str, *, required: bool = False) -> np.ndarray | None:
        """A matrix of numbers (a list of rows; a plain list is one column of an
        input matrix or one row otherwise); errors name the key the file wrote."""
        v = self.get(key, None, required=required)
        if v is None:
            return None
        label = f"{self.where}.{self.aliases.get(key, key)}"
        # numbers only: NumPy would turn "1.5" and true into 1.5 and 1.0 without a word
        if not (_is_number(v) or (isinstance(v, list) and all(_is_number(x) or (isinstance(x, list) and all(map(_is_number, x))) for x in v))):
            raise SpecError(f"{label} must be a matrix of numbers (a list of rows), got {shown(v)}")
        try:
            a = np.asarray(v, dtype=float)
        except ValueError:  # rows of different lengths
            raise SpecError(f"{label} must be a matrix of numbers (a list of rows of one length), got {shown(v)}") from None
        except OverflowError:  # an integer beyond the double range
            raise SpecError(f"{label} must hold finite numbers, got {shown(v)}") from None
        if a.ndim == 1:
            a = a.reshape(-1, 1) if key in ("B", "E", "Fx") else a.reshape(1, -1)
        if a.ndim != 2:
            raise SpecError(f"{label} must be a matrix (a list of rows), got {shown(v)}")
        if not np.all(np.isfinite(a)):  # here, where the key the file wrote (Bu, Bd, Bf) is known
            bad = tuple(int(i) for i in np.argwhere(~np.isfinite(a))[0])
            raise SpecError(f"{label} must hold finite numbers; entry {list(bad)} is {float(a[bad])!r}")
        return a


def _is_number(x: Any) -> bool:
    """A number as :func:`~fdisyn.runtime.values.real_number` reads it: a boolean or a string is no number, whatever NumPy makes of it."""
    return real_number(x) is not None


def _signal(d: Any, where: str) -> Signal:
    if not isinstance(d, Mapping):
        raise SpecError(f"{where} must be a table like {{ kind = \"sine\", amplitude = 1.0, period = 10.0 }}")
    sec = _Section(d, where, {"kind", "offset", "amplitude", "period", "start"})
    kind = sec.get("kind", "constant")
    if kind not in Signal.KINDS:
        raise SpecError(f"{where}.kind must be one of {list(Signal.KINDS)}, got {shown(kind)}")
    # every value is read as written: 0 is a value, not "use the default"
    return Signal(
        kind=kind,
        offset=float(sec.number("offset", 0.0)),  # type: ignore[arg-type]
        amplitude=float(sec.number("amplitude", 0.0)),  # type: ignore[arg-type]
        period=sec.duration("period", 1.0),
        start=float(sec.number("start", 0.0)),  # type: ignore[arg-type]
    )


def problem_from_toml(path: Path) -> Problem:
    """Parse and validate a TOML plant file (format in the module docstring)."""
    try:
        # a regular file of bounded size: a name leading to /dev/zero or a FIFO would never end
        text = read_regular_file(path, LIMITS["file_bytes"], "a TOML plant file", error=SpecError).decode("utf-8")
        doc = tomllib.loads(text)
    except FileNotFoundError:
        raise SpecError(f"no plant file at {path}") from None
    except IsADirectoryError:
        raise SpecError(f"{path} is a directory: SPEC must be a TOML plant file or a built-in problem name (fdisyn list)") from None
    except UnicodeDecodeError as exc:
        raise SpecError(f"{path} is not a text file (byte {exc.start} is not UTF-8): a TOML plant file is expected") from None
    except OSError as exc:
        raise SpecError(f"cannot read plant file {path}: {exc.strerror or exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise SpecError(f"{path} is not valid TOML: {exc}") from exc
    except RecursionError:  # tomllib recurses once per nested array or inline table
        raise SpecError(f"{path}: its TOML is nested too deeply to be a plant file (a matrix is a list of rows)") from None
    return problem_from_document(doc, path)


def problem_from_document(doc: Mapping[str, Any], path: Path, *, origin: str | None = None) -> Problem:
    """The problem a parsed plant file describes (``path`` names it in errors and in the gain file; ``origin`` says
    where the plant comes from in the page's summary, default the file's name)."""
    top = _Section(doc, str(path), {"name", "title", "signals", "model", "design", "designs", "simulation", "scenarios"})
    name = check_diagnoser_name(top.get("name", required=True), f"{path}: name", error=SpecError)
    model = top.get("model", required=True)
    if not isinstance(model, Mapping):
        raise SpecError(f"{path} [model] must be a table (key = value pairs), got {shown(model)}")
    if model.get("time", "continuous") not in ("continuous", "discrete", "nonlinear"):
        raise SpecError(f"{path} [model].time must be 'continuous', 'discrete' or 'nonlinear', got {shown(model.get('time'))}")
    if model.get("time") == "nonlinear":
        return _nonlinear_problem(path, top, name, origin or f"described by {path.name}")
    sig = _Section(top.get("signals", {}), f"{path} [signals]", {"states", "inputs", "unknown_inputs", "outputs", "component_faults", *SIGNAL_TEXTS})
    given = {f"[signals].{k}": check_signal_names(v, f"{path} [signals].{k}", error=SpecError) for k, v in sig.doc.items() if k not in SIGNAL_TEXTS}
    try:
        check_distinct(given, why="they are columns of the trace CSV `fdisyn simulate` writes, and fault classes are named after sensors and component faults", error=SpecError)
    except SpecError as exc:
        raise SpecError(f"{path}: {exc}") from None
    mod = _Section(
        top.get("model", required=True),
        f"{path} [model]",
        {"time", "Ts", "A", "B", "C", "D", "E", "Fx", "Dd", "Df", "Q", "R", "state_scale", *SAMPLED_DATA_LETTERS, *NOISE_KEYS},
    )
    mod.accept_letters(SAMPLED_DATA_LETTERS)
    time = mod.get("time", "continuous")
    if time not in ("continuous", "discrete"):
        raise SpecError(f"{path} [model].time must be 'continuous', 'discrete' or 'nonlinear', got {shown(time)}")
    _process_noise(mod, time)
    ts = mod.number("Ts", required=True)
    if ts is None or ts <= 0:  # number() has refused NaN and ±inf
        raise SpecError(f"{path} [model].{mod.aliases.get('Ts', 'Ts')} must be a positive sample time in seconds, got {ts!r}")
    # read (and name) every matrix first: a wrong one is reported once, by the key the file wrote
    mats = {k: mod.matrix(k, required=k in ("A", "C")) for k in ("A", "B", "C", "D", "E", "Fx", "Dd", "Df", "Q", "R")}
    texts = _signal_texts(sig)
    try:
        plant = LinearPlant.create(
            A=mats["A"],
            B=mats["B"],
            C=mats["C"],
            D=mats["D"],
            E=mats["E"],
            Fx=mats["Fx"],
            Dd=mats["Dd"],
            Df=mats["Df"],
            Q=mats["Q"],
            R=mats["R"],
            Ts=ts if time == "discrete" else None,
            states=sig.get("states"),
            inputs=sig.get("inputs"),
            unknown_inputs=sig.get("unknown_inputs"),
            outputs=sig.get("outputs"),
            component_faults=sig.get("component_faults"),
            **texts,
        )
        physical = plant if time == "discrete" else plant.discretise(ts, name=mod.aliases.get("Ts", "Ts"))
    except FdisynError as exc:
        raise SpecError(f"{path} [model]: {exc}") from exc
    scale = mod.get("state_scale")
    try:
        design_plant = physical.scaled(scale) if scale is not None else physical
    except FdisynError as exc:
        raise SpecError(f"{path} [model].state_scale: {exc}") from exc
    designs: dict[str, DesignFn] = {}
    classes: list[list[Any] | None] = []
    whites = set()
    for label, method, options, where in _design_entries(top, path, name, ("linear", "continuous")):
        if isinstance(options.get("training"), str) and options["training"]:
            # a training trace is named relative to the plant file, like the file's other companions
            options = {**options, "training": str(path.parent / options["training"])}
        white = method.plant_kind == "continuous"
        if white and time != "continuous":
            raise SpecError(f"{where}.method {method.name!r} designs for a continuous plant sampled at Ts: set [model].time = \"continuous\"")
        des_plant = design_plant
        if white or (method.samples_itself and time == "continuous"):
            # the sampled-data methods, and those whose model error is on the continuous A, sample the plant themselves, every Ts
            des_plant = plant.scaled(scale) if scale is not None else plant
            options = {**options, "Ts": ts}
        try:
            check_plant(method, des_plant)
        except ArgumentError as exc:
            raise SpecError(f"{where}.method: {exc}") from exc
        checked = _checked(method, options, des_plant, where)
        record = {"spec": str(path), "method": method.name, **{k: v for k, v in options.items() if k not in ("bank", "faults", "Ts")}}
        designs[label] = _design_fn(method, des_plant, options, checked, record, name=f"{name}_{label}", problem=name, where=where)
        classes.append(checked.get("faults"))  # the fault classes of a bank; a method without them names its faults itself
        whites.add(white)
    if len(whites) > 1:
        raise SpecError(
            f"{path} [[designs]]: the sampled-data methods read [model].E as continuous white noise, the others as unknown "
            "inputs to decouple; the simulation cannot be both: put them in two plant files"
        )
    white = whites.pop()

    sim = _Section(top.get("simulation", {}), f"{path} [simulation]", {"duration", "x0", "inputs", "unknown_inputs"})
    u_sigs = [_signal(s, f"{path} [simulation].inputs[{i}]") for i, s in enumerate(sim.entries("inputs"))]
    d_sigs = [_signal(s, f"{path} [simulation].unknown_inputs[{i}]") for i, s in enumerate(sim.entries("unknown_inputs"))]
    u_sigs += [Signal()] * (physical.m - len(u_sigs))
    d_sigs += [Signal()] * (physical.q - len(d_sigs))
    if len(u_sigs) != physical.m or len(d_sigs) != physical.q:
        raise SpecError(f"{path} [simulation]: {physical.m} input and {physical.q} unknown-input signals at most")
    x0 = sim.vector("x0", physical.n)
    scenarios = {"fault_free": Scenario("fault_free", "No fault.", sim.duration("duration", 100.0, Ts=ts))}
    sources = set(physical.outputs) | set(physical.component_faults)
    # a scenario's fault is a class of one of the designs ("a|b": default classes merged when alike)
    known = None if any(c is None for c in classes) else {f.name for c in classes for f in c}  # type: ignore[union-attr]
    first: dict[str, int] = {}
    for i, sd in enumerate(top.entries("scenarios")):
        w = f"{path} [[scenarios]][{i}]"
        sc = _Section(sd, w, {"name", "description", "duration", "fault", "onset", "end", "sensor_faults", "component_faults"})
        sname = sc.get("name", required=True)
        if sname == "fault_free":
            raise SpecError(f"{w}.name 'fault_free' is the built-in fault-free scenario ([simulation]); choose another name")
        if isinstance(sname, str) and sname in first:
            raise SpecError(f"{w}.name {sname!r} is already the name of [[scenarios]][{first[sname]}]; scenario names must be unique")
        sname = _scenario_name(sname, scenarios, w)
        first[sname] = i
        fname = sc.get("fault")
        # a listed class, or (default classes) a sensor/component name or a merged "a|b" group of them
        if fname is not None and (
            not isinstance(fname, str) or (fname not in known if known is not None else not set(fname.split("|")) <= sources)
        ):
            raise SpecError(f"{w}.fault {shown(fname)} is not a fault class; classes: {sorted(known or sources)}")
        cfs = []
        for j, f in enumerate(sc.entries("component_faults")):
            fs = _Section(f, f"{w}.component_faults[{j}]", {"fault", "value"})
            cname = str(fs.get("fault", required=True))
            if cname not in physical.component_faults:
                raise SpecError(f"{w}.component_faults[{j}]: no component fault {cname!r}; the plant has {list(physical.component_faults)}")
            cfs.append((cname, float(fs.number("value", required=True))))  # type: ignore[arg-type]
        sfs = []
        for j, f in enumerate(sc.entries("sensor_faults")):
            fs = _Section(f, f"{w}.sensor_faults[{j}]", {"sensor", "kind", "value"})
            sensor, kind = fs.get("sensor", required=True), fs.get("kind", required=True)
            if sensor not in physical.outputs:
                raise SpecError(f"{w}.sensor_faults[{j}].sensor {shown(sensor)} is not an output; outputs are {list(physical.outputs)}")
            if kind not in SENSOR_FAULT_KINDS:
                raise SpecError(f"{w}.sensor_faults[{j}].kind must be one of {list(SENSOR_FAULT_KINDS)}, got {shown(kind)}")
            sfs.append(SensorFaultSpec(sensor, kind, float(fs.number("value", required=True))))  # type: ignore[arg-type]
        duration = sc.duration("duration", Ts=ts)
        onset, end = sc.number("onset"), sc.number("end")
        _check_fault_window(w, fname, onset, end, duration, bool(cfs or sfs))
        scenarios[sname] = Scenario(
            name=sname,
            description=sc.text("description", ""),
            duration=duration,
            fault=fname,
            onset=onset,
            end=end,
            params={"sensor_faults": sfs, "component_faults": cfs},
        )

    if white:
        # the sampled-data disturbance (Qiu, Wen & Jiang 2010): continuous white noise of unit intensity, sampled exactly into the process noise
        w_d = van_loan(np.asarray(plant.A), np.asarray(plant.E) @ np.asarray(plant.E).T, ts)
        sim_plant = physical.with_noise(Q=np.asarray(physical.Q) + w_d)
        d_sigs = [Signal()] * physical.q
    else:
        sim_plant = physical

    def simulate(scenario: Scenario, seeds: tuple[int, ...], draws: np.ndarray | None = None, **_: Any) -> Batch:
        return simulate_linear(sim_plant, scenario, seeds, x0=x0, inputs=u_sigs, unknown_inputs=d_sigs, draws=draws)

    def sample_model(**_: Any) -> SampleModel:
        return linear_sample_model(sim_plant, x0=x0, inputs=u_sigs, unknown_inputs=d_sigs)

    return Problem(
        name=name,
        title=top.text("title", name),
        summary=_summary(f"Plant {origin or f'described by {path.name}'}", designs),
        designs=designs,
        default_design=next(iter(designs)),
        scenarios=scenarios,
        simulate=simulate,
        sample_model=sample_model,
        monte_carlo_runs=50,
        model=lambda **_: physical,
        options=_design_options(designs),
        labels=signal_labels(physical),
    )


def _check_fault_window(where: str, fault: str | None, onset: float | None, end: float | None, duration: float, injects: bool) -> None:
    """A faulty scenario's fault is active on ``onset ≤ t < end``; anything else in
    a scenario would be silently ignored (faults without a window never act, a
    window without a fault class is never evaluated) or never happen."""
    if injects and fault is None:
        raise SpecError(f"{where}: sensor_faults and component_faults act only while the fault is active: give fault (the class to isolate) and onset")
    if fault is not None and onset is None:
        raise SpecError(f"{where}: fault {fault!r} needs an onset (the time in seconds it starts)")
    if fault is None and (onset is not None or end is not None):
        raise SpecError(f"{where}: onset and end belong to a fault: give fault (the class to isolate) or remove them")
    if onset is not None and not 0.0 <= onset < duration:
        raise SpecError(f"{where}.onset = {onset:g} s must lie in [0, duration = {duration:g} s)")
    if onset is not None and end is not None and end <= onset:
        raise SpecError(f"{where}.end = {end:g} s must come after onset = {onset:g} s")


def _design_entries(top: _Section, path: Path, name: str, kinds: tuple[str, ...]) -> list[tuple[str, Method, dict[str, Any], str]]:
    """The file's designs: ``[design]`` (one, named after its method) or ``[[designs]]`` (several, each with a
    ``name``), as ``(name, method, options given, where)`` in the file's order."""
    if "design" in top.doc and "designs" in top.doc:
        raise SpecError(f"{path}: give [design] (one design) or [[designs]] (several, each with a name), not both")
    if "designs" not in top.doc:
        method, options = _design_section(top.get("design", {}), f"{path} [design]", path, kinds)
        _diagnoser_name(name, method.name, path)
        return [(method.name, method, options, f"{path} [design]")]
    tables = top.entries("designs")
    if not tables:
        raise SpecError(f"{path} [[designs]] is empty: give one table per design, each with a name and a method")
    out: list[tuple[str, Method, dict[str, Any], str]] = []
    first: dict[str, int] = {}
    for i, table in enumerate(tables):
        where = f"{path} [[designs]][{i}]"
        method, options = _design_section(table, where, path, kinds, named=True)
        if "name" not in options:
            raise SpecError(f"{where}: missing key 'name' (the design's name on the page and in the C API, e.g. name = \"kalman\")")
        label = check_label(options.pop("name"), f"{where}.name", max_length=SHORT_LABEL_MAX, error=SpecError)
        if label in first:
            raise SpecError(f"{where}.name {label!r} is already the name of [[designs]][{first[label]}]; design names must be unique")
        first[label] = i
        _diagnoser_name(name, label, path)
        out.append((label, method, options, where))
    return out


def _design_section(doc: Any, where: str, path: Path, kinds: tuple[str, ...], *, named: bool = False) -> tuple[Method, dict[str, Any]]:
    """One design's table: its method (one designing for ``kinds`` of plants) and the options it gives (``name``
    too when ``named``).

    The keys allowed are those of the methods' schemas (:mod:`fdisyn.synthesis.registry`);
    options a plant file takes from elsewhere (``Ts`` from ``[model]``) are not keys here.
    """
    methods = [m for m in all_methods() if m.plant_kind in kinds]
    keys = {"method"} | ({"name"} if named else set()) | {o.name for m in methods for o in m.options if o.plant_file is None}
    des = _Section(doc, where, keys)
    method = des.get("method", methods[0].name if len(methods) == 1 else "kalman_uio")
    if not isinstance(method, str) or method not in [m.name for m in methods]:
        family = "nonlinear" if "nonlinear" in kinds else "linear"
        raise SpecError(f"{where}.method {shown(method)}: a {family} plant is designed by {', '.join(repr(m.name) for m in methods)}")
    return get_method(method), {k: v for k, v in des.doc.items() if k != "method"}


@contextmanager
def _spec_errors() -> Iterator[None]:
    """A method's :class:`ArgumentError` about a ``[design]`` key is an error of the plant file (its message names the key)."""
    try:
        yield
    except ArgumentError as exc:
        raise SpecError(str(exc)) from exc


def _checked(method: Method, given: Mapping[str, Any], plant: Any, where: str) -> dict[str, Any]:
    """The method's options from a design's table, validated against its schema (errors name the key)."""
    with _spec_errors():
        return check_options(method, given, plant=plant, where=where)


BUDGET_KEYS = ("P_f", "arl0")
"""The two ways of giving a design's false-alarm budget: an option giving one replaces the file's other."""


def _design_fn(method: Method, plant: Any, options: Mapping[str, Any], checked: Mapping[str, Any], record: Mapping[str, Any], *,
               name: str, problem: str, where: str) -> DesignFn:  # fmt: skip
    """A design of the file: its options as the file gives them, updated by the problem's options given (``--option
    KEY=VALUE``; ``None``, the problem's default, keeps the file's value), each validated like the file's."""

    def design_fn(**given: Any) -> GainFile:
        over = {k: v for k, v in given.items() if v is not None and k in method.option_names}
        opts = dict(checked)
        if over:
            base = {k: v for k, v in options.items() if not (k in BUDGET_KEYS and set(BUDGET_KEYS) & set(over))}
            opts = _checked(method, {**base, **over}, plant, f"{where} with the option(s) given")
        with _spec_errors():
            return method.design(plant, name=name, problem=problem, record={**record, **over}, where=where, **opts)

    design_fn.method = method  # type: ignore[attr-defined]  # what the problem's options and summary read
    return design_fn


def _design_options(designs: Mapping[str, Any]) -> dict[str, None]:
    """The problem's options: every key of its designs' methods (``None``: as the file gives it)."""
    keys = sorted({o.name for fn in designs.values() for o in fn.method.options if o.plant_file is None})
    return dict.fromkeys(keys)


def _summary(head: str, designs: Mapping[str, Any]) -> str:
    if len(designs) == 1:
        return f"{head}; design method {next(iter(designs.values())).method.name}."
    return f"{head}; designs " + ", ".join(f"{k} ({fn.method.name})" for k, fn in designs.items()) + "."


def _diagnoser_name(name: str, method: str, path: Path) -> None:
    """The gain file's name ``<name>_<design>`` prefixes the C API: within the length limit too."""
    full = f"{name}_{method}"
    if len(full) > DIAGNOSER_NAME_MAX:
        raise SpecError(
            f"{path}: name {name!r} is too long: the diagnoser's name {name}_{method} (name and design method) has "
            f"{len(full)} characters, at most {DIAGNOSER_NAME_MAX} prefix the generated C API"
        )
    check_diagnoser_name(full, f"{path}: the diagnoser's name (name and design method)", error=SpecError)


def _scenario_name(value: Any, scenarios: Mapping[str, Scenario], where: str) -> str:
    """A scenario's name: a label (it names report figures, i.e. files), not already taken."""
    sname = check_label(value, f"{where}.name", max_length=SHORT_LABEL_MAX, error=SpecError)
    if sname in scenarios:
        raise SpecError(f"{where}.name {sname!r} is taken (by the built-in fault-free scenario or an earlier one); scenario names must be unique")
    return sname


# --------------------------------------------------------------------------- nonlinear plants (Zhou, Xi & Zhang 1991)

def _nonlinear_problem(path: Path, top: _Section, name: str, origin: str) -> Problem:
    """A ``time = "nonlinear"`` plant file: the model of Zhou, Xi & Zhang 1991 (eq. (2.1)) and the NAFDF (format in ``design/examples/PLANT_FILES.md``)."""
    from fdisyn.models.nonlinear import NonlinearPlant
    from fdisyn.numerics.linalg import as_covariance

    sig = _Section(top.get("signals", {}), f"{path} [signals]", {"states", "inputs", "outputs", "parameters", *SIGNAL_TEXTS})
    mod = _Section(top.get("model", required=True), f"{path} [model]",
                   {"time", "Ts", "f", "h", "nominal", "constants", "Q", "R", *NONLINEAR_LETTERS, *NOISE_KEYS})
    mod.accept_letters(NONLINEAR_LETTERS)
    _process_noise(mod, "nonlinear")
    ts = mod.number("Ts")
    names = {}
    for key in ("states", "inputs", "outputs", "parameters"):
        v = sig.get(key, [], required=key != "inputs")
        if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
            raise SpecError(f"{path} [signals].{key} must be a list of names, got {v!r}")
        names[key] = list(check_signal_names(v, f"{path} [signals].{key}", error=SpecError))
    noise = {}
    for key, size, definite in (("Q", len(names["states"]), False), ("R", len(names["outputs"]), True)):
        try:
            noise[key] = as_covariance(mod.get(key, required=True), mod.aliases.get(key, key), size, definite=definite)
        except (ShapeError, ArgumentError) as exc:
            raise SpecError(f"{path} [model].{exc}") from None
    for key in ("f", "h", "nominal"):
        if not isinstance(mod.get(key, required=True), Mapping):
            raise SpecError(f"{path} [model].{key} must be a table such as {{ x = \"...\" }}")
    if not isinstance(mod.get("constants", {}), Mapping):
        raise SpecError(f"{path} [model].constants must be a table such as {{ g = 9.81 }}, got {shown(mod.get('constants'))}")
    texts = _signal_texts(sig)
    try:
        plant = NonlinearPlant.from_expressions(
            states=names["states"],
            inputs=names["inputs"],
            outputs=names["outputs"],
            parameters=names["parameters"],
            nominal=mod.get("nominal"),
            f=mod.get("f"),
            h=mod.get("h"),
            Q=noise["Q"],
            R=noise["R"],
            constants=mod.get("constants"),
            Ts=ts,
            **texts,
        )
    except FdisynError as exc:
        raise SpecError(f"{path} [model]: {exc}") from exc
    step_ts = ts or 1.0
    pars = plant.parameters

    sim = _Section(top.get("simulation", {}), f"{path} [simulation]", {"duration", "x0", "inputs"})
    u_sigs = [_signal(x, f"{path} [simulation].inputs[{i}]") for i, x in enumerate(sim.entries("inputs"))]
    if len(u_sigs) > plant.m:
        raise SpecError(f"{path} [simulation].inputs: {plant.m} input signal(s) at most, got {len(u_sigs)}")
    u_sigs += [Signal()] * (plant.m - len(u_sigs))
    x0 = sim.vector("x0", plant.n)
    if not np.all(np.isfinite(x0)):
        raise SpecError(f"{path} [simulation].x0 must hold finite numbers, got {x0.tolist()}")

    designs: dict[str, DesignFn] = {}
    for label, method, given, where in _design_entries(top, path, name, ("nonlinear",)):
        options = {"x0": x0.tolist(), **given}
        checked = _checked(method, options, plant, where)
        u0 = np.zeros(plant.m) if checked["u0"] is None else np.asarray(checked["u0"], dtype=float)
        # the model must be finite where the simulation starts (x/0, x**x at 0 …): refused here, before any data
        try:
            plant.check_finite(x=x0, u=u0, point=f"the nominal point ([simulation].x0 = {x0.tolist()}, u = {u0.tolist()}, nominal θ)")
        except FdisynError as exc:
            raise SpecError(f"{path} [model]: {exc}") from None
        designs[label] = _design_fn(method, plant, options, checked, {"spec": str(path)}, name=f"{name}_{label}", problem=name, where=where)

    scenarios = {
        "fault_free": Scenario("fault_free", "No fault.", sim.duration("duration", 1000.0 * step_ts, Ts=step_ts))
    }
    for i, sd in enumerate(top.entries("scenarios")):
        w = f"{path} [[scenarios]][{i}]"
        sc = _Section(sd, w, {"name", "description", "duration", "onset", "end", "parameter_faults"})
        theta = dict(zip(pars, plant.theta_nominal.tolist(), strict=True))
        for j, pf in enumerate(sc.entries("parameter_faults")):
            fs = _Section(pf, f"{w}.parameter_faults[{j}]", {"parameter", "scale", "value"})
            q = str(fs.get("parameter", required=True))
            if q not in pars:
                raise SpecError(f"{w}.parameter_faults[{j}]: no parameter {q!r}; the plant has {list(pars)}")
            if ("scale" in fs.doc) == ("value" in fs.doc):
                raise SpecError(f"{w}.parameter_faults[{j}]: give either scale (θ → scale·θ0) or value (θ → value)")
            theta[q] = float(fs.number("value")) if "value" in fs.doc else float(fs.number("scale")) * theta[q]  # type: ignore[arg-type]
            if not np.isfinite(theta[q]):
                raise SpecError(f"{w}.parameter_faults[{j}]: the faulty {q} must be finite, got {theta[q]!r}")
        sizes = {q: theta[q] - float(plant.theta_nominal[k]) for k, q in enumerate(pars) if theta[q] != plant.theta_nominal[k]}
        onset = sc.number("onset")
        if sizes and onset is None:
            raise SpecError(f"{w}: a scenario with parameter faults needs an onset")
        scen = Scenario(
            name=_scenario_name(sc.get("name", required=True), scenarios, w),
            description=sc.text("description", ""),
            duration=sc.duration("duration", Ts=step_ts),
            fault="+".join(sizes) if sizes else None,
            onset=onset if sizes else None,
            end=sc.number("end"),
            params={"theta": [theta[q] for q in pars], "fault_size": sizes},
        )
        scenarios[scen.name] = scen

    def parameters(scenario: Scenario) -> np.ndarray:
        n = int(round(scenario.duration / step_ts))
        # row k of θ drives the transition x(k) → x(k+1): a jump at the onset first shows in y(onset + 1)
        theta = np.tile(plant.theta_nominal, (n, 1))
        if scenario.fault is not None:
            theta[scenario.active(np.arange(n) * step_ts)] = np.asarray(scenario.params["theta"], dtype=float)
        return theta

    keep = {f"true_{q}": q for q in pars} | {f"true_{s}": s for s in plant.states}

    def simulate(scenario: Scenario, seeds: tuple[int, ...], draws: np.ndarray | None = None, **_: Any) -> Batch:
        return simulate_nonlinear_runs(plant, scenario, seeds, x0=x0, drive=lambda sc: (None, parameters(sc)), Ts=step_ts, extra=keep,
                                       signals=u_sigs, draws=draws)

    def sample_model(**_: Any) -> SampleModel:
        return nonlinear_sample_model(plant, x0=x0, drive=lambda sc: (None, parameters(sc)), Ts=step_ts, extra=keep, signals=u_sigs)

    return Problem(
        name=name,
        title=top.text("title", name),
        summary=f"Nonlinear plant {origin}; the adaptive fault detection filter (NAFDF, Zhou, Xi & Zhang 1991)"
        + ("." if len(designs) == 1 else f": designs {', '.join(designs)}."),
        designs=designs,
        default_design=next(iter(designs)),
        scenarios=scenarios,
        simulate=simulate,
        sample_model=sample_model,
        monte_carlo_runs=50,
        options=_design_options(designs),
        labels=signal_labels(plant),
    )
