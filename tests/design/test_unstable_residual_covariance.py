"""The residual covariance of an observer on an unstable plant: stationary, from the stable error dynamics.

The internal form (plant + generator) of an unstable plant is unstable, but an observer's residual
``r = V (y − C x̂ − D u)`` sees only the estimation error ``e = x − x̂``, whose dynamics ``e⁺ = (A − L C) e + w − L v``
are stable. Its covariance is the direct Lyapunov solve on those error dynamics; a generator whose residual sees
an unstable mode has none and is refused.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from fdisyn.models.linear import LinearPlant
from fdisyn.models.sampling import van_loan
from fdisyn.numerics.linalg import spectral_radius
from fdisyn.runtime.errors import ExistenceError
from fdisyn.runtime.gainfile import Generator
from fdisyn.synthesis.lmi_observer import lmi_diagnostic_observer
from fdisyn.synthesis.residual import internal_form, residual_covariance
from fdisyn.synthesis.sampled_data_observer import optimal_diagnostic_observer, sampled_data_generator

TS = 0.1


def _unstable_plant() -> LinearPlant:
    """Three states, one unstable mode (``+0.3``, ``|e^{0.3 Ts}| = 1.03``), one disturbance, two sensors."""
    a = np.array([[0.3, 1.0, 0.0], [0.0, -1.0, 0.5], [0.2, 0.0, -2.0]])
    return LinearPlant.create(
        A=a,
        B=np.array([[0.0], [1.0], [0.5]]),
        C=np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
        E=np.array([[0.0], [1.0], [0.0]]),
        Fx=np.array([[1.0], [0.0], [0.0]]),
        Q=0.01 * np.eye(3),
        R=np.diag([0.04, 0.09]),
    )


DESIGNS = {
    "sampled_data_observer": lambda *, plant: optimal_diagnostic_observer(plant=plant, design="direct"),
    "lmi": lambda *, plant: lmi_diagnostic_observer(plant=plant, eta="inf"),
}


@pytest.mark.parametrize("method", sorted(DESIGNS))
def test_an_unstable_plant_has_the_error_dynamics_residual_covariance(method: str) -> None:
    plant = _unstable_plant()
    gen, cov, cert = sampled_data_generator(DESIGNS[method])(plant, [0, 1], "g", Ts=TS)
    assert cert.passed
    phys = plant.discretise(TS)
    noise = phys.with_noise(Q=np.asarray(phys.Q) + van_loan(np.asarray(plant.A), np.asarray(plant.E) @ np.asarray(plant.E).T, TS))
    assert spectral_radius(internal_form(gen, noise).A) > 1.02  # the full internal form has no stationary law
    # the generator is an observer: Ar = F = A − L C, Cr = −W = −V C, Dy = V
    a, c, l_gain, v = noise.A, noise.C, gen.By, gen.Dy
    np.testing.assert_allclose(gen.Ar, a - l_gain @ c, atol=1e-12 * np.linalg.norm(a))
    np.testing.assert_allclose(gen.Cr, -v @ c, atol=1e-12 * np.linalg.norm(v @ c))
    assert spectral_radius(gen.Ar) < 1.0
    p = scipy.linalg.solve_discrete_lyapunov(gen.Ar, noise.Q + l_gain @ noise.R @ l_gain.T)
    direct = v @ c @ p @ c.T @ v.T + v @ noise.R @ v.T
    np.testing.assert_allclose(cov, direct, rtol=1e-9, atol=1e-12 * np.linalg.norm(direct))
    np.testing.assert_array_equal(cov, residual_covariance(gen, noise))


def test_a_residual_that_sees_an_unstable_mode_has_no_covariance() -> None:
    """``r = y`` (no observer) sees the unstable mode: refused, not a covariance of a diverging signal."""
    noise = _unstable_plant().discretise(TS).with_noise(Q=1e-2 * np.eye(3))
    raw = Generator.from_canonical(
        name="raw", outputs_used=[0, 1], Ar=np.zeros((0, 0)), Bu=np.zeros((0, 1)), By=np.zeros((0, 2)),
        Cr=np.zeros((2, 0)), Du=np.zeros((2, 1)), Dy=np.eye(2),
    )
    with pytest.raises(ExistenceError, match="sees a mode of the plant on or outside the unit circle"):
        residual_covariance(raw, noise)


def test_a_stable_plant_keeps_the_full_internal_form_solve() -> None:
    """Schur stable internal form: the covariance is the Lyapunov solve on ``[x; ξ]``, bit for bit."""
    from fdisyn.numerics.linalg import dlyap

    plant = _unstable_plant()
    stable = LinearPlant.create(A=plant.A - np.eye(3), B=plant.B, C=plant.C, E=plant.E, Fx=plant.Fx, Q=plant.Q, R=plant.R)
    gen, cov, _ = sampled_data_generator(DESIGNS["sampled_data_observer"])(stable, [0, 1], "g", Ts=TS)
    noise = stable.discretise(TS)
    noise = noise.with_noise(Q=np.asarray(noise.Q) + van_loan(np.asarray(stable.A), np.asarray(stable.E) @ np.asarray(stable.E).T, TS))
    form = internal_form(gen, noise)
    assert spectral_radius(form.A) < 1.0
    bw = np.vstack([np.eye(3), np.zeros((gen.n_state, 3))])
    bv = np.vstack([np.zeros((3, 2)), gen.By])
    s = form.C @ dlyap(form.A, bw @ noise.Q @ bw.T + bv @ noise.R @ bv.T) @ form.C.T + gen.Dy @ noise.R @ gen.Dy.T
    np.testing.assert_array_equal(cov, 0.5 * (s + s.T))
