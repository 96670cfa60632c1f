"""A nonlinear plant file (``time = "nonlinear"``) designs the NAFDF of Zhou, Xi & Zhang
(Shanghai Jiao Tong University, c. 1991).

The truth for the TOML route is the built-in ``ship_propulsion`` problem:
The example ``ship.toml`` writes the same plant, the same settings and the
same input, so the design must be the same step function and the simulator
the same data, to the bit.
"""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from fdisyn.app.cli import main
from fdisyn.app.examples import EXAMPLES
from fdisyn.simulation.plant_file import load_spec, problem_from_document
from fdisyn.simulation.signals import Signal
from fdisyn.problems import ship_propulsion as sp
from fdisyn.runtime.errors import FdisynError, SpecError
from fdisyn.runtime.gainfile import read_gain_file
from fdisyn.synthesis.nafdf.design import nafdf_extra_metrics

DATA = EXAMPLES
SHIP = DATA / "ship.toml"


@pytest.fixture(scope="module")
def problem():
    return load_spec(SHIP)


def test_the_file_designs_the_built_in_ship_nafdf(problem) -> None:
    gf, ref = problem.design(), sp.PROBLEM.design()
    assert gf.kind == "nafdf" and gf.name == "ship_nafdf" and gf.faults == ("a", "b")
    assert (gf.inputs, gf.outputs, gf.Ts) == (ref.inputs, ref.outputs, ref.Ts)
    ours, theirs = gf.extensions["nafdf"], ref.extensions["nafdf"]
    for key in ("plant", "settings", "detector_thresholds", "state_layout", "init_state", "r_names", "J_names", "thresholds"):
        assert ours[key] == theirs[key], key


def test_the_file_simulates_the_built_in_ship_data(problem) -> None:
    """Same square wave (offset 5 ± 4, period 50), same x0, same noise draws, same jump of a at 701."""
    ours = problem.run("a_half", [3, 4])
    theirs = sp.PROBLEM.run("paper_a_half", [3, 4])
    np.testing.assert_array_equal(ours.U, theirs.U)
    np.testing.assert_array_equal(ours.Y, theirs.Y)
    np.testing.assert_array_equal(ours.extra["true_a"], theirs.extra["a"])
    assert ours.scenario.fault == "a" and ours.scenario.params["fault_size"] == {"a": pytest.approx(0.29)}


def test_scenarios_by_scale_and_by_value(problem) -> None:
    both = problem.scenario("both")
    assert both.fault == "a+b"
    assert both.params["fault_size"] == {"a": pytest.approx(-0.29), "b": pytest.approx(0.1)}
    b = problem.run("both", [0])
    np.testing.assert_array_equal(b.extra["true_a"][0, :701], -0.58)
    np.testing.assert_array_equal(b.extra["true_a"][0, 701:], 1.5 * -0.58)  # θ → scale·θ0, computed the same way
    np.testing.assert_array_equal(b.extra["true_b"][0, 701:], 0.3)
    assert problem.scenario("fault_free").duration == 20000 and problem.scenario("fault_free").fault is None


def test_cli_design_codegen_and_replay(tmp_path) -> None:
    d = tmp_path / "ship"
    assert main(["design", str(SHIP), "--out", str(d)]) == 0
    assert read_gain_file(d / "gains.json").name == "ship_nafdf"
    assert main(["codegen", str(d)]) == 0
    trace = tmp_path / "t.csv"
    assert main(["simulate", str(SHIP), "--scenario", "a_half", "--seed", "1", "--out", str(trace)]) == 0
    assert main(["replay", str(d), str(trace), str(tmp_path / "o.csv")]) == 0
    out = np.genfromtxt(tmp_path / "o.csv", delimiter=",", names=True)
    # the paper's fault is detected within 20 samples (Monte Carlo: 95 % within ~11) and a is isolated
    assert 701 <= np.flatnonzero(out["alarm"][701:])[0] + 701 <= 721
    assert out["isolated"][-1] == 0


