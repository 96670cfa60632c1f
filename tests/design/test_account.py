"""The design-time account of what a diagnoser can see (fdisyn.numerics.account on its kind's view,
fdisyn.synthesis.account), against independent truths:
python-control's DC gain and frequency response, a seeded simulation of the plant and its generator, SciPy's
noncentral χ² law, and the gain file's reader."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import scipy.stats
from fdisyn.numerics import account as acc_mod
from fdisyn.numerics.account import account_lines
from fdisyn.synthesis import account as kind_acc
from fdisyn.synthesis.account import fault_account, with_account
from fdisyn.synthesis.kinds import get_kind
from fdisyn.runtime.errors import ArgumentError, GainFileError
from fdisyn.runtime.gainfile import gain_file_from_dict, gain_file_sha256, read_gain_file

ROOT = Path(__file__).resolve().parents[2]
REPORTS = ROOT / "reports"


@pytest.fixture(scope="module")
def motor():
    """The example DC motor's plant and its default design (two observers on (i, θ) and (ω, θ))."""
    from fdisyn.app.examples import example_path
    from fdisyn.simulation.plant_file import load_spec

    prob = load_spec(str(example_path("dc_motor")))
    return prob, prob.design()


def _random_stable(rng: np.random.Generator, n: int) -> np.ndarray:
    a = rng.standard_normal((n, n))
    return 0.9 * a / max(abs(np.linalg.eigvals(a)))


def test_gains_match_python_control_dcgain_and_frequency_response() -> None:
    control = pytest.importorskip("control")
    rng = np.random.default_rng(7)
    for _ in range(20):
        n, p = int(rng.integers(1, 7)), int(rng.integers(1, 4))
        a, b, c, d = _random_stable(rng, n), rng.standard_normal(n), rng.standard_normal((p, n)), rng.standard_normal(p)
        gain = acc_mod._gains(a, b, c, d)
        sys = control.ss(a, b[:, None], c, d[:, None], dt=True)
        np.testing.assert_allclose(gain["dc"], np.asarray(control.dcgain(sys)).ravel(), rtol=1e-9, atol=1e-12)
        w = np.linspace(0.0, math.pi, acc_mod._GRID)
        resp = np.asarray(control.frequency_response(sys, w).complex).reshape(p, -1)
        assert gain["peak_gain"] == pytest.approx(float(np.max(np.linalg.norm(resp, axis=0))), rel=1e-9)
        for om in rng.uniform(0, math.pi, 3):  # anywhere on the circle, below the grid's peak by a margin at most
            g = c @ np.linalg.solve(np.exp(1j * om) * np.eye(n) - a, b) + d
            assert np.linalg.norm(g) <= 1.5 * gain["peak_gain"]
        assert gain["effect"] == "persistent"


def test_effect_classes_zero_transient_persistent() -> None:
    rng = np.random.default_rng(3)
    a, c = _random_stable(rng, 3), rng.standard_normal((2, 3))
    # b in the unobservable direction of a generator that cannot see it: an exact zero, to round-off
    a_blk = np.diag([0.5, 0.3])
    assert acc_mod._gains(a_blk, np.array([1.0, 0.0]), np.array([[0.0, 1.0]]), np.zeros(1))["effect"] == "zero"
    # a differentiator 1 − z⁻¹: it moves the residual but has no DC gain
    diff = acc_mod._gains(np.zeros((1, 1)), np.array([1.0]), np.array([[-1.0]]), np.array([1.0]))
    assert diff["effect"] == "transient" and diff["dc_gain"] == 0.0 and diff["peak_gain"] == pytest.approx(2.0)
    # an integrator the residual sees: the effect grows (persistent, no finite DC gain)
    grow = acc_mod._gains(np.eye(1), np.array([1.0]), np.array([[1.0]]), np.zeros(1))
    assert grow["effect"] == "persistent" and grow["dc_gain"] is None
    # an integrator the residual does not see: the stable quotient decides
    a2 = np.array([[1.0, 0.0], [0.2, 0.5]])
    quo = acc_mod._gains(a2, np.array([1.0, 1.0]), np.array([[0.0, 1.0]]), np.zeros(1))
    assert quo["effect"] == "persistent" or quo["dc_gain"] is None
    assert acc_mod._gains(a, rng.standard_normal(3), c, np.zeros(2))["effect"] == "persistent"


def test_ltz_law_is_the_noncentral_chi2_for_equal_weights() -> None:
    for dof, lam, x in ((2, 3.0, 9.0), (5, 0.5, 12.0), (1, 10.0, 7.0)):
        c = [dof + k * lam for k in range(1, 5)]
        assert acc_mod._ltz_sf(x, c) == pytest.approx(float(scipy.stats.ncx2.sf(x, dof, lam)), rel=1e-9)


