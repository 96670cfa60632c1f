"""Values fdisyn used to accept without a word — ignored, or converted into something else — now refused in one
line naming what is wrong and what to write instead (or, where meaningful, honoured)."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fdisyn.app.examples import example_path
from fdisyn.simulation.plant_file import problem_from_document
from fdisyn.models.linear import LinearPlant
from fdisyn.models.nonlinear import NonlinearPlant
from fdisyn.models.sampled_data import SampledDataPlant
from fdisyn.runtime.errors import ArgumentError, SpecError
from fdisyn.runtime.monitor import Monitor
from fdisyn.synthesis.registry import check_options, get_method

from tests.runtime.test_reference import toy


def _example(name: str) -> dict[str, Any]:
    return tomllib.loads(example_path(name).read_text(encoding="utf-8"))


def _refused(doc: dict[str, Any], *expected: str, design: bool = False) -> str:
    with pytest.raises(SpecError) as info:
        problem = problem_from_document(doc, Path("plant.toml"))
        if design:
            problem.design()
    line = str(info.value)
    assert "\n" not in line
    for part in expected:
        assert part in line, (part, line)
    return line


# --------------------------------------------------------------------------- numbers given as text


@pytest.mark.parametrize("ts", ["1_0", "１", "٣", "0.1", b"1", True, [0.1]])
def test_a_sample_time_that_is_not_a_number_is_refused_not_converted(ts: object) -> None:
    with pytest.raises(ArgumentError, match=r"^Ts must be a positive number of seconds; got \w+ "):
        LinearPlant.create(A=[[-1.0]], C=[[1.0]], Ts=ts)


def test_every_model_reads_its_sample_time_by_one_rule() -> None:
    plant = LinearPlant.create(A=[[-1.0]], B=[[1.0]], C=[[1.0]])
    with pytest.raises(ArgumentError, match="Ts must be a positive number of seconds; got str '1_0'"):
        plant.discretise("1_0")  # type: ignore[arg-type]
    with pytest.raises(ArgumentError, match="Ts must be a positive number of seconds; got str '1'"):
        SampledDataPlant.create(A=[[-1.0]], B=[[1.0]], E=[[1.0]], Fx=[[1.0]], C=[[1.0]], Ts="1")  # type: ignore[arg-type]
    with pytest.raises(ArgumentError, match="Ts must be a positive number of seconds; got str '2'"):
        NonlinearPlant.from_expressions(states=["x"], inputs=[], outputs=["y"], parameters=["a"], nominal={"a": 1.0},
                                        f={"x": "a*x"}, h={"y": "x"}, Q=[[0.0]], R=[[1.0]], Ts="2")  # type: ignore[arg-type]
    # numbers of any real type are read
    assert LinearPlant.create(A=[[-1.0]], C=[[1.0]], Ts=np.float32(0.5)).Ts == 0.5
    assert LinearPlant.create(A=[[-1.0]], C=[[1.0]], Ts=2).Ts == 2.0


# --------------------------------------------------------------------------- names compared exactly


def _ship_with(f: str) -> dict[str, Any]:
    doc = _example("ship")
    doc["model"]["f"] = {"x": f}
    return doc


@pytest.mark.parametrize(("expr", "word", "name"), [("0.1*a*ｘ^2 + x + 0.1*b*u", "ｘ", "x"), ("ａ*x + u", "ａ", "a"),
                                                   ("x + ｐｉ", "ｐｉ", "pi")])
def test_a_fullwidth_name_in_an_expression_is_not_read_as_the_name(expr: str, word: str, name: str) -> None:
    _refused(_ship_with(expr), f"f['x']: {word!r} in", f"is not the name {name!r}", "NFKC", f"write {name!r}")


@pytest.mark.parametrize(("expr", "char"), [("x − 1", "U+2212"), ("x + é", "U+00E9"), ("x + ﬁ", "U+FB01"), ("x\u00a0+ 1", "U+00A0")])
def test_any_other_non_ascii_character_in_an_expression_is_named(expr: str, char: str) -> None:
    _refused(_ship_with(expr), "f['x']:", "non-ASCII character", char)


@pytest.mark.parametrize("number", ["1_0", "0x10", "0o7", "0b1", "1_000.5"])
def test_a_number_of_python_s_other_grammars_in_an_expression_is_refused(number: str) -> None:
    _refused(_ship_with(f"x + {number}"), f"the number {number!r}", "is not a decimal numeral")


def test_decimal_numerals_in_an_expression_are_read() -> None:
    problem_from_document(_ship_with("x*1e-3 + .5 + 2. + 3E+2 + 0.1*a*x + 0.1*b*u"), Path("plant.toml"))


def test_a_fullwidth_signal_name_says_what_it_would_read_as() -> None:
    doc = _example("ship")
    doc["signals"]["states"] = ["ｘ"]
    _refused(doc, "[signals].states[0] 'ｘ' is not a signal name", "reads as 'x' only after Unicode NFKC normalisation")


# --------------------------------------------------------------------------- text fields


@pytest.mark.parametrize("value", [[1, 2], math.nan, 3, True, {"a": 1}])
def test_a_title_that_is_not_text_is_refused(value: object) -> None:
    doc = _example("dc_motor")
    doc["title"] = value
    _refused(doc, "plant.toml.title must be a string")


@pytest.mark.parametrize("example", ["dc_motor", "ship"])
@pytest.mark.parametrize("value", [math.nan, [1], 2.5])
def test_a_scenario_description_that_is_not_text_is_refused(example: str, value: object) -> None:
    doc = _example(example)
    doc["scenarios"][0]["description"] = value
    _refused(doc, "[[scenarios]][0].description must be a string")


def test_a_matrix_under_the_papers_letter_is_named_by_that_letter() -> None:
    doc = _example("sampled_data")
    doc["model"]["Bd"][0][0] = math.inf
    _refused(doc, "[model].Bd must hold finite numbers; entry [0, 0] is inf")
    doc = _example("sampled_data")
    doc["model"]["h"] = "1"
    _refused(doc, "[model].h must be a number, got '1'")


def test_a_model_time_that_is_no_kind_is_named_before_anything_else() -> None:
    doc = _example("ship")
    doc["model"]["time"] = "nonlinear "
    _refused(doc, "[model].time must be 'continuous', 'discrete' or 'nonlinear', got 'nonlinear '")


# --------------------------------------------------------------------------- options without effect


def test_beard_fault_free_records_with_both_levels_given_are_refused() -> None:
    plant = LinearPlant.create(A=[[-1.0, 0.0], [0.0, -2.0]], B=[[1.0], [0.0]], C=np.eye(2), Fx=np.eye(2), Ts=0.1)
    records = [(np.zeros((50, 1)), np.zeros((50, 2)))]
    opts = {"decay_rate": 2.0, "h": 0.02, "explicit_level": 0.007, "fault_free": records}
    with pytest.raises(ArgumentError, match="option fault_free: the records only estimate h and explicit_level, and both are given"):
        check_options(get_method("beard_fdf"), opts, plant=plant)
    for left_out in ("h", "explicit_level"):  # one of them estimated from the records: fault_free is read
        rest = {k: v for k, v in opts.items() if k != left_out}
        assert check_options(get_method("beard_fdf"), rest, plant=plant)["fault_free"] is records


@pytest.mark.parametrize("detector", ["wssr", "glr"])
def test_nafdf_min_shift_without_the_cusum_is_refused(detector: str) -> None:
    doc = _example("ship")
    doc["design"].update({"min_shift": 2.0, "detector": detector})
    _refused(doc, "min_shift = 2.0 is read only by the detector 'cusum'", f"the detector here is {detector!r}", design=True)


def test_nafdf_min_shift_with_the_cusum_is_read() -> None:
    doc = _example("ship")
    doc["design"].update({"min_shift": 2.0, "detector": "cusum"})
    problem_from_document(doc, Path("plant.toml"))  # the design itself is the NAFDF suite's


# --------------------------------------------------------------------------- the Monitor's backend


@pytest.mark.parametrize("backend", ["bogus", "Reference", None, 1])
def test_a_monitor_backend_that_is_none_of_the_three_is_refused(backend: object, tmp_path: Path) -> None:
    with pytest.raises(ArgumentError, match=r"^backend = .*: expected 'auto', 'compiled' or 'reference'$"):
        Monitor.from_directory(tmp_path / "nowhere", backend=backend)  # type: ignore[arg-type]  # refused before reading
    with pytest.raises(ArgumentError, match="expected 'auto', 'compiled' or 'reference'"):
        Monitor(toy(), backend=backend)  # type: ignore[arg-type]


def test_the_reference_backend_is_still_chosen_by_name() -> None:
    assert Monitor(toy(), backend="reference").backend == "reference"
    assert Monitor(toy()).backend == "reference"



def test_nafdf_min_shift_without_the_cusum_is_refused_from_python() -> None:
    from fdisyn.problems import ship_propulsion as sp
    from fdisyn.synthesis.nafdf.design import nafdf

    with pytest.raises(ArgumentError, match=r"^min_shift = 0.5 is read only by the detector 'cusum' .* the detector here is 'wssr'"):
        nafdf(sp.plant(), x0=[0.0], P0=100.0, theta0=[0.0, 0.0], min_shift=0.5)


@pytest.mark.parametrize(("kw", "key"), [({"duration": "1_0"}, "duration"), ({"onset": "1"}, "onset"), ({"end": True}, "end"),
                                          ({"duration": math.nan}, "duration")])
def test_a_scenario_time_that_is_not_a_number_is_refused(kw: dict[str, Any], key: str) -> None:
    from fdisyn.simulation.problem import Scenario

    args = {"duration": 10.0, "fault": "y", "onset": 5.0, **kw}
    with pytest.raises(ArgumentError, match=rf"scenario 's': {key} must be a finite number of seconds; got "):
        Scenario("s", "a scenario", **args)


@pytest.mark.parametrize("idx", [["0"], ["１"], [True], [0.0]])
def test_output_indices_that_are_not_whole_numbers_are_refused(idx: list[Any]) -> None:
    plant = LinearPlant.create(A=[[-1.0]], C=[[1.0], [2.0]])
    with pytest.raises(ArgumentError, match="output indices must be whole numbers"):
        plant.select_outputs(idx)
    assert plant.select_outputs([np.int64(1)]).outputs == ("y1",)


def test_a_library_given_to_the_reference_backend_is_refused_not_dropped(tmp_path: Path) -> None:
    # the NumPy reference would run and the library named beside it would be ignored without a word
    with pytest.raises(ArgumentError, match=r"^library = .* with backend = 'reference': the NumPy reference runs no library"):
        Monitor(toy(), library=tmp_path / "libx.so", backend="reference")


def test_a_plant_entry_beyond_what_a_gain_file_holds_is_refused_when_the_plant_is_built() -> None:
    # refused by the plant, with a remedy, not later by the gain-file reader ("write the file again")
    from fdisyn.models.linear import LinearPlant

    with pytest.raises(ArgumentError, match=r"^B\[0, 0\] is 1e\+160; a plant's entries must be at most 1e\+150 in magnitude"):
        LinearPlant.create(A=[[0.5, 0.0], [0.0, 0.3]], B=[[1e160], [1.0]], C=[[1.0, 0.0], [0.0, 1.0]], Ts=0.1)
    LinearPlant.create(A=[[0.5, 0.0], [0.0, 0.3]], B=[[1e150], [1.0]], C=[[1.0, 0.0], [0.0, 1.0]], Ts=0.1)  # at the bound


@pytest.mark.parametrize("gf", ["x", None, {"format": "fdisyn.gains/1"}])
def test_a_monitor_of_something_other_than_a_gain_file_is_refused(gf: object) -> None:
    with pytest.raises(ArgumentError, match=r"^Monitor takes a GainFile .*use Monitor.from_directory\(path\)$"):
        Monitor(gf)  # type: ignore[arg-type]
