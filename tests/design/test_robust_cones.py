"""The implicit thresholds of a Beard filter against independent truths: exact perturbed eigenvectors, finite
differences, sampled model errors; and the eigenstructure NLP against the assignments it starts from."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
from fdisyn.models.sampling import zoh
from fdisyn.numerics.detection_filter import beard_gain, beard_structure
from fdisyn.numerics.robust_cones import (
    HALF_PI,
    implicit_thresholds,
    output_subspaces,
    sampled_angles,
    sampled_model_error,
    subspace_angle,
)
from fdisyn.synthesis.beard_fdf.eigenstructure import admissible_gains, optimise_eigenstructure, residual_covariance_trace
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

JS, JP, K, B_ = 5.0, 1.0, 0.15, 0.05
A_SAT = np.array([[0, 0, 1, 0], [0, 0, 0, 1], [-K / JS, K / JS, -B_ / JS, B_ / JS], [K / JP, -K / JP, B_ / JP, -B_ / JP]])
B_SAT = np.array([[0, 0], [0, 0], [1 / JS, -1 / JS], [0, 1 / JP]])
TS = 0.1


def _satellite():
    ad, bd = zoh(A_SAT, B_SAT, TS)
    st_ = beard_structure(ad, np.eye(4), bd)
    return ad, bd, st_, [s.basis for s in st_.spaces]


def test_subspace_angle_closed_forms():
    basis = np.array([[1.0], [0.0]])
    assert subspace_angle(np.array([1.0, 1.0]), basis) == pytest.approx(np.pi / 4, abs=1e-15)
    assert subspace_angle(np.array([-3.0, 0.0]), basis) == 0.0  # a line: the sign of the fault is free
    assert subspace_angle(np.array([0.0, 2.0]), basis) == pytest.approx(HALF_PI)
    assert subspace_angle(np.zeros(2), basis) == HALF_PI
    assert subspace_angle(np.array([1.0, 1e-12]), basis) == pytest.approx(1e-12, rel=1e-12)  # atan2: no cancellation


def test_sampled_model_error_closed_forms():
    assert sampled_model_error(np.zeros((3, 3)), 0.2, 0.5) == pytest.approx(0.1, rel=1e-14)  # σ·Ts for A = 0
    assert sampled_model_error(A_SAT, None, 0.3) == 0.3  # a discrete A: the bound itself
    # a skew-symmetric A: e^{As} is orthogonal, every norm in the integrand is 1
    w = np.array([[0.0, 2.0], [-2.0, 0.0]])
    assert sampled_model_error(w, 0.7, 0.1) == pytest.approx(0.07, rel=1e-12)


def test_sampled_model_error_bounds_the_sampled_perturbation():
    """‖e^{(A+δA)Ts} − e^{ATs}‖ ≤ σ_d (1 + O(σ)): first order, so at σ = 1e-6 the ratio is ≤ 1 + 1e-5."""
    rng = np.random.default_rng(3)
    sigma = 1e-6
    sd = sampled_model_error(A_SAT, TS, sigma)
    for _ in range(50):
        d = rng.standard_normal((4, 4))
        d *= sigma / np.linalg.norm(d, 2)
        diff = np.linalg.norm(sla.expm((A_SAT + d) * TS) - sla.expm(A_SAT * TS), 2)
        assert diff <= sd * (1 + 1e-5)


def test_bound_is_attained_to_first_order():
    """Along its worst-case direction the exact angle / bound → 1 as σ → 0 (discrete: δG = δA exactly)."""
    ad, bd, st_, spaces = _satellite()
    lg = beard_gain(ad, np.eye(4), bd, [[0.3], [0.8], [0.5, 0.6]]).L
    g = ad - lg @ np.eye(4)
    sigma = 1e-7
    bound = implicit_thresholds(g, np.eye(4), spaces, sigma)
    ang = sampled_angles(ad, None, lg, np.eye(4), spaces, bound, sigma, draws=50)
    worst_rows = ang[-2:]  # the two first-order worst cases come last
    first_order = bound.coefficient * sigma
    for j in range(2):
        assert worst_rows[j, j] / first_order[j] == pytest.approx(1.0, abs=1e-5)  # a real worst case: attained
        assert np.all(ang[:, j] <= bound.Y[j])


def test_shared_eigenvalue_gives_a_half_space():
    """Every eigenvalue at one value: the perturbed eigen-directions are those of δG — arbitrary."""
    ad, bd, st_, spaces = _satellite()
    lg = beard_gain(ad, np.eye(4), bd, [[0.9], [0.9], [0.9, 0.9]]).L
    bound = implicit_thresholds(ad - lg, np.eye(4), spaces, 1e-4)
    assert np.all(bound.Y == HALF_PI) and np.all(np.isinf(bound.coefficient))
    ang = sampled_angles(A_SAT, TS, lg, np.eye(4), spaces, bound, 1e-3, draws=100)
    assert ang.max() > np.radians(80)  # the sampled truth agrees: a tiny δA turns the residual almost anywhere


def _random_case(seed: int):
    """A random discrete (A, C, F) with two faults and distinct random eigenvalues per block."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(4, 7))
    p = int(rng.integers(3, n + 1))
    a = rng.standard_normal((n, n)) / np.sqrt(n)
    c = rng.standard_normal((p, n))
    f = rng.standard_normal((n, 2))
    st_ = beard_structure(a, c, f)
    ev = rng.uniform(-0.8, 0.8, size=n)
    lists, start = [], 0
    for count in st_.free_counts:
        lists.append(list(ev[start : start + count]))
        start += count
    return a, c, f, st_, lists


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000))
def test_sampled_angles_stay_inside_the_bound(seed):
    """Property: over random plants and model errors ‖δA‖ = σ inside Stewart's range (η ≤ 0.2), the exact angle
    of every perturbed residual direction is at most Y_th (the first-order bound with its 1 + 2η margin)."""
    a, c, f, st_, lists = _random_case(seed)
    flat = np.concatenate(lists)
    if st_.fixed.size or min(abs(x - y) for i, x in enumerate(flat) for y in flat[i + 1 :]) < 0.05:
        return  # fixed modes or nearly repeated eigenvalues: another draw
    lg = beard_gain(a, c, f, lists).L
    spaces = [s.basis for s in st_.spaces]
    g = a - lg @ c
    lo, hi = 0.0, 1.0  # the σ where the largest η is 0.2, by bisection (η grows with σ)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if np.max(implicit_thresholds(g, c, spaces, mid).eta) < 0.2 else (lo, mid)
    bound = implicit_thresholds(g, c, spaces, lo)
    assert np.all(bound.in_range)
    ang = sampled_angles(a, None, lg, c, spaces, bound, lo, draws=30, seed=seed)
    assert np.all(ang <= bound.Y + 1e-12)
    first_order = bound.coefficient * lo
    assert np.max(ang / first_order) > 0.5  # and not vacuous: the worst cases come close to the first-order bound


