"""Trace CSV files: the replay grammar, named columns, streaming in bounded memory."""

from __future__ import annotations

import math
import re
import tracemalloc

import numpy as np
import pytest
from fdisyn.runtime import trace
from fdisyn.runtime.errors import TraceError
from fdisyn.runtime.reference import RunResult
from fdisyn.runtime.trace import Trace, parse_field, read_trace, replay_csv, write_trace
from hypothesis import given, settings
from hypothesis import strategies as st


@pytest.mark.parametrize(
    ("text", "value"),
    [
        ("1.5", 1.5),
        (" 1.5\t", 1.5),  # blanks around a field are not part of it
        ('"2"', 2.0),
        (' "2" ', 2.0),
        ('"-3e2"', -300.0),
        ("-inf", -math.inf),
        ("Infinity", math.inf),
        ("+.5E+1", 5.0),
        ("1.", 1.0),
        ("1e-3", 1e-3),
        ("1e999", math.inf),  # beyond the double range: rounded to inf as IEEE 754 does
        ("-1e99999999999999999999", -math.inf),
        ("1e-400", 0.0),
    ],
)
def test_numbers(text, value):
    assert parse_field(text) == value


@pytest.mark.parametrize("text", ["", "  ", '""', ' "" ', "nan", "-NaN", "+nan"])
def test_empty_fields_and_nan_are_nan(text):
    assert math.isnan(parse_field(text))


@pytest.mark.parametrize(
    "text",
    ["abc", "1.5x", "1_0", '"3 "', "e5", ".", "+", "1e", "1e+", "0x1p3", "0x1p99999", "١٢", "１２", "1٫5", "nan(1)", "in f", "--1", "1 2"],
)
def test_anything_else_is_refused_never_replaced(text):
    with pytest.raises(TraceError, match=r"is not a number; expected a decimal numeral such as -1.5e-3, inf, nan or an empty field"):
        parse_field(text)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("1,2", "holds 2 fields; expected one"),
        ('"1', "a quoted field without its closing quote"),
        ('"1"2', "text after the closing quote"),
        ('1"', "a double quote inside an unquoted field"),
        ("1\x00", "character U+0000 is not allowed"),
        ("1\u2028", "character U+2028 is not allowed"),
        (b"1\xff", "bytes that are not UTF-8"),
    ],
)
def test_malformed_fields_are_named(text, message):
    with pytest.raises(TraceError, match=re.escape(message)):
        parse_field(text)


@settings(max_examples=300, deadline=None)
@given(st.floats(allow_nan=False))
def test_printed_numbers_read_back_exactly(x):
    # %.17g is enough digits for every double; correct rounding brings the same double back
    assert parse_field("%.17g" % x) == x
    assert parse_field(repr(x)) == x


def test_round_trip_and_extra_columns(tmp_path):
    t = np.arange(5) * 0.01
    tr = Trace(t=t, inputs=("u",), outputs=("y1", "y2"), U=np.ones((5, 1)), Y=np.arange(10.0).reshape(5, 2), extra={"truth": np.zeros(5)})
    p = write_trace(tr, tmp_path / "t.csv")
    assert p.read_text().splitlines()[0] == "t,u,y1,y2,truth"
    back = read_trace(p, inputs=["u"], outputs=["y2", "y1"])  # any column order; extra columns ignored
    np.testing.assert_array_equal(back.Y, tr.Y[:, ::-1])
    np.testing.assert_array_equal(back.t, t)


def test_names_that_need_quotes_are_written_quoted(tmp_path):
    names = ("a,b", 'say "hi"', " padded ")
    tr = Trace(t=np.arange(3.0), inputs=names[:1], outputs=names[1:], U=np.ones((3, 1)), Y=np.full((3, 2), np.nan))
    p = write_trace(tr, tmp_path / "q.csv")
    assert p.read_text().splitlines()[0] == 't,"a,b","say ""hi"""," padded "'
    back = read_trace(p, inputs=names[:1], outputs=names[1:])
    np.testing.assert_array_equal(back.U, tr.U)
    assert np.isnan(back.Y).all()  # NaN is written as an empty field and read back as NaN


