"""``LinearPlant(A, B, C, D, Ts, **keywords)`` is ``LinearPlant.create`` with python-control's argument order.

The truth is ``create``: the same arguments, given positionally or as keywords, give the same plant field by field,
and the same refusals word for word; ``dataclasses.replace`` and the gain file's design model keep working.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import control
import numpy as np
import pytest
from fdisyn.models.linear import LinearPlant
from fdisyn.runtime.errors import ArgumentError, ShapeError
from fdisyn.runtime.gainfile import read_gain_file
from fdisyn.synthesis.linear_kind import design_plant

REPORTS = Path(__file__).resolve().parents[2] / "reports"
A = [[0.9, 0.1], [0.0, 0.8]]
B = [[1.0], [0.5]]
C = [[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]
D = [[0.0], [0.1], [0.0]]
KEYWORDS = [
    {},
    {"E": [[0.1], [0.0]], "Q": np.eye(2) * 1e-3, "R": np.eye(3) * 1e-2},
    {"E": [[0.1], [0.0]], "Dd": [[0.0], [0.2], [0.0]], "Fx": [[0.0], [1.0]], "Df": [[0.0], [0.0], [0.3]],
     "states": ["h1", "h2"], "inputs": ["pump"], "unknown_inputs": ["leak"], "outputs": ["y1", "y2", "y3"],
     "component_faults": ["valve"], "units": {"h1": "m", "pump": "m³/s"}, "labels": {"h1": "level of tank 1"}},
]


def _same(a: LinearPlant, b: LinearPlant) -> None:
    for f in dataclasses.fields(LinearPlant):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray):
            assert x.dtype == y.dtype and np.array_equal(x, y) and not x.flags.writeable, f.name
        else:
            assert x == y, f.name


@pytest.mark.parametrize("keywords", KEYWORDS)
@pytest.mark.parametrize("Ts", [0.1, None])
def test_positional_and_keyword_construction_is_create(keywords, Ts) -> None:
    truth = LinearPlant.create(A=A, B=B, C=C, D=D, Ts=Ts, **keywords)
    _same(LinearPlant(A, B, C, D, Ts, **keywords), truth)
    _same(LinearPlant(A=A, B=B, C=C, D=D, Ts=Ts, **keywords), truth)
    _same(LinearPlant(np.array(A), np.array(B), C=C, D=D, Ts=Ts, **keywords), truth)


def test_control_ss_arguments_build_the_plant_control_ss_builds() -> None:
    """``control.ss(A, B, C, D, dt)``'s arguments, a scalar 0 for ``D`` and ``dt = 0`` for continuous included."""
    for dt in (0, 0.05):
        sys = control.ss(A, B, C, 0, dt)
        plant = LinearPlant(A, B, C, 0, dt)
        assert plant.Ts == (None if dt == 0 else dt) and plant.is_discrete == (dt != 0)
        assert np.array_equal(plant.D, sys.D) and plant.D.shape == (3, 1)
        _same(plant, LinearPlant.create(A=A, B=B, C=C, D=0, Ts=dt))
    assert LinearPlant(A, B, C).Ts is None  # no D, no Ts: continuous, zero feed-through


@pytest.mark.parametrize(
    ("args", "keywords", "error"),
    [
        ((A, B, C, D, -0.1), {}, ArgumentError),
        ((A, B, C, D, 0.1), {"Q": [[1.0, 0.5], [0.0, 1.0]]}, ArgumentError),
        ((A, B, C, D, 0.1), {"R": -np.eye(3)}, ArgumentError),
        ((A, B, C, [[1.0, 2.0]], 0.1), {}, ShapeError),
        ((A, B, C, D, 0.1), {"outputs": ["y1", "y1", "y3"]}, ArgumentError),
        ((A, B, C, D, 0.1), {"states": ["t", "x1"]}, ArgumentError),
        ((A, B, C, D, 0.1), {"units": {"nobody": "m"}}, ArgumentError),
        ((A, B, C, D, 0.1), {"labels": {"y0": "two\nlines"}}, ArgumentError),
        ((A, B, C, D, True), {}, ArgumentError),
        (([[1e200]], None, [[1.0]], None, 0.1), {}, ArgumentError),
    ],
)
def test_the_constructor_refuses_what_create_refuses_in_the_same_words(args, keywords, error) -> None:
    names = ("A", "B", "C", "D", "Ts")
    with pytest.raises(error) as truth:
        LinearPlant.create(**dict(zip(names, args, strict=True)), **keywords)
    with pytest.raises(error) as ours:
        LinearPlant(*args, **keywords)
    assert str(ours.value) == str(truth.value) and "\n" not in str(ours.value)


def test_c_is_required_in_one_line() -> None:
    with pytest.raises(ArgumentError, match=r"^C, the output matrix \(p × n\), is required; expected LinearPlant\(A, B, C, D, Ts\)"):
        LinearPlant(A, B)


def test_replace_keeps_working_and_checks_what_it_changes() -> None:
    plant = LinearPlant(A, B, C, D, 0.1, E=[[0.1], [0.0]], Q=np.eye(2) * 1e-3, R=np.eye(3) * 1e-2, units={"y0": "m"})
    half = dataclasses.replace(plant, A=0.5 * plant.A)
    assert np.array_equal(half.A, 0.5 * np.asarray(A)) and half.units == {"y0": "m"} and np.array_equal(half.Q, plant.Q)
    scaled = plant.scaled([2.0, 0.5])
    again = dataclasses.replace(scaled)  # a plant's own fields: nothing changes, its Q stays as it is to the bit
    _same(again, scaled)
    with pytest.raises(ShapeError):
        dataclasses.replace(plant, C=np.ones((3, 3)))
    with pytest.raises(ArgumentError, match="state_scale must be None or 2 positive finite numbers"):
        dataclasses.replace(plant, state_scale=(1.0, -1.0))


def test_the_design_model_of_a_committed_gain_file_is_its_plant_as_written() -> None:
    """``design_plant`` builds the plant with the constructor: the file's ``Q`` (symmetric to round-off only) unchanged."""
    gf = read_gain_file(REPORTS / "wind_turbine" / "gains" / "wind_turbine_kalman_uio.json")
    plant = design_plant(gf)
    for key in ("A", "B", "C", "D", "E", "Q", "R"):
        assert np.array_equal(plant.matrices()[key], gf.plant[key]), key
    assert plant.inputs == gf.inputs and plant.outputs == gf.outputs and plant.Ts == gf.Ts
