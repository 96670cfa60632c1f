"""Ship propulsion (Zhou, Xi & Zhang, Shanghai Jiao Tong University, c. 1991, section 3): the paper's
scenario and the other faults, reproduced."""

from __future__ import annotations

import numpy as np
import pytest
from fdisyn.problems import ship_propulsion as sp
from fdisyn.runtime.errors import ArgumentError


@pytest.fixture(scope="module")
def design():
    return sp.design()


def test_input_is_the_documented_square_wave() -> None:
    u = sp.input_signal(200)[:, 0]
    assert set(np.unique(u)) == {1.0, 9.0}
    assert np.all(u[:25] == 9.0) and np.all(u[25:50] == 1.0)
    np.testing.assert_array_equal(u[:150], u[50:200])  # period 50


def test_scenario_time_convention() -> None:
    run = sp.PROBLEM.run(sp.fault_scenario("a_half", {"a": 0.5}, length=800), [0])
    assert run.scenario.fault == "a" and run.scenario.params["fault_size"] == {"a": pytest.approx(0.29)}
    true_a, true_b, x = run.extra["a"][0], run.extra["b"][0], run.extra["x"][0]
    np.testing.assert_array_equal(true_a[:701], -0.58)
    np.testing.assert_array_equal(true_a[701:], -0.29)
    np.testing.assert_array_equal(true_b, 0.2)
    # Q = 0: x(702) is the first state the new a changes
    a, b = true_a[701], true_b[701]
    assert x[702] == pytest.approx(0.1 * a * x[701] ** 2 + x[701] + 0.1 * b * run.U[0, 701, 0], rel=1e-14)  # same formula
    free = sp.fault_scenario("fault_free", length=100)
    assert free.fault is None and free.onset is None and free.duration == 100
    with pytest.raises(ArgumentError, match="unknown parameters"):
        sp.fault_scenario("c_half", {"c": 0.5})


def test_paper_scenario_is_reproduced(design) -> None:
    """a → a0/2 at 701 (paper: detected 712, NF reset 712, EKF reset and isolation of a at 1000,
    Δâ = 0.2891 vs 0.29). Bounds: delay ≤ 20 (the Monte Carlo 95 % quantile is ~11); size within
    0.05 (≈ 4.5 standard deviations of the Monte Carlo size error, 0.011); b never classified."""
    m = sp.reproduce_paper(seed=1)
    assert 1 <= m["detection_delay"] <= 20
    assert m["nf_resets"][0] == m["detection_time"]
    assert m["isolated"] == "a" and m["fault_class"]["b"] == 0
    assert 701 < m["ekf_reparameterisation_time"] <= m["isolation_time"] <= 1300
    assert abs(m["fault_size"]["a"] - 0.29) <= 0.05
    # re-tracking: the re-parameterised EKF's innovations are back at the noise level σ_e = 0.1
    assert abs(m["nf_theta_at_reparameterisation"]["a"] + 0.29) <= 0.05
    assert m["ekf_innovation_rms_after"] == pytest.approx(0.1, rel=0.1)  # 1000 samples: sd of the rms ≈ 2 %
    assert m["wssr_alarm_fraction_after"] < 0.01


@pytest.mark.parametrize("scale, expect", [({"b": 0.5}, "b"), ({"a": 1.5}, "a"), ({"b": 1.5}, "b")])
def test_other_faults_are_isolated(design, scale, expect) -> None:
    """Faults in b and in a the other way: the right parameter is isolated, with the size (the NF's
    change at the decision) within 4 of the NF's own standard deviations there (``info_<θ>``, which
    the excitation tests hold to the Cramér–Rao bound); the other parameter is never classified."""
    run = sp.PROBLEM.run(sp.fault_scenario("fault", scale, length=2500), [21])
    out = design.run(u=run.U[0], y=run.Y[0])
    m = sp.run_metrics(design, run, out)
    assert m["detection_delay"] is not None and m["detection_delay"] <= 60
    assert m["isolated"] == expect
    jn = list(design.J_names)
    for name, size in run.scenario.params["fault_size"].items():
        sd = 1.0 / np.sqrt(out["J"][m["isolation_time"], jn.index(f"info_{name}")])
        assert m["fault_class"][name] >= 1
        assert abs(m["fault_size"][name] - size) <= 4 * sd, (name, m["fault_size"][name], size, sd)
    for name in set(design.fault_names) - set(run.scenario.fault.split("+")):
        assert m["fault_class"][name] == 0


def test_a_jump_of_both_parameters_holds_the_alarm_and_names_neither(design) -> None:
    """a → a0/2 and b → 0.7 b0: no single parameter's jump explains the NF's estimate, so nothing is named
    (``isolated`` names one parameter), the EKF keeps its model and the alarm holds from the detection
    to the end of the run; the diagnosis is not "insufficient excitation" (the data carry the information)."""
    run = sp.PROBLEM.run(sp.fault_scenario("fault", {"a": 0.5, "b": 0.7}, length=2500), [21])
    out = design.run(u=run.U[0], y=run.Y[0])
    m = sp.run_metrics(design, run, out)
    assert m["detection_delay"] is not None and m["detection_delay"] <= 60
    assert m["isolated"] is None and m["ekf_reparameterisations"] == []
    assert np.all(out["alarm"][sp.FAULT_TIME + m["detection_delay"] :] == 1)
    assert out["J"][-1, list(design.J_names).index("insufficient_excitation")] == 0


