"""The step function of a diagnoser as one CasADi ``Function``.

Contract (shared by every diagnoser kind, and by the generated C)::

    step(state[nstate], u[nu], y[ny]) -> (state_next[nstate], r[nr], J[nj],
                                          alarm[1], isolated[1], status[1])

all dense double vectors; ``alarm`` ∈ {0, 1}; ``isolated`` ∈ {−1, 0..nf−1};
``status`` 1 when the sample held a non-finite value (see
:mod:`fdisyn.runtime.reference` for the linear semantics, which this module
reproduces symbolically). Finiteness is tested as ``|v| < ∞`` with
``if_else``, which survives code generation (``v != v`` may not).

Other diagnoser kinds register a builder with :func:`register_step_builder`.
"""

from __future__ import annotations

from collections.abc import Callable

import casadi as ca
import numpy as np

from fdisyn.runtime.errors import GainFileError
from fdisyn.runtime.gainfile import GainFile, linear_state_layout

__all__ = ["STEP_INPUTS", "STEP_OUTPUTS", "step_function", "register_step_builder", "linear_step_function", "finite"]

STEP_INPUTS = ("state", "u", "y")
STEP_OUTPUTS = ("state_next", "r", "J", "alarm", "isolated", "status")

_BUILDERS: dict[str, Callable[[GainFile], ca.Function]] = {}


def register_step_builder(kind: str, builder: Callable[[GainFile], ca.Function]) -> None:
    """Make :func:`step_function` build gain files of ``kind`` with ``builder``."""
    _BUILDERS[kind] = builder


def step_function(gf: GainFile) -> ca.Function:
    """The CasADi step of any diagnoser kind, built from its gain file alone."""
    try:
        builder = _BUILDERS[gf.kind]
    except KeyError:
        raise GainFileError(f"no step builder for diagnoser kind {gf.kind!r}; known kinds: {sorted(_BUILDERS)}") from None
    fn = builder(gf)
    if tuple(fn.name_in()) != STEP_INPUTS or tuple(fn.name_out()) != STEP_OUTPUTS:
        raise GainFileError(f"the {gf.kind!r} step builder broke the step contract: {fn}")
    return fn


def finite(v: ca.SX) -> ca.SX:
    """Elementwise 1 where ``v`` is finite (``|v| < ∞``; false for NaN and ±∞)."""
    return ca.fabs(v) < ca.inf


def _all(flags: ca.SX) -> ca.SX:
    out = ca.SX(1)
    for i in range(flags.numel()):
        out = ca.logic_and(out, flags[i])
    return out


def _const(a: np.ndarray) -> ca.DM:
    # sparsify drops exact zeros: smaller C, and x + 0·y == x exactly for finite y
    return ca.sparsify(ca.DM(np.asarray(a, dtype=float)))


def linear_step_function(gf: GainFile) -> ca.Function:
    """Symbolic step of a ``kind = "linear"`` gain file (semantics of the reference)."""
    st = gf.step
    lay = linear_state_layout(gf.generators, len(gf.evaluators))
    state = ca.SX.sym("state", st.nstate)
    u = ca.SX.sym("u", st.nu)
    y = ca.SX.sym("y", st.ny)
    fin_u = finite(u)
    fin_y = finite(y)
    us = ca.if_else(fin_u, u, 0)
    ys = ca.if_else(fin_y, y, 0)
    all_u = _all(fin_u)
    nxt = ca.SX(state)
    r_parts = []
    valid = []
    for g, gen in enumerate(gf.generators):
        ok = ca.logic_and(all_u, _all(ca.vertcat(*[fin_y[j] for j in gen.outputs_used])))
        valid.append(ok)
        sl = lay[f"xi{g}"]
        ready = state[lay["ready"].start + g]
        xi_eq = ca.mtimes(_const(gen.Xu), us) + ca.mtimes(_const(gen.Xy), ys)
        xi = ca.if_else(ready == 0, xi_eq, state[sl.start : sl.stop])
        r_g = ca.mtimes(_const(gen.Cr), xi) + ca.mtimes(_const(gen.Du), us) + ca.mtimes(_const(gen.Dy), ys)
        xi_next = ca.mtimes(_const(gen.Ar), xi) + ca.mtimes(_const(gen.Bu), us) + ca.mtimes(_const(gen.By), ys)
        nxt[sl.start : sl.stop] = ca.if_else(ok, xi_next, state[sl.start : sl.stop])
        nxt[lay["ready"].start + g] = ca.if_else(ok, 1, ready)
        r_parts.append(ca.if_else(ok, r_g, 0))
    r = ca.vertcat(*r_parts)
    offsets = np.cumsum([0] + [g.n_residual for g in gf.generators])
    assert gf.decision is not None
    persistence = float(gf.decision.persistence)
    j_parts, flags = [], []
    for j, ev in enumerate(gf.evaluators):
        g = ev.generator
        rg = r[int(offsets[g]) : int(offsets[g + 1])]
        jj = ca.if_else(valid[g], ca.mtimes([rg.T, _const(ev.W), rg]), 0)
        c = state[lay["counters"].start + j]
        c_next = ca.if_else(valid[g], ca.if_else(jj > ev.threshold, c + 1, 0), c)
        nxt[lay["counters"].start + j] = c_next
        flags.append(ca.logic_and(valid[g], c_next >= persistence))
        j_parts.append(jj)
    bad = 1 - ca.logic_and(all_u, _all(fin_y))
    nxt[lay["nonfinite"].start] = state[lay["nonfinite"].start] + bad
    alarm = ca.SX(0)
    for fl in flags:
        alarm = ca.logic_or(alarm, fl)
    isolated = ca.SX(-1)
    for f, row in enumerate(np.asarray(gf.decision.signatures, dtype=int)):
        match = ca.SX(1)
        for j, s in enumerate(row):
            match = match * (flags[j] if s else 1 - flags[j])
        isolated = isolated + (f + 1) * match
    return ca.Function(
        "step",
        [state, u, y],
        [nxt, r, ca.vertcat(*j_parts), alarm, isolated, bad],
        list(STEP_INPUTS),
        list(STEP_OUTPUTS),
    )


register_step_builder("linear", linear_step_function)
