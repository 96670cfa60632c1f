"""The small linear-algebra helpers added for the sampled-data design."""

from __future__ import annotations

import numpy as np
import pytest
from fdisyn.numerics.linalg import normal_rank, psd_factor, unobservable_modes
from fdisyn.runtime.errors import ArgumentError
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
