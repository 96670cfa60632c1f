"""The step of a ``kind = "linear"`` gain file as one CasADi ``Function``: the generators, their statistics, the
persistence counters and the decision table, with the semantics of the NumPy reference
(:mod:`fdisyn.runtime.reference`), which this module reproduces symbolically."""

from __future__ import annotations

import functools
from typing import Any

import casadi as ca
import numpy as np
from fdisyn.detectors.symbolic import all_finite, all_of, constant, finite
from fdisyn.detectors.table import DETECTORS
from fdisyn.runtime.gainfile import GainFile
from fdisyn.runtime.layout import StateLayout, linear_state_layout
from fdisyn.runtime.warmup import generator_warmup
from fdisyn.synthesis.kinds import STEP_INPUTS, STEP_OUTPUTS

__all__ = ["linear_step_function"]


TABLE_INSTRUCTIONS = 15_000
"""Largest step (CasADi SX instructions) written as straight-line code; a larger one is written as loops over
constant tables (:func:`_table_step`). The bound is the compiled Monte Carlo's
(:data:`fdisyn.codegen.lanes.MAX_INSTRUCTIONS`): up to it the step runs eight runs at a time in vector
registers, which a table step does not; beyond it straight-line code only costs compile time (the turbofan's
grouped bank, 149 441 instructions: 68 s and 2.4 GB of gcc on 2 cores) where its tables compile in seconds."""


def linear_step_function(gf: GainFile, *, tables: bool | None = None) -> ca.Function:
    """Symbolic step of a ``kind = "linear"`` gain file (semantics of the reference).

    Parameters
    ----------
    gf : GainFile
        A ``linear`` gain file.
    tables : bool, optional
        Write the step as loops over constant tables (an MX function, :func:`_table_step`) rather than as one
        multiply-add per coefficient (an SX function, :func:`_scalar_step`). Default: tables when the scalar
        step would have more than :data:`TABLE_INSTRUCTIONS` instructions. Both give the same values bit for
        bit: each product adds its terms in the same order.

    Returns
    -------
    casadi.Function
        The step (contract of :mod:`fdisyn.synthesis.kinds`).
    """
    if tables is None:
        scalar = _scalar_step(gf) if _scalar_estimate(gf) <= 4 * TABLE_INSTRUCTIONS else None
        if scalar is not None and scalar.n_instructions() <= TABLE_INSTRUCTIONS:
            return scalar
        tables = True
    return _table_step(gf) if tables else _scalar_step(gf)


def _scalar_estimate(gf: GainFile) -> int:
    """A lower bound on the scalar step's instructions (one per stored coefficient and warm-up constant), which
    spares building the scalar step of a diagnoser far beyond :data:`TABLE_INSTRUCTIONS`."""
    from fdisyn.runtime.validate import step_coefficients
    from fdisyn.runtime.warmup import warmup_coefficients

    warm = sum(warmup_coefficients(int(g.warmup), g.n_state, g.n_residual) for g in gf.generators)
    return step_coefficients(gf.generators, gf.evaluators) + warm


def _scalar_step(gf: GainFile) -> ca.Function:
    """The step as one SX function: every product one multiply-add per coefficient."""
    return _step(gf, ca.SX)


def _table_step(gf: GainFile) -> ca.Function:
    """The step as one MX function: every product with a constant matrix a loop over a ``static const`` table
    (CasADi's ``casadi_mtimes_dense``), a warm-up's gains one table read at the sample's index, every
    elementwise operation on a vector one loop, so the C grows with the operations of the step and not with
    its coefficients. Every product adds its terms column by column from the first, as the scalar step's
    does, and an unused warm-up gain contributes nothing (the scalar step adds exact zeros), so both give the
    same values (checked on every reference problem's diagnosers). The equilibrium, the warm-up gain's product
    and the warm-up's correction run only on the samples that use them (:func:`_only_if`)."""
    return _step(gf, ca.MX)


def _product(m: np.ndarray, x: Any) -> Any:
    """``m x`` for a constant ``m``: its nonzeros unrolled (SX), or a dense table in a loop (MX)."""
    if isinstance(x, ca.SX):
        return ca.mtimes(constant(m), x)
    m = np.asarray(m, dtype=float)
    return ca.mtimes(ca.DM(m), x) if np.any(m) else ca.MX.zeros(m.shape[0], x.shape[1])


