"""Designs that do not depend on the units of the states: automatic balancing, exact mapping back, scale-free tests.

A two-mass spring–damper in SI units sampled at 10 ms (stiffness 1e3–1e5 N/m: velocities a hundred times the
positions in a balanced realisation) failed every UIO design in the states it was written in (IPOPT's iteration
limit, a DARE residual 4e-9 over its bound); designed in the balanced states of
:meth:`fdisyn.models.linear.LinearPlant.balancing` and mapped back, every linear method designs it.
"""

from __future__ import annotations

import numpy as np
import pytest

import fdisyn
from fdisyn.models.linear import LinearPlant
from fdisyn.numerics.linalg import state_balancing, unobservable_modes
from fdisyn.numerics.riccati import solve_filter_dare
from fdisyn.runtime.errors import ExistenceError
from fdisyn.synthesis.uio import design_coordinates, kalman_uio, uio_pole_placement

TS = 0.01
PAIRS = [["y_x1", "y_v2"], ["y_x2", "y_v2"]]


def mass_spring(m1: float, m2: float, k1: float, k2: float, c1: float, c2: float, force: float, rx: float, rv: float) -> LinearPlant:
    """ground –k1,c1– m1 –k2,c2– m2 (SI units); u pushes m1, the unknown force d pushes m2; sensors x1, x2, v2.
    ``force``: intensity (N²·s) of white force noise on each mass; ``rx``, ``rv``: sensor variances (m², m²/s²)."""
    a = np.array([
        [0.0, 1.0, 0.0, 0.0],
        [-(k1 + k2) / m1, -(c1 + c2) / m1, k2 / m1, c2 / m1],
        [0.0, 0.0, 0.0, 1.0],
        [k2 / m2, c2 / m2, -k2 / m2, -c2 / m2],
    ])
    b = np.array([[0.0], [1.0 / m1], [0.0], [0.0]])
    e = np.array([[0.0], [0.0], [0.0], [1.0 / m2]])
    return LinearPlant.create(
        A=a, B=b, C=np.eye(4)[[0, 2, 3]], E=e, Fx=b, Q=np.diag([0.0, force / m1**2, 0.0, force / m2**2]),
        R=np.diag([rx, rx, rv]), states=["x1", "v1", "x2", "v2"], inputs=["u"], outputs=["y_x1", "y_x2", "y_v2"],
        unknown_inputs=["d_m2"], component_faults=["f_m1"],
    )


# two plants where the design in the given states failed: IPOPT's iteration limit (kalman_uio_gos), and the
# DARE residual over its bound (kalman_uio with a bank of sensor pairs, kalman_uio_gos)
STIFF = dict(m1=3.1, m2=7.8, k1=7.38e4, k2=5.2e3, c1=14.0, c2=4.4, force=2.4, rx=2.2e-9, rv=1.5e-5)
SOFT = dict(m1=2.0, m2=2.6, k1=1.14e3, k2=1.77e3, c1=22.0, c2=20.0, force=2.9, rx=3.4e-9, rv=9.8e-4)


@pytest.mark.parametrize("params", [STIFF, SOFT], ids=["stiff", "soft"])
def test_mass_spring_in_si_units_designs_with_every_linear_method(params):
    plant = mass_spring(**params)
    discrete = plant.discretise(TS)
    for method, options in (
        ("kalman_uio", {"bank": PAIRS}),
        ("kalman_uio_paper", {"bank": PAIRS}),
        ("uio_pole_placement", {"bank": PAIRS, "poles": [0.5, 0.6, 0.7, 0.8]}),
        ("kalman_uio_gos", {}),
    ):
        gf = fdisyn.design(discrete, method, **options)
        assert gf.certificate["passed"], method
    for method in ("lmi", "sampled_data_observer"):
        assert fdisyn.design(plant, method, Ts=TS).certificate["passed"], method


def test_the_design_is_the_same_in_any_state_units():
    """The same plant in mm and mm/s (or any positive state scaling): the generators' transfers from (u, y) to r
    and the thresholds agree to round-off, and the balancing of the two plants differs only by the units."""
    plant = mass_spring(**STIFF).discretise(TS)
    rng = np.random.default_rng(7)
    for scale in ([1e-3, 1e-3, 1e-3, 1e-3], 10.0 ** rng.uniform(-4, 4, 4)):
        other = LinearPlant.create(**{k: v for k, v in _matrices(plant.scaled(scale)).items()}, Ts=TS,
                                   outputs=plant.outputs, unknown_inputs=plant.unknown_inputs, component_faults=plant.component_faults)
        a = fdisyn.design(plant, "kalman_uio", bank=PAIRS)
        b = fdisyn.design(other, "kalman_uio", bank=PAIRS)
        for ga, gb in zip(a.generators, b.generators, strict=True):
            for ma, mb in zip(_markov(ga), _markov(gb), strict=True):
                np.testing.assert_allclose(mb, ma, rtol=1e-6, atol=1e-9 * np.abs(ma).max())
        for ea, eb in zip(a.evaluators, b.evaluators, strict=True):
            assert eb.threshold == pytest.approx(ea.threshold, rel=1e-12)
            np.testing.assert_allclose(eb.Sigma_r, ea.Sigma_r, rtol=1e-7)


def _matrices(p: LinearPlant) -> dict[str, np.ndarray]:
    return {k: np.asarray(getattr(p, k)) for k in ("A", "B", "C", "D", "E", "Fx", "Q", "R")}


