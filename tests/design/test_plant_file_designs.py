"""Plant files with several designs, options from the command line, the process noise named by what it is,
labels and units, and plants written as TOML (``to_toml``) read back as the same plant and the same designs."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import fdisyn
from fdisyn.app.cli import main
from fdisyn.models.linear import LinearPlant
from fdisyn.models.nonlinear import NonlinearPlant
from fdisyn.runtime.errors import ArgumentError, SpecError
from fdisyn.runtime.gainfile import GainFile, read_gain_file, without_clock
from fdisyn.simulation.plant_file import problem_from_document, problem_from_toml
from tests.helpers import random_plant

MOTOR = Path(fdisyn.__file__).parent / "examples" / "dc_motor.toml"


def _doc(**over: Any) -> dict[str, Any]:
    doc = tomllib.loads(MOTOR.read_text(encoding="utf-8"))
    doc.update(over)
    return {k: v for k, v in doc.items() if v is not None}


def _body(gf: GainFile) -> dict[str, Any]:
    """A gain file but for its provenance (where and when it was made): the diagnoser itself."""
    d = without_clock(gf).to_dict()
    d.pop("provenance")
    return d


TWO = [{"name": "kalman", "method": "kalman_uio"},
       {"name": "poles", "method": "uio_pole_placement", "poles": [0.9, 0.92, 0.94],
        "bank": [["i_meas", "theta_meas"], ["w_meas", "theta_meas"]]}]  # fmt: skip


def _motor_discrete() -> tuple[dict[str, Any], LinearPlant]:
    """The example motor as a discrete plant file (its exact sampling): the pole-placement UIO designs for it."""
    plant = problem_from_toml(MOTOR).model()
    doc = _doc()
    doc["model"] = tomllib.loads(plant.to_toml("dc_motor"))["model"]
    return doc, plant


def test_several_designs_are_the_designs_of_their_own_files(tmp_path: Path) -> None:
    doc, _ = _motor_discrete()
    both = problem_from_document(_doc(design=None, designs=TWO, model=doc["model"]), tmp_path / "two.toml")
    assert list(both.designs) == ["kalman", "poles"] and both.default_design == "kalman"
    for table in TWO:
        alone = {k: v for k, v in table.items() if k != "name"}
        one = problem_from_document(_doc(design=alone, model=doc["model"]), tmp_path / "one.toml")
        a, b = both.design(table["name"]), one.design()
        assert a.name == f"dc_motor_{table['name']}"
        da, db = _body(a), _body(b)
        for d in (da, db):  # the design's name is the one difference: [design] names it after its method
            d.pop("name")
            d["certificate"] = {k: v for k, v in d["certificate"].items() if k != "bank"}
        assert da == db and da["generators"]


@pytest.mark.parametrize(
    ("over", "match"),
    [
        ({"designs": TWO}, r"give \[design\] \(one design\) or \[\[designs\]\]"),
        ({"design": None, "designs": []}, r"\[\[designs\]\] is empty"),
        ({"design": None, "designs": [{"method": "kalman_uio"}]}, r"\[\[designs\]\]\[0\]: missing key 'name'"),
        ({"design": None, "designs": [TWO[0], TWO[0]]}, r"\[\[designs\]\]\[1\]\.name 'kalman' is already the name of \[\[designs\]\]\[0\]"),
        ({"design": None, "designs": [{"name": "a b", "method": "kalman_uio"}]}, r"\[\[designs\]\]\[0\]"),
        ({"design": None, "designs": [TWO[0], {"name": "sd", "method": "sampled_data_observer"}]},
         r"the sampled-data methods read \[model\]\.E as continuous white noise"),
        ({"design": None, "designs": [{"name": "k", "method": "kalman_uio", "nope": 1}]}, r"\[\[designs\]\]\[0\]: unknown key"),
    ],
)
def test_designs_refused_naming_the_table(tmp_path: Path, over: dict[str, Any], match: str) -> None:
    with pytest.raises(SpecError, match=match):
        problem_from_document(_doc(**over), tmp_path / "bad.toml")


def test_option_overrides_a_design_key_like_the_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    spec = tmp_path / "motor.toml"
    spec.write_text(MOTOR.read_text(encoding="utf-8"), encoding="utf-8")
    assert main(["design", str(spec), "--out", str(tmp_path / "a"), "--option", "P_f=1e-4"]) == 0
    written = MOTOR.read_text(encoding="utf-8").replace("arl0 = 3600.0", "P_f = 1e-4")
    assert "P_f = 1e-4" in written
    (tmp_path / "pf.toml").write_text(written.replace('name = "dc_motor"', 'name = "dc_motor"', 1), encoding="utf-8")
    assert main(["design", str(tmp_path / "pf.toml"), "--out", str(tmp_path / "b"), "--option", "persistence=1"]) == 0
    a, b = read_gain_file(tmp_path / "a" / "gains.json"), read_gain_file(tmp_path / "b" / "gains.json")
    assert _body(a) == _body(b)
    assert [e.P_f for e in a.evaluators] == [e.P_f for e in b.evaluators]
    capsys.readouterr()
    assert main(["design", str(spec), "--out", str(tmp_path / "c"), "--option", "P_f=2"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "P_f = 2" in err and "(0, 1)" in err
    assert main(["design", str(spec), "--out", str(tmp_path / "c"), "--option", "poles=[0.5]"]) == 2  # no design reads it
    assert "no option(s) ['poles']" in capsys.readouterr().err


def test_an_option_reaches_only_the_designs_that_read_it(tmp_path: Path) -> None:
    doc, _ = _motor_discrete()
    prob = problem_from_document(_doc(design=None, designs=TWO, model=doc["model"]), tmp_path / "two.toml")
    moved = prob.design("poles", poles=[0.8, 0.85, 0.9])
    assert sorted(np.round(np.abs(np.linalg.eigvals(moved.generators[0].Ar)), 9).tolist()) == [0.8, 0.85, 0.9]
    assert _body(prob.design("kalman", poles=[0.8, 0.85, 0.9])) == _body(prob.design("kalman"))


def test_process_noise_named_by_what_it_is(tmp_path: Path) -> None:
    base = problem_from_toml(MOTOR).model()
    model = dict(_doc()["model"])
    legacy = {**{k: v for k, v in model.items() if k != "Q_intensity"}, "Q": model["Q_intensity"]}
    assert np.array_equal(problem_from_document(_doc(model=legacy), tmp_path / "q.toml").model().Q, base.Q)
    with pytest.raises(SpecError, match=r"\[model\] gives Q and Q_intensity: they are the same process noise, give one"):
        problem_from_document(_doc(model={**model, "Q": model["Q_intensity"]}), tmp_path / "q.toml")
    with pytest.raises(SpecError, match=r"\[model\]\.Q_sample does not fit time = 'continuous'.*write it as Q_intensity"):
        problem_from_document(_doc(model={**{k: v for k, v in legacy.items() if k != "Q"}, "Q_sample": legacy["Q"]}), tmp_path / "q.toml")
    disc, plant = _motor_discrete()
    assert "Q_sample" in disc["model"] and "Q_intensity" not in disc["model"]
    bad = {**{k: v for k, v in disc["model"].items() if k != "Q_sample"}, "Q_intensity": disc["model"]["Q_sample"]}
    with pytest.raises(SpecError, match=r"Q_intensity does not fit time = 'discrete'.*write it as Q_sample"):
        problem_from_document(_doc(model=bad), tmp_path / "q.toml")


def test_labels_and_units_reach_the_problem(tmp_path: Path) -> None:
    prob = problem_from_toml(MOTOR)
    assert prob.labels["w_meas"] == "speed (rad/s)" and prob.labels["load"] == "load (N·m)"
    sig = dict(_doc()["signals"])
    with pytest.raises(SpecError, match=r"\[signals\]\.units\.w_meas must be text in quotes, e\.g\. w_meas = \"rad/s\"; got 3"):
        problem_from_document(_doc(signals={**sig, "units": {"w_meas": 3}}), tmp_path / "u.toml")
    with pytest.raises(SpecError, match=r"\[signals\]\.labels must be a table of text by signal name"):
        problem_from_document(_doc(signals={**sig, "labels": ["speed"]}), tmp_path / "u.toml")
    with pytest.raises(SpecError, match="nope"):
        problem_from_document(_doc(signals={**sig, "units": {"nope": "m"}}), tmp_path / "u.toml")


# --------------------------------------------------------------------------- to_toml


def _same_plant(a: LinearPlant, b: LinearPlant, rtol: float = 0.0) -> None:
    for k in ("A", "B", "C", "D", "E", "Fx", "Dd", "Df", "Q", "R"):
        np.testing.assert_allclose(getattr(a, k), getattr(b, k), rtol=rtol, atol=0.0, err_msg=k)
    for k in ("states", "inputs", "unknown_inputs", "outputs", "component_faults", "units", "labels", "Ts"):
        assert getattr(a, k) == getattr(b, k), k


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 2**31 - 1), continuous=st.booleans(), scaled=st.booleans(), direct=st.booleans())
def test_to_toml_reads_back_as_the_same_plant(tmp_path: Path, seed: int, continuous: bool, scaled: bool, direct: bool) -> None:
    """Every float written by repr reads back as the same double: the file is the plant, bit for bit (a scaled
    plant is written in its original states, to round-off)."""
    rng = np.random.default_rng(seed)
    base = random_plant(seed)
    n, p, q = base.n, base.p, base.q
    scale = 10.0 ** rng.uniform(-3, 3)
    plant = LinearPlant.create(
        A=base.A * scale, B=base.B * scale, C=base.C, E=base.E, Fx=rng.standard_normal((n, 1)),
        Dd=rng.standard_normal((p, q)) if direct else None, Df=rng.standard_normal((p, 1)) if direct else None,
        Q=base.Q, R=base.R, Ts=None if continuous else 10.0 ** rng.uniform(-4, 1),
        outputs=[f"s{i}" for i in range(p)], component_faults=["leak"],
        units={"s0": "m/s²", "leak": "kg/s"}, labels={"s0": "acceleration «x»"},
    )  # fmt: skip
    # a continuous plant sampled at most one time constant of its fastest mode per sample (expm's conditioning
    # then keeps the round-off of a scaled plant's unscaling at round-off)
    ts = 10.0 ** rng.uniform(-4, 0) / max(1.0, float(np.max(np.abs(np.linalg.eigvals(plant.A))))) if continuous else None
    written = plant.scaled(10.0 ** rng.uniform(-3, 3, n)) if scaled else plant
    design = {"method": "nullspace"} if direct else None  # the observer methods refuse Dd, Df (and say so)
    sim = {"duration": 100.0 * (ts or plant.Ts)}  # a hundred samples, whatever the sample time
    back = problem_from_document(tomllib.loads(written.to_toml("rt", Ts=ts, design=design, simulation=sim)), tmp_path / "rt.toml").model()
    # the file's physical plant: the original states (a scaled plant is written unscaled, to round-off)
    _same_plant(back, plant.discretise(ts) if continuous else plant, rtol=1e-9 if scaled else 0.0)


def test_to_toml_refusals() -> None:
    cont = LinearPlant.create(A=[[-1.0]], C=[[1.0]])
    with pytest.raises(ArgumentError, match=r"needs the sample time it is diagnosed at: give Ts"):
        cont.to_toml("c")
    disc = LinearPlant.create(A=[[0.5]], C=[[1.0]], Ts=0.1)
    with pytest.raises(ArgumentError, match=r"differs from the discrete plant's own Ts"):
        disc.to_toml("c", Ts=0.2)
    with pytest.raises(ArgumentError, match=r"give design \(one design\) or designs"):
        disc.to_toml("c", design={"method": "kalman_uio"}, designs={"k": {"method": "kalman_uio"}})
    with pytest.raises(ArgumentError, match=r"finite numbers only"):
        disc.to_toml("c", simulation={"duration": float("nan")})
    for bad, match in ((dict(designs={"k": "kalman_uio"}), r"designs must map each design's name to a mapping"),
                       (dict(scenarios="bias"), r"scenarios must be a list of mappings"),
                       (dict(simulation=[1.0]), r"simulation must be a mapping of its keys")):
        with pytest.raises(ArgumentError, match=match):
            fdisyn.problem(disc, **bad)
    # text a plant file must escape (DEL) reads back as written
    odd = "a\x7fb \"q\" \\ é\n"
    prob = fdisyn.problem(disc, simulation={"duration": 1.0}, scenarios=[{"name": "x", "description": odd, "duration": 1.0}])
    assert prob.scenarios["x"].description == odd


def test_nonlinear_to_toml_round_trip(tmp_path: Path) -> None:
    ship = Path(fdisyn.__file__).parent / "examples" / "ship.toml"
    prob = problem_from_toml(ship)
    doc = tomllib.loads(ship.read_text(encoding="utf-8"))
    model = NonlinearPlant.from_expressions(
        states=doc["signals"]["states"], inputs=doc["signals"].get("inputs", []), outputs=doc["signals"]["outputs"],
        parameters=doc["signals"]["parameters"], nominal=doc["model"]["nominal"], f=doc["model"]["f"], h=doc["model"]["h"],
        Q=doc["model"]["Q_sample"], R=doc["model"]["R"], constants=doc["model"].get("constants"), Ts=doc["model"].get("Ts"),
    )  # fmt: skip
    text = model.to_toml("ship", design=doc["design"], simulation=doc["simulation"], scenarios=doc["scenarios"])
    again = problem_from_document(tomllib.loads(text), tmp_path / "ship.toml")
    assert _body(again.design()) == _body(prob.design())


def test_nonlinear_plant_from_casadi_functions_is_refused() -> None:
    import casadi as ca

    x, u, th = ca.SX.sym("x"), ca.SX.sym("u"), ca.SX.sym("th")
    plant = NonlinearPlant.create(
        f=ca.Function("f", [x, u, th], [th * x + u]), h=ca.Function("h", [x, th], [x]),
        states=["x"], inputs=["u"], outputs=["y"], parameters=["a"], nominal={"a": 0.5}, Q=[[0.01]], R=[[0.01]],
    )  # fmt: skip
    with pytest.raises(ArgumentError, match="built from CasADi functions, which a plant file cannot hold"):
        plant.to_toml("x")


def test_problem_from_python_objects_is_its_plant_file(tmp_path: Path) -> None:
    """``fdisyn.problem`` and the file ``to_toml`` writes give the same designs; ``fdisyn.design`` on the plant the
    same diagnoser, and ``fdisyn.simulate`` the same run as the file's problem."""
    _, plant = _motor_discrete()
    sim = {"duration": 2.0, "x0": [0.4, 0.0, 0.0], "inputs": [{"kind": "step", "offset": 0.4, "amplitude": 5.6, "start": 0.5}]}
    scen = [{"name": "w_offset", "duration": 2.0, "fault": "w_meas", "onset": 1.0,
             "sensor_faults": [{"sensor": "w_meas", "kind": "offset", "value": 1.0}]}]  # fmt: skip
    designs = {t["name"]: {k: v for k, v in t.items() if k != "name"} for t in TWO}
    prob = fdisyn.problem(plant, name="motor", designs=designs, simulation=sim, scenarios=scen)
    path = tmp_path / "motor.toml"
    path.write_text(plant.to_toml("motor", designs=designs, simulation=sim, scenarios=scen), encoding="utf-8")
    filed = problem_from_toml(path)
    for d in designs:
        assert _body(prob.design(d)) == _body(filed.design(d))
    direct = _body(fdisyn.design(plant, "kalman_uio", name="motor_kalman"))
    mine = _body(prob.design("kalman"))
    assert {k: v for k, v in direct.items() if k not in ("problem", "certificate")} == {
        k: v for k, v in mine.items() if k not in ("problem", "certificate")}
    a, b = fdisyn.simulate(prob, "w_offset", seed=3), filed.run("w_offset", [3]).trace(0)
    assert np.array_equal(a.Y, b.Y) and np.array_equal(a.U, b.U)
    assert fdisyn.simulate(plant, scen[0] | {"duration": 2.0}, seed=3).Y.shape == a.Y.shape
