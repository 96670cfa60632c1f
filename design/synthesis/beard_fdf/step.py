"""The Beard detection filter's step as one CasADi ``Function`` (the step contract of :mod:`fdisyn.synthesis.kinds`).

Per valid sample (Beard, MIT thesis, 1971; He, Zhang & Wu, Journal of Astronautics, c. 1999)::

    x̂      = x̂(k), or the equilibrium Xu u + Xy y at the first valid sample (ready = 0)
    ε       = y − C x̂ − D u                                 r
    x̂(k+1) = A x̂ + B u + L ε   (− (A−LC)^W (Σ Φ_jᵀΦ_j)⁺ Σ Φ_jᵀ ε_j after the W-th sample of a warm-up)
    s       = sqrt((1/N) Σ_{j<N} ‖ε(k−j)‖²)                 the window RMS: the magnitude statistic
    m       = (1/N) Σ_{j<N} ε(k−j)                          the window mean: the direction
    ρ       = ‖m‖ / ε̄,   X = asin(min(1, 1/ρ))  (asin(1/rho) with a fixed rho)
    α_i     = atan2(‖(I − P_i) m‖, ‖P_i m‖)  (π/2 when m = 0),   I_i = min(π/2, X + Y_th,i)

With a warm-up of ``W`` samples (:mod:`fdisyn.runtime.warmup`, ``Φ_j = −C (A − L C)^j``) the window is written
from the sample after it. ``J = [s, ρ, α_1..α_k, I_1..I_k]`` once the window is full (``W + N`` samples since
the start), zeros before.
``alarm``: ``s > h`` for ``persistence`` consecutive samples; ``isolated``: the one cone ``α_i ≤ I_i`` the
window mean lies in (with a fixed ``rho`` also ``ρ ≥ rho``), −1 when none or several. A sample with a
non-finite ``u`` or ``y`` keeps the state (``nonfinite`` counts it), status 1, outputs zero (inside the warm-up
it restarts the warm-up); a finite sample whose results overflow does the same and restarts the filter at its
next valid sample.
The NumPy twin is :func:`fdisyn.synthesis.beard_fdf.reference.beard_reference_run`.
"""

from __future__ import annotations

import math

import casadi as ca
from fdisyn.detectors.symbolic import all_finite, constant, finite, persistence_count
from fdisyn.synthesis.kinds import STEP_INPUTS, STEP_OUTPUTS
from fdisyn.runtime.gainfile import GainFile
from fdisyn.synthesis.beard_fdf.payload import BeardFilter, beard_from_gain_file

__all__ = ["beard_step", "beard_step_function"]


def beard_step_function(gf: GainFile) -> ca.Function:
    """The step of a ``kind = "beard_fdf"`` gain file (validated first: :func:`beard_from_gain_file`)."""
    return beard_step(beard_from_gain_file(gf))


def _norm(v: ca.SX) -> ca.SX:
    """``sqrt(Σ v_i²)``: 0 (never NaN) for a zero vector, a 0-entry one included."""
    return ca.sqrt(ca.sumsqr(v)) if v.numel() else ca.SX(0)


