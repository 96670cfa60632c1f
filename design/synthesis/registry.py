"""The design methods: one registry that the plant files, the problems, the CLI and the step assembly read.

A method is one module of :mod:`fdisyn.synthesis` that calls :func:`register`
with a :class:`Method` when it is imported: its plant kind, its options (each an
:class:`Option` with its default, domain and validator), its design function,
and the diagnoser kind its gain files are (what they mean downstream — the
CasADi step, the recovery window of the Monte Carlo, extra metrics — is the
kind's: :mod:`fdisyn.synthesis.kinds`). The registry imports every module of
:mod:`fdisyn.synthesis` the first time a method is looked up, so adding a
method needs no other edit: a plant file's ``[design].method``,
``fdisyn.design(plant, method=...)`` and ``fdisyn methods`` all find it here.

Importing this module is light (no CasADi, no cvxpy); :mod:`fdisyn.runtime`
never imports it.
"""

from __future__ import annotations

import json
import math
import numpy as np
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from typing import Any

from fdisyn.detectors.table import DETECTORS, option_texts
from fdisyn.runtime.errors import ArgumentError
from fdisyn.runtime.gainfile import GainFile
from fdisyn.runtime.schema import LIMITS
from fdisyn.runtime.names import shown
from fdisyn.synthesis import kinds

__all__ = [
    "REQUIRED",
    "DEFAULT_ARL0",
    "Option",
    "Method",
    "PLANT_KINDS",
    "SHARED_OPTIONS",
    "register",
    "get_method",
    "method_names",
    "all_methods",
    "check_plant",
    "check_options",
    "check_option",
    "design",
    "at",
]

class _Required:
    def __repr__(self) -> str:
        return "REQUIRED"


REQUIRED: Any = _Required()
"""The default of an option that has none: it must be given."""

PLANT_KINDS = {
    "linear": "a LinearPlant, discrete (or continuous with the option Ts: ZOH-sampled)",
    "continuous": "a continuous LinearPlant, designed as a sampled-data plant sampled every Ts",
    "nonlinear": "a NonlinearPlant",
}
"""What each ``Method.plant_kind`` designs for."""




def at(where: str, key: str) -> str:
    """How a message names option ``key`` of ``where``: ``PATH [design].P_f`` in a plant
    file's section, ``method 'lmi': option eta`` (or ``problem …: option …``) elsewhere."""
    return f"{where}.{key}" if where.endswith("]") else f"{where}: option {key}"


def _anything(value: Any) -> bool:
    return True


def is_real(v: Any) -> bool:
    """A finite int or float (a boolean is no number)."""
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def is_count(v: Any) -> bool:
    """A whole number ≥ 1 (a boolean is no number)."""
    return isinstance(v, int) and not isinstance(v, bool) and v >= 1


@dataclass(frozen=True)
class Option:
    """One option of a method: its name, default, one-line doc and domain.

    ``accepts`` tests the domain ``expected`` describes (values arrive as JSON or
    TOML, so they are checked rather than converted: ``int(1.5)`` would
    silently become 1); ``refine`` then checks what depends on the plant (an
    output name, one pole per state) and returns the value the design gets.
    """

    name: str
    default: Any
    doc: str
    expected: str
    accepts: Callable[[Any], bool] = _anything
    refine: Callable[[Any, str, Any], Any] | None = None
    """``(value, where, plant) -> value``; raises :class:`ArgumentError` naming ``at(where, name)``."""
    plant_file: str | None = None
    """Where a plant file takes the value from when it is not a ``[design]`` key (e.g. ``[model].Ts``)."""

    @property
    def required(self) -> bool:
        return self.default is REQUIRED

    def validate(self, value: Any, where: str = "", plant: Any = None) -> Any:
        """The checked value, or :class:`ArgumentError` naming the option, the value and what is expected."""
        label = at(where, self.name) if where else f"option {self.name}"
        if value is None and self.default is None:
            return None
        if not self.accepts(value):
            raise ArgumentError(f"{label} = {shown(value)}: expected {self.expected}")
        if isinstance(self.default, float) and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        if self.refine is not None:
            value = self.refine(value, where or "", plant)
        return value


