"""The bank a linear method builds when none is given: one generator per sensor on every other output (the
generalised observer scheme), which isolates each sensor's fault; a sensor whose generator does not exist is named
with the reason (in the gain file's provenance and account, on the terminal), and with none the bank is the one
generator on all outputs. One explicit group of all outputs still asks for one generator."""

from __future__ import annotations

import numpy as np
import pytest

import fdisyn
from fdisyn.numerics.account import account_lines
from fdisyn.runtime.errors import ArgumentError, CertificateError
from tests.helpers import random_plant
from fdisyn.runtime.gainfile import read_gain_file, write_gain_file

OUTPUTS = ["y1", "y2", "y3"]
LEAVE_ONE_OUT = [["y2", "y3"], ["y1", "y3"], ["y1", "y2"]]
"""The default bank of a three-sensor plant, written out (its generators get the same names: g0_y2_y3, …)."""


def three_sensors(**extra: object) -> fdisyn.LinearPlant:
    """A stable discrete plant, one unknown input reaching every sensor: every pair of sensors has its UIO."""
    a = np.array([[0.5, 0.1, 0.0], [0.0, 0.6, 0.1], [0.1, 0.0, 0.7]])
    return fdisyn.LinearPlant.create(
        A=a, B=np.array([[1.0], [0.0], [0.5]]), C=np.eye(3), E=np.array([[1.0], [0.5], [-0.3]]),
        Q=1e-3 * np.eye(3), R=1e-2 * np.eye(3), Ts=0.1, outputs=OUTPUTS, **extra,
    )


def continuous_three_sensors() -> fdisyn.LinearPlant:
    """The sampled-data methods' plant: continuous, a disturbance and a component fault."""
    a = np.array([[-1.0, 0.5, 0.0], [0.0, -2.0, 1.0], [0.5, 0.0, -3.0]])
    b = np.array([[1.0], [0.0], [0.5]])
    return fdisyn.LinearPlant.create(
        A=a, B=b, C=np.eye(3), E=np.array([[1.0], [0.5], [-0.3]]), Fx=b, Q=1e-3 * np.eye(3), R=1e-2 * np.eye(3),
        outputs=OUTPUTS, component_faults=["f"],
    )


def motor(**extra: object) -> fdisyn.LinearPlant:
    """The README's DC motor (current, speed, angle; load torque unknown) at 1 ms: without the angle sensor the
    angle integrator is unobservable, so the generator without th does not exist."""
    a = np.array([[-100.0, -5.0, 0.0], [50.0, -0.1, 0.0], [0.0, 1.0, 0.0]])
    b = np.array([[100.0], [0.0], [0.0]])
    cont = fdisyn.LinearPlant.create(
        A=a, B=b, C=np.eye(3), E=np.array([[0.0], [-1000.0], [0.0]]), Q=np.diag([1e-4, 1e-3, 0.0]),
        R=np.diag([1e-4, 2.5e-3, 1e-6]), outputs=["i", "w", "th"], **extra,
    )
    return cont.discretise(1e-3)


def signatures(gf: fdisyn.GainFile) -> dict[str, tuple[int, ...]]:
    return {f: tuple(int(x) for x in row) for f, row in zip(gf.faults, gf.decision.signatures, strict=True)}


@pytest.mark.parametrize("method, options", [("kalman_uio", {}), ("uio_pole_placement", {"poles": [0.1, 0.2, 0.3]})])
def test_no_bank_isolates_every_sensor(method: str, options: dict) -> None:
    gf = fdisyn.design(three_sensors(), method, **options)
    assert [g.name for g in gf.generators] == ["g0_y2_y3", "g1_y1_y3", "g2_y1_y2"]
    assert gf.faults == ("y1", "y2", "y3")  # was one class 'y1|y2|y3' from one generator on all outputs
    sig = signatures(gf)
    assert sig == {"y1": (0, 1, 1), "y2": (1, 0, 1), "y3": (1, 1, 0)}
    chosen = gf.provenance["bank"]
    assert chosen["generators"] == ["g0_y2_y3", "g1_y1_y3", "g2_y1_y2"] and chosen["left_out"] == []
    assert chosen["all_outputs"]["kept"] is False and "would tell no sensor faults apart" in chosen["all_outputs"]["why"]
    lines = account_lines(gf.account)
    assert "faults the bank cannot tell apart: none (every seen fault has its own signature)" in lines
    assert any(line.startswith("note: no bank given: one generator per sensor on the other outputs") for line in lines)


