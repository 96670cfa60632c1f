"""The command line end to end, in-process (``fdisyn.app.cli.main``)."""

from __future__ import annotations

import argparse
import json
import subprocess
from pathlib import Path

import fdisyn
import numpy as np
import pytest
from fdisyn.app.cli import _parser, main
from fdisyn.app.examples import EXAMPLES
from fdisyn.runtime.compiled import library_suffix
from fdisyn.runtime.gainfile import read_gain_file

DATA = EXAMPLES


def test_built_in_problem_design_codegen_simulate_replay(tmp_path, capsys):
    d = tmp_path / "wt"
    assert main(["design", "wind_turbine", "--out", str(d)]) == 0
    gf = read_gain_file(d / "gains.json")
    assert gf.name == "wind_turbine_kalman_uio" and gf.design == "kalman_uio"
    assert main(["codegen", str(d)]) == 0
    for rel in ("c/wind_turbine_kalman_uio.h", "c/wind_turbine_kalman_uio.c", "c/tools/replay.c", f"libwind_turbine_kalman_uio{library_suffix()}", "replay"):
        assert (d / rel).exists(), rel
    trace = tmp_path / "trace.csv"
    assert main(["simulate", "wind_turbine", "--scenario", "benchmark_stuck", "--seed", "7", "--out", str(trace)]) == 0
    header = trace.read_text().splitlines()[0].split(",")
    assert header[:6] == ["t", "tau_g", "omega_r_m1", "omega_r_m2", "omega_g_m1", "omega_g_m2"]
    assert "fault_active" in header and "tau_r" in header
    assert main(["replay", str(d), str(trace), str(tmp_path / "py.csv")]) == 0
    subprocess.run([str(d / "replay"), str(trace), str(tmp_path / "c.csv")], check=True, capture_output=True)
    assert (tmp_path / "py.csv").read_bytes() == (tmp_path / "c.csv").read_bytes()
    out = np.genfromtxt(tmp_path / "py.csv", delimiter=",", names=True)
    active = out["t"] >= 100.0
    assert np.mean(out["isolated"][active & (out["t"] < 200)] == gf.faults.index("omega_r_m1")) > 0.9


@pytest.mark.parametrize("design", ["kalman_uio_paper", "uio_pole_placement"])
def test_other_designs_by_name(tmp_path, design):
    assert main(["design", "wind_turbine", "--design", design, "--out", str(tmp_path)]) == 0
    assert read_gain_file(tmp_path / "gains.json").design == design


def test_problem_options(tmp_path):
    assert main(["design", "wind_turbine", "--out", str(tmp_path), "--option", "parameters=paper", "--option", "P_f=0.001"]) == 0
    gf = read_gain_file(tmp_path / "gains.json")
    assert gf.name == "wind_turbine_paper_kalman_uio" and gf.evaluators[0].P_f == 0.001


def test_evaluate_writes_metrics(tmp_path):
    out = tmp_path / "m.json"
    assert main(["evaluate", "wind_turbine", "--design", "kalman_uio", "--runs", "2", "--out", str(out), "--workdir", str(tmp_path / "b")]) == 0
    doc = json.loads(out.read_text())
    m = doc["designs"]["kalman_uio"]["benchmark_stuck"]
    for key in ("false_alarm_rate", "missed_detection_rate", "detection_delay_mean_s", "detection_delay_max_samples", "isolation_accuracy"):
        assert key in m
    assert m["missed_detection_rate"] == 0.0 and doc["runs"] == 2


def test_toml_plant_through_the_whole_pipeline(tmp_path):
    spec = str(DATA / "dc_motor.toml")
    d = tmp_path / "motor"
    assert main(["design", spec, "--out", str(d)]) == 0
    gf = read_gain_file(d / "gains.json")
    assert gf.name == "dc_motor_kalman_uio" and gf.outputs == ("i_meas", "w_meas", "theta_meas")
    assert set(gf.faults) == {"i_meas", "w_meas", "theta_meas"}  # a bank of pairs tells every sensor apart
    assert main(["codegen", str(d)]) == 0
    trace = tmp_path / "t.csv"
    assert main(["simulate", spec, "--scenario", "speed_sensor_offset", "--seed", "1", "--out", str(trace)]) == 0
    assert main(["replay", str(d), str(trace), str(tmp_path / "o.csv")]) == 0
    out = np.genfromtxt(tmp_path / "o.csv", delimiter=",", names=True)
    late = out["t"] > 5.5
    assert np.mean(out["isolated"][late] == gf.faults.index("w_meas")) > 0.9
    quiet = (out["t"] > 1.0) & (out["t"] < 5.0)  # after the switch-on at 0.5 s, before the fault
    assert np.mean(out["alarm"][quiet]) < 0.002  # 2 statistics at P_f = 1e-4: ~2e-4 expected


