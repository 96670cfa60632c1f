"""``fdisyn.runtime`` is all a deployment needs: in a fresh interpreter where CasADi, cvxpy,
python-control and SciPy cannot be imported, every runtime module imports and a Monitor runs the
compiled library, loading no ``fdisyn`` module outside ``fdisyn.runtime`` but the package root.
There (a runtime-only installation, without the extra ``design``) ``fdisyn replay``, ``fdisyn
example`` and ``fdisyn --version`` work, and every other command ends with status 2 and one line
naming the missing package and the extra that installs it."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from fdisyn.app import DESIGN_PACKAGES
from fdisyn.app.examples import EXAMPLES

BLOCKED = DESIGN_PACKAGES

PRELUDE = f"""
import json, pkgutil, sys
for name in {BLOCKED!r}:
    sys.modules[name] = None  # `import name` now raises ImportError
"""


@pytest.fixture(scope="module")
def motor_dir(motor_built) -> Path:
    """A deployed diagnoser: the session's compiled DC-motor folder (what ``fdisyn.export`` writes)."""
    return motor_built.directory


def _run(code: str) -> dict:
    out = subprocess.run([sys.executable, "-c", PRELUDE + code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.splitlines()[-1])


def test_the_runtime_and_the_monitor_need_none_of_the_design_side(motor_dir) -> None:
    got = _run(f"""
import fdisyn.runtime
for m in pkgutil.iter_modules(fdisyn.runtime.__path__):
    __import__("fdisyn.runtime." + m.name)
from fdisyn.runtime.monitor import Monitor
mon = Monitor.from_directory({str(motor_dir)!r})
v = mon.update([0.4], [0.4, 0.0, 0.0])
print(json.dumps({{"backend": mon.backend, "alarm": v.alarm, "fault": v.fault,
                  "fdisyn": sorted(m for m in sys.modules if m.split(".")[0] == "fdisyn")}}))
""")
    assert got["backend"] == "compiled" and got["alarm"] is False and got["fault"] is None
    outside = [m for m in got["fdisyn"] if m != "fdisyn" and not m.startswith("fdisyn.runtime")]
    assert outside == [] and "fdisyn.runtime.monitor" in got["fdisyn"]


def test_fdisyn_load_needs_none_of_the_design_side_either(motor_dir) -> None:
    got = _run(f"""
import fdisyn
mon = fdisyn.load({str(motor_dir)!r})
print(json.dumps({{"backend": mon.backend, "fdisyn": sorted(m for m in sys.modules if m.split(".")[0] == "fdisyn")}}))
""")
    outside = [m for m in got["fdisyn"] if m != "fdisyn" and not m.startswith("fdisyn.runtime")]
    assert got["backend"] == "compiled" and outside == ["fdisyn.app", "fdisyn.app.api"]


def test_generator_to_control_imports_python_control_when_called(motor_dir) -> None:
    got = _run(f"""
from fdisyn.runtime.gainfile import read_gain_file
gf = read_gain_file({str(motor_dir)!r} + "/gains.json")
try:
    gf.generators[0].to_control()
    result = "built"
except ImportError:
    result = "ImportError"
print(json.dumps({{"result": result}}))
""")
    assert got["result"] == "ImportError"  # control is blocked here: nothing imported it before the call


def test_without_the_design_extra_each_command_works_or_names_what_is_missing(motor_dir, tmp_path) -> None:
    trace = tmp_path / "in.csv"
    trace.write_text("t,voltage,i_meas,w_meas,theta_meas\n0,0.4,0.4,0,0\n0.001,0.4,0.4,0,0\n", encoding="utf-8")
    work = ["--workdir", str(tmp_path / "w")]
    needs_design = {
        "design": ["design", "wind_turbine", "--out", str(tmp_path / "d")],
        "design a plant file": ["design", str(EXAMPLES / "dc_motor.toml"), "--out", str(tmp_path / "d")],
        "codegen": ["codegen", str(tmp_path / "d")],
        "simulate": ["simulate", "wind_turbine", "--scenario", "fault_free", "--out", str(tmp_path / "t.csv")],
        "evaluate": ["evaluate", "wind_turbine", "--runs", "1", "--out", str(tmp_path / "m.json"), *work],
        "report": ["report", "wind_turbine", "--reports", str(tmp_path / "r"), *work],
        "reproduce": ["reproduce", "--reports", str(tmp_path / "r"), *work],
        "bench": ["bench", "wind_turbine", "--out", str(tmp_path / "b.md"), *work],
        "list": ["list"],
        "methods": ["methods"],
    }
    runtime_only = {
        "replay": ["replay", str(motor_dir), str(trace), str(tmp_path / "out.csv")],
        "example": ["example", "dc_motor", "--out", str(tmp_path / "motor.toml")],
        "version": ["--version"],
    }
    got = _run(f"""
import contextlib, io
from fdisyn.app.cli import main
result = {{}}
for what, argv in {{**{needs_design!r}, **{runtime_only!r}}}.items():
    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        status = main(argv)
    result[what] = [status, err.getvalue()]
print(json.dumps(result))
""")
    for what in needs_design:
        status, err = got[what]
        assert status == 2 and err.count("\n") == 1, (what, err)
        package = err.split("this command needs ", 1)[1].split(",", 1)[0]
        assert package in DESIGN_PACKAGES and err.startswith(f"fdisyn {needs_design[what][0]}: error: "), (what, err)
        assert err.rstrip().endswith("python3 -m pip install 'fdisyn[design]'"), (what, err)
    for what in runtime_only:
        assert got[what][0] == 0, (what, got[what])
    assert (tmp_path / "out.csv").read_text().startswith("t,alarm,isolated,")
    assert (tmp_path / "motor.toml").read_bytes() == (EXAMPLES / "dc_motor.toml").read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.csv", "motor.toml", "out.csv"]  # nothing half-made
