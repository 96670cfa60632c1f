"""LinearPlant: validation messages, scaling invariance, python-control interop."""

from __future__ import annotations

import numpy as np
import pytest
from fdisyn.models.linear import LinearPlant
from fdisyn.numerics.linalg import markov_parameters
from fdisyn.runtime.errors import ArgumentError, ShapeError

from tests.helpers import random_plant


def test_shape_error_names_matrix_and_shapes():
    with pytest.raises(ShapeError, match=r"C has shape \(2, 2\); expected \(any, 3\)"):
        LinearPlant.create(A=np.eye(3), C=np.eye(2))
    with pytest.raises(ShapeError, match=r"E has shape \(2, 1\); expected \(3, any\)"):
        LinearPlant.create(A=np.eye(3), C=np.eye(3), E=np.ones((2, 1)))
    with pytest.raises(ShapeError, match="A must be square"):
        LinearPlant.create(A=np.ones((2, 3)), C=np.ones((1, 3)))


def test_non_finite_and_non_covariance_are_refused():
    with pytest.raises(ArgumentError, match=r"A contains a non-finite entry at index \(0, 1\)"):
        LinearPlant.create(A=[[1.0, np.nan], [0.0, 1.0]], C=np.eye(2))
    with pytest.raises(ArgumentError, match="Q must be positive semidefinite"):
        LinearPlant.create(A=np.eye(2), C=np.eye(2), Q=np.diag([1.0, -1.0]))
    with pytest.raises(ArgumentError, match="R must be symmetric"):
        LinearPlant.create(A=np.eye(2), C=np.eye(2), R=[[1.0, 0.5], [0.0, 1.0]])


def test_names_are_checked():
    with pytest.raises(ArgumentError, match="output names: expected 2 names"):
        LinearPlant.create(A=np.eye(2), C=np.eye(2), outputs=["y"])
    with pytest.raises(ArgumentError, match="unique"):
        LinearPlant.create(A=np.eye(2), C=np.eye(2), outputs=["y", "y"])
    with pytest.raises(ArgumentError, match="is not a signal name"):
        LinearPlant.create(A=np.eye(2), C=np.eye(2), outputs=["y 1", "y2"])


def test_matrices_are_read_only():
    p = random_plant(1)
    with pytest.raises(ValueError):
        p.A[0, 0] = 1.0


@pytest.mark.parametrize("seed", range(5))
def test_state_scaling_keeps_the_transfer_function(seed):
    p = random_plant(seed)
    s = np.random.default_rng(seed).uniform(1e-3, 1e3, p.n)
    ps = p.scaled(s)
    bb = np.hstack([p.B, p.E])
    bbs = np.hstack([ps.B, ps.E])
    d = np.zeros((p.p, bb.shape[1]))
    for m1, m2 in zip(markov_parameters(p.A, bb, p.C, d, 8), markov_parameters(ps.A, bbs, ps.C, d, 8), strict=True):
        # a similarity transform: Markov parameters equal up to round-off amplified by cond(S) ≤ 1e6
        np.testing.assert_allclose(m2, m1, rtol=1e-9, atol=1e-9 * np.abs(m1).max())


def test_python_control_round_trip():
    import control

    p = random_plant(4)
    sys = p.to_control()
    back = LinearPlant.from_control(sys, n_unknown=p.q)
    for k in ("A", "B", "C", "D", "E"):
        np.testing.assert_array_equal(getattr(back, k), getattr(p, k))
    assert back.Ts == p.Ts
    assert isinstance(sys, control.StateSpace)
