"""ARCHITECTURE.md's worked example of a new diagnoser kind runs as written: the module registers the kind
``limit_check`` and its method, ``fdisyn.design`` designs it on a random plant, the gain file is read back by the
runtime, its step exports to C, and the C's alarms and isolations are the band test computed here directly in
NumPy; the kind then passes the contract test of every kind (tests/design/test_kind_contract.py)."""

from __future__ import annotations

import importlib.util
import re
import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import fdisyn
import numpy as np
import pytest
import scipy.stats
from fdisyn.runtime.compiled import CompiledDiagnoser
from fdisyn.runtime.errors import ArgumentError, ExistenceError, GainFileError
from fdisyn.runtime.gainfile import read_gain_file, write_gain_file
from fdisyn.synthesis import kinds, registry

from tests.design.test_kind_contract import check_kind_contract, hostile
from tests.helpers import random_plant

ROOT = Path(__file__).resolve().parents[2]
P_F = 1e-2
"""A budget whose exceedances a short run counts (10⁴ samples: about 100 per sensor)."""


@pytest.fixture
def limit_check(tmp_path: Path) -> Iterator[ModuleType]:
    text = (ROOT / "ARCHITECTURE.md").read_text(encoding="utf-8")
    start = text.index("## How to add a kind")
    section = text[start : text.index("\n## ", start + 1)]
    code = re.search(r"```python\n(.*?)```", section, re.S)
    assert code is not None, "ARCHITECTURE.md lost its worked example of a kind"
    path = tmp_path / "limit_check.py"
    path.write_text(code.group(1), encoding="utf-8")
    registry.all_methods()  # the kinds and methods of fdisyn are discovered first: the example's are checked at once
    spec = importlib.util.spec_from_file_location("fdisyn_example_limit_check", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
        yield module
    finally:
        kinds._KINDS.pop("limit_check", None)
        registry._METHODS.pop("limit_check", None)
        sys.modules.pop("fdisyn_example_limit_check", None)


def simulate(plant, T: int, seed: int, faulty: slice, sensor: int, size: float) -> np.ndarray:  # noqa: ANN001 - a plant
    """``x⁺ = A x + w``, ``y = C x + v`` (the inputs at their nominal 0, no unknown input), started in the
    stationary law, a bias ``size`` on ``sensor`` over ``faulty``."""
    rng = np.random.default_rng(seed)
    lq, lr = np.linalg.cholesky(plant.Q), np.linalg.cholesky(plant.R)
    x = np.linalg.cholesky(stationary(plant)) @ rng.standard_normal(plant.n)
    Y = np.zeros((T, plant.p))
    for k in range(T):
        Y[k] = plant.C @ x + lr @ rng.standard_normal(plant.p)
        x = plant.A @ x + lq @ rng.standard_normal(plant.n)
    Y[faulty, sensor] += size
    return Y


def stationary(plant) -> np.ndarray:  # noqa: ANN001 - a plant
    """``P = Σ_k A^k Q A^kᵀ`` summed until the terms vanish (not SciPy's Lyapunov solver)."""
    P, term = np.zeros_like(plant.Q), plant.Q.copy()
    while np.max(np.abs(term)) > 1e-18 * np.max(np.abs(P), initial=1.0):
        P, term = P + term, plant.A @ term @ plant.A.T
    return P


def band_truth(Y: np.ndarray, nominal: np.ndarray, sigma: np.ndarray, z: float, persistence: int) -> tuple[np.ndarray, np.ndarray]:
    """Alarms and isolations of the band test, sample by sample: a sensor alarms from its ``persistence``-th
    consecutive sample outside ``nominal ± z σ``; the isolated sensor is the one alarming alone."""
    count = np.zeros(Y.shape[1], dtype=int)
    alarm, isolated = np.zeros(len(Y), dtype=int), np.full(len(Y), -1)
    for k, y in enumerate(Y):
        count = np.where(np.abs(y - nominal) > z * sigma, count + 1, 0)
        on = np.flatnonzero(count >= persistence)
        alarm[k] = int(on.size > 0)
        isolated[k] = on[0] if on.size == 1 else -1
    return alarm, isolated


def test_the_worked_example_is_a_complete_kind(limit_check: ModuleType, tmp_path: Path) -> None:
    assert "limit_check" in fdisyn.methods() and "limit_check" in kinds.kind_names()
    plant = random_plant(5, n=3, p=2, q=1, radius=0.8)
    nominal = [0.5, -1.0]
    gf = fdisyn.design(plant, method="limit_check", P_f=P_F, persistence=2, nominal=nominal)
    assert gf.kind == "limit_check" and gf.certificate["passed"] is True
    # the runtime reads the gain file back as written
    write_gain_file(gf, tmp_path / "file.json")
    back = read_gain_file(tmp_path / "file.json")
    assert back.extensions == gf.extensions and np.array_equal(back.thresholds, gf.thresholds)
    # the band: σ from the stationary covariance, z the Gaussian quantile of P_f/2 (computed here, apart)
    sigma = np.sqrt(np.diag(plant.C @ stationary(plant) @ plant.C.T + plant.R))
    z = float(scipy.stats.norm.isf(P_F / 2))
    pay = gf.extensions["limit_check"]
    np.testing.assert_allclose(pay["sigma"], sigma, rtol=1e-10)
    assert pay["z"] == pytest.approx(z, rel=1e-14) and gf.thresholds.tolist() == [pay["z"]] * 2
    # the C against the band test; a 6σ bias on the second sensor from the middle
    T = 10_000
    Y = simulate(plant, T, 1, slice(T // 2, T // 2 + 200), 1, 6.0 * sigma[1]) + np.array(nominal)
    U = np.zeros((T, plant.m))
    built = fdisyn.export(gf, tmp_path / "c")
    cd = CompiledDiagnoser(built / "liblimit_check.so", gf)
    got = cd.run(U, Y)
    alarm, isolated = band_truth(Y, np.array(nominal), np.array(pay["sigma"]), pay["z"], 2)
    np.testing.assert_array_equal(got.alarm, alarm)
    np.testing.assert_array_equal(got.isolated, isolated)
    assert np.all(got.isolated[T // 2 + 1 : T // 2 + 200] == 1)  # the fault, isolated from its second sample
    # the budget: the fault-free exceedance rate per sensor is P_f (about 50 per sensor in 5000 samples;
    # the samples are correlated, so the bounds are wide)
    outside = np.abs(Y[: T // 2] - nominal) > z * sigma
    assert np.all((0.4 * P_F < outside.mean(axis=0)) & (outside.mean(axis=0) < 2.5 * P_F)), outside.mean(axis=0)
    assert kinds.false_alarm_budget(gf) == pytest.approx(plant.Ts / (2 * P_F), rel=1e-9)
    # the Monitor runs it too, naming the sensor
    monitor = fdisyn.load(built)
    far = np.array(nominal) + [0.0, 10.0 * sigma[1]]
    first, second = monitor.update(np.zeros(plant.m), far), monitor.update(np.zeros(plant.m), far)
    assert (first.alarm, second.alarm, second.fault) == (False, True, plant.outputs[1])


def test_the_worked_example_passes_the_contract_of_every_kind(limit_check: ModuleType, tmp_path: Path) -> None:
    plant = random_plant(7, n=3, p=3, q=1, radius=0.8)
    gf = fdisyn.design(plant, method="limit_check", P_f=P_F, persistence=3)
    T = 1000
    sigma = np.array(gf.extensions["limit_check"]["sigma"])
    U, Y = hostile(np.zeros((T, plant.m)), simulate(plant, T, 2, slice(500, 700), 0, 5.0 * sigma[0]), 3)
    worst = check_kind_contract(gf, U, Y, tmp_path)
    assert worst["alarms"] > 0 and worst["reference−CasADi"] == 0.0 and worst["C−CasADi"] == 0.0


def test_the_worked_example_refuses_what_it_cannot_design(limit_check: ModuleType) -> None:
    plant = random_plant(5, n=3, p=2, q=1, radius=0.8)
    with pytest.raises(ArgumentError, match="nominal lists 1 values; expected one per output"):
        fdisyn.design(plant, method="limit_check", nominal=[0.0])
    with pytest.raises(ArgumentError, match="P_f"):
        fdisyn.design(plant, method="limit_check", P_f=2.0)
    with pytest.raises(ExistenceError, match="stable plant"):
        fdisyn.design(random_plant(5, n=3, p=2, q=1, radius=1.2), method="limit_check")
    gf = fdisyn.design(plant, method="limit_check")
    bad = dict(gf.extensions["limit_check"], sigma=[-1.0, 1.0])
    with pytest.raises(GainFileError, match="sigma, z must be positive"):
        limit_check.limit_step(type(gf)(**{**gf.__dict__, "extensions": {"limit_check": bad}}))
