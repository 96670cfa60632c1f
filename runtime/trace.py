"""Trace CSV files: what ``simulate`` writes and ``replay`` reads.

Input trace: a header row; a column ``t``; one column per input and output,
named as in the gain file; other columns are ignored (``simulate`` adds the
true fault and the unknown inputs for reference). Fields are parsed exactly as
the C replay program parses them: surrounding blanks and double quotes are
stripped; an empty or unparsable field is NaN (the diagnoser skips it).

Replay output: ``t, alarm, isolated, J0…, r0…`` with every number printed as
``%.17g``, so that the Python and C replays write identical bytes.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from fdisyn.runtime.errors import TraceError
from fdisyn.runtime.reference import RunResult

__all__ = ["Trace", "read_trace", "write_trace", "parse_field", "write_replay_csv"]


@dataclass(frozen=True, eq=False)
class Trace:
    """Time, inputs and outputs of one run (rows are samples)."""

    t: np.ndarray
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    U: np.ndarray
    Y: np.ndarray
    extra: Mapping[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        # one CSV header holds every name: a repeated one would make a reader take one column for another
        cols = ["t", *self.inputs, *self.outputs, *self.extra]
        repeated = sorted({c for c in cols if cols.count(c) > 1})
        if repeated:
            raise TraceError(f"trace columns t, inputs, outputs and extras must have distinct names; repeated: {repeated}")
        n = self.t.shape[0]
        if self.U.shape != (n, len(self.inputs)) or self.Y.shape != (n, len(self.outputs)):
            raise TraceError(
                f"trace arrays: t has {n} samples, U is {self.U.shape} for {len(self.inputs)} inputs, "
                f"Y is {self.Y.shape} for {len(self.outputs)} outputs"
            )


_C_SPACE = " \t\n\v\f\r"


def parse_field(text: str) -> float:
    """One CSV field exactly as the C replay program reads it.

    Blanks around the field and one pair of double quotes are stripped; the
    rest must be a complete C ``strtod`` number (decimal, hexadecimal, ``inf``,
    ``nan``), otherwise the value is NaN — as is an empty field.
    """
    s = text.strip(_C_SPACE)
    if len(s) >= 2 and s[0] == '"' and s[-1] == '"':
        s = s[1:-1]
    # strtod skips leading blanks but a trailing blank is left unconsumed (→ NaN)
    s = s.lstrip(_C_SPACE)
    if not s or s[-1] in _C_SPACE or "_" in s:
        return float("nan")
    try:
        return float(s)
    except ValueError:
        pass
    if not s.lstrip("+-").lower().startswith("0x"):
        return float("nan")
    try:
        return float.fromhex(s)
    except ValueError:
        return float("nan")


def _split_header(line: str) -> list[str]:
    out = []
    for f in line.rstrip("\r\n").split(","):
        s = f.strip(_C_SPACE)
        if len(s) >= 2 and s[0] == '"' and s[-1] == '"':
            s = s[1:-1]
        out.append(s)
    return out


def read_trace(path: str | Path, *, inputs: Sequence[str], outputs: Sequence[str]) -> Trace:
    """Read the columns ``t``, ``inputs`` and ``outputs`` of a trace CSV."""
    p = Path(path)
    try:
        lines = p.read_text(encoding="utf-8").splitlines()
    except FileNotFoundError:
        raise TraceError(f"no trace file at {p}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise TraceError(f"cannot read trace {p}: {exc}") from exc
    if not lines:
        raise TraceError(f"{p} is empty: expected a header row with the columns t, {', '.join([*inputs, *outputs])}")
    header = _split_header(lines[0])
    cols: dict[str, int] = {}
    for name in ("t", *inputs, *outputs):
        if name not in header:
            what = "time" if name == "t" else ("input" if name in inputs else "output")
            raise TraceError(f"{p} has no column {name!r} (the {what} column); its columns are {header}")
        cols[name] = header.index(name)
    rows = []
    for k, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        fields = line.rstrip("\r\n").split(",")
        if len(fields) != len(header):
            raise TraceError(f"{p} row {k} has {len(fields)} fields; the header has {len(header)}")
        rows.append([parse_field(fields[cols[name]]) for name in ("t", *inputs, *outputs)])
    data = np.asarray(rows, dtype=float).reshape(len(rows), 1 + len(inputs) + len(outputs))
    m = len(inputs)
    return Trace(
        t=data[:, 0],
        inputs=tuple(inputs),
        outputs=tuple(outputs),
        U=data[:, 1 : 1 + m],
        Y=data[:, 1 + m :],
    )


def _fmt(x: float) -> str:
    return "%.17g" % x


def write_trace(trace: Trace, path: str | Path) -> Path:
    """Write ``t``, inputs, outputs and the extra columns (``%.17g``)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    names = ["t", *trace.inputs, *trace.outputs, *trace.extra]
    cols = [trace.t, *trace.U.T, *trace.Y.T, *(np.asarray(v, dtype=float) for v in trace.extra.values())]
    with p.open("w", encoding="utf-8", newline="\n") as fh:
        fh.write(",".join(names) + "\n")
        for row in zip(*cols, strict=True):
            fh.write(",".join("" if np.isnan(v) else _fmt(v) for v in row) + "\n")
    return p


def write_replay_csv(path: str | Path, t: np.ndarray, result: RunResult) -> Path:
    """The replay output CSV (same bytes as the C replay program writes)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    r, jj, alarm, iso = result.r, result.J, result.alarm, result.isolated
    head = ["t", "alarm", "isolated", *(f"J{i}" for i in range(jj.shape[1])), *(f"r{i}" for i in range(r.shape[1]))]
    with p.open("w", encoding="utf-8", newline="\n") as fh:
        fh.write(",".join(head) + "\n")
        for k in range(len(t)):
            vals = [_fmt(t[k]), "%d" % alarm[k], "%d" % iso[k], *map(_fmt, jj[k]), *map(_fmt, r[k])]
            fh.write(",".join(vals) + "\n")
    return p
