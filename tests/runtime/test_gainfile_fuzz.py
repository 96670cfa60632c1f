"""Seeded fuzzing of linear gain files: no traceback and no crash, ever.

Mutations of a valid file (the wind-turbine bank): flipped, inserted and
deleted bytes; deleted fields; values swapped for other JSON types;
non-finite, huge and tiny numbers; matrices with a row or column more or
less; hostile strings (C injections, reserved and overlong names, control
characters). Reading each file, and generating C sources from the ones the
reader accepts, must either succeed or raise an :class:`FdisynError` whose
message is one line. A few accepted files go all the way — ``fdisyn
codegen`` and ``fdisyn replay`` — in fresh processes, so that a crash in C
(a signal) would show as a failed test rather than kill the run.
"""

from __future__ import annotations

import copy
import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fdisyn.codegen.library import generate_sources
from fdisyn.runtime.errors import FdisynError
from fdisyn.runtime.gainfile import read_gain_file
from fdisyn.runtime.trace import Trace, write_trace

MUTATIONS = 240
"""Mutated files per run: about 10 s of reading and C generation on a 2-core machine."""
END_TO_END = 2
"""Accepted files compiled and replayed in subprocesses (a few seconds of gcc each)."""

HOSTILE_STRINGS = (
    'x", 0}; __attribute__((constructor)) static void pwn(void){} static const char *y[] = {"',
    "*/ __attribute__((constructor)) static void pwn(void){} /*",
    "",
    "t",
    "fault_active",
    "a" * 5000,
    "ünïcödé",
    "nul\x00byte",
    "new\nline",
    "@NU@",
    "??/",
    "../../x",
    "-o/tmp/x",
    "casadi_f0",
    "replay",
    "x__y",
)
ODD_VALUES: tuple[Any, ...] = (None, True, False, 0, -1, 2**70, 10**400, 1e308, -1e308, 5e-324, -0.0, "1.5", [], {}, [[1.0]], [None], {"a": 1})
NON_FINITE_TEXT = ("NaN", "Infinity", "-Infinity", "1e999", "-1e999")


