"""``fdisyn bench``: the SDP solve times of the LMI toolkit (seconds of cvxpy + Clarabel that concern no problem
in particular) are measured for the full built-in bench or with ``--sdp``, never for ``fdisyn bench SPEC`` alone."""

from __future__ import annotations

from pathlib import Path

import fdisyn.app.bench as bench
import pytest
from fdisyn.app.cli import main


@pytest.fixture
def calls(monkeypatch) -> list[dict]:
    """``run_bench`` as the command line calls it: its problems and its ``sdp``, ``monte_carlo`` and ``scaling`` flags,
    nothing measured."""
    seen: list[dict] = []

    def fake(problems, *, out: Path, workdir: Path, sdp: bool = False, monte_carlo: bool = False, scaling: bool = False) -> Path:  # noqa: ANN001
        seen.append({"problems": [p.name for p in problems], "sdp": sdp, "monte_carlo": monte_carlo, "scaling": scaling})
        return out

    monkeypatch.setattr(bench, "run_bench", fake)
    return seen


def test_only_the_full_bench_or_sdp_times_the_sdps(calls, tmp_path) -> None:
    out = ["--out", str(tmp_path / "bench.md"), "--workdir", str(tmp_path / "w")]
    assert main(["bench", "wind_turbine", *out]) == 0
    assert main(["bench", "wind_turbine", "--sdp", *out]) == 0
    assert main(["bench", *out]) == 0
    assert main(["bench", "wind_turbine", "--scaling", *out]) == 0
    assert [c["sdp"] for c in calls] == [False, True, True, False]
    assert [c["monte_carlo"] for c in calls] == [False, False, True, False]  # the Monte Carlo's throughput: the full bench
    assert [c["scaling"] for c in calls] == [False, False, True, True]  # the random plants: the full bench or --scaling
    assert calls[0]["problems"] == ["wind_turbine"] and len(calls[2]["problems"]) > 1


def test_the_sdp_section_is_written_only_when_asked(monkeypatch, tmp_path) -> None:
    row = bench.TimingRow(n=2, hinf_solve=1e-3, hinf_wall=2e-2, h2_solve=2e-4, hminus_solve=8e-4, design_solve=5e-3, design_wall=0.3, design_sdps=4)
    asked: list[bool] = []
    big = bench.TimingRow(n=16, hinf_solve=0.5, hinf_wall=0.6, h2_solve=0.1, hminus_solve=0.9, design_solve=4.0, design_wall=5.0, design_sdps=3)
    monkeypatch.setattr(bench, "sdp_timings", lambda **kw: asked.append(True) or [row, big])
    plain = bench.run_bench([], out=tmp_path / "plain.md", workdir=tmp_path / "w").read_text(encoding="utf-8")
    assert asked == [] and "SDP" not in plain and "| problem | design |" in plain
    full = bench.run_bench([], out=tmp_path / "full.md", workdir=tmp_path / "w", sdp=True).read_text(encoding="utf-8")
    assert asked == [True] and full.startswith(plain.split("Measured by")[0])
    assert "## SDP solve times (cvxpy + Clarabel)" in full and "| 2 | 1.0 (20) | 0.2 | 0.8 | SDP | 5 (300 wall, 4 SDPs) |" in full
    assert "| 16 | 500.0 (600) | 100.0 | 900.0 | DARE | 4000 (5000 wall, 3 SDPs) |" in full  # the gain's route by size
