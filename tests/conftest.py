"""Shared fixtures: the compiled wind-turbine and DC-motor diagnosers, each built once, and a wind-turbine trace."""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import pytest
from fdisyn.app.examples import EXAMPLES

_MYPY: list[tuple[subprocess.Popen, Path]] = []
"""The mypy process of ``tests/test_typing.py`` and its scratch folder, while the session runs."""


def pytest_collection_finish(session: pytest.Session) -> None:
    """Start mypy as soon as ``tests/test_typing.py::test_mypy_passes`` is among the tests to run: a process of its
    own for half a minute, it runs on the second core beside the other tests (which use one) instead of after them.
    Under pytest-xdist every worker collects every test, so there the test starts mypy itself (:func:`mypy_run`) in
    the one worker that runs it, beside the other worker's tests."""
    if os.environ.get("PYTEST_XDIST_WORKER"):
        return
    for item in [] if session.config.option.collectonly else session.items:
        if item.nodeid.endswith("test_typing.py::test_mypy_passes"):
            _start_mypy(item.module)
            return


def _start_mypy(module: object) -> None:
    scratch = Path(tempfile.mkdtemp(prefix="fdisyn-mypy-"))
    _MYPY.append((module.start_mypy(scratch), scratch))  # type: ignore[attr-defined]


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """A session that stops early (``-x``) does not leave mypy running; the scratch folder goes either way."""
    for proc, scratch in _MYPY:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        shutil.rmtree(scratch, ignore_errors=True)
    _MYPY.clear()


@pytest.fixture(scope="session")
def mypy_run() -> tuple[subprocess.Popen, Path]:
    """The mypy process started when the tests were collected (or now, under pytest-xdist), and its scratch folder."""
    if not _MYPY:
        from tests import test_typing

        _start_mypy(test_typing)
    return _MYPY[0]


@pytest.fixture(scope="session")
def wt_built(tmp_path_factory: pytest.TempPathFactory):
    """The default wind-turbine bank, designed, written and compiled once."""
    from fdisyn.evaluation.built import build
    from fdisyn.problems.wind_turbine import PROBLEM

    return build(PROBLEM, "kalman_uio", tmp_path_factory.mktemp("wt") / "kalman_uio")


@pytest.fixture(scope="session")
def motor_built(tmp_path_factory: pytest.TempPathFactory):
    """The DC-motor plant file's (the example ``dc_motor``) default design (4 outputs of 2 generators),
    designed, written and compiled once."""
    from fdisyn.simulation.plant_file import load_spec
    from fdisyn.evaluation.built import build

    prob = load_spec(EXAMPLES / "dc_motor.toml")
    return build(prob, prob.default_design, tmp_path_factory.mktemp("motor") / "kalman_uio")


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
    return EXAMPLES
