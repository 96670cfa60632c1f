"""The nonlinear plant of the adaptive fault-detection filter (seed 001, eq. (2.1)).

``NonlinearPlant`` holds

    x(t+1) = f(x(t), u(t), θ) + v(t),     v ~ N(0, Q1)
    y(t)   = h(x(t), θ) + e(t),           e ~ N(0, Q2)

with named states, inputs, outputs and parameters ``θ``, and a nominal value
for every parameter. Seed 001 writes the measurement as ``H(θ) X`` (its
assumption A3, a linear measurement); ``h(x, θ)`` contains that case.

``f`` and ``h`` are CasADi ``Function`` objects. Every Jacobian and parameter
sensitivity the filters need (``∂f/∂x``, ``∂f/∂θ``, ``∂h/∂x``, ``∂h/∂θ``)
comes from CasADi's automatic differentiation (:meth:`NonlinearPlant.derivatives`),
never from hand-written formulas or finite differences. Because AD of a
function with a kink or a jump (``abs``, ``min``, ``if_else``…) returns one
arbitrary branch's derivative, such operations are refused when the plant is
built (:class:`~fdisyn.runtime.errors.NonDifferentiableError`).

A plant can also be written as expression strings
(:meth:`NonlinearPlant.from_expressions`), the form a TOML plant file uses::

    NonlinearPlant.from_expressions(
        states=["x"], inputs=["u"], outputs=["y"], parameters=["a", "b"],
        nominal={"a": -0.58, "b": 0.2},
        f={"x": "0.1*a*x^2 + x + 0.1*b*u"}, h={"y": "x"},
        Q1=0.0, Q2=0.01)
"""

from __future__ import annotations

import ast
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import casadi as ca
import numpy as np
from fdisyn.design.linalg import as_matrix
from fdisyn.design.plant import frozen_array, identifier_names
from fdisyn.design.sampling import check_sample_time
from fdisyn.runtime.errors import NominalValueError, NonDifferentiableError, ShapeError, SpecError
from fdisyn.runtime.names import check_distinct

__all__ = ["NONDIFFERENTIABLE_OPERATIONS", "SMOOTH_FUNCTIONS", "NonlinearPlant", "covariance_matrix"]


SMOOTH_FUNCTIONS: Mapping[str, Callable[..., ca.SX]] = {
    "sin": ca.sin,
    "cos": ca.cos,
    "tan": ca.tan,
    "exp": ca.exp,
    "log": ca.log,
    "sqrt": ca.sqrt,
    "sinh": ca.sinh,
    "cosh": ca.cosh,
    "tanh": ca.tanh,
    "asin": ca.asin,
    "acos": ca.acos,
    "atan": ca.atan,
    "atan2": ca.atan2,
    "log1p": ca.log1p,
    "expm1": ca.expm1,
    "erf": ca.erf,
}
"""Functions an expression may call: differentiable on the interior of their domain."""

_BINARY_FUNCTIONS: Mapping[str, int] = {"atan2": 2}
"""Arity of the functions of :data:`SMOOTH_FUNCTIONS` that take more than one argument."""

NONDIFFERENTIABLE_OPERATIONS: Mapping[int, str] = {
    ca.OP_FABS: "abs",
    ca.OP_SIGN: "sign",
    ca.OP_FLOOR: "floor",
    ca.OP_CEIL: "ceil",
    ca.OP_FMIN: "min",
    ca.OP_FMAX: "max",
    ca.OP_FMOD: "fmod",
    ca.OP_REMAINDER: "remainder",
    ca.OP_COPYSIGN: "copysign",
    ca.OP_LT: "comparison <",
    ca.OP_LE: "comparison <=",
    ca.OP_EQ: "comparison ==",
    ca.OP_NE: "comparison !=",
    ca.OP_NOT: "logical not",
    ca.OP_AND: "logical and",
    ca.OP_OR: "logical or",
    ca.OP_IF_ELSE_ZERO: "if_else",
}
"""CasADi operations refused in a plant model (kinks or jumps: AD is undefined there)."""

# Names a user may write but that denote a non-differentiable operation; the
# parser refuses them by name, so the error says what to avoid.
_NONSMOOTH_NAMES = frozenset(
    {
        "abs",
        "fabs",
        "sign",
        "floor",
        "ceil",
        "round",
        "trunc",
        "min",
        "max",
        "fmin",
        "fmax",
        "mod",
        "fmod",
        "remainder",
        "copysign",
        "if_else",
        "heaviside",
        "step",
        "sat",
        "clip",
    }
)


