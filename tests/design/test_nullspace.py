"""The nullspace method (``method="nullspace"``): one least-order generator per row of a structure matrix, checked
against truths its certificate does not use: the transfer functions at other points than the certificate's, the
least order found from polynomial null vectors at points (tests/design/test_structure.py), and the residuals of
simulated runs through the gain file's NumPy reference, where each sensor's bias must raise the alarm and be
named."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import fdisyn
from fdisyn.app.cli import main
from fdisyn.runtime.errors import ArgumentError, ExistenceError
from fdisyn.synthesis.kinds import reference_run
from fdisyn.synthesis.nullspace import nullspace_generator
from fdisyn.synthesis.structure import analyse_structure, fault_entries
from tests.design.test_structure import _least_order_by_points, _plant, _points

OFF_CIRCLE_TOL = 1e-8
"""``R_u``, ``R_d`` and a decoupled fault's response at points off the unit circle, relative to ``‖Q‖ ‖G‖`` there:
exact zeros of rational functions leave round-off (measured below 1e-12), a seen fault stays above 1e-6."""


def _transfer(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray, z: complex) -> np.ndarray:
    return (c @ np.linalg.solve(z * np.eye(a.shape[0]) - a, b) if a.shape[0] else 0) + d


def _responses(plant: fdisyn.LinearPlant, gen, z: complex) -> tuple[float, float, np.ndarray]:  # noqa: ANN001
    """``(|R_u|, |R_d|, |R_f| per fault)`` at ``z``, each relative to ``‖Q(z)‖`` and the plant's part."""
    a, c = np.asarray(plant.A), np.asarray(plant.C)
    qy = _transfer(gen.Ar, gen.By, gen.Cr, gen.Dy, z)
    qu = _transfer(gen.Ar, gen.Bu, gen.Cr, gen.Du, z)
    qn = np.linalg.norm(np.hstack([qy, qu]))
    gu = _transfer(a, np.asarray(plant.B), c, np.asarray(plant.D), z)
    ru = np.linalg.norm(qy @ gu + qu) / (qn * max(np.linalg.norm(gu), 1.0)) if plant.m else 0.0
    gd = _transfer(a, np.asarray(plant.E), c, np.asarray(plant.Dd), z)
    rd = np.linalg.norm(qy @ gd) / (qn * np.linalg.norm(gd)) if plant.q else 0.0
    _, bf, df = fault_entries(plant)
    gf = _transfer(a, bf, c, df, z)
    rf = np.abs(qy @ gf)[0] / (qn * np.linalg.norm(gf, axis=0))
    return float(ru), float(rd), rf


@pytest.mark.parametrize("seed", range(16))
def test_every_achievable_row_gets_a_decoupled_generator_of_its_least_order(seed: int) -> None:
    plant = _plant(400 + seed)
    res = analyse_structure(plant)
    for row, least in zip(res.rows, res.least_orders, strict=True):
        gen, sigma, cert = nullspace_generator(plant, row, "g", pole=0.5)  # the pole's choice: tests/design/test_gap.py
        assert cert.passed, cert
        assert gen.n_state == least == _least_order_by_points(plant, row, _points(seed))
        assert np.all(np.abs(np.linalg.eigvals(gen.Ar)) < 1) and sigma.shape == (1, 1) and np.isfinite(sigma).all()
        for z in (1.3 * np.exp(0.7j), 0.6 * np.exp(2.1j), -1.7):
            ru, rd, rf = _responses(plant, gen, z)
            assert ru <= OFF_CIRCLE_TOL and rd <= OFF_CIRCLE_TOL, (row, z, ru, rd)
            assert np.all(rf[row == 0] <= OFF_CIRCLE_TOL), (row, z, rf)
        assert all(max(_responses(plant, gen, z)[2][j] for z in (1.3 * np.exp(0.7j), 0.6 * np.exp(2.1j))) > 1e-6 for j in np.flatnonzero(row))


def _isolating_plant() -> fdisyn.LinearPlant:
    """Four sensors, one unknown input and one known input on a stable 4-state plant: each sensor's fault can be
    decoupled alone, so the rows that decouple one sensor each tell every sensor fault apart."""
    rng = np.random.default_rng(21)
    n, p = 4, 4
    a = rng.standard_normal((n, n))
    a *= 0.85 / max(abs(np.linalg.eigvals(a)))
    return fdisyn.LinearPlant.create(
        A=a, B=rng.standard_normal((n, 1)), C=rng.standard_normal((p, n)), E=rng.standard_normal((n, 1)),
        Q=0.01 * np.eye(n), R=0.01 * np.eye(p), Ts=0.1,
    )


