"""The Beard filter designed from a plant file (the example ``beard_textbook``): the detection spaces against
their closed form (Massoumnia, IEEE TAC 31(9), 1986: ``dim T = ν + z``), the assigned spectrum, Beard's invariance
in a noise-free simulation of the plant and the filter, the robust cones (He, Zhang & Wu, Journal of Astronautics,
c. 1999), the Monte Carlo, and the errors a plant file can make."""

from __future__ import annotations

import copy
import tomllib
from pathlib import Path
from typing import Any

import control
import numpy as np
import pytest
from fdisyn.app.cli import main
from fdisyn.app.examples import EXAMPLES
from fdisyn.simulation.plant_file import load_spec, problem_from_document
from fdisyn.evaluation.built import build
from fdisyn.evaluation.evaluate import evaluate
from fdisyn.models.linear import LinearPlant
from fdisyn.numerics.robust_cones import subspace_angle
from fdisyn.runtime.errors import FdisynError
from fdisyn.runtime.gainfile import GainFile
from fdisyn.synthesis.beard_fdf.payload import beard_from_gain_file
from fdisyn.synthesis.beard_fdf.reference import beard_reference_run
from fdisyn.synthesis.registry import get_method

ROOT = Path(__file__).parents[2]
TEXTBOOK = EXAMPLES / "beard_textbook.toml"
DOC = tomllib.loads(TEXTBOOK.read_text(encoding="utf-8"))
TS = DOC["model"]["Ts"]


def _file(tmp_path: Path, name: str = "variant", **changes: dict[str, Any]) -> Path:
    """The textbook file with some keys of some sections replaced (a value None removes the key), written out."""
    doc = copy.deepcopy(DOC)
    for section, keys in changes.items():
        for key, value in keys.items():
            if value is None:
                doc[section].pop(key, None)
            else:
                doc[section][key] = value
    path = tmp_path / f"{name}.toml"
    path.write_text(_toml(doc), encoding="utf-8")
    return path


def _toml(doc: dict[str, Any]) -> str:
    def value(v: Any) -> str:
        if isinstance(v, str):
            return f'"{v}"'
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, dict):
            return "{ " + ", ".join(f"{k} = {value(x)}" for k, x in v.items()) + " }"
        if isinstance(v, list):
            return "[" + ", ".join(value(x) for x in v) + "]"
        return repr(v)

    lines = [f"{k} = {value(v)}" for k, v in doc.items() if not isinstance(v, (dict, list))]
    for k, v in doc.items():
        if isinstance(v, dict):
            lines += [f"[{k}]", *(f"{kk} = {value(vv)}" for kk, vv in v.items())]
    for sc in doc.get("scenarios", []):
        lines += ["[[scenarios]]", *(f"{kk} = {value(vv)}" for kk, vv in sc.items())]
    return "\n".join(lines) + "\n"


def _continuous_plant() -> LinearPlant:
    m, s = DOC["model"], DOC["signals"]
    return LinearPlant.create(
        A=m["A"], B=m["B"], C=m["C"], Fx=m["Fx"], Q=m["Q_intensity"], R=m["R"], states=s["states"], inputs=s["inputs"],
        outputs=s["outputs"], component_faults=s["component_faults"],
    )


def _info(gf: GainFile) -> dict[str, Any]:
    return gf.certificate["beard_fdf"]["info"]


def _checks(gf: GainFile) -> dict[str, dict[str, Any]]:
    return {c["name"]: c for c in gf.certificate["beard_fdf"]["checks"]}


@pytest.fixture(scope="module")
def optimised() -> GainFile:
    return load_spec(TEXTBOOK).design()


# --------------------------------------------------------------------------- the file designs


def test_the_method_samples_a_continuous_plant_itself() -> None:
    assert get_method("beard_fdf").samples_itself
    assert not get_method("kalman_uio").samples_itself


