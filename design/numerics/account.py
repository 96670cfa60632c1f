"""The design-time account of what a linear diagnoser can see: each fault's effect, smallest size, and the classes.

Before any Monte Carlo, for each fault — an additive bias on each sensor, and each component fault (a column of the
plant's ``Fx``) — the account states:

* its **effect** on each generator's residual, from the fault→residual transfer of plant and generator (the internal
  form ``[x; ξ]``, or the generator alone for a sensor fault): ``"zero"`` (its peak gain over the unit circle is
  below :data:`ZERO_RTOL` of the size of the terms it is made of: what an exact cancellation leaves in floating
  point), ``"transient"`` (it moves the residual, but its steady-state (DC) gain is below :data:`ZERO_RTOL` of its
  terms: only the onset of a bias shows, e.g. a sensor bias that looks like a constant unknown input) or
  ``"persistent"`` (a nonzero DC gain; also a fault that drives a mode on or outside the unit circle that the residual
  sees: its effect grows);
* its **smallest detectable size**: the size ``a`` of a step (bias) fault, in the fault's own units, whose steady-state
  residual shift ``a·G(1)`` makes the design's own statistic exceed its own threshold with probability 95 % (and 50 %)
  on a sample in steady state, by the statistic's :class:`SizeLaw` (its detector's: the noncentral χ² law of
  ``J = rᵀ W r`` for a sample, :func:`quadratic_sizes`; a weighted window sum's noncentral quadratic form, its
  stacked covariance from the residual's autocovariances, by the four-moment approximation of Liu, Tang & Zhang,
  Computational Statistics & Data Analysis 53(4), 2009, :func:`window_sizes`; the sequential detectors' own laws).
  The bank's size is the smallest over its statistics;
* the **fault classes**: each fault's signature (the generators that see it persistently, and those that see it at
  all), the groups of faults with equal signatures — the bank cannot tell them apart — with the reason, and the
  classes of the gain file's decision table.

The numbers are computed here from the gain file (generators, evaluators, design model) and, for component faults,
the plant's ``Fx`` — independently of the design's own computations (a direct solve of ``(I − A) x = b`` for the DC
gain, a frequency grid for the peak gain, SciPy's noncentral χ²). The account is stored in the gain file's optional
``account`` block (:func:`fdisyn.synthesis.account.with_account`); :func:`account_lines` renders it as ``fdisyn design``
prints it.

The account is computed on a :class:`BankView` of the diagnoser — its generators, statistics, design model and
decision table — that its kind supplies (:attr:`fdisyn.synthesis.kinds.DiagnoserKind.account_view`): a bank of linear
generators is its own view, a Beard filter is one generator with a window-RMS statistic. Nothing here depends on
which kind it is.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg
import scipy.optimize
import scipy.stats
from fdisyn.runtime.gainfile import GainFile
from fdisyn.runtime.schema import ACCOUNT_EFFECTS, ACCOUNT_FORMAT

__all__ = ["BankView", "SizeLaw", "Sizes", "bank_account", "size_rules", "quadratic_sizes", "window_context",
           "window_sizes", "ncx2_lambda", "size_for", "unaccounted", "account_lines", "default_bank_of", "ZERO_RTOL", "PROBABILITIES",
           "NUMERIC_FAILURES"]

ZERO_RTOL = 1e-8
"""A transfer (peak or DC gain) counts as zero below this fraction of the size of its terms,
``‖C‖·‖(zI − A)⁻¹ b‖ + ‖d‖``. An exact cancellation (a decoupled fault, a bias that looks like a constant unknown
input) computes to round-off of those terms, ~1e-16 times the conditioning of the generator (up to ~1e6 for the
designs fdisyn certifies); a fault that is seen at all is seen at far more than 1e-8 of them. The same rule
separates "reaches" from "cancels" in the design's own signature check."""

PROBABILITIES = (0.95, 0.5)
"""The per-sample detection probabilities of the two smallest sizes (``size``, ``size_50``)."""

NUMERIC_FAILURES = (np.linalg.LinAlgError, ValueError, ZeroDivisionError, OverflowError, FloatingPointError, RuntimeError)
"""Numerical failures of one transfer or law: the account says so for that fault; the design stands."""

_GRID = 257
"""Frequencies ``ω ∈ [0, π]`` of the peak-gain grid: a rational transfer of the orders fdisyn designs (at most a few
hundred states) is nonzero on almost all of them if it is nonzero at all."""
_UNIT_RTOL = 1e-9
"""A mode on or outside the unit circle: ``|λ| ≥ 1 − 1e-9`` (an integrator sampled exactly may come out at 1 − eps)."""
_WINDOW_MAX = 2000
"""Largest ``window · residuals`` of a WSSR statistic whose stacked covariance is formed (dense products of that
order); beyond it the size is not computed (said in the account)."""