def test_the_bank_detects_and_names_each_sensor_bias_in_simulated_runs() -> None:
    plant = _isolating_plant()
    structure = [[0 if j == i else 1 for j in range(4)] for i in range(4)]
    gf = fdisyn.design(plant, method="nullspace", structure=structure, P_f=1e-6)  # 4 × 600 fault-free samples: 0.2 % chance of a false alarm
    assert [g.n_state for g in gf.generators] == list(analyse_structure(plant).least_orders[1:5])  # the rows decoupling one sensor
    rng = np.random.default_rng(3)
    a, b, c, e = (np.asarray(x) for x in (plant.A, plant.B, plant.C, plant.E))
    steps, onset = 1500, 700
    for sensor in range(4):
        x = rng.standard_normal(4)  # the plant is moving when the diagnoser starts
        U = np.sin(0.05 * np.arange(steps))[:, None]
        D = 3.0 * np.cumsum(rng.standard_normal(steps)) / np.sqrt(steps)  # a large, slow unknown input
        Y = np.zeros((steps, 4))
        for k in range(steps):
            Y[k] = c @ x + 0.1 * rng.standard_normal(4)
            x = a @ x + b @ U[k] + e[:, 0] * D[k] + 0.1 * rng.standard_normal(4)
        Y[onset:, sensor] += 3.0
        out = reference_run(gf, U, Y)
        assert not out.alarm[100:onset].any(), f"false alarm before the bias on {plant.outputs[sensor]}"
        after = out.isolated[onset + 50 :]
        assert out.alarm[onset + 50 :].mean() > 0.9
        named = [gf.faults[i] for i in after if i >= 0]
        assert named.count(plant.outputs[sensor]) > 0.9 * len(after), (sensor, set(named))


def test_an_unachievable_row_and_a_malformed_structure_are_refused_by_name() -> None:
    plant = fdisyn.LinearPlant.create(A=[[0.5, 0.1], [0.0, 0.3]], B=[[1.0], [0.0]], C=[[1.0, 0.0], [0.0, 1.0]], E=[[0.0], [1.0]], Ts=0.1)
    with pytest.raises(ExistenceError, match=r"not achievable: decoupling \['y0'\] hides \['y1'\]"):
        fdisyn.design(plant, method="nullspace", structure=[[0, 1]])
    with pytest.raises(ArgumentError, match="structure must be rows of 2 entries 0 or 1"):
        fdisyn.design(plant, method="nullspace", structure=[[1, 2]])
    with pytest.raises(ArgumentError, match="pole"):
        fdisyn.design(plant, method="nullspace", pole=1.5)


PLANT_FILE = """\
name = "four_sensors"
title = "Four sensors, one unknown input"

[signals]
outputs = ["s0", "s1", "s2", "s3"]

[model]
time = "discrete"
Ts = 0.1
A = {A}
B = {B}
C = {C}
E = {E}
Q = {Q}
R = {R}

[design]
method = "nullspace"
structure = [[0, 1, 1, 1], [1, 0, 1, 1], [1, 1, 0, 1], [1, 1, 1, 0]]
pole = 0.3

[simulation]
duration = 10.0

[[scenarios]]
name = "s1_bias"
description = "s1 reads 3 high from 5 s."
duration = 10.0
fault = "s1"
onset = 5.0
sensor_faults = [{{ sensor = "s1", kind = "offset", value = 3.0 }}]
"""