def _markov(g) -> list[np.ndarray]:
    """``[Dy, Cr By, Cr Ar By, …]`` and the same for ``u``: the generator's transfer, whatever its state's units."""
    out, bu, by = [np.hstack([g.Du, g.Dy])], g.Bu, g.By
    for _ in range(g.Ar.shape[0] + 1):
        out.append(g.Cr @ np.hstack([bu, by]))
        bu, by = g.Ar @ bu, g.Ar @ by
    return out


def test_balancing_is_exact_and_the_identity_on_a_balanced_plant():
    plant = mass_spring(**STIFF).discretise(TS)
    s = plant.balancing()
    assert np.all(np.log2(s) == np.round(np.log2(s)))  # powers of two
    assert s[1] / s[0] >= 16 and s[3] / s[2] >= 16  # velocities ≫ positions in SI units at these stiffnesses
    balanced = plant.scaled(s)
    assert np.all(state_balancing(np.asarray(balanced.A), np.ones((4, 0)), np.asarray(balanced.C)) > 0)
    back = balanced.scaled(1.0 / s)  # exact: the same bits
    for k in ("A", "B", "C", "E", "Q"):
        assert np.array_equal(np.asarray(getattr(back, k)), np.asarray(getattr(plant, k))), k
    # a plant already balanced is designed in its own states, to the bit
    unbalanced = LinearPlant.create(**_matrices(balanced), Ts=TS, outputs=plant.outputs)
    assert np.all(unbalanced.balancing() == 1.0)
    assert design_coordinates(unbalanced)[1] is None


def test_a_scaled_plant_overrides_the_balancing():
    """``plant.scaled(s)`` (the plant file's ``state_scale``) is designed in the states given; the automatic
    balancing, and where it was used, is recorded in the certificate."""
    plant = mass_spring(**STIFF).discretise(TS).select_outputs([0, 2])
    auto = kalman_uio(plant)
    assert auto.certificate.info["state_scaling"] == plant.balancing().tolist()
    assert any(c.name.startswith("user's states:") for c in auto.certificate.checks)
    given = plant.scaled([0.01, 0.1, 0.01, 0.1])
    assert given.state_scale == (0.01, 0.1, 0.01, 0.1)
    assert design_coordinates(given) == (given, None)
    d = kalman_uio(given)
    assert "state_scaling" not in d.certificate.info
    # the same observer either way: its residual covariance (the user's states do not enter it)
    np.testing.assert_allclose(d.Sigma_r, auto.Sigma_r, rtol=1e-7)
    pp = uio_pole_placement(plant, poles=[0.5, 0.6, 0.7, 0.8])
    np.testing.assert_allclose(np.sort(np.abs(np.linalg.eigvals(pp.F))), [0.5, 0.6, 0.7, 0.8], atol=1e-9)


def test_detectability_does_not_depend_on_state_units():
    """The PBH test is made on the balanced pair with unit-norm sensor rows: a detectable pair stays detectable
    when its states are measured in units a million times apart (the unbalanced test called the mode 1 of this
    chain unobservable), and an unobservable mode stays found."""
    a = np.array([[1.0, 0.1, 0.0], [0.0, 1.0, 0.1], [0.0, 0.0, 0.5]])
    c = np.array([[1.0, 0.0, 0.0]])
    assert unobservable_modes(a, c, region="unstable-discrete") == []
    for s in ([1.0, 1e6, 1e-6], [1e-6, 1.0, 1e6], [1e4, 1e-4, 1.0]):
        sv = np.asarray(s)
        assert unobservable_modes(a / sv[:, None] * sv[None, :], c * sv[None, :], region="unstable-discrete") == []
    hidden = np.array([[1.2, 0.0], [0.0, 0.5]])
    for s in ([1.0, 1.0], [1e-6, 1e6]):
        sv = np.asarray(s)
        modes = unobservable_modes(hidden / sv[:, None] * sv[None, :], np.array([[0.0, 1.0]]) * sv[None, :], region="unstable-discrete")
        assert modes == [pytest.approx(1.2)]


def test_dare_solution_does_not_depend_on_the_noise_units():
    """A DARE whose noise is of size 1e-7 beside the pencil's identity blocks: solved with the noise scaled by a
    power of two, its relative residual is round-off (it was 3.7e-10, over the UIO certificate's 1e-10)."""
    plant = mass_spring(m1=1.8, m2=5.9, k1=2.65e3, k2=4.6e4, c1=1.3, c2=45.0, force=0.046, rx=3.2e-9, rv=8.9e-6)
    sub = plant.discretise(TS).select_outputs([0, 2])
    d = kalman_uio(sub)
    assert {c.name: c.value for c in d.certificate.checks}["DARE residual"] < 1e-13
    x = solve_filter_dare(np.diag([0.5, 0.9]), np.eye(2), 1e-7 * np.eye(2), 1e-9 * np.eye(2)).X
    y = solve_filter_dare(np.diag([0.5, 0.9]), np.eye(2), np.eye(2), 1e-2 * np.eye(2)).X
    np.testing.assert_allclose(x, 1e-7 * y, rtol=1e-12)


def test_no_noise_model_is_named():
    with pytest.raises(ExistenceError, match=r"no noise model: Q, R and S are all zero.*give the plant's noise covariances Q and R"):
        solve_filter_dare(np.diag([0.5, 0.9]), np.eye(2), np.zeros((2, 2)), np.zeros((2, 2)))
