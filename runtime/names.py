"""The names of fdisyn: one grammar for signals, faults, diagnosers and labels.

Names travel far from where they are typed. A signal name is a column of the
trace CSV that ``fdisyn simulate`` writes and ``replay`` reads, a key of a
nonlinear plant's expressions and a C string literal (``<name>_input_names``);
a fault name is a C string literal; the diagnoser's name prefixes every C
symbol, macro and generated file name. So every name is checked where it
enters — the plant-file reader, :class:`~fdisyn.models.linear.LinearPlant` and
:class:`~fdisyn.models.nonlinear.NonlinearPlant`, the gain-file reader — by the functions below, and
the C generator escapes every string it writes all the same.

Grammar (``NAME`` below is ``[A-Za-z][A-Za-z0-9_]*``):

signal name
    states, inputs, unknown inputs, outputs, component faults, parameters:
    ``NAME`` of at most :data:`SIGNAL_NAME_MAX` (63) characters, not one of
    :data:`RESERVED_SIGNAL_NAMES`. ASCII letters, digits and ``_`` only: a
    CSV column needs no quoting (no comma, quote or blank, which the replay
    reader would split or strip), a C string literal no escape, and the name
    is a C identifier should generated code ever use it as one. A leading
    letter because identifiers starting with ``_`` are partly reserved to the
    C implementation and a leading digit would not be an identifier. 63
    characters is C99's guaranteed number of significant characters of an
    internal identifier or macro name (§5.2.4.1).
fault name
    signal names joined by ``+`` (a combination of faults, e.g. two sensors
    at once) or ``|`` (classes the bank cannot tell apart), at most
    :data:`FAULT_NAME_MAX` (1024) characters — far below C99's 4095-character
    minimum limit for a string literal.
diagnoser name
    ``NAME`` of at most :data:`DIAGNOSER_NAME_MAX` (64) characters with no
    ``__`` and no trailing ``_``: it prefixes C symbols (``<name>_step``,
    ``<NAME>_NU``, CasADi's ``<name>_casadi_step_sparsity_out``); ``__``
    anywhere in an identifier is reserved to C++ implementations, and a
    trailing ``_`` would form ``__`` with the suffixes. 64 characters keep the
    file names it forms (``lib<name>.so``, ``<name>_casadi.c``) far below the
    255-byte file-name limit of common file systems and every symbol under 100
    characters (gcc and clang keep all of them significant; C99 promises
    only 63, which no prefix plus suffix scheme can meet). Reserved:
    ``replay`` and ``bench`` (the programs ``DIR/c/tools/replay.c`` and
    ``bench.c`` include ``<name>.h``: a build of both that puts the tools on
    its include path would find two files of one name) and names starting with ``casadi`` in
    any case (CasADi's generated code owns ``casadi_*`` and ``CASADI_*``).
label
    problem, design, generator, residual and statistic names: a letter or
    digit, then letters, digits and ``_ . + | -``; ``problem`` and ``design``
    at most :data:`SHORT_LABEL_MAX` (64) characters, the others at most
    :data:`LABEL_MAX` (4096; a generator of a bank may be named after all
    the sensors it reads). Labels never become C code; ``problem`` and
    ``design`` appear in a C comment.

Names that share a namespace must be distinct across it, checked by
:func:`check_distinct` (e.g. the states, inputs, unknown inputs, outputs and
component faults of a linear plant are all columns of one trace CSV).
"""

from __future__ import annotations

import re
import reprlib
import unicodedata
from collections.abc import Mapping, Sequence

from fdisyn.runtime.errors import ArgumentError, FdisynError

__all__ = [
    "SIGNAL_NAME_MAX",
    "FAULT_NAME_MAX",
    "DIAGNOSER_NAME_MAX",
    "SHORT_LABEL_MAX",
    "LABEL_MAX",
    "RESERVED_SIGNAL_NAMES",
    "RESERVED_DIAGNOSER_NAMES",
    "check_signal_name",
    "check_signal_names",
    "check_fault_name",
    "check_diagnoser_name",
    "check_label",
    "check_text",
    "check_signal_texts",
    "check_distinct",
    "shown",
]

SIGNAL_NAME_MAX = 63
FAULT_NAME_MAX = 1024
DIAGNOSER_NAME_MAX = 64
SHORT_LABEL_MAX = 64
LABEL_MAX = 4096

