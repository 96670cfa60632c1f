"""The two replays against each other on hostile CSVs: the same bytes, or the same refusal.

``DIR/replay`` (generated C, run as a subprocess) and ``fdisyn replay``
(the streaming Python reader, run in-process through the command line) must,
for every input, either both succeed and write byte-identical OUT.csv, or
both fail with the same exit status and the same one-line message — and then
leave no OUT.csv (and no temporary file) behind. The awkward inputs are a
table of known troublemakers and a seeded fuzzer that mutates a valid trace
with bytes from a hostile alphabet.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import stat
import subprocess
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from fdisyn.app.cli import main
from fdisyn.runtime import trace
from fdisyn.runtime.trace import MAX_COLUMNS, MAX_LINE_BYTES, MAX_NAME_BYTES

HEADER = b"t,voltage,i_meas,w_meas,theta_meas,note"
# a quiet DC motor: 0.615 A, 107.7 rad/s, a slowly turning angle; the note column is ignored by both replays
ROWS = [b"%.3f,6,0.615,107.7,%.4f,ok" % (0.001 * k, 0.1077 * k) for k in range(12)]


@dataclass(frozen=True)
class Outcome:
    status: int
    message: str
    """The last stderr line without the program's prefix (``replay: error: ``, ``fdisyn replay: error: ``)."""
    output: bytes | None


def _outcome(status: int, stderr: str, out: Path, prefix: str) -> Outcome:
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr  # one line, never a traceback
    msg = lines[0]
    if status != 0:
        assert msg.startswith(prefix), msg
        msg = msg[len(prefix) :]
    return Outcome(status, msg, out.read_bytes() if out.is_file() else None)


def replay_c(motor_built, src: Path, out: Path) -> Outcome:
    proc = subprocess.run([str(motor_built.artifacts.replay), str(src), str(out)], capture_output=True, timeout=60)
    assert proc.returncode in (0, 1, 2), proc  # a signal (crash) is negative
    return _outcome(proc.returncode, proc.stderr.decode("utf-8"), out, "replay: error: ")


def replay_py(motor_built, src: Path, out: Path) -> Outcome:
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        try:
            status = main(["replay", str(motor_built.directory), str(src), str(out)])
        except SystemExit as exc:
            status = int(exc.code or 0)
    return _outcome(status, err.getvalue(), out, "fdisyn replay: error: ")


def both(motor_built, tmp: Path, data: bytes) -> Outcome:
    """Run both replays on ``data``; assert they agree; return the (common) outcome."""
    src = tmp / "in.csv"
    src.write_bytes(data)
    before = set(os.listdir(tmp))
    c = replay_c(motor_built, src, tmp / "c.csv")
    p = replay_py(motor_built, src, tmp / "py.csv")
    assert (c.status, c.message) == (p.status, p.message), data[:300]
    assert c.output == p.output, data[:300]
    if c.status:
        assert c.output is None and set(os.listdir(tmp)) == before  # nothing half-written, no temporary file
    for name in ("c.csv", "py.csv"):
        (tmp / name).unlink(missing_ok=True)
    return c


def csv(*rows: bytes, header: bytes = HEADER, end: bytes = b"\n") -> bytes:
    return b"".join(r + end for r in (header, *rows))


def _rows(out: bytes) -> list[list[str]]:
    return [ln.split(",") for ln in out.decode().splitlines()[1:]]


def _longest() -> bytes:
    """ROWS[0] padded in its ignored column to exactly the longest line both replays accept."""
    row = ROWS[0].replace(b",ok", b"," + b"x" * (MAX_LINE_BYTES - len(ROWS[0]) + 2))
    assert len(row) == MAX_LINE_BYTES
    return row


# --------------------------------------------------------------- accepted