def test_bad_toml_key_is_named(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text((DATA / "dc_motor.toml").read_text().replace("method =", "metod ="))
    assert main(["design", str(bad), "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert "unknown key(s) ['metod']" in err and "[design]" in err


def test_toml_rank_condition_failure_is_reported(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    text = (DATA / "dc_motor.toml").read_text().replace('E = [[0.0], [-1000.0], [0.0]]', 'E = [[0.0], [0.0], [0.0]]')
    bad.write_text(text)
    assert main(["design", str(bad), "--out", str(tmp_path / "x")]) == 2
    assert "rank(E) = 0 but E has q = 1" in capsys.readouterr().err


def test_unknown_problem_lists_the_problems(capsys):
    assert main(["design", "windturbine", "--out", "/nonexistent"]) == 2
    err = capsys.readouterr().err
    assert "no built-in problem 'windturbine'; problems: [" in err and "'wind_turbine'" in err


def test_codegen_refuses_a_gain_file_of_another_version(built_copy, capsys):
    p = built_copy / "gains.json"  # as `fdisyn design wind_turbine` wrote it
    doc = json.loads(p.read_text())
    doc["format"] = "fdisyn.gains/7"
    p.write_text(json.dumps(doc))
    assert main(["codegen", str(built_copy)]) == 2
    assert "format version '7'" in capsys.readouterr().err


def test_replay_reports_a_missing_column(built_copy, tmp_path, capsys):
    # built_copy: what `fdisyn design wind_turbine` and `fdisyn codegen` leave (the session's build)
    p = tmp_path / "in.csv"
    p.write_text("t,tau_g,omega_r_m1\n0,1,1\n")
    assert main(["replay", str(built_copy), str(p), str(tmp_path / "o.csv")]) == 2
    assert "in.csv line 1: no column 'omega_r_m2' (output 1)" in capsys.readouterr().err


def _assert_exports_agree(metrics: dict, workdir: Path) -> None:
    """The export checks (a failed check raises, so ``passed`` is always true in a written report): every reference
    saw the same decisions within the tolerance, which is all the committed report keeps; the figures themselves,
    in the build folder, agree far inside it, measured ≤ 1.5e-14 (the motor) against EXPORT_TOL = 1e-12."""
    exports = [c for v in metrics["variants"] for c in v["exports"].values()]
    assert exports and all(c["samples"] == 10_000 and c["nonfinite_samples"] > 0 for c in exports)
    for c in exports:
        assert all(ref == {"decisions_equal": True, "within_tolerance": True} for ref in c["references"].values()), c
    figures = [json.loads(f.read_text()) for f in sorted(workdir.rglob("export_check.json"))]
    assert len(figures) == len(exports)
    for c in figures:
        for ref in c["references"].values():
            assert ref["decisions_equal"] and max(ref["r"], ref["J"], ref["state"]) <= 1e-13, c


def test_reproduce_end_to_end(tmp_path):
    # the main job, with one Monte Carlo run per scenario and three of its report variants to keep the suite short
    three = "default,paper parameter set,GLR at arl0 = 60 s"
    args = ["--runs", "1", "--variants", three, "--reports", str(tmp_path / "r"), "--workdir", str(tmp_path / "b")]
    assert main(["reproduce", "wind_turbine", *args]) == 0
    page = tmp_path / "r" / "wind_turbine" / "index.html"
    text = page.read_text()
    for fig in ("fig1_residuals_benchmark.png", "fig2_paper_F1_benchmark.png", "fig3_paper_F2_benchmark.png"):
        assert fig in text and (page.parent / fig).exists()
    metrics = json.loads((page.parent / "metrics.json").read_text())
    assert [v["label"] for v in metrics["variants"]] == ["default", "paper parameter set", "GLR at arl0 = 60 s"]
    assert "Detectors at one false-alarm budget" not in text  # one variant with arl0: nothing to compare
    assert "False-alarm budget and the Lorden bound" in text
    _assert_exports_agree(metrics, tmp_path / "b" / "wind_turbine")
    assert (page.parent / "gains" / "wind_turbine_kalman_uio.json").exists()


def test_reproduce_refuses_an_unknown_variant(tmp_path, capsys):
    assert main(["reproduce", "wind_turbine", "--variants", "default,nope", "--reports", str(tmp_path / "r"), "--workdir", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err
    assert "has no report variant(s) ['nope']" in err and err.count("\n") == 1


def test_reproduce_plant_files(tmp_path):
    """Both kinds of plant file through the main job: the export check passes (the motor's
    residuals are small differences of an integrating angle, compared against their terms) and
    a problem without its own report hook gets a figure per design and scenario."""
    specs = [str(DATA / "dc_motor.toml"), str(DATA / "ship.toml")]
    assert main(["reproduce", *specs, "--runs", "2", "--reports", str(tmp_path / "r"), "--workdir", str(tmp_path / "b")]) == 0
    for name, design, scenarios in (("dc_motor", "kalman_uio", ("fault_free", "speed_sensor_offset")), ("ship", "nafdf", ("a_half", "both"))):
        page = tmp_path / "r" / name / "index.html"
        metrics = json.loads((page.parent / "metrics.json").read_text())
        _assert_exports_agree(metrics, tmp_path / "b" / name)
        for sc in scenarios:
            assert f"{design}_{sc}.png" in page.read_text() and (page.parent / f"{design}_{sc}.png").exists()
    ship = json.loads((tmp_path / "r" / "ship" / "metrics.json").read_text())["variants"][0]["evaluation"]["designs"]["nafdf"]
    assert ship["a_half"]["missed_detection_rate"] == 0.0 and ship["a_half"]["isolation_accuracy"] == 1.0
    assert set(ship["both"]["extra"]) >= {"all parameter classes correct", "size error a: mean", "size error b: mean"}


def _commands() -> dict[str, argparse.ArgumentParser]:
    sub = next(a for a in _parser()._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def test_version(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out == f"fdisyn {fdisyn.__version__}\n"


@pytest.mark.parametrize("command", sorted(_commands()))
def test_every_command_help_describes_every_argument_and_shows_examples(command, capsys):
    assert main([command, "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "Example" in text
    for action in _commands()[command]._actions:
        assert action.help and action.help != argparse.SUPPRESS, (command, action.dest)
        assert " ".join(action.help.split()) in text, (command, action.dest)
    examples = text.split("Example", 1)[1]
    assert f"fdisyn {command}" in examples
