"""The step of a ``kind = "linear"`` gain file as one CasADi ``Function``: the generators, their statistics, the
persistence counters and the decision table, with the semantics of the NumPy reference
(:mod:`fdisyn.runtime.reference`), which this module reproduces symbolically."""

from __future__ import annotations

import casadi as ca
import numpy as np
from fdisyn.detectors.symbolic import all_finite, all_of, constant, finite
from fdisyn.detectors.table import DETECTORS
from fdisyn.runtime.gainfile import GainFile
from fdisyn.runtime.layout import StateLayout, linear_state_layout
from fdisyn.runtime.warmup import generator_warmup
from fdisyn.synthesis.kinds import STEP_INPUTS, STEP_OUTPUTS

__all__ = ["linear_step_function"]


def linear_step_function(gf: GainFile) -> ca.Function:
    """Symbolic step of a ``kind = "linear"`` gain file (semantics of the reference)."""
    st = gf.step
    lay = linear_state_layout(gf.generators, gf.evaluators, gf.decision)
    state = ca.SX.sym("state", st.nstate)
    u = ca.SX.sym("u", st.nu)
    y = ca.SX.sym("y", st.ny)
    fin_u = finite(u)
    fin_y = finite(y)
    us = ca.if_else(fin_u, u, 0)
    ys = ca.if_else(fin_y, y, 0)
    all_u = all_of(fin_u)
    nxt = ca.SX(state)
    assert gf.decision is not None
    persistence = float(gf.decision.persistence)
    r_parts, j_parts, flags = [], [ca.SX(0)] * len(gf.evaluators), [ca.SX(0)] * len(gf.evaluators)
    live_parts = []  # the residuals of the generators whose statistics ran: the isolation evidence's input
    ran: ca.SX = ca.SX(0)  # some generator's statistics ran
    overflow = ca.SX(0)
    for g, gen in enumerate(gf.generators):
        inputs_ok = ca.logic_and(all_u, all_of(ca.vertcat(*[fin_y[j] for j in gen.outputs_used])))
        sl = lay[f"xi{g}"]
        ready = state[lay["ready"].start + g]
        xi_eq = ca.mtimes(constant(gen.Xu), us) + ca.mtimes(constant(gen.Xy), ys)
        xi = ca.if_else(ready == 0, xi_eq, state[sl.start : sl.stop])
        r_g = ca.mtimes(constant(gen.Cr), xi) + ca.mtimes(constant(gen.Du), us) + ca.mtimes(constant(gen.Dy), ys)
        xi_next = ca.mtimes(constant(gen.Ar), xi) + ca.mtimes(constant(gen.Bu), us) + ca.mtimes(constant(gen.By), ys)
        n_warm = gen.warmup
        warm = generator_warmup(gf, g)
        live: ca.SX = ca.SX(1)  # the statistics run (after the warm-up)
        acc_new = None
        if warm is not None:  # the warm-up: accumulate, correct after the last sample, hold the statistics till then
            gains, correction = warm
            acc_sl = lay[f"acc{g}"]
            acc_new = ca.if_else(ready == 0, ca.SX.zeros(gen.n_state), state[acc_sl.start : acc_sl.stop])
            for k in range(n_warm):
                acc_new = acc_new + ca.if_else(ready == k, ca.mtimes(constant(gains[k]), r_g), ca.SX.zeros(gen.n_state))
            xi_next = xi_next + ca.if_else(ready == n_warm - 1, ca.mtimes(constant(correction), acc_new), ca.SX.zeros(gen.n_state))
            live = ready >= n_warm
        evs = [j for j, ev in enumerate(gf.evaluators) if ev.generator == g]
        values = {}
        for j in evs:
            ev = gf.evaluators[j]
            stat = DETECTORS[ev.kind].statistic
            block = None if stat.block is None else lay[f"{stat.block}{j}"]
            values[j] = stat.evaluate(r_g, None if block is None else state[block.start : block.stop], ev)
        # the statistics' values checked in the order the reference lists them: direct ones, then sequential
        j_g = {j: values[j].J for j in evs if not DETECTORS[gf.evaluators[j].kind].statistic.sequential}
        j_g.update({j: values[j].J for j in evs if DETECTORS[gf.evaluators[j].kind].statistic.sequential})
        windows = {j: values[j].state for j in evs if values[j].state is not None}
        # a finite but absurd value can overflow: the sample is then skipped like a non-finite one
        # the statistics are evaluated in the warm-up too: an absurd sample overflows as it would later
        results_ok = all_finite(r_g, xi_next, *j_g.values(), *windows.values(), *([] if acc_new is None else [acc_new]))
        ok = ca.logic_and(inputs_ok, results_ok)
        overflow = ca.logic_or(overflow, ca.logic_and(inputs_ok, 1 - results_ok))
        nxt[sl.start : sl.stop] = ca.if_else(ok, xi_next, state[sl.start : sl.stop])
        # after an overflow the generator restarts at its next valid sample
        if warm is None:
            nxt[lay["ready"].start + g] = ca.if_else(ok, 1, ca.if_else(inputs_ok, 0, ready))
        else:  # its valid samples counted to warmup + 1; a gap in the warm-up restarts it
            held = ca.if_else(ready < n_warm, 0, ready)
            nxt[lay["ready"].start + g] = ca.if_else(ok, ca.fmin(ready + 1, n_warm + 1), ca.if_else(inputs_ok, 0, held))
            acc_sl = lay[f"acc{g}"]
            assert acc_new is not None
            emptied = ca.if_else(ready == n_warm - 1, ca.SX.zeros(gen.n_state), acc_new)  # used: the accumulator is emptied
            nxt[acc_sl.start : acc_sl.stop] = ca.if_else(ca.logic_and(ok, 1 - live), emptied, state[acc_sl.start : acc_sl.stop])
        running = ok if warm is None else ca.logic_and(ok, live)
        r_parts.append(ca.if_else(ok, r_g, 0))
        live_parts.append(ca.if_else(running, r_g, 0))
        ran = ca.logic_or(ran, running)
        for j, window in windows.items():
            ws = lay[f"{DETECTORS[gf.evaluators[j].kind].statistic.block}{j}"]
            nxt[ws.start : ws.stop] = ca.if_else(running, window, state[ws.start : ws.stop])
        for j in evs:
            jj = ca.if_else(running, j_g[j], 0)
            c = state[lay["counters"].start + j]
            ev = gf.evaluators[j]
            c_next = ca.if_else(running, DETECTORS[ev.kind].statistic.counter(values[j], jj, c, ev), c)
            nxt[lay["counters"].start + j] = c_next
            flags[j] = ca.logic_and(running, c_next >= persistence)
            j_parts[j] = jj
    r = ca.vertcat(*r_parts)
    bad = ca.logic_or(overflow, 1 - ca.logic_and(all_u, all_of(fin_y)))
    nxt[lay["nonfinite"].start] = state[lay["nonfinite"].start] + bad
    alarm = ca.SX(0)
    for fl in flags:
        alarm = ca.logic_or(alarm, fl)
    pattern = ca.SX(-1)  # the class whose signature equals the flag pattern (rows are distinct: at most one)
    for f, row in enumerate(np.asarray(gf.decision.signatures, dtype=int)):
        match = ca.SX(1)
        for j, s in enumerate(row):
            match = match * (flags[j] if s else 1 - flags[j])
        pattern = pattern + (f + 1) * match
    if gf.decision.isolation is None:
        isolated = pattern
    else:
        isolated = _held_class(gf, lay, state, nxt, ca.vertcat(*live_parts), alarm, pattern, ran)
    return ca.Function(
        "step",
        [state, u, y],
        [nxt, r, ca.vertcat(*j_parts), alarm, isolated, bad],
        list(STEP_INPUTS),
        list(STEP_OUTPUTS),
    )