def _names(given: Sequence[str], what: str, *, allow_empty: bool = False) -> tuple[str, ...]:
    names = identifier_names(given, what)
    if not names and not allow_empty:
        raise ShapeError(f"{what} names: expected at least one name, got none")
    return names


def _distinct_names(states: tuple[str, ...], inputs: tuple[str, ...], outputs: tuple[str, ...], parameters: tuple[str, ...]) -> None:
    """Names that share a namespace must differ (an output may share its state's name: it measures it)."""
    check_distinct({"states": states, "inputs": inputs, "parameters": parameters}, why="the expressions of f refer to them by name")
    truth = tuple(f"true_{q}" for q in (*parameters, *states))
    check_distinct(
        {"inputs": inputs, "outputs": outputs, "simulated truth columns": truth},
        why="they are columns of the trace CSV `fdisyn simulate` writes",
    )


def covariance_matrix(value: object, name: str, size: int, *, definite: bool) -> np.ndarray:
    """A ``size × size`` covariance from a scalar (times ``I``), a vector (diagonal) or a matrix.

    Raises :class:`ShapeError` naming ``name`` for non-numbers, a wrong
    shape, asymmetry, or an eigenvalue below zero (``definite``: not above).
    """
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ShapeError(f"{name} must be a number or a matrix of numbers; got {value!r}") from None
    if arr.ndim == 0:
        arr = float(arr) * np.eye(size)
    elif arr.ndim == 1 and arr.size == size:
        arr = np.diag(arr)
    mat = as_matrix(arr, name, rows=size, cols=size)
    if not np.allclose(mat, mat.T, rtol=1e-12, atol=0.0):
        raise ShapeError(f"{name} must be symmetric; max |{name} − {name}ᵀ| = {np.max(np.abs(mat - mat.T)):.3g}")
    mat = 0.5 * (mat + mat.T)
    ev = np.linalg.eigvalsh(mat) if size else np.zeros(0)
    scale = max(1.0, float(np.max(np.abs(ev)))) if ev.size else 1.0
    if definite and ev.size and ev[0] <= 0.0:
        raise ShapeError(f"{name} must be positive definite; smallest eigenvalue {ev[0]:.3g}")
    if ev.size and ev[0] < -1e-12 * scale:
        raise ShapeError(f"{name} must be positive semidefinite (a covariance); smallest eigenvalue {ev[0]:.3g}")
    return mat


def _as_sx_function(fun: object, name: str, in_shapes: Sequence[int], out_size: int, in_names: Sequence[str], out_name: str) -> ca.Function:
    """Re-wrap a user Function as an SX Function with fdisyn's port names, checking shapes."""
    if not isinstance(fun, ca.Function):
        raise SpecError(f"{name} must be a casadi.Function; got {type(fun).__name__}")
    if fun.n_in() != len(in_shapes) or fun.n_out() != 1:
        raise ShapeError(
            f"{name} must have {len(in_shapes)} inputs ({', '.join(in_names)}) and one output; "
            f"got {fun.n_in()} inputs and {fun.n_out()} outputs"
        )
    for k, (size, nm) in enumerate(zip(in_shapes, in_names, strict=False)):
        sp = fun.sparsity_in(k)
        if sp.numel() != size or (size > 0 and sp.size1() != 1 and sp.size2() != 1):
            raise ShapeError(f"{name} input {k} ({nm}) has shape {sp.size()}; expected ({size}, 1)")
    spo = fun.sparsity_out(0)
    if spo.numel() != out_size:
        raise ShapeError(f"{name} output ({out_name}) has shape {spo.size()}; expected ({out_size}, 1)")
    sym = [ca.SX.sym(nm, size) for nm, size in zip(in_names, in_shapes, strict=False)]
    args = [ca.reshape(s, fun.sparsity_in(k).size()) for k, s in enumerate(sym)]
    try:
        out = fun.expand()(*args) if fun.is_a("MXFunction") else fun(*args)
    except RuntimeError as exc:
        raise SpecError(f"{name} cannot be evaluated on SX symbols (it must be expandable to SX): {exc}") from exc
    out = ca.densify(ca.reshape(ca.SX(out), out_size, 1))
    wrapped = ca.Function(name, sym, [out], list(in_names), [out_name])
    _refuse_nondifferentiable(wrapped, name)
    return wrapped


