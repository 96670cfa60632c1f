"""The generalised UIO bank refuses training data and option combinations it would otherwise misread: time stamps
that are not numbers, a training name that is no regular file (a FIFO would block the design), a detector given
twice under its two names, and min_fault for a detector that has no designed fault size."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import numpy as np
import pytest
from fdisyn.models.linear import LinearPlant
from fdisyn.runtime.errors import ArgumentError, TraceError
from fdisyn.runtime.trace import Trace
from fdisyn.synthesis.registry import check_options, design, get_method

from tests.design.test_cli_hostile import _fails_with
from tests.design.test_uio_gos_plant_file import A, B, C, NOISE, TS, _plant_file, _training

PLANT = LinearPlant.create(A=A, B=B, C=C, R=NOISE**2 * np.eye(5), inputs=("u",),
                      outputs=("y1", "y2", "y3", "y4", "y5"), states=("x1", "x2", "x3", "x4"))


def _trace(t: np.ndarray) -> Trace:
    n = t.shape[0]
    rng = np.random.default_rng(3)
    return Trace(t=t, inputs=("u",), outputs=PLANT.outputs, U=rng.standard_normal((n, 1)), Y=rng.standard_normal((n, 5)),
                 extra={s: rng.standard_normal(n) for s in PLANT.states})


def test_a_nan_time_stamp_is_refused_not_passed_as_every_ts() -> None:
    t = np.arange(200) * TS
    t[50] = np.nan
    with pytest.raises(ArgumentError, match=r"training: the time t of sample 51 is nan; expected a finite time every Ts = 0\.05 s"):
        design(PLANT, "kalman_uio_gos", Ts=TS, P_f=1e-4, training=_trace(t))


def test_an_empty_time_field_of_a_training_csv_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "data").mkdir()
    csv = tmp_path / "data" / "train.csv"
    _training(csv)
    lines = csv.read_text(encoding="utf-8").splitlines(keepends=True)
    lines[100] = lines[100][lines[100].index(","):]  # the time field of sample 100 left empty: NaN in the replay grammar
    csv.write_text("".join(lines), encoding="utf-8")
    spec = _plant_file(tmp_path, 'training = "data/train.csv"')
    _fails_with(capsys, ["design", spec, "--out", str(tmp_path / "o")], "[design].training: the time t of sample 100 is nan")


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this system")
def test_a_fifo_as_training_is_refused_at_once(tmp_path: Path) -> None:
    fifo = tmp_path / "train.csv"
    os.mkfifo(fifo)
    outcome: list[BaseException | None] = []

    def run() -> None:
        try:
            design(PLANT, "kalman_uio_gos", Ts=TS, P_f=1e-4, training=str(fifo))
            outcome.append(None)
        except BaseException as exc:  # noqa: BLE001 - handed to the test's thread
            outcome.append(exc)

    worker = threading.Thread(target=run, daemon=True)
    worker.start()
    worker.join(timeout=120)  # a generous bound for a slow machine: the refusal takes no reading at all
    if worker.is_alive():
        # the design waits for a writer: open one (without blocking) so the thread ends, and fail
        os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
        worker.join(timeout=60)
        pytest.fail("a FIFO given as training blocked the design")
    (exc,) = outcome
    assert isinstance(exc, TraceError), exc
    assert str(fifo) in str(exc) and "not a regular file" in str(exc) and "\n" not in str(exc)


def test_a_directory_as_training_is_refused(tmp_path: Path) -> None:
    with pytest.raises(TraceError, match="not a regular file"):
        design(PLANT, "kalman_uio_gos", Ts=TS, P_f=1e-4, training=str(tmp_path))


@pytest.mark.parametrize(("given", "detector", "evaluator"), [
    ({"detector": "chi2", "evaluator": "wssr"}, "chi2", "wssr"),
    ({"detector": "wssr", "evaluator": "chi2"}, "wssr", "chi2"),
    ({"detector": "glr", "evaluator": "wssr"}, "glr", "wssr"),
])
def test_detector_and_evaluator_that_disagree_are_refused(given: dict[str, str], detector: str, evaluator: str) -> None:
    with pytest.raises(ArgumentError, match=rf"option detector = '{detector}' but evaluator = '{evaluator}': they are the same option, give one"):
        check_options(get_method("kalman_uio_gos"), {"P_f": 1e-4, "Ts": TS, "training": "t.csv", **given}, plant=PLANT)


@pytest.mark.parametrize(("given", "kind"), [({}, "wssr"), ({"evaluator": "chi2"}, "chi2"), ({"detector": "chi2"}, "chi2"),
                                             ({"detector": "wssr", "evaluator": "wssr"}, "wssr")])
def test_one_name_or_two_that_agree_choose_the_detector(given: dict[str, str], kind: str) -> None:
    from fdisyn.synthesis.linear_diagnoser import chosen_detector
    from fdisyn.synthesis.uio_gos import DEFAULT_DETECTOR

    opts = check_options(get_method("kalman_uio_gos"), {"P_f": 1e-4, "Ts": TS, "training": "t.csv", **given}, plant=PLANT)
    assert chosen_detector(opts["detector"], opts["evaluator"], "", default=DEFAULT_DETECTOR) == kind


@pytest.mark.parametrize("detector", ["chi2", "wssr"])
@pytest.mark.parametrize("method", ["kalman_uio_gos", "kalman_uio"])
def test_min_fault_with_a_detector_that_ignores_it_is_refused(detector: str, method: str) -> None:
    opts = {"P_f": 1e-4, "Ts": TS, "detector": detector, "min_fault": {"y1": 0.1}}
    if method == "kalman_uio_gos":
        opts["training"] = "t.csv"
    else:
        opts["bank"] = [["y1", "y2", "y3", "y4"]]
    with pytest.raises(ArgumentError, match=rf"option min_fault is read only by the detectors 'cusum' and 'glr' .*the detector here is '{detector}'"):
        check_options(get_method(method), opts, plant=PLANT)


def test_min_fault_with_a_sequential_detector_is_read(tmp_path: Path) -> None:
    for detector in ("cusum", "glr"):
        opts = check_options(get_method("kalman_uio_gos"), {"P_f": 1e-4, "Ts": TS, "detector": detector, "min_fault": {"y1": 0.1},
                                                             "training": "t.csv"}, plant=PLANT)
        assert opts["min_fault"] == {"y1": 0.1}


def test_plant_file_min_fault_with_chi2_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    spec = _plant_file(tmp_path, 'detector = "chi2"\nmin_fault = { y1 = 0.1 }', with_e=True)
    _fails_with(capsys, ["design", spec, "--out", str(tmp_path / "o")], "[design].min_fault is read only by the detectors 'cusum' and 'glr'")
