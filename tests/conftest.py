"""Shared fixtures: seeded random plants and one compiled wind-turbine diagnoser."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def wt_built(tmp_path_factory: pytest.TempPathFactory):
    """The default wind-turbine bank, designed, written and compiled once."""
    from fdisyn.evaluation.evaluate import build
    from fdisyn.problems.wind_turbine import PROBLEM

    return build(PROBLEM, "kalman_uio", tmp_path_factory.mktemp("wt") / "kalman_uio")


@pytest.fixture
def built_copy(wt_built, tmp_path: Path) -> Path:
    """A private copy of the compiled wind-turbine directory (gains.json, library, manifest, replay): what
    ``fdisyn design wind_turbine --out DIR`` and ``fdisyn codegen DIR`` write, for a test to change."""
    d = tmp_path / "wt"
    shutil.copytree(wt_built.directory, d)
    return d


@pytest.fixture(scope="session")
def wt_trace():
    """10⁴ samples (50–150 s) of the benchmark stuck-sensor scenario (fault from 100 s), seed 3."""
    from fdisyn.problems.wind_turbine import PROBLEM

    b = PROBLEM.run("benchmark_stuck", [3])
    sl = slice(5_000, 15_000)
    return b.t[sl], b.U[0][sl].copy(), b.Y[0][sl].copy()


@pytest.fixture
def data_dir() -> Path:
    return Path(__file__).parent / "data"
