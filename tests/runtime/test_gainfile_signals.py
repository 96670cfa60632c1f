"""The gain file's optional ``signals`` block (units and labels of its signals): written, read back, refused when
corrupt in one line naming the field, and a file without it (written before it, or of a plant without units)
reads and hashes as its own document.

The files are the committed gain files of the reports; the truth of a hash is sha256 of the file's own document,
serialised canonically here (sorted keys, no blanks, ASCII), independently of :meth:`GainFile.to_dict`."""

from __future__ import annotations

import copy
import hashlib
import json
from pathlib import Path

import pytest
from fdisyn.runtime.errors import GainFileError
from fdisyn.runtime.gainfile import gain_file_from_dict, gain_file_sha256, read_gain_file, signals_block, write_gain_file
from fdisyn.runtime.monitor import Monitor, fault_label

REPORTS = Path(__file__).resolve().parents[2] / "reports"
FILES = sorted(REPORTS.glob("*/gains/*.json"))
WIND = REPORTS / "wind_turbine" / "gains" / "wind_turbine_kalman_uio.json"
SIGNALS = {
    "units": {"tau_g": "N·m", "omega_r_m1": "rad/s"},
    "labels": {"tau_g": "generator torque", "omega_r_m1": "rotor speed (sensor 1)", "omega_g_m2": "generator speed 2"},
}


def _canonical_sha256(doc: dict) -> str:
    return hashlib.sha256(json.dumps(doc, sort_keys=True, separators=(",", ":"), ensure_ascii=True).encode("ascii")).hexdigest()


def _doc(path: Path = WIND) -> dict:
    return json.loads(path.read_text(encoding="utf-8"))


def test_committed_files_read_with_and_without_the_block_and_keep_their_content_hash() -> None:
    """Every committed gain file: its hash is that of its own document; the block is there exactly for the plants that
    have units (the wind turbine's, not the ship's), and the same file without it reads, hashes as its document,
    and has no units."""
    assert len(FILES) > 40
    with_block = set()
    for path in FILES:
        doc = _doc(path)
        gf = read_gain_file(path)
        assert gain_file_sha256(gf) == _canonical_sha256(doc), path
        if "signals" in doc:
            with_block.add(path.parts[-3])
            assert gf.signals == doc["signals"] and gf.units == doc["signals"].get("units", {})
        bare = {k: v for k, v in doc.items() if k != "signals"}
        old = gain_file_from_dict(bare)
        assert old.signals is None and old.units == {} and old.labels == {}
        assert gain_file_sha256(old) == _canonical_sha256(bare), path
    assert "wind_turbine" in with_block and not {"ship_propulsion", "sampled_data_example"} & with_block
    assert read_gain_file(WIND).units["omega_r_m1"] == "rad/s"  # the problem's plant's unit (problems/wind_turbine.py)


def test_the_block_is_written_and_read_back_and_enters_the_hash(tmp_path) -> None:
    doc = _doc()
    doc["signals"] = copy.deepcopy(SIGNALS)
    gf = gain_file_from_dict(doc)
    assert gf.signals == SIGNALS and gf.units["tau_g"] == "N·m" and gf.labels["omega_g_m2"] == "generator speed 2"
    back = read_gain_file(write_gain_file(gf, tmp_path / "gains.json"))
    assert back.signals == SIGNALS
    assert json.loads((tmp_path / "gains.json").read_text(encoding="utf-8"))["signals"] == SIGNALS
    assert gain_file_sha256(back) == gain_file_sha256(gf) == _canonical_sha256(doc)
    assert gain_file_sha256(gf) != _canonical_sha256(_doc())


def test_signals_block_keeps_the_files_signals_only() -> None:
    units = {"x0": "rad", "u": "V", "y1": "m", "valve": "1", "leak": "m³/s"}
    labels = {"y1": "level", "other": "nothing"}
    block = signals_block(units, labels, ("u",), ("y1", "y2"), ("y1", "y2|valve"))
    assert block == {"units": {"u": "V", "y1": "m", "valve": "1"}, "labels": {"y1": "level"}}
    assert signals_block({"x0": "rad"}, {}, ("u",), ("y1",), ("y1",)) is None


@pytest.mark.parametrize(
    ("block", "message"),
    [
        ([], r"field 'signals' must be an object, found list$"),
        ({"units": {}, "notes": {}}, r"signals holds \['notes'\]; expected only the tables 'units' and 'labels'"),
        ({"units": ["rad"]}, r"signals.units must be a table of text by signal name, found list \['rad'\]$"),
        ({"units": {"x0": "rad"}}, r"signals.units names 'x0', which is not a signal of the gain file; expected keys among \['tau_g', 'omega_r_m1'"),
        ({"labels": {"tau_g": 1}}, r"signals.labels\['tau_g'\] must be a string, found int 1$"),
        ({"labels": {"tau_g": ""}}, r"signals.labels\['tau_g'\] '' is not short text: expected 1 to 80 printable characters"),
        ({"units": {"tau_g": "N" * 33}}, r"signals.units\['tau_g'\] 'N+' is not short text: expected 1 to 32"),
        ({"labels": {"tau_g": "torque\nx"}}, r"signals.labels\['tau_g'\] 'torque\\nx' is not short text"),
        ({"labels": {"tau_g": "torque\x1b[2J"}}, r"signals.labels\['tau_g'\] 'torque\\x1b\[2J' is not short text"),
        ({"labels": {"tau_g": "torque\u2028"}}, r"signals.labels\['tau_g'\] .* is not short text"),
        ({"labels": {"tau_g": "torque "}}, r"without blanks at either end$"),
    ],
)
def test_a_corrupt_block_is_refused_in_one_line(tmp_path, block, message) -> None:
    doc = _doc()
    doc["signals"] = block
    path = tmp_path / "gains.json"
    path.write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(GainFileError, match=message) as exc:
        read_gain_file(path)
    text = str(exc.value)
    assert text.startswith(f"{path}: ") and text.count(str(path)) == 1 and "\n" not in text and len(text) < 400


def test_the_monitor_shows_units_and_the_fault_label() -> None:
    doc = _doc()
    doc["signals"] = copy.deepcopy(SIGNALS)
    mon = Monitor(gain_file_from_dict(doc), backend="reference")
    assert mon.units == SIGNALS["units"] and mon.labels == SIGNALS["labels"]
    gf = mon.gf
    verdict = mon.update([0.0] * len(gf.inputs), [0.0] * len(gf.outputs))
    assert verdict.fault is None and verdict.fault_label is None
    assert fault_label("omega_r_m1+omega_g_m2", mon.labels) == "rotor speed (sensor 1) + generator speed 2"
    assert fault_label("omega_r_m1|omega_g_m1", mon.labels) == "rotor speed (sensor 1) | omega_g_m1"
    assert fault_label("omega_g_m1", {}) == "omega_g_m1"
    plain = Monitor(gain_file_from_dict({k: v for k, v in _doc().items() if k != "signals"}), backend="reference")
    assert plain.units == {} and plain.labels == {}