def beard_step(flt: BeardFilter) -> ca.Function:
    """The CasADi step of ``flt`` (module docstring)."""
    p, k, N = flt.p, flt.k, flt.window
    lay = flt.layout
    state = ca.SX.sym("state", lay.size)
    u = ca.SX.sym("u", flt.m)
    y = ca.SX.sym("y", p)
    old = {name: ca.reshape(state[s.start : s.stop], r, c) for (name, r, c), s in ((e, lay[e[0]]) for e in lay.entries)}
    ok_in = all_finite(u, y)
    us = ca.if_else(finite(u), u, 0) if flt.m else u
    ys = ca.if_else(finite(y), y, 0)

    # ---- the filter
    ready = old["ready"]
    x_eq = ca.mtimes(constant(flt.Xu), us) + ca.mtimes(constant(flt.Xy), ys)
    x = ca.if_else(ready == 0, x_eq, old["xhat"])
    eps = ys - ca.mtimes(constant(flt.C), x) - ca.mtimes(constant(flt.D), us)
    x_next = ca.mtimes(constant(flt.A), x) + ca.mtimes(constant(flt.B), us) + ca.mtimes(constant(flt.L), eps)
    n_warm = flt.warmup
    if n_warm:  # the warm-up: the least-squares initial error over its samples, removed after the last
        gains, correction = flt.warmup_gains
        acc = ca.if_else(ready == 0, ca.SX.zeros(flt.n), old["acc"])
        for j in range(n_warm):
            acc = acc + ca.if_else(ready == j, ca.mtimes(constant(gains[j]), eps), ca.SX.zeros(flt.n))
        last = ready == n_warm - 1
        x_next = x_next + ca.if_else(last, ca.mtimes(constant(correction), acc), ca.SX.zeros(flt.n))
        acc_next = ca.if_else(last, ca.SX.zeros(flt.n), acc)  # used: the accumulator is emptied
    live = ready >= n_warm

    # ---- the window: ε written at column head of the ring, from the sample after the warm-up
    head, count = old["head"], old["count"]
    buf = old["buffer"]
    buf_next = ca.horzcat(*[ca.if_else(ca.logic_and(live, head == j), eps, buf[:, j]) for j in range(N)])
    head_next = ca.if_else(live, ca.if_else(head + 1 >= N, 0, head + 1), head)
    count_next = ca.if_else(live, ca.fmin(count + 1, N), count)
    valid = ca.logic_and(live, count_next >= N)
    s = ca.sqrt(ca.sumsqr(buf_next) / N)
    mean = ca.sum2(buf_next) / N
    norm_m = _norm(mean)
    rho = norm_m / flt.explicit_level
    X = ca.SX(math.asin(1.0 / flt.rho)) if flt.rho is not None else ca.asin(1.0 / ca.fmax(rho, 1.0))
    angles, cones = [], []
    for U, y_th in zip(flt.axes, flt.Y_th, strict=True):
        coeff = ca.mtimes(constant(U.T), mean)
        along = _norm(coeff)
        off = _norm(mean - ca.mtimes(constant(U), coeff))
        angles.append(ca.if_else(ca.logic_or(along > 0, off > 0), ca.atan2(off, along), math.pi / 2))
        cones.append(ca.fmin(math.pi / 2, X + float(y_th)))
    J_raw = ca.vertcat(s, rho, *angles, *cones)
    J_proc = ca.if_else(valid, J_raw, ca.SX.zeros(2 + 2 * k, 1))

    # ---- the decision
    exceed = ca.logic_and(valid, s > flt.h)
    counter_next = persistence_count(exceed, old["counter"], cap=flt.persistence)
    alarm = ca.logic_and(valid, counter_next >= flt.persistence)
    inside = [a <= c for a, c in zip(angles, cones, strict=True)]
    n_inside = sum(inside[1:], inside[0])
    which = sum((i * f for i, f in enumerate(inside) if i), ca.SX(0))
    decide = ca.logic_and(alarm, n_inside == 1)
    if flt.rho is not None:
        decide = ca.logic_and(decide, rho >= flt.rho)
    isolated = ca.if_else(decide, which, -1)

    # ---- a skipped sample: non-finite input, or finite input whose results overflow
    ok = ca.logic_and(ok_in, all_finite(eps, x_next, J_proc, *((acc_next,) if n_warm else ())))
    overflow = ca.logic_and(ok_in, ca.logic_not(ok))
    new = dict(old)
    new.update(xhat=x_next, ready=ca.fmin(ready + 1, n_warm + 1), buffer=buf_next, head=head_next, count=count_next,
               counter=counter_next)
    if n_warm:
        new.update(acc=acc_next)
    held = dict(old)  # a gap in the warm-up restarts it at the next valid sample
    held.update(ready=ca.if_else(ca.logic_or(overflow, ready < n_warm), 0, ready), nonfinite=old["nonfinite"] + 1)
    join = lambda blocks: ca.vertcat(*[ca.vec(ca.SX(blocks[name])) for name, _, _ in lay.entries])  # noqa: E731
    state_next = ca.if_else(ok, join(new), join(held))
    return ca.Function(
        "step",
        [state, u, y],
        [
            state_next,
            ca.if_else(ok, eps, ca.SX.zeros(p, 1)),
            ca.if_else(ok, J_proc, ca.SX.zeros(2 + 2 * k, 1)),
            ca.if_else(ok, alarm, 0),
            ca.if_else(ok, isolated, -1),
            ca.if_else(ok, 0, 1),
        ],
        list(STEP_INPUTS),
        list(STEP_OUTPUTS),
    )