RESERVED_SIGNAL_NAMES: Mapping[str, str] = {
    "t": "the time column of every trace CSV",
    "fault_active": "the column of `fdisyn simulate` that marks where the scenario's fault is active",
}
"""Names a signal may not take, with the column they would collide with."""

RESERVED_DIAGNOSER_NAMES: Mapping[str, str] = {
    "replay": "its library <name>.c would share its name with the replay program's tools/replay.c",
    "bench": "its library <name>.c would share its name with the benchmark's tools/bench.c",
}

_TOKEN = r"[A-Za-z][A-Za-z0-9_]*"
_SIGNAL = re.compile(rf"{_TOKEN}\Z")
_FAULT = re.compile(rf"{_TOKEN}(?:[+|]{_TOKEN})*\Z")
_LABEL = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.+|\-]*\Z")

Error = type[FdisynError]


_REPR = reprlib.Repr()
_REPR.maxlevel = 3
_REPR.maxtuple = _REPR.maxlist = _REPR.maxarray = _REPR.maxdict = _REPR.maxset = _REPR.maxfrozenset = _REPR.maxdeque = 8
_REPR.maxstring = _REPR.maxlong = _REPR.maxother = 1 << 16
_LINE_BREAKS = re.compile(r"\s*\n\s*")


def shown(value: object, limit: int = 80) -> str:
    """``repr(value)`` cut to about ``limit`` characters: every error message quotes a value this way.

    A message stays one short line whatever a file or a caller holds: a string
    is shown whole up to ``limit`` characters, then cut with its length; a
    container is shown to a depth of 3 and 8 items per level (``reprlib``), so
    a deeply nested or huge value costs no more than a short one (``repr`` of
    a deeply nested list would recurse), then cut. Line breaks (NumPy's repr
    of an array has them) become blanks. An integer too long for Python's
    text conversion is shown by its size.
    """
    try:
        text = _REPR.repr(value)
    except ValueError:  # more digits than int → str converts (sys.get_int_max_str_digits)
        text = f"<an integer of {value.bit_length()} bits>" if isinstance(value, int) else f"<a {type(value).__name__}>"
    text = _LINE_BREAKS.sub(" ", text)  # NumPy's repr of an array breaks lines
    if len(text) <= limit:
        return text
    return f"{text[:limit]}… ({len(text)} characters)" if isinstance(value, str) else f"{text[:limit]}…"


def _string(name: object, what: str, error: Error) -> str:
    if not isinstance(name, str):
        raise error(f"{what} must be a string, found {type(name).__name__} {shown(name)}")
    return name


def _folded(s: str) -> str:
    """What a non-ASCII name would read as if folded (Unicode NFKC, as Python folds identifiers): a hint for the message.

    Names are compared exactly and are ASCII; a fullwidth ``ｘ`` is never the name ``x``."""
    if s.isascii():
        return ""
    folded = unicodedata.normalize("NFKC", s)
    if folded != s and folded.isascii():
        return f" (it holds non-ASCII characters: it reads as {folded!r} only after Unicode NFKC normalisation, and names are compared exactly)"
    return " (it holds non-ASCII characters)"


def check_signal_name(name: object, what: str, *, error: Error = ArgumentError) -> str:
    """``name`` if it is a signal name (see the module docstring), else ``error`` naming ``what``."""
    s = _string(name, what, error)
    if not _SIGNAL.match(s) or len(s) > SIGNAL_NAME_MAX:
        raise error(
            f"{what} {shown(s)} is not a signal name{_folded(s)}: expected a letter, then letters, digits or '_', "
            f"at most {SIGNAL_NAME_MAX} characters"
        )
    if s in RESERVED_SIGNAL_NAMES:
        raise error(f"{what} {s!r} is reserved ({RESERVED_SIGNAL_NAMES[s]}); choose another name")
    return s


def check_signal_names(names: object, what: str, *, error: Error = ArgumentError, count: int | None = None) -> tuple[str, ...]:
    """A list of distinct signal names (``count`` of them when given); ``what`` names the list."""
    if isinstance(names, (str, bytes)) or not isinstance(names, Sequence):
        raise error(f"{what} must be a list of names, found {type(names).__name__} {shown(names)}")
    if count is not None and len(names) != count:
        raise error(f"{what}: expected {count} names to match the matrices, found {len(names)}: {shown(list(names))}")
    out = tuple(check_signal_name(nm, f"{what}[{i}]", error=error) for i, nm in enumerate(names))
    repeated = sorted({nm for nm in out if out.count(nm) > 1})
    if repeated:
        raise error(f"{what} must be unique; repeated: {repeated}")
    return out