def test_the_plain_trace_is_replayed(motor_built, tmp_path):
    res = both(motor_built, tmp_path, csv(*ROWS))
    assert res.status == 0 and res.message == "replay: 12 samples, 0 with non-finite values skipped"
    assert res.output is not None
    assert res.output.splitlines()[0] == b"t,alarm,isolated,J0,J1,r0,r1,r2,r3"
    assert [r[0] for r in _rows(res.output)][:3] == ["0", "0.001", "0.002"]


def test_a_header_without_rows_gives_a_header_without_rows(motor_built, tmp_path):
    for data in (HEADER, csv(), csv(b"", b" ")):
        res = both(motor_built, tmp_path, data)
        assert (res.status, res.output) == (0, b"t,alarm,isolated,J0,J1,r0,r1,r2,r3\n")
        assert res.message == "replay: 0 samples, 0 with non-finite values skipped"


SAME_AS_PLAIN = {
    "CRLF line endings": csv(*ROWS, end=b"\r\n"),
    "no line break after the last row": csv(*ROWS)[:-1],
    "a UTF-8 byte-order mark": b"\xef\xbb\xbf" + csv(*ROWS),
    "quoted header in another column order": csv(
        *[b",".join(r.split(b",")[i] for i in (5, 3, 0, 4, 2, 1)) for r in ROWS],
        header=b'"note","w_meas",t,"theta_meas" , "i_meas",voltage',
    ),
    "blank and whitespace-only lines": csv(ROWS[0], b"", b"  \t ", *ROWS[1:], b" ", end=b"\n"),
    "blanks around fields and quoted numbers": csv(*[b" " + r.replace(b",6,", b',\t"6" ,') + b"\t" for r in ROWS]),
    "quotes, commas and escaped quotes in the ignored column": csv(*[r.replace(b",ok", b',"a ""b"", c"') for r in ROWS]),
    "non-ASCII text in the ignored column": csv(*[r.replace(b",ok", ",，١٢ ok é".encode()) for r in ROWS]),
    "explicit signs and exponents": csv(*[r.replace(b",6,", b",+6.0e0,").replace(b",0.615,", b",615E-3,") for r in ROWS]),
}


@pytest.mark.parametrize("case", list(SAME_AS_PLAIN))
def test_equivalent_spellings_give_the_plain_bytes(motor_built, tmp_path, case):
    plain = both(motor_built, tmp_path, csv(*ROWS))
    res = both(motor_built, tmp_path, SAME_AS_PLAIN[case])
    assert res.status == 0 and res.output == plain.output


@pytest.mark.parametrize(
    ("field", "printed"),
    [
        (b"nan", "nan"),
        (b"-nan", "nan"),  # never "-nan"
        (b"NaN", "nan"),
        (b"", "nan"),
        (b"-Infinity", "-inf"),
        (b"inf", "inf"),
        (b"1e999", "inf"),  # beyond the double range: +inf, as IEEE rounding gives
        (b"-1e999", "-inf"),
        (b"1e-400", "0"),  # below the smallest subnormal: 0
        (b"-0", "-0"),
        (b"4.9406564584124654e-324", "4.9406564584124654e-324"),
    ],
)
def test_special_values_in_the_time_column(motor_built, tmp_path, field, printed):
    rows = [ROWS[0], b",".join([field, *ROWS[1].split(b",")[1:]]), *ROWS[2:]]
    res = both(motor_built, tmp_path, csv(*rows))
    assert res.status == 0 and res.output is not None
    assert _rows(res.output)[1][0] == printed


@pytest.mark.parametrize("field", [b"", b"nan", b"-nan", b"1e999", b"-inf", b'""'])
def test_a_non_finite_reading_is_a_skipped_sample(motor_built, tmp_path, field):
    rows = [*ROWS[:5], ROWS[5].replace(b",107.7,", b"," + field + b","), *ROWS[6:]]
    res = both(motor_built, tmp_path, csv(*rows))
    assert res.status == 0 and res.message == "replay: 12 samples, 1 with non-finite values skipped"


