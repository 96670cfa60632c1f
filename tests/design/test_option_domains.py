"""Every numeric option of every method at the edges of the number line (0, tiny, huge, negative, NaN, ±inf, a
huge whole number): through ``fdisyn.design`` each ends in a design or in one of fdisyn's own errors naming the
option, never in a raw Python exception, a hang or an allocation sized by the value; through a plant file the
same value is refused naming ``[design].KEY``. Plants are tiny and the designs the cheapest of each method."""

from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fdisyn.app.cli import main
from fdisyn.detectors import sequential
from fdisyn.models.linear import LinearPlant
from fdisyn.models.nonlinear import NonlinearPlant
from fdisyn.runtime.errors import ArgumentError, FdisynError
from fdisyn.synthesis import registry

C3 = [[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]


def _discrete() -> LinearPlant:
    return LinearPlant.create(A=[[0.5, 0.1], [0.0, 0.7]], C=C3, E=[[1.0], [0.0]], Q=np.eye(2) * 1e-3, R=np.eye(3) * 1e-2, Ts=0.1)


def _continuous() -> LinearPlant:
    return LinearPlant.create(A=[[-1.0, 5.0], [0.0, -2.0]], B=[[0.0], [1.0]], C=np.eye(2), E=[[0.1], [1.0]], R=np.zeros((2, 2)))


def _nonlinear() -> NonlinearPlant:
    return NonlinearPlant.from_expressions(
        states=["x"], inputs=["u"], outputs=["y"], parameters=["a"], nominal={"a": -0.5}, f={"x": "0.5*x + a*u"}, h={"y": "x"},
        Q=[[0.0]], R=[[0.01]],
    )


def _beard() -> LinearPlant:
    return LinearPlant.create(
        A=[[0.0, 1.0, 0.0], [0.01, 0.0, 1.0], [0.0, 0.0, -1.0]], B=[[0.0], [0.0], [1.0]], C=[[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
        Fx=[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], Q=np.diag([0.0, 1e-4, 1e-4]), R=np.eye(2) * 1e-4,
    )


# the cheapest design of each method: a plain Beard filter with given levels and no model error, a two-state UIO
BASE: dict[str, tuple[Any, dict[str, Any]]] = {
    "beard_fdf": (_beard, {"Ts": 0.1, "decay_rate": 2.0, "eigenstructure": "plain", "h": 0.02, "explicit_level": 0.007}),
    "kalman_uio": (_discrete, {}),
    "kalman_uio_paper": (_discrete, {}),
    "kalman_uio_gos": (_discrete, {}),
    "uio_pole_placement": (_discrete, {"poles": [0.1, 0.2]}),
    "lmi": (_continuous, {"Ts": 0.1}),
    "sampled_data_observer": (_continuous, {"Ts": 0.1}),
    "nafdf": (_nonlinear, {}),
    "nullspace": (_discrete, {}),
}
VALUES = [0, 1e-300, 1e308, -1, math.nan, math.inf, -math.inf, 10**12]
SEQUENTIAL = {"P_f", "arl0", "window", "min_fault", "min_shift"}
"""Options whose reading depends on the detector: swept with each detector that reads them."""
LISTS = {"x0", "theta0", "theta_lower", "theta_upper", "isolable_jump", "convergence_tolerance", "u0", "poles"}
NOT_NUMBERS = {"bank", "faults", "sensor_faults", "eigenvalues", "training", "groups", "virtual_outputs", "sensors", "detector",
               "evaluator", "threshold_rule", "eigenstructure", "sampling", "eta", "fault_free", "structure"}


def _detectors(method: str, option: str) -> list[str | None]:
    if option not in SEQUENTIAL or method == "beard_fdf":
        return [None]
    if method == "nafdf":
        return {"min_shift": ["cusum"], "window": ["wssr", "glr"]}.get(option, ["wssr", "cusum", "glr"])
    return {"min_fault": ["cusum", "glr"], "window": ["wssr", "glr"]}.get(option, ["chi2", "wssr", "cusum", "glr"])


def _cases() -> list[Any]:
    out = []
    for m in registry.all_methods():
        for o in m.options:
            if o.name in NOT_NUMBERS:
                continue
            for det in _detectors(m.name, o.name):
                out += [pytest.param(m.name, o.name, det, v, id=f"{m.name}-{o.name}-{det}-{v!r}") for v in VALUES]
    return out


def _options(method: str, option: str, detector: str | None, value: Any) -> dict[str, Any]:
    opts = dict(BASE[method][1])
    if detector is not None:
        opts["detector"] = detector
    size = {"poles": 2}.get(option, 1)
    opts[option] = {"y0": value} if option == "min_fault" else [value] * size if option in LISTS else value
    return opts


@pytest.mark.parametrize(("method", "option", "detector", "value"), _cases())
def test_every_numeric_option_ends_in_a_design_or_a_refusal(method: str, option: str, detector: str | None, value: Any) -> None:
    import fdisyn

    plant = BASE[method][0]()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            fdisyn.design(plant, method=method, **_options(method, option, detector, value))
        except FdisynError as exc:
            text = str(exc)
            assert "\n" not in text
            if isinstance(value, float) and value == 1e308:  # the value as the user wrote it, never its overflow
                assert "got inf" not in text and "found inf" not in text, text


def test_the_sweep_covers_every_method() -> None:
    assert {m.name for m in registry.all_methods()} == set(BASE)


# --------------------------------------------------------------------------- the values the issue measured


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"window": 10**9}, "[design].window = 1000000000: expected a whole number of samples in 1..2039"),
        ({"window": 1500}, "[design].window = 1500: the diagnoser state holds window × outputs + states + 5 entries"),
        ({"draws": 10**12}, "[design].draws = 1000000000000: expected a whole number in 0..10000"),
        ({"noise_gain": 1e200}, "[design].noise_gain = 1e+200: expected a number in [1, 1e+06]"),
        ({"sigma": 1e308}, "[design].sigma = 1e+308: the bound it gives on the sampled model error overflows"),
    ],
)
def test_beard_sizes_are_refused_in_the_plant_file_before_any_allocation(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], options: dict[str, Any], message: str
) -> None:
    from fdisyn.app.examples import EXAMPLES

    text = (EXAMPLES / "beard_textbook.toml").read_text(encoding="utf-8")
    lines = [ln for ln in text.splitlines() if not any(ln.startswith(f"{k} =") for k in options)]
    at = lines.index("[design]") + 1
    lines[at:at] = [f"{k} = {v!r}" for k, v in options.items()]
    path = tmp_path / "beard.toml"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    assert main(["design", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err and "extensions" not in err, err


def test_beard_window_and_draws_from_python_name_the_option() -> None:
    import fdisyn

    base = BASE["beard_fdf"][1]
    with pytest.raises(ArgumentError, match=r"method 'beard_fdf': option window = 1500: .* expected window ≤ 1018 for 2 outputs and 3 states"):
        fdisyn.design(_beard(), method="beard_fdf", **{**base, "window": 1500})
    with pytest.raises(ArgumentError, match="option fault_free = \\[\\]: expected a non-empty list"):
        fdisyn.design(_beard(), method="beard_fdf", **{**base, "fault_free": []})


@pytest.mark.parametrize("detector", ["cusum", "glr"])
def test_a_long_budget_is_computed_and_a_beyond_range_one_names_the_domain(detector: str) -> None:
    import fdisyn

    gf = fdisyn.design(_discrete(), method="kalman_uio", detector=detector, arl0=1e12)
    assert all(math.isfinite(e.threshold) and e.threshold > 20 for e in gf.evaluators)
    gf = fdisyn.design(_discrete(), method="kalman_uio", detector=detector, P_f=1e-300)
    assert all(650 < e.threshold < 700 for e in gf.evaluators)
    # no bank: the default one, a generator per sensor on the other outputs (three statistics)
    with pytest.raises(ArgumentError, match=r"option arl0 = 1e\+308 s gives each of the 3 statistics a mean run length of more than 1e\+300 samples"):
        fdisyn.design(_discrete(), method="kalman_uio", detector=detector, arl0=1e308)
    with pytest.raises(ArgumentError, match=r"option P_f = 1e-310 with detector .* expected P_f ≥ 1e-300"):
        fdisyn.design(_discrete(), method="kalman_uio", detector=detector, P_f=1e-310)


def test_nafdf_extremes_are_computed_or_refused_with_the_domain() -> None:
    import fdisyn

    fdisyn.design(_nonlinear(), method="nafdf", detector="cusum", min_shift=1e-6)
    # a shift this large alarms at its first sample: refused before the design, with the largest shift that works
    with pytest.raises(ArgumentError, match=r"min_shift = 1000000.0 with P_f = 0.01: the CUSUM's threshold would be 0 .* expected min_shift < 5.151 "):
        fdisyn.design(_nonlinear(), method="nafdf", detector="cusum", min_shift=1e6, P_f=0.01)
    # the same at the default budget (arl0, one hour), saying that it is the default
    with pytest.raises(ArgumentError, match=r"min_shift = 1000000.0 with arl0 = 3600.0 s: .* expected min_shift < 7.255 .* is the default false-alarm budget"):
        fdisyn.design(_nonlinear(), method="nafdf", detector="cusum", min_shift=1e6)
    with pytest.raises(ArgumentError, match=r"option min_shift = 1e\+308: expected a number of standard deviations in \[1e-06, 1e\+06\]"):
        fdisyn.design(_nonlinear(), method="nafdf", detector="cusum", min_shift=1e308)
    with pytest.raises(ArgumentError, match=r"arl0 = 1e\+308 s gives each of the detector's 2 statistics .* expected arl0 ≤"):
        fdisyn.design(_nonlinear(), method="nafdf", detector="cusum", arl0=1e308)


# --------------------------------------------------------------------------- the laws in log-space


@pytest.mark.parametrize("arl", [1e9, 1e12, 1e50, 1e200, 1e300])
def test_sequential_thresholds_grow_as_the_log_of_the_run_length(arl: float) -> None:
    # ln ARL₀ ≈ h for a CUSUM on a log-likelihood ratio (Siegmund 1985): the threshold is within a few nats of it
    h = sequential.cusum_threshold(arl, 0.5)
    assert abs(h - math.log(arl)) < 5.0
    assert abs(sequential.cusum_log_arl(h, 0.5) - math.log(arl)) < 1e-8
    g = sequential.glr_threshold(arl, 10)
    assert abs(sequential.glr_log_arl(g, 10) - math.log(arl)) < 1e-8


def test_the_tilted_run_length_agrees_with_page_s_equation_where_both_are_accurate() -> None:
    for info in (0.05, 0.5, 2.0):
        for h in (1.0, 3.0, 6.0):
            direct = sequential._cusum_arl_nystrom(h, info, 0.0, 96)
            assert math.exp(sequential._cusum_log_arl0_tilted(h, info)) == pytest.approx(direct, rel=1e-9)
    # beyond the direct solve's reach: Siegmund's approximation within a few per cent
    for info in (0.5, 2.0):
        h = 30.0
        assert math.exp(sequential._cusum_log_arl0_tilted(h, info)) == pytest.approx(sequential.cusum_arl_siegmund(h, info), rel=0.1)