@dataclass(frozen=True, eq=False)
class Method:
    """A design method: what it designs for, its options, and the diagnoser kind of its gain files.

    ``design(plant, *, name, problem=None, record=None, where="", **checked_options)``
    returns a certified gain file named ``name`` (``problem`` defaults to
    ``name``; ``record`` is stored as the provenance's design options;
    ``where`` prefixes error messages, see :func:`at`).
    """

    name: str
    plant_kind: str
    summary: str
    reference: str
    options: tuple[Option, ...]
    design: Callable[..., GainFile]
    diagnoser_kind: str
    """The :class:`~fdisyn.synthesis.kinds.DiagnoserKind` its gain files are (a registered kind's name): what they
    mean downstream of the design (their step, recovery window, budget, extra metrics) is the kind's."""
    generator: Callable[..., Any] | None = None
    """Linear bank methods: the design of one generator,
    ``(plant, outputs_used, name, **options) -> (Generator, Σ_r, Certificate)``."""
    check: Callable[[Any, Mapping[str, Any], str], None] | None = None
    """Conditions across options or on the plant, checked before designing: ``(plant, options, where)``."""
    samples_itself: bool = False
    """A ``linear`` method whose design samples a continuous plant itself, at the option ``Ts`` (its model error is
    on the continuous ``A``): a plant file hands it the continuous plant and ``[model].Ts``, not the sampled plant."""
    feedthrough: bool = False
    """A ``linear`` method that designs for plants whose unknown inputs or component faults reach the outputs
    directly (``Dd``, ``Df`` nonzero); the others are handed such a plant refused by :func:`check_plant`."""
    option_names: tuple[str, ...] = field(init=False)

    def __post_init__(self) -> None:
        if self.plant_kind not in PLANT_KINDS:
            raise ArgumentError(f"method {self.name!r}: plant_kind {self.plant_kind!r}; expected one of {list(PLANT_KINDS)}")
        object.__setattr__(self, "option_names", tuple(o.name for o in self.options))
        if len(set(self.option_names)) != len(self.option_names):
            raise ArgumentError(f"method {self.name!r} names an option twice: {list(self.option_names)}")

    def option(self, name: str) -> Option:
        for o in self.options:
            if o.name == name:
                return o
        raise ArgumentError(f"method {self.name!r} has no option {name!r}; options: {list(self.option_names)}")


_METHODS: dict[str, Method] = {}
_UNCHECKED: list[str] = []
"""Methods registered while the modules were being discovered: their kind is checked once discovery is done."""


def register(method: Method) -> Method:
    """Make ``method`` known by its name (a module calls this when it is imported).

    Parameters
    ----------
    method : Method
        The method; its ``diagnoser_kind`` must name a registered kind (checked now, or once the modules that
        register the kinds have all been imported).

    Returns
    -------
    Method
        The registered method (its design followed by the account of what the diagnoser can see).

    Raises
    ------
    ArgumentError
        Its name is no identifier, or its diagnoser kind is registered by no module.
    """
    if not method.name.isidentifier():
        raise ArgumentError(f"a method name is an identifier (it names gain files and C symbols); got {method.name!r}")
    if kinds.discovered() and kinds.find_kind(method.diagnoser_kind) is None:
        raise ArgumentError(_unknown_kind(method))
    method = replace(method, design=_accounted(method.design))
    _METHODS[method.name] = method
    if not kinds.discovered():
        _UNCHECKED.append(method.name)
    return method


def _unknown_kind(method: Method) -> str:
    return (
        f"method {method.name!r} names diagnoser kind {method.diagnoser_kind!r}, which no module registers; known kinds: "
        f"{kinds.kind_names()}: register it with fdisyn.synthesis.kinds.register_kind, or name a known kind"
    )