def test_a_plant_file_designs_with_the_nullspace_method(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    plant = _isolating_plant()
    text = PLANT_FILE.format(**{k: np.asarray(getattr(plant, k)).tolist() for k in ("A", "B", "C", "E", "Q", "R")})
    spec = tmp_path / "four.toml"
    spec.write_text(text, encoding="utf-8")
    assert main(["design", str(spec), "--out", str(tmp_path / "out")]) == 0, capsys.readouterr().err
    gf = fdisyn.runtime.gainfile.read_gain_file(tmp_path / "out" / "gains.json")
    assert len(gf.generators) == 4 and all(np.allclose(np.linalg.eigvals(g.Ar), 0.3, atol=1e-3) for g in gf.generators)
    assert main(["analyse", str(spec)]) == 0
    assert "four_sensors: 4 faults, weak structure" in capsys.readouterr().out


def _unstable_plant(seed: int) -> fdisyn.LinearPlant:
    """Spectral radius up to 1.4, states in units spread over six decades, noise on every state and sensor."""
    rng = np.random.default_rng(1000 + seed)
    n, p = int(rng.integers(2, 9)), int(rng.integers(2, 6))
    m, q, nc = int(rng.integers(0, 3)), int(rng.integers(0, p - 1)), int(rng.integers(0, 3))
    a = rng.standard_normal((n, n))
    a *= rng.uniform(1.05, 1.4) / max(abs(np.linalg.eigvals(a)))
    s = 10.0 ** rng.uniform(-3, 3, n)
    return fdisyn.LinearPlant.create(
        A=np.diag(s) @ a @ np.diag(1 / s), B=np.diag(s) @ rng.standard_normal((n, m)), C=rng.standard_normal((p, n)) @ np.diag(1 / s),
        D=rng.standard_normal((p, m)) * (rng.random() < 0.5), E=np.diag(s) @ rng.standard_normal((n, q)),
        Fx=np.diag(s) @ rng.standard_normal((n, nc)), Ts=0.05, component_faults=[f"c{i}" for i in range(nc)],
        Q=np.diag(s**2) * 1e-2, R=1e-2 * np.eye(p),
    )


@pytest.mark.parametrize("seed", range(24))
def test_on_an_unstable_plant_the_filter_cancels_the_unstable_modes_in_its_noise_and_fault_responses(seed: int) -> None:
    """Every row of an unstable plant in the user's units: certified, with a stationary residual (its covariance
    exists), and its responses to the noise and to every fault finite at the unstable poles (evaluated just beside
    them: a pole left in would make them grow like the inverse distance)."""
    plant = _unstable_plant(seed)
    a, c = np.asarray(plant.A), np.asarray(plant.C)
    poles = [z for z in np.linalg.eigvals(a) if abs(z) >= 1]
    lam, vec = np.linalg.eigh(np.asarray(plant.Q))
    wq = vec * np.sqrt(np.clip(lam, 0, None))
    _, bf, df = fault_entries(plant)
    for row in analyse_structure(plant).rows[:6]:
        gen, sigma, cert = nullspace_generator(plant, row, "g", pole=0.5)  # the pole's choice: tests/design/test_gap.py
        assert cert.passed and np.isfinite(sigma).all() and sigma[0, 0] > 0
        for z0 in poles:
            near, nearer = z0 * (1 + 1e-3), z0 * (1 + 1e-7)
            for b, d in ((wq, np.zeros((plant.p, plant.n))), (bf, df)):
                size = [np.linalg.norm(_transfer(gen.Ar, gen.By, gen.Cr, gen.Dy, z) @ _transfer(a, b, c, d, z)) for z in (near, nearer)]
                assert size[1] <= 10 * max(size[0], 1e-12), (row, z0, size)


@pytest.mark.parametrize(("problem", "Ts", "orders"), [
    ("wind_turbine", None, [2, 2, 2, 2]),
    ("turbofan", 0.02, [1, 2, 2, 2, 2, 2, 1, 2, 1]),
    ("satellite_pitch", 0.1, [1, 1, 1, 1, 2, 2]),  # a rigid body: double integrators, sampled exactly
])
def test_the_reference_plants_get_an_isolating_bank_of_least_order_filters(problem: str, Ts: float | None, orders: list[int]) -> None:
    """Each reference plant's rows that decouple one fault each: one filter per fault, every fault its own class."""
    from fdisyn.simulation.problem import get_problem

    plant = get_problem(problem).model()
    plant = plant if plant.is_discrete else plant.discretise(Ts)
    res = analyse_structure(plant)
    rows = [list(r) for r in res.rows if sum(r) == len(res.faults) - 1]
    gf = fdisyn.design(plant, method="nullspace", structure=rows, pole=0.5)
    assert [g.n_state for g in gf.generators] == orders
    assert list(gf.faults) == list(res.faults)  # every fault isolable: its own class


def test_a_continuous_plant_is_designed_on_its_exact_sampling_and_needs_its_sample_time() -> None:
    plant = fdisyn.LinearPlant.create(A=[[-1.0, 0.5], [0.0, -2.0]], B=[[0.0], [1.0]], C=np.eye(2), E=[[0.1], [1.0]],
                                      Q=np.eye(2) * 1e-3, R=np.eye(2) * 1e-2)
    with pytest.raises(ArgumentError, match="a continuous plant needs Ts"):
        fdisyn.design(plant, method="nullspace")
    gf = fdisyn.design(plant, method="nullspace", Ts=0.05)
    assert gf.Ts == 0.05 and gf.certificate["passed"]
    assert [g.n_state for g in gf.generators] == list(analyse_structure(plant.discretise(0.05)).least_orders[:1])
