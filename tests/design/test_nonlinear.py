"""NonlinearPlant: construction, refusals, and AD derivatives against central differences."""

from __future__ import annotations

import json

import casadi as ca
import numpy as np
import pytest
from fdisyn.models.casadi_program import function_from_program, model_program
from fdisyn.models.nonlinear import NonlinearPlant
from fdisyn.simulation.nonlinear import simulate_nonlinear
from fdisyn.problems import ship_propulsion as sp
from fdisyn.runtime.errors import ArgumentError, NominalValueError, NonDifferentiableError, ShapeError
from hypothesis import given, settings
from hypothesis import strategies as st

SHIP = sp.MODEL  # the ship of Zhou, Xi & Zhang 1991, eq. (3.1)

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
    Q=np.diag([1e-6, 1e-4]),
    R=np.diag([1e-4, 1e-3]),
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
                              nominal={"a": 1.0, "b": 1.0}, Q=0.0, R=1.0)


def test_mx_functions_are_expanded_to_the_same_model() -> None:
    x, u, th = ca.MX.sym("x"), ca.MX.sym("u"), ca.MX.sym("th", 2)
    f = ca.Function("f", [x, u, th], [0.1 * th[0] * x**2 + x + 0.1 * th[1] * u])
    h = ca.Function("h", [x, th], [x])
    pl = NonlinearPlant.create(f=f, h=h, states=["x"], inputs=["u"], outputs=["y"], parameters=["a", "b"],
                               nominal={"a": -0.58, "b": 0.2}, Q=0.0, R=0.01)
    ref = NonlinearPlant.from_expressions(**SHIP)
    for k, v in ref.linearise(x=[0.7], u=[3.0]).items():
        np.testing.assert_array_equal(pl.linearise(x=[0.7], u=[3.0])[k], v)  # same arithmetic, same bits


