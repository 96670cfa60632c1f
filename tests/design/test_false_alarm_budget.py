"""The false-alarm budget as a time: ``arl0`` (the diagnoser's mean time between false alarms) by default, ``P_f``
(per statistic and sample) as an explicit choice, both refused; the budget on the terminal and the false alarms
on the pages as durations an operator reads."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from fdisyn.app.cli import main
from fdisyn.app.examples import EXAMPLES
from fdisyn.reporting.budget import budget_line
from fdisyn.reporting.kit import duration, false_alarm_time, false_alarms_pooled
from fdisyn.reporting.page import _summary_false_alarms
from fdisyn.models.linear import LinearPlant
from fdisyn.models.nonlinear import NonlinearPlant
from fdisyn.runtime.errors import ArgumentError
from fdisyn.synthesis.kinds import false_alarm_budget
from fdisyn.synthesis.registry import DEFAULT_ARL0

ONE_BANK = {"bank": [["y0", "y1", "y2"]]}


def _discrete(ts: float = 0.1) -> LinearPlant:
    c3 = [[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]
    return LinearPlant.create(A=[[0.5, 0.1], [0.0, 0.7]], C=c3, E=[[1.0], [0.0]], Q=np.eye(2) * 1e-3, R=np.eye(3) * 1e-2, Ts=ts)


def _beard() -> LinearPlant:
    return LinearPlant.create(
        A=[[0.0, 1.0, 0.0], [0.01, 0.0, 1.0], [0.0, 0.0, -1.0]], B=[[0.0], [0.0], [1.0]], C=[[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
        Fx=[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], Q=np.diag([0.0, 1e-4, 1e-4]), R=np.eye(2) * 1e-4,
    )


BEARD = {"Ts": 0.1, "decay_rate": 2.0, "eigenstructure": "plain"}


def _nonlinear() -> NonlinearPlant:
    return NonlinearPlant.from_expressions(
        states=["x"], inputs=["u"], outputs=["y"], parameters=["a"], nominal={"a": -0.5}, f={"x": "0.5*x + a*u"}, h={"y": "x"},
        Q=[[0.0]], R=[[0.01]],
    )


# --------------------------------------------------------------------------- the default, the explicit choices, both


def test_without_a_budget_the_default_arl0_applies() -> None:
    import fdisyn

    default = fdisyn.design(_discrete(), method="kalman_uio", **ONE_BANK)
    given = fdisyn.design(_discrete(), method="kalman_uio", arl0=DEFAULT_ARL0, **ONE_BANK)
    assert DEFAULT_ARL0 == 3600.0
    assert [e.threshold for e in default.evaluators] == [e.threshold for e in given.evaluators]
    assert [e.P_f for e in default.evaluators] == pytest.approx([0.1 / 3600.0])  # Ts / (statistics · arl0)
    assert false_alarm_budget(default) == 3600.0
    assert "arl0" not in default.provenance["options"]  # the options given are recorded, the budget in the certificate
    assert default.certificate["bank"]["info"]["arl0_s"] == 3600.0


def test_an_explicit_p_f_is_honoured() -> None:
    import fdisyn

    gf = fdisyn.design(_discrete(), method="kalman_uio", P_f=1e-4, **ONE_BANK)
    assert [e.P_f for e in gf.evaluators] == [1e-4]
    assert "arl0_s" not in gf.certificate["bank"]["info"]
    assert false_alarm_budget(gf) == pytest.approx(0.1 / 1e-4)


@pytest.mark.parametrize("method", ["kalman_uio", "beard_fdf", "nafdf"])
def test_both_budgets_are_refused_in_one_line(method: str) -> None:
    import fdisyn

    plant, base = {"kalman_uio": (_discrete, ONE_BANK), "beard_fdf": (_beard, BEARD), "nafdf": (_nonlinear, {})}[method]
    with pytest.raises(ArgumentError, match=r"^method '\w+': P_f = 0.001 and arl0 = 60 s both set the false-alarm budget; give one: "
                       r"arl0, the diagnoser's mean time between false alarms \(s\), or P_f, the rate per statistic and sample$"):
        fdisyn.design(plant(), method=method, P_f=1e-3, arl0=60, **base)


def test_a_plant_file_with_both_budgets_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = (EXAMPLES / "dc_motor.toml").read_text(encoding="utf-8")
    spec = tmp_path / "motor.toml"
    spec.write_text(text.replace("arl0 = 3600.0 ", "P_f = 1e-4\narl0 = 60.0 ", 1), encoding="utf-8")
    from tests.design.test_cli_hostile import _fails_with

    err = _fails_with(capsys, ["design", str(spec), "--out", str(tmp_path / "o")])
    assert err.startswith(f"fdisyn design: error: {spec} [design]: P_f = 0.0001 and arl0 = 60.0 s both set the false-alarm budget")


def test_a_problem_given_both_budgets_refuses_them() -> None:
    from fdisyn.simulation.problem import get_problem

    prob = get_problem("sampled_data_example")
    with pytest.raises(ArgumentError, match=r"problem 'sampled_data_example': P_f = 0.0001 and arl0 = 10.0 s both set .*"
                       r"arl0 alone replaces the problem's P_f = 0.001"):
        prob.check_options({"P_f": 1e-4, "arl0": 10.0})
    assert prob.check_options({"arl0": 10.0})["arl0"] == 10.0  # a variant's arl0 replaces the paper's P_f


def test_a_default_that_leaves_too_few_samples_says_it_is_the_default() -> None:
    import fdisyn

    with pytest.raises(ArgumentError, match=r"arl0 = 3600.0 s gives each of the 1 statistics a mean run length of 0.36 samples at "
                       r"Ts = 10000 s; expected arl0 > 10000 s .* \(arl0 = 3600 s is the default false-alarm budget, no P_f or arl0 "
                       r"was given: give an arl0 that fits, or P_f\)$"):
        fdisyn.design(_discrete(1e4), method="kalman_uio", **ONE_BANK)
    fdisyn.design(_discrete(1e4), method="kalman_uio", P_f=1e-3, **ONE_BANK)  # the remedy works


def test_beard_takes_arl0_as_the_magnitude_tests_rate() -> None:
    import fdisyn

    by_time = fdisyn.design(_beard(), method="beard_fdf", arl0=500.0, **BEARD)
    by_rate = fdisyn.design(_beard(), method="beard_fdf", P_f=0.1 / 500.0, **BEARD)
    a, b = by_time.extensions["beard_fdf"], by_rate.extensions["beard_fdf"]
    assert a["h"] == pytest.approx(b["h"], rel=1e-12) and a["explicit_level"] == pytest.approx(b["explicit_level"], rel=1e-12)
    assert false_alarm_budget(by_time) == 500.0 and false_alarm_budget(by_rate) == pytest.approx(500.0)
    default = fdisyn.design(_beard(), method="beard_fdf", **BEARD)
    assert default.extensions["beard_fdf"]["design"]["arl0_s"] == DEFAULT_ARL0
    assert default.extensions["beard_fdf"]["h"] > a["h"]  # a longer budget, a higher threshold
    given = fdisyn.design(_beard(), method="beard_fdf", h=0.02, explicit_level=0.007, **BEARD)
    assert false_alarm_budget(given) is None and budget_line(given) == "false-alarm budget: none designed (the thresholds were given)"
    with pytest.raises(ArgumentError, match=r"option arl0 = 0.05 s is 0.5 samples at Ts = 0.1 s; expected arl0 > 0.1 s \(one sample\)"):
        fdisyn.design(_beard(), method="beard_fdf", arl0=0.05, **BEARD)


def test_nafdf_takes_the_default_budget() -> None:
    import fdisyn

    gf = fdisyn.design(_nonlinear(), method="nafdf")
    settings = gf.extensions["nafdf"]["settings"]
    assert settings["arl0"] == DEFAULT_ARL0 and false_alarm_budget(gf) == DEFAULT_ARL0
    assert settings["false_alarm_probability"] == pytest.approx(1.0 / (3600.0 - 2 * 50))  # Ts = 1: 1/(arl0/Ts − 2 N2)


# --------------------------------------------------------------------------- the terminal and the pages


def test_fdisyn_design_prints_the_budget(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    main(["design", str(EXAMPLES / "dc_motor.toml"), "--out", str(tmp_path / "m")])
    lines = capsys.readouterr().out.splitlines()
    assert lines[1] == "false-alarm budget: one every 1 h (arl0 = 3600 s); P_f = 1.389·10⁻⁷ per statistic and sample, 2 statistics"


def test_a_design_by_p_f_prints_its_budget_in_time() -> None:
    import fdisyn

    gf = fdisyn.design(_discrete(0.001), method="kalman_uio", P_f=1e-4, **ONE_BANK)
    assert budget_line(gf) == "false-alarm budget: one every 10 s (from P_f = 1·10⁻⁴ per statistic and sample)"


@pytest.mark.parametrize(("seconds", "text"), [
    (None, "—"), (0.0, "0 s"), (0.25, "0.25 s"), (4.118, "4.12 s"), (59.9, "59.9 s"), (60.0, "1 min"), (1000.0, "16.7 min"),
    (3600.0, "1 h"), (5400.0, "1.5 h"), (86400.0, "1 day"), (3 * 86400.0, "3 days"), (2 * 365.25 * 86400.0, "2 years"),
    (math.inf, "∞"),
])
def test_durations_are_shown_in_units_an_operator_reads(seconds: float | None, text: str) -> None:
    assert duration(seconds) == text


def test_false_alarms_are_a_time_and_none_seen_is_a_lower_bound() -> None:
    assert false_alarm_time(3, 12.0) == "one every 4 s"
    assert false_alarm_time(0, 1000.0) == "none in 16.7 min of fault-free data"
    assert false_alarm_time(0, 0.0) == "—"
    m = SimpleNamespace(fault_free_samples=4000, Ts=0.001, false_alarm_episodes=1, false_alarm_rate=2.5e-4)
    quiet = SimpleNamespace(fault_free_samples=4000, Ts=0.001, false_alarm_episodes=0, false_alarm_rate=0.0)
    assert false_alarms_pooled([m, m]) == "one every 4 s (2.5·10⁻⁴ per sample)"
    assert false_alarms_pooled([quiet]) == "none in 4 s of fault-free data"  # never "0 per sample" as if it were a time
    assert false_alarms_pooled([]) == "—"


def test_the_summary_cell_states_the_time_beside_the_rate() -> None:
    assert _summary_false_alarms({"false_alarm_rate": 2.5e-4, "false_alarm_episodes": 2, "fault_free_time_s": 8.24}) == (
        "one every 4.12 s (2.5·10⁻⁴ per sample)")
    assert _summary_false_alarms({"false_alarm_rate": 0.0, "false_alarm_episodes": 0, "fault_free_time_s": 7200}) == (
        "none in 2 h of fault-free data")
    assert _summary_false_alarms({"false_alarm_rate": 1e-3}) == "0.001 per sample"  # a summary written before the times


def test_the_glance_heads_each_design_with_its_false_alarm_time() -> None:
    from fdisyn.reporting.page import _glance_section

    def metric(fault: str | None, episodes: int) -> SimpleNamespace:
        return SimpleNamespace(fault=fault, fault_free_samples=1000, Ts=0.01, false_alarm_episodes=episodes, false_alarm_rate=episodes / 500,
                               missed_detection_rate=None if fault is None else 0.0, detection_delay_mean_s=None if fault is None else 0.5,
                               isolation_accuracy=None if fault is None else 1.0, false_isolation_rate=None if fault is None else 0.0,
                               alarm_held_fraction=None if fault is None else 1.0, isolated_held_fraction=None if fault is None else 1.0)

    metrics = {"a": {"fault_free": metric(None, 2), "s": metric("f", 0)}, "b": {"fault_free": metric(None, 0), "s": metric("f", 0)}}
    glance = _glance_section(SimpleNamespace(labels={}), SimpleNamespace(evaluation=SimpleNamespace(runs=2, metrics=metrics)))  # type: ignore[arg-type]
    assert "false alarms</a>: one every 10 s (0.002 per sample)" in glance
    assert "false alarms</a>: none in 20 s of fault-free data</span>" in glance and "0 per sample" not in glance
