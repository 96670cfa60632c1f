"""Gain files: exact round trip, refusal of foreign, other-version and corrupt files."""

from __future__ import annotations

import json

import numpy as np
import pytest
from fdisyn.runtime.errors import GainFileError
from fdisyn.runtime.gainfile import FORMAT, read_gain_file, write_gain_file


@pytest.fixture
def doc(wt_built, tmp_path):
    path = write_gain_file(wt_built.gain_file, tmp_path / "gains.json")
    return json.loads(path.read_text())


def _write(tmp_path, doc):
    p = tmp_path / "edited.json"
    p.write_text(json.dumps(doc))
    return p


def test_round_trip_is_exact(wt_built, tmp_path):
    gf = wt_built.gain_file
    back = read_gain_file(write_gain_file(gf, tmp_path / "g.json"))
    for a, b in zip(gf.generators, back.generators, strict=True):
        for k in ("Ar", "Bu", "By", "Cr", "Du", "Dy", "Xu", "Xy"):
            assert np.array_equal(getattr(a, k), getattr(b, k)), k  # repr() floats round-trip bit for bit
    for a, b in zip(gf.evaluators, back.evaluators, strict=True):
        assert np.array_equal(a.W, b.W) and a.threshold == b.threshold and a.dof == b.dof
    assert np.array_equal(gf.decision.signatures, back.decision.signatures)
    assert back.to_dict() == gf.to_dict()


def test_contract_fields_are_present(doc):
    for key in ("format", "name", "problem", "Ts", "inputs", "outputs", "faults", "plant", "generators", "evaluators", "decision", "certificate", "provenance"):
        assert key in doc, key
    assert doc["format"] == FORMAT == "fdisyn.gains/1"
    assert set(doc["plant"]) == {"A", "B", "C", "D", "E", "Q", "R"}
    g = doc["generators"][0]
    assert {"name", "outputs_used", "Ar", "Bu", "By", "Cr", "Du", "Dy", "method"} <= set(g)
    assert {"F", "G", "K", "H", "T", "L"} <= set(g["method"])
    e = doc["evaluators"][0]
    assert {"kind", "generator", "P_f", "dof", "threshold", "Sigma_r"} <= set(e)
    assert doc["inputs"] == ["tau_g"]
    assert doc["outputs"] == ["omega_r_m1", "omega_r_m2", "omega_g_m1", "omega_g_m2"]


def test_other_version_is_refused_with_the_version_found(doc, tmp_path):
    doc["format"] = "fdisyn.gains/2"
    with pytest.raises(GainFileError, match=r"format version '2' \('fdisyn.gains/2'\); this fdisyn reads 'fdisyn.gains/1'"):
        read_gain_file(_write(tmp_path, doc))


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("[1, 2]", "top level is a list"),
        ('{"name": "x"}', "no 'format' field"),
        ('{"format": "acados.ocp/3"}', "format 'acados.ocp/3'"),
        ("{not json", "not valid JSON"),
        ('{"format": "fdisyn.gains/1", "x": NaN}', "non-finite number NaN"),
    ],
)
def test_foreign_and_corrupt_files_are_refused(tmp_path, content, message):
    p = tmp_path / "bad.json"
    p.write_text(content)
    with pytest.raises(GainFileError, match=message):
        read_gain_file(p)


def test_missing_file_is_named(tmp_path):
    with pytest.raises(GainFileError, match="no gain file at"):
        read_gain_file(tmp_path / "nope.json")


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: d.pop("faults"), "missing field 'faults'"),
        (lambda d: d["generators"][0].__setitem__("Ar", [[0.5, 0.0]]), r"generators\[0\]: generator 'uio_r_m1_g_m1'.Ar must be square .* found shape \(1, 2\)"),
        (lambda d: d["generators"][0].__setitem__("By", [[0.5, 0.0]]), r"generators\[0\]: generator 'uio_r_m1_g_m1'.By: expected shape \(3, 2\), found \(1, 2\)"),
        (lambda d: d["generators"][1]["By"][0].__setitem__(0, "x"), "holds something that is not a number"),
        (lambda d: d.__setitem__("name", "wind-turbine"), "must be a C identifier"),
        (lambda d: d["generators"][0].__setitem__("Ar", [[1.5, 0, 0], [0, 0, 0], [0, 0, 0]]), "not Schur stable"),
        (lambda d: d["generators"][0]["Xy"][0].__setitem__(0, 123.0), "Xy is not"),
        (lambda d: d["evaluators"][0].__setitem__("generator", 9), "generator 9 is not a generator index"),
        (lambda d: d["decision"]["signatures"][1].__setitem__(0, 2), "only 0 and 1"),
        (lambda d: d["decision"].__setitem__("signatures", [d["decision"]["signatures"][0]] * 8), "shares its signature"),
        (lambda d: d["step"].__setitem__("nstate", 5), r"init_state has 21 entries; nstate is 5"),
        (lambda d: d.__setitem__("Ts", -0.01), "positive sample time"),
    ],
)
def test_inconsistent_content_is_named(doc, tmp_path, edit, message):
    edit(doc)
    with pytest.raises(GainFileError, match=message):
        read_gain_file(_write(tmp_path, doc))
