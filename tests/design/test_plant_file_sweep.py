"""Every key of the example plant files given a value of the wrong kind: refused in one line naming the key.

A seeded, deterministic sweep: each value of ``fdisyn example dc_motor``, ``sampled_data``, ``beard_textbook`` and
``ship`` is replaced by a list, a table, a boolean, NaN, ±inf, numbers written as text (``"1_0"``, ``"1"``, digits
of other scripts), a fullwidth name, and each key by its fullwidth twin and by an unknown key. A value of another
kind than the key's (a number where text is read, text or a boolean where a number is) and a non-finite number are
refused: the plant file is read (and, for the nonlinear plant whose method options are checked when it is designed,
designed) and must end in one :class:`~fdisyn.runtime.errors.SpecError` line naming the key. A replacement of the
same kind (text for text) may be accepted, but never with a raw exception.
"""

from __future__ import annotations

import copy
import math
import tomllib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fdisyn.app.examples import example_names, example_path
from fdisyn.simulation.plant_file import problem_from_document
from fdisyn.runtime.errors import FdisynError, SpecError

EXAMPLES = ("dc_motor", "sampled_data", "beard_textbook", "ship")
FIXED: dict[str, Any] = {
    "list": [1, 2, 3, 4, 5, 6, 7],
    "table": {"a": 1},
    "bool": True,
    "nan": math.nan,
    "inf": math.inf,
    "-inf": -math.inf,
    "underscore": "1_0",
    "text digit": "1",
    "fullwidth digit": "１",
    "fullwidth name": "ｘ",
}
MEANINGFUL: dict[tuple[str, tuple[Any, ...]], float] = {
    ("ship", ("design", "theta_lower")): -math.inf,  # no lower bound (the default)
    ("ship", ("design", "theta_upper")): math.inf,  # no upper bound (the default)
    ("ship", ("design", "isolable_jump")): math.inf,  # no information bound for the parameter (the default)
}
"""Infinities a key documents as meaningful (they are honoured): the key, and the same for its per-parameter entries."""
POOL: tuple[Any, ...] = ("٣", "੧", "𝟏", "1e3", "0x10", "½", "inf", "nan", " 1", "1.5", "-1_000.5", "٫", [], {}, [[1.0]], False)
"""Values drawn (seeded) for every key besides :data:`FIXED`: digits of other scripts, numbers as text, empty containers."""


def _kind(v: Any) -> str:
    if isinstance(v, bool):
        return "bool"
    if isinstance(v, (int, float)):
        return "number"
    return {str: "text", list: "list", dict: "table"}.get(type(v), type(v).__name__)


def _leaves(doc: Any, path: tuple[Any, ...] = ()) -> Iterator[tuple[tuple[Any, ...], Any]]:
    """Every value (and every table and list) with its path; of a list of numbers, its first entry."""
    items = doc.items() if isinstance(doc, dict) else enumerate(doc) if isinstance(doc, list) else ()
    for k, v in items:
        if isinstance(k, int) and k > 0 and not isinstance(v, (dict, list)):
            continue
        yield (*path, k), v
        yield from _leaves(v, (*path, k))


def _set(doc: Any, path: tuple[Any, ...], value: Any) -> None:
    for k in path[:-1]:
        doc = doc[k]
    doc[path[-1]] = value


def _fullwidth(s: str) -> str:
    return "".join(chr(ord(c) + 0xFEE0) if c.isascii() and c.isalnum() else c for c in s)


def _cases() -> Iterator[tuple[str, str, tuple[Any, ...], Any, bool]]:
    """``(example, label, path, value or None, must_refuse)``; ``value is None``: rename the key (fullwidth)."""
    rng = np.random.default_rng(20240624)
    for name in EXAMPLES:
        doc = tomllib.loads(example_path(name).read_text(encoding="utf-8"))
        for path, orig in _leaves(doc):
            drawn = [POOL[i] for i in rng.choice(len(POOL), size=3, replace=False)]
            for label, bad in [*FIXED.items(), *((f"drawn {v!r}", v) for v in drawn)]:
                same = _kind(bad) == _kind(orig)
                if same and _kind(bad) != "number" and not isinstance(orig, str):
                    continue  # a list for a list, a table for a table: the shape checks' business
                non_finite = isinstance(bad, float) and not math.isfinite(bad)
                if non_finite and any(MEANINGFUL.get((name, path[:k])) == bad for k in range(1, len(path) + 1)):
                    yield name, label, path, bad, False  # a single number stands for every parameter
                    continue
                yield name, label, path, bad, (not same) or non_finite
            if isinstance(path[-1], str):
                yield name, "fullwidth key", path, None, True
        for path, orig in [((), doc), *((p, v) for p, v in _leaves(doc) if isinstance(v, dict))]:
            yield name, "unknown key", (*path, "bogus_key"), 1, True


CASES = list(_cases())


def test_the_sweep_covers_every_example() -> None:
    assert set(EXAMPLES) == set(example_names())
    assert len(CASES) > 1000


def _named(path: tuple[Any, ...]) -> str:
    """The key a message must name: the innermost key of the path."""
    return next(str(k) for k in reversed(path) if isinstance(k, str))


@pytest.mark.parametrize("example", EXAMPLES)
def test_every_key_refuses_a_value_of_another_kind_in_one_line(example: str, tmp_path: Path) -> None:
    doc = tomllib.loads(example_path(example).read_text(encoding="utf-8"))
    spec = tmp_path / f"{example}.toml"
    wrong = []
    for name, label, path, bad, must_refuse in CASES:
        if name != example:
            continue
        d = copy.deepcopy(doc)
        if bad is None:  # the key renamed to its fullwidth twin
            parent = d
            for k in path[:-1]:
                parent = parent[k]
            parent[_fullwidth(path[-1])] = parent.pop(path[-1])
        elif path[-1] == "bogus_key":
            parent = d
            for k in path[:-1]:
                parent = parent[k]
            parent["bogus_key"] = 1
        else:
            _set(d, path, copy.deepcopy(bad))
        try:
            problem = problem_from_document(d, spec)
            if must_refuse and path[:1] == ("design",) and example == "ship":
                problem.design()  # the NAFDF checks its options when it designs (a refusal comes before any work)
        except SpecError as exc:
            msg = str(exc)
            if "\n" in msg or (must_refuse and bad is not None and path[-1] != "bogus_key" and _named(path) not in msg):
                wrong.append(f"{label} at {path}: {msg!r}")
            continue
        except FdisynError as exc:
            wrong.append(f"{label} at {path}: {type(exc).__name__} (expected SpecError) {exc}")
            continue
        except Exception as exc:  # noqa: BLE001 - collected, then reported together
            wrong.append(f"{label} at {path}: raw {type(exc).__name__}: {exc}")
            continue
        if must_refuse:
            wrong.append(f"{label} at {path}: accepted")
    assert not wrong, "\n".join(wrong)