def test_correct_rounding_of_long_numerals(motor_built, tmp_path):
    """Decimal → double rounds correctly on both sides, against exact rational arithmetic.

    2^53 + 1 lies exactly halfway between two doubles: with 600 zeros after it the tie goes to the
    even neighbour, with a 1 after them it goes up; only correct rounding of all digits gets both.
    """
    half = "9007199254740993." + "0" * 600
    numerals = [half, half + "1", "0." + "0" * 400 + "1e400", "1" * 4000 + "e-3990", "2.2250738585072011e-308", "1e-320"]
    rows = [b",".join([s.encode(), b"6", b"0.615", b"107.7", b"0", b"ok"]) for s in numerals]
    res = both(motor_built, tmp_path, csv(*rows))
    assert res.status == 0 and res.output is not None
    printed = [r[0] for r in _rows(res.output)]
    assert printed == ["%.17g" % float(Fraction(s)) for s in numerals]  # Fraction → float rounds exactly
    assert printed[:2] == ["9007199254740992", "9007199254740994"]


def test_limits_are_inclusive(motor_built, tmp_path):
    assert both(motor_built, tmp_path, csv(_longest(), *ROWS[1:], end=b"\r\n")).status == 0  # the CR of CRLF is not counted
    assert both(motor_built, tmp_path, csv(ROWS[0]) + _longest()).status == 0  # nor a missing final line break
    wide = HEADER + b"".join(b",c%d" % i for i in range(MAX_COLUMNS - 6))
    assert wide.count(b",") + 1 == MAX_COLUMNS
    row = ROWS[0] + b"," * (MAX_COLUMNS - 6)
    assert both(motor_built, tmp_path, csv(row, header=wide)).status == 0
    named = HEADER.replace(b"note", b"n" * MAX_NAME_BYTES)
    assert both(motor_built, tmp_path, csv(*ROWS, header=named)).status == 0


# --------------------------------------------------------------- refused

