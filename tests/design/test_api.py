"""The public Python API (``fdisyn.design``, ``export``, ``load``, ``methods``; ``LinearPlant.from_control``
and ``to_control``; ``Generator.to_control``) and the error classes it raises."""

from __future__ import annotations

from pathlib import Path

import control
import fdisyn
import numpy as np
import pytest
from fdisyn.app.examples import EXAMPLES
from fdisyn.simulation.plant_file import load_spec
from fdisyn.runtime.compiled import library_suffix
from fdisyn.runtime.errors import ArgumentError, BuildError, ExistenceError, FileError, GainFileError, ShapeError
from fdisyn.runtime.gainfile import read_gain_file, write_gain_file
from fdisyn.runtime.reference import LinearReference
from fdisyn.runtime.warmup import PINV_RTOL
from fdisyn.synthesis.uio import kalman_uio

DATA = EXAMPLES

# The README's DC motor (the example dc_motor): states current, speed, angle; load torque unknown
A = np.array([[-100.0, -5.0, 0.0], [50.0, -0.1, 0.0], [0.0, 1.0, 0.0]])
B = np.array([[100.0], [0.0], [0.0]])
E = np.array([[0.0], [-1000.0], [0.0]])
C = np.eye(3)
TS = 0.001


@pytest.fixture(scope="module")
def motor(motor_built):
    """The plant file's problem, its default design (the existing design path) and the session's folder of it:
    its ``gains.json`` and what ``fdisyn codegen`` built from it."""
    return load_spec(DATA / "dc_motor.toml"), motor_built.gain_file, motor_built.directory


# --------------------------------------------------------------------------- export and load


def test_export_writes_what_fdisyn_codegen_builds(motor, tmp_path) -> None:
    _, gf, d = motor
    assert fdisyn.export(gf, tmp_path) == tmp_path

    def files(root: Path) -> dict[str, bytes]:
        return {str(p.relative_to(root)): p.read_bytes() for p in root.rglob("*") if p.is_file()}

    ours, theirs = files(tmp_path), files(d)
    assert sorted(ours) == sorted(theirs)
    for rel in ours:  # the same gain file and C sources byte for byte (the binaries are gcc's)
        if rel == "gains.json" or rel.startswith("c/") and rel.endswith((".c", ".h")):
            assert ours[rel] == theirs[rel], rel
    assert read_gain_file(tmp_path / "gains.json").name == gf.name == "dc_motor_kalman_uio"


def test_load_runs_the_compiled_library_and_its_verdicts_name_alarm_and_fault(motor) -> None:
    prob, gf, d = motor
    mon = fdisyn.load(d)
    assert isinstance(mon, fdisyn.Monitor) and mon.backend == "compiled"
    batch = prob.run("speed_sensor_offset", [1])
    verdicts = [mon.update(u, y) for u, y in zip(batch.U[0], batch.Y[0], strict=True)]
    t = np.array([v.time for v in verdicts])
    alarm = np.array([v.alarm for v in verdicts])
    faults = [v.fault for v in verdicts]
    assert np.mean(alarm[(t > 1.0) & (t < 5.0)]) < 0.002  # P_f = 1e-4 per statistic before the fault
    late = [f for f, tt in zip(faults, t, strict=True) if tt > 5.5]
    assert late.count("w_meas") / len(late) > 0.9  # the speed-sensor offset, isolated
    ref = fdisyn.load(d, backend="reference").run(batch.U[0], batch.Y[0])
    assert np.array_equal(ref.alarm, alarm)


def test_load_and_export_refuse_with_the_error_classes(motor, tmp_path) -> None:
    _, gf, _ = motor
    with pytest.raises(FileError, match="no gain file at"):  # a missing file
        fdisyn.load(tmp_path / "nowhere")
    write_gain_file(gf, tmp_path / "only" / "gains.json")
    with pytest.raises(BuildError, match=rf"no compiled diagnoser at .*libdc_motor_kalman_uio{library_suffix()}; run `fdisyn codegen`"):
        fdisyn.load(tmp_path / "only")
    assert fdisyn.load(tmp_path / "only", backend="reference").backend == "reference"
    with pytest.raises(ArgumentError, match="backend must be"):
        fdisyn.load(tmp_path / "only", backend="gpu")  # type: ignore[arg-type]
    with pytest.raises(ArgumentError, match="gf must be a GainFile"):
        fdisyn.export(tmp_path / "only" / "gains.json", tmp_path / "x")  # type: ignore[arg-type]
    doc = (tmp_path / "only" / "gains.json").read_text().replace('"passed": true', '"passed": false', 1)
    (tmp_path / "only" / "gains.json").write_text(doc)
    with pytest.raises(GainFileError, match="passed"):
        fdisyn.load(tmp_path / "only", backend="reference")