def _paths(node: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Every path (keys and indices) into a JSON document."""
    out = [prefix]
    if isinstance(node, dict):
        for k, v in node.items():
            out += _paths(v, (*prefix, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out += _paths(v, (*prefix, i))
    return out


def _parent(doc: Any, path: tuple[Any, ...]) -> Any:
    for key in path[:-1]:
        doc = doc[key]
    return doc


def _informational(path: tuple[Any, ...]) -> bool:
    """Free-form parts (provenance, certificate details, a generator's method matrices) that nothing reads."""
    return path[0] == "provenance" or (path[0] == "certificate" and path[1:2] != ("passed",)) or (path[0] == "generators" and path[2:3] == ("method",))


def _pick(rng: np.random.Generator, doc: Any, want: Callable[[Any], bool]) -> tuple[Any, ...] | None:
    """A random path to a value ``want`` accepts; nine times in ten one the reader validates."""
    informational = rng.random() < 0.1
    paths = [p for p in _paths(doc) if p and _informational(p) == informational and want(_parent(doc, p)[p[-1]])]
    return paths[int(rng.integers(len(paths)))] if paths else None


def _mutate(rng: np.random.Generator, base: dict[str, Any], text: str) -> str:
    """One seeded mutation of the document (or of its text)."""
    kind = int(rng.integers(7))
    doc = copy.deepcopy(base)
    if kind == 0:  # bytes flipped, inserted or deleted in the JSON text
        data = bytearray(text.encode("utf-8"))
        for _ in range(int(rng.integers(1, 4))):
            i = int(rng.integers(len(data)))
            op = int(rng.integers(3))
            if op == 0:
                data[i] ^= 1 << int(rng.integers(8))
            elif op == 1:
                data.insert(i, int(rng.choice(list(b'{}[],:"\\0123456789eE.-+ntfx'))))
            else:
                del data[i]
        return data.decode("utf-8", "replace")
    if kind == 1:  # a field or list element deleted
        p = _pick(rng, doc, lambda v: True)
        if p is not None:
            del _parent(doc, p)[p[-1]]
    elif kind == 2:  # a value swapped for another type
        p = _pick(rng, doc, lambda v: True)
        if p is not None:
            _parent(doc, p)[p[-1]] = copy.deepcopy(ODD_VALUES[int(rng.integers(len(ODD_VALUES)))])
    elif kind == 3:  # a number made non-finite (JSON text), huge or tiny
        p = _pick(rng, doc, lambda v: isinstance(v, (int, float)) and not isinstance(v, bool))
        if p is not None:
            marker = "__FUZZ_NUMBER__"
            _parent(doc, p)[p[-1]] = marker
            choices = (*NON_FINITE_TEXT, "1e308", "-1e308", "5e-324", "0", "1" + "0" * 30, "-0.0")
            return json.dumps(doc).replace(f'"{marker}"', choices[int(rng.integers(len(choices)))])
    elif kind == 4:  # a matrix with a row or a column more or less
        p = _pick(rng, doc, lambda v: isinstance(v, list) and bool(v) and all(isinstance(r, list) for r in v))
        if p is not None:
            m = _parent(doc, p)[p[-1]]
            op = int(rng.integers(4))
            if op == 0:
                m.append(list(m[-1]))
            elif op == 1:
                m.pop()
            elif op == 2:
                for row in m:
                    row.append(0.5)
            else:
                for row in m:
                    if row:
                        row.pop()
    elif kind == 5:  # a string replaced by a hostile one
        p = _pick(rng, doc, lambda v: isinstance(v, str))
        if p is not None:
            _parent(doc, p)[p[-1]] = HOSTILE_STRINGS[int(rng.integers(len(HOSTILE_STRINGS)))]
    else:  # a benign-looking number change (a threshold, a probability, a gain): often still a valid file
        p = _pick(rng, doc, lambda v: isinstance(v, float))
        if p is not None:
            _parent(doc, p)[p[-1]] *= float(rng.choice([0.5, 2.0, -1.0, 1.0 + 1e-12]))
    return json.dumps(doc, indent=int(rng.integers(0, 3)))


def _one_line(exc: FdisynError) -> None:
    msg = str(exc)
    assert msg and "\n" not in msg and "Traceback" not in msg, msg


def _end_to_end(directory: Path, trace: Path) -> None:
    """`fdisyn codegen` and `fdisyn replay` in fresh processes: status 0, or 2 with one line; never a signal."""
    for args in (["codegen", str(directory)], ["replay", str(directory), str(trace), str(directory / "out.csv")]):
        proc = subprocess.run([sys.executable, "-m", "fdisyn.app.cli", *args], capture_output=True, text=True, timeout=300)
        assert proc.returncode in (0, 2), (args, proc.returncode, proc.stderr[-2000:])
        if proc.returncode == 2:
            assert proc.stderr.count("\n") == 1, proc.stderr
            return


@pytest.mark.parametrize("seed", [20240611])
def test_mutated_linear_gain_files_never_crash(wt_built, wt_trace, tmp_path, seed):
    text = (wt_built.directory / "gains.json").read_text()
    base = json.loads(text)
    gf0 = wt_built.gain_file
    _, U, Y = wt_trace
    trace = write_trace(Trace(t=np.arange(300) * gf0.Ts, inputs=gf0.inputs, outputs=gf0.outputs, U=U[:300], Y=Y[:300]), tmp_path / "in.csv")
    rng = np.random.default_rng(seed)
    outcomes = {"refused by the reader": 0, "refused by the generator": 0, "generated": 0, "end to end": 0}
    for k in range(MUTATIONS):
        d = tmp_path / f"m{k}"
        d.mkdir()
        (d / "gains.json").write_text(_mutate(rng, base, text), encoding="utf-8")
        try:
            gf = read_gain_file(d / "gains.json")
        except FdisynError as exc:
            _one_line(exc)
            outcomes["refused by the reader"] += 1
            continue
        try:
            generate_sources(gf, d / "c")
        except FdisynError as exc:
            _one_line(exc)
            outcomes["refused by the generator"] += 1
            continue
        outcomes["generated"] += 1
        if outcomes["end to end"] < END_TO_END:
            _end_to_end(d, trace)
            outcomes["end to end"] += 1
    # the mutations reach every stage: most files are refused, some are accepted and built
    assert outcomes["refused by the reader"] > MUTATIONS // 2, outcomes
    assert outcomes["generated"] >= END_TO_END and outcomes["end to end"] == END_TO_END, outcomes