def _refuse_nondifferentiable(fun: ca.Function, name: str) -> None:
    """Raise :class:`NonDifferentiableError` if the SX Function ``fun`` uses a kink/jump operation."""
    for k in range(fun.n_instructions()):
        op = fun.instruction_id(k)
        if op in NONDIFFERENTIABLE_OPERATIONS:
            raise NonDifferentiableError(
                f"{name} uses the non-differentiable operation {NONDIFFERENTIABLE_OPERATIONS[op]!r} "
                f"(instruction {k}); expected only smooth operations ({', '.join(sorted(SMOOTH_FUNCTIONS))}, "
                "+, −, ×, ÷, powers), because every Jacobian comes from automatic differentiation"
            )


class _ExpressionCompiler:
    """Turns one arithmetic expression string into an SX expression, refusing anything else."""

    def __init__(self, symbols: Mapping[str, ca.SX], constants: Mapping[str, float], where: str) -> None:
        self.symbols = symbols
        self.constants = constants
        self.where = where

    def compile(self, text: str) -> ca.SX:
        if not isinstance(text, str) or not text.strip():
            raise SpecError(f"{self.where}: expected a non-empty expression string; got {text!r}")
        try:
            # '^' is power in plant files; Python would parse it as xor with the wrong precedence
            tree = ast.parse(text.strip().replace("^", "**"), mode="eval")
        except SyntaxError as exc:
            raise SpecError(f"{self.where}: cannot parse expression {text!r}: {exc.msg}") from None
        self.text = text
        return self._node(tree.body)

    def _fail_nonsmooth(self, what: str) -> NonDifferentiableError:
        return NonDifferentiableError(
            f"{self.where}: expression {self.text!r} uses {what}, which is not differentiable everywhere; "
            f"expected only smooth operations ({', '.join(sorted(SMOOTH_FUNCTIONS))}, +, −, *, /, ^ or **), "
            "because every Jacobian comes from automatic differentiation"
        )

    def _node(self, node: ast.AST) -> ca.SX:
        if isinstance(node, ast.BinOp):
            left, right = self._node(node.left), self._node(node.right)
            op = node.op
            if isinstance(op, ast.Add):
                return left + right
            if isinstance(op, ast.Sub):
                return left - right
            if isinstance(op, ast.Mult):
                return left * right
            if isinstance(op, ast.Div):
                return left / right
            if isinstance(op, ast.Pow):
                return left**right
            if isinstance(op, (ast.Mod, ast.FloorDiv)):
                raise self._fail_nonsmooth("the operator '%' or '//'")
            raise SpecError(f"{self.where}: operator {type(op).__name__} is not allowed in {self.text!r}")
        if isinstance(node, ast.UnaryOp):
            val = self._node(node.operand)
            if isinstance(node.op, ast.USub):
                return -val
            if isinstance(node.op, ast.UAdd):
                return val
            raise self._fail_nonsmooth(f"the operator {type(node.op).__name__}")
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                raise SpecError(f"{self.where}: constant {node.value!r} in {self.text!r} is not a real number")
            return ca.SX(float(node.value))
        if isinstance(node, ast.Name):
            if node.id in self.symbols:
                return self.symbols[node.id]
            if node.id in self.constants:
                return ca.SX(float(self.constants[node.id]))
            allowed = sorted([*self.symbols, *self.constants])
            raise SpecError(f"{self.where}: unknown name {node.id!r} in {self.text!r}; allowed names are {allowed}")
        if isinstance(node, ast.Call):
            if not isinstance(node.func, ast.Name) or node.keywords:
                raise SpecError(f"{self.where}: only plain calls such as sin(x) are allowed in {self.text!r}")
            fname = node.func.id
            if fname in _NONSMOOTH_NAMES:
                raise self._fail_nonsmooth(f"the function {fname}()")
            if fname not in SMOOTH_FUNCTIONS:
                raise SpecError(
                    f"{self.where}: unknown function {fname!r} in {self.text!r}; allowed: {sorted(SMOOTH_FUNCTIONS)}"
                )
            arity = _BINARY_FUNCTIONS.get(fname, 1)
            if len(node.args) != arity:
                raise SpecError(
                    f"{self.where}: {fname}() takes {arity} argument{'s' if arity > 1 else ''}, "
                    f"got {len(node.args)} in {self.text!r}"
                )
            return SMOOTH_FUNCTIONS[fname](*[self._node(a) for a in node.args])
        if isinstance(node, (ast.Compare, ast.BoolOp, ast.IfExp)):
            raise self._fail_nonsmooth("a comparison or a conditional")
        raise SpecError(f"{self.where}: {type(node).__name__} is not allowed in the expression {self.text!r}")