IN = "in.csv"
REFUSED = {
    "non-ASCII (Arabic-Indic) digits": (
        csv(ROWS[0], ROWS[1].replace(b",6,", ",١٢,".encode())),
        r"line 3: column 'voltage' holds '\xd9\xa1\xd9\xa2', not a number; expected a decimal numeral",
    ),
    "full-width digits": (csv(ROWS[0], ROWS[1].replace(b",6,", ",１２,".encode())), "line 3: column 'voltage' holds '\\xef\\xbc\\x91"),
    "hexadecimal float beyond range": (csv(ROWS[0].replace(b",107.7,", b",0x1p99999,")), "line 2: column 'w_meas' holds '0x1p99999', not a number"),
    "hexadecimal float": (csv(ROWS[0].replace(b",107.7,", b",0x1.3p7,")), "holds '0x1.3p7', not a number"),
    "underscores": (csv(ROWS[0].replace(b",107.7,", b",1_07.7,")), "holds '1_07.7', not a number"),
    "text": (csv(ROWS[0].replace(b",107.7,", b",abc,")), "line 2: column 'w_meas' holds 'abc', not a number"),
    "blank inside a quoted number": (csv(ROWS[0].replace(b",107.7,", b',"107.7 ",')), "holds '107.7 ', not a number"),
    "lone-CR line endings": (csv(*ROWS, end=b"\r"), "line 1: a carriage return (U+000D) not followed by a line feed; expected LF or CRLF"),
    "a final lone CR": (csv(*ROWS)[:-1] + b"\r", "line 13: a carriage return (U+000D)"),
    "NUL byte": (csv(ROWS[0], ROWS[1] + b"\x00"), "line 3: character U+0000 is not allowed; expected printable text and tabs"),
    "vertical tab": (csv(ROWS[0] + b"\x0b"), "line 2: character U+000B is not allowed"),
    "DEL": (csv(ROWS[0] + b"\x7f"), "line 2: character U+007F is not allowed"),
    "U+2028 line separator": (csv(ROWS[0], ROWS[1].replace(b",ok", "\u2028".encode())), "line 3: character U+2028 is not allowed"),
    "U+0085 next line": (csv(ROWS[0].replace(b",ok", ",a\u0085b".encode())), "line 2: character U+0085 is not allowed"),
    "Latin-1 byte": (csv(ROWS[0].replace(b",ok", b",caf\xe9")), "line 2: bytes that are not UTF-8; expected a UTF-8 text file"),
    "UTF-16 file": ("\ufeff".encode("utf-16-le") + csv(*ROWS).decode().encode("utf-16-le"), "line 1: bytes that are not UTF-8"),
    "UTF-16 file without a byte-order mark": (csv(*ROWS).decode().encode("utf-16-le"), "line 1: character U+0000"),
    "encoded surrogate": (csv(ROWS[0].replace(b",ok", b",\xed\xa0\x80")), "line 2: bytes that are not UTF-8"),
    "overlong encoding": (csv(ROWS[0].replace(b",ok", b",\xc0\xaf")), "line 2: bytes that are not UTF-8"),
    "truncated sequence": (csv(ROWS[0].replace(b",ok", b",\xe2\x82")), "line 2: bytes that are not UTF-8"),
    "a byte-order mark after the start": (csv(ROWS[0], header=b"\xef\xbb\xbf" + HEADER.replace(b"t,", b"\xef\xbb\xbft,")), "line 1: no column 't' (time)"),
    "line over the limit": (csv(ROWS[0], ROWS[1].replace(b",ok", b"," + b"x" * MAX_LINE_BYTES)), "line 3: longer than 1048576 bytes"),
    "a line one byte over the limit, CRLF": (csv(_longest() + b"y", end=b"\r\n"), "line 2: longer than 1048576 bytes"),
    "a line at the limit and a lone CR": (csv(_longest() + b"\r", end=b"\r\n"), "line 2: longer than 1048576 bytes"),
    "the last line over the limit": (csv(ROWS[0]) + b"x" * (MAX_LINE_BYTES + 1), "line 3: longer than 1048576 bytes"),
    "more columns than the limit": (csv(ROWS[0] + b"," * MAX_COLUMNS), "line 2: more than 4096 columns; expected at most 4096"),
    "quoted row over the column limit": (csv(ROWS[0] + b',""' * MAX_COLUMNS), "line 2: more than 4096 columns"),
    "header name over the limit": (csv(*ROWS, header=HEADER.replace(b"note", b"n" * (MAX_NAME_BYTES + 1))), "line 1: column 6 of the header is longer than 256 bytes"),
    "empty file": (b"", "line 1: the file is empty; expected a header row naming t and every input and output"),
    "a byte-order mark alone": (b"\xef\xbb\xbf", "line 1: no column 't' (time)"),
    "blank header": (b"\n" + csv(*ROWS, header=HEADER), "line 1: no column 't' (time); expected a header naming t and every input and output"),
    "missing output column": (csv(header=HEADER.replace(b"w_meas", b"w")), "line 1: no column 'w_meas' (output 1)"),
    "header in another case": (csv(header=HEADER.replace(b"voltage", b"Voltage")), "line 1: no column 'voltage' (input 0)"),
    "duplicate needed column": (csv(*ROWS, header=HEADER.replace(b"note", b'"i_meas"')), "line 1: columns 3 and 6 are both named 'i_meas' (output 0); expected one"),
    "ragged row": (csv(ROWS[0], ROWS[1] + b",extra"), "line 3: 7 fields; expected 6, as in the header"),
    "unterminated quote": (csv(ROWS[0].replace(b",ok", b',"ok')), 'line 2: column 6: a quoted field without its closing quote'),
    "quoted line break": (csv(ROWS[0].replace(b",ok", b',"o\nk"')), "line 2: column 6: a quoted field without its closing quote"),
    "quote inside a bare field": (csv(ROWS[0].replace(b",ok", b',o"k')), 'line 2: column 6: a double quote inside an unquoted field'),
    "text after a closing quote": (csv(ROWS[0].replace(b",6,", b',"6"0,')), "line 2: column 2: text after the closing quote"),
}