def _accounted(design: Callable[..., GainFile]) -> Callable[..., GainFile]:
    """``design`` followed by the account of what its diagnoser can see (:func:`fdisyn.synthesis.account.with_account`,
    from the plant it was given: its component faults and units), stored in the gain file's ``account`` block.
    Every way of designing through a method (``fdisyn.design``, plant files, the problems) goes through here."""
    if getattr(design, "accounted", False):
        return design

    def run(plant: Any, **options: Any) -> GainFile:
        from fdisyn.synthesis.account import with_account

        with _default_budget_named(isinstance(options.get("arl0"), _DefaultArl0)):
            gf = design(plant, **options)
        return with_account(gf, plant)

    run.accounted = True  # type: ignore[attr-defined]
    run.__wrapped__ = design  # type: ignore[attr-defined]
    run.__doc__ = design.__doc__
    return run


def _discover() -> None:
    """Import every module that registers kinds and methods (:func:`fdisyn.synthesis.kinds.discover`), then check
    the kind of each method registered meanwhile (an unregistered one: :class:`ArgumentError`, and it is dropped)."""
    kinds.discover()
    while _UNCHECKED and kinds.discovered():
        method = _METHODS.get(_UNCHECKED.pop(0))
        if method is not None and kinds.find_kind(method.diagnoser_kind) is None:
            del _METHODS[method.name]
            raise ArgumentError(_unknown_kind(method))


def all_methods() -> list[Method]:
    """Every registered method, by name."""
    _discover()
    return [_METHODS[k] for k in sorted(_METHODS)]


def method_names() -> list[str]:
    """The names of the registered methods."""
    return [m.name for m in all_methods()]


def get_method(name: str) -> Method:
    """The method ``name``; an unknown one is an :class:`ArgumentError` listing the known ones."""
    _discover()
    if not isinstance(name, str) or name not in _METHODS:
        raise ArgumentError(f"no design method {shown(name)}; methods: {sorted(_METHODS)}")
    return _METHODS[name]


def check_plant(method: Method, plant: Any) -> None:
    """``plant`` is of the kind ``method`` designs for (an :class:`ArgumentError` otherwise)."""
    from fdisyn.models.linear import LinearPlant

    kind = method.plant_kind
    if kind == "nonlinear":
        from fdisyn.models.nonlinear import NonlinearPlant

        ok = isinstance(plant, NonlinearPlant)
    else:
        ok = isinstance(plant, LinearPlant) and (kind == "linear" or not plant.is_discrete)
    if not ok:
        got = type(plant).__name__
        if isinstance(plant, LinearPlant):
            got = f"a {'discrete' if plant.is_discrete else 'continuous'} LinearPlant"
        raise ArgumentError(f"method {method.name!r} designs for {PLANT_KINDS[kind]}; got {got}")
    if isinstance(plant, LinearPlant) and not method.feedthrough:
        reach = [k for k in ("Dd", "Df") if np.any(getattr(plant, k) != 0)]
        if reach:
            able = [m.name for m in all_methods() if m.feedthrough]
            raise ArgumentError(
                f"method {method.name!r} assumes unknown inputs and component faults reach the sensors only through the "
                f"states, but the plant's {' and '.join(reach)} {'are' if len(reach) > 1 else 'is'} nonzero: design it by "
                f"method {' or '.join(repr(a) for a in able)}"
            )


