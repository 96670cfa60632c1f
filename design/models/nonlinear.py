"""The nonlinear plant of the adaptive fault-detection filter (Zhou, Xi & Zhang 1991, eq. (2.1)).

Zhou, Xi & Zhang, "Detection and diagnostics of parameter jump for a class of
nonlinear systems", Shanghai Jiao Tong University, c. 1991.

``NonlinearPlant`` holds

    x(t+1) = f(x(t), u(t), θ) + v(t),     v ~ N(0, Q)
    y(t)   = h(x(t), θ) + e(t),           e ~ N(0, R)

with named states, inputs, outputs and parameters ``θ``, and a nominal value
for every parameter. ``Q`` and ``R`` are the paper's ``Q1`` and ``Q2``; fdisyn
names the noise covariances ``Q`` (process) and ``R`` (measurement) on every
plant, as :class:`~fdisyn.models.linear.LinearPlant` does. Zhou, Xi & Zhang write the measurement as ``H(θ) X`` (their
assumption A3, a linear measurement); ``h(x, θ)`` contains that case.

``f`` and ``h`` are CasADi ``Function`` objects. Every Jacobian and parameter
sensitivity the filters need (``∂f/∂x``, ``∂f/∂θ``, ``∂h/∂x``, ``∂h/∂θ``)
comes from CasADi's automatic differentiation (:meth:`NonlinearPlant.derivatives`),
never from hand-written formulas or finite differences. Because AD of a
function with a kink or a jump (``abs``, ``min``, ``if_else``…) returns one
arbitrary branch's derivative, such operations are refused when the plant is
built (:class:`~fdisyn.runtime.errors.NonDifferentiableError`).

A plant can also be written as expression strings
(:meth:`NonlinearPlant.from_expressions`, the language of
:mod:`fdisyn.models.expressions`), the form a TOML plant file uses::

    NonlinearPlant.from_expressions(
        states=["x"], inputs=["u"], outputs=["y"], parameters=["a", "b"],
        nominal={"a": -0.58, "b": 0.2},
        f={"x": "0.1*a*x^2 + x + 0.1*b*u"}, h={"y": "x"},
        Q=0.0, R=0.01)

Numbers are data: a model may hold no NaN or infinite constant.
:meth:`NonlinearPlant.check_finite` evaluates ``f``, ``h`` and their AD
Jacobians at a point (the designs call it at their initial state and the
nominal ``θ``) and refuses a model that is not finite there — ``x/0``,
``x**x`` at ``x = 0``. ``f`` and ``h`` hold at most
:data:`~fdisyn.models.casadi_program.MAX_MODEL_INSTRUCTIONS` operations, all
smooth (:func:`fdisyn.models.casadi_program.check_model_function`); gain files
store them as operation lists (:mod:`fdisyn.models.casadi_program`). A run of
the plant is simulated by :func:`fdisyn.simulation.nonlinear.simulate_nonlinear`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np
from fdisyn.models.casadi_program import check_model_function
from fdisyn.models.expressions import compile_expression, expression_constants
from fdisyn.models.linear import identifier_names
from fdisyn.models.sampling import check_sample_time
from fdisyn.numerics.linalg import as_covariance, as_vector, frozen_array
from fdisyn.runtime.errors import ArgumentError, NominalValueError, ShapeError
from fdisyn.runtime.names import check_distinct, check_signal_texts, shown
from fdisyn.runtime.schema import SIGNAL_LABEL_MAX, UNIT_MAX
from fdisyn.runtime.values import real_number

__all__ = ["NonlinearPlant"]


def _names(given: Sequence[str], what: str, *, allow_empty: bool = False) -> tuple[str, ...]:
    names = identifier_names(given, what)
    if not names and not allow_empty:
        raise ArgumentError(f"{what} names: expected at least one name, got none")
    return names


def _distinct_names(states: tuple[str, ...], inputs: tuple[str, ...], outputs: tuple[str, ...], parameters: tuple[str, ...]) -> None:
    """Names that share a namespace must differ (an output may share its state's name: it measures it)."""
    check_distinct({"states": states, "inputs": inputs, "parameters": parameters}, why="the expressions of f refer to them by name")
    truth = tuple(f"true_{q}" for q in (*parameters, *states))
    check_distinct(
        {"inputs": inputs, "outputs": outputs, "simulated truth columns": truth},
        why="they are columns of the trace CSV `fdisyn simulate` writes",
    )


def _signal_texts(
    units: Mapping[str, str] | None, labels: Mapping[str, str] | None, signals: Sequence[str]
) -> tuple[dict[str, str], dict[str, str]]:
    """A plant's ``units`` and ``labels``, checked: keys among ``signals``, values short text."""
    return tuple(  # type: ignore[return-value]
        {} if given is None else check_signal_texts(given, key, list(dict.fromkeys(signals)), max_length=longest)
        for key, given, longest in (("units", units, UNIT_MAX), ("labels", labels, SIGNAL_LABEL_MAX))
    )


def _as_sx_function(fun: object, name: str, in_shapes: Sequence[int], out_size: int, in_names: Sequence[str], out_name: str) -> ca.Function:
    """Re-wrap a user Function as an SX Function with fdisyn's port names, checking shapes."""
    if not isinstance(fun, ca.Function):
        raise ArgumentError(f"{name} must be a casadi.Function; got {type(fun).__name__}")
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
        first = next((ln.strip() for ln in str(exc).splitlines() if ln.strip()), type(exc).__name__)  # CasADi's text runs to many lines
        raise ArgumentError(f"{name} cannot be evaluated on SX symbols (it must be expandable to SX): {shown(first, 200)}") from exc
    out = ca.densify(ca.reshape(ca.SX(out), out_size, 1))
    wrapped = ca.Function(name, sym, [out], list(in_names), [out_name])
    check_model_function(wrapped, name)
    return wrapped


@dataclass(frozen=True, eq=False)
class NonlinearPlant:
    """``x⁺ = f(x, u, θ) + v``, ``y = h(x, θ) + e`` (Zhou, Xi & Zhang 1991, eq. (2.1)), with nominal ``θ``.

    Build with :meth:`create` (CasADi Functions) or :meth:`from_expressions`
    (strings). ``f`` has ports ``(x, u, theta) → x_next`` and ``h`` has
    ``(x, theta) → y``; both are SX Functions, checked for shapes and for
    non-differentiable operations.

    Attributes
    ----------
    f : casadi.Function
        The next state, ``(x, u, theta) → x_next``.
    h : casadi.Function
        The outputs, ``(x, theta) → y``.
    states, inputs, outputs, parameters : tuple of str
        The names of the states, inputs, outputs and parameters θ, in the order of the ports.
    theta_nominal : numpy.ndarray
        Nominal parameter values, in the order of :attr:`parameters`.
    Q : numpy.ndarray
        Process-noise covariance of ``v`` (the paper's ``Q1``, eq. (2.1)).
    R : numpy.ndarray
        Measurement-noise covariance of ``e`` (the paper's ``Q2``, eq. (2.1)); positive definite.
    Ts : float or None
        Sample time in seconds (informational; the model is already discrete).
    expressions : Mapping or None
        The expression strings the plant was built from, if any (for reports and gain files).
    units : Mapping of str to str
        A unit per name (states, inputs, outputs, parameters; ``"rad/s"``).
    labels : Mapping of str to str
        A readable name per name, without its unit (``"rotor speed"``).

    Examples
    --------
    >>> plant = NonlinearPlant.from_expressions(
    ...     states=["x"], inputs=["u"], outputs=["y"], parameters=["a"], nominal={"a": 0.9},
    ...     f={"x": "a*x + u"}, h={"y": "x"}, Q=[[0.01]], R=[[0.01]])
    >>> plant.n, plant.m, plant.p, plant.l
    (1, 1, 1, 1)
    """

    f: ca.Function
    h: ca.Function
    states: tuple[str, ...]
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    parameters: tuple[str, ...]
    theta_nominal: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    Ts: float | None = None
    expressions: Mapping[str, object] | None = None
    units: Mapping[str, str] = field(default_factory=dict)
    labels: Mapping[str, str] = field(default_factory=dict)

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
        Q: object,
        R: object,
        Ts: float | None = None,
        units: Mapping[str, str] | None = None,
        expressions: Mapping[str, object] | None = None,
        labels: Mapping[str, str] | None = None,
    ) -> NonlinearPlant:
        """Validate and build a plant from CasADi Functions ``f(x, u, θ)`` and ``h(x, θ)``.

        Parameters
        ----------
        f : casadi.Function
            ``(x, u, theta) → x_next``, an SX Function.
        h : casadi.Function
            ``(x, theta) → y``, an SX Function.
        states, inputs, outputs, parameters : sequence of str
            The names of the states, inputs, outputs and parameters θ, in the order of the ports (distinct, each
            following :mod:`fdisyn.runtime.names`; there may be no inputs).
        nominal : Mapping of str to float
            The nominal value of every parameter.
        Q : array_like
            The process-noise covariance of ``v`` (the paper's ``Q1``).
        R : array_like
            The measurement-noise covariance of ``e`` (the paper's ``Q2``); positive definite.
        Ts : float, optional
            The sample time in seconds (informational; the model is already discrete).
        units : Mapping of str to str, optional
            A unit per name: keys among the states, inputs, outputs and parameters, each unit one line of at most
            :data:`~fdisyn.runtime.schema.UNIT_MAX` printable characters.
        expressions : Mapping, optional
            The expression strings ``f`` and ``h`` were built from (recorded for reports and gain files).
        labels : Mapping of str to str, optional
            A readable name per name, without its unit: keys as ``units``, each at most
            :data:`~fdisyn.runtime.schema.SIGNAL_LABEL_MAX` printable characters.

        Returns
        -------
        NonlinearPlant
            The validated plant.

        Raises
        ------
        NominalValueError
            A parameter has no nominal value, or a non-finite one.
        NonDifferentiableError
            ``f`` or ``h`` uses ``abs``, ``min``/``max``, comparisons, ``if_else``…
        ShapeError
            Wrong port shapes.
        ArgumentError
            Bad names, a covariance that is not one, a model that is too large, a unit or label of no name of the
            plant or that is not short text.
        """
        st = _names(states, "state")
        inp = _names(inputs, "input", allow_empty=True)
        out = _names(outputs, "output")
        par = _names(parameters, "parameter")
        _distinct_names(st, inp, out, par)
        texts = _signal_texts(units, labels, (*st, *inp, *out, *par))
        n, m, p, l = len(st), len(inp), len(out), len(par)
        theta = _nominal_vector(par, nominal)
        f_sx = _as_sx_function(f, "f", (n, m, l), n, ("x", "u", "theta"), "x_next")
        h_sx = _as_sx_function(h, "h", (n, l), p, ("x", "theta"), "y")
        q = as_covariance(Q, "Q", n)
        r = as_covariance(R, "R", p, definite=True)
        return cls(
            f=f_sx,
            h=h_sx,
            states=st,
            inputs=inp,
            outputs=out,
            parameters=par,
            theta_nominal=frozen_array(theta),
            Q=frozen_array(q),
            R=frozen_array(r),
            Ts=None if Ts is None else check_sample_time(Ts),
            expressions=None if expressions is None else dict(expressions),
            units=texts[0],
            labels=texts[1],
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
        Q: object,
        R: object,
        constants: Mapping[str, float] | None = None,
        Ts: float | None = None,
        units: Mapping[str, str] | None = None,
        labels: Mapping[str, str] | None = None,
    ) -> NonlinearPlant:
        """Build a plant from one next-state expression per state and one expression per output.

        Expressions are arithmetic in the state, input, parameter and constant
        names (``+ - * / ^ **``, parentheses, numbers, ``pi``) and the smooth
        functions of :data:`~fdisyn.models.expressions.SMOOTH_FUNCTIONS`. The output expressions may not
        use inputs (the measurement of eq. (2.1) is ``H(θ) X``, no feedthrough).

        Parameters
        ----------
        states, inputs, outputs, parameters : sequence of str
            The names of the states, inputs, outputs and parameters θ, in the order of the ports (distinct, each
            following :mod:`fdisyn.runtime.names`; there may be no inputs).
        nominal : Mapping of str to float
            The nominal value of every parameter.
        Q : array_like
            The process-noise covariance of ``v`` (the paper's ``Q1``).
        R : array_like
            The measurement-noise covariance of ``e`` (the paper's ``Q2``); positive definite.
        Ts : float, optional
            The sample time in seconds (informational; the model is already discrete).
        units, labels : Mapping of str to str, optional
            A unit and a readable name per name, as in :meth:`create`.
        f : Mapping of str to str
            One next-state expression per state.
        h : Mapping of str to str
            One expression per output (no inputs).
        constants : Mapping of str to float, optional
            Named constants the expressions may use.

        Returns
        -------
        NonlinearPlant
            The validated plant.

        Raises
        ------
        NonDifferentiableError
            An expression uses ``abs``, ``min``, ``max``, ``floor``, ``%``,
            comparisons, conditionals or another operation with a kink or jump.
        NominalValueError
            A parameter without a nominal value.
        ArgumentError
            Unknown names or functions, a missing or extra state/output
            expression, a syntax error, a constant (named, literal or folded)
            that is not a finite number, an expression beyond
            :data:`~fdisyn.models.expressions.MAX_EXPRESSION_CHARS` or
            :data:`~fdisyn.models.expressions.MAX_EXPRESSION_OPERATORS`.
        """
        st = _names(states, "state")
        inp = _names(inputs, "input", allow_empty=True)
        out = _names(outputs, "output")
        par = _names(parameters, "parameter")
        _distinct_names(st, inp, out, par)
        _signal_texts(units, labels, (*st, *inp, *out, *par))  # before parsing anything
        _nominal_vector(par, nominal)  # fail on missing nominal values before parsing anything
        consts = {"pi": float(np.pi), **expression_constants(constants)}
        clash = sorted(set(consts) & set(st + inp + out + par))
        if clash:
            raise ArgumentError(f"constant names {clash} clash with signal or parameter names")
        for what, given, expected in (("f", f, st), ("h", h, out)):
            if not isinstance(given, Mapping):
                raise ArgumentError(f"{what}: expected a table of expression strings by name; got {shown(given)}")
            wrong = {k: shown(v) for k, v in given.items() if not isinstance(v, str)}
            if wrong:
                raise ArgumentError(f"{what}: expressions must be strings; got {wrong}")
            keys = set(given)
            if keys != set(expected):
                raise ArgumentError(
                    f"{what}: expected one expression per {'state' if what == 'f' else 'output'} "
                    f"{list(expected)}; missing {sorted(set(expected) - keys)}, unknown {sorted(keys - set(expected))}"
                )
        x = ca.SX.sym("x", len(st))
        u = ca.SX.sym("u", len(inp))
        th = ca.SX.sym("theta", len(par))
        sym_f = {**{nm: x[i] for i, nm in enumerate(st)}, **{nm: u[i] for i, nm in enumerate(inp)}, **{nm: th[i] for i, nm in enumerate(par)}}
        sym_h = {**{nm: x[i] for i, nm in enumerate(st)}, **{nm: th[i] for i, nm in enumerate(par)}}
        fx = ca.vertcat(*[compile_expression(f[nm], sym_f, consts, f"f[{nm!r}]") for nm in st])
        hx_parts = []
        for nm in out:
            try:
                hx_parts.append(compile_expression(h[nm], sym_h, consts, f"h[{nm!r}]"))
            except ArgumentError as exc:
                if any(re.search(rf"\b{re.escape(i)}\b", h[nm]) for i in inp) and "unknown name" in str(exc):
                    raise ArgumentError(f"h[{nm!r}]: the output expression uses an input; h(x, θ) may not depend on u") from None
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
            Q=Q,
            R=R,
            Ts=Ts,
            units=units,
            labels=labels,
            expressions={"f": dict(f), "h": dict(h), "constants": {k: v for k, v in consts.items() if k != "pi"}},
        )

    # dimensions -------------------------------------------------------------
    @property
    def n(self) -> int:
        """The number of states."""
        return len(self.states)

    @property
    def m(self) -> int:
        """The number of inputs."""
        return len(self.inputs)

    @property
    def p(self) -> int:
        """The number of outputs."""
        return len(self.outputs)

    @property
    def l(self) -> int:
        """The number of parameters θ."""
        return len(self.parameters)

    # derivatives ------------------------------------------------------------
    def derivatives(self) -> ca.Function:
        """``(x, u, theta) → (f, F_x, F_theta, h, H_x, H_theta)`` by CasADi AD.

        ``F_x = ∂f/∂x`` (the paper's ``F_t``), ``F_theta = ∂f/∂θ``,
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
        """The values of :meth:`derivatives` at a point, as numpy arrays.

        Parameters
        ----------
        x : array_like
            The state (``n`` entries).
        u : array_like
            The input (``m`` entries).
        theta : array_like, optional
            The parameters (``l`` entries); default: nominal.

        Returns
        -------
        dict of str to numpy.ndarray
            ``f``, ``F_x``, ``F_theta``, ``h``, ``H_x`` and ``H_theta`` at the point.

        Raises
        ------
        ArgumentError
            A vector that does not hold real numbers.
        ShapeError
            A vector of the wrong length.
        """
        th = self.theta_nominal if theta is None else theta
        vals = self.derivatives().call(
            {
                "x": as_vector(x, "x", self.n),
                "u": as_vector(u, "u", self.m),
                "theta": as_vector(th, "theta", self.l),
            }
        )
        return {k: np.array(v, dtype=float) for k, v in vals.items()}

    def check_finite(self, *, x: object, u: object, theta: object | None = None, point: str = "the nominal point") -> None:
        """Refuse a model that is not finite at ``(x, u, θ)`` (``θ`` defaults to nominal).

        ``f``, ``h`` and the four AD Jacobians are evaluated there; the first
        NaN or infinite entry raises :class:`ArgumentError` naming the state or
        output expression, the derivative and the value. A design starts its
        filters at such a point: a model that is not finite there (``x/0``,
        ``log(x)`` at ``x = 0``, ``x**x`` whose derivative at ``x = 0`` is
        ``0·∞``) would make the first step diverge and every later one reset.

        Parameters
        ----------
        x : array_like
            The state (``n`` entries).
        u : array_like
            The input (``m`` entries).
        theta : array_like, optional
            The parameters (``l`` entries); default: nominal.
        point : str
            What the refusal calls the point.

        Raises
        ------
        ArgumentError
            A value or derivative that is not finite there.
        """
        vals = self.linearise(x=x, u=u, theta=theta)
        rows = {"f": self.states, "h": self.outputs}
        cols = {"x": self.states, "theta": self.parameters}
        for key in ("f", "h", "F_x", "F_theta", "H_x", "H_theta"):
            fun = key[0].lower()
            bad = np.argwhere(~np.isfinite(vals[key]))
            if not bad.size:
                continue
            i, j = (int(v) for v in bad[0])
            row = rows[fun][i]
            what = f"{fun}[{row!r}]" if "_" not in key else f"∂{fun}[{row!r}]/∂{cols[key.split('_', 1)[1]][j]}"
            exprs = (self.expressions or {}).get(fun)
            text = f" (the expression {shown(exprs[row])})" if isinstance(exprs, Mapping) and isinstance(exprs.get(row), str) else ""
            raise ArgumentError(
                f"the model is not finite at {point}: {what} = {float(vals[key][i, j])!r}{text}; "
                "expected finite values of f, h and their Jacobians there"
            )

    def to_toml(self, name: str = "plant", **sections: Any) -> str:
        """The plant as a TOML plant file (``time = "nonlinear"``) that the plant-file reader reads back as this plant.

        Only a plant built from expressions (:meth:`from_expressions`, or a plant file) can be written: a plant
        file holds expressions, not CasADi functions.

        Parameters
        ----------
        name : str
            The problem's name (it prefixes the C API of its diagnosers).
        **sections
            Optional sections (:func:`fdisyn.models.plant_toml.plant_file_text`): ``title``, ``design``,
            ``designs``, ``simulation``, ``scenarios``.

        Returns
        -------
        str
            The TOML text.

        Raises
        ------
        ArgumentError
            A plant built from CasADi functions, or a section value a plant file cannot hold.
        """
        from fdisyn.models.plant_toml import nonlinear_tables, plant_file_text

        return plant_file_text(nonlinear_tables(self), name, **sections)


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
        raw = nominal[p]
        v = real_number(raw)  # float() would read the string "0.2" and true
        if v is None:
            raise NominalValueError(f"nominal value of parameter {p!r} must be a number; found {shown(raw)}")
        if not math.isfinite(v):
            raise NominalValueError(f"nominal value of parameter {p!r} must be finite; found {v!r}")
        vals.append(v)
    return np.array(vals)