def test_admissible_gains_keep_every_detection_space_invariant():
    ad, bd, st_, spaces = _satellite()
    l0, basis = admissible_gains(ad, np.eye(4), spaces)
    assert len(basis) == 16 - 6  # C = I: 3 equations per one-dimensional detection space
    rng = np.random.default_rng(0)
    lg = l0 + sum(rng.standard_normal() * b for b in basis)
    g = ad - lg
    for t in spaces:
        assert np.linalg.norm(g @ t - t @ (t.T @ g @ t)) < 1e-12


def test_optimised_eigenstructure_beats_the_spread_assignments():
    ad, bd, st_, spaces = _satellite()
    r = float(np.exp(-0.5 * TS))
    q = np.diag([0, 0, 1e-8, 1e-8])
    rr = np.diag([1e-8, 1e-8, 1e-9, 1e-9])
    lp = beard_gain(ad, np.eye(4), bd, [[r], [r], [r, r]]).L
    plain = residual_covariance_trace(ad - lp, lp, np.eye(4), q, rr)
    groups = [bd[:, :1], bd[:, 1:]]
    gains = [float(np.linalg.norm(np.linalg.solve(np.eye(4) - ad + lp, f))) for f in groups]
    res = optimise_eigenstructure(ad, np.eye(4), groups, st_, radius=r, Q=q, R=rr, noise_gain=2.0, separation=0.02,
                                  plain_trace=plain, plain_fault_gains=gains)
    g = ad - res.L
    eig = np.sort(np.linalg.eigvals(g).real)
    assert np.all(np.abs(np.linalg.eigvals(g).imag) < 1e-12)
    # IPOPT meets its constraints to its tolerance (1e-8 on the squared separation: 2.5e-7 on the separation)
    assert eig[0] >= -1e-7 and eig[-1] <= r + 1e-7 and np.min(np.diff(eig)) >= 0.02 - 1e-6
    best = np.max(implicit_thresholds(g, np.eye(4), spaces, 1.0).coefficient)
    for f, gp in zip(groups, gains, strict=True):  # the fault gain: at least half the plain filter's
        assert np.linalg.norm(np.linalg.solve(np.eye(4) - g, f)) >= gp / 2.0 * (1 - 1e-6)
    for lists in ([[0.92], [0.95], [0.3, 0.6]], [[0.95], [0.91], [0.2, 0.5]], [[0.93], [0.93 - 0.02], [0.0, 0.4]]):
        other = np.max(implicit_thresholds(ad - beard_gain(ad, np.eye(4), bd, lists).L, np.eye(4), spaces, 1.0).coefficient)
        assert best <= other * (1 + 1e-6)
    assert res.noise_ratio <= 2.0 + 1e-6
    assert output_subspaces(np.eye(4), spaces)[0].shape == (4, 1)