def _held_class(
    gf: GainFile, lay: StateLayout, state: ca.SX, nxt: ca.SX, r_live: ca.SX, alarm: ca.SX, pattern: ca.SX, ran: ca.SX
) -> ca.SX:
    """The decision's hypothesis test and held class (:func:`fdisyn.runtime.reference.isolation_test`,
    :func:`~fdisyn.runtime.reference.held_class`), writing the evidence and the named class into ``nxt``; a sample
    on which no statistic ran (``ran`` 0) leaves them as they were and names nothing."""
    assert gf.decision is not None and gf.decision.isolation is not None
    iso = gf.decision.isolation
    ev = lay["evidence"]
    s = float(iso.forgetting) * state[ev.start : ev.stop] + ca.mtimes(constant(np.asarray(iso.basis, dtype=float)), r_live)
    s = ca.if_else(all_finite(s), s, ca.SX.zeros(s.shape[0]))  # an overflow: the evidence starts again
    nxt[ev.start : ev.stop] = ca.if_else(ran, s, state[ev.start : ev.stop])
    q = ca.sumsqr(s)
    directions = np.asarray(iso.directions, dtype=float)
    proj = ca.mtimes(constant(directions), s) if directions.size else ca.SX.zeros(0)
    ranks = [int(k) for k in np.asarray(iso.ranks)]
    nested = np.asarray(iso.nested, dtype=int)
    plausible, supported, row = [], [], 0
    for f, k in enumerate(ranks):
        g = ca.sumsqr(proj[row : row + k]) if k else ca.SX(0)
        row += k
        ok = q - g <= float(iso.reject[f])
        plausible.append(ok)
        supported.append(ca.logic_and(ok, g >= float(iso.accept[f])))
    candidate = ca.SX(-1)
    for f in reversed(range(len(ranks))):  # the first class that qualifies
        qualifies = supported[f]
        for k in range(len(ranks)):
            if k != f and not nested[f][k]:
                qualifies = ca.logic_and(qualifies, 1 - plausible[k])
        candidate = ca.if_else(qualifies, f, candidate)
    nm = lay["named"].start
    named = state[nm] - 1
    ag = lay["age"].start
    age = ca.if_else(alarm, ca.fmin(state[ag] + 1, float(iso.settle)), 0)
    nxt[ag] = ca.if_else(ran, age, state[ag])
    candidate = ca.if_else(age >= float(iso.settle), candidate, -1)
    # the test's candidate when it names one (a plausible named class contains it); else the held name, else the pattern
    held = ca.if_else(alarm, ca.if_else(candidate >= 0, candidate, ca.if_else(named < 0, pattern, named)), -1)
    nxt[nm] = ca.if_else(ran, held + 1, state[nm])
    return ca.if_else(ran, held, -1)
