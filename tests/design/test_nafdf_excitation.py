"""The NAFDF's isolation judged against the NF's own information, through the generated C step.

Zhou, Xi & Zhang (Shanghai Jiao Tong University, c. 1991) arm their classifier (2.6)–(2.8) on a
converged NF. Here "converged" is a law of the NF's covariance ``P_θ = a R⁻¹`` (module docstring of
:mod:`fdisyn.synthesis.nafdf.design`, block 4): with enough excitation every input family isolates
the right parameter; with too little the diagnosis is "detected, not isolable (insufficient
excitation)" with ``info_<θ>`` below ``W1 / isolable_jump²`` and one steady alarm episode per fault
(the criterion of no flicker); a false alarm under too little excitation is dismissed. The ship
problem's step is compiled once for the module.
"""

from __future__ import annotations

import numpy as np
import pytest
from fdisyn.codegen.library import codegen
from fdisyn.problems import ship_propulsion as sp
from fdisyn.runtime.compiled import CompiledDiagnoser
from fdisyn.runtime.gainfile import write_gain_file
from fdisyn.simulation.nonlinear import simulate_nonlinear
from fdisyn.synthesis.nafdf.design import NOT_ISOLABLE, nafdf_diagnosis
from fdisyn.synthesis.nafdf.payload import nafdf_gain_file

FAULTS = (("a", {"a": 0.5}), ("b", {"b": 0.5}))


@pytest.fixture(scope="module")
def ship(tmp_path_factory):
    """The ship's design, its gain file and its compiled C step (one compilation for the module)."""
    dsg = sp.design()
    gf = nafdf_gain_file(dsg, problem="ship_propulsion")
    directory = tmp_path_factory.mktemp("ship_c")
    write_gain_file(gf, directory / "gains.json")
    cd = CompiledDiagnoser(codegen(directory).library, gf)

    def diagnose(u: np.ndarray, y: np.ndarray) -> dict[str, np.ndarray]:
        res = cd.run(u, y)
        return {"alarm": res.alarm, "isolated": res.isolated, "J": res.J, "state": res.state}

    return dsg, gf, diagnose


def info_ratio(dsg, info: dict[str, tuple[float, float]], when: int) -> float:
    """min over the parameters of ``info_θ · isolable_jump² / W1`` (≥ 1: enough information) at ``when`` (0: before the fault, 1: end)."""
    s = dsg.settings
    return min(info[q][when] * float(s.isolable_jump[i]) ** 2 / s.W1 for i, q in enumerate(dsg.fault_names))


def test_the_information_statistics_are_exported_without_thresholds(ship) -> None:
    dsg, gf, _ = ship
    names = list(gf.step.statistic_names)
    assert gf.step.nj == len(names) == 3 + 5 * 2 + 3
    for name in ("info_a", "info_b", "insufficient_excitation"):
        assert np.isinf(gf.thresholds[names.index(name)])  # null in the file: not an alarm statistic
    assert gf.extensions["nafdf"]["settings"]["isolable_jump"] == [0.29, 0.1]


def test_the_reported_sine_isolates_the_jump(ship) -> None:
    """u = 1 + 0.8 sin(2πk/50), a → a0/2 at 701, 3000 samples. With convergence judged on the information
    the classifier needs before the fault (σ(â) ≈ 0.06 > 0.041), the NF never converged, the alarm held to
    the end of the run and nothing was isolated, although after the fault the NF's estimates sat on the
    truth. Now the settled NF's estimate decides which parameter moved (module docstring of
    :mod:`fdisyn.synthesis.nafdf.design`, "Isolation from the NF's estimate"): ``a`` is isolated within
    150 samples of the fault, the EKF is re-parameterised on the new ``a`` and the alarm ends."""
    dsg, gf, diagnose = ship
    T, k = 3000, np.arange(3000)
    u = (1.0 + 0.8 * np.sin(2 * np.pi * k / 50))[:, None]
    theta = np.tile(sp.plant().theta_nominal, (T, 1))
    theta[sp.FAULT_TIME :, 0] *= 0.5
    _, y = simulate_nonlinear(sp.plant(), x0=[0.0], u=u, theta=theta, rng=np.random.default_rng(1))
    out = diagnose(u, y)
    d = nafdf_diagnosis(gf.step.statistic_names, gf.faults, out["alarm"], out["isolated"], out["J"], sp.FAULT_TIME)
    assert d["verdict"] == "isolated a" and d["isolation_delay"] <= 150
    assert np.all(out["isolated"][: sp.FAULT_TIME] == -1)
    assert info_ratio(dsg, d["info"], 0) < 1  # what the former rule asked for before the fault was missing
    last = dsg.unpack_state(out["state"])
    assert last["ekf_reparameterisations"] >= 1 and abs(last["ekf_theta"][0] - 0.5 * sp.NOMINAL["a"]) < 0.05


