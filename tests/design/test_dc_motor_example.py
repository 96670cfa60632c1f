"""The plant-file reference's example (the example ``dc_motor``) is a good one: the file the
reference shows, fault-free runs that alarm at the rate ``P_f`` promises (from the first sample
on), and a speed-sensor offset detected and isolated in every run."""

from __future__ import annotations

import re

import numpy as np
import pytest
from fdisyn.app.examples import EXAMPLES, PLANT_FILES
from fdisyn.simulation.plant_file import load_spec
from fdisyn.evaluation.evaluate import evaluate
from fdisyn.evaluation.metrics import binomial_interval

EXAMPLE = EXAMPLES / "dc_motor.toml"
RUNS = 20


def test_the_reference_shows_the_example_file_verbatim() -> None:
    blocks = re.findall(r"```toml\n(.*?)```", PLANT_FILES.read_text(encoding="utf-8"), flags=re.S)
    motor = [b for b in blocks if b.startswith('name = "dc_motor"')]
    assert motor == [EXAMPLE.read_text(encoding="utf-8")]


@pytest.fixture(scope="module")
def motor(motor_built):
    """The example's problem, its default design as the session built it and a Monte Carlo of ``RUNS`` runs."""
    prob = load_spec(EXAMPLE)
    return prob, motor_built, evaluate(prob, {prob.default_design: motor_built}, runs=RUNS)


def test_fault_free_runs_alarm_at_the_promised_rate(motor) -> None:
    prob, built, ev = motor
    m = ev.metrics[prob.default_design]["fault_free"]
    gf = built.gain_file
    p_f = gf.evaluators[0].P_f
    assert [e.P_f for e in gf.evaluators] == [p_f, p_f] and m.fault_free_samples == RUNS * 10_000
    alarms = round(m.false_alarm_rate * m.fault_free_samples)
    # An alarm is either of two χ² statistics (white residuals, so samples are independent):
    # its probability lies between P_f (one statistic) and 2·P_f (the union bound); the counts
    # are judged by two-sided 99.9 % binomial intervals of those two probabilities.
    lo, _ = binomial_interval(m.fault_free_samples, p_f)
    _, hi = binomial_interval(m.fault_free_samples, 2 * p_f)
    assert lo <= alarms <= hi, (alarms, lo, hi)
    for rate in m.statistic_exceedance:
        count = round(rate * m.fault_free_samples)
        lo1, hi1 = binomial_interval(m.fault_free_samples, p_f)
        assert lo1 <= count <= hi1, (count, lo1, hi1)


def test_no_start_up_transient(motor) -> None:
    """The runs start at an equilibrium, so the first samples alarm like any others. (A motor
    started while turning alarmed on its first ~130 samples in every run: 2600 alarms here.)"""
    prob, built, _ = motor
    batch = prob.run("fault_free", range(RUNS))
    first = np.array([built.diagnoser.run(batch.U[i], batch.Y[i]).alarm[:130] for i in range(RUNS)])
    # Left: the first sample's noise, which the equilibrium start holds (~1.5 % alarms over the
    # first ten samples): measured 6 alarms in these 2600 samples; 26 (1 %) is a hundredth of
    # the transient.
    assert first.sum() <= 26


def test_the_speed_sensor_offset_is_detected_and_isolated(motor) -> None:
    prob, built, ev = motor
    m = ev.metrics[prob.default_design]["speed_sensor_offset"]
    assert m.fault == "w_meas" and m.runs == RUNS
    assert m.missed_detection_rate == 0.0
    assert m.isolation_accuracy is not None and m.isolation_accuracy >= 0.95
    # a 1 rad/s offset is 20 standard deviations of the speed noise: seen within a few samples
    assert m.detection_delay_max_s is not None and m.detection_delay_max_s <= 0.02
