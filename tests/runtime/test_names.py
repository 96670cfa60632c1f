"""The name grammar of fdisyn.runtime.names: what each kind of name accepts and refuses, and why."""

from __future__ import annotations

import re

import numpy as np
import pytest
from fdisyn.runtime.errors import ArgumentError, GainFileError, SpecError
from fdisyn.runtime.names import (
    DIAGNOSER_NAME_MAX,
    FAULT_NAME_MAX,
    SIGNAL_NAME_MAX,
    check_diagnoser_name,
    check_distinct,
    check_fault_name,
    check_label,
    check_signal_name,
    check_signal_names,
    shown,
)

HOSTILE = 'x", 0}; __attribute__((constructor)) static void pwn(void){} static const char *y[] = {"'


@pytest.mark.parametrize("name", ["y", "omega_r_m1", "Y2", "a__b", "x" * SIGNAL_NAME_MAX])
def test_signal_names_accepted(name):
    assert check_signal_name(name, "output") == name


@pytest.mark.parametrize(
    ("name", "message"),
    [
        ("", "is not a signal name"),
        ("_y", "is not a signal name"),  # identifiers starting with '_' are partly reserved to C
        ("2y", "is not a signal name"),
        ("y 1", "is not a signal name"),  # a blank is stripped by the CSV reader
        ("y,1", "is not a signal name"),  # a comma splits a CSV header
        ('y"', "is not a signal name"),
        ("ÿ", "is not a signal name"),
        ("y\n", "is not a signal name"),  # `$` would match before a final newline; the grammar does not
        (HOSTILE, "is not a signal name"),
        ("x" * (SIGNAL_NAME_MAX + 1), "at most 63 characters"),
        ("t", "is reserved .*time column"),
        ("fault_active", "is reserved .*fdisyn simulate"),
        (3, "must be a string, found int"),
        (None, "must be a string, found NoneType"),
    ],
)
def test_signal_names_refused(name, message):
    with pytest.raises(ArgumentError, match=message):
        check_signal_name(name, "output")


def test_the_error_class_is_the_callers():
    with pytest.raises(SpecError, match=r"plant.toml \[signals\].outputs\[1\] 't' is reserved"):
        check_signal_names(["y", "t"], "plant.toml [signals].outputs", error=SpecError)
    with pytest.raises(GainFileError, match="must be unique; repeated: \\['y'\\]"):
        check_signal_names(["y", "z", "y"], "outputs", error=GainFileError)
    with pytest.raises(ArgumentError, match="expected 2 names to match the matrices, found 1"):
        check_signal_names(["y"], "output names", count=2)
    with pytest.raises(ArgumentError, match="must be a list of names, found str"):
        check_signal_names("y", "output names")


def test_a_long_hostile_value_is_cut_in_the_message():
    with pytest.raises(ArgumentError) as err:
        check_signal_name("x;" * 5000, "output")
    assert len(str(err.value)) < 300 and "(10002 characters)" in str(err.value) and "\n" not in str(err.value)


def test_every_value_is_quoted_on_one_short_line():
    """Strings whole up to the limit, containers to a bounded depth and length, NumPy's line breaks folded,
    and values whose repr would recurse or could not be converted quoted all the same."""
    assert shown("abc") == "'abc'"
    assert shown([0.5, "x"]) == "[0.5, 'x']"
    deep: list = []
    node = deep
    for _ in range(5000):  # repr() of this list raises RecursionError
        node.append([])
        node = node[0]
    assert shown(deep) == "[[[[...]]]]"
    assert shown(list(range(10**6))) == "[0, 1, 2, 3, 4, 5, 6, 7, ...]"
    assert shown(10**5000) == "<an integer of 16610 bits>"  # beyond Python's int → str digit limit
    text = shown(np.arange(100.0).reshape(10, 10), limit=60)
    assert "\n" not in text and len(text) == 61 and text.endswith("…")


@pytest.mark.parametrize("name", ["f", "omega_r_m1+omega_g_m1", "a|b|c", "a+b|c"])
def test_fault_names_accepted(name):
    assert check_fault_name(name, "faults[0]") == name


@pytest.mark.parametrize("name", ["", "a+", "+a", "a||b", "a b", "a-b", HOSTILE, "x" * (FAULT_NAME_MAX + 1), "a\x00b"])
def test_fault_names_refused(name):
    with pytest.raises(ArgumentError, match="not a fault name"):
        check_fault_name(name, "faults[0]")


@pytest.mark.parametrize("name", ["dc_motor_kalman_uio", "wind_turbine_paper_kalman_uio_paper", "a", "x" * DIAGNOSER_NAME_MAX])
def test_diagnoser_names_accepted(name):
    assert check_diagnoser_name(name, "name") == name


@pytest.mark.parametrize(
    ("name", "message"),
    [
        ("dc__motor", "no '__'"),
        ("_dc", "starts with a letter"),
        ("dc_", "no trailing '_'"),  # <name>_step would hold '__'
        ("x" * (DIAGNOSER_NAME_MAX + 1), "at most 64 characters"),
        ("x" * 300, "at most 64 characters"),  # would exceed the file-name limit in lib<name>.so
        ("wind-turbine", "cannot prefix the generated C API"),
        ("replay", "reserved: .*replay.c"),
        ("bench", "reserved: .*bench.c"),
        ("casadi_f0", "reserved: CasADi"),
        ("CASADI", "reserved: CasADi"),
    ],
)
def test_diagnoser_names_refused(name, message):
    with pytest.raises(ArgumentError, match=message):
        check_diagnoser_name(name, "name")


def test_labels():
    for ok in ("kalman_uio", "uio_r_m1_g_m1.omega_r_m1", "J_g0", "2nd-design", "a+b|c"):
        assert check_label(ok, "design") == ok
    for bad in ("", "*/ x /*", "a b", "../x", "a/b", ".hidden", "x" * 65):
        with pytest.raises(ArgumentError, match="is not a label"):
            check_label(bad, "design", max_length=64)


def test_distinct_names_both_places():
    with pytest.raises(ArgumentError, match=r"the name 'w' is used by the states and by the outputs; names must be distinct across the states, inputs, outputs \(one CSV\)"):
        check_distinct({"states": ("x", "w"), "inputs": ("u",), "outputs": ("w",)}, why="one CSV")
    check_distinct({"states": ("x",), "outputs": ("y",)}, why="one CSV")  # nothing shared: no error


@pytest.mark.parametrize(
    ("check", "name", "folded"),
    [(check_signal_name, "ｘ", "x"), (check_signal_name, "ﬂow", "flow"), (check_fault_name, "ｙ1+y2", "y1+y2"),
     (check_diagnoser_name, "ｍotor", "motor"), (check_label, "ｐlant", "plant")],
)
def test_a_name_that_folds_into_another_says_so(check, name: str, folded: str) -> None:  # noqa: ANN001
    """Names are compared exactly: a compatibility character (fullwidth, ligature) is never the ASCII name it resembles."""
    with pytest.raises(ArgumentError, match=rf"reads as '{re.escape(folded)}' only after Unicode NFKC normalisation, and names are compared exactly"):
        check(name, "name")


def test_a_non_ascii_name_that_folds_into_nothing_valid_is_refused_plainly() -> None:
    with pytest.raises(ArgumentError, match=r"'é' is not a signal name \(it holds non-ASCII characters\): expected a letter"):
        check_signal_name("é", "name")
