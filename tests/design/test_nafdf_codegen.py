"""The NAFDF step through the pipeline's C path (gain file → codegen → ctypes): C ≡ CasADi."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from fdisyn.codegen.library import codegen
from fdisyn.problems import ship_propulsion as sp
from fdisyn.problems import wind_turbine_efficiency as wt
from fdisyn.runtime.compiled import CompiledDiagnoser
from fdisyn.runtime.gainfile import write_gain_file
from fdisyn.simulation.nonlinear import simulate_nonlinear
from fdisyn.synthesis.nafdf.design import NafdfDesign
from fdisyn.synthesis.nafdf.payload import nafdf_gain_file

KEYS = ("state", "r", "J", "alarm", "isolated", "status")


def max_scaled_gap(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> float:
    """max |a − b| / max(1, |b|) over every output of every sample."""
    return max(float(np.max(np.abs(a[k] - b[k]) / np.maximum(1.0, np.abs(b[k])))) for k in KEYS)


def compiled(dsg: NafdfDesign, problem: str, directory) -> CompiledDiagnoser:  # noqa: ANN001 - a path
    gf = nafdf_gain_file(dsg, problem=problem)
    write_gain_file(gf, directory / "gains.json")
    return CompiledDiagnoser(codegen(directory).library, gf)


def c_run(cd: CompiledDiagnoser, u: np.ndarray, y: np.ndarray) -> dict[str, np.ndarray]:
    """Per-sample C calls, keeping the state after each step (what ``NafdfDesign.run`` returns)."""
    s = cd.init_state()
    rows = []
    for k in range(y.shape[0]):
        o = cd.step(s, u[k], y[k])
        rows.append((s.copy(), o.r, o.J, o.alarm, o.isolated, o.status))
    return {key: np.array([row[i] for row in rows], dtype=float) for i, key in enumerate(KEYS)}


@pytest.fixture(scope="module")
def ship():
    return sp.design()


def test_ship_c_step_equals_casadi_over_a_5000_step_faulty_run(ship, tmp_path) -> None:
    """C and the CasADi Function agree to ≤ 1e-10 (far above round-off, far below what a wrongly
    generated operation would change) over 5000 samples with the
    paper's fault, a second fault in b, and non-finite samples. Both evaluate the same operation
    sequence in IEEE double (no fast-math, no FMA contraction at -O2 on x86-64), so only libm's
    log may differ, by an ulp, in the classifier statistic."""
    T = 5000
    run = sp.PROBLEM.run(sp.fault_scenario("a_half", {"a": 0.5}, length=T), [7])
    theta = np.column_stack([run.extra["a"][0], run.extra["b"][0]])
    theta[3000:, 1] = 0.1  # b halves at 3000: a second episode after the first one is closed
    x, y = simulate_nonlinear(sp.plant(), x0=[0.0], u=run.U[0], theta=theta, rng=np.random.default_rng(7))
    y[[100, 1500, 2500], 0] = [np.nan, np.inf, -np.inf]
    u = run.U[0].copy()
    u[2000, 0] = np.nan
    ref = ship.run(u=u, y=y)
    got = c_run(compiled(ship, "ship_propulsion", tmp_path), u, y)
    assert max_scaled_gap(got, ref) <= 1e-10
    # the run exercised what it claims to: skips, an isolation, both re-initialisations
    assert got["status"].sum() == 4
    last = ship.unpack_state(got["state"][-1])
    assert last["alarm_resets"] >= 2 and last["ekf_reparameterisations"] >= 2
    assert np.any(got["isolated"] == 0)


def test_wind_turbine_efficiency_fault_in_c(tmp_path) -> None:
    """The second plant through the same code path, in C: the η 0.97 → 0.92 jump is detected within
    a second, isolated as η, and its size estimated to 0.005 (10 % of the jump; the converged η̂
    spreads by ~4e-4); C equals CasADi (≤ 1e-10) on the first 1200 samples."""
    dsg = wt.design()
    run = wt.PROBLEM.run(replace(wt.PROBLEM.scenario("eta_drop"), duration=9000 * wt.TS), [3])  # η drops at 40 s (sample 4000)
    u, y = run.U[0], run.Y[0]
    cd = compiled(dsg, "wind_turbine_efficiency", tmp_path)
    head = dsg.run(u=u[:1200], y=y[:1200])
    assert max_scaled_gap(c_run(cd, u[:1200], y[:1200]), head) <= 1e-10
    got = cd.run(u, y)
    alarm = got.alarm
    assert not np.any(alarm[:4000]), "false alarm before the fault"
    delay = int(np.flatnonzero(alarm[4000:])[0])
    assert delay <= 100
    iso = np.flatnonzero(got.isolated >= 0)
    assert iso.size and got.isolated[iso[0]] == 0
    jn = list(dsg.J_names)
    size = got.J[-1, jn.index("fault_size_eta")]
    assert abs(size - (wt.ETA_FAULTY - wt.ETA_NOMINAL)) <= 0.005
    last = dsg.unpack_state(got.state)
    assert abs(last["ekf_theta"][0] - wt.ETA_FAULTY) <= 0.005  # the EKF was re-parameterised to the new η
