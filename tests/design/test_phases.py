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


def test_the_main_job_s_section_of_the_bench_file_is_replaced_not_repeated(monkeypatch: pytest.MonkeyPatch, tmp_path) -> None:
    """``record_main_job`` writes the phase table as one section of ``bench.md``: into a file with other sections it
    replaces its own (a second run does not add a second), leaves the others as they were, and ``kept_section``
    gives it back for ``fdisyn bench``'s rewrite of the file."""
    from fdisyn.app.bench import MAIN_JOB_HEADING, kept_section, record_main_job

    now = [0.0]
    monkeypatch.setattr(time, "perf_counter", lambda: now[0])
    monkeypatch.setattr(progress, "_PHASES", {})
    bench = tmp_path / "bench.md"
    bench.write_text("# fdisyn benchmark\n\n## Steps\n\n| a |\n\n## SDP solve times\n\nrows\n", encoding="utf-8")
    for seconds in (7.0, 11.0):
        with progress.phase("p", "report"):
            now[0] += seconds
        record_main_job(bench, ["p"])
    text = bench.read_text(encoding="utf-8")
    assert text.count(MAIN_JOB_HEADING) == 1 and "| p | 0 | 0 | 0 | 0 | 18 | 18 |" in text
    assert text.startswith("# fdisyn benchmark\n\n## Steps\n\n| a |\n\n## SDP solve times\n\nrows\n")
    kept = kept_section(bench)
    assert kept[:2] == ["", MAIN_JOB_HEADING] and "| p | 0 | 0 | 0 | 0 | 18 | 18 |" in kept
    assert kept_section(tmp_path / "none.md") == []
    fresh = record_main_job(tmp_path / "new" / "bench.md", ["p"])
    assert fresh.read_text(encoding="utf-8").count(MAIN_JOB_HEADING) == 1
