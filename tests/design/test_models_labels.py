"""Units and labels of a plant's signals: checked where they enter, kept by every method that returns a modified
plant, and carried into the gain file's ``signals`` block by the designs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from fdisyn.models.linear import LinearPlant
from fdisyn.models.nonlinear import NonlinearPlant
from fdisyn.runtime.errors import ArgumentError
from fdisyn.runtime.gainfile import gain_file_from_dict, read_gain_file, write_gain_file
from fdisyn.runtime.schema import SIGNAL_LABEL_MAX, UNIT_MAX
from fdisyn.synthesis.registry import design

REPORTS = Path(__file__).resolve().parents[2] / "reports"

UNITS = {"h1": "m", "h2": "m", "pump": "m³/s", "y1": "m", "y2": "m", "leak": "m³/s", "valve": "1"}
LABELS = {"h1": "level of tank 1", "pump": "pump flow", "y1": "level sensor 1", "y2": "level sensor 2", "valve": "outlet valve"}


def _plant(**kw) -> LinearPlant:
    return LinearPlant.create(
        A=[[-0.05, 0.0], [0.05, -0.04]], B=[[0.02], [0.0]], C=np.eye(2), E=[[0.01], [0.0]], Fx=[[0.0], [0.03]],
        Q=np.diag([1e-6, 1e-6]), R=np.diag([1e-4, 1e-4]), states=["h1", "h2"], inputs=["pump"], unknown_inputs=["leak"],
        outputs=["y1", "y2"], component_faults=["valve"], **{"units": UNITS, "labels": LABELS, **kw},
    )


def test_units_and_labels_are_kept_by_every_modified_plant() -> None:
    plant = _plant()
    assert plant.units == UNITS and plant.labels == LABELS
    discrete = plant.discretise(1.0)
    for other in (discrete, plant.scaled([2.0, 4.0]), plant.with_noise(R=np.eye(2) * 1e-3), discrete.scaled([1.0, 2.0]).with_noise()):
        assert other.units == UNITS and other.labels == LABELS
    one = plant.select_outputs([1])
    assert one.outputs == ("y2",)
    assert one.units == {k: v for k, v in UNITS.items() if k != "y1"}
    assert one.labels == {k: v for k, v in LABELS.items() if k != "y1"}


@pytest.mark.parametrize(
    ("given", "message"),
    [
        ({"labels": {"x9": "nothing"}}, r"^labels names 'x9', which is not a signal of the plant; expected keys among \['h1', 'h2', 'pump', 'leak', 'y1', 'y2', 'valve'\]$"),
        ({"units": {"y1": ""}}, r"^units\['y1'\] '' is not short text: expected 1 to 32 printable characters on one line"),
        ({"units": {"y1": "m" * (UNIT_MAX + 1)}}, r"^units\['y1'\] 'm+' is not short text"),
        ({"labels": {"y1": "a" * (SIGNAL_LABEL_MAX + 1)}}, r"^labels\['y1'\] .* is not short text: expected 1 to 80"),
        ({"labels": {"y1": "rotor\nspeed"}}, r"^labels\['y1'\] 'rotor\\nspeed' is not short text"),
        ({"labels": {"y1": "speed\u202e"}}, r"^labels\['y1'\] .* is not short text"),
        ({"labels": {"y1": " speed"}}, r"without blanks at either end$"),
        ({"labels": {"y1": 3}}, r"^labels\['y1'\] must be a string, found int 3$"),
        ({"units": ["m"]}, r"^units must be a table of text by signal name, found list \['m'\]$"),
    ],
)
def test_a_bad_unit_or_label_is_refused_in_one_line(given, message) -> None:
    with pytest.raises(ArgumentError, match=message) as exc:
        _plant(**given)
    assert "\n" not in str(exc.value)


def test_printable_unicode_is_a_unit() -> None:
    assert _plant(units={"y1": "N·m", "y2": "°C", "pump": "m³/s"}).units["y1"] == "N·m"


def _nonlinear(**kw) -> NonlinearPlant:
    return NonlinearPlant.from_expressions(
        states=["x"], inputs=["u"], outputs=["y"], parameters=["a"], nominal={"a": 0.9},
        f={"x": "a*x + u"}, h={"y": "x"}, Q=[[0.01]], R=[[0.01]], **kw,
    )


def test_a_nonlinear_plant_checks_and_keeps_its_units_and_labels() -> None:
    plant = _nonlinear(units={"x": "m", "a": "1"}, labels={"y": "position sensor", "a": "gain"})
    assert plant.units == {"x": "m", "a": "1"} and plant.labels == {"y": "position sensor", "a": "gain"}
    with pytest.raises(ArgumentError, match=r"^labels names 'z', which is not a signal of the plant; expected keys among \['x', 'u', 'y', 'a'\]$"):
        _nonlinear(labels={"z": "nothing"})
    with pytest.raises(ArgumentError, match=r"^units\['x'\] 'a\\tb' is not short text"):
        _nonlinear(units={"x": "a\tb"})


def test_a_design_writes_the_signals_block_and_it_reads_back(tmp_path) -> None:
    plant = _plant().discretise(1.0)
    gf = design(plant, "kalman_uio", name="tanks", problem="tanks", arl0=3600.0)
    # the file's signals only: inputs, outputs and the component fault; no state, no unknown input
    keys = {"pump", "y1", "y2", "valve"}
    assert gf.signals == {
        "units": {k: v for k, v in UNITS.items() if k in keys},
        "labels": {k: v for k, v in LABELS.items() if k in keys},
    }
    path = write_gain_file(gf, tmp_path / "gains.json")
    back = read_gain_file(path)
    assert back.signals == gf.signals and back.units["pump"] == "m³/s" and back.labels["valve"] == "outlet valve"
    assert gain_file_from_dict(back.to_dict()).to_dict() == gf.to_dict()


def test_a_plant_without_units_or_labels_writes_no_block() -> None:
    gf = design(_plant(units=None, labels=None).discretise(1.0), "kalman_uio", name="tanks", problem="tanks", arl0=3600.0)
    assert gf.signals is None and "signals" not in gf.to_dict()
