"""Wind-turbine drive train with η as the parameter: the exact ZOH as an SX expression."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from fdisyn.models.sampling import zoh
from fdisyn.problems import wind_turbine_efficiency as wt
from fdisyn.problems.wind_turbine import PARAMETER_SETS, continuous_model


@pytest.mark.parametrize("eta", [0.5, 0.92, 0.97, 1.2])
def test_symbolic_zoh_equals_scipy_expm(eta: float) -> None:
    """The Taylor/squaring exponential in SX equals scipy's expm-based ZOH to 1e-14 relative
    (its truncation error is < 1e-19; what remains is the round-off of either method)."""
    ad, bd = (np.array(ca.evalf(v)) for v in wt.zoh_matrices(eta))
    a, b = wt.DRIVE_TRAIN.matrices(eta, twist_scale=wt.TWIST_SCALE)
    ad_ref, bd_ref = zoh(a, b, wt.TS)
    np.testing.assert_allclose(ad, ad_ref, rtol=1e-14, atol=1e-14 * np.max(np.abs(ad_ref)))
    for j in range(2):  # the input columns differ by 6 decades: compare each on its own scale
        np.testing.assert_allclose(bd[:, j], bd_ref[:, j], rtol=1e-12, atol=1e-14 * np.max(np.abs(bd_ref[:, j])))


def test_the_drive_train_is_the_wind_turbine_problems() -> None:
    """One model for both problems: symbolic and numeric ``A(η)`` agree to the bit, and at the nominal η
    it is the wind_turbine problem's continuous model with the twist in milliradians."""
    a_sx, b_sx = (np.array(ca.evalf(v)) for v in wt.DRIVE_TRAIN.matrices(ca.SX(0.93), twist_scale=wt.TWIST_SCALE))
    a, b = wt.DRIVE_TRAIN.matrices(0.93, twist_scale=wt.TWIST_SCALE)
    np.testing.assert_array_equal(a_sx, a)
    np.testing.assert_array_equal(b_sx, b)
    m = continuous_model(PARAMETER_SETS["benchmark"])
    t = np.diag([1.0, 1.0, wt.TWIST_SCALE])
    a0, b0 = wt.DRIVE_TRAIN.matrices(twist_scale=wt.TWIST_SCALE)
    np.testing.assert_allclose(a0, t @ m.A @ np.linalg.inv(t), rtol=1e-15, atol=0.0)
    np.testing.assert_array_equal(b0, np.hstack([m.E, m.B]))  # [τ_r, τ_g]


def test_benchmark_modes() -> None:
    """The benchmark drive train's modes: ≈ −0.0072 and −0.055 ± 28.16j (the 4.5 Hz torsional mode)."""
    a, _ = wt.DRIVE_TRAIN.matrices(twist_scale=wt.TWIST_SCALE)
    ev = np.sort_complex(np.linalg.eigvals(a))
    # reference: the same parameters' A written out by hand, eigenvalues by NumPy: −0.0072367 and
    # −0.0549572 ± 28.1633456j; tolerances 5e-5 and 5e-4 cover the rounding of the values below
    np.testing.assert_allclose(ev.real, [-0.05496, -0.05496, -0.00724], atol=5e-5)
    np.testing.assert_allclose(np.abs(ev.imag), [28.1633, 28.1633, 0.0], atol=5e-4)


def test_operating_point_is_an_equilibrium() -> None:
    pl = wt.plant()
    x0, u0 = wt.operating_point()
    step = np.array(pl.f(x0, u0, wt.ETA_NOMINAL)).reshape(-1) - x0
    assert np.max(np.abs(step) / np.maximum(np.abs(x0), 1e-3)) < 1e-12  # round-off of A_D x + B_D u


def test_eta_sensitivity_is_automatic_differentiation() -> None:
    """∂f/∂η from AD through the series equals a central difference (step 1e-6, error ~1e-12)."""
    pl = wt.plant()
    x0, u0 = wt.operating_point()
    lin = pl.linearise(x=x0, u=u0, theta=[0.95])
    h = 1e-6
    fd = (np.array(pl.f(x0, u0, 0.95 + h)) - np.array(pl.f(x0, u0, 0.95 - h))).reshape(-1) / (2 * h)
    # the difference's round-off is eps·|f_i|/h: 3e-8 on ω_g (|f| = 152, entry 0.4 → rtol 1e-6) and
    # 4e-10 on ω_r (|f| = 1.6, entry 3.5e-6 → atol 1e-9)
    np.testing.assert_allclose(lin["F_theta"].reshape(-1), fd, rtol=1e-6, atol=1e-9)


def test_claims_of_the_efficiency_drop():
    from tests.helpers import check_claims, claims_context, scenario_metrics

    drop = scenario_metrics("eta_drop", "eta", Ts=wt.TS, detection_delay_mean_s=0.46, detection_delay_max_s=0.72,
                            isolation_accuracy=0.98, extra={"isolation delay median (samples)": 405.0,
                                                            "size error eta: mean": -2e-5, "size error eta: sd": 1.2e-3})
    claims = wt.PROBLEM.claims(claims_context(wt.PROBLEM, [{"label": "default", "metrics": {"nafdf": {"eta_drop": drop}}}]))
    check_claims(claims)
    assert [c.verdict for c in claims] == ["reproduced"] * 3
    assert {"eta", "theta_hat_eta", "wssr", "tau_r", "omega_g", "nafdf"} <= set(wt.PROBLEM.labels)
