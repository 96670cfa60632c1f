"""Semantics of the linear step, on a hand-made gain file whose statistics are easy to steer.

Two generators, ``r_i = y_i`` (``Cr = 0``, ``Dy = e_i``), ``Σ_r = 1``: so
``J_i = y_i²`` and every rule (skipping, persistence, isolation) can be driven
sample by sample.
"""

from __future__ import annotations

import numpy as np
import pytest
from fdisyn.runtime.gainfile import Decision, Evaluator, GainFile, Generator, StepSpec
from fdisyn.runtime.layout import linear_state_layout
from fdisyn.runtime.monitor import Monitor
from fdisyn.runtime.reference import LinearReference

THRESHOLD = 4.0


def toy(persistence: int = 1) -> GainFile:
    gens = []
    for i in range(2):
        dy = np.zeros((1, 2))
        dy[0, i] = 1.0
        by = np.zeros((1, 2))
        by[0, i] = 0.5
        ar = np.array([[0.5]])
        gens.append(
            Generator(
                name=f"g{i}", outputs_used=(i,), Ar=ar, Bu=np.zeros((1, 1)), By=by, Cr=np.zeros((1, 1)), Du=np.zeros((1, 1)),
                Dy=dy, Xu=np.zeros((1, 1)), Xy=np.linalg.solve(np.eye(1) - ar, by),
            )
        )
    evs = [Evaluator(kind="chi2", generator=i, P_f=0.05, dof=1, threshold=THRESHOLD, Sigma_r=np.eye(1), W=np.eye(1)) for i in range(2)]
    lay = linear_state_layout(gens, evs)
    return GainFile(
        kind="linear", name="toy", problem="toy", design="toy", Ts=0.1, inputs=("u",), outputs=("y0", "y1"), faults=("y0", "y1", "both"),
        step=StepSpec(nu=1, ny=2, nr=2, nj=2, nstate=lay.size, init_state=np.zeros(lay.size), residual_names=("r0", "r1"), statistic_names=("J0", "J1")),
        plant={"A": np.eye(1) * 0.5, "B": np.zeros((1, 1)), "C": np.ones((2, 1)), "D": np.zeros((2, 1)), "E": np.zeros((1, 0)), "Q": np.eye(1), "R": np.eye(2)},
        generators=tuple(gens), evaluators=tuple(evs),
        decision=Decision(kind="signature_table", signatures=np.array([[1, 0], [0, 1], [1, 1]]), persistence=persistence),
        certificate={"passed": True},  # by construction: J_i = y_i² exactly, Σ_r = W = 1
    )


def test_statistic_alarm_and_isolation():
    ref = LinearReference(toy())
    s = ref.init_state()
    assert ref.step(s, [0.0], [1.0, 1.0]).alarm == 0
    o = ref.step(s, [0.0], [3.0, 1.0])  # J0 = 9 > 4
    assert (o.alarm, o.isolated) == (1, 0)
    np.testing.assert_array_equal(o.J, [9.0, 1.0])
    assert ref.step(s, [0.0], [1.0, -3.0]).isolated == 1
    assert ref.step(s, [0.0], [3.0, 3.0]).isolated == 2
    o = ref.step(s, [0.0], [2.0, 0.0])  # J = 4 is not above the threshold
    assert (o.alarm, o.isolated) == (0, -1)


def test_persistence_counts_consecutive_exceedances():
    ref = LinearReference(toy(persistence=3))
    s = ref.init_state()
    alarms = [ref.step(s, [0.0], [y, 0.0]).alarm for y in (3, 3, 3, 3, 0, 3, 3, 3)]
    assert alarms == [0, 0, 1, 1, 0, 0, 0, 1]


def test_non_finite_output_skips_only_the_generators_that_read_it():
    ref = LinearReference(toy())
    s = ref.init_state()
    ref.step(s, [0.0], [1.0, 2.0])
    before = s.copy()
    lay = ref.layout
    o = ref.step(s, [0.0], [np.nan, 5.0])
    assert o.status == 1 and o.J[0] == 0.0 and o.r[0] == 0.0  # g0 skipped: no value, no alarm from it
    assert o.J[1] == 25.0 and o.alarm == 1 and o.isolated == 1  # g1 still watches y1
    assert s[lay["xi0"]] == before[lay["xi0"]]  # g0's state unchanged
    assert s[lay["nonfinite"]][0] == 1.0
    o = ref.step(s, [np.inf], [1.0, 1.0])  # a non-finite input stops every generator
    assert o.status == 1 and o.alarm == 0 and not np.any(o.J)
    assert s[lay["nonfinite"]][0] == 2.0


def test_generator_starts_at_the_equilibrium_of_its_first_valid_sample():
    ref = LinearReference(toy())
    s = ref.init_state()
    ref.step(s, [0.0], [np.nan, 2.0])  # g0 not started yet
    assert s[ref.layout["ready"]].tolist() == [0.0, 1.0]
    ref.step(s, [0.0], [4.0, 2.0])
    # ξ = (1 − 0.5)⁻¹ 0.5 y = y at equilibrium; one step later still y for a constant y
    assert s[ref.layout["xi0"]][0] == pytest.approx(4.0)


def test_monitor_names_the_fault_and_counts_skipped_samples():
    mon = Monitor(toy())
    assert mon.backend == "reference"
    v = mon.update([0.0], [0.0, 3.0])
    assert v.alarm and v.fault == "y1"
    v = mon.update([0.0], [np.nan, 0.0])
    assert v.skipped and mon.skipped_samples == 1
    res = mon.run(np.zeros((3, 1)), np.array([[0.0, 0.0], [3.0, 3.0], [np.nan, np.nan]]))
    assert res.isolated.tolist() == [-1, 2, -1]
    assert mon.skipped_samples == 2 and mon.samples == 5