@pytest.mark.parametrize("case", list(REFUSED))
def test_refused_inputs(motor_built, tmp_path, case):
    data, expected = REFUSED[case]
    res = both(motor_built, tmp_path, data)
    assert res.status == 2
    assert res.message.startswith(f"{tmp_path / IN} line ") and expected in res.message, res.message


def test_the_first_fault_is_reported_across_blocks(motor_built, tmp_path):
    """Python checks the numbers of a block of rows at once; an earlier bad number still wins over a later fault."""
    rows = [b"%d,6,0.615,107.7,0,ok" % k for k in range(6000)]
    rows[4500] = rows[4500].replace(b",107.7,", b",1..2,")
    rows[4600] += b",extra"
    res = both(motor_built, tmp_path, csv(*rows))
    assert res.status == 2 and "line 4502: column 'w_meas' holds '1..2'" in res.message
    rows[4500] = rows[4500].replace(b",1..2,", b",\x00,")
    assert "line 4502: character U+0000" in both(motor_built, tmp_path, csv(*rows)).message
    rows[100] = rows[100].replace(b",6,", b",x,")
    assert "line 102: column 'voltage' holds 'x'" in both(motor_built, tmp_path, csv(*rows)).message


def test_a_failed_replay_leaves_an_existing_output_untouched(motor_built, tmp_path):
    src = tmp_path / "in.csv"
    src.write_bytes(csv(ROWS[0], b"1,2"))
    for run in (replay_c, replay_py):
        out = tmp_path / "keep.csv"
        out.write_bytes(b"previous\n")
        assert run(motor_built, src, out).status == 2
        assert out.read_bytes() == b"previous\n"
        assert sorted(os.listdir(tmp_path)) == ["in.csv", "keep.csv"]


def test_an_output_that_is_a_link_a_device_or_a_fifo_is_refused_and_left_as_it_was(motor_built, tmp_path):
    """The rename at the end replaces the name itself: OUT.csv = /dev/full or /dev/stdout (a link) would
    become a plain file (as root, the device node is gone), a link to a file would lose its target."""
    good = tmp_path / "good.csv"
    good.write_bytes(csv(*ROWS))
    target = tmp_path / "target.csv"
    target.write_bytes(b"previous\n")
    link = tmp_path / "link.csv"
    link.symlink_to(target)
    device = tmp_path / "null.csv"
    device.symlink_to("/dev/null")  # a link to a device: nothing here ever renames over /dev itself
    fifo = tmp_path / "fifo.csv"
    os.mkfifo(fifo)
    for out in (link, device, fifo):
        c, p = replay_c(motor_built, good, out), replay_py(motor_built, good, out)
        assert (c.status, c.message) == (p.status, p.message) == (
            2,
            f"{out} is not a regular file (a symbolic link, a device, a FIFO or a socket); expected the path of a file to create or replace",
        )
    assert link.is_symlink() and device.is_symlink() and stat.S_ISFIFO(os.lstat(fifo).st_mode)
    assert target.read_bytes() == b"previous\n"
    assert sorted(os.listdir(tmp_path)) == ["fifo.csv", "good.csv", "link.csv", "null.csv", "target.csv"]  # no temporary file


