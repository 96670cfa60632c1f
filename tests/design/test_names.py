"""Names where they enter the design side: plant files, LinearPlant, NonlinearPlant, simulated traces.

Each refusal names the key (or both places of a collision) and what was
expected; a name that passes here passes the gain-file reader and the C
generator too.
"""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path

import numpy as np
import pytest
from fdisyn.app.cli import main
from fdisyn.app.examples import EXAMPLES
from fdisyn.simulation.plant_file import problem_from_document
from fdisyn.models.linear import LinearPlant
from fdisyn.models.nonlinear import NonlinearPlant
from fdisyn.runtime.errors import ArgumentError, SpecError, TraceError
from fdisyn.runtime.trace import Trace

DATA = EXAMPLES
MOTOR = tomllib.loads((DATA / "dc_motor.toml").read_text())
SHIP = tomllib.loads((DATA / "ship.toml").read_text())
HOSTILE = 'x", 0}; __attribute__((constructor)) static void pwn(void){} static const char *y[] = {"'


def _motor(edit) -> object:  # noqa: ANN001 - a function editing the document
    doc = copy.deepcopy(MOTOR)
    edit(doc)
    return problem_from_document(doc, Path("motor.toml"))


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        # signal names: grammar, reserved names, collisions (duplicate columns of `fdisyn simulate`)
        (lambda d: d["signals"].__setitem__("outputs", ["t", "w_meas", "theta_meas"]), r"motor.toml \[signals\].outputs\[0\] 't' is reserved \(the time column"),
        (lambda d: d["signals"].__setitem__("inputs", ["fault_active"]), r"\[signals\].inputs\[0\] 'fault_active' is reserved"),
        (lambda d: d["signals"].__setitem__("outputs", ["i_meas", "speed", "theta_meas"]), r"motor.toml: the name 'speed' is used by the \[signals\].states and by the \[signals\].outputs"),
        (lambda d: d["signals"].__setitem__("outputs", ["i_meas", "voltage", "theta_meas"]), r"the name 'voltage' is used by the \[signals\].inputs and by the \[signals\].outputs"),
        (lambda d: d["signals"].__setitem__("unknown_inputs", ["voltage"]), r"the name 'voltage' is used by the \[signals\].inputs and by the \[signals\].unknown_inputs"),
        (lambda d: d["signals"].__setitem__("outputs", ["i meas", "w_meas", "theta_meas"]), r"\[signals\].outputs\[0\] 'i meas' is not a signal name"),
        (lambda d: d["signals"].__setitem__("outputs", [HOSTILE, "w_meas", "theta_meas"]), r"\[signals\].outputs\[0\] .* is not a signal name"),
        (lambda d: d["signals"].__setitem__("states", ["x", "x", "z"]), r"\[signals\].states must be unique; repeated: \['x'\]"),
        (lambda d: d["signals"].__setitem__("outputs", ["x0", "w_meas", "theta_meas"]) or d["signals"].pop("states"), r"the name 'x0' is used by the states and by the outputs"),
        # the diagnoser name prefixes the C API (and with its method forms the gain file's name)
        (lambda d: d.__setitem__("name", "dc__motor"), r"motor.toml: name 'dc__motor' cannot prefix the generated C API"),
        (lambda d: d.__setitem__("name", "_dc"), r"name '_dc' cannot prefix"),
        (lambda d: d.__setitem__("name", "dc_"), r"name 'dc_' cannot prefix"),
        (lambda d: d.__setitem__("name", "m" * 300), r"name 'mmmm.* \(302 characters\) cannot prefix the generated C API: .* at most 64 characters"),
        (lambda d: d.__setitem__("name", "m" * 60), r"name 'm{60}' is too long: the diagnoser's name m{60}_kalman_uio \(name and design method\) has 71 characters, at most 64"),
        (lambda d: d.__setitem__("name", 7), r"name must be a string, found int"),
        # fault classes and bank groups: names checked, references must be output names
        (lambda d: d["design"].__setitem__("faults", [{"name": HOSTILE, "sensors": ["w_meas"]}]), r"\[design\].faults\[0\].name .* is not a fault name"),
        (lambda d: d["design"].__setitem__("faults", [{"name": "w", "sensors": ["w_meas"]}, {"name": "w", "sensors": ["i_meas"]}]), r"\[design\].faults\[1\].name 'w' names another fault class too"),
        (lambda d: d["design"].__setitem__("faults", [{"name": "w", "sensors": [1]}]), r"\[design\].faults\[0\].sensors\[0\]: no output 1; outputs are"),
        (lambda d: d["design"].__setitem__("faults", [{"name": "w", "sensors": ["w_meas", "w_meas"]}]), r"\[design\].faults\[0\].sensors names output 'w_meas' twice"),
        (lambda d: d["design"].__setitem__("faults", [{"name": "w", "components": ["nope"]}]), r"\[design\].faults\[0\].components\[0\]: no component fault 'nope'"),
        (lambda d: d["design"].__setitem__("bank", [["i_meas", "speed"]]), r"\[design\].bank\[0\]\[1\]: no output 'speed'; outputs are \['i_meas', 'w_meas', 'theta_meas'\]"),
        (lambda d: d["design"].__setitem__("bank", [["i_meas", "i_meas"]]), r"\[design\].bank\[0\] names output 'i_meas' twice"),
        (lambda d: d["design"].__setitem__("bank", [[]]), r"\[design\].bank\[0\] must be a non-empty list of output names"),
        # scenario names become report file names; a second scenario of the same name would replace the first
        (lambda d: d["scenarios"][0].__setitem__("name", "../../etc/x"), r"\[\[scenarios\]\]\[0\].name '../../etc/x' is not a label"),
        (lambda d: d["scenarios"][0].__setitem__("name", "fault_free"), r"name 'fault_free' is the built-in fault-free scenario"),
        (lambda d: d["scenarios"].append(dict(d["scenarios"][0])), r"\[\[scenarios\]\]\[1\].name 'speed_sensor_offset' is already the name of \[\[scenarios\]\]\[0\]"),
    ],
)
def test_plant_file_names_are_refused_where_they_enter(edit, message):
    with pytest.raises(SpecError, match=message) as err:
        _motor(edit)
    assert "\n" not in str(err.value)


