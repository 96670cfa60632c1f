"""``fdisyn.runtime`` is all a deployment needs: in a fresh interpreter where CasADi, cvxpy,
python-control and SciPy cannot be imported, every runtime module imports and a Monitor runs the
compiled library, loading no ``fdisyn`` module outside ``fdisyn.runtime`` but the package root."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

BLOCKED = ("casadi", "cvxpy", "clarabel", "control", "scipy", "matplotlib")

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