# --------------------------------------------------------------------------- python-control


def test_generator_to_control_is_the_residual_generator(motor) -> None:
    """Simulated by python-control, each generator gives the residuals of the NumPy reference: over its warm-up from
    the equilibrium the runtime starts at, after it from that equilibrium less the initial error the warm-up's
    residuals give by weighted least squares (NumPy's ``lstsq`` on the stacked transient ``Cr Ar^k``)."""
    prob, gf, _ = motor
    batch = prob.run("speed_sensor_offset", [3])
    U, Y = batch.U[0][:300], batch.Y[0][:300]
    r_ref = LinearReference(gf).run(U, Y).r
    k = 0
    for i, g in enumerate(gf.generators):
        ss = g.to_control()
        assert isinstance(ss, control.StateSpace) and ss.dt == gf.Ts == TS
        assert (ss.ninputs, ss.noutputs, ss.nstates) == (gf.step.nu + gf.step.ny, g.n_residual, g.n_state)
        x0 = g.Xu @ U[0] + g.Xy @ Y[0]
        early = np.atleast_2d(control.forced_response(ss, U=np.hstack([U, Y]).T, X0=x0).outputs).T
        n = g.warmup
        assert n >= 1
        w = next(e.W for e in gf.evaluators if e.generator == i)
        lam, vec = np.linalg.eigh(w)
        root = np.sqrt(np.clip(lam, 0.0, None))[:, None] * vec.T  # rootᵀ root = W
        stacked = np.vstack([root @ g.Cr @ np.linalg.matrix_power(g.Ar, j) for j in range(n)])
        # the runtime leaves out the directions of Σ Φᵀ W Φ below PINV_RTOL of its largest: singular values of the
        # stacked transient below sqrt(PINV_RTOL) of its largest
        delta = np.linalg.lstsq(stacked, np.concatenate([root @ early[j] for j in range(n)]), rcond=np.sqrt(PINV_RTOL))[0]
        late = np.atleast_2d(control.forced_response(ss, U=np.hstack([U, Y]).T, X0=x0 - delta).outputs).T
        r = np.vstack([early[:n], late[n:]])
        assert np.allclose(r, r_ref[:, k : k + g.n_residual], rtol=1e-9, atol=1e-9 * np.max(np.abs(r)))
        k += g.n_residual
    assert k == gf.step.nr


def test_from_control_takes_the_last_columns_as_unknown_inputs() -> None:
    Q, R = np.diag([1e-7, 1e-6, 1e-10]), np.diag([1e-4, 2.5e-3, 1e-6])
    cont = control.ss(A, np.hstack([B, E]), C, 0)
    pc = fdisyn.LinearPlant.from_control(cont, n_unknown=1, Q=Q, R=R, inputs=["v"], unknown_inputs=["load"], outputs=["i", "w", "th"])
    assert pc.Ts is None and np.array_equal(pc.B, B) and np.array_equal(pc.E, E) and np.array_equal(pc.Q, Q)
    assert (pc.inputs, pc.unknown_inputs, pc.outputs, pc.states) == (("v",), ("load",), ("i", "w", "th"), ("x0", "x1", "x2"))
    disc = fdisyn.LinearPlant.from_control(control.c2d(cont, TS), n_unknown=1)
    exact = pc.discretise(TS)  # exact ZOH sampling of the same model
    assert disc.Ts == TS and np.allclose(disc.A, exact.A, atol=1e-12) and np.allclose(disc.E, exact.E, atol=1e-12)
    assert fdisyn.LinearPlant.from_control(cont).E.shape == (3, 0)  # n_unknown = 0: every input is known
    back = fdisyn.LinearPlant.from_control(pc.to_control(), n_unknown=pc.q, inputs=pc.inputs, unknown_inputs=pc.unknown_inputs, outputs=pc.outputs)
    assert np.array_equal(back.A, pc.A) and np.array_equal(back.E, pc.E) and back.Ts is None
    ss = exact.to_control()
    assert ss.dt == TS and ss.input_labels == ["v", "load"] and ss.output_labels == ["i", "w", "th"]


