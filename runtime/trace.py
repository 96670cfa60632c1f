"""Trace CSV files: what ``simulate`` writes and both replays read.

Input trace: a header row; a column ``t``; one column per input and output,
named as in the gain file; other columns are ignored (``simulate`` adds the
true fault and the unknown inputs for reference).

Both replays — ``fdisyn replay`` (this module) and the generated C program
``DIR/replay`` (``runtime/c/replay.c.in``) — read one grammar, written down in
``runtime/REFERENCE.md`` ("Replay CSV grammar") and implemented here and there step by step
in the same order, so that a file is either read identically by both or
refused by both with the same message:

1. physical lines end at LF; the CR of a CRLF is dropped; a line holds at
   most :data:`MAX_LINE_BYTES` bytes (line break excluded); the file may open
   with a UTF-8 byte-order mark, which is skipped;
2. every line is UTF-8 without control characters (C0 except tab, DEL, C1 —
   among them U+0085 —, U+2028, U+2029) and without a lone CR: these are line
   breaks for some readers and not for others, so they are refused rather
   than guessed at;
3. records are RFC 4180 fields separated by commas; blanks (space, tab)
   around a field are not part of it; a quoted field may hold commas and
   ``""`` for a quote but no line break; at most :data:`MAX_COLUMNS` fields;
4. lines holding only blanks are skipped; every other record has as many
   fields as the header;
5. the header names ``t``, every input and every output exactly once (exact
   byte match after unquoting; header names at most :data:`MAX_NAME_BYTES`);
6. the fields read are numerals of an ASCII grammar (``[+-]`` decimal with
   optional exponent, or ``inf``/``infinity``/``nan`` in any case), converted
   with correct rounding (magnitudes beyond the double range become ±inf, as
   IEEE 754 rounding does); an empty field is NaN: the diagnoser skips that
   sample and counts it. Anything else — hexadecimal, ``1_000``, non-ASCII
   digits — is refused, never replaced.

Replay output: ``t, alarm, isolated, J0…, r0…`` with every number printed as
``%.17g`` (NaN as ``nan`` whatever its sign bit), so both replays write
identical bytes. The output is written to a temporary file next to it and
renamed at the end: on any error the output path is neither created nor
changed.

Errors in the data raise :class:`~fdisyn.runtime.errors.TraceError` with the
message ``<path> line <n>: <what>; expected <what>``; a file the operating
system refuses to read or write raises ``OSError`` (its ``errno`` kept) whose
``strerror`` is ``cannot read|write <path>: <reason>``.
"""

from __future__ import annotations

import math
import os
import re
import stat
import tempfile
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, NoReturn

import numpy as np
from fdisyn.runtime.errors import TraceError
from fdisyn.runtime.reference import RunResult

__all__ = [
    "MAX_LINE_BYTES",
    "MAX_COLUMNS",
    "MAX_NAME_BYTES",
    "Trace",
    "TraceReader",
    "read_trace",
    "write_trace",
    "parse_field",
    "replay_csv",
    "shown_path",
    "write_replay_csv",
]

MAX_LINE_BYTES = 1 << 20
"""Longest line (bytes, line break excluded) either replay reads: bounds the C program's buffer."""
MAX_COLUMNS = 4096
"""Most fields in one record."""
MAX_NAME_BYTES = 256
"""Longest header name: names are identifiers; a longer one is a data row or a broken file."""

_CHUNK = 1 << 20  # bytes read at a time: memory stays bounded whatever the file's size
_BLOCK_ROWS = 4096  # samples handed to the diagnoser per call
_BOM = b"\xef\xbb\xbf"
_BLANKS = b" \t"