def test_motor_account_sensor_effects_and_sizes(motor) -> None:
    _, gf = motor
    a = gf.account
    assert a is not None and a["format"] == 1
    by = {e["name"]: e for e in a["faults"]}
    assert by["i_meas"]["effect"] == by["w_meas"]["effect"] == "persistent"
    # the angle sensor's bias looks like a constant load torque, which every observer decouples: onset only
    assert by["theta_meas"]["effect"] == "transient" and by["theta_meas"]["size"] is None
    assert by["i_meas"]["seen_by"] == ["g0_i_meas_theta_meas"]
    # the design's own figure, sqrt(J_th / gᵀWg) (the bias whose mean crosses the threshold), lies between the 50 % and 95 % sizes
    mdb = gf.certificate["bank"]["info"]["min_detectable_bias"]["g0_i_meas_theta_meas"]["i_meas"]
    assert by["i_meas"]["size_50"] < by["i_meas"]["size"]
    assert 0.8 * by["i_meas"]["size_50"] < mdb < by["i_meas"]["size"]
    assert a["classes"]["groups"] == [] and [c["name"] for c in a["classes"]["decision"]] == list(gf.faults)
    assert fault_account(gf) == dict(a)  # the stored block, without a plant


def _simulate_chi2(gf, gen_index: int, sensor: int, size: float, runs: int, samples: int, seed: int) -> np.ndarray:
    """J of statistic ``gen_index`` at the last of ``samples`` steps of ``runs`` seeded runs of the design model with
    its noise, a bias ``size`` on output ``sensor`` from the start (generators started at rest)."""
    pl = gf.plant
    gen, ev = gf.generators[gen_index], gf.evaluators[gen_index]
    rng = np.random.default_rng(seed)
    n, p = pl["A"].shape[0], pl["C"].shape[0]
    lw, lv = np.linalg.cholesky(pl["Q"] + 1e-30 * np.eye(n)), np.linalg.cholesky(pl["R"])
    x, xi = np.zeros((runs, n)), np.zeros((runs, gen.n_state))
    bias = np.zeros(p)
    bias[sensor] = size
    for _ in range(samples):
        y = x @ pl["C"].T + rng.standard_normal((runs, p)) @ lv.T + bias
        r = xi @ gen.Cr.T + y @ gen.Dy.T
        xi = xi @ gen.Ar.T + y @ gen.By.T
        x = x @ pl["A"].T + rng.standard_normal((runs, n)) @ lw.T
    return np.einsum("ki,ij,kj->k", r, ev.W, r)


def test_smallest_size_is_detected_95_and_50_percent_in_simulation(motor) -> None:
    _, gf = motor
    e = next(f for f in gf.account["faults"] if f["name"] == "w_meas")
    g = [i for i, gen in enumerate(gf.generators) if gen.name == e["size_by"].removeprefix("J_")][0]
    rho = max(abs(np.linalg.eigvals(gf.generators[g].Ar)))
    samples = int(math.ceil(math.log(1e-6) / math.log(rho)))
    runs = 1500
    for size, p in ((e["size"], 0.95), (e["size_50"], 0.5)):
        hit = float(np.mean(_simulate_chi2(gf, g, gf.outputs.index("w_meas"), size, runs, samples, seed=11) > gf.evaluators[g].threshold))
        sd = math.sqrt(p * (1 - p) / runs)
        assert abs(hit - p) <= 4 * sd, (size, p, hit)


def test_component_faults_need_the_design_model(motor) -> None:
    prob, gf = motor
    from fdisyn.models.linear import LinearPlant

    plant = LinearPlant.create(
        A=gf.plant["A"], B=gf.plant["B"], C=gf.plant["C"], D=gf.plant["D"], E=gf.plant["E"], Q=gf.plant["Q"], R=gf.plant["R"],
        Fx=np.column_stack([gf.plant["E"][:, 0], gf.plant["B"][:, 0]]), Ts=gf.Ts, outputs=gf.outputs, inputs=gf.inputs,
        component_faults=("load_like", "actuator"),
    )
    a = fault_account(gf, plant)
    by = {e["name"]: e for e in a["faults"]}
    assert by["load_like"]["effect"] == "zero"  # in the direction of the decoupled unknown input
    assert by["actuator"]["effect"] == "persistent" and by["actuator"]["size"] > 0
    assert "load_like" in a["classes"]["unseen"]
    other = replace(plant, A=0.5 * plant.A)
    b = fault_account(gf, other)
    assert [e["type"] for e in b["faults"]] == ["sensor"] * 3 and "not the design model" in b["notes"][0]
    with pytest.raises(ArgumentError, match="must be a GainFile"):
        fault_account({"kind": "linear"})


def test_merged_classes_are_named_with_the_reason() -> None:
    gf = read_gain_file(REPORTS / "sampled_data_example" / "gains" / "sampled_data_example_direct.json")
    a = fault_account(gf)
    assert a["classes"]["groups"] == [{"faults": ["y1", "y2", "f"], "reason": "'y1', 'y2', 'f': all seen persistently by the same generators (direct)"}]


