"""A NAFDF gain file is data: every field of ``extensions.nafdf`` is validated against what the payload
implies before a step is built, and a refusal is one line naming the field (the CLI: status 2)."""

from __future__ import annotations

import copy
import json
from collections.abc import Callable
from pathlib import Path

import fdisyn.synthesis.nafdf.design as nafdf_module
import numpy as np
import pytest
from fdisyn.app.cli import main
from fdisyn.codegen.step import step_function
from fdisyn.problems import ship_propulsion as sp
from fdisyn.runtime.errors import GainFileError
from fdisyn.runtime.gainfile import read_gain_file
from fdisyn.synthesis.nafdf.payload import nafdf_from_gain_file, nafdf_gain_file


@pytest.fixture(scope="module")
def ship():
    dsg = sp.design()
    return dsg, nafdf_gain_file(dsg, problem="ship_propulsion").to_dict()


def write(tmp_path: Path, doc: dict) -> Path:
    d = tmp_path / "diag"
    d.mkdir(exist_ok=True)
    (d / "gains.json").write_text(json.dumps(doc, allow_nan=False))
    return d


def edited(doc: dict, edit: Callable[[dict], object]) -> dict:
    out = copy.deepcopy(doc)
    edit(out)
    return out


def test_the_valid_file_rebuilds_the_designed_step(ship, tmp_path) -> None:
    dsg, doc = ship
    gf = read_gain_file(write(tmp_path, doc) / "gains.json")
    assert step_function(gf).serialize() == dsg.step.serialize()
    np.testing.assert_array_equal(nafdf_from_gain_file(gf).init_state(), dsg.init_state())


def _payload(doc: dict) -> dict:
    return doc["extensions"]["nafdf"]


def _set(path: tuple, value: object) -> Callable[[dict], None]:
    def edit(doc: dict) -> None:
        node = doc
        for k in path[:-1]:
            node = node[k]
        node[path[-1]] = value

    return edit


P = ("extensions", "nafdf")
CASES: list[tuple[str, Callable[[dict], object], str]] = [
    ("all-zero init_state", lambda d: d["step"].__setitem__("init_state", [0.0] * d["step"]["nstate"]),
     r"step.init_state\[1\] \(ekf_P\[0,0\]\) is 0.0; extensions.nafdf implies 100.0"),
    ("all-zero payload init_state", lambda d: _payload(d).__setitem__("init_state", [0.0] * d["step"]["nstate"]),
     r"extensions.nafdf.init_state\[1\] \(ekf_P\[0,0\]\) is 0.0; the settings give 100.0"),
    ("faults that disagree", _set(("faults",), ["b", "a"]), r"faults is \('b', 'a'\); extensions.nafdf implies \('a', 'b'\)"),
    ("thresholds too short", lambda d: _payload(d)["thresholds"].pop(), r"extensions(.nafdf|\['nafdf'\]).thresholds (is .*expected 16 entries|must list one threshold \(or null\) per statistic \(16\))"),
    ("threshold edited", lambda d: _payload(d)["thresholds"].__setitem__(0, 1e-9), "extensions.nafdf.thresholds is"),
    ("uncertified file", _set(("certificate", "passed"), False), "certificate.passed is False, not true: the design did not pass its verification"),
    ("uncertified payload", _set((*P, "certificate", "passed"), False), "extensions.nafdf.certificate did not pass"),
    ("version 1 (CasADi strings)", _set((*P, "version"), 1),
     r"payload version is 1 \(the model as CasADi serialised strings\); this fdisyn reads versions 3, 4: design it again"),
    ("version 2 (range tolerance)", _set((*P, "version"), 2),
     r"payload version is 2 \(the NF's convergence by a fixed tolerance .*\); this fdisyn reads versions 3, 4: design it again"),
    ("version 2 settings", _set((*P, "settings", "convergence_tolerance"), [0.03, 0.01]),
     r"extensions.nafdf.settings: missing field\(s\) \[\], unknown field\(s\) \['convergence_tolerance'\]"),
    ("unknown operation", lambda d: _payload(d)["plant"]["f"]["ops"].__setitem__(4, ["fabs", 3]),
     r"extensions.nafdf.plant.f: f.ops\[4\]: unknown operation 'fabs'"),
    ("forward reference", lambda d: _payload(d)["plant"]["f"]["ops"].__setitem__(2, ["mul", 0, 9]),
     r"f: ops\[2\] operand \(an earlier value\) must be an integer in 0..1"),
    ("expressions that lie", _set((*P, "plant", "expressions", "f", "x"), "0.2*a*x^2 + x + 0.1*b*u"),
     "expressions.f describe another model than extensions.nafdf.plant.f"),
    ("WSSR table edited", lambda d: _payload(d)["detector_thresholds"].__setitem__(3, 1.0),
     r"extensions.nafdf.detector_thresholds\[3\] is 1.0; the settings .* give"),
    ("window 100000", _set((*P, "settings", "window"), 100_000), "extensions.nafdf.settings: window is 100000; at most 1000"),
    ("window 1e9 as a float", _set((*P, "settings", "window"), 1e9), "extensions.nafdf.settings.window must be an integer"),
    ("window 10**9", _set((*P, "settings", "window"), 10**9), "window is 1000000000; at most 1000"),
    ("classifier window huge", _set((*P, "settings", "classifier_window"), 10**12), "classifier_window is 1000000000000; at most 1000"),
    ("P0 edited", _set((*P, "settings", "P0"), [[900.0]]), r"init_state\[1\] \(ekf_P\[0,0\]\) is 100.0; the settings give 900.0"),
    ("negative P0", _set((*P, "settings", "P0"), [[-1.0]]), "extensions.nafdf.settings: P0 must be positive definite"),
    ("unknown payload field", _set((*P, "recovery_samples"), 5), r"unknown field\(s\) \['recovery_samples'\]"),
    ("state name with C in it", _set((*P, "plant", "states"), ['x"); system("rm -rf /'] ), "plant.states must be a list of distinct identifiers"),
    ("nominal as text", _set((*P, "plant", "theta_nominal"), ["-0.58", 0.2]), "plant.theta_nominal must hold numbers"),
    ("huge integer", _set((*P, "plant", "theta_nominal"), [10**400, 0.2]), "plant.theta_nominal must hold finite numbers"),
    ("Q2 not a covariance", _set((*P, "plant", "Q2"), [[0.0]]), "extensions.nafdf.plant: Q2 must be positive definite"),
    ("state layout edited", lambda d: _payload(d)["state_layout"].reverse(), "state_layout does not match"),
    ("names edited", lambda d: _payload(d)["J_names"].__setitem__(0, "x"), "extensions.nafdf.J_names is"),
    ("payload not an object", _set(P, [1, 2]), r"extensions\['nafdf'\] must be an object, found list"),
    ("sample time disagrees", _set(("Ts",), 2.0), "Ts is 2.0; extensions.nafdf implies 1.0"),
]