# A numeral: ASCII only (a bytes pattern cannot match other digits), no hexadecimal, no underscores.
_NUM = rb"[+-]?(?:(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?|(?i:infinity|inf|nan))"  # longest first: the cell check is atomic
_NUMERAL = re.compile(_NUM)
# The fields read from a block of rows, joined by LF: each empty or a numeral, blanks around it allowed.
# Atomic groups and possessive repeats: a refused block costs linear time, never a backtracking blow-up.
_CELL = rb"(?>[ \t]*+(?:" + _NUM + rb")?+[ \t]*+)"
_CELLS = re.compile(_CELL + rb"(?:\n" + _CELL + rb")*+")
# Any byte that needs a closer look: controls, DEL and every non-ASCII byte (UTF-8 and its refusals).
_SUSPECT = re.compile(rb"[\x00-\x08\x0a-\x1f\x7f-\xff]")
# Refused characters of decoded text: C0 except tab (CR here is always a lone CR), DEL, C1, U+2028, U+2029.
_REFUSED = re.compile("[\x00-\x08\x0a-\x1f\x7f-\x9f\u2028\u2029]")
_NOT_A_NUMBER = "expected a decimal numeral such as -1.5e-3, inf, nan or an empty field"


@dataclass(frozen=True, eq=False)
class Trace:
    """Time, inputs and outputs of one run (rows are samples).

    Attributes
    ----------
    t : numpy.ndarray
        The sample times in seconds, one per row.
    inputs : tuple of str
        The input names, one per column of ``U``.
    outputs : tuple of str
        The output names, one per column of ``Y``.
    U : numpy.ndarray
        The inputs (``N × len(inputs)``).
    Y : numpy.ndarray
        The outputs (``N × len(outputs)``).
    extra : Mapping of str to numpy.ndarray
        Further columns written after the outputs (a fault's true size, say); not read back.

    Raises
    ------
    TraceError
        A column name repeated, or arrays whose sizes do not match the names and ``t``.
    """

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


# ------------------------------------------------------------------ fields


def _shown(value: bytes, limit: int = 32) -> str:
    """Text as quoted in a message: printable ASCII kept, other bytes (and ``\\``, ``'``) as ``\\xHH``, ``limit`` bytes at most.

    The C replay prints the same text, and a message stays one line whatever a file holds.
    """
    out = "".join(chr(c) if 0x20 <= c < 0x7F and c not in b"\\'" else f"\\x{c:02x}" for c in value[:limit])
    return out + ("..." if len(value) > limit else "")


# Code points kept in a shown path besides printable ASCII: everything from U+00A1 except characters that
# are invisible, reorder the text (bidirectional controls) or are blanks a reader would take for spaces.
_PATH_HIDDEN = ((0xAD, 0xAD), (0x1680, 0x1680), (0x2000, 0x200F), (0x2028, 0x202F), (0x205F, 0x206F), (0x3000, 0x3000),
                (0xFEFF, 0xFEFF), (0xFFF9, 0xFFFB))


def shown_path(path: str | os.PathLike[str]) -> str:
    """A file name as both replays print it in a message: one line, the same text from Python and from C.

    The name's bytes (``os.fsencode``: the bytes the system and the C
    program see) are read as UTF-8; printable ASCII is kept, and so is a
    space between two other characters; a character from U+00A1 on is kept
    unless it is invisible, a bidirectional control or a blank (U+00AD,
    U+1680, U+2000–U+200F, U+2028–U+202F, U+205F–U+206F, U+3000, U+FEFF,
    U+FFF9–U+FFFB). Every other byte — control characters, a backslash,
    DEL, C1, U+00A0, bytes that are not UTF-8, a space at either end or
    beside another — is written ``\\xHH``. The generated C program applies
    the same rule (``shown_path`` in ``replay.c``).

    Parameters
    ----------
    path : str or os.PathLike
        The name as the user gave it (undecodable bytes as surrogate escapes).

    Returns
    -------
    str
        The name as quoted in messages.
    """
    try:
        raw = os.fsencode(path)
    except UnicodeEncodeError:  # a lone surrogate that no system name holds: shown by its UTF-8 bytes
        raw = os.fspath(path).encode("utf-8", "surrogatepass")
    n = len(raw)
    out: list[str] = []
    i = 0
    while i < n:
        c = raw[i]
        if c < 0x80:
            if c == 0x20:
                keep = 0 < i < n - 1 and raw[i - 1] != 0x20 and raw[i + 1] != 0x20
            else:
                keep = 0x20 < c < 0x7F and c != 0x5C
            out.append(chr(c) if keep else f"\\x{c:02x}")
            i += 1
            continue
        size = 2 if 0xC2 <= c <= 0xDF else 3 if 0xE0 <= c <= 0xEF else 4 if 0xF0 <= c <= 0xF4 else 0
        try:
            cp = ord(raw[i : i + size].decode("utf-8")) if size else -1
        except UnicodeDecodeError:
            cp = -1
        if cp < 0:
            out.append(f"\\x{c:02x}")
            i += 1
            continue
        if cp < 0xA1 or any(lo <= cp <= hi for lo, hi in _PATH_HIDDEN):
            out.extend(f"\\x{b:02x}" for b in raw[i : i + size])
        else:
            out.append(chr(cp))
        i += size
    return "".join(out)