def check_options(method: Method, options: Mapping[str, Any], *, plant: Any = None, where: str | None = None) -> dict[str, Any]:
    """Every option of ``method``: the given ones validated, the others at their defaults.

    An unknown option, or one of another method, is an :class:`ArgumentError`
    listing the allowed ones; so is a missing required one.
    """
    where = f"method {method.name!r}" if where is None else where
    unknown = [k for k in options if k not in method.option_names]
    if unknown:
        owners = [m.name for m in all_methods() if unknown[0] in m.option_names]
        if owners and len(unknown) == 1:
            readers = f"only by method {owners[0]!r}" if len(owners) == 1 else f"by methods {', '.join(map(repr, owners))}"
            raise ArgumentError(f"{at(where, unknown[0])} is read {readers}, not by {method.name!r}: remove it")
        raise ArgumentError(f"{where}: unknown option(s) {sorted(unknown)}; allowed: {sorted(method.option_names)}")
    out: dict[str, Any] = {}
    for o in method.options:
        if o.name in options:
            out[o.name] = o.validate(options[o.name], where, plant)
        elif o.required:
            word = "key" if where.endswith("]") else "option"
            raise ArgumentError(f"{where}: missing {word} {o.name!r}: expected {o.expected}")
        else:
            out[o.name] = o.default
    defaulted = _budget(method, out, where)
    if method.check is not None:
        # the default budget is checked by the design itself, after the plant (a sample time that cannot be sampled
        # is named first, and a default that leaves too few samples is refused saying that it is the default)
        method.check(plant, {**out, "arl0": None, "P_f": 0.5} if defaulted else out, where)
    return out


class _DefaultArl0(float):
    """:data:`DEFAULT_ARL0` as :func:`check_options` hands it to a design: a float that marks the budget as the
    default, so that a refusal of it says so (:func:`_default_budget_named`)."""


def _budget(method: Method, out: dict[str, Any], where: str) -> bool:
    """Resolve the false-alarm budget of a method that takes both ``P_f`` and ``arl0`` (in place in ``out``).

    ``arl0`` alone, or ``P_f`` alone (the per-sample choice), is used as given; neither gives ``arl0`` =
    :data:`DEFAULT_ARL0`; both are refused (they set the same thresholds). Returns whether the default applied.

    Raises
    ------
    ArgumentError
        Both ``P_f`` and ``arl0`` are given.
    """
    if "P_f" not in method.option_names or "arl0" not in method.option_names:
        return False
    if out["P_f"] is not None and out["arl0"] is not None:
        raise ArgumentError(
            f"{where}: P_f = {shown(out['P_f'])} and arl0 = {shown(out['arl0'])} s both set the false-alarm budget; give one: "
            "arl0, the diagnoser's mean time between false alarms (s), or P_f, the rate per statistic and sample"
        )
    if out["P_f"] is None and out["arl0"] is None:
        out["arl0"] = _DefaultArl0(DEFAULT_ARL0)
        return True
    return False


@contextmanager
def _default_budget_named(defaulted: bool) -> Iterator[None]:
    """A refusal of the default ``arl0`` (a plant whose sample time leaves too few samples in an hour) says that
    it is the default and what to give instead, in the same line."""
    try:
        yield
    except ArgumentError as exc:
        if not defaulted or "arl0" not in str(exc):
            raise
        raise ArgumentError(
            f"{exc} (arl0 = {DEFAULT_ARL0:g} s is the default false-alarm budget, no P_f or arl0 was given: give an arl0 "
            "that fits, or P_f)"
        ) from None


def _jsonable(value: Any) -> Any:
    try:
        json.dumps(value)
        return value
    except (TypeError, ValueError):
        tolist = getattr(value, "tolist", None)
        return tolist() if callable(tolist) else repr(value)


def design(
    plant: Any,
    method: str,
    *,
    name: str | None = None,
    problem: str | None = None,
    record: Mapping[str, Any] | None = None,
    where: str | None = None,
    **options: Any,
) -> GainFile:
    """Design ``plant`` by ``method`` with ``options``: a certified gain file.

    The plant's kind and the options are checked against the method's schema
    first (unknown or invalid: :class:`ArgumentError`). ``name`` names the gain
    file (default: the method's name), ``problem`` its problem (default:
    ``name``); ``record`` replaces the design options stored in its provenance
    (default: the method and the options given); ``where`` prefixes error
    messages (a plant file's ``PATH [design]``).
    """
    m = get_method(method)
    check_plant(m, plant)
    checked = check_options(m, options, plant=plant, where=where)
    if record is None:
        record = {"method": m.name, **{k: _jsonable(v) for k, v in options.items()}}
    return m.design(plant, name=name or m.name, problem=problem, record=record, where=where or f"method {m.name!r}", **checked)


