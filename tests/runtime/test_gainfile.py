"""Gain files: exact round trip, refusal of foreign, other-version and corrupt files."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
from fdisyn.runtime.errors import BuildError, GainFileError
from fdisyn.runtime.gainfile import gain_file_sha256, read_gain_file, write_gain_file
from fdisyn.runtime.jsondata import parse_json_data
from fdisyn.runtime.schema import FORMAT, LIMITS


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
        (lambda d: d.__setitem__("name", "wind-turbine"), "cannot prefix the generated C API"),
        (lambda d: d["generators"][0].__setitem__("Ar", [[1.5, 0, 0], [0, 0, 0], [0, 0, 0]]), "not Schur stable"),
        (lambda d: d["generators"][0]["Xy"][0].__setitem__(0, 123.0), "Xy is not"),
        (lambda d: d["evaluators"][0].__setitem__("generator", 9), "generator 9 is not a generator index"),
        (lambda d: d["decision"]["signatures"][1].__setitem__(0, 2), "only 0 and 1"),
        (lambda d: d["decision"].__setitem__("signatures", [d["decision"]["signatures"][0]] * 8), "shares its signature"),
        (lambda d: d["step"].__setitem__("nstate", 5), r"init_state has 38 entries; nstate is 5"),
        (lambda d: d.__setitem__("Ts", -0.01), "positive sample time"),
    ],
)
def test_inconsistent_content_is_named(doc, tmp_path, edit, message):
    edit(doc)
    with pytest.raises(GainFileError, match=message):
        read_gain_file(_write(tmp_path, doc))


def _weight_edit(scale_w: float = 1.0, w=None, dof=None):  # noqa: ANN001, ANN202 - an edit of evaluators[0]
    def edit(d):  # noqa: ANN001, ANN202
        ev = d["evaluators"][0]
        ev["W"] = w if w is not None else (np.array(ev["W"]) * scale_w).tolist()
        if dof is not None:
            ev["dof"] = dof

    return edit


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        # the certificate: a design that failed verification is neither compiled nor run
        (lambda d: d["certificate"].__setitem__("passed", False), "certificate.passed is False, not true: the design did not pass its verification"),
        (lambda d: d["certificate"].__setitem__("passed", "true"), "certificate.passed is 'true', not true"),
        (lambda d: d["certificate"].pop("passed"), "certificate has no 'passed' field"),
        (lambda d: d.__setitem__("certificate", []), "field 'certificate' must be an object"),
        # every verdict inside it too, and every check by its own numbers: the top flag alone is one edit away
        (lambda d: d["certificate"]["generators"][1]["checks"][0].__setitem__("passed", False), r"certificate.generators\[1\].checks\[0\].passed is False, not true"),
        (lambda d: d["certificate"]["bank"].__setitem__("passed", None), r"certificate.bank.passed is None, not true"),
        (lambda d: d["certificate"]["generators"][0]["checks"][0].__setitem__("value", 1e9), r"certificate.generators\[0\].checks\[0\] \(.*\): value 1000000000.0 '<=' bound .* does not hold"),
        (lambda d: d["certificate"]["generators"][0]["checks"][0].__setitem__("value", "nan"), r"value 'nan' '<=' bound .* does not hold"),
        (lambda d: d["certificate"]["generators"][0]["checks"][0].__setitem__("relation", "<"), r"value .* '<' bound .* does not hold"),
        (lambda d: d["certificate"]["generators"][0]["checks"][0].__setitem__("bound", 10**400), r"value .* '<=' bound 1000.* does not hold"),
        # a persistence beyond what a count in a double can reach would never alarm
        (lambda d: d["decision"].__setitem__("persistence", 10**30), r"decision.persistence: 10{30}; at most 1000000000 consecutive exceedances"),
        # χ² weights: a negative-definite W gives a statistic that can never alarm
        (_weight_edit(-1.0), r"evaluators\[0\].W must be positive semidefinite and nonzero \(smallest eigenvalue -81.2"),
        (_weight_edit(w=[[0.0, 0.0], [0.0, 0.0]]), r"evaluators\[0\].W must be positive semidefinite and nonzero"),
        (_weight_edit(1.001), r"evaluators\[0\].W is not the pseudo-inverse of Sigma_r on its range"),
        (_weight_edit(dof=2), r"evaluators\[0\].W has rank 1 but dof is 2"),
        (_weight_edit(dof=0), r"evaluators\[0\].dof must be between 1 and the residual size 2, found 0"),
        (_weight_edit(w=[[1.0, 0.5], [0.0, 1.0]]), r"evaluators\[0\].W is not symmetric"),
        (lambda d: d["evaluators"][1].__setitem__("Sigma_r", [[-1.0, 0.0], [0.0, -1.0]]), r"evaluators\[1\].Sigma_r must be a nonzero covariance"),
        (lambda d: d["evaluators"][1].__setitem__("threshold", 0.0), r"evaluators\[1\].threshold must be positive"),
        # names (they reach C literals, CSV headers and C identifiers)
        (lambda d: d.__setitem__("name", "wt__x"), "cannot prefix the generated C API"),
        (lambda d: d.__setitem__("name", "wt_"), "no trailing '_'"),
        (lambda d: d.__setitem__("name", "w" * 300), "at most 64 characters"),
        (lambda d: d["outputs"].__setitem__(0, "tau_g"), r"the name 'tau_g' is used by the inputs and by the outputs"),
        (lambda d: d["inputs"].__setitem__(0, "t"), r"inputs\[0\] 't' is reserved"),
        (lambda d: d["faults"].__setitem__(1, "omega_r_m1"), r"faults must be unique; repeated: \['omega_r_m1'\]"),
        (lambda d: d["step"]["residual_names"].__setitem__(0, "r 0"), r"step.residual_names\[0\] 'r 0' is not a label"),
        (lambda d: d["generators"][0].__setitem__("name", "*/"), r"generators\[0\].name '\*/' is not a label"),
        # numbers are numbers: NumPy would turn "0.5" and true into floats without a word
        (lambda d: d["generators"][0]["Ar"][0].__setitem__(0, "0.5"), r"matrix 'Ar' holds something that is not a number"),
        (lambda d: d["generators"][0]["Ar"][0].__setitem__(0, True), r"matrix 'Ar' holds something that is not a number"),
        (lambda d: d["generators"][0]["Ar"][0].__setitem__(0, 10**400), r"matrix 'Ar' holds something that is not a number"),
        (lambda d: d["step"]["init_state"].__setitem__(0, False), r"field 'init_state' must be a list of numbers"),
        (lambda d: d.__setitem__("Ts", 10**400), r"field 'Ts' must be a finite number"),
        # a linear step starts from zero (generators start at the equilibrium of their first valid sample)
        (lambda d: d["step"]["init_state"].__setitem__(12, 1.0), r"step.init_state of a linear diagnoser must be all zeros; entries \[12\] are not"),
    ],
)
def test_unsafe_content_is_refused(doc, tmp_path, edit, message):
    edit(doc)
    with pytest.raises(GainFileError, match=message) as err:
        read_gain_file(_write(tmp_path, doc))
    assert "\n" not in str(err.value)


def test_json_nested_too_deeply_is_refused(tmp_path):
    p = tmp_path / "deep.json"
    p.write_text('{"format": "fdisyn.gains/1", "x": ' + "[" * 100_000 + "]" * 100_000 + "}")
    with pytest.raises(GainFileError, match="nested too deeply"):
        read_gain_file(p)


def test_a_gain_file_that_is_no_regular_file_is_refused_without_reading(tmp_path):
    """A received directory may hold a link to a device or a FIFO: read, it would never end (or block)."""
    link = tmp_path / "zero.json"
    link.symlink_to("/dev/zero")
    with pytest.raises(GainFileError, match=r"zero.json is not a regular file \(a device, a FIFO or a directory\); expected a gain file"):
        read_gain_file(link)
    fifo = tmp_path / "fifo.json"
    os.mkfifo(fifo)
    with pytest.raises(GainFileError, match=r"fifo.json is not a regular file"):
        read_gain_file(fifo)  # opened without waiting for a writer: no test hangs here


def test_an_oversized_file_is_refused_before_it_is_read(doc, tmp_path, monkeypatch):
    from fdisyn.runtime import schema

    p = _write(tmp_path, doc)
    monkeypatch.setitem(schema.LIMITS, "file_bytes", p.stat().st_size - 1)
    with pytest.raises(GainFileError, match=rf"has {p.stat().st_size} bytes; a gain file may have at most {p.stat().st_size - 1}"):
        read_gain_file(p)


def _dense_generator(doc, n: int, *, diagonal: bool = False) -> None:  # noqa: ANN001 - a gain-file document
    """Give generator 0 a dense, stable n-state Ar (and consistent Bu, By, Cr, Xu, Xy); ``diagonal``: Ar = I/2
    (a large file written quickly)."""
    rng = np.random.default_rng(1)
    if diagonal:
        a = 0.5 * np.eye(n)
    else:
        a = rng.standard_normal((n, n))
        a *= 0.5 / np.max(np.abs(np.linalg.eigvals(a)))
    g = doc["generators"][0]
    doc["step"]["nstate"] += n - len(g["Ar"])
    g["Ar"] = a.tolist()
    g["Bu"] = rng.standard_normal((n, 1)).tolist()
    by = np.zeros((n, 4))
    by[:, g["outputs_used"]] = rng.standard_normal((n, len(g["outputs_used"])))
    g["By"] = by.tolist()
    g["Cr"] = rng.standard_normal((2, n)).tolist()
    g["Xu"] = np.linalg.solve(np.eye(n) - a, np.array(g["Bu"])).tolist()
    g["Xy"] = np.linalg.solve(np.eye(n) - a, by).tolist()
    doc["step"]["init_state"] = [0.0] * doc["step"]["nstate"]


def test_a_generator_beyond_the_state_limit_is_refused_at_once(doc, tmp_path, monkeypatch):
    """A generator of more than 1 024 states is refused on its size, before the eigenvalue check or any C; the
    coefficient limit (a step's constant tables) likewise."""
    n0 = len(doc["generators"][0]["Ar"])
    _dense_generator(doc, 1100, diagonal=True)
    p = _write(tmp_path, doc)
    with pytest.raises(GainFileError, match=r"states in one generator: 1100; at most 1024 are supported"):
        read_gain_file(p)
    assert n0 < 1100
    monkeypatch.setitem(LIMITS, "coefficients", 10_000)  # the limit's message, at a size a test writes quickly
    _dense_generator(doc, 120)
    with pytest.raises(GainFileError, match=r"hold 1[0-9]{4} nonzero coefficients; at most 10000 are supported"):
        read_gain_file(_write(tmp_path, doc))


def test_the_content_hash_sees_values_not_layout(doc, tmp_path):
    h = gain_file_sha256(read_gain_file(_write(tmp_path, doc)))
    p = tmp_path / "spaced.json"
    p.write_text(json.dumps(dict(sorted(doc.items(), reverse=True)), indent=8))
    assert gain_file_sha256(read_gain_file(p)) == h
    doc["evaluators"][2]["threshold"] = np.nextafter(doc["evaluators"][2]["threshold"], np.inf)  # one ulp
    assert gain_file_sha256(read_gain_file(_write(tmp_path, doc))) != h


# --------------------------------------------------------------------------- repeated keys
_REPORTS = Path(__file__).resolve().parents[2] / "reports"
_DUP = "__repeated__"


def _with_repeated_key(path: Path, where: tuple[object, ...], key: str, first: object) -> str:
    """The JSON text of ``path`` with ``key`` written twice in the object at ``where``: ``first`` before the
    file's own value (a JSON reader keeps the last)."""
    doc = json.loads(path.read_text(encoding="utf-8"))
    parent = doc
    for k in where[:-1]:
        parent = parent[k]
    parent[where[-1]] = {_DUP: 0, **parent[where[-1]]} if where else None
    return json.dumps(doc, indent=1).replace(f'"{_DUP}": 0', f'"{key}": {json.dumps(first)}', 1)


@pytest.mark.parametrize(
    ("file", "where", "key", "first", "place"),
    [
        ("wind_turbine/gains/wind_turbine_kalman_uio.json", ("generators", 0), "Bu", [[1.0]], r"in generators\[0\]"),
        ("wind_turbine/gains/wind_turbine_kalman_uio.json", ("certificate",), "passed", False, "in certificate"),
        ("wind_turbine/gains/wind_turbine_kalman_uio.json", ("certificate", "generators", 1), "passed", False, r"in certificate\.generators\[1\]"),
        ("wind_turbine/gains/wind_turbine_kalman_uio.json", ("provenance",), "fdisyn", "0", "in provenance"),
        ("satellite_pitch/gains/satellite_pitch_optimised.json", ("extensions", "beard_fdf"), "h", 1.0, r"in extensions\.beard_fdf"),
        ("ship_propulsion/gains/ship_propulsion_nafdf.json", ("extensions", "nafdf", "settings"), "window", 3, r"in extensions\.nafdf\.settings"),
    ],
)
def test_a_repeated_key_is_refused_with_its_place(tmp_path, file, where, key, first, place):
    p = tmp_path / "gains.json"
    p.write_text(_with_repeated_key(_REPORTS / file, where, key, first), encoding="utf-8")
    with pytest.raises(GainFileError, match=rf"key '{key}' appears more than once {place}; a gain file holds each key once"):
        read_gain_file(p)


def test_a_repeated_key_at_the_top_level_is_refused(tmp_path):
    doc = json.loads((_REPORTS / "wind_turbine/gains/wind_turbine_kalman_uio.json").read_text(encoding="utf-8"))
    text = json.dumps({_DUP: 0, **doc}).replace(f'"{_DUP}": 0', '"name": "other"', 1)
    p = tmp_path / "gains.json"
    p.write_text(text, encoding="utf-8")
    with pytest.raises(GainFileError, match=r"key 'name' appears more than once at the top level") as exc:
        read_gain_file(p)
    assert "\n" not in str(exc.value)


def test_parse_json_data_names_a_hostile_key_on_one_line():
    with pytest.raises(BuildError, match=r"m\.json: key 'x' appears more than once in a\.'b\\nc'\[1\]; a build manifest holds"):
        parse_json_data('{"a": {"b\\nc": [0, {"x": 1, "x": 2}]}}', "m.json", "a build manifest", error=BuildError)
    assert parse_json_data('{"a": [{"x": 1}, {"x": 2}]}', "m.json", "a build manifest") == {"a": [{"x": 1}, {"x": 2}]}