@pytest.mark.parametrize(
    "kind, offset, amplitude",
    [("square", 5.0, 4.0), ("sines", 6.0, 5.5), ("prbs", 5.0, 4.0), ("ramps", 5.0, 4.0)],
)
def test_each_family_with_enough_excitation_isolates_the_right_parameter(ship, kind, offset, amplitude) -> None:
    """Two runs of each fault per family at an amplitude whose information is enough before the fault
    (σ(â) ≤ 0.041, σ(b̂) ≤ 0.014): the jumping parameter is isolated within 600 samples of the fault
    (measured 106–136 samples: the NF's estimate decides 2·N2 samples after its reset at the alarm)."""
    dsg, gf, diagnose = ship
    study = sp.excitation_study(diagnose, gf.step.statistic_names, cells=[(kind, offset, amplitude)], faults=FAULTS, seeds=(1, 2))
    for rec in study:
        for run in rec["runs"]:
            assert run["verdict"] == f"isolated {rec['fault']}", (rec["fault"], run)
            assert run["isolation_delay"] <= 600
            assert info_ratio(dsg, run["info"], 0) >= 1


def test_every_family_and_amplitude_names_the_right_parameter_or_none(ship) -> None:
    """The report's excitation study (every family at every amplitude, both jumps, three runs): no run ever
    names the wrong parameter; every family with a varying input isolates every jump, and the constant
    input (the data carry b/a only, apart from the transient after the jump) isolates or says not
    isolable. Measured: 123 of 126 runs isolated (before: 52, the rest detected but not isolated or not
    isolable), the constant input's a → a0/2 not isolable in 3 of 3 runs."""
    _, gf, diagnose = ship
    for rec in sp.excitation_study(diagnose, gf.step.statistic_names):
        for run in rec["runs"]:
            verdict, right = run["verdict"], f"isolated {rec['jumping'][0]}"
            assert verdict in (right, NOT_ISOLABLE) if rec["kind"] == "constant" else verdict == right, (rec, run)
            if verdict.startswith("isolated"):  # slow ramps: the NF may sit on the ridge of b/a until a turn
                assert run["isolation_delay"] <= (1200 if rec["kind"] == "slow_ramps" else 600), (rec, run)


def test_a_false_alarm_under_too_little_excitation_is_dismissed(ship) -> None:
    """Fault-free, u = 5 constant, a burst of three outliers at 1000 raises the WSSR alarm. The NF never
    has the information to converge, but once the burst has left the EKF's window its innovations pass
    the χ²(N2 p) test on N2 consecutive windows: the episode is dismissed about 2·N2 samples after it
    opened instead of holding the alarm for the rest of the run, and nothing is isolated or reported
    not isolable."""
    dsg, gf, diagnose = ship
    batch = sp.PROBLEM.run(sp.fault_scenario("quiet", length=3000, signal={"kind": "constant", "offset": 5.0, "amplitude": 0.0}), [2])
    u, y = batch.U[0], batch.Y[0].copy()
    y[1000:1003, 0] += 1.0
    out = diagnose(u, y)
    alarm = out["alarm"]
    starts, ends = np.flatnonzero(np.diff(np.concatenate([[0], alarm])) > 0), np.flatnonzero(np.diff(np.concatenate([alarm, [0]])) < 0)
    assert starts.tolist() == [int(starts[0])] and 1000 <= starts[0] <= 1003
    assert ends[0] - starts[0] <= 2 * dsg.settings.classifier_window + 10
    last = dsg.unpack_state(out["state"])
    assert last["episodes_dismissed"] == 1 and last["ekf_reparameterisations"] == 0
    assert np.all(out["isolated"] == -1) and last["insufficient_excitation"] == 0