F_SHIP = 'f = { x = "0.1*a*x^2'  # the start of the ship's f, where a test puts its own expression


def _write(tmp_path: Path, old: str, new: str) -> Path:
    text = SHIP.read_text()
    assert old in text, old
    p = tmp_path / "bad.toml"
    p.write_text(text.replace(old, new, 1))
    return p


@pytest.mark.parametrize(
    "old, new, match",
    [
        ('method = "nafdf"', 'method = "kalman_uio"', "a nonlinear plant is designed by 'nafdf'"),
        ("nominal = { a = -0.58, b = 0.2 }", "nominal = { a = -0.58 }", "'b'"),
        ('f = { x = "0.1*a*x^2', 'f = { x = "abs(x) + 0.1*a*x^2', "abs"),
        ("theta0 = { a = 0.0, b = 0.0 }", "theta0 = { a = 0.0 }", r"missing \['b'\]"),
        ('{ parameter = "a", scale = 0.5 }', '{ parameter = "c", scale = 0.5 }', "no parameter 'c'"),
        ('{ parameter = "a", scale = 0.5 }', '{ parameter = "a", scale = 0.5, value = 1.0 }', "either scale"),
        ("onset = 701\nparameter_faults = [{ parameter = \"a\"", "parameter_faults = [{ parameter = \"a\"", "needs an onset"),
        ("W1 = 50.0", "W1 = 500.0", "W1 < W2"),
        ("window = 10", "windw = 10", "unknown key"),
        ("x0 = [0.0]", "x0 = [0.0, 1.0]", "x0 must have 1 entries"),
        ("x0 = [0.0]", 'x0 = ["zero"]', r"\[simulation\].x0 must be a list of 1 numbers"),
        ("R = [[0.01]]", "R = [[0.01, 0.0]]", r"\[model\].R has shape \(1, 2\); expected \(1, 1\)"),
        ("Q_sample = [[0.0]]", "Q_sample = [[-1.0]]", r"\[model\].Q_sample must be positive semidefinite"),
        ("R = [[0.01]]", "R = 0.0", r"\[model\].R must be positive definite"),
        ('states = ["x"]', "states = 3", r"\[signals\].states must be a list of names"),
        ("window = 10", 'window = "ten"', r"\[design\].window = 'ten': expected a whole number of samples in 1\.\.1000"),
        ("P0 = 100.0", 'P0 = "big"', "P0 must be a number or an array of numbers"),
        # numbers are data: NaN and inf are refused where they enter, naming the expression
        (F_SHIP, 'f = { x = "x/0 + 0.1*a*x^2', r"\[model\]: f\['x'\]: the constant subexpression 'x/0' .* evaluates to inf"),
        (F_SHIP, 'f = { x = "log(-1.0) + 0.1*a*x^2', r"'log\(-1.0\)' .* evaluates to nan"),
        (F_SHIP, 'f = { x = "1e999*x + 0.1*a*x^2', "the number '1e999' .* is not a finite double"),
        (F_SHIP, 'f = { x = "10**10**10*x + 0.1*a*x^2', r"'10\*\*10\*\*10' .* evaluates to inf"),
        (F_SHIP, 'f = { x = "x**x + 0.1*a*x^2', r"not finite at the nominal point .*: ∂f\['x'\]/∂x = nan \(the expression"),
        (F_SHIP, 'f = { x = "c*x + 0.1*a*x^2', "constant 'c' must be a finite number; got nan"),
        (F_SHIP, 'f = { x = "' + "x+" * 4000 + '0.1*a*x^2', "more than 1000 operators"),
        ("x0 = [0.0]", "x0 = [nan]", r"\[simulation\].x0 must hold finite numbers"),
        ('{ parameter = "b", value = 0.3 }', '{ parameter = "b", value = inf }', r"parameter_faults\[1\].value must be a finite number"),
        ("window = 10", "window = 100000", r"\[design\].window = 100000: expected a whole number of samples in 1\.\.1000"),
        ("window = 10", "window = 1e9", r"\[design\].window = 1000000000.0: expected a whole number"),
        ("window = 10", "window = inf", r"\[design\].window = inf: expected a whole number"),
        ("classifier_window = 50", "classifier_window = 5000", "classifier_window is 5000; at most 1000"),
        ("window = 10", "window = 10\nu0 = [1.0, 2.0]", r"\[design\].u0 must have 1 entries"),
    ],
)
def test_bad_nonlinear_files_name_the_problem(tmp_path, old, new, match) -> None:
    path = _write(tmp_path, old, new)
    if "c*x" in new:  # the constant comes from [model].constants
        path.write_text(path.read_text().replace("nominal = {", "constants = { c = nan }\nnominal = {", 1))
    with pytest.raises(SpecError, match=match) as info:
        load_spec(path).design()
    assert "\n" not in str(info.value)


