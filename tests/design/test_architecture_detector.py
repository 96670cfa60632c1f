"""ARCHITECTURE.md's worked example of a new detector runs as written: its two entries (the runtime's NumPy
oracle in ``runtime/statistics.py``, the design's detector module) register an EWMA statistic, and with no other
change ``fdisyn.design`` builds a bank with it, the gain file reads back, the compiled C equals the NumPy oracle
and the CasADi step, its threshold holds the false-alarm budget on a simulated plant, and the account's smallest
detectable size is crossed half the time at its 50 % size."""

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
from fdisyn.detectors.table import DETECTORS, option_texts
from fdisyn.runtime.compiled import CompiledDiagnoser
from fdisyn.runtime.errors import ArgumentError, GainFileError
from fdisyn.runtime.gainfile import read_gain_file, write_gain_file
from fdisyn.runtime.statistics import STATISTICS

from tests.design.test_architecture_kind import simulate, stationary
from tests.design.test_kind_contract import check_kind_contract, hostile
from tests.helpers import random_plant

ROOT = Path(__file__).resolve().parents[2]
SPAN = 8
P_F = 0.05
"""A budget whose exceedances a run of 10⁵ samples counts to a few per cent (about 5000 exceedances, correlated
over about a span)."""


@pytest.fixture
def ewma(tmp_path: Path) -> Iterator[tuple[ModuleType, ModuleType]]:
    text = (ROOT / "ARCHITECTURE.md").read_text(encoding="utf-8")
    start = text.index("## How to add a detector")
    section = text[start : text.index("\n## ", start + 1)]
    blocks = re.findall(r"```python\n(.*?)```", section, re.S)
    assert len(blocks) == 2, "ARCHITECTURE.md lost its worked example of a detector (its runtime and design entries)"
    saved = dict(STATISTICS), dict(DETECTORS)
    modules = []
    try:
        for name, code in zip(("fdisyn_example_ewma_statistic", "fdisyn_example_ewma"), blocks, strict=True):
            path = tmp_path / f"{name}.py"
            path.write_text(code, encoding="utf-8")
            spec = importlib.util.spec_from_file_location(name, path)
            assert spec is not None and spec.loader is not None
            module = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(module)
            modules.append(module)
        yield modules[0], modules[1]
    finally:
        for table, before in zip((STATISTICS, DETECTORS), saved, strict=True):
            table.clear()
            table.update(before)
        for name in ("fdisyn_example_ewma_statistic", "fdisyn_example_ewma"):
            sys.modules.pop(name, None)


def exceed(gf, plant, T: int, seed: int, tmp_path: Path, bias: tuple[int, float] | None = None) -> np.ndarray:  # noqa: ANN001
    """``J > threshold`` of every statistic over a simulated run through the compiled step, after a burn-in of
    twenty spans (the EWMA starts at 0); a constant ``bias`` (sensor, size) from the start."""
    Y = simulate(plant, T, seed, slice(0, T if bias else 0), bias[0] if bias else 0, bias[1] if bias else 0.0)
    built = fdisyn.export(gf, tmp_path / f"c{seed}")
    got = CompiledDiagnoser(built / f"lib{gf.name}.so", gf).run(np.zeros((T, plant.m)), Y)
    return (got.J > np.asarray(gf.thresholds)[None, :])[20 * SPAN :]


