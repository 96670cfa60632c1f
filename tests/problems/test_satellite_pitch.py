"""Satellite pitch axis with a solar array (He, Zhang & Wu, Journal of Astronautics, c. 1999): the stand-in
design model, the truth simulator and the scenarios."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from fdisyn.simulation.problem import Scenario
from fdisyn.problems import satellite_pitch as sp
from fdisyn.runtime.errors import ArgumentError

ONSET = int(round(sp.ONSET / sp.TS))


def _sampled() -> tuple[np.ndarray, np.ndarray]:
    plant = sp.design_model().discretise(sp.TS)
    return np.asarray(plant.A), np.asarray(plant.B)


def _past_onset(scenario: Scenario) -> Scenario:
    """``scenario`` cut 60 s after the onset (3600 of its 6000 samples), for the tests that judge every sample of a
    run by the same rule: a run's draws are made at once per seed, so the shorter run is the longer one's start."""
    return replace(scenario, duration=sp.ONSET + 60.0)


def _beard_gain() -> tuple[np.ndarray, np.ndarray]:
    """A Beard gain for C = I: ``G = A_d − L`` keeps each sampled fault direction an eigenvector."""
    ad, bd = _sampled()
    v = np.column_stack([bd[:, 0], bd[:, 1], [1.0, 0, 0, 0], [0, 1.0, 0, 0]])
    g = v @ np.diag([0.9, 0.85, 0.8, 0.75]) @ np.linalg.inv(v)
    return ad - g, bd


def test_design_model_is_the_stated_rigid_model() -> None:
    Js, Jp, k, b = 5.0, 1.0, 0.15, 0.05
    A = [[0, 0, 1, 0], [0, 0, 0, 1], [-k / Js, k / Js, -b / Js, b / Js], [k / Jp, -k / Jp, b / Jp, -b / Jp]]
    B = [[0, 0], [0, 0], [1 / Js, -1 / Js], [0, 1 / Jp]]
    plant = sp.design_model()
    np.testing.assert_array_equal(plant.A, A)
    np.testing.assert_array_equal(plant.B, B)
    np.testing.assert_array_equal(plant.Fx, B)
    np.testing.assert_array_equal(plant.C, np.eye(4))
    np.testing.assert_array_equal(plant.D, np.zeros((4, 2)))
    np.testing.assert_array_equal(plant.Q, np.zeros((4, 4)))
    np.testing.assert_allclose(np.diag(plant.R), np.square(sp.TRUTH.noise))
    assert plant.Ts is None and plant.component_faults == ("pitch_wheel", "array_drive")
    assert plant.inputs == ("T_y", "T_p") and plant.states == ("theta", "phi", "theta_dot", "phi_dot")


def test_ideal_truth_is_the_exactly_sampled_model() -> None:
    """Reduced to the design model, the truth steps as ``x⁺ = A_d x + B_d (τ + [T_d, 0])`` with the applied
    torques τ. RK4 at h = Ts/5 on ‖A h‖ ≈ 0.01 errs by ‖A h‖⁵/120 ≈ 1e-12 relative per sample at most; states are
    below 0.03, so 1e-12 absolute per sample bounds it with room for round-off."""
    truth = replace(sp.TRUTH.ideal, start_at_rest=True)
    ad, bd = _sampled()
    for scenario in (sp.SCENARIOS["fault_free"], sp.fault_scenario("pitch_wheel", 0.5)):
        run = sp.simulate(_past_onset(scenario), [3], truth=truth)
        x = np.column_stack([run.extra[s][0] for s in sp.STATES])
        tau = np.column_stack([run.extra["T_y_applied"][0] + truth.disturbance, run.extra["T_p_applied"][0]])
        one_step = x[:-1] @ ad.T + tau[:-1] @ bd.T
        assert np.max(np.abs(x[1:] - one_step)) < 1e-12
        assert np.max(np.abs(x[:, 1])) > 0.01  # the run moves: the array is driven to its sun angle
        np.testing.assert_array_equal(run.extra["q"], 0.0)
        np.testing.assert_array_equal(run.Y[0], x)  # no noise


def test_energy_is_conserved_without_torques_and_damping() -> None:
    """The truth's equations (flexible mode, sin spring) conserve their energy when nothing drives or damps them;
    the damper, the modal damping and the friction only take energy out. RK4 damps an oscillation of frequency ω
    by (ω h)⁶/144 per step: the flexible mode (2.56 rad/s with its coupling, h = 0.02 s) loses at most 7e-7 of
    its energy in 5000 steps, so the bound is 1e-6 relative."""
    truth = replace(sp.TRUTH, flex_damping=0.0, friction_torque=0.0, disturbance=0.0)
    p = {"Js": np.array([5.0]), "Jp": np.array([1.0]), "k": np.array([0.15]), "b": np.array([0.0])}
    x = np.array([[0.0, 0.3, 0.01, -0.02, 0.01, 0.0]])
    tau = np.zeros((1, 2))
    e0 = sp.energy(x, p, truth)
    for _ in range(5000):
        x = sp.rk4_step(x, tau, p, truth, 0.02)
    assert abs(sp.energy(x, p, truth)[0] - e0[0]) < 1e-6 * e0[0]
    damped = sp.TRUTH
    p["b"] = np.array([0.05])
    x = np.array([[0.0, 0.3, 0.01, -0.02, 0.01, 0.0]])
    energies = []
    for _ in range(2000):
        x = sp.rk4_step(x, np.array([[-damped.disturbance, 0.0]]), p, damped, 0.02)  # the wheel cancels T_d
        energies.append(sp.energy(x, p, damped)[0])
    assert np.all(np.diff(energies) <= 1e-15) and energies[-1] < 0.5 * e0[0]


def test_closed_loop_settles_before_onset() -> None:
    """Started at rest, the rates settle to the noise level well before the onset, at the run's equilibrium;
    the scenarios start at that equilibrium and stay there."""
    truth = replace(sp.TRUTH, start_at_rest=True)
    # the start from rest up to the onset, all this run is judged on (a run's first samples do not depend on its length)
    run = sp.simulate(replace(sp.SCENARIOS["fault_free"], duration=sp.ONSET), [0, 1, 2], truth=truth)
    late = slice(ONSET - 600, ONSET)  # the last 60 s before the onset
    for rate, bound in (("theta_dot", 5e-5), ("phi_dot", 1e-4)):
        assert np.max(np.abs(run.extra[rate][:, late])) < bound  # noise-driven: a few 1e-5 rad/s
        assert np.max(np.abs(run.extra[rate][:, :100])) > 3 * bound  # the start-up transient
    eq = sp.steady_state(sp.run_parameters([0, 1, 2]))
    for i, s in enumerate(("theta", "phi")):
        np.testing.assert_allclose(run.extra[s][:, late].mean(axis=1), eq[:, i], atol=2e-5)
    assert np.all(np.abs(eq[:, 1] - sp.TRUTH.cant) < 1e-3)
    steady = sp.simulate(sp.SCENARIOS["fault_free"], [0, 1, 2])
    np.testing.assert_array_equal(steady.extra["theta"][:, 0], eq[:, 0])
    assert np.max(np.abs(steady.extra["theta_dot"])) < 5e-5
    # the wheel carries the disturbance, the drive the spring preload
    np.testing.assert_allclose(steady.U[:, ONSET - 600 : ONSET].mean(axis=1), [[-1e-3, 3e-3]] * 3, rtol=0.05)


@pytest.mark.parametrize("actuator", ["pitch_wheel", "array_drive"])
def test_fault_is_a_torque_loss_from_onset(actuator: str) -> None:
    kappa = 0.3
    run = sp.simulate(sp.fault_scenario(actuator, kappa), [7, 8])
    j = sp.FAULTS.index(actuator)
    applied = np.stack([run.extra["T_y_applied"], run.extra["T_p_applied"]], axis=-1)
    assert np.max(np.abs(run.U[..., 0])) < sp.TRUTH.wheel_limit and np.max(np.abs(run.U[..., 1])) < sp.TRUTH.drive_limit
    np.testing.assert_array_equal(applied[:, :ONSET], run.U[:, :ONSET])
    np.testing.assert_array_equal(applied[:, ONSET:, 1 - j], run.U[:, ONSET:, 1 - j])
    np.testing.assert_allclose(applied[:, ONSET:, j] - run.U[:, ONSET:, j], -kappa * run.U[:, ONSET:, j], rtol=1e-12, atol=0)
    assert np.all(run.active == (run.t >= sp.ONSET))


@pytest.mark.parametrize("actuator, disturbance", [("pitch_wheel", sp.TRUTH.disturbance), ("array_drive", 0.0)])
def test_fault_enters_along_its_column_of_B(actuator: str, disturbance: float) -> None:
    """Through a Beard gain of the sampled model the residual of the ideal truth stays on the sampled fault
    direction (the disturbance is a pitch-wheel torque, so it shares that line), and grows there from the onset."""
    L, bd = _beard_gain()
    ad, _ = _sampled()
    truth = replace(sp.TRUTH.ideal, start_at_rest=True, disturbance=disturbance)
    run = sp.simulate(_past_onset(sp.fault_scenario(actuator, 0.3)), [0], truth=truth)
    eps = sp.filter_residuals(ad, bd, np.eye(4), np.zeros((4, 2)), L, run.U, run.Y)[0]
    f = bd[:, sp.FAULTS.index(actuator)]
    f = f / np.linalg.norm(f)
    after = eps[1000:]  # the filter's start-up error has decayed (0.9¹⁰⁰⁰)
    off_line = after - np.outer(after @ f, f)
    assert np.max(np.linalg.norm(off_line, axis=1)) < 1e-9 * np.max(np.linalg.norm(after, axis=1))
    assert np.linalg.norm(eps[ONSET + 100]) > 1.3 * np.linalg.norm(eps[ONSET - 1]) > 0


def test_filter_on_its_own_model_at_equilibrium_has_no_residual() -> None:
    L, bd = _beard_gain()
    ad, _ = _sampled()
    truth = replace(sp.TRUTH.ideal, disturbance=0.0)
    run = sp.simulate(replace(sp.SCENARIOS["fault_free"], duration=200 * sp.TS), [0], truth=truth)  # the 200 samples judged
    eps = sp.filter_residuals(ad, bd, np.eye(4), np.zeros((4, 2)), L, run.U, run.Y)
    assert np.max(np.abs(eps)) < 1e-14


def test_explicit_levels_are_quantiles_of_the_window_statistics() -> None:
    rng = np.random.default_rng(0)
    res = rng.standard_normal((3, 40, 2))
    window = 5
    means = [np.linalg.norm(res[r, k - window + 1 : k + 1].mean(axis=0)) for r in range(3) for k in range(window - 1, 40)]
    rms = [np.sqrt(np.mean(np.sum(res[r, k - window + 1 : k + 1] ** 2, axis=1))) for r in range(3) for k in range(window - 1, 40)]
    level, h = sp.explicit_levels(res, window, 0.1)
    assert level == pytest.approx(np.quantile(means, 0.9), rel=1e-12)
    assert h == pytest.approx(np.quantile(rms, 0.9), rel=1e-12)
    with pytest.raises(ArgumentError, match="fewer than the window"):
        sp.explicit_levels(res, 41, 0.1)


def test_seeds_give_reproducible_different_runs() -> None:
    sc = _past_onset(sp.SCENARIOS["pitch_wheel_loss"])
    a = sp.simulate(sc, [4, 5])
    b = sp.simulate(sc, [4, 5])
    c = sp.simulate(sc, [5])
    np.testing.assert_array_equal(a.Y, b.Y)
    np.testing.assert_array_equal(a.U, b.U)
    np.testing.assert_array_equal(a.Y[1], c.Y[0])  # a run depends on its own seed only
    assert not np.allclose(a.Y[0], a.Y[1])
    assert a.extra["true_k"][0, 0] != a.extra["true_k"][1, 0]


def test_model_error_is_within_sigma() -> None:
    p = sp.run_parameters(range(3000))
    for name, nominal in zip(("Js", "Jp", "k", "b"), (5.0, 1.0, 0.15, 0.05), strict=True):
        rel = p[name] / nominal - 1.0
        assert np.max(np.abs(rel)) <= sp.TRUTH.parameter_error and np.ptp(rel) > 1.8 * sp.TRUTH.parameter_error
    a0, _ = sp.rigid_matrices(5.0, 1.0, 0.15, 0.05)
    a, _ = sp.rigid_matrices(p["Js"], p["Jp"], p["k"], p["b"])
    measured = np.linalg.norm(a - a0, 2, axis=(-2, -1))
    low, high = sp.model_error_range()
    assert low == 0.0 and 0.9 * high < measured.max() <= high < sp.SIGMA


def test_scenarios_and_the_fault_size_sweep() -> None:
    assert set(sp.PROBLEM.scenarios) == {"fault_free", "pitch_wheel_loss", "array_drive_loss"}
    assert sp.PROBLEM.scenario("array_drive_loss").params == {"actuator": "array_drive", "kappa": sp.KAPPA}
    sweep = sp.fault_size_scenarios([0.1, 0.5])
    assert sorted(sweep) == ["array_drive_loss_k0.1", "array_drive_loss_k0.5", "pitch_wheel_loss_k0.1", "pitch_wheel_loss_k0.5"]
    sc = sweep["pitch_wheel_loss_k0.5"]
    assert sc.fault == "pitch_wheel" and sc.onset == sp.ONSET and sc.params["kappa"] == 0.5
    run = sp.PROBLEM.run(sc, [1])
    assert run.U.shape == (1, 6000, 2) and run.Y.shape == (1, 6000, 4)
    np.testing.assert_allclose(run.extra["T_y_applied"][0, ONSET:], 0.5 * run.U[0, ONSET:, 0], rtol=1e-12)
    trace = run.trace(0)
    assert "T_p_applied" in trace.extra and "theta" in trace.extra
    for bad in ("wheel", "array_drive"):
        with pytest.raises(ArgumentError):
            sp.fault_scenario(bad, 1.5)


def test_labels_name_the_signals_faults_and_designs():
    plant = sp.design_model()
    names = {*plant.inputs, *plant.outputs, *sp.FAULTS, *sp.PROBLEM.designs, "rho", "rms"}
    names |= {f"eps_{o}" for o in plant.outputs} | {f"{k}_{f}" for k in ("angle", "cone") for f in sp.FAULTS}
    assert not sorted(names - set(sp.PROBLEM.labels))
    assert sp.PROBLEM.model().outputs == plant.outputs


@pytest.mark.slow
def test_both_beard_filters_design_and_see_every_fault() -> None:
    # the eigenstructure NLP once failed on some BLAS kernels; .ci/run designs both again under Haswell
    for name in ("optimised", "plain"):
        gf = sp.PROBLEM.design(name)
        assert gf.certificate["passed"] is True, name
        assert gf.account is not None and {f["effect"] for f in gf.account["faults"]} == {"persistent"}, name
