"""The main job's phase timer (:func:`fdisyn.evaluation.progress.phase`) and its table, on a fake clock."""

from __future__ import annotations

import time

import pytest
from fdisyn.app.pipeline import PHASES, phase_table
from fdisyn.evaluation import progress


def test_a_phase_inside_another_counts_for_itself_only(monkeypatch: pytest.MonkeyPatch) -> None:
    now = [100.0]
    monkeypatch.setattr(time, "perf_counter", lambda: now[0])
    monkeypatch.setattr(progress, "_PHASES", {})
    with progress.phase("p", "Monte Carlo"):
        now[0] += 2.0
        with progress.phase("p", "generate and compile"):
            now[0] += 5.0
        now[0] += 1.0
    with progress.phase("q", "design"):
        now[0] += 0.5
    with pytest.raises(RuntimeError), progress.phase("q", "design"):  # a phase that fails is counted too
        now[0] += 0.25
        raise RuntimeError
    assert progress.phase_seconds() == {("p", "Monte Carlo"): 3.0, ("p", "generate and compile"): 5.0, ("q", "design"): 0.75}
    table = phase_table(["p", "q"])
    rows = table.splitlines()
    assert rows[0] == "| problem | " + " | ".join(PHASES) + " | total |"
    assert rows[2] == "| p | 0 | 5 | 0 | 3 | 0 | 8 |" and rows[3] == "| q | 1 | 0 | 0 | 0 | 0 | 1 |"
    assert rows[4] == "| all | 1 | 5 | 0 | 3 | 0 | 9 |"
    assert "largest process:" in table
