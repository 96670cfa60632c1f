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
    if "P_f = 1e-310" in design or "arl0" in design:  # the plant file's own P_f line replaced (a budget is one of them)
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
    from fdisyn.reporting.page import summary_table, write_index
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


# --------------------------------------------------------------------------- NAFDF min_shift


def _nafdf(**options: Any) -> Any:
    import fdisyn

    make, base = BASE["nafdf"]
    return fdisyn.design(make(), method="nafdf", **{**base, **options})


@pytest.mark.parametrize("detector", ["wssr", "glr"])
@pytest.mark.parametrize("value", [1.0, 1, 2.0])
def test_any_min_shift_with_a_detector_that_does_not_read_it_is_refused(detector: str, value: float) -> None:
    with pytest.raises(ArgumentError, match=rf"min_shift = {value} is read only by the detector 'cusum' .*the detector here is '{detector}'"):
        _nafdf(detector=detector, min_shift=value)


def test_the_cusum_reads_min_shift_and_its_default_is_one() -> None:
    default, given = _nafdf(detector="cusum"), _nafdf(detector="cusum", min_shift=1.0)
    assert default.extensions["nafdf"]["settings"]["min_shift"] == given.extensions["nafdf"]["settings"]["min_shift"] == 1.0
    assert default.extensions["nafdf"]["detector_thresholds"] == given.extensions["nafdf"]["detector_thresholds"]
    assert _nafdf(detector="cusum", min_shift=2.0).extensions["nafdf"]["settings"]["min_shift"] == 2.0


@pytest.mark.parametrize("detector", ["wssr", "glr"])
def test_designs_without_the_cusum_record_the_default_shift_and_read_back(detector: str, tmp_path: Path) -> None:
    from fdisyn.runtime.gainfile import read_gain_file, write_gain_file
    from fdisyn.synthesis.nafdf.payload import nafdf_from_gain_file

    gf = _nafdf(detector=detector)
    assert gf.extensions["nafdf"]["settings"]["min_shift"] == 1.0  # the format every earlier gain file has
    write_gain_file(gf, tmp_path / "gains.json")
    assert nafdf_from_gain_file(read_gain_file(tmp_path / "gains.json")).settings.min_shift == 1.0


def test_a_stored_shift_other_than_the_default_without_the_cusum_is_refused(tmp_path: Path) -> None:
    import json

    from fdisyn.runtime.errors import GainFileError
    from fdisyn.runtime.gainfile import gain_file_from_dict, write_gain_file
    from fdisyn.synthesis.nafdf.payload import nafdf_from_gain_file

    write_gain_file(_nafdf(detector="wssr"), tmp_path / "gains.json")
    doc = json.loads((tmp_path / "gains.json").read_text(encoding="utf-8"))
    doc["extensions"]["nafdf"]["settings"]["min_shift"] = 2.0
    with pytest.raises((GainFileError, ArgumentError), match="min_shift = 2.0 is read only by the detector 'cusum'"):
        nafdf_from_gain_file(gain_file_from_dict(doc))


def test_a_plant_file_min_shift_with_the_wssr_is_refused_even_at_the_default_value() -> None:
    from tests.design.test_values_refused import _example, _refused

    doc = _example("ship")
    doc["design"].update({"min_shift": 1.0, "detector": "wssr"})
    _refused(doc, "min_shift = 1.0 is read only by the detector 'cusum'", "the detector here is 'wssr'", design=True)


@pytest.mark.parametrize(("options", "bound"), [
    ({"min_shift": 5.2}, "expected min_shift < 5.151 for this budget"),
    ({"min_shift": 1e6, "P_f": 1e-6}, "expected min_shift < 9.783 "),
])
def test_a_shift_that_one_sample_detects_within_the_budget_is_refused_naming_the_bound(options: dict[str, float], bound: str) -> None:
    options = {"P_f": 0.01, **options}  # the per-sample budget the bounds are stated for
    with pytest.raises(ArgumentError, match=rf"min_shift = {options['min_shift']!r} with P_f = {options['P_f']!r}: the CUSUM's threshold would be 0"):
        _nafdf(detector="cusum", **options)
    with pytest.raises(ArgumentError, match=bound):
        _nafdf(detector="cusum", **options)


