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
(:meth:`NonlinearPlant.from_expressions`), the form a TOML plant file uses::

    NonlinearPlant.from_expressions(
        states=["x"], inputs=["u"], outputs=["y"], parameters=["a", "b"],
        nominal={"a": -0.58, "b": 0.2},
        f={"x": "0.1*a*x^2 + x + 0.1*b*u"}, h={"y": "x"},
        Q=0.0, R=0.01)

Numbers are data: a model may hold no NaN or infinite constant. A literal
that overflows (``1e999``), a constant subexpression that folds to one
(``10**10**10``, ``log(-1.0)``) and a ``[model].constants`` entry that is not
finite are refused where they enter, naming the expression.
:meth:`NonlinearPlant.check_finite` evaluates ``f``, ``h`` and their AD
Jacobians at a point (the designs call it at their initial state and the
nominal ``θ``) and refuses a model that is not finite there — ``x/0``,
``x**x`` at ``x = 0``.

Limits, checked before anything is parsed or built (a plant file is data a
user or an attacker controls; these keep every stage bounded):

* an expression has at most :data:`MAX_EXPRESSION_CHARS` characters and
  :data:`MAX_EXPRESSION_OPERATORS` operators (operator symbols, parentheses,
  commas and keywords each count once): Python's parser nests once per
  operator and builds its syntax tree recursively, so a 5000-term sum would
  exhaust its recursion limit; a hand-written model expression has a few
  dozen operators;
* ``f`` and ``h`` have at most :data:`MAX_MODEL_INSTRUCTIONS` CasADi
  operations each: the NAFDF step evaluates the model and its Jacobians four
  times, so a larger model could not fit its step budget
  (:data:`fdisyn.synthesis.nafdf.settings.MAX_STEP_INSTRUCTIONS`) anyway.

:func:`model_program` writes ``f`` or ``h`` as a list of elementary
operations (the form gain files store) and :func:`function_from_program`
rebuilds it after validating every operation, index and constant, so a
corrupted or crafted file never reaches CasADi's own deserialiser.
"""

from __future__ import annotations

import ast
import io
import keyword
import math
import re
import tokenize
import unicodedata
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np
from fdisyn.models.linear import identifier_names
from fdisyn.models.sampling import check_sample_time
from fdisyn.numerics.linalg import as_covariance, as_vector, frozen_array
from fdisyn.runtime.errors import ArgumentError, NominalValueError, NonDifferentiableError, ShapeError
from fdisyn.runtime.names import check_distinct, shown
from fdisyn.runtime.values import real_number

__all__ = [
    "MAX_EXPRESSION_CHARS",
    "MAX_EXPRESSION_OPERATORS",
    "MAX_MODEL_INSTRUCTIONS",
    "NONDIFFERENTIABLE_OPERATIONS",
    "SMOOTH_FUNCTIONS",
    "SMOOTH_OPERATIONS",
    "NonlinearPlant",
    "function_from_program",
    "model_program",
]

MAX_EXPRESSION_CHARS = 10_000
"""Longest expression string (characters); see the module docstring."""
MAX_EXPRESSION_OPERATORS = 1_000
"""Most operators in one expression: bounds the nesting of Python's recursive parser (module docstring)."""
MAX_MODEL_INSTRUCTIONS = 10_000
"""Most CasADi operations in ``f`` or in ``h`` (a quarter of the NAFDF step budget; module docstring)."""


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

