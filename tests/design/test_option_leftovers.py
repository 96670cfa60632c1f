"""Option values that were accepted without a word, refused by an unrelated message, or refused with a raw
exception: each now designs as documented or is refused in one line naming the key as the user wrote it."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from fdisyn.runtime.errors import ArgumentError
from fdisyn.synthesis.registry import check_options, get_method

from tests.design.test_cli_hostile import _fails_with
from tests.design.test_option_domains import BASE
from tests.design.test_uio_gos_plant_file import _plant_file

LINEAR = ["kalman_uio", "kalman_uio_paper", "kalman_uio_gos", "uio_pole_placement", "lmi", "sampled_data_observer"]


def _linear(method: str, **given: Any) -> dict[str, Any]:
    make, base = BASE[method]
    return check_options(get_method(method), {**base, **given}, plant=make())


# --------------------------------------------------------------------------- detector and evaluator, one option


@pytest.mark.parametrize("method", LINEAR)
@pytest.mark.parametrize(("detector", "evaluator"), [("wssr", "chi2"), ("chi2", "wssr"), ("cusum", "chi2"), ("glr", "wssr")])
def test_a_detector_and_an_evaluator_that_disagree_are_refused_by_every_linear_method(method: str, detector: str, evaluator: str) -> None:
    with pytest.raises(ArgumentError, match=rf"option detector = '{detector}' but evaluator = '{evaluator}': they are the same option, give one"):
        _linear(method, detector=detector, evaluator=evaluator)


@pytest.mark.parametrize("method", LINEAR)
def test_either_name_or_both_agreeing_choose_the_detector(method: str) -> None:
    import fdisyn

    make, base = BASE[method]
    default = "wssr" if method == "kalman_uio_gos" else "chi2"
    for given, kind in (({}, default), ({"evaluator": "wssr"}, "wssr"), ({"detector": "wssr"}, "wssr"),
                        ({"detector": "chi2", "evaluator": "chi2"}, "chi2")):
        _linear(method, **given)
        if method == "kalman_uio":  # the bank's statistic itself (a cheap design)
            gf = fdisyn.design(make(), method=method, **base, **given)
            assert {e.kind for e in gf.evaluators} == {kind}, (given, kind)


def test_a_plant_file_names_both_keys_of_a_disagreeing_pair(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    spec = _plant_file(tmp_path, 'detector = "wssr"\nevaluator = "chi2"', with_e=True)
    _fails_with(capsys, ["design", spec, "--out", str(tmp_path / "o")], "[design].detector = 'wssr' but evaluator = 'chi2'")


# --------------------------------------------------------------------------- kalman_uio_gos: its budget named as written


@pytest.mark.parametrize(("design", "expected"), [
    ("arl0 = 1e308", "[design].arl0 = 1e+308 s gives each of the 8 statistics a mean run length of more than 1e+300 samples"),
    ("arl0 = 1e-3", "[design].arl0 = 0.001 s gives each of the 8 statistics a mean run length of 0.16 samples"),
    ('arl0 = 1e308\ngroups = [["y1", "y2", "y3", "y4"], ["y5", "y2", "y3", "y4"]]',
     "[design].arl0 = 1e+308 s gives each of the 8 statistics"),
    ('detector = "cusum"\nP_f = 1e-310', "[design].P_f = 1e-310 with detector 'cusum'"),
])
def test_the_gos_budget_is_refused_naming_the_plant_file_key(tmp_path: Path, capsys: pytest.CaptureFixture[str], design: str, expected: str) -> None:
    spec = _plant_file(tmp_path, design, with_e=True)
    if "P_f = 1e-310" in design:  # the plant file's own P_f line replaced
        Path(spec).write_text(Path(spec).read_text(encoding="utf-8").replace("P_f = 1e-4\n", ""), encoding="utf-8")
    _fails_with(capsys, ["design", spec, "--out", str(tmp_path / "o")], expected)


# --------------------------------------------------------------------------- --option values read strictly


@pytest.mark.parametrize(("value", "key"), [('{"a": 1, "a": 2}', "'a'"), ('[{"b": {"c": 1, "c": 1}}]', "'c'")])
def test_an_option_value_with_a_repeated_key_is_refused(value: str, key: str) -> None:
    from fdisyn.app.cli import _options

    with pytest.raises(ArgumentError, match=rf"^--option bank: key {key} appears more than once"):
        _options([f"bank={value}"])


def test_option_values_are_read_as_before_otherwise() -> None:
    import math

    from fdisyn.app.cli import _options

    got = _options(["a=1e-3", "b=[1, 2]", 'c={"x": 1, "y": [2]}', "d=paper", "e=NaN", 'f="x"'])
    assert {k: v for k, v in got.items() if k != "e"} == {"a": 1e-3, "b": [1, 2], "c": {"x": 1, "y": [2]}, "d": "paper", "f": "x"}
    assert math.isnan(got["e"])  # refused by the option's domain, as written (`option P_f = nan`)


def test_a_repeated_key_in_an_option_is_one_line_and_status_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _fails_with(capsys, ["design", "wind_turbine", "--out", str(tmp_path / "d"), "--option", 'P_f={"a": 1, "a": 2}'],
                "--option P_f: key 'a' appears more than once")


def test_a_metrics_document_with_a_repeated_key_is_refused(tmp_path: Path) -> None:
    from fdisyn.app.report import summary_table, write_index
    from fdisyn.runtime.errors import FileError

    (tmp_path / "p").mkdir()
    doc = tmp_path / "p" / "metrics.json"
    doc.write_text('{"problem": "p", "verdict": {"title": "t", "claims": 1, "reproduced": 0, "reproduced": 1}, "summary": []}\n',
                   encoding="utf-8")
    for read in (lambda: write_index(tmp_path), lambda: summary_table(tmp_path, ["p"])):
        with pytest.raises(FileError, match=r"metrics\.json: key 'reproduced' appears more than once in verdict"):
            read()
    doc.write_text('{"problem": "p", "verdict": {"title": "t", "claims": 1, "reproduced": 1}, "summary": []}\n', encoding="utf-8")
    assert "1 of 1 claims reproduced" in write_index(tmp_path).read_text(encoding="utf-8")


# --------------------------------------------------------------------------- covariances: finiteness before arithmetic


@pytest.mark.parametrize("value", [float("inf"), -float("inf"), float("nan"), [1.0, float("inf")]])
def test_a_non_finite_covariance_is_refused_without_a_numpy_warning(value: object) -> None:
    import warnings

    from fdisyn.numerics.linalg import as_covariance

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a RuntimeWarning from inf · I would fail here
        with pytest.raises(ArgumentError, match=r"^Q must hold finite variances; got "):
            as_covariance(value, "Q", 2)


def test_a_non_finite_noise_in_a_plant_is_one_line_without_a_warning() -> None:
    import warnings

    from fdisyn.models.nonlinear import NonlinearPlant

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ArgumentError, match=r"Q must hold finite variances; got inf"):
            NonlinearPlant.from_expressions(states=["x", "z"], inputs=[], outputs=["y"], parameters=["a"], nominal={"a": -0.5},
                                            f={"x": "a*x", "z": "a*z"}, h={"y": "x"}, Q=float("inf"), R=[[0.01]])
