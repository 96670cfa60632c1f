"""The workflow scripts shipped in ``fdisyn/examples/workflows/`` run as a user runs them, in an empty folder, and
do what they say: designs compared on one page, a trace plotted, names and units from python-control to the page,
a plant file that designs the same diagnoser, a firmware program built against the generated C."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

import fdisyn
from fdisyn.runtime.gainfile import GainFile, read_gain_file, without_clock
from fdisyn.simulation.plant_file import problem_from_toml

WORKFLOWS = Path(fdisyn.__file__).parent / "examples" / "workflows"
RUNS = "3"  # Monte Carlo runs per scenario: enough for every page section, few for the suite


def _run(script: str, folder: Path, *args: str) -> str:
    env = {**os.environ, "MPLBACKEND": "Agg"}
    proc = subprocess.run([sys.executable, str(WORKFLOWS / script), *args], cwd=folder, env=env, capture_output=True,
                          text=True, timeout=900)  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc.stdout


def _body(gf: GainFile) -> dict[str, Any]:
    d = without_clock(gf).to_dict()
    d.pop("provenance")  # where and when it was made: a plant file's path, a Python problem's
    return d


def _png(path: Path) -> None:
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 10_000


def test_own_linear_plant(tmp_path: Path) -> None:
    out = _run("own_linear_plant.py", tmp_path, RUNS)
    assert "the plant file designs the same generators: True" in out
    page = (tmp_path / "reports" / "motor" / "index.html").read_text(encoding="utf-8")
    assert "designs kalman (kalman_uio), wssr (kalman_uio)" in page
    assert page.count("speed (rad/s)") >= 2  # python-control's output name w_meas, the plant's label and unit
    _png(tmp_path / "motor_trace.png")
    built = read_gain_file(tmp_path / ".fdisyn" / "motor" / "default" / "kalman" / "gains.json")
    assert built.inputs == ("voltage",) and built.outputs == ("i_meas", "w_meas", "theta_meas")  # from control.ss
    assert built.units["w_meas"] == "rad/s" and built.labels["w_meas"] == "speed"
    # the plant file it wrote designs the gain file the Python problem built, to the last bit
    for design in ("kalman", "wssr"):
        filed = problem_from_toml(tmp_path / "motor.toml").design(design)
        assert _body(filed) == _body(read_gain_file(tmp_path / ".fdisyn" / "motor" / "default" / design / "gains.json"))
    assert "isolated in 100%" in out


def test_own_nonlinear_plant(tmp_path: Path) -> None:
    _run("own_nonlinear_plant.py", tmp_path, RUNS)
    page = (tmp_path / "reports" / "ship" / "index.html").read_text(encoding="utf-8")
    assert "built in Python" in page and "hull resistance" in page  # the parameter's label names its fault
    _png(tmp_path / "ship_trace.png")
    filed = problem_from_toml(tmp_path / "ship.toml").design("nafdf")
    (built,) = (tmp_path / ".fdisyn" / "ship").rglob("nafdf/gains.json")  # the report's build of the design
    assert _body(filed) == _body(read_gain_file(built))


@pytest.mark.skipif(not (Path("/usr/bin/gcc").exists() or os.environ.get("CC")), reason="needs a C compiler")
def test_deploy_to_c(tmp_path: Path) -> None:
    out = _run("deploy_to_c.py", tmp_path)
    assert "the firmware's residuals agree with the Python reference" in out