def test_the_worked_example_is_a_complete_detector(ewma: tuple[ModuleType, ModuleType], tmp_path: Path) -> None:
    _, design = ewma
    assert list(DETECTORS)[-1] == "ewma" and "'ewma', the exponentially weighted mean" in option_texts()["detector"]
    plant = random_plant(3, n=3, p=3, q=1, radius=0.8)
    gf = fdisyn.design(plant, method="kalman_uio", detector="ewma", window=SPAN, P_f=P_F)
    assert gf.certificate["passed"] is True and gf.name
    assert {e.kind for e in gf.evaluators} == {"ewma"} and {e.window for e in gf.evaluators} == {SPAN}
    # the runtime reads the file back as written (the window is the span)
    write_gain_file(gf, tmp_path / "file.json")
    back = read_gain_file(tmp_path / "file.json")
    assert [(e.kind, e.window, e.threshold) for e in back.evaluators] == [(e.kind, e.window, e.threshold) for e in gf.evaluators]
    # the weights: λ(1 − λ)^k down to the tail left out
    w = design.weights(SPAN)
    assert w[0] == pytest.approx(2.0 / (SPAN + 1)) and 1.0 - w.sum() <= design.TAIL
    # the threshold holds the budget: the stationary exceedance rate of each statistic, counted on a simulated
    # plant through the compiled step (independent of the quadratic-form law the threshold came from); the
    # samples are correlated over about a span, so the binomial spread is widened by 2·span: ±25 % is > 4σ
    rate = exceed(gf, plant, 100_000, 1, tmp_path).mean(axis=0)
    assert np.all(np.abs(rate / P_F - 1.0) < 0.25), rate
    # the account: its rule is the example's, and a bias of the 50 % size is above the threshold about half the time
    acc = gf.account
    assert acc is not None and {s["rule"] for s in acc["statistics"]} == {"EWMA: P(J > threshold) = 95 % (50 %) in steady state"}
    fault = next(f for f in acc["faults"] if f["type"] == "sensor" and f["size_50"])
    j = gf.step.statistic_names.index(fault["size_by"])
    sensor = list(gf.outputs).index(fault["name"])
    half = exceed(gf, plant, 40_000, 2, tmp_path, (sensor, fault["size_50"]))[:, j].mean()
    assert abs(half - 0.5) < 0.1, half  # the four-moment law's error and the run's spread (σ ≈ 0.02)
    most = exceed(gf, plant, 40_000, 3, tmp_path, (sensor, fault["size"]))[:, j].mean()
    assert abs(most - 0.95) < 0.04, most  # measured 0.502 and 0.948 on this plant


def test_the_worked_example_passes_the_contract_of_every_kind(ewma: tuple[ModuleType, ModuleType], tmp_path: Path) -> None:
    """The compiled C, the CasADi step and the runtime's NumPy oracle agree sample by sample, on hostile input
    too (gaps, outliers, non-finite samples)."""
    plant = random_plant(5, n=3, p=3, q=1, radius=0.9)
    gf = fdisyn.design(plant, method="kalman_uio", detector="ewma", window=SPAN, P_f=1e-3, persistence=2)
    T = 1000
    U, Y = hostile(np.zeros((T, plant.m)), simulate(plant, T, 3, slice(500, 700), 0, 5.0), 3)
    worst = check_kind_contract(gf, U, Y, tmp_path)  # the oracle within the contract's REFERENCE (BLAS products)
    assert worst["alarms"] > 0 and "reference−CasADi" in worst and worst["C−CasADi"] == 0.0


def test_the_worked_example_is_refused_where_its_rules_say(ewma: tuple[ModuleType, ModuleType], tmp_path: Path) -> None:
    plant = random_plant(3, n=3, p=3, q=1, radius=0.8)
    gf = fdisyn.design(plant, method="kalman_uio", detector="ewma", P_f=P_F)
    assert {e.window for e in gf.evaluators} == {10}  # the detector's own default span
    with pytest.raises(GainFileError, match=r"window must be the EWMA's span, a whole number of samples in 1\.\.10000"):
        type(gf)(**{**gf.__dict__, "evaluators": [type(e)(**{**e.__dict__, "window": 0}) for e in gf.evaluators]})
    # an unknown name is refused by the option's domain, which reads the table live (its text was composed when the
    # registry was imported: a module in design/detectors/ is registered before that, this late one after)
    with pytest.raises(ArgumentError, match="option detector = 'ewm': expected 'chi2', 'wssr', 'cusum' or 'glr'"):
        fdisyn.design(plant, method="kalman_uio", detector="ewm")
    with pytest.raises(ArgumentError, match="window = 3 needs detector = 'wssr', 'glr' or 'ewma'"):
        fdisyn.design(plant, method="kalman_uio", detector="chi2", window=3)
