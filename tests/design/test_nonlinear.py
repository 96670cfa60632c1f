"""NonlinearPlant: construction, refusals, and AD derivatives against central differences."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from fdisyn.design.nonlinear import NonlinearPlant
from fdisyn.runtime.errors import NominalValueError, NonDifferentiableError, ShapeError, SpecError
from hypothesis import given, settings
from hypothesis import strategies as st

SHIP = dict(
    states=["x"],
    inputs=["u"],
    outputs=["y"],
    parameters=["a", "b"],
    nominal={"a": -0.58, "b": 0.2},
    f={"x": "0.1*a*x^2 + x + 0.1*b*u"},
    h={"y": "x"},
    Q1=0.0,
    Q2=0.01,
)

# A smooth two-state plant exercising every kind of dependence (x, u, θ in f and h).
PENDULUM = dict(
    states=["phi", "omega"],
    inputs=["torque"],
    outputs=["angle", "energy"],
    parameters=["g_over_l", "damping", "gain"],
    nominal={"g_over_l": 9.81, "damping": 0.3, "gain": 1.5},
    f={
        "phi": "phi + 0.01*omega",
        "omega": "omega - 0.01*(g_over_l*sin(phi) + damping*omega) + 0.01*gain*torque",
    },
    h={"angle": "atan2(sin(phi), cos(phi))", "energy": "0.5*omega^2 + g_over_l*(1 - cos(phi)) + exp(-damping)*tanh(omega)"},
    Q1=np.diag([1e-6, 1e-4]),
    Q2=np.diag([1e-4, 1e-3]),
)


def central_differences(fun, args: list[np.ndarray], k: int, h: float = 1e-5) -> np.ndarray:
    base = [np.array(a, dtype=float) for a in args]
    cols = []
    for j in range(base[k].size):
        plus = [a.copy() for a in base]
        minus = [a.copy() for a in base]
        plus[k][j] += h
        minus[k][j] -= h
        cols.append((np.array(fun(*plus), dtype=float) - np.array(fun(*minus), dtype=float)).reshape(-1) / (2 * h))
    return np.array(cols).T


def test_ship_model_values() -> None:
    pl = NonlinearPlant.from_expressions(**SHIP)
    lin = pl.linearise(x=[1.0], u=[2.0])
    # eq. (3.1) at x = 1, u = 2: f = 0.1 a + 1 + 0.2 b; ∂f/∂x = 1 + 0.2 a x; ∂f/∂θ = [0.1 x², 0.1 u]
    # rtol 1e-15: a handful of roundings of O(1) numbers, as in the reference expression itself
    np.testing.assert_allclose(lin["f"], [[0.1 * -0.58 + 1 + 0.2 * 0.2]], rtol=1e-15)
    np.testing.assert_allclose(lin["F_x"], [[1 + 0.2 * -0.58]], rtol=1e-15)
    np.testing.assert_allclose(lin["F_theta"], [[0.1, 0.2]], rtol=1e-15)
    np.testing.assert_array_equal(lin["H_x"], [[1.0]])
    np.testing.assert_array_equal(lin["H_theta"], [[0.0, 0.0]])


@settings(max_examples=40, derandomize=True, deadline=None)
@given(
    x=st.lists(st.floats(-2.0, 2.0), min_size=2, max_size=2),
    u=st.floats(-3.0, 3.0),
    theta=st.lists(st.floats(0.1, 12.0), min_size=3, max_size=3),
)
def test_ad_jacobians_equal_central_differences(x: list[float], u: float, theta: list[float]) -> None:
    """AD Jacobians vs central differences, ≤ 1e-7.

    Step 1e-5: truncation error h²·|f'''|/6 ≤ 1e-10·(|θ|·e^|x| ≈ 100) ≈ 1e-8 and
    round-off eps·|f|/h ≈ 1e-10·|f| — both below 1e-7 for these bounded inputs.
    """
    pl = NonlinearPlant.from_expressions(**PENDULUM)
    xv, uv, tv = np.array(x), np.array([u]), np.array(theta)
    lin = pl.linearise(x=xv, u=uv, theta=tv)
    checks = [
        (lin["F_x"], central_differences(pl.f, [xv, uv, tv], 0)),
        (lin["F_theta"], central_differences(pl.f, [xv, uv, tv], 2)),
        (lin["H_x"], central_differences(pl.h, [xv, tv], 0)),
        (lin["H_theta"], central_differences(pl.h, [xv, tv], 1)),
    ]
    for ad, fd in checks:
        np.testing.assert_allclose(ad, fd, rtol=0, atol=1e-7 * max(1.0, float(np.max(np.abs(fd)))))


def test_missing_nominal_value_is_named() -> None:
    spec = {**SHIP, "nominal": {"a": -0.58}}
    with pytest.raises(NominalValueError, match=r"\['b'\] have no nominal value"):
        NonlinearPlant.from_expressions(**spec)
    with pytest.raises(NominalValueError, match="must be finite"):
        NonlinearPlant.from_expressions(**{**SHIP, "nominal": {"a": float("nan"), "b": 0.2}})
    with pytest.raises(NominalValueError, match="unknown parameters"):
        NonlinearPlant.from_expressions(**{**SHIP, "nominal": {"a": -0.58, "b": 0.2, "c": 1.0}})


@pytest.mark.parametrize(
    "expr, what",
    [
        ("0.1*a*abs(x) + x + 0.1*b*u", "abs"),
        ("0.1*a*x + max(x, 0) + 0.1*b*u", "max"),
        ("floor(x) + 0.1*b*u*a", "floor"),
        ("x % 2 + a*b*u", "'%'"),
        ("x if x > 0 else a*b*u", "comparison or a conditional"),
        ("(x > 0)*a + b*u", "comparison or a conditional"),
        ("if_else(x, a, b*u)", "if_else"),
    ],
)
def test_non_differentiable_expressions_are_refused(expr: str, what: str) -> None:
    with pytest.raises(NonDifferentiableError, match="not differentiable") as info:
        NonlinearPlant.from_expressions(**{**SHIP, "f": {"x": expr}})
    assert what in str(info.value)


def test_non_differentiable_function_is_refused() -> None:
    x, u, th = ca.SX.sym("x"), ca.SX.sym("u"), ca.SX.sym("th", 2)
    f = ca.Function("f", [x, u, th], [th[0] * ca.fmax(x, 0) + th[1] * u])
    h = ca.Function("h", [x, th], [x])
    with pytest.raises(NonDifferentiableError, match="'max'"):
        NonlinearPlant.create(f=f, h=h, states=["x"], inputs=["u"], outputs=["y"], parameters=["a", "b"],
                              nominal={"a": 1.0, "b": 1.0}, Q1=0.0, Q2=1.0)


def test_mx_functions_are_expanded_to_the_same_model() -> None:
    x, u, th = ca.MX.sym("x"), ca.MX.sym("u"), ca.MX.sym("th", 2)
    f = ca.Function("f", [x, u, th], [0.1 * th[0] * x**2 + x + 0.1 * th[1] * u])
    h = ca.Function("h", [x, th], [x])
    pl = NonlinearPlant.create(f=f, h=h, states=["x"], inputs=["u"], outputs=["y"], parameters=["a", "b"],
                               nominal={"a": -0.58, "b": 0.2}, Q1=0.0, Q2=0.01)
    ref = NonlinearPlant.from_expressions(**SHIP)
    for k, v in ref.linearise(x=[0.7], u=[3.0]).items():
        np.testing.assert_array_equal(pl.linearise(x=[0.7], u=[3.0])[k], v)  # same arithmetic, same bits


@pytest.mark.parametrize(
    "change, error, match",
    [
        ({"f": {"x": "x + q"}}, SpecError, "unknown name 'q'"),
        ({"f": {"x": "x + cbrt(u)"}}, SpecError, "unknown function 'cbrt'"),
        ({"f": {"x": "x + sin(u, x)"}}, SpecError, r"sin\(\) takes 1 argument, got 2"),
        ({"f": {"x": "x + atan2(u)"}}, SpecError, r"atan2\(\) takes 2 arguments, got 1"),
        ({"f": {}}, SpecError, r"missing \['x'\]"),
        ({"h": {"y": "x + u"}}, SpecError, "may not depend on u"),
        ({"f": {"x": "x +"}}, SpecError, "cannot parse"),
        ({"Q2": 0.0}, ShapeError, "positive definite"),
        ({"Q1": -1.0}, ShapeError, "positive semidefinite"),
        ({"states": ["x", "x"]}, ShapeError, "unique"),
    ],
)
def test_bad_specifications_name_the_problem(change: dict, error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        NonlinearPlant.from_expressions(**{**SHIP, **change})


def test_wrong_function_shapes_are_refused() -> None:
    x, u, th = ca.SX.sym("x", 2), ca.SX.sym("u"), ca.SX.sym("th", 2)
    f = ca.Function("f", [x, u, th], [x])
    h = ca.Function("h", [x, th], [x[0]])
    with pytest.raises(ShapeError, match="input 0"):
        NonlinearPlant.create(f=f, h=h, states=["x"], inputs=["u"], outputs=["y"], parameters=["a", "b"],
                              nominal={"a": 1.0, "b": 1.0}, Q1=0.0, Q2=1.0)


def test_simulation_follows_the_model_and_the_time_convention() -> None:
    """x[k+1] = f(x[k], u[k], θ[k]) + v[k]; with Q1 = 0 the states are the noise-free recursion."""
    pl = NonlinearPlant.from_expressions(**SHIP)
    T = 50
    u = np.linspace(0.0, 4.0, T)[:, None]
    theta = np.tile(pl.theta_nominal, (T, 1))
    theta[30:, 0] = -0.29
    x, y = pl.simulate(x0=[0.1], u=u, theta=theta, rng=np.random.default_rng(0))
    ref = [0.1]
    for k in range(T - 1):
        a, b = theta[k]
        ref.append(0.1 * a * ref[-1] ** 2 + ref[-1] + 0.1 * b * u[k, 0])
    np.testing.assert_allclose(x[:, 0], ref, rtol=1e-14)  # same recursion; CasADi may order the sum differently
    assert y.shape == (T, 1)
    # the noise is e ~ N(0, 0.01): 50 samples have sd within a factor 2 of 0.1 (chance < 1e-9 otherwise)
    assert 0.05 < float(np.std(y[:, 0] - x[:, 0])) < 0.2