def _only_if(cond: Any, fn: Any, *args: Any) -> Any:
    """``fn(*args)`` where ``cond`` holds, else zeros of its shape; in MX ``fn`` runs only then (a switch in the C on
    ``args`` alone): the equilibrium, a warm-up gain's product and the warm-up's correction are needed on a few
    samples of a run, yet are a quarter of a large bank's products. ``fn`` takes its constant matrices as
    arguments (``args`` holds them as constants), so one switch serves every generator of the same shapes and the C
    has one copy of it, its constants passed by pointer (:func:`_switch`). The value is the same arithmetic either
    way."""
    if not isinstance(args[-1], ca.MX):
        return ca.if_else(cond, fn(*args), 0)
    return _switch(fn, tuple(a.shape for a in args))(cond, *args)


@functools.lru_cache(maxsize=None)
def _switch(fn: Any, shapes: tuple[tuple[int, int], ...]) -> ca.Function:
    """The one switch ``cond ? fn(*args) : 0`` for arguments of ``shapes`` (cached: the same ``Function`` object
    is one function in the C, however many generators call it)."""
    syms = [ca.MX.sym(f"a{i}", *shape) for i, shape in enumerate(shapes)]
    taken = ca.Function(f"{fn.__name__.strip('_')}", syms, [fn(*syms)])
    none = ca.Function("zeros", syms, [ca.MX.zeros(taken.size_out(0))])
    return ca.Function.if_else(f"only_if_{fn.__name__.strip('_')}", taken, none)


def _affine(*pairs: Any) -> Any:
    """``M₁ x₁ + M₂ x₂ + …`` for ``pairs = (M₁, x₁, M₂, x₂, …)``, the products added in that order."""
    out = ca.mtimes(pairs[0], pairs[1])
    for k in range(2, len(pairs), 2):
        out = out + ca.mtimes(pairs[k], pairs[k + 1])
    return out


def _lazy_affine(cond: Any, terms: list[tuple[np.ndarray, Any]]) -> Any:
    """``Σ M x`` over ``terms`` (constant ``M``, symbolic ``x``) where ``cond`` holds, else zeros: in SX the products'
    nonzeros unrolled, in MX one shared switch (:func:`_only_if`) over the nonzero ``M`` only (as
    :func:`_product` skips a zero matrix)."""
    if not isinstance(terms[0][1], ca.MX):
        return ca.if_else(cond, sum((_product(m, x) for m, x in terms[1:]), _product(*terms[0])), 0)
    live = [(np.asarray(m, dtype=float), x) for m, x in terms if np.any(m)]
    if not live:
        return ca.MX.zeros(np.shape(terms[0][0])[0], 1)
    return _only_if(cond, _affine, *[a for m, x in live for a in (ca.MX(ca.DM(m)), x)])


def _warm_product(table: Any, k: Any, r: Any) -> Any:
    """``gains[k] r`` for the warm-up gains ``table``, column ``k`` the ``k``-th gain column-major."""
    nr = r.shape[0]
    ns = table.shape[0] // nr
    return ca.mtimes(ca.reshape(table[k * (ns * nr) + ca.DM(np.arange(ns * nr, dtype=float))], ns, nr), r)


def _warm_gain(gains: np.ndarray, ready: Any, r_g: Any, acc: Any) -> Any:
    """``acc + gains[ready] r`` while ``ready`` is below the warm-up's length, else ``acc``."""
    n_warm, ns, nr = gains.shape
    if isinstance(r_g, ca.SX):  # a sum of exact one-hot terms
        for k in range(n_warm):
            acc = acc + ca.if_else(ready == k, ca.mtimes(constant(gains[k]), r_g), ca.SX.zeros(ns))
        return acc
    # gains[k] column-major in column k: the sample's gain is one read of ns·nr entries at k·ns·nr
    table = ca.MX(ca.DM(np.transpose(gains, (0, 2, 1)).reshape(n_warm, ns * nr).T))
    k = ca.fmin(ca.fmax(ready, 0), n_warm - 1)
    return acc + _only_if(ready < n_warm, _warm_product, table, k, r_g)