@pytest.mark.parametrize("method", ["lmi", "sampled_data_observer"])
def test_no_bank_isolates_every_sensor_sampled_data(method: str) -> None:
    gf = fdisyn.design(continuous_three_sensors(), method, Ts=0.1)
    assert [g.name for g in gf.generators] == ["g0_y2_y3", "g1_y1_y3", "g2_y1_y2"]
    assert gf.faults == ("y1", "y2", "y3", "f")
    assert signatures(gf) == {"y1": (0, 1, 1), "y2": (1, 0, 1), "y3": (1, 1, 0), "f": (1, 1, 1)}
    # the component fault has its own signature already: the generator on all outputs is not designed
    assert gf.provenance["bank"]["all_outputs"] == {"kept": False, "why": "every fault class has its own signature without it"}


def test_a_sensor_without_its_generator_is_named_with_the_reason(tmp_path) -> None:
    gf = fdisyn.design(motor(), "uio_pole_placement", poles=[0.5, 0.6, 0.7])
    assert [g.name for g in gf.generators] == ["g0_w_th", "g1_i_th"]
    assert gf.faults == ("i", "w", "th")  # two generators still isolate the three sensors
    (left,) = gf.provenance["bank"]["left_out"]
    assert left["sensor"] == "th" and left["outputs"] == ["i", "w"]
    assert left["reason"].startswith("the generator without th does not exist: (C, A1) is not detectable")
    # stored in the gain file (provenance and the account's optional bank), read back by the current reader
    path = write_gain_file(gf, tmp_path / "gains.json")
    back = read_gain_file(path)
    assert back.provenance["bank"] == gf.provenance["bank"] and back.account["classes"]["bank"]["left_out"] == [left]
    assert any("the generator without th does not exist" in n for n in back.account["notes"])


def test_a_merge_names_the_missing_generator() -> None:
    """A voltage (actuator) fault and an angle-sensor fault reach both generators: one class, and the account says
    which generator would have told them apart and why it does not exist."""
    plant = motor(Fx=np.array([[100.0], [0.0], [0.0]]), component_faults=["f_v"])
    gf = fdisyn.design(plant, "uio_pole_placement", poles=[0.5, 0.6, 0.7])
    assert gf.faults == ("i", "w", "th|f_v")
    (group,) = gf.account["classes"]["groups"]
    assert group["faults"] == ["th", "f_v"]
    assert "the decision table names them together ('th|f_v')" in group["reason"]
    assert "the generator without th does not exist: (C, A1) is not detectable" in group["reason"]
    # the generator on all outputs was designed and judged: it reads th too, so it tells them no more apart
    assert gf.provenance["bank"]["all_outputs"] == {"kept": False, "why": "it tells no more fault classes apart (3 without it)"}
    assert [g.name for g in gf.generators] == ["g0_w_th", "g1_i_th"]
    text = "\n".join(account_lines(gf.account))
    assert "faults the bank cannot tell apart:\n  'th' and 'f_v': " in text


def test_no_generator_without_a_sensor_falls_back_to_one_on_all_outputs() -> None:
    """Two sensors and one unknown input: a UIO on one sensor has no residual (p = q), so the bank is the one
    generator on all outputs, and the merged class says why."""
    plant = fdisyn.LinearPlant.create(
        A=np.array([[0.5, 0.1], [0.0, 0.6]]), B=np.array([[1.0], [0.0]]), C=np.eye(2), E=np.array([[1.0], [0.5]]),
        Q=1e-3 * np.eye(2), R=1e-2 * np.eye(2), Ts=0.1, outputs=["y1", "y2"],
    )
    gf = fdisyn.design(plant, "uio_pole_placement", poles=[0.2, 0.3])
    assert [g.name for g in gf.generators] == ["g0_y1_y2"] and gf.faults == ("y1|y2",)
    chosen = gf.provenance["bank"]
    assert [d["sensor"] for d in chosen["left_out"]] == ["y1", "y2"]
    assert chosen["all_outputs"] == {"kept": True, "why": "no sensor has a generator on the other outputs"}
    reasons = " ".join(g["reason"] for g in gf.account["classes"]["groups"])
    assert "the generator without y1 does not exist: p = 1 outputs and q = 1 unknown inputs leave no residual" in reasons


@pytest.mark.parametrize("bank", [[OUTPUTS], {"all": OUTPUTS}])
def test_one_group_of_all_outputs_keeps_one_generator(bank: object) -> None:
    gf = fdisyn.design(three_sensors(), "uio_pole_placement", poles=[0.1, 0.2, 0.3], bank=bank)
    assert len(gf.generators) == 1 and gf.faults == ("y1|y2|y3",)
    assert "bank" not in gf.provenance and "bank" not in gf.account["classes"]
    assert not any(n.startswith("no bank given") for n in gf.account["notes"])


