"""The turbofan of Long & Wang, Aeroengine 43(5), 2017, section 2: the transcribed model's structural facts,
the grouping the paper made by hand, and the unknown-input direction estimated from the stand-in truth."""

from __future__ import annotations

import numpy as np
import pytest
from fdisyn.problems import turbofan as tf
from fdisyn.runtime.errors import ExistenceError
from fdisyn.synthesis.uio_gos import estimate_unknown_input, output_groups


def _idx(names, pool):
    return [pool.index(x) for x in names]


def test_rank_c_is_eight_and_both_paper_groups_complete_to_rank_twelve() -> None:
    # exact: the dependency T3 = T25 + (0.02969/0.04786) P3 holds between printed numbers, so rank is not tolerance-dependent
    s = np.linalg.svd(tf.C, compute_uv=False)
    assert np.linalg.matrix_rank(tf.C) == 8 and s[8] < 1e-14 * s[0]
    virtual = np.eye(12)[_idx(tf.PAPER_VIRTUAL, tf.STATES)]
    for group in tf.PAPER_GROUPS:
        rows = tf.C[_idx(group, tf.OUTPUTS)]
        assert np.linalg.matrix_rank(rows) == 8
        assert np.linalg.matrix_rank(np.vstack([rows, virtual])) == 12


def test_the_search_finds_the_paper_grouping_first() -> None:
    sols = output_groups(tf.C, outputs=tf.OUTPUTS)
    paper = {tuple(_idx(g, tf.OUTPUTS)) for g in tf.PAPER_GROUPS}
    assert all(len(s.groups) == 2 for s in sols)  # 9 sensors, bases of 8: two groups, no fewer
    assert set(sols[0].groups) == paper
    assert {frozenset(s.groups) for s in sols} >= {frozenset(paper)}


def test_open_loop_is_stable_with_engine_time_scales() -> None:
    lam = np.linalg.eigvals(tf.A)
    assert np.all(lam.real < 0)
    # slowest ≈ spool inertia (about 1 s), fastest ≈ gas-path volumes (about 10 ms)
    assert 0.3 < -lam.real.max() < 3 and 30 < -lam.real.min() < 200


def test_transcription_table_matches_the_matrices() -> None:
    import re

    rows = {"A": tf.STATES, "B": tf.STATES, "C": tf.OUTPUTS}
    cols = {"A": tf.STATES, "B": tf.INPUTS, "C": tf.STATES}
    checked = 0
    for position, _printed, value, _why in tf.TRANSCRIPTION:
        m = re.fullmatch(r"([ABC])\[(\w+), (\w+)\]", position)
        if m and re.fullmatch(r"-?[0-9.]+", value):
            mat = {"A": tf.A, "B": tf.B, "C": tf.C}[m[1]]
            assert mat[rows[m[1]].index(m[2]), cols[m[1]].index(m[3])] == float(value), position
            checked += 1
    assert checked >= 15


def _training() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n = int(120 / tf.TS)
    t = np.arange(n) * tf.TS
    u = np.zeros((n, 4))
    for t0, v in [(5, 1), (25, 0.3), (40, -0.5), (60, 0.8), (80, 0.0), (95, 1.2), (110, 0.5)]:
        u[t >= t0, 3] = v * tf.TRUTH.throttle_step
    y, x = tf.simulate_truth(u, [0])
    return u, y[0], x[0]


def test_estimated_unknown_input_is_the_spool_curvature() -> None:
    u, y, x = _training()
    g = _idx(tf.PAPER_GROUPS[0], tf.OUTPUTS)
    v = _idx(tf.PAPER_VIRTUAL, tf.STATES)
    est = estimate_unknown_input(tf.design_model(), tf.TS, u, y, x[:, v], group=g, virtual=v, d_rate=0.003, rank_gap=5)
    assert est.rank == 1
    # the truth's steady mismatch enters the N2 and N1 rows only: the estimate must lie in that plane
    e = est.E[:, 0] / np.linalg.norm(est.E[:, 0])
    assert np.linalg.norm(e[[10, 11]]) > 0.99
    with pytest.raises(ExistenceError, match="no clear rank gap"):
        estimate_unknown_input(tf.design_model(), tf.TS, u, y, x[:, v], group=g, virtual=v, d_rate=0.003, rank_gap=50)