def _step(gf: GainFile, sym: Any) -> ca.Function:
    """The step in the symbolic type ``sym`` (``casadi.SX`` or ``casadi.MX``)."""
    st = gf.step
    lay = linear_state_layout(gf.generators, gf.evaluators, gf.decision)
    state = sym.sym("state", st.nstate)
    u = sym.sym("u", st.nu)
    y = sym.sym("y", st.ny)
    fin_u, fin_y = finite(u), finite(y)
    us, ys = ca.if_else(fin_u, u, 0), ca.if_else(fin_y, y, 0)
    nxt = sym(state)
    parts = []
    for g, gen in enumerate(gf.generators):
        ready = state[lay["ready"].start + g]
        sl = lay[f"xi{g}"]
        if sym is ca.MX:
            xi_eq = _lazy_affine(ready == 0, [(gen.Xu, us), (gen.Xy, ys)])
        else:
            xi_eq = _product(gen.Xu, us) + _product(gen.Xy, ys)
        xi = ca.if_else(ready == 0, xi_eq, state[sl.start : sl.stop])
        r_g = _product(gen.Cr, xi) + _product(gen.Du, us) + _product(gen.Dy, ys)
        xi_next = _product(gen.Ar, xi) + _product(gen.Bu, us) + _product(gen.By, ys)
        warm = generator_warmup(gf, g)
        acc_new = None
        if warm is not None:  # the warm-up: accumulate, correct after the last sample, hold the statistics till then
            gains, correction = warm
            acc_sl = lay[f"acc{g}"]
            acc_new = ca.if_else(ready == 0, sym.zeros(gen.n_state), state[acc_sl.start : acc_sl.stop])
            acc_new = _warm_gain(gains, ready, r_g, acc_new)
            xi_next = xi_next + _lazy_affine(ready == gen.warmup - 1, [(correction, acc_new)])
        parts.append((r_g, all_finite(xi_next, *([] if acc_new is None else [acc_new])), xi_next, acc_new))
    (r, j, alarm, bad), oks, lives, naming = _decision(gf, lay, state, fin_u, fin_y, [(r, fin) for r, fin, _, _ in parts], nxt)
    isolated = _isolated(gf, lay, state, nxt, alarm, *naming)
    for g, (_, _, xi_next, acc_new) in enumerate(parts):
        _advance_generator(gf, lay, g, state, nxt, xi_next, acc_new, oks[g], lives[g])
    return ca.Function("step", [state, u, y], [nxt, r, j, alarm, isolated, bad], list(STEP_INPUTS), list(STEP_OUTPUTS))


def _isolated(gf: GainFile, lay: StateLayout, state: Any, nxt: Any, alarm: Any, r_live: Any, pattern: Any, ran: Any) -> Any:
    """The class the step names: the signature the alarms match, or the hypothesis test's held class."""
    assert gf.decision is not None
    if gf.decision.isolation is None:
        return pattern
    return _held_class(gf, lay, state, nxt, r_live, alarm, pattern, ran)


def _advance_generator(gf: GainFile, lay: StateLayout, g: int, state: Any, nxt: Any, xi_next: Any, acc_new: Any, ok: Any, live: Any) -> None:
    """Write generator ``g``'s state and warm-up accumulator into ``nxt``: kept when its sample was skipped
    (``ok`` 0), the accumulator emptied after the warm-up's last sample."""
    sl = lay[f"xi{g}"]
    nxt[sl.start : sl.stop] = ca.if_else(ok, xi_next, state[sl.start : sl.stop])
    if acc_new is not None:
        n_warm = gf.generators[g].warmup
        ready = state[lay["ready"].start + g]
        acc_sl = lay[f"acc{g}"]
        zeros = (ca.SX if isinstance(acc_new, ca.SX) else ca.MX).zeros(acc_new.shape[0])
        emptied = ca.if_else(ready == n_warm - 1, zeros, acc_new)  # used: the accumulator is emptied
        nxt[acc_sl.start : acc_sl.stop] = ca.if_else(ca.logic_and(ok, 1 - live), emptied, state[acc_sl.start : acc_sl.stop])


