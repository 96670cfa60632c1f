"""ARCHITECTURE.md's worked example of a new method runs as written: the module registers itself,
``fdisyn.design`` designs with it, and its generators meet independent truths (the requested poles,
and a zero residual on a noise-free trajectory)."""

from __future__ import annotations

import importlib.util
import re
import sys
from collections.abc import Iterator
from pathlib import Path

import fdisyn
import numpy as np
import pytest
from fdisyn.synthesis import registry

from tests.helpers import random_plant

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def luenberger(tmp_path: Path) -> Iterator[None]:
    text = (ROOT / "ARCHITECTURE.md").read_text(encoding="utf-8")
    section = text[text.index("## How to add a method") : text.index("## How to add a problem")]
    code = re.search(r"```python\n(.*?)```", section, re.S)
    assert code is not None, "ARCHITECTURE.md lost its worked example"
    path = tmp_path / "luenberger.py"
    path.write_text(code.group(1), encoding="utf-8")
    spec = importlib.util.spec_from_file_location("fdisyn_example_luenberger", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    try:
        yield
    finally:
        registry._METHODS.pop("luenberger", None)
        sys.modules.pop("fdisyn_example_luenberger", None)


def test_the_worked_example_is_a_complete_method(luenberger: None) -> None:
    assert "luenberger" in fdisyn.methods()
    plant = random_plant(3, n=3, p=2, q=1, radius=0.8)
    poles = [0.1, 0.2, 0.3]
    gf = fdisyn.design(plant, method="luenberger", poles=poles, P_f=1e-3)
    assert gf.certificate["passed"] is True
    gen = gf.generators[0]
    np.testing.assert_allclose(np.sort(np.linalg.eigvals(gen.Ar).real), poles, atol=1e-9)  # well-conditioned KNV
    # noise-free, no unknown input, both started at zero: the residual is round-off
    rng = np.random.default_rng(0)
    x, xi = np.zeros(plant.n), np.zeros(gen.n_state)
    worst = 0.0
    for _ in range(200):
        u = rng.standard_normal(plant.m)
        y = plant.C @ x + plant.D @ u
        r = gen.Cr @ xi + gen.Du @ u + gen.Dy @ y
        worst = max(worst, float(np.max(np.abs(r))))
        x, xi = plant.A @ x + plant.B @ u, gen.Ar @ xi + gen.Bu @ u + gen.By @ y
    assert worst < 1e-10 * max(1.0, float(np.max(np.abs(x))))


def test_a_bad_option_is_refused_by_the_schema(luenberger: None) -> None:
    plant = random_plant(3, n=3, p=2, q=1, radius=0.8)
    with pytest.raises(fdisyn.runtime.errors.ArgumentError, match="poles"):
        fdisyn.design(plant, method="luenberger", poles=[2.0, 0.1, 0.1])