def check_fault_name(name: object, what: str, *, error: Error = ArgumentError) -> str:
    """``name`` if it is a fault name: signal names joined by ``+`` or ``|``."""
    s = _string(name, what, error)
    if not _FAULT.match(s) or len(s) > FAULT_NAME_MAX:
        raise error(
            f"{what} {shown(s)} is not a fault name{_folded(s)}: expected names (a letter, then letters, digits or '_') "
            f"joined by '+' or '|', at most {FAULT_NAME_MAX} characters"
        )
    return s


def check_diagnoser_name(name: object, what: str, *, error: Error = ArgumentError) -> str:
    """``name`` if it may prefix the generated C API (see the module docstring), else ``error``."""
    s = _string(name, what, error)
    if not _SIGNAL.match(s) or "__" in s or s.endswith("_") or len(s) > DIAGNOSER_NAME_MAX:
        raise error(
            f"{what} {shown(s)} cannot prefix the generated C API{_folded(s)}: expected a C identifier that starts with a letter, "
            f"has no '__' and no trailing '_', at most {DIAGNOSER_NAME_MAX} characters"
        )
    if s in RESERVED_DIAGNOSER_NAMES:
        raise error(f"{what} {s!r} is reserved: {RESERVED_DIAGNOSER_NAMES[s]}")
    if s.lower().startswith("casadi"):
        raise error(f"{what} {s!r} is reserved: CasADi's generated code owns the names starting with 'casadi'")
    return s


def check_label(name: object, what: str, *, max_length: int = LABEL_MAX, error: Error = ArgumentError) -> str:
    """``name`` if it is a label: a letter or digit, then letters, digits or ``_ . + | -``."""
    s = _string(name, what, error)
    if not _LABEL.match(s) or len(s) > max_length:
        raise error(
            f"{what} {shown(s)} is not a label{_folded(s)}: expected a letter or digit, then letters, digits or '_', '.', '+', '|', '-', "
            f"at most {max_length} characters"
        )
    return s


def check_text(value: object, what: str, *, max_length: int, error: Error = ArgumentError) -> str:
    """``value`` if it is short text: one line of 1 to ``max_length`` printable characters, no blank at either end.

    The readable texts of signals (a unit such as ``"rad/s"`` or ``"N·m"``, a label such as ``"rotor speed"``)
    are data that reach pages, terminals and gain files but never C or a CSV header: any printable Unicode is
    accepted (``str.isprintable``: no control character, line or paragraph separator, or invisible formatting
    character such as a bidirectional override), so the text shows as one line wherever it is printed.
    """
    s = _string(value, what, error)
    if not s or len(s) > max_length or not s.isprintable() or s != s.strip():
        raise error(
            f"{what} {shown(s)} is not short text: expected 1 to {max_length} printable characters on one line, "
            "without blanks at either end"
        )
    return s


def check_signal_texts(
    texts: object, what: str, signals: Sequence[str], *, max_length: int, owner: str = "the plant", error: Error = ArgumentError
) -> dict[str, str]:
    """A table signal name → text (:func:`check_text`) whose every key is one of ``signals`` (those of ``owner``);
    ``what`` names the table.

    Returns a plain ``dict`` in the table's order; refuses a key that is not one of ``signals`` naming the key and the
    signals there are.
    """
    if not isinstance(texts, Mapping):
        raise error(f"{what} must be a table of text by signal name, found {type(texts).__name__} {shown(texts)}")
    known = set(signals)
    out: dict[str, str] = {}
    for key, value in texts.items():
        _string(key, f"a key of {what}", error)
        if key not in known:
            raise error(
                f"{what} names {shown(key)}, which is not a signal of {owner}; expected keys among {shown(list(signals), 200)}"
            )
        out[key] = check_text(value, f"{what}[{key!r}]", max_length=max_length, error=error)
    return out


def check_distinct(groups: Mapping[str, Sequence[str]], *, why: str, error: Error = ArgumentError) -> None:
    """Refuse a name used by two of ``groups`` (plural label → names), naming both and ``why`` they must differ.

    Uniqueness within a group is :func:`check_signal_names`' job.
    """
    seen: dict[str, str] = {}
    for label, names in groups.items():
        for nm in names:
            if nm in seen and seen[nm] != label:
                raise error(
                    f"the name {nm!r} is used by the {seen[nm]} and by the {label}; names must be distinct across "
                    f"the {', '.join(groups)} ({why})"
                )
            seen.setdefault(nm, label)