_BINARY_OPERATIONS: Mapping[str, int] = {
    "add": ca.OP_ADD,
    "sub": ca.OP_SUB,
    "mul": ca.OP_MUL,
    "div": ca.OP_DIV,
    "pow": ca.OP_POW,
    "constpow": ca.OP_CONSTPOW,
    "atan2": ca.OP_ATAN2,
    "hypot": ca.OP_HYPOT,
}
_UNARY_OPERATIONS: Mapping[str, int] = {
    "neg": ca.OP_NEG,
    "sq": ca.OP_SQ,
    "twice": ca.OP_TWICE,
    "inv": ca.OP_INV,
    "sqrt": ca.OP_SQRT,
    "exp": ca.OP_EXP,
    "log": ca.OP_LOG,
    "log1p": ca.OP_LOG1P,
    "expm1": ca.OP_EXPM1,
    "sin": ca.OP_SIN,
    "cos": ca.OP_COS,
    "tan": ca.OP_TAN,
    "asin": ca.OP_ASIN,
    "acos": ca.OP_ACOS,
    "atan": ca.OP_ATAN,
    "sinh": ca.OP_SINH,
    "cosh": ca.OP_COSH,
    "tanh": ca.OP_TANH,
    "asinh": ca.OP_ASINH,
    "acosh": ca.OP_ACOSH,
    "atanh": ca.OP_ATANH,
    "erf": ca.OP_ERF,
    "erfinv": ca.OP_ERFINV,
}
SMOOTH_OPERATIONS: Mapping[str, int] = {**_BINARY_OPERATIONS, **_UNARY_OPERATIONS}
"""Every CasADi operation a plant model may use, by the name a gain file stores (arithmetic and the
functions smooth on the interior of their domain). Anything else — the kinks and jumps of
:data:`NONDIFFERENTIABLE_OPERATIONS`, calls into other Functions — is refused."""
_OPERATION_NAMES: Mapping[int, str] = {code: name for name, code in SMOOTH_OPERATIONS.items()}

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
    _check_model_function(wrapped, name)
    return wrapped


def _check_model_function(fun: ca.Function, name: str) -> None:
    """Refuse an SX model Function that is too large, uses an operation outside
    :data:`SMOOTH_OPERATIONS` or holds a non-finite constant.

    Raises :class:`NonDifferentiableError` for kinks and jumps (AD is undefined
    there) and :class:`ArgumentError` otherwise; each names the instruction.
    """
    count = fun.n_instructions()
    if count > MAX_MODEL_INSTRUCTIONS:
        raise ArgumentError(
            f"{name} has {count} operations; at most {MAX_MODEL_INSTRUCTIONS} are allowed "
            "(the NAFDF step evaluates the model and its Jacobians four times within a bounded size)"
        )
    for k in range(count):
        op = fun.instruction_id(k)
        if op in (ca.OP_INPUT, ca.OP_OUTPUT):
            continue
        if op == ca.OP_CONST:
            value = float(fun.instruction_constant(k))
            if not math.isfinite(value):
                raise ArgumentError(f"{name} holds the constant {value!r} (instruction {k}); expected only finite numbers in a model")
            continue
        if op in NONDIFFERENTIABLE_OPERATIONS:
            raise NonDifferentiableError(
                f"{name} uses the non-differentiable operation {NONDIFFERENTIABLE_OPERATIONS[op]!r} "
                f"(instruction {k}); expected only smooth operations ({', '.join(sorted(SMOOTH_FUNCTIONS))}, "
                "+, −, ×, ÷, powers), because every Jacobian comes from automatic differentiation"
            )
        if op not in _OPERATION_NAMES:
            raise ArgumentError(
                f"{name} uses CasADi operation {op} (instruction {k}), which a plant model may not hold; "
                f"expected only {sorted(SMOOTH_OPERATIONS)}"
            )


def model_program(fun: ca.Function) -> dict[str, list[Any]]:
    """``f`` or ``h`` of a :class:`NonlinearPlant` as plain data: ``{"ops": [...], "out": [...]}``.

    Operation ``i`` defines value ``i``: ``["input", port, entry]``,
    ``["const", number]``, ``[name, a]`` or ``[name, a, b]`` with ``name`` in
    :data:`SMOOTH_OPERATIONS` and ``a``, ``b`` indices of earlier values;
    ``out[k]`` is the value of output entry ``k``. It is CasADi's own
    operation sequence, so :func:`function_from_program` rebuilds the
    identical graph, and it holds nothing but names, indices and finite
    numbers, so a reader can validate all of it before building anything.
    """
    ops: list[Any] = []
    where: dict[int, int] = {}  # CasADi work-vector slot → index of the value it holds
    out: list[int] = [0] * fun.nnz_out(0)
    for k in range(fun.n_instructions()):
        op = fun.instruction_id(k)
        args = fun.instruction_input(k)
        res = fun.instruction_output(k)
        if op == ca.OP_OUTPUT:
            out[res[1]] = where[args[0]]
            continue
        if op == ca.OP_INPUT:
            ops.append(["input", int(args[0]), int(args[1])])
        elif op == ca.OP_CONST:
            ops.append(["const", float(fun.instruction_constant(k))])
        else:
            name = _OPERATION_NAMES[op]
            arity = 2 if name in _BINARY_OPERATIONS else 1
            ops.append([name, *[where[a] for a in args[:arity]]])
        where[res[0]] = len(ops) - 1
    return {"ops": ops, "out": list(out)}