@pytest.mark.parametrize(
    ("make", "error", "match"),
    [
        (lambda: fdisyn.LinearPlant.from_control(control.tf([1], [1, 1])), ArgumentError, "sys must be a control.StateSpace; got TransferFunction"),
        (lambda: fdisyn.LinearPlant.from_control(control.ss(A, B, C, 0), n_unknown=2), ArgumentError, r"n_unknown must be a whole number in 0..1"),
        (lambda: fdisyn.LinearPlant.from_control(control.ss(A, B, C, 0), n_unknown=True), ArgumentError, "n_unknown"),
        (lambda: fdisyn.LinearPlant.from_control(control.ss(A, B, C, 0, dt=True), n_unknown=1), ArgumentError, "does not say the sample time"),
        # a non-finite Q is a wrong value (ArgumentError); a Q of the wrong size a ShapeError
        (lambda: fdisyn.LinearPlant.from_control(control.ss(A, B, C, 0), Q=np.diag([1.0, np.nan, 1.0])), ArgumentError, "Q contains a non-finite entry"),
        (lambda: fdisyn.LinearPlant.from_control(control.ss(A, B, C, 0), Q=np.eye(2)), ShapeError, r"Q has shape \(2, 2\); expected \(3, 3\)"),
        (lambda: fdisyn.LinearPlant.from_control(control.ss(A, B, C, 0), inputs=["a b"]), ArgumentError, "is not a signal name"),
    ],
)
def test_from_control_refuses_with_the_error_classes(make, error, match) -> None:
    with pytest.raises(error, match=match) as info:
        make()
    assert "\n" not in str(info.value)


# --------------------------------------------------------------------------- design through the API


def blind_plant() -> fdisyn.LinearPlant:
    """The sampled motor whose load torque reaches the speed only, watched by the current and angle
    sensors: ``C E = 0``, so no unknown-input observer exists (Hu et al. 2013, Acta Automatica Sinica
    39(8), eq. (3): ``rank(C E) = rank(E)``)."""
    sampled = control.c2d(control.ss(A, B, C, 0), TS)
    return fdisyn.LinearPlant.create(A=sampled.A, B=sampled.B, C=C[[0, 2]], E=[[0.0], [1.0], [0.0]], R=1e-4 * np.eye(2), Ts=TS)


def test_an_existence_failure_is_an_existence_error() -> None:
    with pytest.raises(ExistenceError, match=r"rank\(C E\)|rank\(E\)"):
        kalman_uio(blind_plant())


def test_design_through_the_registry_names_the_method(motor) -> None:
    pytest.importorskip("fdisyn.synthesis.registry", reason="fdisyn.design needs the method registry")
    _, gf, _ = motor
    plant = fdisyn.LinearPlant.from_control(control.c2d(control.ss(A, np.hstack([B, E]), C, 0), TS), n_unknown=1, Q=np.diag([1e-7, 1e-6, 1e-10]), R=np.diag([1e-4, 2.5e-3, 1e-6]))
    assert "kalman_uio" in fdisyn.methods()
    with pytest.raises(ArgumentError, match="nope"):
        fdisyn.design(plant, method="nope")
    with pytest.raises(ExistenceError):
        fdisyn.design(blind_plant(), method="kalman_uio")


def test_the_public_names() -> None:
    assert set(fdisyn.__all__) == {"__version__", "design", "export", "load", "methods", "fault_account", "LinearPlant", "NonlinearPlant", "SampledDataPlant", "GainFile", "Monitor",
                                  "structure_matrices", "analyse_structure", "check_structure", "analyse_gaps", "bank_performance",
                                  "problem", "simulate", "evaluate", "fault_size_sweep", "report", "plot_trace", "plot_laws", "plot_detection"}
    for name in fdisyn.__all__:
        assert getattr(fdisyn, name) is not None
    assert fdisyn.__version__[0].isdigit()  # the installed distribution's version (fdisyn --version prints it)


def test_from_control_keeps_the_unknown_inputs_feedthrough_and_the_observer_methods_refuse_it() -> None:
    """An unknown input that reaches the sensors directly is the plant's ``Dd``; the methods that assume it does not
    say so in one line and name the method that designs for it."""
    sys = control.ss(A, np.hstack([B, E]), C, np.hstack([np.zeros((3, 1)), np.ones((3, 1))]), dt=0.1)
    plant = fdisyn.LinearPlant.from_control(sys, n_unknown=1)
    assert np.array_equal(plant.Dd, np.ones((3, 1))) and plant.Df.shape == (3, 0)
    assert np.array_equal(plant.to_control().D, sys.D)
    with pytest.raises(ArgumentError, match=r"method 'kalman_uio' assumes unknown inputs and component faults reach the sensors only through the states, but the plant's Dd is nonzero: design it by method 'nullspace'"):
        fdisyn.design(plant, method="kalman_uio")