# --------------------------------------------------------------------------- transfers
def _stable_part(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """``(A, B, C)`` restricted to the modes that matter: the whole system when ``A`` is Schur stable; otherwise the
    quotient without the modes on or outside the unit circle, when ``C`` does not see them (``C U₁ = 0``, Schur form
    with them first) or ``B`` does not excite them (``U₂ᵀ B = 0``, Schur form with them last). ``None`` when an
    unstable mode is both excited and seen (the output grows without bound)."""
    n = a.shape[0]
    if n == 0:
        return a, b, c
    if float(np.max(np.abs(np.linalg.eigvals(a)))) < 1.0 - _UNIT_RTOL:
        return a, b, c
    outside = lambda re, im: re * re + im * im >= (1.0 - _UNIT_RTOL) ** 2  # noqa: E731
    inside = lambda re, im: re * re + im * im < (1.0 - _UNIT_RTOL) ** 2  # noqa: E731
    t, u, k = scipy.linalg.schur(a, output="real", sort=outside)
    if float(np.linalg.norm(c @ u[:, :k])) <= _UNIT_RTOL * max(float(np.linalg.norm(c)), 1e-300):
        return t[k:, k:], (u.T @ b)[k:], (c @ u)[:, k:]
    t, u, k = scipy.linalg.schur(a, output="real", sort=inside)
    if float(np.linalg.norm((u.T @ b)[k:])) <= _UNIT_RTOL * max(float(np.linalg.norm(b)), 1e-300):
        return t[:k, :k], (u.T @ b)[:k], (c @ u)[:, :k]
    return None


def _gains(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> dict[str, Any]:
    """Peak gain over the frequency grid, DC gain (vector) and the effect class of the transfer ``(a, b, c, d)``
    (one input column ``b``)."""
    part = _stable_part(a, b, c)
    if part is None:
        return {"effect": "persistent", "peak_gain": None, "dc_gain": None, "dc": None}
    a2, b2, c2 = part
    n = a2.shape[0]
    b2, d = b2.reshape(n, 1), d.reshape(-1, 1)
    nc = float(np.linalg.norm(c2, 2)) if c2.size else 0.0
    z = np.exp(1j * np.linspace(0.0, math.pi, _GRID))
    if n:
        x = np.linalg.solve(z[:, None, None] * np.eye(n) - a2, np.broadcast_to(b2, (_GRID, n, 1)))
        g = np.einsum("ij,fjk->fik", c2, x) + d
        peak = float(np.max(np.linalg.norm(g[:, :, 0], axis=1)))
        ref = float(np.max(nc * np.linalg.norm(x[:, :, 0], axis=1))) + float(np.linalg.norm(d))
    else:
        peak = ref = float(np.linalg.norm(d))
    x1 = np.linalg.solve(np.eye(n) - a2, b2) if n else np.zeros((0, 1))
    dc = (c2 @ x1 + d).ravel().real
    ref_dc = nc * float(np.linalg.norm(x1)) + float(np.linalg.norm(d))
    if not peak > ZERO_RTOL * ref:
        effect = "zero"
    elif not float(np.linalg.norm(dc)) > ZERO_RTOL * ref_dc:
        effect = "transient"
    else:
        effect = "persistent"
    return {"effect": effect, "peak_gain": peak, "dc_gain": float(np.linalg.norm(dc)) if effect == "persistent" else 0.0, "dc": dc if effect == "persistent" else None}


def _internal(gen: Any, plant: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """``(A_i, C_i)`` of plant + generator on the state ``[x; ξ]``: ``x⁺ = A x``, ``ξ⁺ = Ar ξ + By C x``,
    ``r = Dy C x + Cr ξ``."""
    a, c = plant["A"], plant["C"]
    n, ns = a.shape[0], gen.n_state
    ai = np.block([[a, np.zeros((n, ns))], [gen.By @ c, gen.Ar]])
    ci = np.hstack([gen.Dy @ c, gen.Cr])
    return ai, ci


def _fault_path(gen: Any, plant: Mapping[str, np.ndarray], kind: str, column: np.ndarray | int) -> tuple[np.ndarray, ...]:
    """``(A, b, C, d)`` from one fault to ``gen``'s residual: a sensor bias ``y + e_j a`` enters the generator alone
    (``Ar, By e_j, Cr, Dy e_j``); a component fault ``x⁺ = … + f a``, ``y = … + g a`` (``column = [f; g]``) the
    internal form (``[f; By g]``, feed-through ``Dy g``)."""
    if kind == "sensor":
        j = int(column)  # type: ignore[arg-type]
        return gen.Ar, gen.By[:, j], gen.Cr, gen.Dy[:, j]
    ai, ci = _internal(gen, plant)
    col = np.asarray(column, dtype=float)
    n = ai.shape[0] - gen.n_state
    f, g = col[:n], (col[n:] if col.size > n else np.zeros(gen.By.shape[1]))
    b = np.concatenate([f, gen.By @ g])
    return ai, b, ci, gen.Dy @ g


# --------------------------------------------------------------------------- sizes
def _ncx2_sf(x: float, dof: float, lam: float) -> float:
    """``P(χ²_dof(λ) > x)``: SciPy's series, or, where that series does not converge (Boost warns; far tails at
    a large ``λ``), the normal law of the same mean ``dof + λ`` and variance ``2(dof + 2λ)``, which the noncentral
    law approaches as ``λ`` grows (Johnson, Kotz & Balakrishnan, Continuous Univariate Distributions 2, 1995,
    ch. 29) — the sizes only need the crossing of ``p`` to a few digits."""
    if lam <= 0:
        return float(scipy.stats.chi2.sf(x, dof))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        value = float(scipy.stats.ncx2.sf(x, dof, lam))
    if caught or not math.isfinite(value):
        value = float(scipy.stats.norm.sf((x - dof - lam) / math.sqrt(2.0 * (dof + 2.0 * lam))))
    return value


def ncx2_lambda(threshold: float, dof: float, p: float) -> float:
    """The noncentrality ``λ`` with ``P(χ²_dof(λ) > threshold) = p``.

    Parameters
    ----------
    threshold : float
        The level.
    dof : float
        Degrees of freedom.
    p : float
        The exceedance probability wanted.

    Returns
    -------
    float
        ``λ ≥ 0`` (0 when the central law already exceeds ``threshold`` with probability ``p``).

    Examples
    --------
    >>> round(ncx2_lambda(3.841458820694124, 1, 0.5), 3)  # χ²(1)'s 95 % point, crossed half the time at λ ≈ 1.96²
    3.841
    """
    sf = lambda lam: _ncx2_sf(threshold, dof, lam)  # noqa: E731
    if sf(0.0) >= p:
        return 0.0
    hi = max(1.0, threshold)
    while sf(hi) < p:
        hi *= 2.0
    return float(scipy.optimize.brentq(lambda lam: sf(lam) - p, 0.0, hi, xtol=1e-12 * hi, rtol=1e-10))


def _ltz_sf(x: float, c: Sequence[float]) -> float:
    """``P(Q > x)`` for a noncentral Gaussian quadratic form from its ``c_k = Σ λ_i^k + k Σ λ_i^k δ_i²``, ``k = 1…4``
    (Liu, Tang & Zhang, Computational Statistics & Data Analysis 53(4), 2009, eqs. (4)–(11))."""
    c1, c2, c3, c4 = c
    s1, s2 = c3 / c2**1.5, c4 / c2**2
    if s1 * s1 > s2:
        a = 1.0 / (s1 - math.sqrt(s1 * s1 - s2))
        delta = max(s1 * a**3 - a * a, 0.0)
        dof = a * a - 2.0 * delta
    else:
        a, delta, dof = 1.0 / s1, 0.0, 1.0 / (s1 * s1)
    t = (x - c1) / math.sqrt(2.0 * c2)
    arg = t * math.sqrt(2.0) * a + dof + delta
    return _ncx2_sf(arg, dof, delta)


def _autocovariances(gen: Any, plant: Mapping[str, np.ndarray], lags: int) -> np.ndarray | None:
    """``R(τ)``, ``τ = 0…lags−1``, of ``gen``'s residual under the design model's noise ``Q``, ``R`` (the internal form
    driven by ``[w; v]``); ``None`` when the residual sees a mode on or outside the unit circle (no stationary law)."""
    ai, ci = _internal(gen, plant)
    n, p = plant["A"].shape[0], plant["C"].shape[0]
    k = np.vstack([np.hstack([np.eye(n), np.zeros((n, p))]), np.hstack([np.zeros((gen.n_state, n)), gen.By])])
    dn = np.hstack([np.zeros((gen.n_residual, n)), gen.Dy])
    w = scipy.linalg.block_diag(plant["Q"], plant["R"])
    part = _stable_part(ai, k, ci)
    if part is None:
        return None
    a, kk, c = part
    if a.shape[0] and float(np.max(np.abs(np.linalg.eigvals(a)))) >= 1.0 - _UNIT_RTOL:
        return None
    pw = scipy.linalg.solve_discrete_lyapunov(a, kk @ w @ kk.T) if a.shape[0] else np.zeros((0, 0))
    out = np.empty((lags, gen.n_residual, gen.n_residual))
    out[0] = c @ pw @ c.T + dn @ w @ dn.T
    cross = pw @ c.T  # E[z(k) r(k)ᵀ] part from the state; plus the feedthrough's K W Dnᵀ one step later
    m = kk @ w @ dn.T
    ak = np.eye(a.shape[0])
    for tau in range(1, lags):
        out[tau] = c @ ak @ (a @ cross + m)
        ak = ak @ a
    return out


def _window_operator(ev: Any, acov: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, list[float], np.ndarray]:
    """``(𝒲𝒮, [tr((𝒲𝒮)^k), k = 1…4], weights)`` of a weighted window sum: ``𝒮`` the stacked covariance of its
    window (block Toeplitz of the residual's autocovariances), ``𝒲 = diag(weights) ⊗ W``."""
    n_w, nr = len(weights), acov.shape[1]
    big = np.empty((n_w * nr, n_w * nr))
    for i in range(n_w):
        for j in range(n_w):
            big[i * nr : (i + 1) * nr, j * nr : (j + 1) * nr] = acov[i - j] if i >= j else acov[j - i].T
    ws = np.kron(np.diag(weights), ev.W) @ big
    t, pk = [], np.eye(n_w * nr)
    for _ in range(4):
        pk = pk @ ws
        t.append(float(np.trace(pk)))
    return ws, t, weights


def _window_moments(g: np.ndarray, ev: Any, op: tuple[np.ndarray, list[float], np.ndarray]) -> tuple[list[float], list[float]]:
    """``(t_k, q_k)``, ``k = 1…4``: ``c_k(a) = t_k + k a² q_k`` are the moments of Liu, Tang & Zhang of the window sum
    ``J`` in steady state under the residual shift ``a·g`` (``q_k = 𝗺ᵀ(𝒲𝒮)^(k−1)𝒲𝗺``, ``𝗺 = 1 ⊗ g``)."""
    ws, t, weights = op
    m = np.tile(g, len(weights))
    q, v = [], np.kron(weights, ev.W @ g)
    for _ in range(4):
        q.append(float(m @ v))
        v = ws @ v
    return t, q


def size_for(prob: Callable[[float], float], p: float) -> float | None:
    """The smallest ``a > 0`` with ``prob(a) ≥ p`` (``prob`` nondecreasing in ``a``), by bracketing then bisection.

    Parameters
    ----------
    prob : callable
        ``prob(a)``: the detection probability of a fault of size ``a``.
    p : float
        The probability wanted.

    Returns
    -------
    float or None
        The size, ``None`` when no size below ``2⁴⁰⁰`` reaches ``p``.

    Examples
    --------
    >>> round(size_for(lambda a: min(a / 10.0, 1.0), 0.5), 9)
    5.0
    """
    lo, hi = 0.0, 1.0
    if prob(hi) < p:
        for _ in range(400):
            lo, hi = hi, hi * 2.0
            if prob(hi) >= p:
                break
        else:
            return None
    else:
        for _ in range(400):
            if prob(hi / 2.0) < p:
                lo = hi / 2.0
                break
            hi /= 2.0
        else:
            return None
    return float(scipy.optimize.brentq(lambda a: prob(a) - p, lo, hi, xtol=1e-12 * hi, rtol=1e-9))


Sizes = tuple[float | None, float | None, str | None]
"""``(size at 95 %, size at 50 %, why not)`` of one statistic for one fault (``None`` sizes with the reason)."""


@dataclass(frozen=True)
class SizeLaw:
    """How the account computes one statistic's smallest detectable size, and how it says so.

    Each detector names its law (:attr:`fdisyn.detectors.table.Detector.size_law`); the account reads the laws of a
    :class:`BankView` and names no detector.

    Attributes
    ----------
    name : str
        The statistic's kind in the account block (its evaluator's ``kind``).
    rule : str
        How its size is defined, one clause for the terminal and the report (e.g. ``"χ²: P(J > threshold) = 95 %
        (50 %) on a sample"``).
    sizes : callable
        ``sizes(ev, g, context) -> (s95, s50, why_not)``: the sizes of a fault whose unit step shifts the residual
        by ``g`` in steady state, the statistic's energy ``gᵀ W g`` already checked positive.
    context : callable or None
        ``context(ev, generator, model)``: what ``sizes`` reads that depends on the statistic alone (computed once
        per statistic, e.g. its window's covariance); ``None``: nothing.
    """

    name: str
    rule: str
    sizes: Callable[[Any, np.ndarray, Any], Sizes]
    context: Callable[[Any, Any, Mapping[str, np.ndarray]], Any] | None = None


def quadratic_sizes(ev: Any, g: np.ndarray, context: Any = None) -> Sizes:
    """The sizes of ``J = rᵀ W r`` against its ``threshold`` on one sample: ``J`` is noncentral χ²(``dof``) with
    noncentrality ``a² gᵀ W g`` (exact when ``W`` whitens the residual on its ``dof`` directions).

    Parameters
    ----------
    ev : Evaluator
        The statistic (``threshold``, ``dof``, ``W``).
    g : numpy.ndarray
        The residual's steady-state shift per unit of fault.
    context : Any
        Unused.

    Returns
    -------
    tuple
        ``(size at 95 %, size at 50 %, None)``.
    """
    energy = float(g @ ev.W @ g)
    sizes = [math.sqrt(ncx2_lambda(float(ev.threshold), int(ev.dof), p) / energy) for p in PROBABILITIES]
    return sizes[0], sizes[1], None


def window_context(ev: Any, gen: Any, model: Mapping[str, np.ndarray], weights: np.ndarray | None = None) -> Any:
    """What :func:`window_sizes` reads of a window sum ``J = Σ_{l<N} w_l r(k−l)ᵀ W r(k−l)``: its window's stacked
    covariance operator, or why there is none (a text).

    Parameters
    ----------
    ev : Evaluator
        The statistic (its ``W``; its ``window`` ``N`` when ``weights`` is not given).
    gen : Generator
        Its residual generator.
    model : Mapping
        The design model with its noise ``Q`` and ``R``.
    weights : numpy.ndarray, optional
        ``w_l``, newest first (its length is the window); default ``N`` ones (the WSSR).

    Returns
    -------
    tuple or str
        ``(𝒲𝒮, traces, weights)`` (see :func:`window_sizes`), or the reason no law is formed.
    """
    w = np.ones(int(ev.window)) if weights is None else np.asarray(weights, dtype=float)
    if len(w) * gen.n_residual > _WINDOW_MAX:
        return f"the window's stacked covariance would be of order {len(w) * gen.n_residual} (> {_WINDOW_MAX})"
    try:
        ac = _autocovariances(gen, model, len(w))
    except NUMERIC_FAILURES:
        ac = None
    if ac is None:
        return "the residual has no stationary law on the design model (a mode on the unit circle)"
    return _window_operator(ev, ac, w)


def window_sizes(ev: Any, g: np.ndarray, context: Any) -> Sizes:
    """The sizes of a window sum ``J = Σ_{l<N} w_l r(k−l)ᵀ W r(k−l)`` against its ``threshold``: the noncentral
    Gaussian quadratic form of the window (its stacked covariance from the residual's autocovariances) by the
    four-moment law of Liu, Tang & Zhang (Computational Statistics & Data Analysis 53(4), 2009).

    Parameters
    ----------
    ev : Evaluator
        The statistic (``threshold``, ``window``, ``W``).
    g : numpy.ndarray
        The residual's steady-state shift per unit of fault.
    context : tuple or str
        :func:`window_context` of the statistic.

    Returns
    -------
    tuple
        ``(size at 95 %, size at 50 %, None)``, or ``(None, None, why)``.
    """
    if isinstance(context, str):
        return None, None, context
    t, q = _window_moments(g, ev, context)
    law = lambda a: _ltz_sf(float(ev.threshold), [t[k] + (k + 1) * a * a * q[k] for k in range(4)])  # noqa: E731
    s95, s50 = (size_for(law, p) for p in PROBABILITIES)
    return s95, s50, None


# --------------------------------------------------------------------------- the account
@dataclass(frozen=True, eq=False)
class BankView:
    """A diagnoser as the account sees it: a bank of linear residual generators, one statistic each, on a model.

    Parameters
    ----------
    generators : sequence of Generator
        The residual generators (canonical form).
    statistics : sequence
        One per statistic: its ``generator`` (index into ``generators``), its weight ``W`` and what its law reads
        (``threshold``, ``dof``, ``window``; a sequential statistic's ``directions`` and ``drift``).
    statistic_names : sequence of str
        The statistics' names, in order.
    laws : sequence of SizeLaw
        Each statistic's law of its smallest detectable size (its detector's
        :attr:`~fdisyn.detectors.table.Detector.size_law`).
    model : Mapping
        The design model: ``A`` and ``C`` (a plant given to the account must have them), the noise ``Q`` and ``R``
        when the gain file holds them (else they are taken from the plant given), and what the transfers read.
    persistence : int
        Consecutive exceedances before a statistic alarms.
    signatures : ndarray or None
        The decision table (faults × statistics, 0/1); None: the diagnoser decides otherwise.
    classes : callable or None
        ``(gf, entries) -> classes block`` for a diagnoser that does not isolate by a signature table (None: the
        classes are the groups of equal signatures and the decision table's).
    default_bank : Mapping or None
        How the bank was built when none was given (:func:`default_bank_of`); None: given, or no bank.
    no_noise : str
        The note when neither the gain file nor the plant gives the noise (no smallest sizes).
    """

    generators: Sequence[Any]
    statistics: Sequence[Any]
    statistic_names: Sequence[str]
    laws: Sequence[SizeLaw]
    model: Mapping[str, np.ndarray]
    persistence: int
    signatures: np.ndarray | None = None
    classes: Callable[[GainFile, Sequence[Mapping[str, Any]]], dict[str, Any]] | None = None
    default_bank: Mapping[str, Any] | None = None
    no_noise: str = "no smallest sizes: the gain file holds no noise model (give its plant)"


def _design_plant(gf: GainFile, view: BankView, plant: Any) -> tuple[Any, str | None]:
    """``plant`` sampled like the gain file's design model (ZOH at ``gf.Ts`` when continuous: exact for a step
    fault, held over the sample) when it is that model (the same ``A`` and ``C``), else ``None`` and why not."""
    if plant is None:
        return None, None
    if getattr(plant, "Ts", None) is None and hasattr(plant, "discretise"):
        plant = plant.discretise(float(gf.Ts))
    model = view.model
    try:
        a, c = np.asarray(plant.A, dtype=float), np.asarray(plant.C, dtype=float)
    except (AttributeError, TypeError, ValueError):
        return None, f"the plant given is a {type(plant).__name__}, not a LinearPlant"
    same = a.shape == model["A"].shape and c.shape == model["C"].shape
    if same:
        same = float(np.linalg.norm(a - model["A"])) <= 1e-8 * max(float(np.linalg.norm(a)), 1e-300) and float(
            np.linalg.norm(c - model["C"])
        ) <= 1e-8 * max(float(np.linalg.norm(c)), 1e-300)
    if not same:
        return None, "the plant given is not the design model of the gain file (other states or sample time)"
    return plant, None


def bank_account(gf: GainFile, view: BankView, plant: Any = None) -> dict[str, Any]:
    """What a diagnoser can see, before any Monte Carlo: each fault's effect, its smallest detectable size, the classes.

    Parameters
    ----------
    gf : GainFile
        The diagnoser (its outputs, faults, sample time and provenance).
    view : BankView
        The diagnoser as a bank of linear generators (its kind's :attr:`~fdisyn.synthesis.kinds.DiagnoserKind.account_view`).
    plant : LinearPlant, optional
        The plant the design was made for (discrete, or continuous: then ZOH-sampled at ``gf.Ts``): its ``Fx`` gives
        the component faults, its ``units`` the faults' units, its ``Q`` and ``R`` the noise when the view has none.
        Without it, the account covers the sensor faults only.

    Returns
    -------
    dict
        The ``account`` block of the gain file (see the gain-file section of ``runtime/REFERENCE.md``): ``faults`` (per fault: ``name``,
        ``type``, ``unit``, ``effect``, ``size``, ``size_50``, ``seen_by`` and per generator ``effect``, ``peak_gain``,
        ``dc_gain``), ``statistics`` (the definition of each statistic's size), ``classes`` (``groups`` of faults the
        bank cannot tell apart with their ``reason``, ``unseen`` faults, the ``decision`` table's classes), ``notes``.

    Raises
    ------
    NUMERIC_FAILURES
        A failure outside one fault's transfer or law (the caller says so in the block: :func:`unaccounted`).
    """
    notes: list[str] = []
    units = dict(getattr(plant, "units", {}) or {})
    comp_names = list(getattr(plant, "component_faults", ()) or ())
    design, why = _design_plant(gf, view, plant)
    if why is not None:
        notes.append(f"component faults {comp_names} not accounted for: {why}" if comp_names else why)
    fx = None
    if design is not None and comp_names:  # a component fault's column of Fx over its column of Df (zero if none)
        fx = np.asarray(design.Fx, dtype=float)
        fx = np.vstack([fx, np.asarray(getattr(design, "Df", np.zeros((np.shape(design.C)[0], fx.shape[1]))), dtype=float)])
    gens: list[Any] = list(view.generators)
    evs: list[Any] = list(view.statistics)
    model = dict(view.model)
    stat_names = list(view.statistic_names)
    persistence = int(view.persistence)
    if "Q" not in model:  # the noise from the plant given
        if design is not None:
            model.update(Q=np.asarray(design.Q, dtype=float), R=np.asarray(design.R, dtype=float))
        else:
            notes.append(view.no_noise)
    faults: list[tuple[str, str, Any]] = [(o, "sensor", j) for j, o in enumerate(gf.outputs)]
    if fx is not None:
        faults += [(c, "component", fx[:, k]) for k, c in enumerate(comp_names)]
    context: dict[int, Any] = {}  # each statistic's law context, computed once
    entries = []
    for name, ftype, col in faults:
        per_gen: dict[str, dict[str, Any]] = {}
        dcs: dict[int, Any] = {}
        try:
            for gi, gen in enumerate(gens):
                gain = _gains(*_fault_path(gen, model, ftype, col))
                dcs[gi] = gain.pop("dc")
                per_gen[gen.name] = gain
        except NUMERIC_FAILURES as exc:  # a transfer that cannot be evaluated: said, never a failed design
            notes.append(f"fault {name}: its transfer to the residuals could not be evaluated ({type(exc).__name__}: {exc})")
            continue
        sizes: list[tuple[float, float | None, str]] = []
        reasons: list[str] = []
        for si, ev in enumerate(evs):
            gi = int(ev.generator)
            if per_gen[gens[gi].name]["effect"] != "persistent":
                continue
            if dcs[gi] is None:
                sizes.append((0.0, 0.0, stat_names[si]))
                reasons.append(f"{stat_names[si]}: its effect grows without bound (any size is detected)")
                continue
            if "Q" not in model:
                continue
            law = view.laws[si]
            if law.context is not None and si not in context:
                context[si] = law.context(ev, gens[gi], model)
            s95: float | None
            s50: float | None
            why_not: str | None
            try:
                if not float(dcs[gi] @ ev.W @ dcs[gi]) > 0:
                    s95, s50, why_not = None, None, "its steady-state shift lies where the statistic has no weight"
                else:
                    s95, s50, why_not = law.sizes(ev, dcs[gi], context.get(si))
            except NUMERIC_FAILURES as exc:
                s95, s50, why_not = None, None, f"its law could not be evaluated ({type(exc).__name__}: {exc})"
            if s95 is None:
                reasons.append(f"{stat_names[si]}: {why_not}")
            else:
                sizes.append((s95, s50, stat_names[si]))
        seen = [g for g, v in per_gen.items() if v["effect"] != "zero"]
        effects = {v["effect"] for v in per_gen.values()}
        effect = "persistent" if "persistent" in effects else ("transient" if "transient" in effects else "zero")
        best = min(sizes, key=lambda s: s[0]) if sizes else None
        s50s = [s[1] for s in sizes if s[1] is not None]
        entries.append(
            {
                "name": name,
                "type": ftype,
                "unit": units.get(name),
                "effect": effect,
                "size": None if best is None else best[0],
                "size_50": min(s50s) if s50s else None,
                "size_by": None if best is None else best[2],
                "seen_by": seen,
                "persistent_in": [g for g, v in per_gen.items() if v["effect"] == "persistent"],
                "generators": per_gen,
                **({"size_notes": reasons} if reasons else {}),
            }
        )
    chosen = view.default_bank
    if chosen is not None:
        notes.insert(0, _bank_note(chosen))
    return {
        "format": ACCOUNT_FORMAT,
        "kind": gf.kind,
        "zero_rtol": ZERO_RTOL,
        "persistence": persistence,
        "statistics": [{"name": stat_names[i], "kind": law.name, "rule": law.rule} for i, law in enumerate(view.laws)],
        "faults": entries,
        "classes": _classes(gf, view, entries),
        "notes": notes,
    }


def _classes(gf: GainFile, view: BankView, entries: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Groups of faults with equal signatures (persistent generators, generators that see them at all), with why."""
    if view.classes is not None:
        return view.classes(gf, entries)
    chosen = view.default_bank
    left_out = {str(d["sensor"]): str(d["reason"]) for key in ("left_out", "narrowed") for d in (chosen or {}).get(key, [])}
    groups: dict[tuple[tuple[str, ...], tuple[str, ...]], list[str]] = {}
    unseen = []
    for e in entries:
        if not e["seen_by"]:
            unseen.append(e["name"])
            continue
        groups.setdefault((tuple(e["persistent_in"]), tuple(e["seen_by"])), []).append(e["name"])
    merged = []
    for (pers, seen), names in groups.items():
        if len(names) < 2:
            continue
        quoted = _quoted(names)
        if pers and tuple(pers) == tuple(seen):
            why = f"{quoted}: all seen persistently by the same generators ({', '.join(pers)})"
        elif pers:
            why = f"{quoted}: all seen persistently by {', '.join(pers)} and transiently by the same others"
        else:
            why = f"{quoted}: all seen only transiently, by the same generators ({', '.join(seen)})"
        missing = [left_out[n] for n in names if n in left_out]
        if missing:  # a sensor without its generator in a bank built by default: why it merges
            why += "; " + "; ".join(missing)
        merged.append({"faults": names, "reason": why})
    decision = []
    if view.signatures is not None:
        for f, row in zip(gf.faults, np.asarray(view.signatures, dtype=int), strict=True):
            decision.append({"name": f, "statistics": [gf.step.statistic_names[j] for j in np.flatnonzero(row)]})
    else:
        decision = [{"name": f, "statistics": []} for f in gf.faults]
    out: dict[str, Any] = {"groups": merged, "unseen": unseen, "decision": decision}
    if chosen is not None:
        # a bank built by default: a decision class merged from look-alikes (the same statistics read them) is said too
        # when the effects above tell its faults apart (one seen persistently, another at its onset only)
        known = {e["name"] for e in entries}
        for f in gf.faults:
            parts = [n for n in f.split("|") if n in known]
            if len(parts) < 2 or any(sorted(g["faults"]) == sorted(parts) for g in merged):
                continue
            why = f"{_quoted(parts)}: the same statistics read them, so the decision table names them together ('{f}')"
            missing = [left_out[n] for n in parts if n in left_out]
            merged.append({"faults": parts, "reason": why + "".join(f"; {m}" for m in missing)})
        out["bank"] = dict(chosen)
    return out


def _quoted(names: Sequence[str]) -> str:
    return " and ".join(f"'{n}'" for n in names) if len(names) == 2 else ", ".join(f"'{n}'" for n in names)


def default_bank_of(gf: GainFile) -> dict[str, Any] | None:
    """How a linear method built the bank of ``gf`` when none was given (the provenance's ``bank``, written by
    :func:`fdisyn.synthesis.linear_diagnoser.default_bank`): ``rule``, ``generators``, ``left_out`` and ``narrowed``
    (``sensor``, ``outputs``, ``reason``) and ``all_outputs`` (``kept``, ``why``); ``None`` for a bank that was given.

    Parameters
    ----------
    gf : GainFile
        A linear diagnoser.

    Returns
    -------
    dict or None
        The provenance's ``bank`` with its lists checked, or ``None``.
    """
    chosen = gf.provenance.get("bank") if isinstance(gf.provenance, Mapping) else None
    if not isinstance(chosen, Mapping):
        return None
    listed = lambda v: [d for d in v if isinstance(d, Mapping) and "sensor" in d and "reason" in d] if isinstance(v, list) else []  # noqa: E731
    return {**chosen, "left_out": listed(chosen.get("left_out")), "narrowed": listed(chosen.get("narrowed"))}


def _bank_note(chosen: Mapping[str, Any]) -> str:
    """The account's note on a bank built by default: its rule and generators, the sensors without one and why,
    and whether the generator on all outputs is in it."""
    text = f"no bank given: {chosen.get('rule', 'built by default')}: {', '.join(map(str, chosen.get('generators', [])))}"
    text += "".join(f"; {d['reason']}" for key in ("left_out", "narrowed") for d in chosen.get(key, []))
    whole = chosen.get("all_outputs")
    if isinstance(whole, Mapping) and whole.get("why"):
        text += f"; the generator on all outputs {'is in the bank' if whole.get('kept') else 'is not in the bank'}: {whole['why']}"
    return text


def unaccounted(gf: GainFile, exc: BaseException) -> dict[str, Any]:
    """The ``account`` block of a diagnoser whose account failed numerically: empty, with the failure as its note
    (informational: a design that passed its certificate is not refused for its account).

    Parameters
    ----------
    gf : GainFile
        The diagnoser.
    exc : BaseException
        The failure (one of :data:`NUMERIC_FAILURES`).

    Returns
    -------
    dict
        An ``account`` block without faults or statistics.
    """
    return {"format": ACCOUNT_FORMAT, "kind": gf.kind, "zero_rtol": ZERO_RTOL, "statistics": [], "faults": [],
            "classes": {"groups": [], "unseen": [], "decision": []},
            "notes": [f"not computed: {type(exc).__name__}: {exc}"]}  # fmt: skip


def _unit(e: Mapping[str, Any]) -> str:
    return str(e["unit"]) if e.get("unit") else f"in the units of {e['name']}"


def size_rules(account: Mapping[str, Any]) -> str:
    """How the account's smallest sizes are defined, one clause per law of its statistics (``"; "``-separated, in
    the order the statistics first use them).

    Parameters
    ----------
    account : Mapping
        A gain file's ``account`` block.

    Returns
    -------
    str
        The clauses; a statistic of a file written before the rules were stored is named by its kind.
    """
    return "; ".join(dict.fromkeys(str(st.get("rule") or st["kind"]) for st in account["statistics"]))


def account_lines(account: Mapping[str, Any] | None, not_computed: str | None = None) -> list[str]:
    """The account as ``fdisyn design`` prints it: a table (fault, effect, smallest size with its unit, the
    generators that see it) and the classes that merge.

    Parameters
    ----------
    account : Mapping or None
        A gain file's ``account`` block; ``None``: the kind is not covered (the line says why).
    not_computed : str, optional
        Why the account is not computed for the diagnoser's kind
        (:attr:`~fdisyn.synthesis.kinds.DiagnoserKind.account_note`), for a ``None`` account.

    Returns
    -------
    list of str
        Lines without trailing newlines.
    """
    if account is None:
        return [f"what the design can see: not computed — {not_computed or 'not a linear diagnoser'}"]
    out = ["what the design can see (a step fault in steady state; smallest size: " + size_rules(account) + "):"]
    rows = [("fault", "effect", "smallest size (95 %)", "50 %", "seen by")]
    for e in account["faults"]:
        size = "—" if e["size"] is None else f"{e['size']:.3g} ({_unit(e)})"
        half = "—" if e.get("size_50") is None else f"{e['size_50']:.3g}"
        if e["effect"] == "transient":
            size, half = "none at steady state", "—"
        elif e["effect"] == "zero":
            size, half = "undetectable", "—"
        seen = e["seen_by"]
        by = ", ".join(seen) if len(seen) <= 3 else f"{len(seen)} generators ({', '.join(seen[:2])}, …)"
        rows.append((f"{e['name']} ({e['type']})", e["effect"], size, half, by or "no generator"))
    widths = [max(len(r[i]) for r in rows) for i in range(4)]
    out += ["  " + "  ".join(r[i].ljust(widths[i]) for i in range(4)) + "  " + r[4] for r in rows]
    groups = account["classes"]["groups"]
    if groups:
        out.append("faults the bank cannot tell apart:")
        out += [f"  {g['reason']}" for g in groups]
    else:
        out.append("faults the bank cannot tell apart: none (every seen fault has its own signature)")
    decision = account["classes"].get("decision", [])
    if any(c["statistics"] for c in decision):  # a signature table: the statistics that isolate each class
        out.append("the decision table isolates: " + ", ".join(f"'{c['name']}'" for c in decision))
        effect = {e["name"]: e["effect"] for e in account["faults"]}
        onset = [c["name"] for c in decision if c["name"] in effect and effect[c["name"]] != "persistent"]
        if onset:
            out.append(
                "  of them seen at the onset only (no steady-state effect): " + ", ".join(f"'{n}'" for n in onset)
                + " — a lasting bias there is alarmed, if at all, only while its transient lasts"
            )
    if account["classes"]["unseen"]:
        out.append(f"faults no generator sees: {', '.join(account['classes']['unseen'])}")
    out += [f"note: {n}" for n in account.get("notes", [])]
    return out