@pytest.mark.parametrize("what, edit, match", CASES, ids=[c[0] for c in CASES])
def test_each_corruption_is_named_in_one_line(ship, tmp_path, monkeypatch, what: str, edit, match: str) -> None:
    """Refused by the reader (generic fields) or by the payload validation, before any step is built."""
    _, doc = ship
    path = write(tmp_path, edited(doc, edit)) / "gains.json"

    def never(*args: object, **kwargs: object) -> None:
        raise AssertionError(f"{what}: a step was built from a corrupted payload")

    monkeypatch.setattr(nafdf_module, "_build_step", never)
    with pytest.raises(GainFileError, match=match) as info:
        step_function(read_gain_file(path))
    assert "\n" not in str(info.value)


def test_a_crafted_model_that_is_infinite_at_x0_is_refused(ship, tmp_path) -> None:
    """A well-formed program, f(x) = log(x): valid operations, but −inf at x0 = 0 where the EKF starts."""
    _, doc = ship

    def edit(d: dict) -> None:
        pl = _payload(d)["plant"]
        pl["expressions"] = None
        pl["f"] = {"ops": [["input", 0, 0], ["log", 0]], "out": [1]}

    gf = read_gain_file(write(tmp_path, edited(doc, edit)) / "gains.json")
    with pytest.raises(GainFileError, match=r"extensions.nafdf: the model is not finite at the EKF's start .*f\['x'\] = -inf"):
        step_function(gf)


def test_codegen_refuses_a_corrupted_file_with_status_2_and_one_line(ship, tmp_path, capsys) -> None:
    _, doc = ship
    d = write(tmp_path, edited(doc, lambda x: x["step"].__setitem__("init_state", [0.0] * x["step"]["nstate"])))
    assert main(["codegen", str(d)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("fdisyn codegen: error: step.init_state[1]") and "\n" not in err
    assert not (d / "c").exists() or not any((d / "c").glob("*.c"))  # nothing generated