def test_the_textbook_file_designs_optimised(optimised: GainFile) -> None:
    assert optimised.kind == "beard_fdf" and optimised.name == "beard_textbook_beard_fdf"
    assert optimised.faults == ("f_push", "f_act")  # the component faults, as the scenarios name them
    assert {sc.fault for sc in load_spec(TEXTBOOK).scenarios.values()} == {None, "f_push", "f_act"}
    assert optimised.Ts == TS and optimised.certificate["passed"]
    info = _info(optimised)
    assert info["eigenstructure"] == "optimised" and info["cones"]["overlapping_pairs"] == []
    assert all(0 < y < 0.01 for y in optimised.extensions["beard_fdf"]["Y_th"])


def test_the_textbook_file_designs_plain(tmp_path: Path) -> None:
    gf = load_spec(_file(tmp_path, design={"eigenstructure": "plain"})).design()
    info = _info(gf)
    assert info["eigenstructure"] == "plain" and gf.certificate["passed"]
    # every eigenvalue at the decay bound as often as its block's outputs allow (f_push's plane is seen through one
    # output: its second eigenvalue 0.02 below), so the blocks share it: the cones are half-spaces (detection, no isolation)
    r = np.exp(-DOC["design"]["decay_rate"] * TS)
    np.testing.assert_allclose(np.sort(np.hypot(*np.asarray(info["eigenvalues_z"]).T)), [r - 0.02, r, r], atol=1e-9)
    assert gf.extensions["beard_fdf"]["Y_th"] == [np.pi / 2, np.pi / 2]


def test_a_discrete_plant_file_designs(tmp_path: Path) -> None:
    pd = _continuous_plant().discretise(TS)
    path = _file(tmp_path, model={"time": "discrete", "A": np.asarray(pd.A).tolist(), "Fx": np.asarray(pd.Fx).tolist(),
                                  "B": np.asarray(pd.B).tolist(), "Q_intensity": None, "Q_sample": np.asarray(pd.Q).tolist()},
                 design={"sigma": 0.0})
    gf = load_spec(path).design()
    assert gf.faults == ("f_push", "f_act") and _info(gf)["detection_space_dims"] == [2, 1]
    np.testing.assert_allclose(beard_from_gain_file(gf).A, pd.A, atol=1e-14)


# --------------------------------------------------------------------------- geometry and spectrum


def _closed_form_dim(a: np.ndarray, c: np.ndarray, f: np.ndarray, dt: float | None) -> int:
    """``ν + z``: the relative degree (first ``j`` with ``C A^{j−1} f ≠ 0``) plus the invariant zeros of ``(A, f, C)``."""
    nu = next(j for j in range(1, a.shape[0] + 1) if np.linalg.norm(c @ np.linalg.matrix_power(a, j - 1) @ f) > 1e-12)
    sys = control.ss(a, f, c, np.zeros((c.shape[0], 1)), dt) if dt is not None else control.ss(a, f, c, np.zeros((c.shape[0], 1)))
    return nu + len(sys.zeros())


def test_the_detection_spaces_are_the_closed_form(optimised: GainFile) -> None:
    assert _info(optimised)["detection_space_dims"] == [2, 1]
    plant = _continuous_plant()
    a, c, fx = np.asarray(plant.A), np.asarray(plant.C), np.asarray(plant.Fx)
    # continuous: f_push has ν = 2 (C f = 0), f_act ν = 1, neither an invariant zero
    assert [_closed_form_dim(a, c, fx[:, [i]], None) for i in range(2)] == [2, 1]
    # sampled: f_push_d has ν = 1 and the sampling zero near −1 of a relative-degree-2 system (Åström, Hagander & Sternby 1984)
    pd = plant.discretise(TS)
    ad, fd = np.asarray(pd.A), np.asarray(pd.Fx)
    assert [_closed_form_dim(ad, c, fd[:, [i]], TS) for i in range(2)] == [2, 1]
    zero = control.ss(ad, fd[:, [0]], c, np.zeros((2, 1)), TS).zeros()
    assert zero.size == 1 and abs(zero[0] + 1) < 1e-2


