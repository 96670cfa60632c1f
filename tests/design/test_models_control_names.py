"""python-control's signal names in and out: ``LinearPlant.from_control`` keeps a system's labels,
``LinearPlant.to_control`` gives them back, and a generator's ``to_control`` is named after its gain file."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import control
import numpy as np
import pytest
from fdisyn.models.linear import LinearPlant
from fdisyn.runtime.errors import ArgumentError
from fdisyn.runtime.gainfile import read_gain_file

REPORTS = Path(__file__).resolve().parents[2] / "reports"
A = [[0.9, 0.1], [0.0, 0.8]]
B = [[1.0, 0.2], [0.5, 0.0]]
C = [[1.0, 0.0], [0.0, 1.0]]


def _sys(dt: float = 0.1, **names) -> control.StateSpace:
    return control.ss(A, B, C, 0, dt, **names)


def test_a_named_system_goes_round_trip_with_its_labels() -> None:
    sys = _sys(states=["level", "flow"], inputs=["pump", "leak"], outputs=["h", "q"])
    plant = LinearPlant.from_control(sys, n_unknown=1)
    assert (plant.states, plant.inputs, plant.unknown_inputs, plant.outputs) == (("level", "flow"), ("pump",), ("leak",), ("h", "q"))
    back = plant.to_control()
    assert (back.state_labels, back.input_labels, back.output_labels) == (sys.state_labels, sys.input_labels, sys.output_labels)
    for key in ("A", "B", "C", "D"):
        assert np.array_equal(getattr(back, key), getattr(sys, key))
    assert back.dt == sys.dt


def test_python_controls_default_labels_become_fdisyns_defaults() -> None:
    plant = LinearPlant.from_control(_sys(), n_unknown=1)
    assert (plant.states, plant.inputs, plant.unknown_inputs, plant.outputs) == (("x0", "x1"), ("u0",), ("d0",), ("y0", "y1"))
    assert plant.to_control().input_labels == ["u0", "d0"]
    mixed = LinearPlant.from_control(_sys(inputs=["pump", "u[1]"], outputs=["h", "y[1]"]), n_unknown=1)
    assert (mixed.inputs, mixed.unknown_inputs, mixed.outputs) == (("pump",), ("d0",), ("h", "y1"))
    continuous = LinearPlant.from_control(control.ss([[-1.0]], [[1.0]], [[1.0]], 0, states=["w"]))
    assert continuous.Ts is None and continuous.states == ("w",) and continuous.inputs == ("u0",)


def test_names_given_win_over_the_systems_labels() -> None:
    sys = _sys(states=["level", "flow"], inputs=["pump", "leak"], outputs=["h", "q"])
    plant = LinearPlant.from_control(sys, n_unknown=1, outputs=["h1", "h2"], unknown_inputs=["wind"], labels={"h1": "level"})
    assert (plant.states, plant.inputs, plant.unknown_inputs, plant.outputs) == (("level", "flow"), ("pump",), ("wind",), ("h1", "h2"))
    assert plant.labels == {"h1": "level"}


@pytest.mark.parametrize(
    ("names", "message"),
    [
        ({"inputs": ["pump speed", "leak"]}, r"^sys.input_labels\[0\] = 'pump speed' cannot be an fdisyn signal name: expected a letter, "
                                             r"then letters, digits or '_', at most 63 characters; pass inputs=\[…\] to from_control to name them$"),
        ({"inputs": ["pump", "t"]}, r"^sys.input_labels\[1\] = 't' cannot be an fdisyn signal name: it is reserved \(the time column of every "
                                    r"trace CSV\); pass unknown_inputs=\[…\] to from_control to name them$"),
        ({"states": ["x-1", "x2"]}, r"^sys.state_labels\[0\] = 'x-1' cannot be an fdisyn signal name: .*; pass states=\[…\]"),
        ({"outputs": ["h", "débit"]}, r"^sys.output_labels\[1\] = 'débit' cannot be an fdisyn signal name: .*; pass outputs=\[…\]"),
    ],
)
def test_a_label_outside_the_grammar_is_refused_in_one_line(names, message) -> None:
    with pytest.raises(ArgumentError, match=message) as exc:
        LinearPlant.from_control(_sys(**names), n_unknown=1)
    assert "\n" not in str(exc.value)
    key = {"inputs": "inputs", "states": "states", "outputs": "outputs"}[next(iter(names))]
    fixed = {key: [f"s{i}" for i in range(2)]} if key != "inputs" else {"inputs": ["pump"], "unknown_inputs": ["leak"]}
    assert LinearPlant.from_control(_sys(**names), n_unknown=1, **fixed).n == 2  # the remedy the message names works


def test_a_generator_of_a_gain_file_is_named_after_the_file() -> None:
    gf = read_gain_file(REPORTS / "wind_turbine" / "gains" / "wind_turbine_kalman_uio.json")
    offset = 0
    for g in gf.generators:
        sys = g.to_control()
        assert sys.input_labels == [*gf.inputs, *gf.outputs]
        own = gf.step.residual_names[offset : offset + g.n_residual]
        offset += g.n_residual
        assert [f"{g.name}.{r}" for r in sys.output_labels] == list(own)
        assert sys.name == g.name and sys.dt == gf.Ts
    assert gf.generators[0].to_control().output_labels == ["omega_r_m1", "omega_g_m1"]


def test_a_generator_outside_a_gain_file_keeps_python_controls_names() -> None:
    gf = read_gain_file(REPORTS / "wind_turbine" / "gains" / "wind_turbine_kalman_uio.json")
    g = gf.generators[0]
    bare = dataclasses.replace(g, input_names=(), output_names=(), residual_names=(), Ts=None).to_control()
    assert bare.input_labels == [f"u[{i}]" for i in range(len(gf.inputs) + len(gf.outputs))]
    assert bare.output_labels == [f"y[{i}]" for i in range(g.n_residual)]
