"""ARCHITECTURE.md's worked example of a new problem runs as written: a complete ``Problem`` whose design is
certified, whose Monte Carlo (compiled and Python) keeps the designed false-alarm budget and finds and isolates
its fault."""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path
from types import ModuleType

import pytest
from fdisyn.evaluation.built import build
from fdisyn.evaluation.evaluate import evaluate
from scipy.stats import poisson

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def two_tanks(tmp_path_factory: pytest.TempPathFactory) -> ModuleType:
    text = (ROOT / "ARCHITECTURE.md").read_text(encoding="utf-8")
    section = text[text.index("## How to add a problem") :]
    code = re.search(r"```python\n(.*?)```", section, re.S)
    assert code is not None, "ARCHITECTURE.md lost its worked problem"
    path = tmp_path_factory.mktemp("problem") / "two_tanks.py"
    path.write_text(code.group(1), encoding="utf-8")
    spec = importlib.util.spec_from_file_location("fdisyn_example_two_tanks", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop("fdisyn_example_two_tanks", None)


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "python"])
def test_the_worked_problem_keeps_its_budget_and_isolates_its_fault(two_tanks: ModuleType, tmp_path: Path, compiled: bool) -> None:
    problem = two_tanks.PROBLEM
    gf = problem.design()
    assert gf.certificate["passed"] is True
    runs = 40
    ev = evaluate(problem, {"kalman": build(problem, "kalman", tmp_path / "kalman")}, runs=runs, workers=1, progress=False, compiled=compiled)
    nominal, bias = ev.metrics["kalman"]["nominal"], ev.metrics["kalman"]["h2_bias"]
    # fault-free: episodes over runs × 1800 s at one false alarm per hour; the diagnoser's episodes are Poisson at
    # most (persistence 1, χ² statistics of white residuals), so more than the 1e-6 upper quantile is a broken budget
    hours = runs * problem.scenarios["nominal"].duration / 3600.0
    assert nominal.false_alarm_episodes <= poisson.ppf(1 - 1e-6, hours * 3600.0 / problem.options["arl0"])
    # a 10 cm bias against 1 cm of sensor noise: found at once and named in every run
    assert bias.missed_detection_rate == 0.0
    assert bias.isolation_accuracy == 1.0
    assert bias.detection_delay_max_s is not None and bias.detection_delay_max_s <= 2 * gf.Ts