def _shown_name(name: str) -> str:
    """A gain-file name as quoted in a message (a name never holds a lone surrogate that matches a header)."""
    return _shown(name.encode("utf-8", "surrogatepass"), MAX_NAME_BYTES)


def _number(value: bytes) -> float | None:
    """The value of one field's text (blanks and quotes already removed), or None if it is no numeral."""
    if not value:
        return math.nan
    if _NUMERAL.fullmatch(value) is None:
        return None
    return float(value)  # correctly rounded, like strtod in the C locale; ±inf beyond the double range


def parse_field(text: str | bytes) -> float:
    """One CSV field as both replays read it.

    Blanks (space, tab) around the field and one pair of enclosing double
    quotes (with ``""`` inside for a quote) are removed; the rest must be
    empty (NaN) or a numeral of the grammar.

    Parameters
    ----------
    text : str or bytes
        One field as it stands between the commas of a row.

    Returns
    -------
    float
        Its value; NaN for an empty field.

    Raises
    ------
    TraceError
        The field is not a number of the replay grammar, or holds more than one field.

    Examples
    --------
    >>> parse_field(' "1.5e3" ')
    1500.0
    """
    raw = text.encode("utf-8") if isinstance(text, str) else bytes(text)
    _check_text(raw, lambda msg: _raise(f"field '{_shown(raw)}': {msg}"))
    fields = _split(raw, lambda msg: _raise(f"field '{_shown(raw)}': {msg}"))
    if len(fields) != 1:
        _raise(f"field '{_shown(raw)}' holds {len(fields)} fields; expected one")
    v = _number(fields[0])
    if v is None:
        _raise(f"'{_shown(fields[0])}' is not a number; {_NOT_A_NUMBER}")
    return v


def _raise(msg: str) -> NoReturn:
    raise TraceError(msg)


def _split(line: bytes, fail: Callable[[str], NoReturn]) -> list[bytes]:
    """The fields of one line, unquoted, without surrounding blanks (RFC 4180, no line breaks).

    Scans left to right like the C program, so the first fault found is the same.
    """
    if b'"' not in line:
        fields = [f.strip(_BLANKS) for f in line.split(b",")]
        if len(fields) > MAX_COLUMNS:
            fail(f"more than {MAX_COLUMNS} columns; expected at most {MAX_COLUMNS}")
        return fields
    fields = []
    i, n = 0, len(line)
    while True:
        if len(fields) == MAX_COLUMNS:
            fail(f"more than {MAX_COLUMNS} columns; expected at most {MAX_COLUMNS}")
        while i < n and line[i] in _BLANKS:
            i += 1
        col = len(fields) + 1
        if i < n and line[i] == 0x22:  # '"'
            i += 1
            parts: list[bytes] = []
            while True:
                j = line.find(b'"', i)
                if j < 0:
                    fail(f"column {col}: a quoted field without its closing quote; expected the closing quote on the same line")
                parts.append(line[i:j])
                if line[j + 1 : j + 2] == b'"':
                    parts.append(b'"')
                    i = j + 2
                    continue
                i = j + 1
                break
            while i < n and line[i] in _BLANKS:
                i += 1
            if i < n and line[i] != 0x2C:  # ','
                fail(f"column {col}: text after the closing quote; expected a comma or the end of the line")
            fields.append(b"".join(parts))
        else:
            j = line.find(b",", i)
            end = n if j < 0 else j
            raw = line[i:end]
            if b'"' in raw:
                fail(f'column {col}: a double quote inside an unquoted field; expected the whole field in quotes, with "" for a quote')
            fields.append(raw.rstrip(_BLANKS))
            i = end
        if i >= n:
            return fields
        i += 1  # the comma