def _lambda_path(s, n: int) -> np.ndarray:
    """The NF's forgetting factor over its first ``n`` updates, λ(t) = λ0 λ(t−1) + (1 − λ0) λ∞ from λ(0)."""
    lam, out = s.forgetting_initial, np.empty(n)
    for k in range(n):
        lam = s.forgetting_rate * lam + (1.0 - s.forgetting_rate) * s.forgetting_final
        out[k] = lam
    return out


def _cramer_rao(u: np.ndarray, x0: float, theta: np.ndarray, s, r: float) -> np.ndarray:
    """Independent covariance of (a, b) from the NF's window: the ship's output ``y = x(x0, a, b) + v``
    (Q = 0, ``v ~ N(0, r)``), sensitivities by central differences of the simulated trajectory, the
    exponentially weighted least squares of the NF's forgetting, ``x0`` unknown: the sandwich
    ``I⁻¹ M I⁻¹`` with ``I = Σ w_k J_kᵀ J_k / r`` and ``M = Σ w_k² J_kᵀ J_k / r`` (its inverse is the
    Cramér–Rao bound of a weighted estimator)."""

    def path(p: np.ndarray) -> np.ndarray:
        x = np.empty(len(u))
        x[0] = p[0]
        for k in range(len(u) - 1):
            x[k + 1] = 0.1 * p[1] * x[k] ** 2 + x[k] + 0.1 * p[2] * u[k]
        return x

    p0 = np.array([x0, *theta])
    J = np.empty((len(u), 3))
    for j in range(3):
        h = 1e-6 * max(1.0, abs(p0[j]))
        dp = np.zeros(3)
        dp[j] = h
        J[:, j] = (path(p0 + dp) - path(p0 - dp)) / (2 * h)
    lam = _lambda_path(s, len(u))
    w = np.ones(len(u))
    for k in range(len(u) - 2, -1, -1):
        w[k] = w[k + 1] * lam[k + 1]
    info = (J * w[:, None]).T @ J / r
    mid = (J * (w**2)[:, None]).T @ J / r
    inv = np.linalg.inv(info)
    return (inv @ mid @ inv)[1:, 1:]


@pytest.mark.parametrize("kind, offset, amplitude", [("square", 5.0, 4.0), ("sines", 5.0, 2.0), ("sines", 1.0, 0.8), ("prbs", 5.0, 2.0), ("square", 1.0, 0.8)])
def test_the_nf_information_is_the_cramer_rao_bound_of_its_window(ship, kind, offset, amplitude) -> None:
    """The information the diagnosis judges by (``info_<θ> = 1/σ²``, from the NF's ``a R⁻¹``) against the
    Cramér–Rao bound of the same window computed independently (:func:`_cramer_rao`: the simulated
    trajectory's sensitivities, the NF's forgetting, the initial state a nuisance), at the end of runs
    with each jump, the NF at least 600 updates old. Agreement within [0.6, 1.6]: the NF evaluates its
    sensitivities along its estimate's path and reports the stationary law ``P_θ/(1 + λ)``; measured
    0.77–1.33 on these cells, seeds 1–2."""
    dsg, _, _ = ship
    lay, s = dsg.layout, dsg.settings
    r = float(np.asarray(sp.plant().R).reshape(-1)[0])
    for par in ("a", "b"):
        for seed in (1, 2):
            batch = sp._simulate(sp.fault_scenario("x", {par: 0.5}, signal={"kind": kind, "offset": offset, "amplitude": amplitude}), (seed,))
            res = dsg.run(u=batch.U[0], y=batch.Y[0])
            last = lay.unpack(res["state"][-1])
            age = int(last["nf_age"])
            assert age >= 600, (par, seed, age)
            t0 = len(res["state"]) - age
            theta = np.array([sp.NOMINAL["a"], sp.NOMINAL["b"]])
            theta[0 if par == "a" else 1] *= 0.5
            x = np.asarray(batch.extra["x"][0]).reshape(-1)
            cov = _cramer_rao(batch.U[0][t0 - 1 :, 0], float(x[t0 - 1]), theta, s, r)
            ratio = np.asarray(last["nf_info"]).reshape(-1) * np.diag(cov)
            assert np.all((ratio >= 0.6) & (ratio <= 1.6)), (par, seed, ratio)

