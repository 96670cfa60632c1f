"""The linear-algebra functions: the validators, the Lyapunov solver, the sampled-data design's factor and rank tests."""

from __future__ import annotations

import numpy as np
import pytest
from fdisyn.numerics.linalg import (
    as_covariance,
    as_vector,
    dlyap,
    frozen_array,
    normal_rank,
    psd_factor,
    real_array,
    unobservable_modes,
)
from fdisyn.runtime.errors import ArgumentError, ExistenceError, ShapeError
from hypothesis import given, settings
from hypothesis import strategies as st


@settings(derandomize=True, max_examples=30, deadline=None)
@given(n=st.integers(1, 6), r=st.integers(0, 6), seed=st.integers(0, 2**16))
def test_psd_factor_reproduces_w_with_rank_columns(n: int, r: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    r = min(r, n)
    g = rng.standard_normal((n, r))
    w = g @ g.T
    b = psd_factor(w)
    assert b.shape == (n, r)
    # B Bᵀ = W to round-off of eigh: ~n·eps·‖W‖.
    assert np.linalg.norm(b @ b.T - w) <= 1e-13 * max(np.linalg.norm(w), 1.0)
    # Columns orthogonal (eigenvectors scaled by √λ).
    gram = b.T @ b
    assert np.linalg.norm(gram - np.diag(np.diag(gram))) <= 1e-12 * max(np.linalg.norm(w), 1.0)


def test_psd_factor_refuses_indefinite_and_asymmetric() -> None:
    with pytest.raises(ArgumentError, match="positive semidefinite"):
        psd_factor(np.diag([1.0, -1.0]), "Wx")
    with pytest.raises(ArgumentError, match="symmetric"):
        psd_factor(np.array([[1.0, 2.0], [0.0, 1.0]]), "Wx")


def test_normal_rank_of_tall_wide_and_rank_deficient_systems() -> None:
    rng = np.random.default_rng(3)
    a = 0.5 * np.eye(3) + 0.1 * rng.standard_normal((3, 3))
    b1 = rng.standard_normal((3, 1))
    c2 = rng.standard_normal((2, 3))
    assert normal_rank(a, b1, c2, np.zeros((2, 1))) == 1  # tall: 2 outputs, 1 input
    b3 = rng.standard_normal((3, 3))
    assert normal_rank(a, b3, c2, np.zeros((2, 3))) == 2  # wide
    # Two identical outputs: rank 1 however many inputs.
    c_dup = np.vstack([c2[:1], c2[:1]])
    assert normal_rank(a, b3, c_dup, np.zeros((2, 3))) == 1


def test_unobservable_modes_by_region() -> None:
    a = np.diag([2.0, -0.7, 0.5])
    c = np.array([[0.0, 0.0, 1.0]])
    assert unobservable_modes(a, c, region="unstable-continuous") == [2.0]
    assert sorted(z.real for z in unobservable_modes(a, c, region="all")) == [-0.7, 2.0]
    assert unobservable_modes(a, c, region="unstable-discrete") == [2.0]


def test_covariances_from_a_number_a_diagonal_or_a_matrix() -> None:
    np.testing.assert_array_equal(as_covariance(0.5, "Q", 2), 0.5 * np.eye(2))
    np.testing.assert_array_equal(as_covariance([1.0, 2.0], "Q", 2), np.diag([1.0, 2.0]))
    # symmetric to 1e-10 of the largest entry: symmetrised, halves first (no overflow at 1e308)
    big = as_covariance([[1e308, 0.0], [1e-300, 1e308]], "Q", 2)
    assert np.all(np.isfinite(big)) and big[0, 1] == big[1, 0]
    assert as_covariance(0.0, "Q", 2).sum() == 0.0  # semidefinite is enough without definite
    with pytest.raises(ArgumentError, match="R must be positive definite; smallest eigenvalue 0"):
        as_covariance(0.0, "R", 2, definite=True)
    with pytest.raises(ArgumentError, match="Q must be positive semidefinite"):
        as_covariance(-1.0, "Q", 1)
    with pytest.raises(ArgumentError, match="Q must hold numbers only; found '1e-2'"):
        as_covariance("1e-2", "Q", 1)
    with pytest.raises(ShapeError, match=r"Q has shape \(2, 3\); expected \(2, 2\)"):
        as_covariance(np.ones((2, 3)), "Q", 2)


def test_vectors_and_read_only_copies() -> None:
    np.testing.assert_array_equal(as_vector([[1.0], [2.0]], "x0", 2), [1.0, 2.0])
    np.testing.assert_array_equal(as_vector(3.0, "x0", 2, fill=True), [3.0, 3.0])
    with pytest.raises(ShapeError, match="x0 has 1 entries; expected 2"):
        as_vector(3.0, "x0", 2)
    with pytest.raises(ArgumentError, match="x0 must hold numbers only; found True"):
        as_vector([1.0, True], "x0", 2)
    a = frozen_array([1, 2])
    assert a.dtype == float and not a.flags.writeable
    with pytest.raises(ArgumentError, match="beyond the range of a double"):
        real_array([10**400], "A")


def test_lyapunov_solver_refines_to_round_off_and_refuses_unstable_a() -> None:
    """A strongly non-normal stable A (‖A‖₂ ≈ 1e4 at ρ = 0.3): with the refinement step the residual
    is at round-off of ‖X‖; without it, the doubling's sum alone."""
    t = np.array([[1.0, 3e3], [0.0, 1.0]])
    a = t @ np.diag([0.3, -0.2]) @ np.linalg.inv(t)
    q = np.eye(2)
    for refine in (True, False):
        x = dlyap(a, q, refine=refine)
        np.testing.assert_array_equal(x, x.T)
        assert np.linalg.eigvalsh(x)[0] > 0.0
    x = dlyap(a, q)
    assert np.linalg.norm(a @ x @ a.T + q - x) <= 1e-14 * np.linalg.norm(x)
    with pytest.raises(ExistenceError, match="spectral radius of A is 1.1"):
        dlyap(np.array([[1.1]]), np.eye(1))