def function_from_program(
    program: object, *, name: str, in_names: Sequence[str], in_sizes: Sequence[int], out_name: str, out_size: int
) -> ca.Function:
    """Rebuild an SX Function from :func:`model_program`'s data, validating all of it first.

    Checked before any CasADi object is made: the structure, at most
    :data:`MAX_MODEL_INSTRUCTIONS` operations, every operation name in
    :data:`SMOOTH_OPERATIONS` with its arity, every index pointing to an
    earlier value (so the graph is acyclic), every input entry within its
    port, every constant a finite number, one output per entry. Raises
    :class:`ArgumentError` naming the operation (the gain-file reader words it as a
    :class:`GainFileError` naming the field).
    """
    if not isinstance(program, Mapping) or set(program) != {"ops", "out"}:
        raise ArgumentError(f"{name}: expected an object with the fields 'ops' and 'out'")
    ops, out = program["ops"], program["out"]
    if not isinstance(ops, list) or not isinstance(out, list):
        raise ArgumentError(f"{name}: 'ops' and 'out' must be lists")
    if len(ops) > MAX_MODEL_INSTRUCTIONS:
        raise ArgumentError(f"{name} has {len(ops)} operations; at most {MAX_MODEL_INSTRUCTIONS} are allowed")
    if len(out) != out_size:
        raise ArgumentError(f"{name}.out has {len(out)} entries; expected {out_size}")

    def index(v: object, limit: int, what: str) -> int:
        if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v < limit:
            raise ArgumentError(f"{name}: {what} must be an integer in 0..{limit - 1}; found {shown(v)}")
        return v

    for i, op in enumerate(ops):
        if not isinstance(op, list) or not op or not isinstance(op[0], str):
            raise ArgumentError(f"{name}.ops[{i}] must be a list starting with an operation name; found {shown(op)}")
        kind = op[0]
        if kind == "input":
            if len(op) != 3:
                raise ArgumentError(f"{name}.ops[{i}]: 'input' takes a port and an entry; found {shown(op)}")
            port = index(op[1], len(in_sizes), f"ops[{i}] port")
            index(op[2], in_sizes[port], f"ops[{i}] entry of {in_names[port]}")
        elif kind == "const":
            if len(op) != 2 or isinstance(op[1], bool) or not isinstance(op[1], (int, float)) or not math.isfinite(op[1]):
                raise ArgumentError(f"{name}.ops[{i}]: 'const' takes one finite number; found {shown(op)}")
        elif kind in SMOOTH_OPERATIONS:
            arity = 2 if kind in _BINARY_OPERATIONS else 1
            if len(op) != arity + 1:
                raise ArgumentError(f"{name}.ops[{i}]: {kind!r} takes {arity} operand(s); found {shown(op)}")
            for v in op[1:]:
                index(v, i, f"ops[{i}] operand (an earlier value)")
        else:
            raise ArgumentError(f"{name}.ops[{i}]: unknown operation {shown(kind)}; expected 'input', 'const' or one of {sorted(SMOOTH_OPERATIONS)}")
    for k, v in enumerate(out):
        index(v, len(ops), f"out[{k}]")

    sym = [ca.SX.sym(nm, size) for nm, size in zip(in_names, in_sizes, strict=True)]
    values: list[ca.SX] = []
    for op in ops:
        kind = op[0]
        if kind == "input":
            values.append(sym[op[1]][op[2]])
        elif kind == "const":
            values.append(ca.SX(float(op[1])))
        elif kind in _BINARY_OPERATIONS:
            values.append(ca.SX.binary(_BINARY_OPERATIONS[kind], values[op[1]], values[op[2]]))
        else:
            values.append(ca.SX.unary(_UNARY_OPERATIONS[kind], values[op[1]]))
    result = ca.vertcat(*[values[v] for v in out]) if out else ca.SX(0, 1)
    return ca.Function(name, sym, [ca.densify(result)], list(in_names), [out_name])


