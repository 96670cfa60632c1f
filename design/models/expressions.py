"""The expression language of a nonlinear plant file: one arithmetic string to a CasADi expression.

:meth:`fdisyn.models.nonlinear.NonlinearPlant.from_expressions` compiles the
``f`` and ``h`` of a plant file here. An expression is ASCII arithmetic in
the plant's names and named constants (``+ - * / ^ **``, parentheses, decimal
numbers) and the smooth functions of :data:`SMOOTH_FUNCTIONS`; anything with a
kink or a jump is refused by name
(:class:`~fdisyn.runtime.errors.NonDifferentiableError`), since every Jacobian
comes from automatic differentiation.

Numbers are data: a literal that overflows (``1e999``), a constant
subexpression that folds to one (``10**10**10``, ``log(-1.0)``) and a
``[model].constants`` entry that is not finite are refused where they enter,
naming the expression. An expression has at most
:data:`MAX_EXPRESSION_CHARS` characters and :data:`MAX_EXPRESSION_OPERATORS`
operators (operator symbols, parentheses, commas and keywords each count
once), checked before it is parsed: Python's parser nests once per operator
and builds its syntax tree recursively, so a 5000-term sum would exhaust its
recursion limit; a hand-written model expression has a few dozen operators.
"""

from __future__ import annotations

import ast
import io
import keyword
import math
import re
import tokenize
import unicodedata
from collections.abc import Callable, Mapping

import casadi as ca
from fdisyn.runtime.errors import ArgumentError, NonDifferentiableError
from fdisyn.runtime.names import shown
from fdisyn.runtime.values import real_number

__all__ = ["MAX_EXPRESSION_CHARS", "MAX_EXPRESSION_OPERATORS", "SMOOTH_FUNCTIONS", "compile_expression", "expression_constants"]

MAX_EXPRESSION_CHARS = 10_000
"""Longest expression string (characters); see the module docstring."""
MAX_EXPRESSION_OPERATORS = 1_000
"""Most operators in one expression: bounds the nesting of Python's recursive parser (module docstring)."""


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


def compile_expression(text: str, symbols: Mapping[str, ca.SX], constants: Mapping[str, float], where: str) -> ca.SX:
    """One expression string as a CasADi expression.

    Parameters
    ----------
    text : str
        The expression.
    symbols : mapping of str to casadi.SX
        The names it may use for the plant's signals and parameters.
    constants : mapping of str to float
        The named constants it may use (finite).
    where : str
        Where the expression was written, for the errors (e.g. ``f['x']``).

    Returns
    -------
    casadi.SX
        The expression.

    Raises
    ------
    NonDifferentiableError
        The expression uses an operation with a kink or a jump.
    ArgumentError
        Anything else that is not smooth arithmetic in the given names, a number that is not a finite double, an
        expression beyond the limits.
    """
    return _ExpressionCompiler(symbols, constants, where).compile(text)


def expression_constants(constants: object) -> dict[str, float]:
    """``[model].constants``: identifier names with finite real values (a NaN or inf constant is refused here).

    Parameters
    ----------
    constants : object
        The table as read (``None``: no constant).

    Returns
    -------
    dict of str to float
        The constants by name.

    Raises
    ------
    ArgumentError
        Not a table, a name that is not an identifier, a value that is not a finite number.
    """
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
