"""The filtering DARE (SciPy on the dual problem, the pencil for diagnosis) against closed forms and invariants."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from fdisyn.numerics.riccati import dare_pencil_eigenvalues, dare_residual, solve_filter_dare
from fdisyn.runtime.errors import ExistenceError, SolverError
from hypothesis import given, settings
from hypothesis import strategies as st


def test_scalar_closed_form():
    # X = a²X + q − a²c²X²/(c²X + r)  ⇔  c²X² + (r − a²r − q c²) X − q r = 0 (positive root)
    a, c, q, r = 1.2, 0.7, 0.3, 0.5
    bq = r - a * a * r - q * c * c
    x = (-bq + np.sqrt(bq * bq + 4 * c * c * q * r)) / (2 * c * c)
    sol = solve_filter_dare([[a]], [[c]], [[q]], [[r]])
    assert sol.X[0, 0] == pytest.approx(x, rel=1e-14)
    assert sol.L[0, 0] == pytest.approx(a * x * c / (c * c * x + r), rel=1e-14)
    assert abs(sol.closed_loop_eigenvalues[0]) < 1


def test_zero_measurement_noise_full_state_closed_form():
    # C = I, R = 0, S = 0: X = A X Aᵀ + Q − A X X⁻¹ X Aᵀ = Q and L = A (deadbeat); the DTARS of
    # Qiu, Wen & Jiang (Control Theory & Applications 27(8), 2010, Lemma 4)
    rng = np.random.default_rng(0)
    a = rng.standard_normal((3, 3))
    b = rng.standard_normal((3, 3))
    q = b @ b.T
    sol = solve_filter_dare(a, np.eye(3), q, np.zeros((3, 3)))
    np.testing.assert_allclose(sol.X, q, rtol=1e-11, atol=1e-12 * np.abs(q).max())  # cond(Q)·eps level
    np.testing.assert_allclose(sol.L, a, rtol=1e-10, atol=1e-11)
    assert np.max(np.abs(sol.closed_loop_eigenvalues)) < 1e-6  # A − L C = 0: all eigenvalues at the origin


@settings(max_examples=30, derandomize=True, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_cross_term_solution_is_stabilising_and_matches_the_pencil(seed):
    rng = np.random.default_rng(seed)
    n, p = int(rng.integers(1, 6)), int(rng.integers(1, 4))
    a = rng.standard_normal((n, n)) * rng.uniform(0.3, 1.5)
    c = rng.standard_normal((p, n))
    g = rng.standard_normal((n + p, n + p))
    joint = g @ g.T + 0.1 * np.eye(n + p)  # joint covariance of (w, v): makes [[Q, S], [Sᵀ, R]] ⪰ 0
    q, s, r = joint[:n, :n], joint[:n, n:], joint[n:, n:]
    sol = solve_filter_dare(a, c, q, r, s)
    assert sol.residual < 1e-11
    assert dare_residual(a, c, q, r, s, sol.X) == sol.residual
    assert np.max(np.abs(sol.closed_loop_eigenvalues)) < 1
    # SciPy's X and the pencil's eigenvalues are independent computations: A − L C has the
    # pencil's stable eigenvalues (measured ≤ 5e-12 apart over 300 draws)
    eig = dare_pencil_eigenvalues(a, c, q, r, s)
    stable = eig[np.abs(eig) < 1]
    assert stable.size == n
    gap = np.abs(sol.closed_loop_eigenvalues[:, None] - stable[None, :])
    assert max(gap.min(axis=0).max(), gap.min(axis=1).max()) < 1e-9


@settings(max_examples=20, derandomize=True, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_stabilising_solution_is_the_kalman_fixed_point(seed):
    # iterate the Riccati difference equation from 0: it converges to the stabilising solution
    rng = np.random.default_rng(seed)
    n, p = int(rng.integers(1, 5)), int(rng.integers(1, 3))
    a = rng.standard_normal((n, n))
    a *= rng.uniform(0.3, 0.95) / max(abs(np.linalg.eigvals(a)))
    c = rng.standard_normal((p, n))
    q, r = np.eye(n) * rng.uniform(0.1, 2), np.eye(p) * rng.uniform(0.1, 2)
    x = np.zeros((n, n))
    for _ in range(5000):
        gain = a @ x @ c.T @ np.linalg.inv(c @ x @ c.T + r)
        nxt = a @ x @ a.T + q - gain @ c @ x @ a.T
        # the iteration contracts at rate ρ(A − LC)² < 0.95²: at most 5000 steps reach round-off, a few hundred
        # usually do; once a step moves x by 1e-14 of itself, what is left is below 1e-14 / (1 − 0.95²) ≈ 1e-13
        done = np.linalg.norm(nxt - x) <= 1e-14 * np.linalg.norm(nxt)
        x = nxt
        if done:
            break
    sol = solve_filter_dare(a, c, q, r)
    np.testing.assert_allclose(sol.X, x, rtol=1e-9, atol=1e-12)


def test_undetectable_unstable_mode_has_no_stabilising_solution():
    a = np.diag([1.5, 0.5])
    c = np.array([[0.0, 1.0]])  # the unstable mode is invisible
    with pytest.raises(ExistenceError, match=r"\(C, A\) is not detectable \(mode λ = 1.5"):
        solve_filter_dare(a, c, np.eye(2), np.eye(1))


def test_mode_on_the_unit_circle_without_noise_is_refused():
    a = np.diag([1.0, 0.5])
    c = np.array([[1.0, 1.0]])
    q = np.diag([0.0, 1.0])  # the marginal mode is seen but never excited: pencil eigenvalues on the circle
    with pytest.raises(ExistenceError, match="unit circle"):
        solve_filter_dare(a, c, q, np.eye(1))


def test_a_failed_reordering_of_a_pencil_with_unit_circle_eigenvalues_names_the_circle(monkeypatch):
    """LAPACK's reordering inside SciPy's solver may fail on such a pencil (it does with OpenBLAS's
    SandyBridge kernel); the existence condition, not the solver, is then what the user is told."""

    def failing_dare(*args, **kwargs):
        raise ValueError("Reordering of (A, B) failed")

    monkeypatch.setattr(scipy.linalg, "solve_discrete_are", failing_dare)
    a, c, q = np.diag([1.0, 0.5]), np.array([[1.0, 1.0]]), np.diag([0.0, 1.0])
    with pytest.raises(ExistenceError, match="eigenvalue\\(s\\) on the unit circle"):
        solve_filter_dare(a, c, q, np.eye(1))
    # fdisyn's explanation first, SciPy's words after it
    with pytest.raises(SolverError, match=r"^the DARE pencil's ordered QZ decomposition failed \(SciPy: Reordering"):
        solve_filter_dare(np.diag([0.9, 0.5]), c, np.eye(2), np.eye(1))
