"""The generalised observer scheme on linearly dependent outputs (Long & Wang, Aeroengine 43(5), 2017):
grouping, virtual outputs and the exclude-one UIO bank, against independent truths."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from fdisyn.models.linear import LinearPlant
from fdisyn.runtime.errors import ExistenceError
from fdisyn.runtime.reference import LinearReference
from fdisyn.synthesis.residual import internal_form
from fdisyn.synthesis.uio_gos import completed_condition, gos_diagnoser, output_groups, uio_name, virtual_outputs

# y5 = y1 + y2: rank C = 4 < 5 outputs. E reaches y3 and y4 together, so no single sensor fault lies in the
# range of C E (a sensor fault there would look like the unknown input and be decoupled with it)
A = np.array([[0.7, 0.1, 0.0, 0.0], [0.0, 0.6, 0.2, 0.0], [0.1, 0.0, 0.5, 0.1], [0.0, 0.0, 0.1, 0.4]])
C = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 0.5], [0, 0.3, 0, 1.0], [1.0, 1.0, 0, 0]])


def _plant() -> LinearPlant:
    return LinearPlant.create(
        A=A, B=np.array([[1.0], [0.5], [0.0], [0.2]]), C=C, E=np.array([[0.0], [0.2], [1.0], [0.5]]),
        Q=0.01 * np.eye(4), R=0.01 * np.eye(5), Ts=0.1, outputs=("y1", "y2", "y3", "y4", "y5"),
    )


def test_groups_are_the_fewest_independent_sets_covering_every_sensor() -> None:
    sols = output_groups(C, outputs=_plant().outputs)
    # brute force: a group is a basis (4 independent rows); two bases are needed to cover 5 sensors
    bases = [b for b in itertools.combinations(range(5), 4) if np.linalg.matrix_rank(C[list(b)]) == 4]
    pairs = {frozenset(p) for p in itertools.combinations(bases, 2) if set().union(*p) == set(range(5))}
    assert {frozenset(s.groups) for s in sols} == pairs
    assert [s.condition for s in sols] == sorted(s.condition for s in sols)
    for s in sols:
        for g, v in zip(s.groups, s.virtual, strict=True):
            assert np.linalg.matrix_rank(np.vstack([C[list(g)], np.eye(4)[list(v)]])) == 4


def test_virtual_outputs_minimise_the_completed_condition_number() -> None:
    c = np.array([[1.0, 1.0, 0, 0], [0, 0, 1.0, 0]])
    best = virtual_outputs(c, [0, 1])
    every = {s: completed_condition(c, [0, 1], s) for s in itertools.combinations(range(4), 2)}
    assert completed_condition(c, [0, 1], best) == min(every.values())
    with pytest.raises(ExistenceError, match="linearly dependent"):
        virtual_outputs(np.array([[1.0, 0], [2.0, 0]]), [0, 1])


def test_a_zero_row_cannot_be_grouped() -> None:
    with pytest.raises(ExistenceError, match=r"\['y2'\] have a zero row"):
        output_groups(np.array([[1.0, 0], [0, 0], [0, 1.0]]), outputs=("y1", "y2", "y3"))


def test_bank_decouples_e_and_isolates_every_sensor_fault() -> None:
    pl = _plant()
    grouping = output_groups(C, outputs=pl.outputs)[0]
    gf = gos_diagnoser(pl, grouping.groups, name="gos", problem="gos", design="kalman_uio_gos", P_f=1e-6)
    names = [g.name for g in gf.generators]
    assert len(names) == sum(len(g) for g in grouping.groups)
    for gen in gf.generators:  # the UIO's residual does not see d (internal form, all Markov parameters)
        assert internal_form(gen, pl).coupling("d") < 1e-9
    ref = LinearReference(gf)
    rng = np.random.default_rng(1)
    n = 400
    u = rng.standard_normal((n, 1))
    d = np.cumsum(rng.standard_normal(n)) * 0.5  # a large unknown input: decoupled, raises nothing
    x = np.zeros(4)
    y = np.empty((n, 5))
    for k in range(n):
        y[k] = C @ x
        x = A @ x + pl.B[:, 0] * u[k, 0] + pl.E[:, 0] * d[k]
    clean = ref.run(u, y)
    assert not clean.alarm[50:].any()
    for i, sensor in enumerate(pl.outputs):
        yf = y.copy()
        yf[200:, i] += 5.0
        res = ref.run(u, yf)
        iso = res.isolated[260:]
        assert np.all(iso == gf.faults.index(sensor)), sensor
        # exactly the UIOs that do not read the sensor stay silent: in each group holding it, the one excluding it
        silent = {names[j] for j in range(len(names)) if res.J[260:, j].max() <= gf.evaluators[j].threshold}
        assert silent == {names[j] for j, gen in enumerate(gf.generators) if i not in gen.outputs_used}
        assert {uio_name(gi, sensor) for gi, g in enumerate(grouping.groups) if i in g} <= silent