def test_the_budget_is_split_over_the_default_banks_statistics() -> None:
    """``arl0`` is the whole diagnoser's: each of the default bank's three statistics gets a third, exactly as when
    the same bank is written out."""
    plant = three_sensors()
    default = fdisyn.design(plant, "uio_pole_placement", poles=[0.1, 0.2, 0.3], arl0=50.0)
    given = fdisyn.design(plant, "uio_pole_placement", poles=[0.1, 0.2, 0.3], arl0=50.0, bank=LEAVE_ONE_OUT)
    assert [g.name for g in default.generators] == [g.name for g in given.generators]
    for a, b in zip(default.evaluators, given.evaluators, strict=True):
        assert a.threshold == b.threshold and a.P_f == b.P_f
    assert all(e.P_f == pytest.approx(plant.Ts / (3 * 50.0), rel=1e-12) for e in default.evaluators)


def test_the_options_check_counts_the_default_banks_statistics() -> None:
    """Before any design the budget is checked on the default bank's three statistics, not on one: arl0 = 0.05 s at
    Ts = 0.1 s is 1.5 samples per statistic for three statistics (designed), 0.5 for one (refused)."""
    plant = three_sensors()
    gf = fdisyn.design(plant, "uio_pole_placement", poles=[0.1, 0.2, 0.3], arl0=0.05)
    assert len(gf.evaluators) == 3
    with pytest.raises(ArgumentError, match=r"arl0 = 0.05 s gives each of the 1 statistics a mean run length of 0.5 samples"):
        fdisyn.design(plant, "uio_pole_placement", poles=[0.1, 0.2, 0.3], arl0=0.05, bank=[OUTPUTS])


def test_an_output_decoupled_with_the_unknown_input_is_not_read() -> None:
    """x1 is all unknown input; y0 = x1, y1 = x2, y2 = x1 + x2. Without y0 the UIO's residual is y1's alone (y2 only
    estimates x1), and so is the one without y2: one generator on y1, one on y0 and y2, and the account says why y0
    and y2 merge (the generator on all outputs would merge all three)."""
    plant = fdisyn.LinearPlant.create(
        A=[[0.5, 0.1], [0.0, 0.7]], C=[[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]], E=[[1.0], [0.0]], Q=np.eye(2) * 1e-3,
        R=np.eye(3) * 1e-2, Ts=0.1,
    )
    gf = fdisyn.design(plant, "kalman_uio")
    assert [(g.name, g.outputs_used) for g in gf.generators] == [("g0_y1", (1,)), ("g1_y0_y2", (0, 2))]
    assert gf.faults == ("y0|y2", "y1")
    chosen = gf.provenance["bank"]
    assert chosen["narrowed"] == [{"sensor": "y0", "outputs": ["y1"], "reason": "the generator without y0 reads y1 only: "
                                   "y2 does not reach its residual (decoupled with the unknown input)"}]
    assert chosen["left_out"][0]["sensor"] == "y2" and chosen["left_out"][0]["reason"].endswith(", as g0_y1 does")
    (group,) = gf.account["classes"]["groups"]
    assert group["faults"] == ["y0", "y2"] and "the generator without y0 reads y1 only" in group["reason"]


@pytest.mark.parametrize("detector", ["cusum", "glr"])
def test_a_sequential_default_bank_leaves_out_a_generator_whose_residual_does_not_whiten(detector: str) -> None:
    """On this plant the plain UIO without y2 has a residual whose whitening leaves a lag-1 autocorrelation of 1 (its
    feedthrough noise is singular): the CUSUM's and GLR's thresholds would not hold there. The bank's certificate
    refuses such a generator in a bank given; the default bank leaves it out, says why, and still isolates every
    sensor with the other two (y2 is the one sensor both read)."""
    plant = random_plant(1, radius=0.8)
    poles = [0.9, 0.85, 0.8, -0.7, 0.75]
    with pytest.raises(CertificateError, match="residual white"):
        fdisyn.design(plant, method="uio_pole_placement", poles=poles, detector=detector, arl0=100.0, bank=[["y0", "y1"]])
    gf = fdisyn.design(plant, method="uio_pole_placement", poles=poles, detector=detector, arl0=100.0)
    assert gf.certificate["passed"] is True
    assert [g.name for g in gf.generators] == ["g0_y1_y2", "g1_y0_y2"]
    (out,) = gf.provenance["bank"]["left_out"]
    assert out["sensor"] == "y2" and "does not whiten" in out["reason"]
    assert gf.faults == ("y0", "y1", "y2")  # three signatures from two generators: (0, 1), (1, 0), (1, 1)
