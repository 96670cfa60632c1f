"""The Beard detection filter's step in plain NumPy: an independent twin of the CasADi step.

Written from the specification (Beard, MIT thesis, 1971; He, Zhang & Wu, Journal of Astronautics,
c. 1999), sample by sample and without CasADi, so that the symbolic step
(:mod:`fdisyn.synthesis.beard_fdf.step`) and the generated C can be checked against it. The state
vector is the one of :attr:`BeardFilter.layout`.
"""

from __future__ import annotations

import math

import numpy as np
from fdisyn.runtime.reference import RunResult
from fdisyn.synthesis.beard_fdf.payload import BeardFilter

__all__ = ["beard_reference_run"]


def beard_reference_run(flt: BeardFilter, U: np.ndarray, Y: np.ndarray, state: np.ndarray | None = None) -> RunResult:
    """Run ``flt`` over ``U`` (T × m) and ``Y`` (T × p) from ``state`` (default: the initial state).

    Returns ``r`` (T × p), ``J`` (T × (2 + 2k)), ``alarm``, ``isolated``, ``status`` (T each) and the
    state after the last sample.
    """
    m, p, k, N = flt.m, flt.p, flt.k, flt.window
    Y = np.asarray(Y, dtype=float).reshape(-1, p)
    T = Y.shape[0]
    U = np.asarray(U, dtype=float).reshape(T, m)
    lay = flt.layout
    st = lay.unpack(flt.init_state() if state is None else state)
    xhat = np.array(st["xhat"], dtype=float)
    buf = np.array(st["buffer"], dtype=float).reshape(p, N)
    ready, head, count, counter, nonfinite = (float(st[key]) for key in ("ready", "head", "count", "counter", "nonfinite"))  # type: ignore[arg-type]
    n_warm = flt.warmup
    if n_warm:
        gains, correction = flt.warmup_gains
        acc = np.array(st["acc"], dtype=float).reshape(-1)
    if flt.rho is None:
        fixed_x = None
    else:
        fixed_x = math.asin(1.0 / flt.rho)
    half = math.pi / 2
    r_out, J_out = np.zeros((T, p)), np.zeros((T, 2 + 2 * k))
    alarm_out, iso_out, status_out = np.zeros(T, dtype=int), np.full(T, -1, dtype=int), np.zeros(T, dtype=int)

    for t in range(T):
        u, y = U[t], Y[t]
        if not (np.all(np.isfinite(u)) and np.all(np.isfinite(y))):
            nonfinite += 1
            if ready < n_warm:  # a gap in the warm-up: it starts again at the next valid sample
                ready = 0.0
            status_out[t] = 1
            continue
        x = flt.Xu @ u + flt.Xy @ y if ready == 0 else xhat
        eps = y - flt.C @ x - flt.D @ u
        x_next = flt.A @ x + flt.B @ u + flt.L @ eps
        new_acc = None
        with np.errstate(over="ignore", invalid="ignore"):
            if n_warm and ready < n_warm:  # the warm-up: Σ Φ_jᵀ ε_j, and the least-squares correction after its last sample
                new_acc = (np.zeros(flt.n) if ready == 0 else acc) + gains[int(ready)] @ eps
                if ready == n_warm - 1:
                    x_next = x_next + correction @ new_acc
                    new_acc = np.zeros(flt.n)
        live = ready >= n_warm  # the window runs from the sample after the warm-up
        new_buf = buf.copy()
        if live:
            new_buf[:, int(head)] = eps
        new_count = min(count + 1, N) if live else count
        valid = live and new_count >= N
        with np.errstate(over="ignore", invalid="ignore"):
            stats = _statistics(flt, new_buf, fixed_x, half)
        J = stats[0] if valid else np.zeros(2 + 2 * k)
        finite = [eps, x_next, J] + ([new_acc] if new_acc is not None else [])
        if not all(np.all(np.isfinite(v)) for v in finite):
            nonfinite += 1
            ready = 0.0
            status_out[t] = 1
            continue
        J_vals, inside, rho = stats
        exceed = valid and J_vals[0] > flt.h
        counter = min(counter + 1, flt.persistence) if exceed else 0.0
        alarm = valid and counter >= flt.persistence
        iso = -1
        if alarm and sum(inside) == 1 and (flt.rho is None or rho >= flt.rho):
            iso = inside.index(True)
        xhat, buf, count = x_next, new_buf, float(new_count)
        ready = min(ready + 1.0, n_warm + 1.0)
        if new_acc is not None:
            acc = new_acc
        if live:
            head = 0.0 if head + 1 >= N else head + 1
        r_out[t], J_out[t], alarm_out[t], iso_out[t] = eps, J, int(alarm), iso
    blocks = {"xhat": xhat, "ready": ready, "buffer": buf, "head": head, "count": count, "counter": counter, "nonfinite": nonfinite}
    if n_warm:
        blocks["acc"] = acc
    final = lay.pack(blocks)
    return RunResult(r=r_out, J=J_out, alarm=alarm_out, isolated=iso_out, status=status_out, state=final)


def _statistics(flt: BeardFilter, buf: np.ndarray, fixed_x: float | None, half: float) -> tuple[np.ndarray, list[bool], float]:
    """``J = [s, ρ, α…, I…]`` of a full window, whether the mean lies in each cone, and ``ρ``."""
    N = buf.shape[1]
    s = math.sqrt(float(np.sum(buf * buf)) / N)
    mean = buf.sum(axis=1) / N
    rho = math.sqrt(float(mean @ mean)) / flt.explicit_level
    if fixed_x is not None:
        X = fixed_x
    elif rho > 1.0:
        X = math.asin(1.0 / rho)
    else:
        X = half  # ε̄ may explain the whole mean: any direction
    angles, cones = [], []
    for U, y_th in zip(flt.axes, flt.Y_th, strict=True):
        coeff = U.T @ mean
        along = math.sqrt(float(coeff @ coeff))
        rest = mean - U @ coeff
        off = math.sqrt(float(rest @ rest))
        angles.append(math.atan2(off, along) if (along > 0 or off > 0) else half)
        cones.append(min(half, X + float(y_th)))
    inside = [a <= c for a, c in zip(angles, cones, strict=True)]
    return np.array([s, rho, *angles, *cones]), inside, rho
