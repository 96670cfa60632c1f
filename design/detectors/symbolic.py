"""The symbolic vocabulary every generated step is written in (CasADi ``SX``), and the one symbolic
implementation of each detector's per-sample update and alarm rule.

Finiteness is tested as ``|v| < ∞`` with ``if_else``, which survives code generation (``v != v`` may be
folded away).

Every step that offers a detector calls the function of this module for it (the linear step of
:mod:`fdisyn.synthesis.linear_step`; the NAFDF's fast detection, its innovation windows and its counters in
:mod:`fdisyn.synthesis.nafdf.step`; the Beard filter's persistence in
:mod:`fdisyn.synthesis.beard_fdf.step`); where two steps differ (the NAFDF's WSSR is a mean over the
samples seen, its CUSUM is tuned to a shift, its sums restart when an alarm is dismissed) the difference
is an argument or the caller's choice, never a second implementation. Each function adds, clamps and
compares in the order of the NumPy reference (:mod:`fdisyn.runtime.reference`), the independent oracle
these updates are tested against (a window summed newest first, a CUSUM's increment before its drift,
a GLR's ``d·d·w``); matrix products are CasADi's, which may add their terms in another order than
NumPy's (round-off only). A linear diagnoser's statistic of a given kind is its detector's
:attr:`~fdisyn.detectors.table.Detector.statistic` (a :class:`LinearStatistic` its module registers in
:data:`~fdisyn.detectors.table.DETECTORS`), so that its step names no detector.

==========  ========================================================================================
detector    per-sample update
==========  ========================================================================================
χ²          :func:`chi2`: ``q = rᵀ W r``
WSSR        :func:`wssr_update`: ``q`` shifted into the window (newest first, :func:`shift_in`), ``J``
            its sum (:func:`window_sum`; or, with a fill count, its mean over the samples seen);
            :func:`wssr_held`, :func:`wssr_threshold`
CUSUM       :func:`cusum_update`: Page's two-sided sums clamped to ``[0, 2h]``; :func:`cusum_latch`
GLR         :func:`glr_update`: the onset sums ``d_i(n)``; :func:`glr_statistic`: ``max d² w``;
            :func:`glr_hold`
counters    :func:`persistence_count`: consecutive samples above the threshold
==========  ========================================================================================
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca
import numpy as np
from fdisyn.runtime.gainfile import Evaluator

__all__ = [
    "finite",
    "all_finite",
    "any_of",
    "all_of",
    "constant",
    "largest",
    "window_sum",
    "shift_in",
    "chi2",
    "wssr_update",
    "wssr_held",
    "wssr_threshold",
    "cusum_update",
    "cusum_latch",
    "glr_update",
    "glr_statistic",
    "glr_hold",
    "persistence_count",
    "Evaluated",
    "LinearStatistic",
    "above_threshold",
]


def finite(v: ca.SX) -> ca.SX:
    """Elementwise 1 where ``v`` is finite (``|v| < ∞``; false for NaN and ±∞).

    The one finiteness test of every generated step (linear and NAFDF): written
    with a comparison, which code generation keeps, where ``v != v`` may be
    folded away.

    Parameters
    ----------
    v : casadi.SX
        Any expression.

    Returns
    -------
    casadi.SX
        0 or 1 per entry, the shape of ``v``.
    """
    return ca.fabs(v) < ca.inf


def all_finite(*exprs: ca.SX) -> ca.SX:
    """1 if every entry of every expression is finite (:func:`finite`), else 0.

    Parameters
    ----------
    *exprs : casadi.SX
        Expressions of any shapes, tested in the order given.

    Returns
    -------
    casadi.SX
        A scalar 0 or 1.
    """
    if any(isinstance(e, ca.MX) for e in exprs):
        return all_of(finite(ca.vertcat(*[ca.vec(e) for e in exprs])))
    return all_of(finite(ca.vertcat(*[ca.vec(ca.SX(e)) for e in exprs])))


def any_of(flags: ca.SX) -> ca.SX:
    """1 if any entry of ``flags`` is nonzero (a chain of ``||`` from the first entry), else 0.

    Parameters
    ----------
    flags : casadi.SX
        The flags (column-major order).

    Returns
    -------
    casadi.SX
        A scalar 0 or 1.
    """
    if isinstance(flags, ca.MX):  # one loop over the entries: the largest 0/1 flag
        return ca.mmax(flags != 0) if flags.numel() else ca.MX(0)
    out = ca.SX(0)
    for i in range(flags.numel()):
        out = ca.logic_or(out, flags[i])
    return out


def all_of(flags: ca.SX) -> ca.SX:
    """1 if every entry of ``flags`` is nonzero (a chain of ``&&`` from the first entry), else 0.

    Parameters
    ----------
    flags : casadi.SX
        The flags (column-major order).

    Returns
    -------
    casadi.SX
        A scalar 0 or 1.
    """
    if isinstance(flags, ca.MX):  # one loop over the entries: the smallest 0/1 flag
        return ca.mmin(flags != 0) if flags.numel() else ca.MX(1)
    out = ca.SX(1)
    for i in range(flags.numel()):
        out = ca.logic_and(out, flags[i])
    return out


def constant(a: np.ndarray) -> ca.DM:
    """``a`` as a CasADi constant with its exact zeros dropped (smaller C, and ``x + 0·y == x`` exactly for
    finite ``y``).

    Parameters
    ----------
    a : numpy.ndarray
        A real matrix or vector.

    Returns
    -------
    casadi.DM
        The sparse constant.
    """
    return ca.sparsify(ca.DM(np.asarray(a, dtype=float)))


def largest(v: ca.SX) -> ca.SX:
    """The largest entry of ``v`` (column-major order), ``fmax`` folded from the first entry.

    Parameters
    ----------
    v : casadi.SX
        At least one entry.

    Returns
    -------
    casadi.SX
        A scalar.
    """
    if isinstance(v, ca.MX):  # a loop from −∞: the same largest entry (NaN entries are passed over by fmax alike)
        return ca.mmax(v)
    top = v[0]
    for i in range(1, v.numel()):
        top = ca.fmax(top, v[i])
    return top


def window_sum(v: ca.SX) -> ca.SX:
    """The sum of ``v``'s entries added in order, first (the newest sample of a window) first.

    Parameters
    ----------
    v : casadi.SX
        At least one entry.

    Returns
    -------
    casadi.SX
        A scalar.
    """
    if isinstance(v, ca.MX):  # one loop, first entry first (0 + v₀ + v₁ + …: the same sums)
        return ca.sum1(v)
    total = v[0]
    for i in range(1, v.numel()):
        total = total + v[i]
    return total


def shift_in(q: ca.SX, window: ca.SX) -> ca.SX:
    """The window (a column, newest first) with ``q`` shifted in at the top and its oldest entry dropped.

    Parameters
    ----------
    q : casadi.SX
        The newest value, a scalar.
    window : casadi.SX
        The window before it, a column of ``N ≥ 1`` entries.

    Returns
    -------
    casadi.SX
        The new window, ``N`` entries.
    """
    n = window.numel()
    if n <= 1:
        return q if isinstance(q, ca.MX) else ca.SX(q)
    return ca.vertcat(q, window[: n - 1])


# --------------------------------------------------------------------------- χ²


def chi2(r: ca.SX, W: np.ndarray) -> ca.SX:
    """The χ² statistic ``q = rᵀ W r`` of a residual ``r`` with the constant weight ``W``.

    Parameters
    ----------
    r : casadi.SX
        The residual, a column.
    W : numpy.ndarray
        The weight (``Σ_r⁺`` on the kept directions, :func:`fdisyn.detectors.chi2.chi2_evaluator`).

    Returns
    -------
    casadi.SX
        ``q``, a scalar.
    """
    return ca.mtimes([r.T, constant(W), r])


# --------------------------------------------------------------------------- WSSR


def wssr_update(q: ca.SX, window: ca.SX, count: ca.SX | None = None) -> tuple[ca.SX, ca.SX, ca.SX | None]:
    """One sample of a WSSR statistic: ``q`` shifted into the window, newest first, the oldest dropped.

    Parameters
    ----------
    q : casadi.SX
        This sample's χ² value (:func:`chi2`, or the NAFDF's normalised innovation square).
    window : casadi.SX
        The last ``N`` values, newest first; zeros for samples not seen yet.
    count : casadi.SX, optional
        The number of samples in the window. Without it (a linear diagnoser) ``J`` is the window's sum;
        with it (the NAFDF's ``L(t)``, Zhou, Xi & Zhang, c. 1991, eq. (2.4)) it is the sum over the
        samples seen, ``min(count + 1, N)``.

    Returns
    -------
    J : casadi.SX
        The statistic: the sum added newest first (:func:`window_sum`), or that sum over the new count.
    window : casadi.SX
        The new window.
    count : casadi.SX or None
        The new count, ``None`` without one.
    """
    shifted = shift_in(q, window)
    if count is None:
        return window_sum(shifted), shifted, None
    filled = ca.fmin(count + 1, window.numel())
    return window_sum(shifted) / filled, shifted, filled


def wssr_held(window: ca.SX, count: ca.SX) -> tuple[ca.SX, ca.SX]:
    """The mean WSSR statistic of a window left as it is (a skipped sample): the sum over ``max(count, 1)``.

    Parameters
    ----------
    window : casadi.SX
        The window, newest first.
    count : casadi.SX
        The number of samples in it (0 before the first).

    Returns
    -------
    J : casadi.SX
        The statistic.
    count : casadi.SX
        The count it is taken over, ``max(count, 1)`` (for :func:`wssr_threshold`).
    """
    held = ca.fmax(count, 1)
    return window_sum(window) / held, held


def wssr_threshold(count: ca.SX, table: np.ndarray) -> ca.SX:
    """``table[count − 1]`` for a whole-number ``count`` in ``1..len(table)``: the threshold of a WSSR mean
    over ``count`` samples (:func:`fdisyn.detectors.wssr.wssr_threshold_table`), a sum of exact one-hot terms.

    Parameters
    ----------
    count : casadi.SX
        The number of samples in the window.
    table : numpy.ndarray
        The threshold for each count.

    Returns
    -------
    casadi.SX
        The threshold.
    """
    out = ca.SX(0)
    for i, val in enumerate(table):
        out = out + ca.if_else(count == i + 1, ca.SX(float(val)), ca.SX(0.0))
    return out


# --------------------------------------------------------------------------- CUSUM


def cusum_update(
    z: ca.SX, sums: ca.SX, drift: np.ndarray | float, threshold: float, *, shift: float | None = None
) -> tuple[ca.SX, ca.SX]:
    """One sample of Page's two-sided CUSUM: ``S⁺ ← S⁺ + z − drift`` and ``S⁻ ← S⁻ − z − drift``, each
    clamped to ``[0, 2·threshold]``; ``J`` the largest sum. Tuned to a shift ``δ`` of a unit-variance ``z``
    the increments are ``δ (±z) − δ²/2``.

    Parameters
    ----------
    z : casadi.SX
        The projected residual, one entry per tested direction (a linear diagnoser's directions are
        already scaled to its designed fault).
    sums : casadi.SX
        The sums ``S⁺`` then ``S⁻`` (``2 m`` entries).
    drift : numpy.ndarray or float
        The drift per direction (``m`` entries, applied to both signs), or one drift for all (``δ²/2``).
    threshold : float
        ``h``: the sums are capped at ``2 h``, so that evidence long past does not delay the release.
    shift : float, optional
        ``δ``, multiplying both signs of ``z`` (the NAFDF's normalised innovations); none by default.

    Returns
    -------
    J : casadi.SX
        The largest new sum.
    sums : casadi.SX
        The new sums.
    """
    both = ca.vertcat(z, -z) if shift is None else float(shift) * ca.vertcat(z, -z)
    drifts = constant(np.concatenate([drift, drift])) if isinstance(drift, np.ndarray) else float(drift)
    new = ca.fmin(ca.fmax(sums + both - drifts, 0), 2.0 * float(threshold))
    return largest(new), new


def cusum_latch(sums: ca.SX, latches: ca.SX, threshold: float) -> tuple[ca.SX, ca.SX]:
    """The CUSUM's alarm: each sum's latch is 1 from crossing ``threshold`` until the sum returns to 0.

    Parameters
    ----------
    sums : casadi.SX
        The new sums (:func:`cusum_update`).
    latches : casadi.SX
        Their latches before this sample (0 or 1).
    threshold : float
        ``h``.

    Returns
    -------
    latches : casadi.SX
        The new latches.
    alarm : casadi.SX
        1 if any sum is latched.
    """
    if isinstance(sums, ca.MX):  # elementwise, as loops
        held = ca.if_else(ca.logic_or(sums > threshold, ca.logic_and(latches > 0, sums > 0)), 1, 0)
        return held, any_of(held)
    latch = ca.vertcat(
        *[ca.if_else(ca.logic_or(sums[i] > threshold, ca.logic_and(latches[i] > 0, sums[i] > 0)), 1, 0) for i in range(sums.numel())]
    )
    return latch, any_of(latch)


# --------------------------------------------------------------------------- GLR


def glr_update(z: ca.SX, sums: ca.SX, window: int) -> ca.SX:
    """One sample of the windowed GLR's onset sums (Willsky & Jones, IEEE TAC, 1976): per hypothesis
    ``d(1) = z(1)`` and ``d(n) = d(n−1) + z(n)`` for ``n = 2 … M``; the oldest onset leaves the window.

    Parameters
    ----------
    z : casadi.SX
        This sample's projected residual per hypothesis and onset (hypothesis-major, ``M`` per hypothesis).
    sums : casadi.SX
        The onset sums before this sample, laid out as ``z``.
    window : int
        ``M``, the onsets per hypothesis.

    Returns
    -------
    casadi.SX
        The new onset sums, laid out as ``z``.
    """
    if isinstance(z, ca.MX):  # d(1) = z(1) + 0: each onset's previous sum moved down by a 0/1 table
        size = z.numel()
        shift = np.zeros((size, size))
        for h in range(size // window):
            for n in range(1, window):
                shift[h * window + n, h * window + n - 1] = 1.0
        return ca.mtimes(constant(shift), sums) + z
    parts = []
    for h in range(z.numel() // window):
        base = h * window
        parts.append(z[base])
        for n in range(1, window):
            parts.append(sums[base + n - 1] + z[base + n])
    return ca.vertcat(*parts)


def glr_statistic(sums: ca.SX, weights: np.ndarray) -> ca.SX:
    """The GLR statistic ``J = max d² w`` over the onsets with a positive weight ``w = 1/(2c)``.

    Parameters
    ----------
    sums : casadi.SX
        The onset sums (any shape; taken in column-major order).
    weights : numpy.ndarray
        The weight of each sum, same shape (:func:`fdisyn.runtime.statistics.glr_weights`); at least one positive.

    Returns
    -------
    casadi.SX
        ``J``.
    """
    w = np.asarray(weights, dtype=float).reshape(-1, order="F")
    if isinstance(sums, ca.MX):  # the onsets with a weight, as one loop each: (d·d)·w, then the largest
        keep = [i for i in range(sums.numel()) if w[i] > 0]
        d = sums[keep]
        return largest(d * d * ca.DM(w[keep]))
    return largest(ca.vertcat(*[sums[i] * sums[i] * float(w[i]) for i in range(sums.numel()) if w[i] > 0]))


def glr_hold(J: ca.SX, held: ca.SX, threshold: float, release: float) -> ca.SX:
    """The GLR's alarm: raised when ``J`` exceeds ``threshold``, held while it stays above ``release``.

    Parameters
    ----------
    J : casadi.SX
        The statistic.
    held : casadi.SX
        The alarm before this sample (0 or 1).
    threshold, release : float
        The threshold and the release level (:func:`fdisyn.runtime.gainfile.release_level`).

    Returns
    -------
    casadi.SX
        The new alarm (0 or 1).
    """
    return ca.if_else(ca.logic_or(J > threshold, ca.logic_and(held > 0, J > release)), 1, 0)


# --------------------------------------------------------------------------- counters


def persistence_count(exceeds: ca.SX, count: ca.SX, cap: float | None = None) -> ca.SX:
    """The number of consecutive samples a test has held: ``count + 1`` (at most ``cap``) while
    ``exceeds``, else 0.

    Parameters
    ----------
    exceeds : casadi.SX
        This sample's test (e.g. ``J > threshold``).
    count : casadi.SX
        The count before this sample.
    cap : float, optional
        Where the count stops growing (the Beard filter's persistence); unbounded without.

    Returns
    -------
    casadi.SX
        The new count.
    """
    return ca.if_else(exceeds, count + 1 if cap is None else ca.fmin(count + 1, cap), 0)


# --------------------------------------------------------------------------- a linear diagnoser's statistics


@dataclass(frozen=True)
class Evaluated:
    """One sample of one statistic of a linear diagnoser: its value, its new state block and what its alarm
    rule needs besides ``J``."""

    J: ca.SX
    state: ca.SX | None = None
    latched: ca.SX | None = None


@dataclass(frozen=True)
class LinearStatistic:
    """How a linear diagnoser's statistic of one kind (:class:`~fdisyn.runtime.gainfile.Evaluator`) is
    evaluated per sample, in the semantics of :class:`fdisyn.runtime.reference.LinearReference`.

    ``block``: the prefix of its state block in :func:`~fdisyn.runtime.layout.linear_state_layout`
    (``None``: no state beyond its counter); ``sequential``: one of
    :data:`~fdisyn.runtime.schema.SEQUENTIAL_KINDS` (the step checks its value for overflow after the
    other statistics' of its generator, in the reference's order); ``evaluate(r, block, ev)``: its value and
    new block from the generator's residual ``r`` and the block before the sample;
    ``counter(value, J, counter, ev)``: its alarm counter after a valid sample (``J`` the reported value).
    Adding a statistic kind adds one in its detector's module (:class:`fdisyn.detectors.table.Detector`); the
    linear step is unchanged.
    """

    block: str | None
    sequential: bool
    evaluate: Callable[[ca.SX, ca.SX | None, Evaluator], Evaluated]
    counter: Callable[[Evaluated, ca.SX, ca.SX, Evaluator], ca.SX]


def above_threshold(value: Evaluated, J: ca.SX, count: ca.SX, ev: Evaluator) -> ca.SX:
    """The alarm counter of a statistic compared with its threshold on each sample (χ², WSSR): consecutive
    exceedances (:func:`persistence_count`).

    Parameters
    ----------
    value : Evaluated
        This sample's value (unused: the rule reads ``J``).
    J : casadi.SX
        The reported value.
    count : casadi.SX
        The counter before the sample.
    ev : Evaluator
        The statistic (its ``threshold``).

    Returns
    -------
    casadi.SX
        The counter after the sample.
    """
    return persistence_count(J > ev.threshold, count)
