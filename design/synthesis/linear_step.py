"""The step of a ``kind = "linear"`` gain file as one CasADi ``Function``: the generators, their statistics, the
persistence counters and the decision table, with the semantics of the NumPy reference
(:mod:`fdisyn.runtime.reference`), which this module reproduces symbolically."""

from __future__ import annotations

import casadi as ca
import numpy as np
from fdisyn.detectors.symbolic import all_finite, all_of, any_of, constant, finite
from fdisyn.runtime.gainfile import SEQUENTIAL_KINDS, GainFile, glr_weights, linear_state_layout, release_level
from fdisyn.synthesis.kinds import STEP_INPUTS, STEP_OUTPUTS

__all__ = ["linear_step_function"]


def linear_step_function(gf: GainFile) -> ca.Function:
    """Symbolic step of a ``kind = "linear"`` gain file (semantics of the reference)."""
    st = gf.step
    lay = linear_state_layout(gf.generators, gf.evaluators)
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
    overflow = ca.SX(0)
    for g, gen in enumerate(gf.generators):
        inputs_ok = ca.logic_and(all_u, all_of(ca.vertcat(*[fin_y[j] for j in gen.outputs_used])))
        sl = lay[f"xi{g}"]
        ready = state[lay["ready"].start + g]
        xi_eq = ca.mtimes(constant(gen.Xu), us) + ca.mtimes(constant(gen.Xy), ys)
        xi = ca.if_else(ready == 0, xi_eq, state[sl.start : sl.stop])
        r_g = ca.mtimes(constant(gen.Cr), xi) + ca.mtimes(constant(gen.Du), us) + ca.mtimes(constant(gen.Dy), ys)
        xi_next = ca.mtimes(constant(gen.Ar), xi) + ca.mtimes(constant(gen.Bu), us) + ca.mtimes(constant(gen.By), ys)
        evs = [j for j, ev in enumerate(gf.evaluators) if ev.generator == g]
        j_g = {j: ca.mtimes([r_g.T, constant(gf.evaluators[j].W), r_g]) for j in evs if gf.evaluators[j].kind not in SEQUENTIAL_KINDS}
        windows = {}
        latched = {}
        for j in evs:
            ev = gf.evaluators[j]
            if ev.kind == "wssr":  # shift q in, sum newest first (the reference's order)
                ws = lay[f"window{j}"]
                windows[j] = ca.vertcat(j_g[j], state[ws.start : ws.stop - 1])
                total = windows[j][0]
                for i in range(1, windows[j].numel()):
                    total = total + windows[j][i]
                j_g[j] = total
            elif ev.kind in SEQUENTIAL_KINDS:
                assert ev.directions is not None
                ws = lay[f"sequential{j}"]
                z = ca.mtimes(constant(ev.directions), r_g)
                old = state[ws.start : ws.stop]
                if ev.kind == "cusum":
                    assert ev.drift is not None
                    drift = constant(np.concatenate([ev.drift, ev.drift]))
                    m2 = 2 * ev.directions.shape[0]
                    sums = ca.fmin(ca.fmax(old[:m2] + ca.vertcat(z, -z) - drift, 0), 2.0 * float(ev.threshold))
                    terms = sums
                    latch = ca.vertcat(
                        *[ca.if_else(ca.logic_or(sums[i] > ev.threshold, ca.logic_and(old[m2 + i] > 0, sums[i] > 0)), 1, 0) for i in range(m2)]
                    )
                    latched[j] = any_of(latch)
                    sums = ca.vertcat(sums, latch)
                else:
                    m = int(ev.window)
                    parts = []
                    for h in range(ev.directions.shape[0] // m):
                        base = h * m
                        parts.append(z[base])
                        for n in range(1, m):
                            parts.append(old[base + n - 1] + z[base + n])
                    sums = ca.vertcat(*parts)
                    weights = glr_weights(ev.information, m)
                    terms = ca.vertcat(*[sums[i] * sums[i] * float(weights[i]) for i in range(sums.numel()) if weights[i] > 0])
                windows[j] = sums
                top = terms[0]
                for i in range(1, terms.numel()):
                    top = ca.fmax(top, terms[i])
                j_g[j] = top
        # a finite but absurd value can overflow: the sample is then skipped like a non-finite one
        results_ok = all_finite(r_g, xi_next, *j_g.values(), *windows.values())
        ok = ca.logic_and(inputs_ok, results_ok)
        overflow = ca.logic_or(overflow, ca.logic_and(inputs_ok, 1 - results_ok))
        nxt[sl.start : sl.stop] = ca.if_else(ok, xi_next, state[sl.start : sl.stop])
        # after an overflow the generator restarts at its next valid sample
        nxt[lay["ready"].start + g] = ca.if_else(ok, 1, ca.if_else(inputs_ok, 0, ready))
        r_parts.append(ca.if_else(ok, r_g, 0))
        for j, window in windows.items():
            ws = lay[("window" if gf.evaluators[j].kind == "wssr" else "sequential") + str(j)]
            nxt[ws.start : ws.stop] = ca.if_else(ok, window, state[ws.start : ws.stop])
        for j in evs:
            jj = ca.if_else(ok, j_g[j], 0)
            c = state[lay["counters"].start + j]
            ev = gf.evaluators[j]
            if ev.kind == "cusum":  # any latched sum
                c_next = ca.if_else(ok, ca.if_else(latched[j], 1, 0), c)
            elif ev.kind == "glr":  # raised above the threshold, held down to the release level
                held = ca.logic_or(jj > ev.threshold, ca.logic_and(c > 0, jj > release_level(ev)))
                c_next = ca.if_else(ok, ca.if_else(held, 1, 0), c)
            else:
                c_next = ca.if_else(ok, ca.if_else(jj > ev.threshold, c + 1, 0), c)
            nxt[lay["counters"].start + j] = c_next
            flags[j] = ca.logic_and(ok, c_next >= persistence)
            j_parts[j] = jj
    r = ca.vertcat(*r_parts)
    bad = ca.logic_or(overflow, 1 - ca.logic_and(all_u, all_of(fin_y)))
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