def test_gain_file_block_round_trip_hash_and_validation(motor, tmp_path: Path) -> None:
    _, gf = motor
    doc = gf.to_dict()
    back = gain_file_from_dict(json.loads(json.dumps(doc)))
    assert back.account == json.loads(json.dumps(doc["account"])) and gain_file_sha256(back) == gain_file_sha256(gf)
    bare = replace(gf, account=None)
    assert "account" not in bare.to_dict() and gain_file_sha256(bare) != gain_file_sha256(gf)
    # a file written before the block existed (a committed one with the block taken out) reads without one and
    # hashes as its bytes' canonical JSON
    old = tmp_path / "old.json"
    doc_old = json.loads((REPORTS / "wind_turbine" / "gains" / "wind_turbine_kalman_uio.json").read_text())
    doc_old.pop("account")
    old.write_text(json.dumps(doc_old, indent=1))
    g_old = read_gain_file(old)
    canon = json.dumps(json.loads(old.read_text()), sort_keys=True, separators=(",", ":"), ensure_ascii=True)
    import hashlib

    assert g_old.account is None and gain_file_sha256(g_old) == hashlib.sha256(canon.encode()).hexdigest()
    for edit, field in (
        (lambda d: d["account"]["faults"][0].update(effect="maybe"), "faults[0].effect"),
        (lambda d: d["account"]["faults"][1].update(size=-1.0), "faults[1].size"),
        (lambda d: d["account"].update(format=2), "account.format"),
        (lambda d: d["account"]["faults"][0].update(type="sensor", name="nowhere"), "faults[0].type"),
        (lambda d: d["account"]["classes"]["groups"].append({"faults": ["i_meas", "zz"], "reason": "x"}), "groups[0].faults"),
        (lambda d: d["account"]["faults"][0]["generators"]["g0_i_meas_theta_meas"].update(dc_gain="1"), "dc_gain"),
    ):
        d = json.loads(json.dumps(doc))
        edit(d)
        with pytest.raises(GainFileError, match=field.replace("[", r"\[").replace("]", r"\]")):
            gain_file_from_dict(d)


def test_nafdf_is_not_accounted_and_says_why() -> None:
    gf = read_gain_file(REPORTS / "ship_propulsion" / "gains" / "ship_propulsion_nafdf.json")
    assert with_account(gf) is gf and fault_account(gf) is None
    (line,) = account_lines(None, get_kind("nafdf").account_note)
    assert "not computed" in line and "nonlinear" in line


def test_beard_filter_account_with_its_plant() -> None:
    from fdisyn.problems.satellite_pitch import PROBLEM

    gf = read_gain_file(REPORTS / "satellite_pitch" / "gains" / "satellite_pitch_plain.json")
    a = fault_account(gf, PROBLEM.model(**PROBLEM.options))
    by = {e["name"]: e for e in a["faults"]}
    assert by["pitch_wheel"]["type"] == "component" and by["pitch_wheel"]["effect"] == "persistent"
    assert by["theta_m"]["unit"] == "rad" and by["theta_m"]["size"] > 0
    assert [g["faults"] for g in a["classes"]["groups"]] == [["pitch_wheel", "array_drive"]]


def test_design_command_prints_the_account(motor, tmp_path: Path, capsys) -> None:
    from fdisyn.app.cli import main
    from fdisyn.app.examples import example_path

    spec = tmp_path / "m.toml"
    spec.write_text(example_path("dc_motor").read_text(encoding="utf-8"), encoding="utf-8")
    assert main(["design", str(spec), "--out", str(tmp_path / "m")]) == 0
    out = capsys.readouterr().out
    assert "what the design can see" in out
    assert any(line.split()[:3] == ["theta_meas", "(sensor)", "transient"] for line in out.splitlines())
    assert "(A)" in out and "(rad/s)" in out  # the plant file's [signals].units
    assert read_gain_file(tmp_path / "m" / "gains.json").account is not None


def test_public_api_exports_fault_account() -> None:
    import fdisyn

    assert fdisyn.fault_account is fault_account and "fault_account" in dir(fdisyn)


def test_report_shows_the_account_folded_beside_the_certificate(motor) -> None:
    from fdisyn.reporting.certificates import _certificate_html

    prob, gf = motor
    page = _certificate_html(gf, prob)
    assert "<summary>What the design can see</summary>" in page
    assert "none at steady state" in page and "(rad/s)" in page
    nafdf = read_gain_file(REPORTS / "ship_propulsion" / "gains" / "ship_propulsion_nafdf.json")
    assert "What the design can see: not computed" in _certificate_html(nafdf)
    assert "What the design can see" not in _certificate_html(replace(gf, account=None), prob)


def test_a_transfer_that_cannot_be_evaluated_is_said_not_fatal(motor, monkeypatch) -> None:
    _, gf = motor

    def broken(*_args: object) -> dict:
        raise np.linalg.LinAlgError("Singular matrix")

    monkeypatch.setattr(acc_mod, "_gains", broken)
    a = with_account(gf).account
    assert a["faults"] == [] and any("could not be evaluated" in n for n in a["notes"])
    monkeypatch.setattr(kind_acc, "fault_account", lambda *_: (_ for _ in ()).throw(ValueError("bad")))
    b = with_account(gf).account
    assert b["faults"] == [] and b["notes"] == ["not computed: ValueError: bad"]
    assert "not computed" in "\n".join(account_lines(b))
