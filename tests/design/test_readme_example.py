"""The README's Python example (section "Python") runs as written: a DC motor from a python-control
model to a running monitor, through the public API (``fdisyn.design``, ``export``, ``load``,
``methods``, ``LinearPlant.from_control``, ``Generator.to_control``)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).parents[2]


def readme_example() -> str:
    """The first ``python`` block of the README's "Python" section, verbatim."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text.split("\n## Python\n", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```python\n(.*?)```", section, flags=re.S)[0]


def test_the_example_shows_the_whole_api() -> None:
    code = readme_example()
    for name in ("LinearPlant.from_control(", "fdisyn.design(", "fdisyn.export(", "fdisyn.load(", ".to_control()", "fdisyn.methods()", "fdisyn.__version__"):
        assert name in code, name
    for letter in ("A", "B", "E", "C", "Ts", "Q", "R"):  # the example defines its plant itself
        assert re.search(rf"^{letter} = ", code, flags=re.M), letter


def test_the_readme_example_runs(tmp_path, monkeypatch) -> None:
    pytest.importorskip("fdisyn.synthesis.registry", reason="fdisyn.design needs the method registry")
    import control
    import fdisyn

    monkeypatch.chdir(tmp_path)
    env: dict = {}
    exec(compile(readme_example(), "README.md", "exec"), env)  # noqa: S102 - the README's own code
    gf, mon, plant = env["gf"], env["mon"], env["plant"]
    assert isinstance(gf, fdisyn.GainFile) and gf.certificate["passed"] is True
    assert isinstance(mon, fdisyn.Monitor) and mon.backend == "compiled"
    assert plant.inputs == ("v",) and plant.unknown_inputs == ("load",) and plant.outputs == ("i", "w", "th") and plant.Ts == 0.001
    assert (tmp_path / "motor" / "gains.json").is_file() and (tmp_path / "motor" / "replay").is_file()
    v = mon.update(np.array([0.4]), np.array([0.4, 0.0, 0.0]))  # the motor at rest holding the load: no alarm
    assert v.alarm is False and v.fault is None
    g = gf.generators[0].to_control()
    assert isinstance(g, control.StateSpace) and g.dt == gf.Ts and g.ninputs == 4 and g.noutputs == gf.generators[0].n_residual
    assert "kalman_uio" in env["fdisyn"].methods()
