"""Every path of the public API refuses bad-but-plausible input with one of fdisyn's own errors: one line naming
what is wrong and what was expected, solver wording (SciPy, LAPACK, IPOPT) only after fdisyn's explanation."""

from __future__ import annotations

import os

import numpy as np
import pytest

import fdisyn
from fdisyn.models.linear import LinearPlant
from fdisyn.runtime.errors import ArgumentError, BuildError, ExistenceError, FdisynError, FileError, GainFileError

A = np.array([[0.9, 0.1, 0.0], [0.0, 0.8, 0.1], [0.0, 0.0, 0.7]])
C = np.eye(3)[:2]
E = np.array([[0.0], [1.0], [0.0]])
SOLVERS = ("scipy", "lapack", "ipopt", "qz decomposition", "reordering", "rank(b)")


def plant(**noise: object) -> LinearPlant:
    return LinearPlant.create(A=A, C=C, E=E, Ts=0.1, **noise)  # type: ignore[arg-type]


def one_fdisyn_line(exc: BaseException) -> str:
    assert isinstance(exc, FdisynError), f"{type(exc).__name__}: {exc}"
    msg = str(exc)
    assert "\n" not in msg
    low = msg.lower()
    first = min((low.find(w) for w in SOLVERS if w in low), default=len(msg))
    assert first > 40, f"solver wording before fdisyn's explanation: {msg}"
    return msg


@pytest.mark.parametrize("method", ["kalman_uio", "kalman_uio_paper"])
@pytest.mark.parametrize(
    ("noise", "said"),
    [
        ({}, r"outputs \['y0', 'y1'\] have none \(R_ii = 0\).*R > 0 on the outputs used"),  # Q = R = 0: was SciPy's QZ failure
        ({"Q": np.eye(3)}, r"R_ii = 0.*R > 0 on the outputs used"),
        ({"Q": np.eye(3), "R": np.diag([1.0, 0.0])}, r"outputs \['y1'\] have no sensor noise \(R_ii = 0\)"),
    ],
    ids=["Q=R=0", "R=0", "R singular"],
)
def test_a_missing_noise_model_is_named(method, noise, said):
    with pytest.raises(ExistenceError, match=said) as err:
        fdisyn.design(plant(**noise), method)
    one_fdisyn_line(err.value)


def test_poles_no_gain_can_assign_are_named_with_poles_that_work():
    good = plant(Q=np.eye(3), R=np.eye(2))
    with pytest.raises(ExistenceError, match=r"mode\(s\) \[0.7\] of A1 = T A are unobservable.*e.g. poles = \[0.7, 0.5, 0.5\]") as err:
        fdisyn.design(good, "uio_pole_placement", poles=[0.5, 0.5, 0.5])  # was SciPy's "repeated more than rank(B) times"
    one_fdisyn_line(err.value)
    assert fdisyn.design(good, "uio_pole_placement", poles=[0.7, 0.5, 0.5]).certificate["passed"]
    square = LinearPlant.create(A=np.diag([0.9, 0.8, 0.7]), C=np.eye(3)[:2] + 0.1, E=np.zeros((3, 0)), Ts=0.1, Q=np.eye(3), R=np.eye(2))
    with pytest.raises(ExistenceError, match=r"pole 0.5 is requested 3 times.*at most 2 times; give distinct poles") as err:
        fdisyn.design(square, "uio_pole_placement", poles=[0.5, 0.5, 0.5])
    one_fdisyn_line(err.value)


def test_export_to_a_path_that_cannot_be_written(tmp_path):
    gf = fdisyn.design(plant(Q=1e-3 * np.eye(3), R=1e-2 * np.eye(2)), "kalman_uio")
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    (tmp_path / "g" / "gains.json").mkdir(parents=True)
    (tmp_path / "c_file").mkdir()
    (tmp_path / "c_file" / "c").write_text("x")
    cases = [
        ("/proc/x", FileError, r"cannot create the export folder /proc/x: .*a folder you can write in"),  # was FileNotFoundError
        (a_file, FileError, r"export folder .*a_file is a file"),
        (a_file / "sub", FileError, r"cannot create the export folder .*a_file/sub"),
        (tmp_path / "g", FileError, r"gains.json is a folder, where the diagnoser's gain file goes"),
        (tmp_path / "c_file", BuildError, r"cannot write .*c_file/c while building"),
    ]
    for where, kind, said in cases:
        with pytest.raises(kind, match=said) as err:
            fdisyn.export(gf, where)
        one_fdisyn_line(err.value)
    with pytest.raises(ArgumentError, match="directory must be a path"):
        fdisyn.export(gf, 3)  # type: ignore[arg-type]


def test_load_and_from_control_name_what_is_wrong(tmp_path):
    import control

    (tmp_path / "g" / "gains.json").mkdir(parents=True)
    for where, said in ((tmp_path / "none", "no gain file at"), (tmp_path / "g", "is a directory; expected a gain file")):
        with pytest.raises(GainFileError, match=said) as err:
            fdisyn.load(where)
        one_fdisyn_line(err.value)
    continuous = LinearPlant.from_control(control.ss(-np.eye(2), np.eye(2), np.eye(2), 0), n_unknown=1, Q=np.eye(2), R=np.eye(2))
    with pytest.raises(ArgumentError, match="missing option 'Ts'") as err:
        fdisyn.design(continuous, "kalman_uio")
    one_fdisyn_line(err.value)


def test_seeded_sweep_of_degenerate_noise_and_poles():
    """Random small plants with zero, singular or partial noise and random (possibly repeated) poles: every
    design succeeds or raises one fdisyn line, never a raw exception or a solver's words first."""
    rng = np.random.default_rng(20250)
    outcomes = {"designed": 0, "refused": 0}
    for _ in range(12):
        n, p = int(rng.integers(2, 5)), int(rng.integers(2, 4))
        a = rng.normal(size=(n, n)) * 0.4
        c = rng.normal(size=(p, n)) * 10.0 ** rng.uniform(-3, 3, size=(p, 1))
        e = rng.normal(size=(n, 1))
        q = np.diag(rng.choice([0.0, 1e-3, 1.0], size=n))
        r = np.diag(rng.choice([0.0, 1e-4, 1.0], size=p))
        pl = LinearPlant.create(A=a, C=c, E=e, Q=q, R=r, Ts=0.05)
        poles = list(rng.choice([0.2, 0.5, 0.5], size=n))
        for method, options in (("kalman_uio", {}), ("kalman_uio_paper", {}), ("uio_pole_placement", {"poles": poles})):
            try:
                fdisyn.design(pl, method, **options)
                outcomes["designed"] += 1
            except Exception as exc:  # noqa: BLE001 - judged below
                one_fdisyn_line(exc)
                outcomes["refused"] += 1
    assert outcomes["designed"] and outcomes["refused"]
