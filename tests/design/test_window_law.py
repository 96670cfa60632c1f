"""The laws of the windowed residual statistics (fdisyn.detectors.window) against independent truths.

Truths: closed forms (a white residual: ``N s²/σ² ~ χ²(N p)``; equal weights: a scaled χ²; weights in pairs:
the hypoexponential law; two weights: the one-dimensional integral over one of them given the other), the
impulse-response sum of the autocovariance, its recursion identity over random stable systems (hypothesis), a
long simulation of the Beard filter itself (plant and observer, with an input and a feedthrough) within
Bartlett's (1946) standard error of the sample autocovariance, and independent simulated windows whose
exceedance counts must fall in the binomial interval.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.integrate
import scipy.linalg
import scipy.optimize
import scipy.stats
from fdisyn.evaluation.metrics import binomial_interval
from fdisyn.detectors import window as law
from fdisyn.detectors.window import (
    QUANTILE_RTOL,
    beard_residual_autocovariance,
    quadratic_form_quantile,
    quadratic_form_sf,
    residual_autocovariance,
    window_mean_level,
    window_rms_threshold,
)
from fdisyn.runtime.errors import ArgumentError, ExistenceError, ShapeError
from hypothesis import given, settings
from hypothesis import strategies as st

# A Beard-type filter on a two-state, two-output plant with an input: G = A − L C has eigenvalues 0.7 and 0.6
# (correlated residual), correlated measurement noise.
A = np.array([[0.95, 0.1], [0.0, 0.8]])
B = np.array([[0.5], [1.0]])
C = np.eye(2)
D = np.array([[0.2], [-0.1]])
L = np.array([[0.25, 0.1], [0.05, 0.2]])
Q = np.diag([0.05, 0.02])
R = np.array([[0.1, 0.03], [0.03, 0.2]])


def rel(a: float, b: float) -> float:
    return abs(a - b) / abs(b)


# --- closed forms ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("window, p", [(1, 1), (5, 2), (20, 3), (50, 1)])
@pytest.mark.parametrize("P_f", [0.05, 1e-4, 1e-8])
def test_white_residual_is_scaled_chi2(window, p, P_f):
    """``ε ~ N(0, σ² I_p)`` white: ``N s²/σ² = Σ_j ‖ε(k−j)‖²/σ² ~ χ²(N p)`` (``s`` sums the squared norm of each
    sample over the window and divides by ``N``, as the runtime does) and ``N ‖m‖²/σ² ~ χ²(p)``."""
    sigma = 0.7
    r_list = [sigma**2 * np.eye(p)] + [np.zeros((p, p))] * (window - 1)
    h = window_rms_threshold(r_list, window, P_f)
    assert rel(h, sigma * math.sqrt(scipy.stats.chi2.isf(P_f, window * p) / window)) < 1e-12
    level = window_mean_level(r_list, window, P_f)
    assert rel(level, sigma * math.sqrt(scipy.stats.chi2.isf(P_f, p) / window)) < 1e-12


@pytest.mark.parametrize("n", [1, 2, 7, 300])
@pytest.mark.parametrize("P_f", [0.5, 1e-3, 1e-8])
def test_equal_weights_are_scaled_chi2(n, P_f):
    assert rel(quadratic_form_quantile([2.5] * n, P_f), 2.5 * scipy.stats.chi2.isf(P_f, n)) < 1e-12
    # zero weights add nothing
    assert rel(quadratic_form_quantile([0.0] * 3 + [2.5] * n, P_f), 2.5 * scipy.stats.chi2.isf(P_f, n)) < 1e-12


def test_no_weight_is_the_point_mass_at_zero():
    assert quadratic_form_quantile([0.0, 0.0], 0.01) == 0.0
    assert quadratic_form_sf(0.5, []) == 0.0


# --- Imhof's integral against exact laws -----------------------------------------------------------------------


@pytest.mark.parametrize("n", [2, 5, 50, 2000])
@pytest.mark.parametrize("P_f", [0.1, 1e-8])
def test_nearly_equal_weights(n, P_f):
    """``Σ Z_i² + δ Z_1²``: the quantile of ``χ²_n`` moves by ``δ x/n`` to first order (``E[Z_1² | Σ Z_i² = x]
    = x/n``), ``δ = 1e-7`` — 1e-3 of the move is below 1e-10 relative, so Imhof's integral (not the χ² shortcut,
    whose bounds are 1e-7 apart) must find it to :data:`QUANTILE_RTOL`."""
    weights = np.ones(n)
    weights[0] += 1e-7
    exact = scipy.stats.chi2.isf(P_f, n)
    assert rel(quadratic_form_quantile(weights, P_f), exact * (1 + 1e-7 / n)) < QUANTILE_RTOL


def hypoexponential_sf(x: float, weights: np.ndarray) -> float:
    """``P(Σ λ_j (Z_j² + Z_j'²) > x)`` for distinct ``λ_j``: a sum of exponentials of means ``2 λ_j``."""
    return float(sum(np.exp(-x / (2 * lj)) * np.prod(lj / (lj - np.delete(weights, j))) for j, lj in enumerate(weights)))


@pytest.mark.parametrize("pairs", [(1.0, 0.5), (1.0, 0.3, 0.1), (2.0, 1.8, 0.02)])
@pytest.mark.parametrize("P_f", [1e-2, 1e-5, 1e-8])
def test_weights_in_pairs_against_the_hypoexponential_law(pairs, P_f):
    lam = np.array(pairs)
    exact = scipy.optimize.brentq(lambda x: hypoexponential_sf(x, lam) - P_f, 1e-3, 500.0, xtol=1e-300, rtol=1e-14)
    got = quadratic_form_quantile(np.repeat(lam, 2), P_f)
    assert rel(got, exact) < QUANTILE_RTOL
    assert abs(quadratic_form_sf(exact, np.repeat(lam, 2)) - P_f) < 1e-13


def test_a_dominating_pair_near_the_median():
    """One pair of weight 1 and four pairs below 1e-3 at ``P_f = 0.5``: accepting Imhof evaluations at a QUADPACK
    error estimate of 1e-3 of ``P_f`` (instead of 1e-5) let the quantile be 6e-5 off here."""
    lam = np.array([1.0, 9.53501204e-04, 8.32634690e-04, 1.24966454e-04, 8.82903554e-05])
    exact = scipy.optimize.brentq(lambda x: hypoexponential_sf(x, lam) - 0.5, 1e-3, 50.0, xtol=1e-300, rtol=1e-14)
    assert rel(quadratic_form_quantile(np.repeat(lam, 2), 0.5), exact) < QUANTILE_RTOL


def two_weight_sf(x: float, small: float) -> float:
    """``P(Z_1² + small Z_2² > x) = E[P(Z_1² > x − small Z_2²)]``, integrated over ``Z_2 ≥ 0`` (twice)."""

    def integrand(z: float) -> float:
        return scipy.stats.norm.pdf(z) * scipy.stats.chi2.sf(max(x - small * z * z, 0.0), 1)

    kink = math.sqrt(x / small)
    # the normal density beyond 40 is below 1e-300: nothing to integrate there
    head = scipy.integrate.quad(integrand, 0.0, min(kink, 40.0), epsabs=1e-22, epsrel=1e-13, limit=500)[0]
    tail = scipy.stats.norm.sf(kink)  # beyond the kink the probability is one
    return 2.0 * (head + tail)


@pytest.mark.parametrize("small", [0.5, 1e-3, 1e-6, 1e-10])
@pytest.mark.parametrize("P_f", [1e-2, 1e-8])
def test_a_dominating_weight_against_the_conditional_integral(small, P_f):
    """One weight of 1 and one odd weight ``small``; the smaller, the more the integrand decays like ``u^{−3/2}``."""
    lo = scipy.stats.chi2.isf(P_f, 1)
    bracket = (lo * (1 - 1e-6), lo * (1 + 1e-6) + 100.0 * small)  # the quantile is lo plus about small · E[Z_2² | …]
    exact = scipy.optimize.brentq(lambda x: two_weight_sf(x, small) - P_f, *bracket, xtol=1e-300, rtol=1e-13)
    assert rel(quadratic_form_quantile([1.0, small], P_f), exact) < QUANTILE_RTOL


def test_scale_invariance_and_the_survival_function_at_the_quantile():
    weights = np.array([3.0, 1.0, 0.4, 0.4, 0.01])
    for P_f in (0.3, 1e-6):
        x = quadratic_form_quantile(weights, P_f)
        assert rel(quadratic_form_quantile(1e-6 * weights, P_f), 1e-6 * x) < 1e-9
        assert abs(quadratic_form_sf(x, weights) - P_f) < 1e-12 + 1e-9 * P_f


def test_liu_tang_zhang_fallback(monkeypatch):
    """Only where Imhof's integral cannot be evaluated; it is exact for equal weights (``l = n``) and, for spread
    weights, a few per cent off in the quantile at ``P_f = 0.01``."""
    n = 7
    assert rel(law._liu_tang_zhang_quantile(np.ones(n), 1e-6), scipy.stats.chi2.isf(1e-6, n)) < 1e-12
    weights = np.array([1.0, 0.7, 0.2, 0.05])
    imhof = quadratic_form_quantile(weights, 0.01)
    assert rel(law._liu_tang_zhang_quantile(weights, 0.01), imhof) < 0.03
    monkeypatch.setattr(law, "_imhof_sf", lambda x, lam, stretch=1.0: (math.nan, math.nan))
    with pytest.warns(RuntimeWarning, match="Liu, Tang & Zhang"):
        fallback = quadratic_form_quantile(weights, 0.01)
    assert fallback == law._liu_tang_zhang_quantile(weights, 0.01)
    with pytest.raises(ExistenceError):
        quadratic_form_sf(1.0, weights)


# --- the autocovariance ----------------------------------------------------------------------------------------


def random_system(rng: np.random.Generator, n: int, p: int, q: int, radius: float) -> tuple[np.ndarray, ...]:
    g = rng.standard_normal((n, n))
    g *= radius / max(np.max(np.abs(np.linalg.eigvals(g))), 1e-12)
    k = rng.standard_normal((n, q))
    c = rng.standard_normal((p, n))
    dn = rng.standard_normal((p, q))
    f = rng.standard_normal((q, q))
    return g, k, c, dn, f @ f.T + 0.1 * np.eye(q)


def test_autocovariance_against_the_impulse_response_sum():
    """``ε = Σ_j H_j n(k−j)``, ``H_0 = Dn``, ``H_j = C G^{j−1} K``: ``R(τ) = Σ_j H_{j+τ} W H_jᵀ``; at spectral
    radius 0.8 the terms beyond 400 are below 0.8^400 ≈ 1e-39 of the first."""
    rng = np.random.default_rng(11)
    g, k, c, dn, w = random_system(rng, 4, 3, 5, 0.8)
    h = [dn] + [c @ np.linalg.matrix_power(g, j - 1) @ k for j in range(1, 420)]
    got = residual_autocovariance(g, k, c, dn, w, 6)
    for tau in range(7):
        want = sum(h[j + tau] @ w @ h[j].T for j in range(len(h) - tau))
        assert np.linalg.norm(got[tau] - want) <= 1e-12 * np.linalg.norm(got[0])


@settings(max_examples=40, deadline=None)
@given(
    n=st.integers(1, 5),
    p=st.integers(1, 3),
    q=st.integers(1, 4),
    radius=st.floats(0.0, 0.97),
    key=st.integers(0, 2**32 - 1),
)
def test_autocovariance_identity_over_random_stable_systems(n, p, q, radius, key):
    """``R(0) = C Σ Cᵀ + Dn W Dnᵀ``, ``R(τ) = C G^τ Σ Cᵀ + C G^{τ−1} K W Dnᵀ`` (τ ≥ 1) with ``Σ`` from SciPy's
    Lyapunov solver (not the one used inside)."""
    g, k, c, dn, w = random_system(np.random.default_rng(key), n, p, q, radius)
    sigma = scipy.linalg.solve_discrete_lyapunov(g, k @ w @ k.T)
    got = residual_autocovariance(g, k, c, dn, w, 5)
    scale = np.linalg.norm(c) ** 2 * np.linalg.norm(sigma) + np.linalg.norm(dn) ** 2 * np.linalg.norm(w)
    assert np.linalg.norm(got[0] - (c @ sigma @ c.T + dn @ w @ dn.T)) <= 1e-9 * scale
    for tau in range(1, 6):
        want = c @ np.linalg.matrix_power(g, tau) @ sigma @ c.T + c @ np.linalg.matrix_power(g, tau - 1) @ k @ w @ dn.T
        assert np.linalg.norm(got[tau] - want) <= 1e-9 * scale


def test_beard_autocovariance_against_a_long_simulation():
    """Plant ``x⁺ = A x + B u + w``, ``y = C x + D u + v`` and the filter ``x̂⁺ = A x̂ + B u + L ε``,
    ``ε = y − C x̂ − D u``, simulated as written. Each sample autocovariance ``(1/T) Σ ε_a(k+τ) ε_b(k)`` is within
    5 of Bartlett's (1946) standard errors ``sqrt((1/T) Σ_h [R_aa(h) R_bb(h) + R_ab(τ−h) R_ab(τ+h)])`` (Gaussian
    fourth moments, Isserlis) of the law: for 2 × 2 × 6 entries a failure by chance has probability below 2e-5."""
    rng = np.random.default_rng(5)
    steps, burn, lags = 100_000, 200, 5
    wq = np.linalg.cholesky(Q)
    vr = np.linalg.cholesky(R)
    x = np.zeros(2)
    xhat = np.zeros(2)
    eps = np.empty((steps, 2))
    u = rng.standard_normal((steps + burn, 1))
    w = rng.standard_normal((steps + burn, 2)) @ wq.T
    v = rng.standard_normal((steps + burn, 2)) @ vr.T
    for k in range(steps + burn):
        y = C @ x + D @ u[k] + v[k]
        e = y - C @ xhat - D @ u[k]
        if k >= burn:
            eps[k - burn] = e
        x = A @ x + B @ u[k] + w[k]
        xhat = A @ xhat + B @ u[k] + L @ e
    law_r = beard_residual_autocovariance(A, C, L, Q, R, 200)

    def r_at(tau: int) -> np.ndarray:
        return law_r[tau] if tau >= 0 else law_r[-tau].T

    for tau in range(lags + 1):
        sample = eps[tau:].T @ eps[: steps - tau] / (steps - tau)
        for a in range(2):
            for b in range(2):
                var = sum(r_at(h)[a, a] * r_at(h)[b, b] + r_at(tau - h)[a, b] * r_at(tau + h)[a, b] for h in range(-150, 151))
                assert abs(sample[a, b] - law_r[tau][a, b]) <= 5.0 * math.sqrt(var / (steps - tau)), (tau, a, b)


# --- the thresholds against simulated windows ------------------------------------------------------------------


def simulated_windows(rng: np.random.Generator, runs: int, window: int, burn: int) -> np.ndarray:
    """``runs`` independent stationary windows ``ε(k−N+1) … ε(k)`` of the error dynamics
    ``e⁺ = (A − L C) e + w − L v``, ``ε = C e + v``, each from ``e = 0`` after ``burn`` steps (the initial
    condition's share of the covariance is ``ρ(G)^{2·burn}``)."""
    g = A - L @ C
    wq, vr = np.linalg.cholesky(Q), np.linalg.cholesky(R)
    e = np.zeros((runs, 2))
    out = np.empty((window, runs, 2))
    for k in range(burn + window):
        w = rng.standard_normal((runs, 2)) @ wq.T
        v = rng.standard_normal((runs, 2)) @ vr.T
        if k >= burn:
            out[k - burn] = e @ C.T + v
        e = e @ g.T + w - v @ L.T
    return out


@pytest.mark.parametrize("P_f", [0.01, 0.002])
def test_thresholds_against_independent_simulated_windows(P_f):
    """``s > h`` and ``‖m‖ > ε̄`` on 100 000 independent windows of 8 samples: counts within the binomial interval
    of level 1e-3. The law that ignores the correlation (the eigenvalues of ``R(0)`` repeated ``N`` times) gives
    counts outside it, so the test tells the two apart."""
    window, runs = 8, 100_000
    eps = simulated_windows(np.random.default_rng(23), runs, window, 120)  # ρ(G)^240 = 0.7^240 ≈ 1e-37
    s = np.sqrt(np.mean(np.sum(eps**2, axis=2), axis=0))
    m = np.linalg.norm(np.mean(eps, axis=0), axis=1)
    r_list = beard_residual_autocovariance(A, C, L, Q, R, window - 1)
    lo, hi = binomial_interval(runs, P_f)
    assert lo <= int(np.sum(s > window_rms_threshold(r_list, window, P_f))) <= hi
    assert lo <= int(np.sum(m > window_mean_level(r_list, window, P_f))) <= hi
    white = math.sqrt(quadratic_form_quantile(np.tile(np.linalg.eigvalsh(r_list[0]), window), P_f) / window)
    assert not lo <= int(np.sum(s > white)) <= hi


def test_a_long_window():
    """``N p = 1000``. ``N s² = ‖E‖²`` has mean ``N tr R(0)`` and variance ``2 tr Σ_E² = 2 Σ_{i,j} ‖R(j − i)‖_F²``;
    its upper tail is heavier than the normal one (positive skewness), so at ``P_f = 1e-6`` (``z = 4.75``) the
    threshold lies above the normal quantile and, for a window much longer than the correlation time, not far
    above it (below ``z = 8``). ``‖m‖ ≤ s`` sample by sample (Cauchy–Schwarz), hence for the quantiles too."""
    window, P_f = 500, 1e-6
    r_list = beard_residual_autocovariance(A, C, L, Q, R, window - 1)
    frob = np.sum(r_list**2, axis=(1, 2))
    mean = window * np.trace(r_list[0])
    sd = math.sqrt(2.0 * (window * frob[0] + 2.0 * np.sum((window - np.arange(1, window)) * frob[1:])))
    z = scipy.stats.norm.isf(P_f)
    h = window_rms_threshold(r_list, window, P_f)
    assert math.sqrt((mean + z * sd) / window) < h < math.sqrt((mean + 8.0 * sd) / window)
    assert window_mean_level(r_list, window, P_f) < h


# --- inputs ----------------------------------------------------------------------------------------------------


def one_line(exc: pytest.ExceptionInfo) -> bool:
    return "\n" not in str(exc.value)


@pytest.mark.parametrize("bad", [0, 1, -0.1, 1.5, math.nan, True, "0.01", None])
def test_false_alarm_probability_is_checked(bad):
    with pytest.raises(ArgumentError) as exc:
        quadratic_form_quantile([1.0, 2.0], bad)
    assert one_line(exc)


@pytest.mark.parametrize("bad", [0, -1, 2.5, math.inf, True, "3"])
def test_window_is_checked(bad):
    with pytest.raises(ArgumentError) as exc:
        window_rms_threshold([np.eye(2)] * 4, bad, 0.01)
    assert one_line(exc)


def test_inputs_are_checked():
    g, k, c, dn, w = random_system(np.random.default_rng(1), 3, 2, 4, 0.5)
    cases = [
        (ExistenceError, lambda: residual_autocovariance(np.diag([1.0, 0.5, 0.2]), k, c, dn, w, 3)),
        (ShapeError, lambda: residual_autocovariance(g, k[:2], c, dn, w, 3)),
        (ShapeError, lambda: residual_autocovariance(g, k, c, dn[:, :3], w, 3)),
        (ShapeError, lambda: residual_autocovariance(g[:2], k, c, dn, w, 3)),
        (ArgumentError, lambda: residual_autocovariance(g, k, c, dn, -w, 3)),
        (ArgumentError, lambda: residual_autocovariance(g, np.where(k > 0, np.nan, k), c, dn, w, 3)),
        (ArgumentError, lambda: residual_autocovariance(g, k, c, dn, w, -1)),
        (ArgumentError, lambda: residual_autocovariance(g, k, c, dn, w, 1.5)),
        (ExistenceError, lambda: beard_residual_autocovariance(np.diag([1.01, 0.5]), C, np.zeros((2, 2)), Q, R, 2)),
        (ShapeError, lambda: beard_residual_autocovariance(A, C, L[:, :1], Q, R, 2)),
        (ArgumentError, lambda: quadratic_form_quantile([1.0, -0.5], 0.01)),
        (ArgumentError, lambda: quadratic_form_quantile([1.0, math.inf], 0.01)),
        (ArgumentError, lambda: quadratic_form_sf(math.nan, [1.0])),
        (ShapeError, lambda: window_rms_threshold([np.eye(2)] * 3, 4, 0.01)),
        (ShapeError, lambda: window_mean_level(np.ones((4, 2, 3)), 2, 0.01)),
        (ArgumentError, lambda: window_rms_threshold([np.eye(2), np.full((2, 2), np.nan)], 2, 0.01)),
        (ArgumentError, lambda: window_rms_threshold([np.eye(2), 5.0 * np.eye(2)], 2, 0.01)),  # |R(1)| > R(0)
        (ArgumentError, lambda: window_mean_level([-np.eye(2)], 1, 0.01)),
        (ExistenceError, lambda: window_rms_threshold([np.zeros((2, 2))] * 3, 3, 0.01)),
        (ExistenceError, lambda: window_mean_level([np.eye(1), -np.eye(1)], 2, 0.01)),  # m ≡ 0 for N = 2
        (ArgumentError, lambda: window_rms_threshold([np.eye(3)] * 3000, 3000, 0.01)),
    ]
    for error, call in cases:
        with pytest.raises(error) as exc:
            call()
        assert one_line(exc), exc.value