def test_a_hostile_fault_name_stops_fdisyn_design_with_one_line(tmp_path, capsys):
    text = (DATA / "dc_motor.toml").read_text().replace(
        'bank = [["i_meas", "theta_meas"], ["w_meas", "theta_meas"]]',
        'bank = [["i_meas", "theta_meas"], ["w_meas", "theta_meas"]]\nfaults = [{ name = "x\\", 0}; int pwn;", sensors = ["w_meas"] }]',
    )
    (tmp_path / "bad.toml").write_text(text)
    assert main(["design", str(tmp_path / "bad.toml"), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "[design].faults[0].name" in err and "is not a fault name" in err
    assert not (tmp_path / "out").exists()


def test_valid_fault_classes_reach_the_gain_file(tmp_path):
    doc = copy.deepcopy(MOTOR)
    doc["design"]["faults"] = [{"name": "w_meas", "sensors": ["w_meas"]}, {"name": "i_meas|theta_meas", "sensors": ["i_meas", "theta_meas"]}]
    doc["scenarios"][0]["fault"] = "w_meas"
    gf = problem_from_document(doc, tmp_path / "m.toml").design()
    assert gf.faults == ("w_meas", "i_meas|theta_meas")


def test_linear_plant_names_share_one_namespace():
    base = {"A": np.eye(2) * 0.5, "B": np.ones((2, 1)), "C": np.eye(2), "E": np.ones((2, 1)), "Ts": 0.1}
    for names, message in (
        ({"states": ["a", "b"], "outputs": ["b", "c"]}, "the name 'b' is used by the states and by the outputs"),
        ({"inputs": ["y0"]}, "the name 'y0' is used by the inputs and by the outputs"),  # default output names
        ({"unknown_inputs": ["x1"]}, "the name 'x1' is used by the states and by the unknown inputs"),
        ({"outputs": ["t", "y1"]}, r"output names\[0\] 't' is reserved"),
    ):
        with pytest.raises(ArgumentError, match=message):
            LinearPlant.create(**base, **names)  # type: ignore[arg-type]
    with pytest.raises(ArgumentError, match="the name 'f0' is used by the outputs and by the component faults"):
        LinearPlant.create(**base, Fx=np.ones((2, 1)), outputs=["f0", "y1"])  # type: ignore[arg-type]


def _nonlinear(**names: list[str]) -> NonlinearPlant:
    kw = {"states": ["x"], "inputs": ["u"], "outputs": ["y"], "parameters": ["a"]} | names
    x, u, a = kw["states"][0], kw["inputs"][0], kw["parameters"][0]
    return NonlinearPlant.from_expressions(
        **kw, nominal={a: 0.5}, f={x: f"{a}*{x} + {u}"}, h={kw["outputs"][0]: x}, Q=0.0, R=0.01  # type: ignore[arg-type]
    )


def test_nonlinear_plant_names():
    assert _nonlinear(outputs=["x"]).outputs == ("x",)  # an output may be named after the state it measures
    with pytest.raises(ArgumentError, match="the name 'a' is used by the states and by the parameters; .*f refer to them by name"):
        _nonlinear(states=["a"], parameters=["a"])
    with pytest.raises(ArgumentError, match="the name 'x' is used by the states and by the inputs"):
        _nonlinear(inputs=["x"])
    with pytest.raises(ArgumentError, match="the name 'u' is used by the inputs and by the outputs"):
        _nonlinear(outputs=["u"])
    with pytest.raises(ArgumentError, match="the name 'true_x' is used by the outputs and by the simulated truth columns"):
        _nonlinear(outputs=["true_x"])


def test_nonlinear_plant_file_names():
    doc = copy.deepcopy(SHIP)
    doc["signals"]["parameters"] = ["a", "t"]
    with pytest.raises(SpecError, match=r"\[signals\].parameters\[1\] 't' is reserved"):
        problem_from_document(doc, Path("ship.toml"))
    doc = copy.deepcopy(SHIP)
    doc["name"] = "ship__x"
    with pytest.raises(SpecError, match="name 'ship__x' cannot prefix the generated C API"):
        problem_from_document(doc, Path("ship.toml"))


def test_a_trace_with_repeated_columns_is_refused():
    t = np.zeros(3)
    with pytest.raises(TraceError, match=r"distinct names; repeated: \['x'\]"):
        Trace(t=t, inputs=("u",), outputs=("x",), U=np.zeros((3, 1)), Y=np.zeros((3, 1)), extra={"x": t})
    with pytest.raises(TraceError, match=r"repeated: \['t'\]"):
        Trace(t=t, inputs=(), outputs=("y",), U=np.zeros((3, 0)), Y=np.zeros((3, 1)), extra={"t": t})


def test_simulate_writes_distinct_columns(tmp_path):
    # the motor's states and unknown input are extra columns beside its inputs and outputs
    trace = tmp_path / "t.csv"
    assert main(["simulate", str(DATA / "dc_motor.toml"), "--scenario", "fault_free", "--seed", "1", "--out", str(trace)]) == 0
    header = trace.read_text().splitlines()[0].split(",")
    assert len(header) == len(set(header)) and header[:5] == ["t", "voltage", "i_meas", "w_meas", "theta_meas"]