def test_the_eigenvalues_are_the_assigned_ones(tmp_path: Path) -> None:
    s_plane = [[-0.5, -1.0], [-2.0], []]
    gf = load_spec(_file(tmp_path, design={"eigenvalues": s_plane, "decay_rate": None})).design()
    flt = beard_from_gain_file(gf)
    got = np.sort_complex(np.linalg.eigvals(flt.A - flt.L @ flt.C))
    want = np.sort_complex(np.exp(TS * np.array([-0.5, -1.0, -2.0], dtype=complex)))
    np.testing.assert_allclose(got, want, atol=1e-8)
    assert _info(gf)["eigenstructure"] == "assigned"


def test_the_residual_of_each_fault_stays_in_its_subspace(optimised: GainFile) -> None:
    """Noise-free: the continuous plant sampled exactly, driven by an input and a random held fault, and the filter on
    its measured outputs (not the error recursion)."""
    flt = beard_from_gain_file(optimised)
    pd = _continuous_plant().discretise(TS)
    ad, bd, c, fd = (np.asarray(v) for v in (pd.A, pd.B, pd.C, pd.Fx))
    rng = np.random.default_rng(3)
    steps, onset, settled = 900, 100, 700  # ‖G^600‖ ≈ 0.819^600: the start's error is gone
    for i in range(2):
        u = 0.01 * rng.standard_normal((steps, 1))
        mu = np.zeros(steps)
        mu[onset:] = np.repeat(rng.standard_normal((steps - onset) // 20 + 1), 20)[: steps - onset]
        x, y = np.zeros(3), np.zeros((steps, 2))
        for k in range(steps):
            y[k] = c @ x
            x = ad @ x + bd @ u[k] + fd[:, i] * mu[k]
        r = beard_reference_run(flt, u, y).r
        assert np.linalg.norm(r[settled:], axis=1).min() > 1e-4  # the fault is seen
        worst = max(subspace_angle(r[k], flt.axes[i]) for k in range(settled, steps))
        assert worst <= 1e-8, (optimised.faults[i], worst)


def test_the_certificate_checks_the_bound_by_sampling(optimised: GainFile) -> None:
    check = _checks(optimised)["largest sampled residual-direction angle / Y_th"]
    assert check["passed"] and 0 < check["value"] <= 1.0
    info = _info(optimised)
    assert all(0 < s <= y for s, y in zip(info["sampled_angle_deg"], info["Y_th_deg"], strict=True))


def test_a_large_sigma_designs_and_names_the_overlapping_cones(tmp_path: Path) -> None:
    gf = load_spec(_file(tmp_path, design={"sigma": 10.0})).design()
    info = _info(gf)
    assert gf.certificate["passed"] and gf.extensions["beard_fdf"]["Y_th"] == [np.pi / 2, np.pi / 2]
    assert info["cones"]["overlapping_pairs"] == [[0, 1]]
    assert "f_push and f_act overlap" in info["overlap"]


# --------------------------------------------------------------------------- the Monte Carlo


def test_the_monte_carlo_completes(tmp_path: Path) -> None:
    prob = load_spec(TEXTBOOK)
    built = build(prob, prob.default_design, tmp_path / "beard_fdf")
    ev = evaluate(prob, {prob.default_design: built}, runs=5)
    metrics = ev.metrics[prob.default_design]
    assert set(metrics) == {"fault_free", "push", "actuator"}
    for sname in ("push", "actuator"):
        assert metrics[sname].missed_detection_rate == 0.0 and metrics[sname].isolation_accuracy == 1.0, sname


# --------------------------------------------------------------------------- errors: one line, the condition named


def _refused(path: Path, capsys: pytest.CaptureFixture[str]) -> str:
    assert main(["design", str(path), "--out", str(path.parent / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    return err


def test_a_fault_in_the_unobservable_subspace_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # only the actuator is measured: the mass (and f_push on it) never reaches an output
    path = _file(tmp_path, model={"C": [[0.0, 0.0, 1.0], [0.0, 0.0, 2.0]]})
    err = _refused(path, capsys)
    assert "unobservable subspace" in err and "1 = 'f_push'" in err
    with pytest.raises(FdisynError, match="unobservable subspace"):
        load_spec(path).design()


def test_faults_with_one_output_direction_are_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # both faults push the position: one residual direction for two faults
    path = _file(tmp_path, model={"Fx": [[1.0, 2.0], [0.0, 0.0], [0.0, 0.0]]})
    err = _refused(path, capsys)
    assert "not output separable" in err and "'f_act'" in err


@pytest.mark.parametrize(
    ("design", "message"),
    [
        ({"decay_rate": None}, "give decay_rate"),
        ({"eigenvalues": [[-1.0], [-2.0]], "decay_rate": None}, "[design].eigenvalues: expected 3 lists of lengths [2, 1, 0]"),
        ({"sensor_faults": ["y_vel"]}, "[design].sensor_faults: ['y_vel'] are not outputs"),
        ({"sigma": -1.0}, "[design].sigma = -1.0: expected a number ≥ 0"),
        ({"Ts": 0.2}, "[design]: unknown key(s) ['Ts']"),
    ],
)
def test_bad_design_keys_are_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str], design: dict[str, Any], message: str) -> None:
    assert message in _refused(_file(tmp_path, design=design), capsys)


def test_a_sensor_fault_is_isolated_by_name(tmp_path: Path) -> None:
    # f_act and a position-sensor fault: the sensor fault's plane [f_s, A f_s] (f_s = e_pos) reaches y_pos only
    path = _file(
        tmp_path,
        model={"Fx": [[0.0], [0.0], [1.0]]},
        signals={"component_faults": ["f_act"]},
        # the sensor fault's plane holds the position mode: eigenvalues assigned apart (s-plane, 1/s)
        design={"sensor_faults": ["y_pos"], "eigenvalues": [[-2.0], [-0.5, -1.0], []], "decay_rate": None},
    )
    doc = tomllib.loads(path.read_text(encoding="utf-8"))
    doc["scenarios"] = [
        {"name": "pos_offset", "duration": 40.0, "fault": "y_pos", "onset": 20.0,
         "sensor_faults": [{"sensor": "y_pos", "kind": "offset", "value": 0.5}]},
        DOC["scenarios"][1],
    ]
    prob = problem_from_document(doc, path)
    gf = prob.design()
    assert gf.faults == ("f_act", "y_pos")
    batch = prob.run("pos_offset", [0])
    out = beard_reference_run(beard_from_gain_file(gf), batch.U[0], batch.Y[0])
    # the filter absorbs a constant offset once its error settles: the fault shows (and is isolated) in between
    after = out.isolated[200:]
    assert np.sum(after == gf.faults.index("y_pos")) >= 10 and set(after[after >= 0].tolist()) == {gf.faults.index("y_pos")}


def test_without_h_and_explicit_level_the_thresholds_come_from_the_law(tmp_path: Path, optimised: GainFile) -> None:
    gf = load_spec(_file(tmp_path, design={"h": None, "explicit_level": None})).design()
    info, ext = _info(gf), gf.extensions["beard_fdf"]
    assert info["levels_from"] == "the law of the residual under the design noise (Q, R)"
    # the file's values are the quantiles over fault-free runs, which the law under the same noise should be near
    given = optimised.extensions["beard_fdf"]
    assert 0.5 < ext["h"] / given["h"] < 2 and 0.5 < ext["explicit_level"] / given["explicit_level"] < 2
    assert ext["thresholds"][:2] == [ext["h"], 1.0]