def test_io_errors_end_with_status_1_and_the_same_line(motor_built, tmp_path):
    good = tmp_path / "good.csv"
    good.write_bytes(csv(*ROWS))
    (tmp_path / "adir").mkdir()
    cases = [
        (tmp_path / "missing.csv", tmp_path / "o.csv", f"cannot read {tmp_path / 'missing.csv'}: No such file or directory"),
        (tmp_path / "adir", tmp_path / "o.csv", f"cannot read {tmp_path / 'adir'}: Is a directory"),
        (good, tmp_path / "nofolder" / "o.csv", f"cannot write {tmp_path / 'nofolder' / 'o.csv'}: No such file or directory"),
        (good, tmp_path / "adir", f"cannot write {tmp_path / 'adir'}: Is a directory"),
    ]
    for src, out, message in cases:
        c, p = replay_c(motor_built, src, out), replay_py(motor_built, src, out)
        assert c == p == Outcome(1, message, None)
        assert sorted(os.listdir(tmp_path)) == ["adir", "good.csv"] and os.listdir(tmp_path / "adir") == []


ODD_NAMES = {
    "a line feed": b"bad\nname.csv",
    "a carriage return": b"cr\rname.csv",
    "a byte that is not UTF-8": b"a\xffb.csv",
    "a UTF-8 sequence cut short": b"x\xc3.csv",
    "an encoded surrogate": b"s\xed\xa0\x80.csv",
    "a tab": b"tab\there.csv",
    "two spaces": b"two  spaces.csv",
    "a leading space": b" lead.csv",
    "a trailing space": b"trail.csv ",
    "a backslash": b"back\\slash.csv",
    "a terminal escape": b"esc\x1b[31m.csv",
    "NEL (C1)": "nel\u0085.csv".encode(),
    "a line separator": "ls\u2028.csv".encode(),
    "a bidirectional override": "bidi\u202evsc.csv".encode(),
    "a no-break space": "nb\u00a0sp.csv".encode(),
    "accents and fullwidth letters": "données ｘ.csv".encode(),
}


@pytest.mark.parametrize("case", list(ODD_NAMES))
def test_odd_file_names_are_shown_alike_by_both_replays(motor_built, tmp_path, case):
    """A file name is shown by one rule (trace.shown_path) on both sides: the same single line."""
    odd = tmp_path / os.fsdecode(ODD_NAMES[case])  # the name's bytes, as the system and the C program see them
    odd.write_bytes(csv(*ROWS, header=b"t,x"))
    good = tmp_path / "good.csv"
    good.write_bytes(csv(*ROWS))
    missing = tmp_path / (odd.name + ".missing")
    link = tmp_path / (odd.name + ".link")
    link.symlink_to(good)
    shown = trace.shown_path
    cases = [
        (odd, tmp_path / "o.csv", 2, f"{shown(str(odd))} line 1: no column 'voltage' (input 0); expected a header naming t and every input and output"),
        (missing, tmp_path / "o.csv", 1, f"cannot read {shown(str(missing))}: No such file or directory"),
        (good, odd / "o.csv", 1, f"cannot write {shown(str(odd / 'o.csv'))}: Not a directory"),
        (good, link, 2, f"{shown(str(link))} is not a regular file (a symbolic link, a device, a FIFO or a socket); expected the path of a file to create or replace"),
    ]
    for src, out, status, message in cases:
        c, p = replay_c(motor_built, src, out), replay_py(motor_built, src, out)
        assert (c.status, c.message) == (p.status, p.message) == (status, message), case
        assert message.isprintable() and message == " ".join(message.split())
    assert good.read_bytes() == csv(*ROWS) and not (tmp_path / "o.csv").exists()  # nothing written anywhere
    named = tmp_path / (odd.name + ".out")  # and an odd name that works
    c, p = replay_c(motor_built, good, named), replay_py(motor_built, good, named)
    assert c.status == p.status == 0 and named.read_bytes() == csv_out_of(motor_built, good, tmp_path)


def csv_out_of(motor_built, src: Path, tmp: Path) -> bytes:
    """What both replays write for ``src`` under a plain name."""
    res = replay_c(motor_built, src, tmp / "plain-out.csv")
    assert res.status == 0 and res.output is not None
    return res.output