def _decision(
    gf: GainFile, lay: StateLayout, state: Any, fin_u: Any, fin_y: Any, gens: list[tuple[Any, Any]], nxt: Any
) -> tuple[list[Any], list[Any], list[Any], tuple[Any, Any, Any]]:
    """The statistics, counters and alarm of the step, from the inputs' and outputs' finiteness flags and each
    generator's residual and the finiteness of its next state and accumulator (``gens``); writes every state
    entry but the generators', the accumulators' and the isolation test's into ``nxt``. Returns ``r, J, alarm, bad`` (outputs of the step);
    per generator whether its sample was used (``ok``) and whether its statistics run (``live``, past the
    warm-up); and what the class is named from: the residuals whose statistics ran, the class whose signature
    the alarms match (−1: none) and whether any statistic ran (:func:`_isolated`)."""
    sym: Any = ca.SX if isinstance(state, ca.SX) else ca.MX
    all_u = all_of(fin_u)
    assert gf.decision is not None
    persistence = float(gf.decision.persistence)
    r_parts, j_parts, flags = [], [sym(0)] * len(gf.evaluators), [sym(0)] * len(gf.evaluators)
    live_parts = []  # the residuals of the generators whose statistics ran: the isolation evidence's input
    oks, lives = [], []
    ran = sym(0)  # some generator's statistics ran
    overflow = sym(0)
    for g, gen in enumerate(gf.generators):
        r_g, gen_finite = gens[g]
        inputs_ok = ca.logic_and(all_u, all_of(fin_y[[int(j) for j in gen.outputs_used]]))
        ready = state[lay["ready"].start + g]
        n_warm = gen.warmup
        warm = bool(n_warm)  # generator_warmup gives its constants exactly then
        live = ready >= n_warm if warm else sym(1)  # the statistics run (after the warm-up)
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
        results_ok = ca.logic_and(all_finite(r_g, *j_g.values(), *windows.values()), gen_finite)
        ok = ca.logic_and(inputs_ok, results_ok)
        overflow = ca.logic_or(overflow, ca.logic_and(inputs_ok, 1 - results_ok))
        # after an overflow the generator restarts at its next valid sample
        if not warm:
            nxt[lay["ready"].start + g] = ca.if_else(ok, 1, ca.if_else(inputs_ok, 0, ready))
        else:  # its valid samples counted to warmup + 1; a gap in the warm-up restarts it
            held = ca.if_else(ready < n_warm, 0, ready)
            nxt[lay["ready"].start + g] = ca.if_else(ok, ca.fmin(ready + 1, n_warm + 1), ca.if_else(inputs_ok, 0, held))
        running = ok if not warm else ca.logic_and(ok, live)
        oks.append(ok)
        lives.append(live)
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
    alarm = sym(0)
    for fl in flags:
        alarm = ca.logic_or(alarm, fl)
    pattern = sym(-1)  # the class whose signature equals the flag pattern (rows are distinct: at most one)
    for f, row in enumerate(np.asarray(gf.decision.signatures, dtype=int)):
        match = sym(1)
        for j, s in enumerate(row):
            match = match * (flags[j] if s else 1 - flags[j])
        pattern = pattern + (f + 1) * match
    return [r, ca.vertcat(*j_parts), alarm, bad], oks, lives, (ca.vertcat(*live_parts), pattern, ran)


def _held_class(
    gf: GainFile, lay: StateLayout, state: Any, nxt: Any, r_live: Any, alarm: Any, pattern: Any, ran: Any
) -> Any:
    """The decision's hypothesis test and held class (:func:`fdisyn.runtime.reference.isolation_test`,
    :func:`~fdisyn.runtime.reference.held_class`), writing the evidence and the named class into ``nxt``; a sample
    on which no statistic ran (``ran`` 0) leaves them as they were and names nothing. Written in the symbolic type of ``state`` (SX in the
    scalar step, MX in the table step, where its products are loops over the test's constant tables)."""
    sym: Any = ca.SX if isinstance(state, ca.SX) else ca.MX
    assert gf.decision is not None and gf.decision.isolation is not None
    iso = gf.decision.isolation
    ev = lay["evidence"]
    s = float(iso.forgetting) * state[ev.start : ev.stop] + ca.mtimes(constant(np.asarray(iso.basis, dtype=float)), r_live)
    s = ca.if_else(all_finite(s), s, sym.zeros(s.shape[0]))  # an overflow: the evidence starts again
    nxt[ev.start : ev.stop] = ca.if_else(ran, s, state[ev.start : ev.stop])
    q = ca.sumsqr(s)
    directions = np.asarray(iso.directions, dtype=float)
    proj = ca.mtimes(constant(directions), s) if directions.size else sym.zeros(0)
    ranks = [int(k) for k in np.asarray(iso.ranks)]
    nested = np.asarray(iso.nested, dtype=int)
    plausible, supported, row = [], [], 0
    for f, k in enumerate(ranks):
        g = ca.sumsqr(proj[row : row + k]) if k else sym(0)
        row += k
        ok = q - g <= float(iso.reject[f])
        plausible.append(ok)
        supported.append(ca.logic_and(ok, g >= float(iso.accept[f])))
    candidate = sym(-1)
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