def test_the_largest_shift_shown_designs_and_the_bound_is_the_zero_threshold_law() -> None:
    import math

    from fdisyn.detectors.sequential import cusum_arl, cusum_threshold
    from fdisyn.synthesis.nafdf.settings import largest_min_shift

    most = largest_min_shift(0.01, 2)
    assert cusum_arl(0.0, 0.5 * most**2) == pytest.approx(2 / 0.01, rel=1e-9)  # h = 0 there: a run of 1/Q(δ/2)
    assert cusum_threshold(2 / 0.01, 0.5 * 5.151**2) > 0.0
    gf = _nafdf(detector="cusum", min_shift=5.151, P_f=0.01)
    assert 0.0 < gf.extensions["nafdf"]["detector_thresholds"][0] < 1e-2
    assert math.isclose(largest_min_shift(1e-300, 1), 74.1, rel_tol=1e-3)


def test_an_arl0_budget_is_named_as_written() -> None:
    with pytest.raises(ArgumentError, match=r"min_shift = 8.0 with arl0 = 1000.0 s: the CUSUM's threshold would be 0 .*expected min_shift < "):
        _nafdf(detector="cusum", min_shift=8.0, arl0=1000.0)


# --------------------------------------------------------------------------- sample times that lose the plant or overflow


@pytest.mark.parametrize("method", ["lmi", "sampled_data_observer"])
def test_a_huge_sample_time_shows_its_value_and_the_range_that_works(method: str) -> None:
    import fdisyn

    make, base = BASE[method]
    with pytest.raises(ArgumentError) as info:
        fdisyn.design(make(), method=method, **{**base, "Ts": 1e308})
    line = str(info.value)
    assert "Ts = 1e+308 s is too long to sample this model" in line and "inf" not in line, line
    assert line.endswith("expected Ts < 354.9 s (and ≥ 4.063e-17 s)"), line


@pytest.mark.parametrize("ts", [1e-300, 1e-17])
def test_a_sample_time_that_loses_the_plant_is_refused_naming_ts(ts: float) -> None:
    import fdisyn

    make, base = BASE["beard_fdf"]
    with pytest.raises(ArgumentError) as info:  # a decay rate that keeps the bound below 1: only Ts is wrong
        fdisyn.design(make(), method="beard_fdf", **{**base, "Ts": ts, "decay_rate": 1e-6 / ts})
    line = str(info.value)
    assert f"Ts = {ts:g} s is too short to sample this model: e^(A·Ts) rounds to the identity" in line, line
    assert "zero column" not in line and line.endswith("expected Ts ≥ 1.57e-16 s (and < 709.8 s)"), line


def test_the_shortest_sample_time_shown_samples_the_plant() -> None:
    make, _ = BASE["beard_fdf"]
    plant = make()
    import numpy as np

    assert np.any(plant.discretise(1.58e-16).A != np.eye(3))  # the sampled model still moves
    with pytest.raises(ArgumentError, match=r"^Ts = 1e-16 s is too short"):
        plant.discretise(1e-16)


# --------------------------------------------------------------------------- beard_fdf: a model error below round-off


def test_a_model_error_below_round_off_designs_like_none() -> None:
    import fdisyn
    import numpy as np

    make, base = BASE["beard_fdf"]
    none, tiny = (fdisyn.design(make(), method="beard_fdf", **{**base, "sigma": s, "draws": 20}) for s in (0.0, 1e-300))
    a, b = none.extensions["beard_fdf"], tiny.extensions["beard_fdf"]
    np.testing.assert_array_equal(np.asarray(a["L"]), np.asarray(b["L"]))
    assert a["h"] == b["h"] and a["explicit_level"] == b["explicit_level"]
    y = np.asarray(b["Y_th"])  # a bound ∝ sigma where it is informative (π/2 where the eigen-directions are not Lipschitz)
    assert np.all((y < 1e-12) | (y == np.pi / 2))
    ratios = [c["value"] for c in tiny.certificate["beard_fdf"]["checks"] if c["name"].startswith("largest sampled residual-direction angle")]
    # where a bound is informative it is checked, and passes: round-off angles against the bound with round-off's
    # model error (with every bound π/2 there is no angle to check)
    assert len(ratios) == int(np.any(y < 1e-12)) and all(0.0 <= r <= 1.0 for r in ratios)


def test_a_model_error_that_matters_is_still_checked_against_its_own_bound() -> None:
    import fdisyn

    make, base = BASE["beard_fdf"]
    gf = fdisyn.design(make(), method="beard_fdf", **{**base, "sigma": 1e-4, "draws": 20})
    assert gf.certificate["passed"]
