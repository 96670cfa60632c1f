"""Trace CSV files: named columns, the replay program's parsing rules."""

from __future__ import annotations

import math

import numpy as np
import pytest
from fdisyn.runtime.errors import TraceError
from fdisyn.runtime.trace import Trace, parse_field, read_trace, write_trace


@pytest.mark.parametrize(
    ("text", "value"),
    [("1.5", 1.5), (" 1.5 ", 1.5), ('"2"', 2.0), ("-inf", -math.inf), ("0x1p3", 8.0), ("1e-3", 1e-3)],
)
def test_numbers(text, value):
    assert parse_field(text) == value


@pytest.mark.parametrize("text", ["", "  ", "abc", "1.5x", "1_0", '"3 "', "nan", "e5"])
def test_not_numbers_are_nan(text):
    assert math.isnan(parse_field(text))


def test_round_trip_and_extra_columns(tmp_path):
    t = np.arange(5) * 0.01
    tr = Trace(t=t, inputs=("u",), outputs=("y1", "y2"), U=np.ones((5, 1)), Y=np.arange(10.0).reshape(5, 2), extra={"truth": np.zeros(5)})
    p = write_trace(tr, tmp_path / "t.csv")
    assert p.read_text().splitlines()[0] == "t,u,y1,y2,truth"
    back = read_trace(p, inputs=["u"], outputs=["y2", "y1"])  # any column order; extra columns ignored
    np.testing.assert_array_equal(back.Y, tr.Y[:, ::-1])
    np.testing.assert_array_equal(back.t, t)


def test_missing_column_is_named(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("t,u,y1\n0,1,2\n")
    with pytest.raises(TraceError, match=r"no column 'y2' \(the output column\)"):
        read_trace(p, inputs=["u"], outputs=["y1", "y2"])
    with pytest.raises(TraceError, match=r"no column 'v' \(the input column\)"):
        read_trace(p, inputs=["v"], outputs=["y1"])


def test_ragged_row_is_named(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("t,u,y\n0,1,2\n0.1,1\n")
    with pytest.raises(TraceError, match="row 3 has 2 fields; the header has 3"):
        read_trace(p, inputs=["u"], outputs=["y"])