def test_usage_error_is_status_2(motor_built, tmp_path):
    proc = subprocess.run([str(motor_built.artifacts.replay), "only-one"], capture_output=True, text=True)
    assert proc.returncode == 2 and proc.stderr.startswith("usage: ")
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        status = main(["replay", str(motor_built.directory), "only-one"])
    assert status == 2 and err.getvalue().count("\n") == 1 and err.getvalue().startswith("fdisyn replay: error: ")


def test_the_output_gets_the_mode_of_a_new_file(motor_built, tmp_path):
    res = both(motor_built, tmp_path, csv(*ROWS))
    assert res.status == 0
    src = tmp_path / "in.csv"
    mask = os.umask(0)
    os.umask(mask)
    for run, name in ((replay_c, "c.csv"), (replay_py, "py.csv")):
        run(motor_built, src, tmp_path / name)
        assert (tmp_path / name).stat().st_mode & 0o777 == 0o666 & ~mask


# ---------------------------------------------------------------- fuzzer

HOSTILE = [
    b'"', b'""', b",", b"\r", b"\n", b"\r\n", b"\x00", b"\t", b" ", b"\x0b", b"\x0c", b"\x1b", b"\x7f",
    "\u2028".encode(), "\u2029".encode(), "\u0085".encode(), "\ufeff".encode(), b"\xef\xbb\xbf",
    b"\xff", b"\xc3", b"\x80", b"\xed\xa0\x80", b"\xf4\x90\x80\x80", b"\xc0\xaf", b"\xe2\x82",
    "١٢".encode(), "１２".encode(), "٫".encode(), "é".encode(),
    b"1e999", b"-1e999", b"1e-400", b"1e99999999999999999999", b"0x1p3", b"0x1p99999", b"-0x1.8p1",
    b"nan", b"-nan", b"NaN", b"inf", b"-Infinity", b"infinity", b"1_0", b"e5", b".", b"+", b"-", b"1.", b".5", b"E",
    b"9007199254740993", b"0", b"7", b"12",
]


def _mutate(rng: np.random.Generator, data: bytes) -> bytes:
    for _ in range(int(rng.integers(1, 4))):
        kind = rng.integers(0, 10)
        pos = int(rng.integers(0, len(data) + 1))
        if kind <= 5:  # insert a hostile token
            data = data[:pos] + HOSTILE[int(rng.integers(len(HOSTILE)))] + data[pos:]
        elif kind == 6 and data:  # delete a few bytes
            data = data[:pos] + data[pos + int(rng.integers(1, 4)) :]
        elif kind == 7:  # replace a whole field by a hostile token (quoted at times)
            starts = [0] + [i + 1 for i, b in enumerate(data) if b in b",\n"]
            s = starts[int(rng.integers(len(starts)))]
            e = min([i for i in (data.find(b",", s), data.find(b"\n", s)) if i >= 0], default=len(data))
            tok = HOSTILE[int(rng.integers(len(HOSTILE)))]
            data = data[:s] + (b'"' + tok + b'"' if rng.random() < 0.3 else tok) + data[e:]
        elif kind == 8:  # swap two lines
            lines = data.split(b"\n")
            i, j = rng.integers(0, len(lines), size=2)
            lines[i], lines[j] = lines[j], lines[i]
            data = b"\n".join(lines)
        else:  # a random byte
            data = data[:pos] + bytes([int(rng.integers(0, 256))]) + data[pos:]
    return data


