"""Sequential change detection on a white Gaussian residual: CUSUM and windowed GLR, their thresholds from a
false-alarm budget in time, and the Lorden bound on the detection delay.

A residual ``r ~ N(0, Σ)`` (white: every linear generator's residual is whitened first, see
:func:`fdisyn.synthesis.residual.whitened`) changes to ``N(μ, Σ)`` when a fault of steady-state signature ``μ``
appears. With ``W = Σ⁺`` the log-likelihood ratio of one sample is ``s = μᵀ W r − ½ μᵀ W μ``, whose law is
``N(−I, 2I)`` before the change and ``N(+I, 2I)`` after it, ``I = ½ μᵀ W μ`` being the Kullback–Leibler
information per sample (nats).

* **CUSUM** (Page, Biometrika 41(1/2), 1954): ``S(k) = max(0, S(k−1) + s(k))``, alarm when ``S > h``. Its mean
  run length from ``S = 0`` with no fault, ``ARL₀(h)``, solves Page's integral equation
  ``L(x) = 1 + L(0) F(−x) + ∫₀ʰ L(y) f(y − x) dy`` (``f``, ``F``: density and distribution of ``s``), computed
  by Nyström's method on Gauss–Legendre nodes (:func:`cusum_arl`); Siegmund's corrected diffusion
  approximation (Siegmund, Sequential Analysis, Springer 1985, eq. (2.56)) is its independent check
  (:func:`cusum_arl_siegmund`).
* **Windowed GLR** (Willsky & Jones, IEEE Transactions on Automatic Control 21(1), 1976): for a fault of
  known residual signature ``ρ(ℓ)`` (``ℓ`` samples after onset) but unknown size ``ν`` and onset within the
  last ``M`` samples, ``l(k) = max_{n ≤ M} d(n)² / (2 c(n))`` with ``d(n) = Σ_{ℓ<n} ρ(ℓ)ᵀ W r(k−n+1+ℓ)`` and
  ``c(n) = Σ_{ℓ<n} ρ(ℓ)ᵀ W ρ(ℓ)``; the maximising ``n`` estimates the onset and ``d/c`` the size. Its mean run
  length has no closed form: :func:`glr_arl` is the approximation of Siegmund & Venkatraman (Annals of
  Statistics 23(1), 1995, eq. (10)) for a constant signature, with Siegmund's overshoot correction ``ν(x)``
  (Siegmund & Yakir, The Statistics of Gene Mapping, Springer 2007, eq. (4.35)).

The Lorden bound (Lorden, Annals of Mathematical Statistics 42(6), 1971): no detector whose mean time
between false alarms is ``ARL₀`` samples detects a change of information ``I`` faster, in the worst case,
than ``ln(ARL₀) / I`` samples as ``ARL₀ → ∞``; CUSUM attains it for the change it is tuned to.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

import casadi as ca
import numpy as np
import scipy.optimize
import scipy.special
import scipy.stats
from fdisyn.detectors.chi2 import chi2_evaluator
from fdisyn.detectors.symbolic import (
    Evaluated,
    LinearStatistic,
    constant,
    cusum_latch,
    cusum_update,
    glr_hold,
    glr_statistic,
    glr_update,
)
from fdisyn.detectors.table import Detector, register
from fdisyn.numerics.account import PROBABILITIES, SizeLaw, Sizes, ncx2_lambda
from fdisyn.runtime.errors import ArgumentError, ExistenceError, ShapeError, SolverError
from fdisyn.runtime.gainfile import Evaluator, release_level
from fdisyn.runtime.statistics import MAX_GLR_WINDOW, glr_weights
from fdisyn.runtime.names import shown

__all__ = [
    "cusum_arl",
    "cusum_arl_siegmund",
    "cusum_threshold",
    "glr_arl",
    "glr_threshold",
    "lorden_delay",
    "onset_lorden_delay",
    "split_budget",
    "cusum_evaluator",
    "scaled_signatures",
    "glr_evaluator",
    "ARL_RTOL",
    "MAX_ARL_SAMPLES",
    "check_arl_samples",
    "CUSUM",
    "GLR",
]

ARL_RTOL = 1e-6
"""Relative accuracy of :func:`cusum_arl` (Nyström with at least 96 Gauss–Legendre nodes, and 8 per standard
deviation of the increment on the continuation region; the tests compare it with twice as many nodes and with
Siegmund's approximation, which is within a few per cent)."""

MAX_ARL_SAMPLES = 1e300
"""Largest mean run length (samples) of one statistic whose threshold is computed: a false-alarm rate of
``1e-300`` per sample. The run-length laws are evaluated in log-space there (thresholds near 690 nats); beyond
it ``1/ARL`` leaves the normal range of a double (a gain file stores the rate ``P_f = 1/ARL``)."""

_NYSTROM_TRUSTED = 1e8
"""Largest ``ARL₀`` the direct Nyström solve of Page's equation (:func:`cusum_arl`) is taken from: its system
has a condition number of the order of the run length, so beyond ``1e8`` samples round-off reaches
:data:`ARL_RTOL`; the run length is then computed from the renewal form with the exponential change of
measure (:func:`_cusum_log_arl0_tilted`), whose systems stay well conditioned. A threshold search for a run
length up to ``1e8`` (:func:`cusum_threshold`, :func:`cusum_evaluator`) takes the direct values wherever the
solve succeeds: the root lies where they are accurate, and longer run lengths only steer the bracket."""

_NODES = 96
_LOG_MAX = math.log(float(np.finfo(float).max))
_DIFFUSION_BEYOND = 30.0
"""``h/σ`` beyond which :func:`cusum_arl` uses Siegmund's approximation (a Nyström system of ``8 h/σ`` nodes
would grow past 240; the increment is then a small fraction of the threshold, where the corrected diffusion is
accurate: within 0.05 % of the integral equation at ``h/σ ≈ 25`` already)."""


def _positive(value: float, name: str) -> float:
    v = float(value)
    if not math.isfinite(v) or v <= 0.0:
        raise ArgumentError(f"{name} must be a positive finite number; got {value!r}")
    return v


def check_arl_samples(arl_samples: float, what: str) -> float:
    """``arl_samples`` if it is a mean run length the thresholds are computed for: finite, ``≥ 1`` sample's
    fraction above 0 and at most :data:`MAX_ARL_SAMPLES`; else an :class:`ArgumentError` that names ``what``
    (the user's option and value) and the working domain.

    Parameters
    ----------
    arl_samples : float
        The mean run length of one statistic, in samples.
    what : str
        How the message names the value, e.g. ``"PATH [design].arl0 = 1e+308 s"``.

    Returns
    -------
    float
        ``arl_samples``.

    Raises
    ------
    ArgumentError
        Outside ``(0, MAX_ARL_SAMPLES]``.
    """
    v = float(arl_samples)
    if not (v > 0.0 and v <= MAX_ARL_SAMPLES):  # NaN fails too
        raise ArgumentError(
            f"{what} is a mean run length of {v:.3g} samples per statistic; the thresholds are computed up to "
            f"{MAX_ARL_SAMPLES:g} samples (a false-alarm rate of {1.0 / MAX_ARL_SAMPLES:g} per sample): give a smaller value"
        )
    return v


def cusum_arl(h: float, information: float, *, shift: float = 0.0, nodes: int = _NODES) -> float:
    """Mean run length (samples) of the CUSUM ``S = max(0, S + s)`` from ``S = 0`` to ``S > h``.

    ``s ~ N(−I + 2 I·shift, 2I)``: ``shift = 0`` is no fault (``ARL₀``), ``shift = 1`` the fault the CUSUM is
    tuned to (its mean delay from ``S = 0``, ``ARL₁``). Page's integral equation on ``[0, h]``, solved by
    Nyström's method on Gauss–Legendre nodes (the kernel is smooth; the atom at 0 is the ``L(0) F(−x)`` term).
    An ``ARL₀`` beyond :data:`_NYSTROM_TRUSTED` comes from the renewal form instead (:func:`_cusum_log_arl0_tilted`);
    one beyond the double range is ``inf`` (:func:`cusum_log_arl` gives its logarithm).
    """
    log_scale, value = _cusum_run_length(h, information, shift, nodes, _NYSTROM_TRUSTED)
    if not log_scale:
        return value
    return math.exp(value) if value < _LOG_MAX else math.inf



def cusum_log_arl(h: float, information: float, *, shift: float = 0.0, nodes: int = _NODES) -> float:
    """``ln`` of :func:`cusum_arl`, finite however long the run length (``math.log`` of it where that is finite)."""
    log_scale, value = _cusum_run_length(h, information, shift, nodes, _NYSTROM_TRUSTED)
    return value if log_scale else math.log(value)


def _cusum_run_length(h: float, information: float, shift: float, nodes: int, trusted: float) -> tuple[bool, float]:
    """``(False, ARL)`` from the Nyström solve of Page's equation, or ``(True, ln ARL)`` where that is not used:
    a threshold of many increments (Siegmund's approximation), or an ``ARL₀`` beyond ``trusted`` or whose solve
    failed (:func:`_cusum_log_arl0_tilted`)."""
    i = _positive(information, "information")
    if not math.isfinite(h) or h < 0.0:
        raise ArgumentError(f"h must be a finite threshold ≥ 0; got {h!r}")
    if h > 0.0 and h / math.sqrt(2.0 * i) > _DIFFUSION_BEYOND:
        # a threshold of many increment deviations: Siegmund's corrected diffusion is accurate to O(σ²) there
        value = cusum_arl_siegmund(h, i, shift=shift)
        return (False, value) if math.isfinite(value) else (True, _siegmund_log_arl(h, i, shift))
    if float(shift) != 0.0 or h == 0.0:
        return False, _cusum_arl_nystrom(h, i, shift, nodes)
    try:
        direct = _cusum_arl_nystrom(h, i, 0.0, nodes)
    except SolverError:  # the solve lost every digit to round-off: a very long run length
        direct = math.nan
    if 1.0 <= direct <= trusted:
        return False, direct
    return True, _cusum_log_arl0_tilted(h, i, nodes)


def _cusum_log_arl0_tilted(h: float, information: float, nodes: int = _NODES) -> float:
    """``ln ARL₀`` of the CUSUM by its renewal form with an exponential change of measure, for long run lengths.

    The CUSUM restarts from 0 whenever ``S`` falls to 0, so ``ARL₀ = N(0)/P(0)`` (Page, Biometrika 41(1/2), 1954):
    ``N(x)`` is the mean length of an excursion of the random walk from ``x`` until it leaves ``(0, h]`` and
    ``P(x)`` the probability that it leaves above ``h``. ``s`` is a log-likelihood ratio, so under the fault's
    law (increments ``N(+I, 2I)``) ``P(x) = E₁[e^{−(S_τ − x)}; S_τ > h] = e^{x−h} G(x)`` with
    ``G(x) = E₁[e^{−(S_τ − h)}; S_τ > h] ≤ 1`` (Wald's likelihood-ratio identity; Siegmund, Sequential Analysis,
    Springer 1985, ch. 2). ``N`` (drift down) and ``G`` (drift up) solve integral equations with no atom, whose
    Nyström systems are well conditioned whatever the run length, and ``ln ARL₀ = ln N(0) + h − ln G(0)``.
    """
    i = _positive(information, "information")
    sd = math.sqrt(2.0 * i)
    top = h / sd
    count = int(max(int(nodes), math.ceil(8.0 * top)))
    t, w = np.polynomial.legendre.leggauss(count)
    x = 0.5 * top * (t + 1.0)
    w = 0.5 * top * w
    pts = np.concatenate([[0.0], x])

    def kernel(mean: float) -> np.ndarray:
        dz = x[None, :] - pts[:, None] - mean
        return np.exp(-0.5 * dz * dz) * (w[None, :] / math.sqrt(2.0 * math.pi))

    k0, k1 = kernel(-0.5 * sd), kernel(0.5 * sd)
    eye = np.eye(count)
    n = np.linalg.solve(eye - k0[1:], np.ones(count))
    n0 = 1.0 + float(k0[0] @ n)
    # the overshoot term: E[e^{−σ(z − top)}; z > top] for z ~ N(x + σ/2, 1), in closed form
    gap = top - (pts + 0.5 * sd)
    over = np.exp(sd * gap + 0.5 * sd * sd + scipy.special.log_ndtr(-(gap + sd)))
    g = np.linalg.solve(eye - k1[1:], over[1:])
    g0 = float(over[0] + k1[0] @ g)
    if not (n0 >= 1.0 and g0 > 0.0 and math.isfinite(n0) and math.isfinite(g0)):
        raise SolverError(f"the CUSUM run length for h = {h:g}, I = {i:g} could not be computed (N(0) = {n0!r}, G(0) = {g0!r})")
    return math.log(n0) + h - math.log(g0)


def _cusum_arl_nystrom(h: float, information: float, shift: float, nodes: int) -> float:
    """:func:`cusum_arl` by the Nyström solve of Page's equation with its atom at 0."""
    i = _positive(information, "information")
    if not math.isfinite(h) or h < 0.0:
        raise ArgumentError(f"h must be a finite threshold ≥ 0; got {h!r}")
    # in units of the increment's standard deviation σ = √(2I): s/σ ~ N(−σ/2 + σ·shift, 1) on [0, h/σ]
    sd = math.sqrt(2.0 * i)
    mean, top = (-i + 2.0 * i * float(shift)) / sd, h / sd
    if h == 0.0:  # every sample above 0 alarms: a geometric run length (longer than any double: inf)
        above = float(scipy.stats.norm.sf(0.0, mean, 1.0))
        return 1.0 / above if above > 0.0 else math.inf
    # the kernel has unit width: a few nodes per unit of the interval keep the quadrature exact to round-off
    count = int(max(int(nodes), math.ceil(8.0 * top)))
    t, w = np.polynomial.legendre.leggauss(count)
    x = 0.5 * top * (t + 1.0)
    w = 0.5 * top * w
    # L(x_i) = 1 + L(0) F(−x_i) + Σ_j w_j f(x_j − x_i) L(x_j), with L(0) as an extra unknown (row for x = 0)
    pts = np.concatenate([[0.0], x])
    dz = x[None, :] - pts[:, None] - mean
    kern = np.exp(-0.5 * dz * dz) * (w[None, :] / math.sqrt(2.0 * math.pi))
    atom = scipy.special.ndtr(-pts - mean)
    m = np.zeros((len(pts), len(pts)))
    m[:, 0] = -atom
    m[:, 1:] = -kern
    m += np.eye(len(pts))
    arl = np.linalg.solve(m, np.ones(len(pts)))
    value = float(arl[0])
    if not math.isfinite(value) or value < 1.0:
        raise SolverError(f"the CUSUM run length for h = {h:g}, I = {i:g} is not a number ≥ 1 ({value!r}): the integral equation is ill-posed there")
    return value


def cusum_arl_siegmund(h: float, information: float, *, shift: float = 0.0) -> float:
    """Siegmund's approximation of :func:`cusum_arl`: with the increments standardised (``σ = √(2I)``, mean
    ``Δ``), ``ARL ≈ (exp(−2Δb) + 2Δb − 1) / (2Δ²)``, ``b = h/σ + 1.166`` (Siegmund 1985, eq. (2.56)); ``inf``
    beyond the double range (:func:`_siegmund_log_arl` gives its logarithm)."""
    i = _positive(information, "information")
    sd = math.sqrt(2.0 * i)
    delta = (-i + 2.0 * i * float(shift)) / sd
    b = h / sd + 1.166
    if abs(delta) < 1e-12:
        return b * b
    if -2.0 * delta * b > _LOG_MAX - 1.0:
        log_arl = _siegmund_log_arl(h, i, shift)
        return math.exp(log_arl) if log_arl < _LOG_MAX else math.inf
    return (math.exp(-2.0 * delta * b) + 2.0 * delta * b - 1.0) / (2.0 * delta * delta)


def _siegmund_log_arl(h: float, information: float, shift: float = 0.0) -> float:
    """``ln`` of :func:`cusum_arl_siegmund`, in log-space where its exponential overflows (the same number
    elsewhere): with ``z = −2Δb > 0``, ``ARL = e^z (1 − (z + 1) e^{−z}) / (2Δ²)``."""
    i = _positive(information, "information")
    sd = math.sqrt(2.0 * i)
    delta = (-i + 2.0 * i * float(shift)) / sd
    z = -2.0 * delta * (h / sd + 1.166)
    if abs(delta) < 1e-12 or z <= _LOG_MAX - 1.0:
        return math.log(cusum_arl_siegmund(h, i, shift=shift))
    return z + math.log1p(-(z + 1.0) * math.exp(-z)) - math.log(2.0 * delta * delta)


def cusum_threshold(arl0: float, information: float) -> float:
    """The CUSUM threshold ``h`` with ``ARL₀(h) = arl0`` samples (:func:`cusum_arl`, root on ``ln ARL``)."""
    target = check_arl_samples(_positive(arl0, "arl0"), f"arl0 = {shown(arl0)}")
    i = _positive(information, "information")
    if target <= cusum_arl(0.0, i):
        return 0.0
    trusted = _trusted(target)

    def log_arl(h: float) -> float:
        log_scale, value = _cusum_run_length(h, i, 0.0, _NODES, trusted)
        return value if log_scale else math.log(value)

    lo, hi = 0.0, 1.0
    while log_arl(hi) < math.log(target):
        lo, hi = hi, 2.0 * hi
        if hi > 1e4:
            raise SolverError(f"no CUSUM threshold reaches ARL₀ = {target:g} samples for I = {i:g}")
    return float(scipy.optimize.brentq(lambda h: log_arl(h) - math.log(target), lo, hi, xtol=1e-10, rtol=1e-12))


def _trusted(target: float) -> float:
    """The largest direct Nyström value a search for run length ``target`` takes (:data:`_NYSTROM_TRUSTED`)."""
    return math.inf if target <= _NYSTROM_TRUSTED else _NYSTROM_TRUSTED


def _overshoot(x: float) -> float:
    """Siegmund's ``ν(x)``: the discrete-time correction of a Gaussian random walk's first passage
    (``ν(x) ≈ (2/x)(Φ(x/2) − ½) / ((x/2)Φ(x/2) + φ(x/2))``, Siegmund & Yakir 2007, eq. (4.35))."""
    if x <= 0.0:
        return 1.0
    z = 0.5 * x
    return (2.0 / x) * (scipy.stats.norm.cdf(z) - 0.5) / (z * scipy.stats.norm.cdf(z) + scipy.stats.norm.pdf(z))


def glr_arl(h: float, window: int) -> float:
    """Mean run length (samples) of the windowed GLR ``max_{n ≤ M} d(n)²/(2c(n)) > h`` on white Gaussian data
    with a constant signature (Siegmund & Venkatraman 1995, eq. (10), two-sided)::

        ARL₀ ≈ √(2π) e^{c²/2} / (c ∫_{c√(2/M)}^{c√2} x ν(x)² dx),   c = √(2h).

    The integral runs over the onsets ``n = 1 … M`` (``x = c √(2/n)``). ``inf`` beyond the double range
    (:func:`glr_log_arl` gives its logarithm).
    """
    m, integral = _glr_integral(h, window)
    if h > _LOG_MAX - 10.0:
        log_arl = glr_log_arl(h, m)
        return math.exp(log_arl) if log_arl < _LOG_MAX else math.inf
    c = math.sqrt(2.0 * h)
    # the first onset (n = 1) alone is a χ²₁ test: the run length is at most 1/P(χ²₁ > 2h)
    bound = 1.0 / float(scipy.stats.chi2.sf(2.0 * h, 1))
    return min(math.sqrt(2.0 * math.pi) * math.exp(0.5 * c * c) / (c * integral), bound) if integral > 0 else bound


def glr_log_arl(h: float, window: int) -> float:
    """``ln`` of :func:`glr_arl`, finite however long the run length (``math.log`` of it where that is finite)."""
    m, integral = _glr_integral(h, window)
    if h <= _LOG_MAX - 10.0:
        return math.log(glr_arl(h, m))
    c = math.sqrt(2.0 * h)
    log_bound = -float(scipy.stats.chi2.logsf(2.0 * h, 1))
    if integral <= 0:
        return log_bound
    return min(0.5 * math.log(2.0 * math.pi) + 0.5 * c * c - math.log(c * integral), log_bound)


def _glr_integral(h: float, window: int) -> tuple[int, float]:
    """The window and the overshoot integral ``∫ x ν(x)² dx`` of :func:`glr_arl` (arguments checked)."""
    m = int(window)
    if m < 1:
        raise ArgumentError(f"window must be ≥ 1; got {window!r}")
    if not math.isfinite(h) or h <= 0.0:
        raise ArgumentError(f"h must be a positive finite threshold; got {h!r}")
    c = math.sqrt(2.0 * h)
    lo, hi = c * math.sqrt(2.0 / m), c * math.sqrt(2.0)
    xs, ws = np.polynomial.legendre.leggauss(64)
    xs = 0.5 * (hi - lo) * (xs + 1.0) + lo
    return m, float(np.sum(0.5 * (hi - lo) * ws * xs * np.array([_overshoot(x) ** 2 for x in xs])))


def glr_threshold(arl0: float, window: int) -> float:
    """The GLR threshold ``h`` with :func:`glr_arl` ``(h, window) = arl0`` samples."""
    target = check_arl_samples(_positive(arl0, "arl0"), f"arl0 = {shown(arl0)}")
    lo, hi = 1e-3, 1.0
    while glr_log_arl(hi, window) < math.log(target):
        lo, hi = hi, 2.0 * hi
        if hi > 1e4:
            raise SolverError(f"no GLR threshold reaches ARL₀ = {target:g} samples for window {window}")
    if glr_log_arl(lo, window) > math.log(target):
        return lo
    return float(scipy.optimize.brentq(lambda h: glr_log_arl(h, window) - math.log(target), lo, hi, xtol=1e-10, rtol=1e-12))


def lorden_delay(arl0: float, information: float) -> float:
    """``ln(ARL₀) / I`` samples: Lorden's (1971) asymptotic lower bound on the worst-case mean delay."""
    return math.log(_positive(arl0, "arl0")) / _positive(information, "information")


def onset_lorden_delay(arl0: float, information: Any, tail: float) -> float:
    """The smallest ``n`` with ``Σ_{ℓ<n} I_ℓ ≥ ln(ARL₀)``: Lorden's bound for a change whose information per sample
    builds up after the onset.

    The non-i.i.d. form of Lorden's bound (Lai, IEEE Transactions on Information Theory 44(7), 1998): the mean
    delay is bounded below by the time the cumulative Kullback–Leibler information of the post-change samples takes
    to reach ``ln(ARL₀)``. Between whole samples ``n`` is interpolated linearly (the cumulative information is taken
    to grow evenly over a sample), so for a constant ``I_ℓ = I`` it is :func:`lorden_delay`, ``ln(ARL₀)/I``.

    Parameters
    ----------
    arl0 : float
        The false-alarm budget in samples (> 1 for a positive bound).
    information : array_like
        ``I_ℓ`` (nats) for the lags ``ℓ = 0, …, L−1`` after the onset: each ``≥ 0``, or an unbiased estimate of it
        (a measured shift's information less its noise's, which may fall below 0); the bound is the first ``n`` at
        which their cumulative sum reaches ``ln(ARL₀)``.
    tail : float
        The information per sample from lag ``L`` on (≥ 0; the change's steady state).

    Returns
    -------
    float
        The bound in samples; ``inf`` when the information never reaches ``ln(ARL₀)``.

    Raises
    ------
    ArgumentError
        ``arl0`` is not positive and finite, an information is not finite, or ``tail`` is negative.

    Examples
    --------
    >>> round(onset_lorden_delay(math.e ** 4, [1.0, 1.0], 1.0), 12)  # a step: ln(ARL)/I
    4.0
    >>> onset_lorden_delay(math.e ** 4, [0.0, 2.0, 2.0], 2.0)  # nothing on the onset sample, then 2 nats each
    3.0
    """
    level = math.log(_positive(arl0, "arl0"))
    info = np.asarray(information, dtype=float).reshape(-1)
    if not np.all(np.isfinite(info)) or not (math.isfinite(float(tail)) and float(tail) >= 0.0):
        raise ArgumentError("the information per sample must be finite at every lag, and finite and ≥ 0 in the tail")
    if level <= 0.0:
        return 0.0
    total = np.cumsum(info)
    reached = np.flatnonzero(total >= level)
    m = int(reached[0]) if reached.size else info.size  # the first lag whose cumulative information reaches it
    if m < info.size:  # info[m] > 0: the sum was below the level a lag before
        before = float(total[m - 1]) if m else 0.0
        return m + (level - before) / float(info[m])
    measured = float(total[-1]) if info.size else 0.0
    return float(info.size + (level - measured) / float(tail)) if tail > 0.0 else math.inf


def split_budget(arl0_samples: float, parts: int) -> float:
    """Each of ``parts`` statistics' share of a diagnoser's false-alarm budget: ``parts · ARL₀`` samples.

    Alarms of the diagnoser are the union of its statistics' alarms, so their rates add at most
    (Bonferroni): ``1/ARL₀ ≤ Σ 1/ARL_j``. Equal shares make the diagnoser's mean time between false
    alarms at least ``arl0`` — exactly when the statistics never alarm together, longer when they do.
    """
    return _positive(arl0_samples, "arl0") * int(parts)


# --------------------------------------------------------------------------- evaluators of a linear generator


def _union_threshold(
    arl_samples: float, log_arl_of: Callable[[float], float], what: str, approx: Callable[[float], float] | None = None
) -> float:
    """``h`` with ``Σ_i 1/ARL_i(h) = 1/arl_samples`` (``log_arl_of(h)`` returns ``−ln Σ_i 1/ARL_i(h)``); ``approx``,
    a cheap approximation of ``log_arl_of``, brackets the root first."""
    target = math.log(check_arl_samples(_positive(arl_samples, "arl0"), f"a {what} statistic's run length"))
    if approx is not None:
        guess = _union_threshold(arl_samples, approx, what)
        lo, hi = 0.8 * guess, 1.25 * guess
        if log_arl_of(lo) < target < log_arl_of(hi):
            return float(scipy.optimize.brentq(lambda h: log_arl_of(h) - target, lo, hi, xtol=1e-10, rtol=1e-12))
    lo, hi = 1e-3, 1.0
    while log_arl_of(hi) < target:
        lo, hi = hi, 2.0 * hi
        if hi > 1e4:
            raise SolverError(f"no {what} threshold reaches a mean run length of {arl_samples:g} samples")
    if log_arl_of(lo) >= target:
        return lo
    return float(scipy.optimize.brentq(lambda h: log_arl_of(h) - target, lo, hi, xtol=1e-10, rtol=1e-12))


def _log_union(counts: Sequence[tuple[float, float]]) -> float:
    """``−ln Σ_i c_i e^{−L_i}`` for pairs ``(c_i, L_i)``: the log run length of a union of statistics from theirs."""
    terms = [math.log(c) - log_arl for c, log_arl in counts]
    top = max(terms)
    return -(top + math.log(sum(math.exp(t - top) for t in terms)))


ALIKE_COSINE = 0.99
ALIKE_SIZE = 0.1
"""Two fault signatures in one generator whose directions agree to a cosine of :data:`ALIKE_COSINE` (either
sign, in the metric of ``W``) and whose informations differ by less than :data:`ALIKE_SIZE` (relative) are one
hypothesis: their statistics would run within a fraction of a drift of each other, and counting them twice
would spend the false-alarm budget twice on one test. The smaller one is kept (it detects the larger)."""


def _distinct(
    signatures: Sequence[np.ndarray], names: Sequence[str], weight: np.ndarray, *, any_size: bool = False
) -> list[tuple[np.ndarray, str]]:
    """The signatures without alike repeats (:data:`ALIKE_COSINE`, :data:`ALIKE_SIZE`; ``any_size``: of any
    size, for a statistic that estimates the size — the GLR's is the same for parallel signatures), smallest
    first, each with the names of the classes it stands for (``a|b``, the kept one first)."""
    sig = [np.asarray(s, dtype=float) for s in signatures]
    if len(names) != len(sig):
        raise ShapeError(f"{len(sig)} signatures need as many names, got {len(names)}")
    info = [float(np.sum((s @ weight) * s)) for s in sig]
    out: list[list[Any]] = []
    for k in np.argsort(info, kind="stable"):
        a, ia = sig[k], info[k]
        for kept in out:
            b, ib = kept[0], kept[1]
            cross = float(np.sum((a @ weight) * b))
            if ia > 0 and ib > 0 and abs(cross) >= ALIKE_COSINE * math.sqrt(ia * ib) and (any_size or ia <= (1.0 + ALIKE_SIZE) * ib):
                kept[2].append(names[k])
                break
        else:
            out.append([a, ia, [names[k]]])
    return [(a, "|".join(n)) for a, _, n in out]


def cusum_evaluator(
    generator: int, sigma_r: np.ndarray, signatures: Sequence[np.ndarray], arl_samples: float, names: Sequence[str] | None = None
) -> Evaluator:
    """A CUSUM statistic on a white residual of covariance ``sigma_r`` for the fault signatures ``μ_i``.

    Each ``μ`` gives two CUSUMs, for ``+μ`` and ``−μ`` (a bias of either sign), on the direction ``μᵀ W``
    with drift ``½ μᵀ W μ``. ``J = max_i S_i`` alarms above the ``h`` whose union run length
    ``1 / Σ_i 1/ARL₀_i(h)`` (:func:`cusum_arl` of each CUSUM's information) is ``arl_samples``: the CUSUMs of one
    statistic share its budget as the statistics share the diagnoser's (:func:`split_budget`).
    """
    base = chi2_evaluator(generator, sigma_r, 0.5)
    rows, drift, labels = [], [], []
    for mu, label in _distinct(signatures, names or [f"h{i}" for i in range(len(signatures))], base.W):
        labels.append(label)
        a = np.asarray(mu, dtype=float) @ base.W
        info = 0.5 * float(a @ np.asarray(mu, dtype=float))
        rows.append(a)
        drift.append(info)
    if not rows:
        raise ExistenceError(f"generator {generator} has no fault signature to run a CUSUM on")

    counts: dict[float, int] = {}
    for i in drift:
        counts[i] = counts.get(i, 0) + 2  # both signs

    trusted = _trusted(float(arl_samples))

    def log_arl(h: float) -> float:
        runs = [(c, _cusum_run_length(h, i, 0.0, _NODES, trusted)) for i, c in counts.items()]
        if not any(log_scale for _, (log_scale, _) in runs):
            return math.log(1.0 / sum(c / value for c, (_, value) in runs))
        return _log_union([(c, value if log_scale else math.log(value)) for c, (log_scale, value) in runs])

    def siegmund(h: float) -> float:
        values = [(c, cusum_arl_siegmund(h, i)) for i, c in counts.items()]
        if all(math.isfinite(v) for _, v in values):
            return math.log(1.0 / sum(c / v for c, v in values))
        return _log_union([(c, _siegmund_log_arl(h, i)) for i, c in counts.items()])

    h = _union_threshold(arl_samples, log_arl, "CUSUM", siegmund)
    return replace(
        base,
        kind="cusum",
        P_f=1.0 / float(arl_samples),
        threshold=h,
        directions=np.array(rows),
        drift=np.array(drift),
        hypotheses=tuple(labels),
    )


def glr_evaluator(
    generator: int, sigma_r: np.ndarray, signatures: Sequence[np.ndarray], arl_samples: float, window: int,
    names: Sequence[str] | None = None,
) -> Evaluator:
    """A windowed GLR statistic on a white residual of covariance ``sigma_r`` for the transient fault
    signatures ``ρ_i`` (each ``(window, nr)``: the residual ``ℓ`` samples after a unit step fault).

    The threshold ``h`` makes ``m`` hypotheses' union run length ``ARL(h)/m`` (:func:`glr_arl`, constant
    signature) equal to ``arl_samples``.
    """
    m = int(window)
    base = chi2_evaluator(generator, sigma_r, 0.5)
    rows, info, labels = [], [], []
    for rho, label in _distinct(signatures, names or [f"h{i}" for i in range(len(signatures))], base.W, any_size=True):
        labels.append(label)
        r = np.asarray(rho, dtype=float)
        if r.shape != (m, base.W.shape[0]):
            raise ShapeError(f"a GLR signature must be ({m}, {base.W.shape[0]}); got {r.shape}")
        a = r @ base.W
        rows.append(a)
        info.append(np.cumsum(np.einsum("ij,ij->i", a, r)))
    if not rows:
        raise ExistenceError(f"generator {generator} has no fault signature to run a GLR on")
    count = len(rows)

    def log_arl(h: float) -> float:
        if h <= _LOG_MAX - 10.0:
            return math.log(glr_arl(h, m) / count)
        return glr_log_arl(h, m) - math.log(count)

    h = _union_threshold(arl_samples, log_arl, "GLR")
    return replace(
        base,
        kind="glr",
        P_f=1.0 / float(arl_samples),
        threshold=h,
        window=m,
        directions=np.vstack(rows),
        information=np.concatenate(info),
        hypotheses=tuple(labels),
    )


# --------------------------------------------------------------------------- the detectors' entries


def _cusum_update(r: ca.SX, block: ca.SX | None, ev: Evaluator) -> Evaluated:
    assert block is not None and ev.directions is not None and ev.drift is not None
    m2 = 2 * ev.directions.shape[0]
    J, sums = cusum_update(ca.mtimes(constant(ev.directions), r), block[:m2], ev.drift, ev.threshold)
    latches, latched = cusum_latch(sums, block[m2:], ev.threshold)
    return Evaluated(J, ca.vertcat(sums, latches), latched)


def _cusum_counter(value: Evaluated, J: ca.SX, count: ca.SX, ev: Evaluator) -> ca.SX:
    assert value.latched is not None
    return ca.if_else(value.latched, 1, 0)


def _glr_update(r: ca.SX, block: ca.SX | None, ev: Evaluator) -> Evaluated:
    assert block is not None and ev.directions is not None
    sums = glr_update(ca.mtimes(constant(ev.directions), r), block, int(ev.window))
    return Evaluated(glr_statistic(sums, glr_weights(ev.information, ev.window)), sums)


def _glr_counter(value: Evaluated, J: ca.SX, count: ca.SX, ev: Evaluator) -> ca.SX:
    return glr_hold(J, count, ev.threshold, release_level(ev))


def scaled_signatures(
    signatures: Sequence[np.ndarray], names: Sequence[str], weight: np.ndarray, shifts: Sequence[float] | None
) -> tuple[list[np.ndarray], list[str]]:
    """Each signature ``μ`` rescaled to the whitened shifts ``δ`` (``‖μ‖_W = sqrt(μᵀ W μ) = δ``), one per shift,
    with its name repeated: the hypotheses of a multi-scale CUSUM; ``shifts`` ``None``: the signatures as given.

    A CUSUM tuned to ``δ₀`` detects a shift ``δ`` after about ``h / (δ δ₀ − δ₀²/2)`` samples against Lorden's
    ``h / (δ²/2)``: within 10 % for ``δ`` within a factor √2 of ``δ₀``, but 2.5 times it at a factor 4. Shifts a
    factor 2 apart keep every shift between them near the bound, for ``ln(#shifts)`` more threshold (Lorden,
    Annals of Mathematical Statistics 42(6), 1971, on several CUSUMs run together).

    Parameters
    ----------
    signatures : sequence of numpy.ndarray
        The hypotheses' steady-state residual signatures.
    names : sequence of str
        Their names.
    weight : numpy.ndarray
        ``W``, the inverse residual covariance.
    shifts : sequence of float or None
        The whitened shifts.

    Returns
    -------
    tuple
        ``(signatures, names)``; a signature the weight does not see is kept as given.

    Examples
    --------
    >>> sig, names = scaled_signatures([np.array([2.0, 0.0])], ["a"], np.eye(2), [0.5, 1.0])
    >>> [s.tolist() for s in sig], names
    ([[0.5, 0.0], [1.0, 0.0]], ['a', 'a'])
    """
    if shifts is None:
        return [np.asarray(m, dtype=float) for m in signatures], list(names)
    out, labels = [], []
    for mu, name in zip(signatures, names, strict=True):
        mu = np.asarray(mu, dtype=float)
        size = math.sqrt(max(float(mu @ weight @ mu), 0.0))
        for delta in shifts if size > 0 else [size]:
            out.append(mu * (float(delta) / size) if size > 0 else mu)
            labels.append(name)
    return out, labels


def _cusum_hypotheses(
    gi: int, sigma: np.ndarray, visible: Sequence[str], steady: dict[str, np.ndarray], infos: dict[str, float],
    arl_samples: float, window: int | None, response: Callable[[str, int], np.ndarray], shifts: Sequence[float] | None = None,
) -> Evaluator:
    weight = chi2_evaluator(gi, sigma, 0.5).W
    signatures, names = scaled_signatures([steady[k] for k in visible], visible, weight, shifts)
    return cusum_evaluator(gi, sigma, signatures, arl_samples, names=names)


def _glr_hypotheses(
    gi: int, sigma: np.ndarray, visible: Sequence[str], steady: dict[str, np.ndarray], infos: dict[str, float],
    arl_samples: float, window: int | None, response: Callable[[str, int], np.ndarray], shifts: Sequence[float] | None = None,
) -> Evaluator:
    m = window
    if m is None:  # twice the Lorden delay of the weakest hypothesis, clipped to 25…100 samples
        weakest = min(infos[k] for k in visible)
        m = int(min(100, max(25, math.ceil(2.0 * lorden_delay(arl_samples, weakest)))))
    if not 1 <= int(m) <= MAX_GLR_WINDOW:
        raise ArgumentError(f"window = {m}: a GLR onset window must be 1..{MAX_GLR_WINDOW} samples")
    signatures = [response(k, int(m)) for k in visible]
    return glr_evaluator(gi, sigma, signatures, arl_samples, int(m), names=visible)


def _glr_sizes(ev: Evaluator, g: np.ndarray, context: Any = None) -> Sizes:
    """The GLR's sizes from its full-window term ``d²/(2c)`` alone (a lower bound on ``J``, so the sizes are upper
    bounds): for the hypothesis best aligned with the shift, ``2·term`` is noncentral χ²(1)."""
    m = int(ev.window)
    rows = np.asarray(ev.directions).reshape(-1, m, g.shape[0])
    info = np.asarray(ev.information).reshape(-1, m)[:, -1]
    best = max(float((rows[i] @ g).sum()) ** 2 / float(info[i]) for i in range(rows.shape[0]))
    if not best > 0:
        return None, None, "no hypothesis of the GLR is aligned with its steady-state shift"
    sizes = [math.sqrt(ncx2_lambda(2.0 * float(ev.threshold), 1, p) / best) for p in PROBABILITIES]
    return sizes[0], sizes[1], None


def _cusum_sizes(ev: Evaluator, g: np.ndarray, context: Any = None) -> Sizes:
    """The size above which the CUSUM's best sum drifts upward: its mean increment ``a·(a_iᵀ g) − drift_i`` turns
    positive, so the fault is detected with probability one (no 50 % size)."""
    rows = np.asarray(ev.directions)
    drift = np.asarray(ev.drift)
    bounds = [float(drift[i]) / abs(float(rows[i] @ g)) for i in range(rows.shape[0]) if abs(float(rows[i] @ g)) > 0]
    if not bounds:
        return None, None, "no hypothesis of the CUSUM is aligned with its steady-state shift"
    return min(bounds), None, None


CUSUM: Detector = register(
    Detector(
        kind="cusum",
        doc="Page's CUSUM for each fault class's designed minimum fault (or, with shifts, for each of several sizes)",
        windowed=False,
        no_window="window = {window}: the CUSUM has no window (give it for 'wssr' or 'glr')",
        sequential=True,
        evaluators=lambda request: request.sequential(CUSUM),
        statistic=LinearStatistic("sequential", True, _cusum_update, _cusum_counter),
        size_law=SizeLaw("cusum", "CUSUM: the size above which its sum drifts up (detected with probability 1)", _cusum_sizes),
        cited="CUSUM (Page, Biometrika 41(1/2), 1954)",
        hypotheses=_cusum_hypotheses,
        reads_shifts=True,
    )
)
"""The CUSUM detector (:class:`~fdisyn.detectors.table.Detector`): Page, Biometrika 41(1/2), 1954."""

GLR: Detector = register(
    Detector(
        kind="glr",
        doc="the windowed GLR of Willsky & Jones for a fault of unknown size and onset",
        windowed=True,
        no_window="",
        sequential=True,
        evaluators=lambda request: request.sequential(GLR),
        statistic=LinearStatistic("sequential", True, _glr_update, _glr_counter),
        size_law=SizeLaw("glr", "GLR: P(full-window term > threshold) = 95 % (50 %)", _glr_sizes),
        cited="windowed GLR (Willsky & Jones, IEEE Transactions on Automatic Control 21(1), 1976)",
        hypotheses=_glr_hypotheses,
        window_doc="the GLR's onset window",
        window_default="chosen from the designed faults",
    )
)
"""The windowed GLR detector (:class:`~fdisyn.detectors.table.Detector`): Willsky & Jones, IEEE Transactions on
Automatic Control 21(1), 1976."""