# --------------------------------------------------------------------------- options several methods and problems share

DEFAULT_ARL0 = 3600.0
"""The false-alarm budget when neither ``P_f`` nor ``arl0`` is given: one false alarm of the whole diagnoser per hour
of operation (s). A per-sample rate is no budget an operator can judge — ``P_f = 1e-3`` at 1 kHz is a false alarm
every second — so the default is a time. An hour keeps the alarms of one diagnoser a small part of an operator's load
(a control room copes with about one alarm of any kind per ten minutes), is still checked by a Monte Carlo of a few
hours of fault-free data, and costs little detection: a threshold grows with the logarithm of the budget (a χ²
threshold by about 2·ln 24 ≈ 6.4 from an hour to a day)."""

P_F = Option(
    "P_f",
    None,
    "false-alarm probability per statistic and sample, given instead of arl0 (the per-sample choice; sets the "
    "thresholds; default: none, the budget is arl0)",
    "a false-alarm probability per statistic and sample: a number in (0, 1)",
    lambda v: is_real(v) and 0.0 < v < 1.0,
)
PERSISTENCE = Option(
    "persistence",
    1,
    "consecutive exceedances before a statistic alarms",
    f"a whole number ≥ 1 of consecutive exceedances, at most {LIMITS['persistence']}",
    lambda v: is_count(v) and v <= LIMITS["persistence"],  # a count in a double; the gain file's limit
)
DETECTOR = Option(
    "detector",
    None,
    f"the statistic of each generator: {option_texts()['detector']} (default: evaluator's value)",
    option_texts()["kinds"],
    lambda v: v in DETECTORS,  # read live: a registered detector is accepted
)
ARL0 = Option(
    "arl0",
    None,
    "the diagnoser's mean time between false alarms (s): sets every threshold from its statistic's law (default: "
    f"{DEFAULT_ARL0:g} s, one hour, unless P_f is given; give one of arl0 and P_f)",
    "a positive number of seconds (each statistic's share at most 1e300 samples: the thresholds' working domain)",
    lambda v: is_real(v) and v > 0,
)
WINDOW = Option("window", 10, "WSSR window N in samples (Zhou, Xi & Zhang c. 1991, eq. (2.4))", "a whole number of samples ≥ 1", is_count)

SHARED_OPTIONS: Mapping[str, Option] = {o.name: o for o in (P_F, PERSISTENCE, WINDOW, DETECTOR, ARL0)}
"""Options several methods and problems share, with their domains (a problem's own
default may differ: :func:`check_option` keeps the domain)."""


def check_option(key: str, value: Any, default: Any, where: str) -> Any:
    """Validate a problem's option ``key``: by :data:`SHARED_OPTIONS` when it is one of
    them, else by the type of its ``default`` (ints accepted for floats).

    Raises :class:`ArgumentError` naming ``where``, the value and what is expected.
    """
    if key in SHARED_OPTIONS:
        return SHARED_OPTIONS[key].validate(value, where)
    if isinstance(default, bool):
        kind, ok = "true or false", lambda v: isinstance(v, bool)
    elif isinstance(default, int):
        kind, ok = "a whole number", lambda v: isinstance(v, int) and not isinstance(v, bool)
    elif isinstance(default, float):
        kind, ok = "a finite number", is_real
    elif isinstance(default, str):
        kind, ok = f"a string such as {default!r}", lambda v: isinstance(v, str)
    else:
        return value
    return Option(key, default, "", kind, ok).validate(value, where)
