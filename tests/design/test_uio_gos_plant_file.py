"""The generalised UIO bank from a plant file (Long & Wang, Aeroengine 43(5), 2017): E estimated from a training
trace against the E that generated it, the keys' defaults, and errors a user can act on."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
from fdisyn.runtime.gainfile import read_gain_file
from fdisyn.runtime.trace import Trace, write_trace

from tests.design.test_cli_hostile import _fails_with, _status_and_lines

# a continuous 4-state plant whose fifth sensor is the sum of the first two (rank C = 4 < 5 outputs)
A = np.array([[-1.0, 0.5, 0.0, 0.0], [0.0, -2.0, 1.0, 0.0], [0.5, 0.0, -3.0, 0.5], [0.0, 0.0, 0.5, -4.0]])
B = np.array([[1.0], [0.5], [0.0], [0.2]])
C = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 0.5], [0, 0.3, 0, 1.0], [1.0, 1.0, 0, 0]])
E_TRUE = np.array([0.0, 0.2, 1.0, 0.5])
TS = 0.05
NOISE = 0.01


def _rows(m: np.ndarray) -> str:
    return "[" + ", ".join("[" + ", ".join(repr(float(x)) for x in row) + "]" for row in np.atleast_2d(m)) + "]"


def _training(path: Path, seed: int = 1) -> None:
    """Fault-free data of the plant driven by a slowly varying unknown input along E_TRUE (exact ZOH)."""
    rng = np.random.default_rng(seed)
    n = 4000
    t = np.arange(n) * TS
    u = np.sign(np.sin(2 * np.pi * t / 15.0))[:, None]
    d = 2.0 * np.sin(2 * np.pi * t / 23.0) + np.cumsum(rng.standard_normal(n)) * 0.05
    big = np.zeros((6, 6))
    big[:4, :4], big[:4, 4], big[:4, 5] = A, B[:, 0], E_TRUE
    ed = scipy.linalg.expm(big * TS)
    x = np.zeros(4)
    X = np.empty((n, 4))
    for k in range(n):
        X[k] = x
        x = ed[:4, :4] @ x + ed[:4, 4] * u[k, 0] + ed[:4, 5] * d[k]
    y = X @ C.T + NOISE * rng.standard_normal((n, 5))
    write_trace(Trace(t=t, inputs=("u",), outputs=("y1", "y2", "y3", "y4", "y5"), U=u, Y=y,
                      extra={f"x{i + 1}": X[:, i] for i in range(4)}), path)


def _plant_file(tmp_path: Path, design: str, *, with_e: bool = False) -> str:
    text = f"""name = "gos_demo"
[signals]
states = ["x1", "x2", "x3", "x4"]
inputs = ["u"]
outputs = ["y1", "y2", "y3", "y4", "y5"]
[model]
time = "continuous"
Ts = {TS}
A = {_rows(A)}
B = {_rows(B)}
C = {_rows(C)}
R = {_rows(NOISE**2 * np.eye(5))}
{"E = " + _rows(np.array([[0.0], [0.0], [1.0], [0.0]])) + chr(10) + "Q = " + _rows(0.01 * np.eye(4)) if with_e else ""}
[design]
method = "kalman_uio_gos"
P_f = 1e-4
{design}
"""
    (tmp_path / "plant.toml").write_text(text, encoding="utf-8")
    return str(tmp_path / "plant.toml")


@pytest.fixture
def trained(tmp_path: Path) -> Path:
    (tmp_path / "data").mkdir()
    _training(tmp_path / "data" / "train.csv")
    return tmp_path


def test_a_plant_file_estimates_e_and_designs_the_bank(trained: Path, capsys: pytest.CaptureFixture[str]) -> None:
    spec = _plant_file(trained, 'training = "data/train.csv"\nrank_gap = 5.0')  # relative to the plant file
    status, lines = _status_and_lines(capsys, ["design", spec, "--out", str(trained / "out")])
    assert status == 0, lines
    gf = read_gain_file(next((trained / "out").rglob("gains.json")))
    chosen = gf.provenance["options"]["chosen"]
    assert chosen["E_rank"] == 1 and chosen["groups"]
    e = np.asarray(chosen["E"])[:, 0]
    # the direction that generated the data, up to sign: the estimate's error is the noise floor over a
    # 200 s run (measured |cos| = 0.9999); 0.995 fails for any other direction of the plant's dynamics
    assert abs(e @ E_TRUE) / (np.linalg.norm(e) * np.linalg.norm(E_TRUE)) > 0.995
    # one UIO per sensor in each group, WSSR over the default window
    assert len(gf.generators) == sum(len(g) for g in chosen["groups"])
    assert {ev.kind for ev in gf.evaluators} == {"wssr"} and {ev.window for ev in gf.evaluators} == {25}
    cert = json.dumps(gf.certificate, ensure_ascii=False)
    assert "internal form: largest normalised Markov parameter d → r" in cert


def test_a_sensor_in_no_group_is_named(trained: Path, capsys: pytest.CaptureFixture[str]) -> None:
    spec = _plant_file(trained, 'training = "data/train.csv"\ngroups = [["y1", "y2", "y3", "y4"]]')
    _fails_with(capsys, ["design", spec, "--out", str(trained / "o")], "[design].groups: sensor(s) ['y5'] are in no group")


def test_an_estimate_without_a_rank_gap_is_refused(trained: Path, capsys: pytest.CaptureFixture[str]) -> None:
    spec = _plant_file(trained, 'training = "data/train.csv"\nrank_gap = 1e9')
    _fails_with(capsys, ["design", spec, "--out", str(trained / "o")], "[design].training: group 1", "no clear rank gap", "singular values")


def test_a_failed_existence_condition_names_the_group_and_the_sensor(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # a discrete model whose E reaches y3 alone: the UIO that does not read y3 has C E = 0, rank(Cⁱ E) < rank(E)
    # (sampling a continuous model would spread E over the states A couples it to)
    spec = _plant_file(tmp_path, 'groups = [["y1", "y2", "y3", "y4"], ["y2", "y3", "y4", "y5"]]', with_e=True)
    text = Path(spec).read_text(encoding="utf-8").replace('time = "continuous"', 'time = "discrete"')
    Path(spec).write_text(text.replace(f"A = {_rows(A)}", f"A = {_rows(scipy.linalg.expm(A * TS))}"), encoding="utf-8")
    line = _fails_with(capsys, ["design", spec, "--out", str(tmp_path / "o")], "group 1 ['y1', 'y2', 'y3', 'y4'], the UIO without y3")
    assert "rank" in line


def test_a_missing_training_file_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    spec = _plant_file(tmp_path, 'training = "nowhere.csv"')
    _fails_with(capsys, ["design", spec, "--out", str(tmp_path / "o")], "[design].training", "nowhere.csv")


def test_training_needs_a_continuous_model(trained: Path, capsys: pytest.CaptureFixture[str]) -> None:
    spec = _plant_file(trained, 'training = "data/train.csv"')
    text = Path(spec).read_text(encoding="utf-8").replace('time = "continuous"', 'time = "discrete"')
    Path(spec).write_text(text, encoding="utf-8")
    _fails_with(capsys, ["design", spec, "--out", str(trained / "o")], "[design].training: estimating E needs the continuous model")