@dataclass(frozen=True, eq=False)
class NonlinearPlant:
    """``x⁺ = f(x, u, θ) + v``, ``y = h(x, θ) + e`` (seed 001, eq. (2.1)), with nominal ``θ``.

    Build with :meth:`create` (CasADi Functions) or :meth:`from_expressions`
    (strings). ``f`` has ports ``(x, u, theta) → x_next`` and ``h`` has
    ``(x, theta) → y``; both are SX Functions, checked for shapes and for
    non-differentiable operations.
    """

    f: ca.Function
    h: ca.Function
    states: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    parameters: tuple[str, ...]
    theta_nominal: np.ndarray
    """Nominal parameter values, in the order of :attr:`parameters`."""
    Q1: np.ndarray
    """Process-noise covariance (seed 001: ``Q1``)."""
    Q2: np.ndarray
    """Measurement-noise covariance (seed 001: ``Q2``); positive definite."""
    Ts: float | None = None
    """Sample time in seconds (informational; the model is already discrete)."""
    expressions: Mapping[str, object] | None = None
    """The expression strings the plant was built from, if any (for reports and gain files)."""
    units: Mapping[str, str] = field(default_factory=dict)

    # construction ------------------------------------------------------------
    @classmethod
    def create(
        cls,
        *,
        f: ca.Function,
        h: ca.Function,
        states: Sequence[str],
        inputs: Sequence[str],
        outputs: Sequence[str],
        parameters: Sequence[str],
        nominal: Mapping[str, float],
        Q1: object,
        Q2: object,
        Ts: float | None = None,
        units: Mapping[str, str] | None = None,
        expressions: Mapping[str, object] | None = None,
    ) -> NonlinearPlant:
        """Validate and build a plant from CasADi Functions ``f(x, u, θ)`` and ``h(x, θ)``.

        Raises
        ------
        NominalValueError
            A parameter has no nominal value, or a non-finite one.
        NonDifferentiableError
            ``f`` or ``h`` uses ``abs``, ``min``/``max``, comparisons, ``if_else``…
        ShapeError, SpecError
            Wrong port shapes, bad names, a covariance that is not one.
        """
        st = _names(states, "state")
        inp = _names(inputs, "input", allow_empty=True)
        out = _names(outputs, "output")
        par = _names(parameters, "parameter")
        _distinct_names(st, inp, out, par)
        n, m, p, l = len(st), len(inp), len(out), len(par)
        theta = _nominal_vector(par, nominal)
        f_sx = _as_sx_function(f, "f", (n, m, l), n, ("x", "u", "theta"), "x_next")
        h_sx = _as_sx_function(h, "h", (n, l), p, ("x", "theta"), "y")
        q1 = covariance_matrix(Q1, "Q1", n, definite=False)
        q2 = covariance_matrix(Q2, "Q2", p, definite=True)
        return cls(
            f=f_sx,
            h=h_sx,
            states=st,
            inputs=inp,
            outputs=out,
            parameters=par,
            theta_nominal=frozen_array(theta),
            Q1=frozen_array(q1),
            Q2=frozen_array(q2),
            Ts=None if Ts is None else check_sample_time(Ts),
            expressions=None if expressions is None else dict(expressions),
            units=dict(units or {}),
        )

    @classmethod
    def from_expressions(
        cls,
        *,
        states: Sequence[str],
        inputs: Sequence[str],
        outputs: Sequence[str],
        parameters: Sequence[str],
        nominal: Mapping[str, float],
        f: Mapping[str, str],
        h: Mapping[str, str],
        Q1: object,
        Q2: object,
        constants: Mapping[str, float] | None = None,
        Ts: float | None = None,
        units: Mapping[str, str] | None = None,
    ) -> NonlinearPlant:
        """Build a plant from one next-state expression per state and one expression per output.

        Expressions are arithmetic in the state, input, parameter and constant
        names (``+ − * / ^ **``, parentheses, numbers, ``pi``) and the smooth
        functions of :data:`SMOOTH_FUNCTIONS`. The output expressions may not
        use inputs (seed 001's measurement is ``H(θ) X``, no feedthrough).

        Raises
        ------
        NonDifferentiableError
            An expression uses ``abs``, ``min``, ``max``, ``floor``, ``%``,
            comparisons, conditionals or another operation with a kink or jump.
        NominalValueError
            A parameter without a nominal value.
        SpecError
            Unknown names or functions, a missing or extra state/output
            expression, a syntax error.
        """
        st = _names(states, "state")
        inp = _names(inputs, "input", allow_empty=True)
        out = _names(outputs, "output")
        par = _names(parameters, "parameter")
        _distinct_names(st, inp, out, par)
        _nominal_vector(par, nominal)  # fail on missing nominal values before parsing anything
        consts = {"pi": float(np.pi), **{str(k): float(v) for k, v in (constants or {}).items()}}
        clash = sorted(set(consts) & set(st + inp + out + par))
        if clash:
            raise SpecError(f"constant names {clash} clash with signal or parameter names")
        for what, given, expected in (("f", f, st), ("h", h, out)):
            wrong = {k: v for k, v in given.items() if not isinstance(v, str)}
            if wrong:
                raise SpecError(f"{what}: expressions must be strings; got {wrong}")
            keys = set(given)
            if keys != set(expected):
                raise SpecError(
                    f"{what}: expected one expression per {'state' if what == 'f' else 'output'} "
                    f"{list(expected)}; missing {sorted(set(expected) - keys)}, unknown {sorted(keys - set(expected))}"
                )
        x = ca.SX.sym("x", len(st))
        u = ca.SX.sym("u", len(inp))
        th = ca.SX.sym("theta", len(par))
        sym_f = {**{nm: x[i] for i, nm in enumerate(st)}, **{nm: u[i] for i, nm in enumerate(inp)}, **{nm: th[i] for i, nm in enumerate(par)}}
        sym_h = {**{nm: x[i] for i, nm in enumerate(st)}, **{nm: th[i] for i, nm in enumerate(par)}}
        fx = ca.vertcat(*[_ExpressionCompiler(sym_f, consts, f"f[{nm!r}]").compile(f[nm]) for nm in st])
        hx_parts = []
        for nm in out:
            try:
                hx_parts.append(_ExpressionCompiler(sym_h, consts, f"h[{nm!r}]").compile(h[nm]))
            except SpecError as exc:
                if any(re.search(rf"\b{re.escape(i)}\b", h[nm]) for i in inp) and "unknown name" in str(exc):
                    raise SpecError(f"h[{nm!r}]: the output expression uses an input; h(x, θ) may not depend on u") from None
                raise
        hx = ca.vertcat(*hx_parts)
        return cls.create(
            f=ca.Function("f", [x, u, th], [fx]),
            h=ca.Function("h", [x, th], [hx]),
            states=st,
            inputs=inp,
            outputs=out,
            parameters=par,
            nominal=nominal,
            Q1=Q1,
            Q2=Q2,
            Ts=Ts,
            units=units,
            expressions={"f": dict(f), "h": dict(h), "constants": {k: v for k, v in consts.items() if k != "pi"}},
        )

    # dimensions -------------------------------------------------------------
    @property
    def n(self) -> int:
        return len(self.states)

    @property
    def m(self) -> int:
        return len(self.inputs)

    @property
    def p(self) -> int:
        return len(self.outputs)

    @property
    def l(self) -> int:
        return len(self.parameters)

    # derivatives ------------------------------------------------------------
    def derivatives(self) -> ca.Function:
        """``(x, u, theta) → (f, F_x, F_theta, h, H_x, H_theta)`` by CasADi AD.

        ``F_x = ∂f/∂x`` (seed 001's ``F_t``), ``F_theta = ∂f/∂θ``,
        ``H_x = ∂h/∂x`` (``H_t``), ``H_theta = ∂h/∂θ`` — the Jacobians of the
        EKF and the sensitivities of the joint state/parameter filter (2.5).
        """
        x = ca.SX.sym("x", self.n)
        u = ca.SX.sym("u", self.m)
        th = ca.SX.sym("theta", self.l)
        fx = self.f(x, u, th)
        hx = self.h(x, th)
        return ca.Function(
            "plant_derivatives",
            [x, u, th],
            [fx, ca.jacobian(fx, x), ca.jacobian(fx, th), hx, ca.jacobian(hx, x), ca.jacobian(hx, th)],
            ["x", "u", "theta"],
            ["f", "F_x", "F_theta", "h", "H_x", "H_theta"],
        )

    def linearise(self, *, x: object, u: object, theta: object | None = None) -> dict[str, np.ndarray]:
        """The values of :meth:`derivatives` at a point (``theta`` defaults to nominal), as numpy arrays."""
        th = self.theta_nominal if theta is None else theta
        vals = self.derivatives().call(
            {
                "x": _vector(x, "x", self.n),
                "u": _vector(u, "u", self.m),
                "theta": _vector(th, "theta", self.l),
            }
        )
        return {k: np.array(v, dtype=float) for k, v in vals.items()}

    # simulation -------------------------------------------------------------
    def simulate(
        self,
        *,
        x0: object,
        u: object,
        theta: object | None = None,
        rng: np.random.Generator,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Simulate ``T`` samples of (2.1) with Gaussian noise; returns ``(x, y)``, shapes ``(T, n)``, ``(T, p)``.

        ``u`` has shape ``(T, m)``; ``theta`` is ``(l,)`` (constant) or
        ``(T, l)``, where row ``k`` is the parameter of the transition
        ``x(k) → x(k+1)`` (a fault at ``k_f`` first shows in ``y(k_f + 1)``).
        ``x[k]`` and ``y[k] = h(x[k], θ(k)) + e[k]`` are the state and
        measurement at sample ``k``; ``x[0] = x0``.
        """
        uu = np.asarray(u, dtype=float)
        if uu.ndim == 1 and self.m == 1:
            uu = uu[:, None]
        if uu.ndim != 2 or uu.shape[1] != self.m:
            raise ShapeError(f"u has shape {uu.shape}; expected (T, {self.m})")
        T = uu.shape[0]
        th = self.theta_nominal if theta is None else np.asarray(theta, dtype=float)
        if th.ndim == 1:
            th = np.broadcast_to(th, (T, self.l))
        if th.shape != (T, self.l):
            raise ShapeError(f"theta has shape {th.shape}; expected ({self.l},) or ({T}, {self.l})")
        x0v = _vector(x0, "x0", self.n)
        v = _gaussian(rng, self.Q1, T)
        e = _gaussian(rng, self.Q2, T)
        xs = ca.SX.sym("x", self.n)
        drive = ca.SX.sym("drive", self.m + self.l + self.n)
        step = ca.Function(
            "plant_transition",
            [xs, drive],
            [self.f(xs, drive[: self.m], drive[self.m : self.m + self.l]) + drive[self.m + self.l :]],
        )
        # x(k+1) for k = 0..T-2, by one accumulated map over the whole horizon (fast, no Python loop)
        drives = np.hstack([uu, th, v]).T
        xnext = np.array(step.mapaccum(max(T - 1, 1))(x0v, drives[:, : max(T - 1, 1)]), dtype=float)
        x = np.vstack([x0v[None, :], xnext.T[: T - 1]])
        thx = ca.SX.sym("thx", self.l)
        meas = ca.Function("plant_measurement", [xs, thx], [self.h(xs, thx)]).map(T)
        y = np.array(meas(x.T, th.T), dtype=float).T + e
        return x, y


def _vector(value: object, name: str, size: int) -> np.ndarray:
    v = np.asarray(value, dtype=float).reshape(-1)
    if v.size != size:
        raise ShapeError(f"{name} has {v.size} entries; expected {size}")
    return v


def _gaussian(rng: np.random.Generator, cov: np.ndarray, count: int) -> np.ndarray:
    """``count`` samples of ``N(0, cov)`` (rows); a singular ``cov`` is fine (eigen-factor, not Cholesky)."""
    w, vecs = np.linalg.eigh(cov)
    factor = vecs * np.sqrt(np.clip(w, 0.0, None))[None, :]
    return rng.standard_normal((count, cov.shape[0])) @ factor.T


def _nominal_vector(parameters: Sequence[str], nominal: Mapping[str, float]) -> np.ndarray:
    if not isinstance(nominal, Mapping):
        raise NominalValueError(f"nominal must map each parameter name to a number; got {type(nominal).__name__}")
    missing = [p for p in parameters if p not in nominal]
    if missing:
        raise NominalValueError(
            f"parameters {missing} have no nominal value; expected one for every parameter {list(parameters)}, "
            f"found values for {sorted(nominal)}"
        )
    extra = sorted(set(nominal) - set(parameters))
    if extra:
        raise NominalValueError(f"nominal values given for unknown parameters {extra}; parameters are {list(parameters)}")
    vals = []
    for p in parameters:
        try:
            v = float(nominal[p])
        except (TypeError, ValueError):
            raise NominalValueError(f"nominal value of parameter {p!r} must be a number; found {nominal[p]!r}") from None
        if not np.isfinite(v):
            raise NominalValueError(f"nominal value of parameter {p!r} must be finite; found {v!r}")
        vals.append(v)
    return np.array(vals)
