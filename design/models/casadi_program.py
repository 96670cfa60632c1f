"""A CasADi model function as a list of elementary operations: the form gain files store.

:func:`model_program` writes an SX function (``f`` or ``h`` of a
:class:`~fdisyn.models.nonlinear.NonlinearPlant`) as CasADi's own operation
sequence, and :func:`function_from_program` rebuilds it after validating every
operation, index and constant, so a corrupted or crafted file never reaches
CasADi's own deserialiser. :func:`check_model_function` refuses a function
holding an operation outside :data:`SMOOTH_OPERATIONS`, a non-finite constant
or more than :data:`MAX_MODEL_INSTRUCTIONS` operations: the NAFDF step
evaluates the model and its Jacobians four times, so a larger model could not
fit its step budget (:data:`fdisyn.synthesis.nafdf.settings.MAX_STEP_INSTRUCTIONS`)
anyway.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import casadi as ca
from fdisyn.models.expressions import SMOOTH_FUNCTIONS
from fdisyn.runtime.errors import ArgumentError, NonDifferentiableError
from fdisyn.runtime.names import shown

__all__ = [
    "MAX_MODEL_INSTRUCTIONS",
    "NONDIFFERENTIABLE_OPERATIONS",
    "SMOOTH_OPERATIONS",
    "check_model_function",
    "function_from_program",
    "model_program",
]

MAX_MODEL_INSTRUCTIONS = 10_000
"""Most CasADi operations in ``f`` or in ``h`` (a quarter of the NAFDF step budget; module docstring)."""

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


def check_model_function(fun: ca.Function, name: str) -> None:
    """Refuse an SX model Function that is too large, uses an operation outside
    :data:`SMOOTH_OPERATIONS` or holds a non-finite constant.

    Parameters
    ----------
    fun : casadi.Function
        An SX function (``f`` or ``h`` of a plant).
    name : str
        Its name in the errors.

    Raises
    ------
    NonDifferentiableError
        A kink or a jump (AD is undefined there), naming the instruction.
    ArgumentError
        More than :data:`MAX_MODEL_INSTRUCTIONS` operations, a non-finite constant or another operation a plant
        model may not hold, naming the instruction.
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