def test_the_papers_noise_letters_are_read_as_q_and_r(problem, tmp_path) -> None:
    """Zhou, Xi & Zhang's ``Q1``, ``Q2`` (eq. (2.1)) may stand for ``Q``, ``R``; errors name the key the file wrote."""
    lettered = _write(tmp_path, "Q_sample = [[0.0]]", "Q1 = [[0.0]]")
    lettered.write_text(lettered.read_text().replace("R = [[0.01]]", "Q2 = [[0.01]]", 1))
    assert load_spec(lettered).design().extensions["nafdf"]["plant"] == problem.design().extensions["nafdf"]["plant"]
    lettered.write_text(lettered.read_text().replace("Q2 = [[0.01]]", "Q2 = 0.0", 1))
    with pytest.raises(SpecError, match=r"\[model\].Q2 must be positive definite"):
        load_spec(lettered).design()
    with pytest.raises(SpecError, match=r"\[model\] gives both 'Q1' and 'Q': they are the same matrix"):
        load_spec(_write(tmp_path, "Q_sample = [[0.0]]", "Q = [[0.0]]\nQ1 = [[0.0]]"))


@pytest.mark.parametrize(
    "old, new",
    [(F_SHIP, 'f = { x = "x**x + 0.1*a*x^2'), (F_SHIP, 'f = { x = "' + "x+" * 5000 + '0.1*a*x^2'), ("window = 10", "window = 100000")],
)
def test_cli_refuses_with_status_2_and_one_line(tmp_path, capsys, old, new) -> None:
    assert main(["design", str(_write(tmp_path, old, new)), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("fdisyn design: error: ") and "\n" not in err and "Traceback" not in err
    assert not (tmp_path / "out" / "gains.json").exists()


def test_a_file_with_the_deprecated_convergence_tolerance_still_designs(problem, tmp_path, capsys) -> None:
    """``convergence_tolerance`` (a plant file written before the information law) designs the step that
    ``isolable_jump = √W1 · tol`` designs; the CLI succeeds and says so in one warning line."""
    old = _write(tmp_path, "isolable_jump = { a = 0.29, b = 0.1 }", "convergence_tolerance = [0.03, 0.01]")
    with pytest.warns(FutureWarning, match="convergence_tolerance is deprecated"):
        gf = load_spec(old).design()
    assert gf.extensions["nafdf"]["settings"]["isolable_jump"] == pytest.approx([0.03 * 50**0.5, 0.01 * 50**0.5], rel=1e-15)
    assert main(["design", str(old), "--out", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err.strip()
    assert err.startswith("fdisyn design: warning: FutureWarning: the NAFDF option convergence_tolerance is deprecated") and "\n" not in err


def test_square_signal_on_the_sample_grid() -> None:
    s = Signal(kind="square", offset=5.0, amplitude=4.0, period=50.0)
    u = s.sample(np.arange(200.0), np.random.default_rng(0), 1.0)
    np.testing.assert_array_equal(u, np.where(np.arange(200) % 50 < 25, 9.0, 1.0))
    # a period that is a whole number of samples splits exactly even when Ts is not a binary fraction
    t = np.arange(1000) * 0.01
    v = Signal(kind="square", amplitude=1.0, period=0.2).sample(t, np.random.default_rng(0), 0.01)
    np.testing.assert_array_equal(v, np.where(np.arange(1000) % 20 < 10, 1.0, -1.0))


def test_nafdf_extra_metrics_by_hand() -> None:
    """Three runs with known latched classes, sizes and isolation times (and a fourth, not isolable)."""
    names = ("fault_class_a", "fault_class_b", "fault_size_a", "fault_size_b", "insufficient_excitation")
    gf = SimpleNamespace(faults=("a", "b"), Ts=1.0, step=SimpleNamespace(statistic_names=names))
    N = 10
    J = np.zeros((4, N, 5))
    J[:, -1] = [[1, 0, 0.30, 0.0, 0], [2, 0, 0.26, 0.0, 0], [1, 1, 0.5, 0.1, 0], [0, 0, 0.0, 0.0, 1]]
    iso = -np.ones((4, N), dtype=int)
    iso[0, 7:], iso[1, 9:], iso[2, 6:] = 0, 0, 0
    runs = {"J": J, "isolated": iso, "alarm": np.zeros((4, N), dtype=int)}
    sc = SimpleNamespace(fault="a", onset=5.0, params={"fault_size": {"a": 0.29}})
    m = nafdf_extra_metrics(sc, gf, runs)
    assert m["all parameter classes correct"] == pytest.approx(2 / 4)
    assert m["isolation delay median (samples)"] == 2.0  # delays 2, 4, 1
    assert m["runs detected, not isolable (insufficient excitation)"] == 0.25
    err = np.array([0.30, 0.26, 0.5]) - 0.29
    assert m["size error a: mean"] == pytest.approx(err.mean()) and m["size error a: sd"] == pytest.approx(err.std(ddof=1))
    alarm = np.zeros((2, N), dtype=int)
    alarm[0, 2:4] = alarm[0, 6] = alarm[1, 9] = 1
    free = nafdf_extra_metrics(
        SimpleNamespace(fault=None, onset=None, params={}), gf, {"J": J[:2], "isolated": -np.ones((2, N), dtype=int), "alarm": alarm}
    )
    assert free == {"runs with an isolation": 0.0, "alarm episodes per 10k samples": pytest.approx(1e4 * 3 / 20)}


def _key_paths(node: object, prefix: tuple = ()) -> list[tuple]:
    out = []
    if isinstance(node, dict):
        for k, v in node.items():
            out += [(*prefix, k), *_key_paths(v, (*prefix, k))]
    elif isinstance(node, list) and node and all(isinstance(x, dict) for x in node):
        for i, v in enumerate(node):
            out += [(*prefix, i), *_key_paths(v, (*prefix, i))]
    return out


@pytest.mark.parametrize("name", ["ship.toml", "dc_motor.toml", "sampled_data.toml"])
def test_every_key_with_a_wrong_value_gives_a_named_error(name) -> None:
    """Each key (and table) of the example files replaced in turn by a value of the wrong type or
    sign: parsing, designing and simulating either succeed or raise an fdisyn error — never a
    bare TypeError/ValueError from deep inside (the CLI turns fdisyn errors into one line)."""
    doc = tomllib.loads((DATA / name).read_text())
    for path in _key_paths(doc):
        for bad in ("x", -1.0, {"q": 1}, [["a"]]):
            d = copy.deepcopy(doc)
            node = d
            for k in path[:-1]:
                node = node[k]
            node[path[-1]] = bad
            try:
                prob = problem_from_document(d, DATA / name)
                prob.design()
                for sc in list(prob.scenarios)[:2]:
                    prob.run(sc, [0])
            except FdisynError:
                pass