# ------------------------------------------------------------------- lines


def _check_text(line: bytes, fail: Callable[[str], NoReturn]) -> None:
    """Refuse bytes that are not UTF-8 and refused characters, the first one in the line first."""
    if _SUSPECT.search(line) is None:
        return
    try:
        text = line.decode("utf-8")
        bad_at = len(text)
    except UnicodeDecodeError as exc:
        text = line[: exc.start].decode("utf-8")
        bad_at = -1
    m = _REFUSED.search(text)
    if m is not None:
        cp = ord(m.group())
        if cp == 0x0D:
            fail("a carriage return (U+000D) not followed by a line feed; expected LF or CRLF line endings")
        fail(f"character U+{cp:04X} is not allowed; expected printable text and tabs")
    if bad_at < 0:
        fail("bytes that are not UTF-8; expected a UTF-8 text file")


class TraceReader:
    """Streams the columns ``t``, inputs and outputs of a trace CSV in blocks of samples.

    Reads the file in chunks of 1 MiB, so memory does not grow with the file.
    ``source`` is the name used in messages (as the user typed it; shown by :func:`shown_path`).

    Parameters
    ----------
    fh : binary file
        The open trace, positioned at its start.
    source : str
        The file's name, as messages show it.
    inputs, outputs : sequence of str
        The columns to read besides ``t`` (each must be in the header; others are ignored).

    Raises
    ------
    TraceError
        The file is empty, or its header lacks a column or repeats one.
    """

    def __init__(self, fh: IO[bytes], source: str, *, inputs: Sequence[str], outputs: Sequence[str]) -> None:
        self.source = source
        self._shown_source = shown_path(source)
        self.names = ("t", *inputs, *outputs)
        self.lineno = 0
        self._cells: list[bytes] = []  # fields read from the rows not yet handed out, row after row
        self._linenos: list[int] = []  # the line of each of those rows
        self._fh = fh
        self._lines = self._physical_lines()
        header = next(self._lines, None)
        if header is None:
            self.lineno = 1
            self._fail("the file is empty; expected a header row naming t and every input and output")
        if header.startswith(_BOM):
            header = header[len(_BOM) :]
        _check_text(header, self._fail)
        cols = _split(header, self._fail)
        for c, head in enumerate(cols, start=1):
            if len(head) > MAX_NAME_BYTES:
                self._fail(f"column {c} of the header is longer than {MAX_NAME_BYTES} bytes; expected a column name")
        self.ncols = len(cols)
        self.columns: list[int] = []
        for k, name in enumerate(self.names):
            role = "time" if k == 0 else (f"input {k - 1}" if k <= len(inputs) else f"output {k - 1 - len(inputs)}")
            key = name.encode("utf-8", "surrogatepass")
            where = [c for c, h in enumerate(cols) if h == key]
            if not where:
                self._fail(f"no column '{_shown_name(name)}' ({role}); expected a header naming t and every input and output")
            if len(where) > 1:
                self._fail(f"columns {where[0] + 1} and {where[1] + 1} are both named '{_shown_name(name)}' ({role}); expected one")
            self.columns.append(where[0])

    def _fail(self, msg: str) -> NoReturn:
        """Refuse the file at the current line, unless a row before it already holds a refused field."""
        lineno = self.lineno
        self._check_pending()
        raise TraceError(f"{self._shown_source} line {lineno}: {msg}")

    def _read(self) -> bytes:
        try:
            return self._fh.read(_CHUNK)
        except OSError as exc:
            self._check_pending()  # the rows read before come first, as in the C program
            raise OSError(exc.errno, f"cannot read {self._shown_source}: {exc.strerror or exc}") from exc

    def _physical_lines(self) -> Iterator[bytes]:
        """Lines without their LF or CRLF, counted in ``lineno``; a line over the limit is refused when reached."""
        too_long = f"longer than {MAX_LINE_BYTES} bytes; expected at most {MAX_LINE_BYTES} bytes per line"
        carry = b""
        while chunk := self._read():
            parts = (carry + chunk if carry else chunk).split(b"\n")
            carry = parts.pop()
            for p in parts:
                self.lineno += 1
                if p[-1:] == b"\r":
                    p = p[:-1]
                if len(p) > MAX_LINE_BYTES:
                    self._fail(too_long)
                yield p
            if len(carry) > MAX_LINE_BYTES + 1:  # over the limit even if a CRLF follows
                self.lineno += 1
                self._fail(too_long)
        if carry:  # a last line without a line break keeps a final CR (a lone one)
            self.lineno += 1
            if len(carry) > MAX_LINE_BYTES:
                self._fail(too_long)
            yield carry

    def blocks(self, rows: int = _BLOCK_ROWS) -> Iterator[np.ndarray]:
        """Blocks of at most ``rows`` samples: arrays of shape (k, 1 + nu + ny), columns in the order t, inputs, outputs.

        The fields read are collected per block and checked as one string (a
        numeral or empty each); a fault found later in the file is reported
        only after the block's earlier rows are checked (``_fail``), so the
        first fault is the C program's first fault.

        Parameters
        ----------
        rows : int
            The most samples in one block.

        Yields
        ------
        numpy.ndarray
            One block of samples.

        Raises
        ------
        TraceError
            A row that does not follow the replay grammar (named by its line).
        """
        cols, ncols, m = self.columns, self.ncols, len(self.columns)
        fail = self._fail
        cells, linenos = self._cells, self._linenos
        for line in self._lines:
            if _SUSPECT.search(line) is not None:
                _check_text(line, fail)
            if b'"' in line:
                fields = _split(line, fail)
                if len(fields) != ncols:
                    fail(f"{len(fields)} fields; expected {ncols}, as in the header")
                picked = [fields[c] for c in cols]
                for k, f in enumerate(picked):  # unquoted text: no blanks allowed inside the quotes
                    if f and _NUMERAL.fullmatch(f) is None:
                        fail(self._not_a_number(k, f))
            else:
                if not line.strip(_BLANKS):
                    continue  # a line of blanks
                fields = line.split(b",")
                if len(fields) > MAX_COLUMNS:
                    fail(f"more than {MAX_COLUMNS} columns; expected at most {MAX_COLUMNS}")
                if len(fields) != ncols:
                    fail(f"{len(fields)} fields; expected {ncols}, as in the header")
                picked = [fields[c] for c in cols]
            cells += picked
            linenos.append(self.lineno)
            if len(linenos) == rows:
                yield self._take(m)
        if linenos:
            yield self._take(m)

    def _not_a_number(self, k: int, value: bytes) -> str:
        """The message for field ``value`` (blanks outside quotes already removed) of the ``k``-th column read."""
        return f"column '{_shown_name(self.names[k])}' holds '{_shown(value)}', not a number; {_NOT_A_NUMBER}"

    def _check_pending(self) -> None:
        """Refuse the first field of the pending rows that is neither empty nor a numeral."""
        cells, linenos = self._cells, self._linenos
        if not cells or _CELLS.fullmatch(b"\n".join(cells)) is not None:
            return
        m = len(self.columns)
        for i, c in enumerate(cells):
            if _CELLS.fullmatch(c) is None:
                row, k = divmod(i, m)
                self.lineno = linenos[row]
                msg = self._not_a_number(k, c.strip(_BLANKS))
                cells.clear()
                linenos.clear()
                self._fail(msg)

    def _take(self, m: int) -> np.ndarray:
        self._check_pending()
        try:
            values = list(map(float, self._cells))  # correctly rounded, like strtod in the C locale; ±inf beyond range
        except ValueError:  # an empty field (the check has refused everything else)
            values = list(map(_to_float, self._cells))
        block = np.array(values, dtype=float).reshape(len(self._linenos), m)
        self._cells.clear()
        self._linenos.clear()
        return block


