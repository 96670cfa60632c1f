"""The symbolic vocabulary every generated step is written in (CasADi ``SX``): finiteness tests and reductions
that survive code generation.

Finiteness is tested as ``|v| < ∞`` with ``if_else``, which survives code generation (``v != v`` may be folded
away).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

__all__ = ["finite", "all_finite", "any_of", "all_of", "constant"]


def finite(v: ca.SX) -> ca.SX:
    """Elementwise 1 where ``v`` is finite (``|v| < ∞``; false for NaN and ±∞).

    The one finiteness test of every generated step (linear and NAFDF): written
    with a comparison, which code generation keeps, where ``v != v`` may be
    folded away.
    """
    return ca.fabs(v) < ca.inf


def all_finite(*exprs: ca.SX) -> ca.SX:
    """1 if every entry of every expression is finite (:func:`finite`), else 0."""
    return all_of(finite(ca.vertcat(*[ca.vec(ca.SX(e)) for e in exprs])))


def any_of(flags: ca.SX) -> ca.SX:
    out = ca.SX(0)
    for i in range(flags.numel()):
        out = ca.logic_or(out, flags[i])
    return out


def all_of(flags: ca.SX) -> ca.SX:
    out = ca.SX(1)
    for i in range(flags.numel()):
        out = ca.logic_and(out, flags[i])
    return out


def constant(a: np.ndarray) -> ca.DM:
    # sparsify drops exact zeros: smaller C, and x + 0·y == x exactly for finite y
    return ca.sparsify(ca.DM(np.asarray(a, dtype=float)))