def test_missing_column_is_named(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("t,u,y1\n0,1,2\n")
    with pytest.raises(TraceError, match=r"t.csv line 1: no column 'y2' \(output 1\); expected a header naming t and every input"):
        read_trace(p, inputs=["u"], outputs=["y1", "y2"])
    with pytest.raises(TraceError, match=r"no column 'v' \(input 0\)"):
        read_trace(p, inputs=["v"], outputs=["y1"])


def test_duplicate_column_is_refused(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text('t,u,y,"y"\n0,1,2,3\n')
    with pytest.raises(TraceError, match=r"line 1: columns 3 and 4 are both named 'y' \(output 0\); expected one"):
        read_trace(p, inputs=["u"], outputs=["y"])
    p.write_text("t,u,y,x,x\n0,1,2,3,4\n")  # columns the diagnoser does not read may share a name
    assert read_trace(p, inputs=["u"], outputs=["y"]).Y[0, 0] == 2.0


def test_names_in_messages_stay_on_one_line(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("t,u,y\n0,1,2\n")
    with pytest.raises(TraceError) as exc:
        read_trace(p, inputs=["u"], outputs=["y\n'2'\u00e9"])
    assert r"no column 'y\x0a\x272\x27\xc3\xa9' (output 0)" in str(exc.value) and "\n" not in str(exc.value)


def test_ragged_row_is_named(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("t,u,y\n0,1,2\n0.1,1\n")
    with pytest.raises(TraceError, match="line 3: 2 fields; expected 3, as in the header"):
        read_trace(p, inputs=["u"], outputs=["y"])


def test_missing_file_is_a_trace_error(tmp_path):
    with pytest.raises(TraceError, match="cannot read .*nothing.csv: No such file or directory"):
        read_trace(tmp_path / "nothing.csv", inputs=["u"], outputs=["y"])


def test_line_numbers_count_skipped_blank_lines(tmp_path):
    p = tmp_path / "t.csv"
    p.write_bytes(b"t,u,y\r\n0,1,2\r\n\r\n \t\r\n0.2,1,x\r\n")
    with pytest.raises(TraceError, match="line 5: column 'y' holds 'x', not a number"):
        read_trace(p, inputs=["u"], outputs=["y"])


def test_messages_show_hostile_bytes_escaped(tmp_path):
    p = tmp_path / "t.csv"
    p.write_bytes("t,u,y\n0,1,\u00e9\\'".encode() + b"x" * 40 + b"\n")
    with pytest.raises(TraceError) as exc:
        read_trace(p, inputs=["u"], outputs=["y"])
    assert str(exc.value).endswith(r"column 'y' holds '\xc3\xa9\x5c\x27" + "x" * 28 + "...', not a number; expected a decimal numeral such as -1.5e-3, inf, nan or an empty field")


@pytest.mark.parametrize(("chunk", "rows"), [(1, 1), (7, 2), (64, 5)])
def test_chunk_and_block_boundaries_do_not_matter(tmp_path, monkeypatch, chunk, rows):
    rng = np.random.default_rng(7)
    lines = [b't,"u", y ,note']
    for k in range(40):
        lines.append(b"%.17g,%s,%.17g,%s" % (k * 0.1, [b"", b'"1.5"', b" nan ", b"-2e-3"][k % 4], rng.standard_normal(), b'"a,""b"""'))
        if k % 9 == 0:
            lines.append(b"  ")
    p = tmp_path / "t.csv"
    p.write_bytes(b"\r\n".join(lines) + b"\r\n")
    whole = read_trace(p, inputs=["u"], outputs=["y"])
    monkeypatch.setattr(trace, "_CHUNK", chunk)
    with open(p, "rb") as fh:
        parts = list(trace.TraceReader(fh, str(p), inputs=["u"], outputs=["y"]).blocks(rows))
    assert all(b.shape[0] <= rows for b in parts)
    got = np.concatenate(parts)
    np.testing.assert_array_equal(got, np.column_stack([whole.t, whole.U, whole.Y]))
    assert whole.t.shape == (40,) and np.isnan(whole.U[0::4, 0]).all() and (whole.U[1::4, 0] == 1.5).all()


def _zeros(U: np.ndarray, Y: np.ndarray) -> RunResult:
    """A stand-in diagnoser (2 statistics, 3 residuals): the test is about I/O, not the step."""
    n = Y.shape[0]
    z = np.zeros(n, dtype=int)
    return RunResult(r=np.zeros((n, 3)), J=np.ones((n, 2)), alarm=z, isolated=z - 1, status=z, state=np.zeros(1))


def test_the_replay_streams_in_bounded_memory(tmp_path, monkeypatch):
    """Peak Python memory does not grow with the trace: 64 KiB chunks and 256-row blocks keep it
    under 1 MiB for a 2 MB file, which the former whole-file reader held several times over."""
    monkeypatch.setattr(trace, "_CHUNK", 1 << 16)
    monkeypatch.setattr(trace, "_BLOCK_ROWS", 256)
    rng = np.random.default_rng(1)
    n = 12_000
    extra = {f"e{i}": rng.standard_normal(n) for i in range(6)}  # ignored columns: bytes to read, little to convert
    tr = Trace(t=np.arange(n) * 1e-3, inputs=("u",), outputs=("y",), U=rng.standard_normal((n, 1)), Y=rng.standard_normal((n, 1)), extra=extra)
    src = write_trace(tr, tmp_path / "in.csv")
    size = src.stat().st_size
    tracemalloc.start()
    try:
        samples, skipped = replay_csv(_zeros, str(src), str(tmp_path / "out.csv"), inputs=["u"], outputs=["y"], nj=2, nr=3)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert (samples, skipped) == (n, 0)
    assert size > 2_000_000 and peak < (1 << 20), (size, peak)
    out = (tmp_path / "out.csv").read_text().splitlines()
    assert out[0] == "t,alarm,isolated,J0,J1,r0,r1,r2" and len(out) == n + 1
    assert out[1234] == "%.17g,0,-1,1,1,0,0,0" % tr.t[1233]