def _to_float(cell: bytes) -> float:
    """A checked field (empty, blanks, or a numeral with blanks around) as a float."""
    try:
        return float(cell)
    except ValueError:
        return math.nan  # only an empty field gets here: the check has refused everything else


def _open_input(source: str | Path) -> IO[bytes]:
    try:
        return open(source, "rb")  # noqa: SIM115 - the caller closes it
    except OSError as exc:
        raise OSError(exc.errno, f"cannot read {shown_path(source)}: {exc.strerror or exc}") from exc


def read_trace(path: str | Path, *, inputs: Sequence[str], outputs: Sequence[str]) -> Trace:
    """Read the columns ``t``, ``inputs`` and ``outputs`` of a trace CSV (the replay grammar).

    Parameters
    ----------
    path : str or Path
        The trace CSV.
    inputs, outputs : sequence of str
        The columns to read besides ``t``.

    Returns
    -------
    Trace
        The whole trace in memory (:class:`TraceReader` streams it instead).

    Raises
    ------
    TraceError
        A data error (named by its line and column) or a file that cannot be read.
    """
    try:
        with _open_input(str(path)) as fh:
            reader = TraceReader(fh, str(path), inputs=inputs, outputs=outputs)
            parts = list(reader.blocks())
    except TraceError:
        raise
    except OSError as exc:
        raise TraceError(exc.strerror or str(exc)) from exc
    m = len(inputs)
    data = np.concatenate(parts) if parts else np.zeros((0, 1 + m + len(outputs)))
    return Trace(t=data[:, 0], inputs=tuple(inputs), outputs=tuple(outputs), U=data[:, 1 : 1 + m], Y=data[:, 1 + m :])