@pytest.mark.parametrize(
    "change, error, match",
    [
        ({"f": {"x": "x + q"}}, ArgumentError, "unknown name 'q'"),
        ({"f": {"x": "x + cbrt(u)"}}, ArgumentError, "unknown function 'cbrt'"),
        ({"f": {"x": "x + sin(u, x)"}}, ArgumentError, r"sin\(\) takes 1 argument, got 2"),
        ({"f": {"x": "x + atan2(u)"}}, ArgumentError, r"atan2\(\) takes 2 arguments, got 1"),
        ({"f": {}}, ArgumentError, r"missing \['x'\]"),
        ({"h": {"y": "x + u"}}, ArgumentError, "may not depend on u"),
        ({"f": {"x": "x +"}}, ArgumentError, "cannot parse"),
        ({"R": 0.0}, ArgumentError, "positive definite"),
        ({"Q": -1.0}, ArgumentError, "positive semidefinite"),
        ({"states": ["x", "x"]}, ArgumentError, "unique"),
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
                              nominal={"a": 1.0, "b": 1.0}, Q=0.0, R=1.0)


def test_simulation_follows_the_model_and_the_time_convention() -> None:
    """x[k+1] = f(x[k], u[k], θ[k]) + v[k]; with Q = 0 the states are the noise-free recursion."""
    pl = NonlinearPlant.from_expressions(**SHIP)
    T = 50
    u = np.linspace(0.0, 4.0, T)[:, None]
    theta = np.tile(pl.theta_nominal, (T, 1))
    theta[30:, 0] = -0.29
    x, y = simulate_nonlinear(pl, x0=[0.1], u=u, theta=theta, rng=np.random.default_rng(0))
    ref = [0.1]
    for k in range(T - 1):
        a, b = theta[k]
        ref.append(0.1 * a * ref[-1] ** 2 + ref[-1] + 0.1 * b * u[k, 0])
    np.testing.assert_allclose(x[:, 0], ref, rtol=1e-14)  # same recursion; CasADi may order the sum differently
    assert y.shape == (T, 1)
    # the noise is e ~ N(0, 0.01): 50 samples have sd within a factor 2 of 0.1 (chance < 1e-9 otherwise)
    assert 0.05 < float(np.std(y[:, 0] - x[:, 0])) < 0.2


# --------------------------------------------------------------------------- numbers are data


@pytest.mark.parametrize(
    "expr, match",
    [
        ("x/0 + a*b*u", r"'x/0' .* evaluates to inf"),
        ("log(-1.0) + x + a*b*u", r"'log\(-1.0\)' .* evaluates to nan"),
        ("1e999*x + a*b*u", r"the number '1e999' .* is not a finite double"),
        ("10**10**10*x + a*b*u", r"'10\*\*10\*\*10' .* evaluates to inf"),
        ("10^400*x + a*b*u", r"'10\*\*400' .* evaluates to inf"),
        ("1" + "0" * 400 + "*x + a*b*u", "is not a finite double"),
        ("1e308*10*x + a*b*u", r"'1e308\*10' .* evaluates to inf"),
        ("(1e308*x)*10 + a*b*u", "holds the constant inf"),  # CasADi folds the two constants itself
    ],
)
def test_non_finite_constants_are_refused_where_they_enter(expr: str, match: str) -> None:
    with pytest.raises(ArgumentError, match=match) as info:
        NonlinearPlant.from_expressions(**{**SHIP, "f": {"x": expr}})
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("value", [float("nan"), float("inf"), -float("inf"), "1.0", True, [1.0]])
def test_named_constants_must_be_finite_numbers(value: object) -> None:
    with pytest.raises(ArgumentError, match="constant 'c' must be a"):
        NonlinearPlant.from_expressions(**{**SHIP, "f": {"x": "c*x + a*b*u"}, "constants": {"c": value}})


def test_a_function_holding_a_nan_constant_is_refused() -> None:
    x, u, th = ca.SX.sym("x"), ca.SX.sym("u"), ca.SX.sym("th", 2)
    f = ca.Function("f", [x, u, th], [th[0] * x + th[1] * u + ca.SX(float("nan")) * x])
    h = ca.Function("h", [x, th], [x])
    with pytest.raises(ArgumentError, match="holds the constant nan"):
        NonlinearPlant.create(f=f, h=h, states=["x"], inputs=["u"], outputs=["y"], parameters=["a", "b"],
                              nominal={"a": 1.0, "b": 1.0}, Q=0.0, R=1.0)


@pytest.mark.parametrize(
    "f, h, point, match",
    [
        # d/dx x^x = x^x (ln x + 1): 0·∞ at x = 0 although x^x itself is 1 there
        ({"x": "x**x + a*b*u"}, {"y": "x"}, [0.0], r"∂f\['x'\]/∂x = nan \(the expression 'x\*\*x \+ a\*b\*u'\)"),
        ({"x": "log(x) + a*b*u"}, {"y": "x"}, [0.0], r"f\['x'\] = -inf"),
        ({"x": "x + a*b*u"}, {"y": "sqrt(x)"}, [0.0], r"∂h\['y'\]/∂x = inf"),
        ({"x": "x + a*b*u"}, {"y": "x/(x - a)"}, [-0.58], r"h\['y'\] = (-)?inf|h\['y'\] = nan"),
    ],
)
def test_a_model_not_finite_at_the_point_is_refused(f: dict, h: dict, point: list, match: str) -> None:
    """The model builds (nothing is constant), but evaluating f, h and the AD Jacobians at the point
    finds the NaN/inf and names the expression; a regular point of the same model passes."""
    pl = NonlinearPlant.from_expressions(**{**SHIP, "f": f, "h": h})
    with pytest.raises(ArgumentError, match=match) as info:
        pl.check_finite(x=point, u=[1.0])
    assert "\n" not in str(info.value) and "not finite at the nominal point" in str(info.value)
    pl.check_finite(x=[0.7], u=[1.0])


# --------------------------------------------------------------------------- expression limits


@pytest.mark.parametrize(
    "expr, match",
    [
        ("+".join(["x"] * 5000), "10007 characters; at most 10000"),  # RecursionError in ast.parse before
        ("+".join(["x"] * 3000), "more than 1000 operators"),
        ("-" * 3000 + "x", "more than 1000 operators"),
        ("x" + "*x" * 6000, "characters; at most 10000"),
        ("sin(" * 300 + "x" + ")" * 300, "cannot parse"),  # Python's parser: too many nested parentheses
    ],
)
def test_oversized_expressions_give_one_line(expr: str, match: str) -> None:
    with pytest.raises(ArgumentError, match=match) as info:
        NonlinearPlant.from_expressions(**{**SHIP, "f": {"x": expr + " + a*b*u"}})
    assert "\n" not in str(info.value)


def test_expressions_within_the_limits_compile_without_recursion() -> None:
    """900 operators (a 450-term sum) and 150 nested calls: the compiler walks the tree with its own
    stack. Truths: the sum of 450 copies of x is 450 x; sin∘…∘sin (150 times) by NumPy."""
    pl = NonlinearPlant.from_expressions(**{**SHIP, "f": {"x": "+".join(["x"] * 449) + " + a*b*u"}})
    lin = pl.linearise(x=[0.3], u=[0.0])
    assert lin["F_x"][0, 0] == 449.0  # a sum of exact ones
    assert lin["f"][0, 0] == pytest.approx(449 * 0.3, rel=1e-13)  # 449 roundings of the running sum
    deep = NonlinearPlant.from_expressions(**{**SHIP, "f": {"x": "sin(" * 150 + "x" + ")" * 150 + " + a*b*u"}})
    want = 0.3
    for _ in range(150):
        want = np.sin(want)
    assert float(deep.linearise(x=[0.3], u=[0.0])["f"][0, 0]) == pytest.approx(want, rel=1e-14)  # same libm sin, 150 times


# --------------------------------------------------------------------------- the model as data


@pytest.mark.parametrize("spec", [SHIP, PENDULUM], ids=["ship", "pendulum"])
def test_model_program_rebuilds_the_identical_function(spec: dict) -> None:
    pl = NonlinearPlant.from_expressions(**spec)
    n, m, l = pl.n, pl.m, pl.l
    for fun, ins, sizes, out, size in ((pl.f, ("x", "u", "theta"), (n, m, l), "x_next", n), (pl.h, ("x", "theta"), (n, l), "y", pl.p)):
        prog = json.loads(json.dumps(model_program(fun), allow_nan=False))  # strict JSON, as in a gain file
        again = function_from_program(prog, name=fun.name(), in_names=ins, in_sizes=sizes, out_name=out, out_size=size)
        assert again.serialize() == fun.serialize()


@pytest.mark.parametrize(
    "edit, match",
    [
        (lambda p: p["ops"].append(["fabs", 0]), "unknown operation 'fabs'"),
        (lambda p: p["ops"].__setitem__(2, ["mul", 0, 5]), r"ops\[2\] operand \(an earlier value\) must be an integer in 0..1"),
        (lambda p: p["ops"].__setitem__(2, ["mul", 0, True]), "must be an integer"),
        (lambda p: p["ops"].__setitem__(1, ["input", 2, 7]), r"entry of theta must be an integer in 0..1"),
        (lambda p: p["ops"].__setitem__(1, ["input", 3, 0]), r"port must be an integer in 0..2"),
        (lambda p: p["ops"].__setitem__(0, ["const", "0.1"]), "takes one finite number"),
        (lambda p: p["ops"].__setitem__(0, ["const", 1e400]), "takes one finite number"),
        (lambda p: p["ops"].__setitem__(4, ["sq", 3, 3]), "takes 1 operand"),
        (lambda p: p["out"].append(0), "out has 2 entries; expected 1"),
        (lambda p: p["out"].__setitem__(0, 99), r"out\[0\] must be an integer in 0..11"),
        (lambda p: p.__setitem__("ops", [["const", 1.0]] * 10_001), "10001 operations; at most 10000"),
        (lambda p: p.__setitem__("extra", 1), "fields 'ops' and 'out'"),
    ],
)
def test_a_corrupted_program_is_refused_before_casadi(edit, match: str) -> None:
    prog = model_program(NonlinearPlant.from_expressions(**SHIP).f)
    edit(prog)
    with pytest.raises(ArgumentError, match=match):
        function_from_program(prog, name="f", in_names=("x", "u", "theta"), in_sizes=(1, 1, 2), out_name="x_next", out_size=1)