def test_fault_free_run_isolates_nothing(design) -> None:
    m = sp.run_metrics(design, sp.PROBLEM.run(sp.fault_scenario("fault_free", length=10_000), [5]))
    assert m["isolated"] is None
    assert all(v == 0 for v in m["fault_class"].values())
    # P_f = 1e-4 per sample: over 10^4 samples more than 5 alarm episodes has probability < 1e-3
    assert m["false_alarm_episodes"] <= 5


# ------------------------------------------------------------------ through the pipeline (gain file → C)


@pytest.fixture(scope="module")
def ship_built(tmp_path_factory):
    from fdisyn.evaluation.built import build
    from fdisyn.problems.ship_propulsion import PROBLEM

    return build(PROBLEM, "nafdf", tmp_path_factory.mktemp("ship") / "nafdf")


def test_gain_file_round_trip_rebuilds_the_same_step(ship_built):
    from fdisyn.runtime.gainfile import read_gain_file

    gf = read_gain_file(ship_built.directory / "gains.json")
    assert gf.kind == "nafdf" and gf.faults == ("a", "b") and gf.inputs == ("u",) and gf.outputs == ("y",)
    assert gf.to_dict() == ship_built.gain_file.to_dict()
    assert np.isinf(gf.thresholds[list(gf.step.statistic_names).index("theta_hat_a")])


def test_compiled_step_equals_casadi_over_a_5000_step_faulty_run(ship_built):
    from fdisyn.app.pipeline import check_export
    from fdisyn.problems.ship_propulsion import PROBLEM

    b = PROBLEM.run("both_a0.5_b0.7", [4])
    U = np.tile(b.U[0], (3, 1))[:5000]
    Y = np.tile(b.Y[0], (3, 1))[:5000].copy()
    Y[[100, 2500, 4000], 0] = [np.nan, np.inf, -np.inf]
    chk = check_export(ship_built, U, Y)
    v = chk.references["casadi"]
    # the same SX graph compiled: agreement to round-off of a different evaluation order (bound 1e-10: far
    # above that round-off, far below what a wrongly generated operation would change)
    assert max(v["r"], v["J"], v["state"]) <= 1e-10 and v["decisions_equal"]
    assert chk.nonfinite_samples == 3


def test_replay_through_the_command_line(ship_built, tmp_path):
    import subprocess

    from fdisyn.app.cli import main

    trace = tmp_path / "t.csv"
    assert main(["simulate", "ship_propulsion", "--scenario", "paper_a_half", "--seed", "1", "--out", str(trace)]) == 0
    assert main(["replay", str(ship_built.directory), str(trace), str(tmp_path / "py.csv")]) == 0
    subprocess.run([str(ship_built.artifacts.replay), str(trace), str(tmp_path / "c.csv")], check=True, capture_output=True)
    assert (tmp_path / "py.csv").read_bytes() == (tmp_path / "c.csv").read_bytes()
    out = np.genfromtxt(tmp_path / "py.csv", delimiter=",", names=True)
    assert out["isolated"][-1] == 0  # 'a', latched
    assert np.all(out["isolated"][:701] == -1)


def test_small_monte_carlo_through_the_compiled_step(ship_built):
    """20 seeds through the pipeline's evaluation (the full study is `fdisyn reproduce`): every paper
    fault detected, at least 18 isolated as a and none as b, no isolation on healthy runs."""
    from fdisyn.evaluation.evaluate import evaluate
    from fdisyn.problems.ship_propulsion import PROBLEM

    ev = evaluate(PROBLEM, {"nafdf": ship_built}, runs=20, scenarios=["paper_a_half", "fault_free"])
    paper, healthy = ev.metrics["nafdf"]["paper_a_half"], ev.metrics["nafdf"]["fault_free"]
    assert paper.missed_detection_rate == 0.0
    assert paper.isolation_accuracy >= 0.9 and paper.first_isolation_accuracy >= 0.9
    assert healthy.extra["runs with an isolation"] == 0.0
    assert abs(paper.extra["size error a: mean"]) < 0.02  # true Δa = 0.29; the converged â spreads by ~0.02


def test_labels_name_what_the_gain_file_names(ship_built):
    from fdisyn.problems.ship_propulsion import PROBLEM

    gf = ship_built.gain_file
    names = {*gf.inputs, *gf.outputs, *gf.faults, *gf.step.residual_names, *gf.step.statistic_names, *PROBLEM.designs}
    assert not sorted(names - set(PROBLEM.labels))


def test_claims_of_the_paper_fault_and_the_threshold():
    from fdisyn.problems.ship_propulsion import PROBLEM

    from tests.helpers import check_claims, claims_context, scenario_metrics

    paper = scenario_metrics("paper_a_half", "a", detection_delay_mean_s=8.6, detection_delay_max_s=11.0, isolation_accuracy=1.0,
                             extra={"isolation delay median (samples)": 126.0, "size error a: mean": 0.002, "size error a: sd": 0.017})
    ff = scenario_metrics("fault_free", mean_time_between_false_alarms_s=33333.0, false_alarm_episodes=60)
    claims = PROBLEM.claims(claims_context(PROBLEM, [{"label": "default", "metrics": {"nafdf": {"paper_a_half": paper, "fault_free": ff}}}]))
    check_claims(claims)
    verdicts = [c.verdict for c in claims]
    assert verdicts == ["reproduced", "reproduced", "differs", "reproduced", "differs"]  # detection, isolation, when, size, β0