# ----------------------------------------------------------------- writing


def _fmt(x: float) -> str:
    return "%.17g" % x  # NaN prints as "nan" whatever its sign bit: the C side prints it the same


def _csv_name(name: str) -> str:
    """A header name as an RFC 4180 field: quoted when it holds a comma, a quote, blanks at its ends or a line break."""
    if any(ch in name for ch in ',"\r\n') or name != name.strip(" \t"):
        return '"' + name.replace('"', '""') + '"'
    return name


def write_trace(trace: Trace, path: str | Path) -> Path:
    """Write ``t``, inputs, outputs and the extra columns (``%.17g``; NaN as an empty field).

    Parameters
    ----------
    trace : Trace
        What to write.
    path : str or Path
        The CSV to write (its folder is created).

    Returns
    -------
    Path
        ``path``.
    """
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    names = ["t", *trace.inputs, *trace.outputs, *trace.extra]
    cols = [trace.t, *trace.U.T, *trace.Y.T, *(np.asarray(v, dtype=float) for v in trace.extra.values())]
    with p.open("w", encoding="utf-8", newline="\n") as fh:
        fh.write(",".join(map(_csv_name, names)) + "\n")
        for row in zip(*cols, strict=True):
            fh.write(",".join("" if np.isnan(v) else _fmt(v) for v in row) + "\n")
    return p


class _AtomicOutput:
    """A text file written under a temporary name in the target's folder and renamed at the end.

    On an exception the temporary file is removed, so the target is never left half-written.
    I/O failures raise ``OSError("cannot write <target>: <reason>")``.
    """

    def __init__(self, target: str | Path) -> None:
        self.target = str(target)
        try:
            mode: int | None = os.lstat(self.target).st_mode
        except (OSError, ValueError):
            mode = None  # no such file yet (or a name the system refuses: reported by mkstemp below)
        if mode is not None and not stat.S_ISREG(mode) and not stat.S_ISDIR(mode):
            # the rename replaces the name itself: a symbolic link (/dev/stdout), a device node (/dev/full)
            # or a FIFO would become a plain file
            raise TraceError(
                f"{shown_path(self.target)} is not a regular file (a symbolic link, a device, a FIFO or a socket); "
                "expected the path of a file to create or replace"
            )
        folder, base = os.path.split(self.target)
        try:
            fd, self.tmp = tempfile.mkstemp(prefix=base + ".", dir=folder or ".")
        except OSError as exc:
            raise self._error(exc) from exc
        try:
            mask = os.umask(0)
            os.umask(mask)
            os.fchmod(fd, 0o666 & ~mask)  # the mode a plain new file gets, not mkstemp's 0600
            self.fh: IO[bytes] = os.fdopen(fd, "wb")
        except OSError as exc:
            os.close(fd)
            os.unlink(self.tmp)
            raise self._error(exc) from exc

    def _error(self, exc: OSError) -> OSError:
        return OSError(exc.errno, f"cannot write {shown_path(self.target)}: {exc.strerror or exc}")

    def write(self, text: str) -> None:
        try:
            self.fh.write(text.encode("ascii"))
        except OSError as exc:
            raise self._error(exc) from exc

    def __enter__(self) -> _AtomicOutput:
        return self

    def __exit__(self, kind: object, exc: object, tb: object) -> None:
        if kind is None:
            try:
                self.fh.close()
                os.replace(self.tmp, self.target)
                return
            except OSError as err:
                self._discard()
                raise self._error(err) from err
        self._discard()

    def _discard(self) -> None:
        try:
            self.fh.close()
        except OSError:
            pass  # the temporary file goes anyway; the first error is the one reported
        try:
            os.unlink(self.tmp)
        except FileNotFoundError:
            pass


