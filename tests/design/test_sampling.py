"""Exact sampling: ZOH and Van Loan against closed forms and independent integrals."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.integrate
import scipy.linalg
import scipy.signal
from fdisyn.models.linear import LinearPlant
from fdisyn.models.sampling import van_loan, zoh
from fdisyn.runtime.errors import ArgumentError
from hypothesis import given, settings
from hypothesis import strategies as st


def test_zoh_scalar_closed_form():
    # ẋ = a x + b u held over h: x⁺ = e^{ah} x + (e^{ah} − 1)/a · b u
    a, b, h = -0.7, 2.0, 0.3
    ad, bd = zoh(np.array([[a]]), np.array([[b]]), h)
    assert ad[0, 0] == pytest.approx(np.exp(a * h), rel=1e-15)  # expm of a scalar is exact to round-off
    assert bd[0, 0] == pytest.approx((np.exp(a * h) - 1) / a * b, rel=1e-14)


def test_zoh_integrator_needs_no_inverse():
    # a double integrator: singular A; B_D = [h²/2, h]
    ad, bd = zoh(np.array([[0.0, 1.0], [0.0, 0.0]]), np.array([[0.0], [1.0]]), 0.5)
    np.testing.assert_allclose(ad, [[1.0, 0.5], [0.0, 1.0]], rtol=0, atol=1e-15)
    np.testing.assert_allclose(bd.ravel(), [0.125, 0.5], rtol=1e-15)


@settings(max_examples=20, derandomize=True, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_zoh_matches_scipy_cont2discrete(seed):
    rng = np.random.default_rng(seed)
    n, m = int(rng.integers(1, 6)), int(rng.integers(1, 3))
    a, b = rng.standard_normal((n, n)), rng.standard_normal((n, m))
    ad, bd = zoh(a, b, 0.2)
    ad2, bd2, *_ = scipy.signal.cont2discrete((a, b, np.eye(n), np.zeros((n, m))), 0.2, method="zoh")
    # both are one expm of the same block matrix, evaluated independently: agree to round-off
    np.testing.assert_allclose(ad, ad2, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(bd, bd2, rtol=1e-12, atol=1e-14)


def test_van_loan_scalar_closed_form():
    # ∫₀ʰ e^{2aτ} w dτ = w (e^{2ah} − 1) / (2a)
    a, w, h = -1.3, 0.8, 0.4
    q = van_loan(np.array([[a]]), np.array([[w]]), h)
    assert q[0, 0] == pytest.approx(w * (np.exp(2 * a * h) - 1) / (2 * a), rel=1e-13)


@settings(max_examples=10, derandomize=True, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_van_loan_matches_quadrature(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 5))
    a = rng.standard_normal((n, n))
    bb = rng.standard_normal((n, 2))
    w = bb @ bb.T
    h = 0.3
    quad, err = scipy.integrate.quad_vec(lambda s: scipy.linalg.expm(a * s) @ w @ scipy.linalg.expm(a.T * s), 0.0, h, epsabs=1e-14, epsrel=1e-13)
    # adaptive quadrature is accurate to its own error estimate; 1e-10 covers it with margin
    np.testing.assert_allclose(van_loan(a, w, h), quad, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("h", [0.0, -0.1, float("nan"), float("inf"), "fast"])
def test_bad_sample_time_is_refused(h):
    with pytest.raises(ArgumentError, match="positive"):
        zoh(np.eye(2), np.ones((2, 1)), h)  # type: ignore[arg-type]


def test_discretise_uses_van_loan_for_process_noise():
    a = np.array([[-1.0, 0.5], [0.0, -2.0]])
    q = np.diag([0.3, 0.1])
    plant = LinearPlant.create(A=a, B=np.ones((2, 1)), C=np.eye(2), E=np.array([[1.0], [0.0]]), Q=q, R=np.eye(2))
    d = plant.discretise(0.05)
    np.testing.assert_allclose(d.Q, van_loan(a, q, 0.05), rtol=1e-15)
    ad, bd = zoh(a, np.hstack([plant.B, plant.E]), 0.05)
    np.testing.assert_allclose(d.A, ad, rtol=1e-15)
    np.testing.assert_allclose(np.hstack([d.B, d.E]), bd, rtol=1e-15)
    with pytest.raises(ArgumentError, match="already discrete"):
        d.discretise(0.05)