def test_differential_fuzz(motor_built, tmp_path, monkeypatch):
    """600 seeded mutations of a valid trace: identical bytes or the identical refusal, never a crash (~12 s).

    The Python side reads in chunks of 5 bytes to 1 MiB and hands out blocks of 1 to 4096 rows, so
    lines split across reads and faults on either side of a block boundary are part of the draw.
    """
    rng = np.random.default_rng(20240611)
    seen = {0: 0, 1: 0, 2: 0}
    kinds = set()
    for _ in range(600):
        monkeypatch.setattr(trace, "_CHUNK", int(rng.choice([5, 64, 1 << 20])))
        monkeypatch.setattr(trace, "_BLOCK_ROWS", int(rng.choice([1, 3, 4096])))
        data = _mutate(rng, csv(*ROWS) if rng.random() < 0.9 else csv(*ROWS, end=b"\r\n"))
        res = both(motor_built, tmp_path, data)
        seen[res.status] += 1
        kinds.add(re.sub(r"'[^']*'|\d+", "#", res.message.split(": ", 1)[-1].split(";")[0]))
    # the fuzzer must exercise both sides of the grammar and most of its refusals, not one of them over and over
    assert seen[0] >= 60 and seen[2] >= 300, seen
    assert len(kinds) >= 12, sorted(kinds)


def _random_numeral(rng: np.random.Generator) -> str:
    """A numeral of the grammar: long mantissas, exponents around the double range's ends, specials, empty."""
    if rng.random() < 0.06:
        return str(rng.choice(["nan", "NaN", "-nan", "inf", "-Inf", "+INFINITY", ""]))
    digits = lambda k: "".join(rng.choice(list("0123456789"), size=k))  # noqa: E731
    k = int(rng.choice([1, 2, 5, 17, 18, 25, 60, 400]))
    body = [digits(k), digits(int(rng.integers(1, 5))) + "." + digits(k), "." + digits(k)][int(rng.integers(3))]
    s = str(rng.choice(["", "+", "-"])) + body
    if rng.random() < 0.5:
        s += str(rng.choice(["e", "E"])) + str(rng.choice(["", "+", "-"])) + str(rng.choice([0, 5, 22, 300, 308, 309, 323, 324, 400, 99999]))
    return s


def _exact(numeral: str) -> float:
    """The double nearest to a numeral, by exact rational arithmetic (the truth both replays must print)."""
    body = numeral.lstrip("+-").lower()
    if body in ("nan", ""):
        return float("nan")
    sign = -1.0 if numeral.startswith("-") else 1.0
    if body.startswith("inf"):
        return sign * float("inf")
    try:
        return sign * float(Fraction(body))  # int / int rounds correctly
    except OverflowError:
        return sign * float("inf")


def test_differential_fuzz_of_valid_files(motor_built, tmp_path):
    """80 seeded valid files: random column order, quoting, blanks, line endings and numerals (up to
    400 digits, exponents at the ends of the double range). Both replays accept them, write the same
    bytes, and print each t as the correctly rounded double of its numeral."""
    rng = np.random.default_rng(4180)
    names = ["t", "voltage", "i_meas", "w_meas", "theta_meas", "note", "x"]

    def wrap(text: str) -> str:
        blank = lambda: "".join(rng.choice([" ", "\t"], size=int(rng.integers(0, 3)))) if rng.random() < 0.2 else ""  # noqa: E731
        quoted = '"' + text.replace('"', '""') + '"' if rng.random() < 0.2 else text
        return blank() + quoted + blank()

    for _ in range(80):
        order = rng.permutation(len(names))
        lines, times = [",".join(wrap(names[i]) for i in order)], []
        for _ in range(int(rng.integers(0, 20))):
            if rng.random() < 0.05:
                lines.append(" " * int(rng.integers(0, 3)))
                continue
            row = {n: _random_numeral(rng) for n in ("t", "voltage", "i_meas", "w_meas", "theta_meas", "x")}
            row["note"] = '"' + str(rng.choice(["ok", "a,b", 'q""q', "é", ""])) + '"'
            times.append(row["t"])
            lines.append(",".join(row[names[i]] if names[i] == "note" else wrap(row[names[i]]) for i in order))
        eol = "\r\n" if rng.random() < 0.3 else "\n"
        res = both(motor_built, tmp_path, (eol.join(lines) + (eol if rng.random() < 0.8 else "")).encode())
        assert res.status == 0 and res.output is not None, res.message
        assert [r[0] for r in _rows(res.output)] == ["%.17g" % _exact(s) for s in times]