def _replay_header(nj: int, nr: int) -> str:
    return ",".join(["t", "alarm", "isolated", *(f"J{i}" for i in range(nj)), *(f"r{i}" for i in range(nr))]) + "\n"


def _replay_rows(t: np.ndarray, result: RunResult) -> str:
    nj, nr = result.J.shape[1], result.r.shape[1]
    fmt = "%.17g,%d,%d" + ",%.17g" * (nj + nr) + "\n"  # "%.17g" prints NaN as "nan" whatever its sign bit
    rows = np.column_stack([t, result.alarm, result.isolated, result.J, result.r]).tolist()
    return "".join([fmt % tuple(row) for row in rows])


def write_replay_csv(path: str | Path, t: np.ndarray, result: RunResult) -> Path:
    """The replay output CSV of a whole run (same bytes as both replays write).

    Parameters
    ----------
    path : str or Path
        The CSV to write; written to a temporary file and renamed, so a failed write leaves no partial file.
    t : numpy.ndarray
        The sample times, one per row of ``result``.
    result : RunResult
        The run (:meth:`~fdisyn.runtime.monitor.Monitor.run`).

    Returns
    -------
    Path
        ``path``.
    """
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    with _AtomicOutput(p) as out:
        out.write(_replay_header(result.J.shape[1], result.r.shape[1]))
        out.write(_replay_rows(np.asarray(t, dtype=float), result))
    return p


def replay_csv(
    run: Callable[[np.ndarray, np.ndarray], RunResult],
    source: str,
    target: str,
    *,
    inputs: Sequence[str],
    outputs: Sequence[str],
    nj: int,
    nr: int,
) -> tuple[int, int]:
    """Stream the trace ``source`` through ``run`` and write the replay CSV ``target``.

    ``run(U, Y)`` processes one block of samples continuing the diagnoser's
    state (``Monitor.run``). Memory stays bounded by a block and a chunk of
    the file. The steps and their order (open the input, read the
    header, create the output, stream, rename) are the C program's, so both
    report the same first error.

    Parameters
    ----------
    run : callable
        ``run(U, Y) -> RunResult``: one block of samples through the diagnoser.
    source : str
        The trace CSV.
    target : str
        The replay CSV to write (to a temporary file renamed at the end).
    inputs, outputs : sequence of str
        The gain file's input and output names: the columns read besides ``t``.
    nj, nr : int
        The numbers of statistics and residuals (the output's columns).

    Returns
    -------
    tuple of int
        The number of samples and of samples skipped for non-finite values.

    Raises
    ------
    TraceError
        A data error in ``source`` (named by its line and column).
    OSError
        ``source`` cannot be opened or ``target`` cannot be written (the caller words it).
    """
    m = len(inputs)
    samples = skipped = 0
    with _open_input(source) as fh:
        reader = TraceReader(fh, source, inputs=inputs, outputs=outputs)
        with _AtomicOutput(target) as out:
            out.write(_replay_header(nj, nr))
            for block in reader.blocks(_BLOCK_ROWS):
                res = run(block[:, 1 : 1 + m], block[:, 1 + m :])
                out.write(_replay_rows(block[:, 0], res))
                samples += block.shape[0]
                skipped += res.nonfinite_samples
    return samples, skipped