def _operator_count(text: str) -> int:
    """Operators in ``text`` — operator and punctuation tokens and keywords — counted without parsing.

    Each can add one level to the syntax tree, so this bounds the depth of
    Python's recursive parser before it runs. Tokenizing is a loop, not a
    recursion; counting stops just past the limit. Text that does not
    tokenize is left to the parser, which reports the syntax error.
    """
    count = 0
    try:
        for tok in tokenize.generate_tokens(io.StringIO(text).readline):
            if tok.type in (tokenize.OP, tokenize.ERRORTOKEN) or (tok.type == tokenize.NAME and keyword.iskeyword(tok.string)):
                count += 1
                if count > MAX_EXPRESSION_OPERATORS:
                    break
    except (tokenize.TokenError, SyntaxError):
        pass
    return count


_NON_ASCII = re.compile(r"[^\x00-\x7f]")
_DECIMAL = re.compile(r"(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_WORD = re.compile(r"\w+")  # a run of (Unicode) identifier characters: what the parser would read as one name


class _ExpressionCompiler:
    """Turns one arithmetic expression string into an SX expression, refusing anything else.

    The syntax tree is walked with an explicit stack (no recursion), so the
    only nesting limit is the parser's, which :data:`MAX_EXPRESSION_OPERATORS`
    keeps out of reach. Every literal and every constant subexpression is
    checked finite where it is formed (``1e999``, ``10**10**10``, ``log(-1.0)``).
    """

    def __init__(self, symbols: Mapping[str, ca.SX], constants: Mapping[str, float], where: str) -> None:
        self.symbols = symbols
        self.constants = constants
        self.where = where
        self.text = ""
        self.source = ""

    def compile(self, text: str) -> ca.SX:
        if not isinstance(text, str) or not text.strip():
            raise ArgumentError(f"{self.where}: expected a non-empty expression string; got {shown(text)}")
        self.text = text
        if len(text) > MAX_EXPRESSION_CHARS:
            raise ArgumentError(
                f"{self.where}: the expression has {len(text)} characters; at most {MAX_EXPRESSION_CHARS} are allowed"
            )
        self._refuse_non_ascii(text)
        # '^' is power in plant files; Python would parse it as xor with the wrong precedence
        self.source = text.strip().replace("^", "**")
        ops = _operator_count(self.source)
        if ops > MAX_EXPRESSION_OPERATORS:
            raise ArgumentError(
                f"{self.where}: the expression has more than {MAX_EXPRESSION_OPERATORS} operators; "
                "split it with [model].constants or simplify it (Python's parser nests once per operator)"
            )
        try:
            tree = ast.parse(self.source, mode="eval")
        except SyntaxError as exc:
            raise ArgumentError(f"{self.where}: cannot parse expression {shown(text)}: {exc.msg}") from None
        except (RecursionError, MemoryError, ValueError) as exc:
            # ValueError: an integer literal beyond Python's digit limit; the others: nesting too deep
            raise ArgumentError(f"{self.where}: cannot parse expression {shown(text)}: {type(exc).__name__}") from None
        return self._evaluate(tree.body)

    def _refuse_non_ascii(self, text: str) -> None:
        """Refuse any character beyond ASCII, naming the name it would become.

        Python's parser folds every identifier by Unicode NFKC, so a fullwidth
        ``ｘ`` or a ligature would silently be read as the name ``x``. Names are
        compared exactly: an expression is ASCII (names, numbers, operators)."""
        bad = _NON_ASCII.search(text)
        if bad is None:
            return
        word = next((w.group() for w in _WORD.finditer(text) if w.start() <= bad.start() < w.end()), bad.group())
        folded = unicodedata.normalize("NFKC", word)
        if folded != word and folded.isascii() and folded in (*self.symbols, *self.constants):
            raise ArgumentError(
                f"{self.where}: {word!r} in {shown(text)} is not the name {folded!r} (it reads as {folded!r} only after "
                f"Unicode NFKC normalisation); names are compared exactly and hold ASCII letters, digits and '_': write {folded!r}"
            )
        ch = bad.group()
        raise ArgumentError(
            f"{self.where}: {word!r} in {shown(text)} holds the non-ASCII character {ch!r} (U+{ord(ch):04X}); expected ASCII "
            "names (letters, digits, '_'), numbers and the operators + - * / ^ ** ( )"
        )

    def _fail_nonsmooth(self, what: str) -> NonDifferentiableError:
        return NonDifferentiableError(
            f"{self.where}: expression {shown(self.text)} uses {what}, which is not differentiable everywhere; "
            f"expected only smooth operations ({', '.join(sorted(SMOOTH_FUNCTIONS))}, +, -, *, /, ^ or **), "
            "because every Jacobian comes from automatic differentiation"
        )

    def _segment(self, node: ast.AST) -> str:
        seg = ast.get_source_segment(self.source, node)
        return shown(seg if seg is not None else self.text)

    def _evaluate(self, root: ast.AST) -> ca.SX:
        """Post-order walk with an explicit stack: check each node on the way down, combine on the way up."""
        stack: list[tuple[ast.AST, bool]] = [(root, False)]
        done: list[ca.SX] = []
        while stack:
            node, children_done = stack.pop()
            if children_done:
                kids = self._children(node)
                args = done[len(done) - len(kids) :] if kids else []
                del done[len(done) - len(kids) :]
                done.append(self._combine(node, args))
            else:
                self._admit(node)
                stack.append((node, True))
                stack.extend((child, False) for child in reversed(self._children(node)))
        return done[0]

    @staticmethod
    def _children(node: ast.AST) -> list[ast.AST]:
        if isinstance(node, ast.BinOp):
            return [node.left, node.right]
        if isinstance(node, ast.UnaryOp):
            return [node.operand]
        if isinstance(node, ast.Call):
            return list(node.args)
        return []

    def _admit(self, node: ast.AST) -> None:
        """Refuse a node that is not plain smooth arithmetic (before its operands are built)."""
        if isinstance(node, ast.BinOp):
            if isinstance(node.op, (ast.Mod, ast.FloorDiv)):
                raise self._fail_nonsmooth("the operator '%' or '//'")
            if not isinstance(node.op, (ast.Add, ast.Sub, ast.Mult, ast.Div, ast.Pow)):
                raise ArgumentError(f"{self.where}: operator {type(node.op).__name__} is not allowed in {shown(self.text)}")
        elif isinstance(node, ast.UnaryOp):
            if not isinstance(node.op, (ast.USub, ast.UAdd)):
                raise self._fail_nonsmooth(f"the operator {type(node.op).__name__}")
        elif isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                raise ArgumentError(f"{self.where}: constant {shown(node.value)} in {shown(self.text)} is not a real number")
            seg = ast.get_source_segment(self.source, node)
            if seg is None or not _DECIMAL.fullmatch(seg):
                # Python also reads 1_0 as 10 and 0x10 as 16: a plant file's numbers are plain decimals
                raise ArgumentError(
                    f"{self.where}: the number {shown(seg)} in {shown(self.text)} is not a decimal numeral; expected digits "
                    "with an optional decimal point and exponent, such as 0.58 or 1e-3 (no '_', no 0x, 0o or 0b prefix)"
                )
        elif isinstance(node, ast.Name):
            if node.id not in self.symbols and node.id not in self.constants:
                allowed = sorted([*self.symbols, *self.constants])
                raise ArgumentError(f"{self.where}: unknown name {node.id!r} in {shown(self.text)}; allowed names are {allowed}")
        elif isinstance(node, ast.Call):
            if not isinstance(node.func, ast.Name) or node.keywords:
                raise ArgumentError(f"{self.where}: only plain calls such as sin(x) are allowed in {shown(self.text)}")
            fname = node.func.id
            if fname in _NONSMOOTH_NAMES:
                raise self._fail_nonsmooth(f"the function {fname}()")
            if fname not in SMOOTH_FUNCTIONS:
                raise ArgumentError(
                    f"{self.where}: unknown function {fname!r} in {shown(self.text)}; allowed: {sorted(SMOOTH_FUNCTIONS)}"
                )
            arity = _BINARY_FUNCTIONS.get(fname, 1)
            if len(node.args) != arity:
                raise ArgumentError(
                    f"{self.where}: {fname}() takes {arity} argument{'s' if arity > 1 else ''}, "
                    f"got {len(node.args)} in {shown(self.text)}"
                )
        elif isinstance(node, (ast.Compare, ast.BoolOp, ast.IfExp)):
            raise self._fail_nonsmooth("a comparison or a conditional")
        else:
            raise ArgumentError(f"{self.where}: {type(node).__name__} is not allowed in the expression {shown(self.text)}")

    def _combine(self, node: ast.AST, args: list[ca.SX]) -> ca.SX:
        if isinstance(node, ast.BinOp):
            left, right = args
            op = node.op
            if isinstance(op, ast.Add):
                out = left + right
            elif isinstance(op, ast.Sub):
                out = left - right
            elif isinstance(op, ast.Mult):
                out = left * right
            elif isinstance(op, ast.Div):
                out = left / right
            else:
                out = left**right
        elif isinstance(node, ast.UnaryOp):
            out = -args[0] if isinstance(node.op, ast.USub) else args[0]
        elif isinstance(node, ast.Constant):
            try:
                value = float(node.value)  # type: ignore[arg-type]  # an int or float: _admit checked it
            except OverflowError:
                value = math.inf
            if not math.isfinite(value):
                raise ArgumentError(
                    f"{self.where}: the number {self._segment(node)} in {shown(self.text)} is not a finite double; "
                    "expected a finite number"
                )
            return ca.SX(value)
        elif isinstance(node, ast.Name):
            if node.id in self.symbols:
                return self.symbols[node.id]
            return ca.SX(float(self.constants[node.id]))
        else:
            assert isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
            out = SMOOTH_FUNCTIONS[node.func.id](*args)
        # CasADi folds constant operands at once: a non-finite result is a NaN/inf constant in the model
        if out.is_constant() and not math.isfinite(float(out)):
            raise ArgumentError(
                f"{self.where}: the constant subexpression {self._segment(node)} in {shown(self.text)} evaluates to "
                f"{float(out)!r}; expected a finite number"
            )
        return out


@dataclass(frozen=True, eq=False)
class NonlinearPlant:
    """``x⁺ = f(x, u, θ) + v``, ``y = h(x, θ) + e`` (Zhou, Xi & Zhang 1991, eq. (2.1)), with nominal ``θ``.

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
    Q: np.ndarray
    """Process-noise covariance of ``v`` (the paper's ``Q1``, eq. (2.1))."""
    R: np.ndarray
    """Measurement-noise covariance of ``e`` (the paper's ``Q2``, eq. (2.1)); positive definite."""
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
        Q: object,
        R: object,
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
        ShapeError
            Wrong port shapes.
        ArgumentError
            Bad names, a covariance that is not one, a model that is too large.
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
        Q: object,
        R: object,
        constants: Mapping[str, float] | None = None,
        Ts: float | None = None,
        units: Mapping[str, str] | None = None,
    ) -> NonlinearPlant:
        """Build a plant from one next-state expression per state and one expression per output.

        Expressions are arithmetic in the state, input, parameter and constant
        names (``+ - * / ^ **``, parentheses, numbers, ``pi``) and the smooth
        functions of :data:`SMOOTH_FUNCTIONS`. The output expressions may not
        use inputs (the measurement of eq. (2.1) is ``H(θ) X``, no feedthrough).

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
            :data:`MAX_EXPRESSION_CHARS` or :data:`MAX_EXPRESSION_OPERATORS`.
        """
        st = _names(states, "state")
        inp = _names(inputs, "input", allow_empty=True)
        out = _names(outputs, "output")
        par = _names(parameters, "parameter")
        _distinct_names(st, inp, out, par)
        _nominal_vector(par, nominal)  # fail on missing nominal values before parsing anything
        consts = {"pi": float(np.pi), **_constants(constants)}
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
        fx = ca.vertcat(*[_ExpressionCompiler(sym_f, consts, f"f[{nm!r}]").compile(f[nm]) for nm in st])
        hx_parts = []
        for nm in out:
            try:
                hx_parts.append(_ExpressionCompiler(sym_h, consts, f"h[{nm!r}]").compile(h[nm]))
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
        """The values of :meth:`derivatives` at a point (``theta`` defaults to nominal), as numpy arrays."""
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

    # simulation -------------------------------------------------------------
    def simulate(
        self,
        *,
        x0: object,
        u: object,
        theta: object | None = None,
        rng: np.random.Generator,
        draws: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Simulate ``T`` samples of (2.1) with Gaussian noise; returns ``(x, y)``, shapes ``(T, n)``, ``(T, p)``.

        ``u`` has shape ``(T, m)``; ``theta`` is ``(l,)`` (constant) or
        ``(T, l)``, where row ``k`` is the parameter of the transition
        ``x(k) → x(k+1)`` (a fault at ``k_f`` first shows in ``y(k_f + 1)``).
        ``x[k]`` and ``y[k] = h(x[k], θ(k)) + e[k]`` are the state and
        measurement at sample ``k``; ``x[0] = x0``. ``draws`` (T × (n + p)) replaces
        the standard normals drawn from ``rng`` (``v``'s, then ``e``'s, per sample):
        the draws of the compiled simulation, to compare the two on the same noise.
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
        x0v = as_vector(x0, "x0", self.n)
        if draws is not None and np.shape(draws) != (T, self.n + self.p):
            raise ShapeError(f"draws have shape {np.shape(draws)}; expected ({T}, {self.n + self.p})")
        v = _gaussian(rng, self.Q, T, None if draws is None else draws[:, : self.n])
        e = _gaussian(rng, self.R, T, None if draws is None else draws[:, self.n :])
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


def _constants(constants: object) -> dict[str, float]:
    """``[model].constants``: identifier names with finite real values (a NaN or inf constant is refused here)."""
    if constants is None:
        return {}
    if not isinstance(constants, Mapping):
        raise ArgumentError(f"constants must be a table of names and numbers; got {shown(constants)}")
    out: dict[str, float] = {}
    for k, v in constants.items():
        if not isinstance(k, str) or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", k):
            raise ArgumentError(f"constant name {shown(k)} is not an identifier (letters, digits, underscore; no leading digit)")
        fv = real_number(v)
        if fv is None:
            raise ArgumentError(f"constant {k!r} must be a number; got {shown(v)}")
        if not math.isfinite(fv):
            raise ArgumentError(f"constant {k!r} must be a finite number; got {shown(v)}")
        out[k] = fv
    return out


def noise_factor(cov: np.ndarray) -> np.ndarray:
    """``F`` with ``F Fᵀ = cov`` (square; a singular ``cov`` is fine: eigen-factor, not Cholesky)."""
    w, vecs = np.linalg.eigh(cov)
    return vecs * np.sqrt(np.clip(w, 0.0, None))[None, :]


def _gaussian(rng: np.random.Generator, cov: np.ndarray, count: int, z: np.ndarray | None = None) -> np.ndarray:
    """``count`` samples of ``N(0, cov)`` (rows), from ``rng`` or the given standard normals ``z``."""
    return (rng.standard_normal((count, cov.shape[0])) if z is None else z) @ noise_factor(cov).T


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
