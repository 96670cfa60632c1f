"""A nonlinear problem's runs (fdisyn.simulation.nonlinear.simulate_nonlinear_runs): each run is simulate_nonlinear on
its own seed, the kept truths are the plant's states and parameters, and what cannot be simulated is refused in one
line."""

from __future__ import annotations

import numpy as np
import pytest
from fdisyn.models.nonlinear import NonlinearPlant
from fdisyn.runtime.errors import ArgumentError
from fdisyn.simulation.nonlinear import simulate_nonlinear, simulate_nonlinear_runs
from fdisyn.simulation.problem import Scenario
from fdisyn.simulation.signals import Signal

PLANT = NonlinearPlant.from_expressions(
    states=["x"], inputs=["u"], outputs=["y"], parameters=["a", "b"], nominal={"a": -0.58, "b": 0.2},
    f={"x": "0.1*a*x^2 + x + 0.1*b*u"}, h={"y": "x"}, Q=1e-4, R=0.01,
)
SC = Scenario("s", "", 50.0)
THETA = np.tile(PLANT.theta_nominal, (50, 1))
U = np.linspace(1.0, 9.0, 50)[:, None]


def test_each_run_is_the_plants_simulation_on_its_seed() -> None:
    b = simulate_nonlinear_runs(PLANT, SC, (3, 4), x0=[0.5], drive=lambda sc: (U, THETA), Ts=1.0, extra={"x": "x", "a": "a"})
    for i, seed in enumerate((3, 4)):
        x, y = simulate_nonlinear(PLANT, x0=[0.5], u=U, theta=THETA, rng=np.random.default_rng(seed))
        assert np.array_equal(b.Y[i], y) and np.array_equal(b.extra["x"][i], x[:, 0]) and np.array_equal(b.U[i], U)
        assert np.array_equal(b.extra["a"][i], THETA[:, 0])
    assert b.seeds == (3, 4) and np.array_equal(b.t, np.arange(50.0)) and list(b.extra) == ["x", "a"]


def test_signals_are_drawn_per_run_before_the_noise() -> None:
    sig = Signal("prbs", offset=5.0, amplitude=2.0, period=7.0)
    b = simulate_nonlinear_runs(PLANT, SC, (1, 2), x0=[0.0], drive=lambda sc: (None, THETA), Ts=1.0, signals=[sig])
    assert not np.array_equal(b.U[0], b.U[1])
    rng = np.random.default_rng(2)
    u = sig.sample(np.arange(50.0), rng, 1.0)[:, None]
    assert np.array_equal(b.U[1], u)
    assert np.array_equal(b.Y[1], simulate_nonlinear(PLANT, x0=[0.0], u=u, theta=THETA, rng=rng)[1])


def test_what_cannot_be_simulated_is_refused_in_one_line() -> None:
    with pytest.raises(ArgumentError, match="neither"):
        simulate_nonlinear_runs(PLANT, SC, (1,), x0=[0.0], drive=lambda sc: (None, THETA), Ts=1.0)
    with pytest.raises(ArgumentError, match="neither states"):
        simulate_nonlinear_runs(PLANT, SC, (1,), x0=[0.0], drive=lambda sc: (U, THETA), Ts=1.0, extra={"z": "zeta"})
