"""JSON documents fdisyn reads as data: a size-bounded regular file, a strict parser, plain values to write.

Used for gain files (:mod:`fdisyn.runtime.gainfile`), build manifests (:mod:`fdisyn.runtime.compiled`) and the
design side's own data files.
"""

from __future__ import annotations

import json
import math
import os
import stat
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from fdisyn.runtime.errors import FdisynError, GainFileError
from fdisyn.runtime.names import shown

__all__ = ["read_regular_file", "parse_json_data", "to_jsonable"]


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
