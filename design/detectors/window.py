"""The laws of the windowed residual statistics of a linear residual generator under Gaussian noise.

A residual generator ``e(k+1) = G e(k) + K n(k)``, ``ε(k) = C e(k) + Dn n(k)`` driven by white Gaussian
``n ~ N(0, W)`` with a stable ``G`` has a stationary Gaussian residual whose autocovariance
``R(τ) = E[ε(k+τ) ε(k)ᵀ]`` is :func:`residual_autocovariance` (the Beard filter's case:
:func:`beard_residual_autocovariance`). Over a window of ``N`` samples the Beard filter (Beard, MIT thesis,
1971; He, Zhang & Wu, Journal of Astronautics, c. 1999) tests two statistics,

* the window RMS ``s = sqrt((1/N) Σ_{j<N} ‖ε(k−j)‖²)`` against the magnitude threshold ``h``
  (:func:`window_rms_threshold`), and
* the norm of the window mean ``m = (1/N) Σ_{j<N} ε(k−j)`` against the explicit level ``ε̄``
  (:func:`window_mean_level`).

Both squares are Gaussian quadratic forms ``Σ λ_i χ²_1`` (independent ``χ²_1``; ``λ_i`` the eigenvalues of the
covariance of the stacked window, respectively of ``m``), so each threshold is the ``1 − P_f`` quantile of such
a form (:func:`quadratic_form_quantile`): Imhof's inversion of the characteristic function (Imhof, Biometrika
48(3/4), 1961, eq. (3.2)), with the four-moment χ² approximation of Liu, Tang & Zhang (Computational Statistics
& Data Analysis 53(4), 2009) only where that integral cannot be evaluated.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import scipy.integrate
import scipy.linalg
import scipy.optimize
import scipy.stats
from fdisyn.numerics.linalg import as_covariance, as_matrix, as_square, dlyap, real_array, spectral_radius
from fdisyn.runtime.errors import ArgumentError, ExistenceError, ShapeError
from fdisyn.runtime.names import shown
from fdisyn.runtime.values import real_number

__all__ = [
    "residual_autocovariance",
    "beard_residual_autocovariance",
    "quadratic_form_sf",
    "quadratic_form_quantile",
    "window_energy_quantile",
    "window_rms_threshold",
    "window_mean_level",
    "QUANTILE_RTOL",
    "MAX_WINDOW_SIZE",
]

QUANTILE_RTOL = 1e-6
"""Relative accuracy of :func:`quadratic_form_quantile` for ``1e-8 ≤ P_f < 1``, as tested against exact laws
(χ² of equal weights, the hypoexponential law of weights in pairs, the conditional one-dimensional integral of
two weights). The error observed there is at most about ``1e-8``: the survival function comes out of Imhof's
integral to a few units of round-off of ``1/2`` (5e-17), i.e. to a relative ``1e-8`` at ``P_f = 1e-8``, and
the quantile moves less than the probability in relative terms (``x f(x) / P(Q > x) > 1`` in the tail)."""

MAX_WINDOW_SIZE = 8192
"""Largest ``N·p`` (the order of the window covariance) accepted. The eigenvalues of the ``N p × N p`` matrix
(``scipy.linalg.eigvalsh``) took 0.5 s at 2000 on this project's two-core machine when idle (4 to 14 s under
the load of parallel test runs) and grow as the cube; 8192 is one to several minutes and 0.5 GB."""

_PSD_RTOL = 1e-10
"""Eigenvalues of a covariance down to ``−_PSD_RTOL`` times the largest are round-off (set to zero); more
negative ones mean the input is not a covariance. An eigenvalue solve of order ``n`` is backward stable to
about ``n·eps`` of the largest eigenvalue, 4.5e-13 at ``n = 2048``."""

_EQUAL_RTOL = 1e-10
"""Where the χ² bounds ``max_k λ_(k) χ²_k ≤ Q ≤ λ_max χ²_n`` pin the quantile to this relative width — one
weight, or all equal to round-off — their midpoint is the quantile (the exact scaled χ²)."""

_IMHOF_ACCEPT = 1e-5
"""An evaluation of Imhof's integral is accepted by :func:`quadratic_form_quantile` when QUADPACK's error
estimate is below this fraction of ``P_f`` (:func:`_imhof`). The estimates do not go below about 1e-14 absolute
(1.2e-6 to 1.8e-6 of ``P_f = 1e-8`` where the actual error was 1e-8 of it), hence not 1e-6; a looser 1e-3 let an
evaluation 6.4e-5 off ``P_f = 0.2`` through (weights ``1`` and nine below 1e-2), and the quantile by as much."""

_SF_ABSTOL = 1e-12
"""The same acceptance for :func:`quadratic_form_sf`, absolute."""

_STRETCHES = (1.0, 1.37, 2.0)
"""Where QAWF's tail integral starts, relative to its first choice (:func:`_imhof_sf`), tried in turn. Its
extrapolation reported 8e3 times ``P_f`` as error for the weights ``(1, 1e-6)`` at ``P_f = 1e-8`` (the envelope
changes its power law at ``u = 1e6``) where the value was right to 2e-8; started 1.37 times later, the estimate
was 1.3e-6 of ``P_f``."""


def residual_autocovariance(G: object, K: object, C: object, Dn: object, W: object, lags: object) -> np.ndarray:
    """``R(τ) = E[ε(k+τ) ε(k)ᵀ]``, ``τ = 0..lags``, of the stationary residual of a stable linear generator.

    ``e(k+1) = G e(k) + K n(k)``, ``ε(k) = C e(k) + Dn n(k)``, ``n`` white Gaussian ``N(0, W)``. With
    ``Σ = G Σ Gᵀ + K W Kᵀ`` (the stationary covariance of ``e``, :func:`fdisyn.numerics.linalg.dlyap`) and ``e(k)``
    independent of ``n(k), n(k+1), …``:

        R(0) = C Σ Cᵀ + Dn W Dnᵀ,
        R(τ) = C G^τ Σ Cᵀ + C G^{τ−1} K W Dnᵀ      (τ ≥ 1),

    computed as ``R(τ) = C P(τ)``, ``P(1) = G Σ Cᵀ + K W Dnᵀ``, ``P(τ+1) = G P(τ)``. ``R(−τ) = R(τ)ᵀ``.
    Returns an array of shape ``(lags + 1, p, p)``. Raises :class:`ShapeError` for inconsistent shapes,
    :class:`ArgumentError` for non-finite entries, a ``W`` that is not a covariance or a bad ``lags``, and
    :class:`ExistenceError` when ``G`` is not stable (spectral radius ≥ 1: no stationary law).
    """
    g = as_square(G, "G")
    n = g.shape[0]
    k = as_matrix(K, "K", rows=n)
    q = k.shape[1]
    c = as_matrix(C, "C", cols=n)
    p = c.shape[0]
    dn = as_matrix(Dn, "Dn", rows=p, cols=q)
    w = as_covariance(W, "W", q)
    count = _whole(lags, "lags", 0)
    radius = spectral_radius(g)
    if not radius < 1.0:
        raise ExistenceError(f"G has spectral radius {radius:.12g} ≥ 1: the residual has no stationary law")
    sigma = dlyap(g, k @ w @ k.T)
    out = np.empty((count + 1, p, p))
    r0 = c @ sigma @ c.T + dn @ w @ dn.T
    out[0] = 0.5 * (r0 + r0.T)
    cross = g @ sigma @ c.T + k @ w @ dn.T  # P(1) = E[e(k+1) ε(k)ᵀ]
    for tau in range(1, count + 1):
        out[tau] = c @ cross
        cross = g @ cross
    return out


def beard_residual_autocovariance(A: object, C: object, L: object, Q: object, R: object, lags: object) -> np.ndarray:
    """:func:`residual_autocovariance` of the Beard filter ``x̂⁺ = A x̂ + B u + L (y − C x̂)`` (and ``− D u``).

    The plant ``x⁺ = A x + B u + w``, ``y = C x + D u + v`` with process noise ``w ~ N(0, Q)`` and measurement
    noise ``v ~ N(0, R)``, independent and white: the error ``e = x − x̂`` and the residual ``ε = y − C x̂ − D u``
    obey ``e⁺ = (A − L C) e + w − L v``, ``ε = C e + v``, i.e. ``G = A − L C``, ``n = [w; v]``,
    ``K = [I, −L]``, ``Dn = [0, I]``, ``W = blkdiag(Q, R)``. ``Q`` and ``R`` may be a number (times ``I``), a
    vector (the diagonal) or a matrix (:func:`fdisyn.numerics.linalg.as_covariance`).
    """
    a = as_square(A, "A")
    n = a.shape[0]
    c = as_matrix(C, "C", cols=n)
    p = c.shape[0]
    gain = as_matrix(L, "L", rows=n, cols=p)
    q = as_covariance(Q, "Q", n)
    r = as_covariance(R, "R", p)
    k = np.hstack([np.eye(n), -gain])
    dn = np.hstack([np.zeros((p, n)), np.eye(p)])
    w = scipy.linalg.block_diag(q, r)
    return residual_autocovariance(a - gain @ c, k, c, dn, w, lags)


def quadratic_form_sf(x: object, eigenvalues: object) -> float:
    """``P(Q > x)`` for ``Q = Σ λ_i χ²_1`` (independent ``χ²_1``, ``λ_i ≥ 0``) by Imhof's inversion formula.

    Imhof (Biometrika 48(3/4), 1961, eq. (3.2)) for central ``χ²_1`` terms:

        P(Q > x) = 1/2 + (1/π) ∫_0^∞ sin θ(u) / (u ρ(u)) du,
        θ(u) = (1/2) Σ arctan(λ_i u) − x u / 2,   ρ(u) = Π (1 + λ_i² u²)^{1/4},

    with the weights scaled to a largest of one (``Q/λ_max``) and the integral evaluated by QUADPACK
    (``scipy.integrate.quad``) as :func:`_imhof_sf` describes. Accurate to a few units of round-off of 1/2
    (absolute; see :data:`QUANTILE_RTOL`); an evaluation whose error estimate exceeds 1e-12 raises
    :class:`ExistenceError` (seen only for ``x`` below about 1e-9 of the largest weight, where ``P(Q > x)`` is
    1 to that accuracy). Equal weights (to 1e-10) are the scaled χ² (``scipy.stats.chi2``). Zero weights are left
    out; no weight at all gives the point mass at 0. Raises
    :class:`ArgumentError` for a non-finite ``x`` and for non-finite or negative weights.
    """
    lam = _weights(eigenvalues)
    t = real_number(x)
    if t is None or not math.isfinite(t):
        raise ArgumentError(f"x must be a finite number; got {shown(x)}")
    if t <= 0.0 or lam.size == 0:  # Q > 0 almost surely unless every weight is zero
        return 1.0 if t < 0.0 or lam.size else 0.0
    if lam[-1] - lam[0] <= _EQUAL_RTOL * lam[-1]:  # equal weights: the scaled χ²
        return float(scipy.stats.chi2.sf(t / float(np.mean(lam)), lam.size))
    try:
        return min(1.0, max(0.0, _imhof(t / lam[-1], lam / lam[-1], _SF_ABSTOL)))
    except _ImhofFailure:
        raise ExistenceError(f"Imhof's integral could not be evaluated to {_SF_ABSTOL:g} at x = {t!r}") from None


def quadratic_form_quantile(eigenvalues: object, P_f: object) -> float:
    """The ``1 − P_f`` quantile ``x`` of ``Q = Σ λ_i χ²_1`` (``P(Q > x) = P_f``; ``λ_i ≥ 0``).

    Bracketed by ``max_k λ_(k) χ²_k(1 − P_f) ≤ x ≤ λ_max χ²_n(1 − P_f)`` (``λ_(1) ≥ λ_(2) ≥ …``; ``Q`` dominates
    ``λ_(k)`` times a ``χ²_k`` and is dominated by ``λ_max`` times a ``χ²_n``). Where these bounds coincide to
    1e-10 relative — a single non-zero weight, or all equal (the exact scaled χ²) — their midpoint is returned.
    Otherwise Brent's method finds the root of ``P(Q > x) − P_f`` inside the bracket with Imhof's
    :func:`quadratic_form_sf` (Imhof, Biometrika 48(3/4), 1961, eq. (3.2)); the result is accurate to
    :data:`QUANTILE_RTOL` relative for ``P_f`` down to 1e-8, a single dominating weight included.

    Fallback: only when Imhof's integral cannot be evaluated (no evaluation with a finite probability and a
    QUADPACK error estimate below 1e-5 of ``P_f``, :data:`_STRETCHES`) the quantile of Liu, Tang & Zhang's
    (Computational Statistics & Data Analysis 53(4), 2009) χ² approximation is returned, with a
    ``RuntimeWarning``: ``Q ≈ μ_Q + σ_Q (χ²_l − l)/√(2 l)``,
    ``c_k = Σ λ_i^k``, ``μ_Q = c_1``, ``σ_Q = √(2 c_2)``, ``l = c_2³/c_3²`` — their moment match with zero
    non-centrality, the branch a central form always takes (``s_1² = c_3²/c_2³ ≤ c_4/c_2² = s_2`` by
    Cauchy–Schwarz). It matches mean, variance and skewness only and is not accurate to :data:`QUANTILE_RTOL` in
    the far tail.

    Raises :class:`ArgumentError` for non-finite or negative weights (below −1e-10 of the largest: not round-off)
    and for ``P_f`` outside (0, 1). All weights zero: 0.
    """
    lam = _weights(eigenvalues)
    p_f = _probability(P_f)
    if lam.size == 0:
        return 0.0
    top = float(lam[-1])
    lam = lam / top
    desc = lam[::-1]
    lo = float(np.max(desc * scipy.stats.chi2.isf(p_f, np.arange(1, lam.size + 1))))
    hi = float(scipy.stats.chi2.isf(p_f, lam.size))
    if hi - lo <= _EQUAL_RTOL * hi:
        return top * 0.5 * (lo + hi)
    seen: dict[float, float] = {}  # brentq evaluates the ends of its bracket again

    def excess(x: float) -> float:
        if x not in seen:
            seen[x] = _imhof(x, lam, _IMHOF_ACCEPT * p_f)
        return seen[x] - p_f

    # The bounds widened by 1e-6 so that round-off of P(Q > x) (~1e-16) cannot flip the signs at them: 1e-6 of x
    # moves it by more than 1e-6 · P_f in the tail. The search starts around Liu, Tang & Zhang's value (within
    # about 1 % of the quantile where measured) and widens geometrically until it brackets the root.
    a, b = lo * (1.0 - 1e-6), hi * (1.0 + 1e-6)
    guess = min(max(_liu_tang_zhang_quantile(lam, p_f), a), b)
    try:
        width = 1.01
        x0, x1 = max(a, guess / width), min(b, guess * width)
        f0, f1 = excess(x0), excess(x1)
        while f0 < 0.0 or f1 > 0.0:
            if (f0 < 0.0 and x0 <= a) or (f1 > 0.0 and x1 >= b):
                raise _ImhofFailure
            width *= width
            if f0 < 0.0:
                x1, f1 = x0, f0
                x0 = max(a, x0 / width)
                f0 = excess(x0)
            else:
                x0, f0 = x1, f1
                x1 = min(b, x1 * width)
                f1 = excess(x1)
        x = float(scipy.optimize.brentq(excess, x0, x1, xtol=1e-300, rtol=1e-10, maxiter=200))
    except (_ImhofFailure, RuntimeError):  # brentq's non-convergence is a RuntimeError
        warnings.warn(
            f"Imhof's integral could not be evaluated for {lam.size} weights at P_f = {p_f:g}; "
            "the quantile is Liu, Tang & Zhang's (2009) χ² approximation",
            RuntimeWarning,
            stacklevel=2,
        )
        x = _liu_tang_zhang_quantile(lam, p_f)
    return top * x


def window_energy_quantile(R_list: object, window: object, P_f: object, weights: object = None) -> float:
    """The ``1 − P_f`` quantile of the window energy ``Σ_{j<N} ‖ε(k−j)‖²`` at stationarity.

    ``R_list`` holds ``R(0), R(1), …`` (``R(τ) = E[ε(k+τ) ε(k)ᵀ]``, ``p × p``; at least ``N = window`` of
    them, e.g. :func:`residual_autocovariance` with ``lags ≥ N − 1``). The stacked window
    ``E = [ε(k); ε(k−1); …; ε(k−N+1)]`` has the block-Toeplitz covariance ``Σ_E`` with blocks
    ``E[ε(k−i) ε(k−j)ᵀ] = R(j − i)`` (``R(−τ) = R(τ)ᵀ``), so ``‖E‖² = Σ μ_l χ²_1`` over the ``N p``
    eigenvalues ``μ_l`` of ``Σ_E`` (``scipy.linalg.eigvalsh``: 0.5 s at ``N p = 2000`` on an idle core, the
    quantile about as long again; at most :data:`MAX_WINDOW_SIZE`), and the quantile is
    :func:`quadratic_form_quantile`'s. A weighted sum ``Σ ε(k−j)ᵀ W ε(k−j)`` is the energy of ``T ε`` for any
    ``T`` with ``Tᵀ T = W`` (autocovariance ``T R(τ) Tᵀ``). Raises :class:`ExistenceError` when the residual
    has zero covariance (the energy is ≡ 0: no threshold).
    """
    r, n = _autocovariances(R_list, window)
    p = r.shape[1]
    # blocks[i, j] = R(j − i): index j − i + N − 1 into [R(−(N−1)) … R(−1), R(0), R(1) … R(N−1)]
    both = np.concatenate([np.transpose(r[:0:-1], (0, 2, 1)), r])
    idx = np.arange(n)[None, :] - np.arange(n)[:, None] + n - 1
    cov = np.transpose(both[idx], (0, 2, 1, 3)).reshape(n * p, n * p)
    if weights is not None:
        w = real_array(weights, "weights")
        if w.shape != (n,) or not np.all(w >= 0) or not np.any(w > 0):
            raise ArgumentError(f"weights must be {n} non-negative numbers, one per sample of the window, not all zero; got shape {w.shape}")
        d = np.repeat(np.sqrt(w), p)
        cov = d[:, None] * cov * d[None, :]
    mu = _covariance_eigenvalues(0.5 * (cov + cov.T), "the window covariance of R_list")
    return quadratic_form_quantile(mu, P_f)


def window_rms_threshold(R_list: object, window: object, P_f: object) -> float:
    """``h``: the ``1 − P_f`` quantile of the window RMS ``s = sqrt((1/N) Σ_{j<N} ‖ε(k−j)‖²)`` at stationarity.

    ``N s²`` is the window energy, so ``h = sqrt(x / N)`` with ``x`` :func:`window_energy_quantile` (``R_list``
    and the errors as there).
    """
    x = window_energy_quantile(R_list, window, P_f)
    return math.sqrt(x / _whole(window, "window", 1))


def window_mean_level(R_list: object, window: object, P_f: object) -> float:
    """``ε̄``: the ``1 − P_f`` quantile of ``‖m‖``, ``m = (1/N) Σ_{j<N} ε(k−j)``, at stationarity.

    ``Σ_m = (1/N²) Σ_{i,j<N} R(i − j) = (1/N²) [N R(0) + Σ_{τ=1}^{N−1} (N − τ)(R(τ) + R(τ)ᵀ)]``, so
    ``‖m‖² = Σ ν_l χ²_1`` over its ``p`` eigenvalues and ``ε̄ = sqrt(x)`` with ``x``
    :func:`quadratic_form_quantile`. ``R_list`` as for :func:`window_rms_threshold`. Raises
    :class:`ExistenceError` when ``m`` has zero covariance.
    """
    r, n = _autocovariances(R_list, window)
    weights = (n - np.arange(1, n)).astype(float)
    tail = np.tensordot(weights, r[1:n], axes=1) if n > 1 else np.zeros_like(r[0])
    cov = (n * r[0] + tail + tail.T) / float(n) ** 2
    nu = _covariance_eigenvalues(0.5 * (cov + cov.T), "the covariance of the window mean of R_list")
    return math.sqrt(quadratic_form_quantile(nu, P_f))


class _ImhofFailure(Exception):
    """Imhof's integral was not evaluated to the accuracy the quantile needs."""


def _imhof(x: float, lam: np.ndarray, tol: float) -> float:
    """:func:`_imhof_sf` from the first of :data:`_STRETCHES` whose value is a probability (to 1e-3) and whose
    error estimate is at most ``tol``; :class:`_ImhofFailure` when none is."""
    for stretch in _STRETCHES:
        value, error = _imhof_sf(x, lam, stretch)
        if math.isfinite(value) and -1e-3 <= value <= 1.0 + 1e-3 and error <= tol:
            return value
    raise _ImhofFailure


def _imhof_sf(x: float, lam: np.ndarray, stretch: float = 1.0) -> tuple[float, float]:
    """Imhof's ``P(Q > x)`` and the summed QUADPACK error estimates, for positive weights ``lam`` (largest 1).

    ``θ(u) = φ(u) − ω u`` with ``φ(u) = (1/2) Σ arctan(λ_i u)``, ``ω = x/2``; the amplitude ``1/(u ρ(u))``.

    * The tail beyond ``U`` is dropped where it is below 1e-17 (a fifth of the round-off of 1/2): ``log(1 + λ²u²)``
      is convex in ``log u``, so ``ρ(u) ≥ ρ(U) (u/U)^{D/4}`` with ``D = Σ 2λ_i²U²/(1 + λ_i²U²)`` and
      ``∫_U^∞ du/(u ρ) ≤ 4/(D ρ(U))``; ``U`` is the least power of two (up to 2^60) meeting that.
    * From ``a`` on, where ``φ′(u) ≤ ω/8`` (``φ′`` decreases), ``sin θ = sin φ cos ωu − cos φ sin ωu`` has envelopes
      ``sin φ/(u ρ)`` and ``cos φ/(u ρ)`` that vary eight times slower than the carrier: QUADPACK's QAWF
      (``quad(weight='cos'/'sin', b=inf)``), whose extrapolation over the cycles copes with the slow ``u^{−3/2}``
      decay of a single dominating weight — used only when the tail is not negligible at ``a``.
    * ``[0, min(a, U)]`` by adaptive Gauss–Kronrod on pieces of two periods ``2π/ω`` each (at most 4000 pieces).
    """
    omega = 0.5 * x
    total_weight = float(np.sum(lam))

    def phase_amplitude(u: float) -> tuple[float, float]:
        lu = lam * u
        return 0.5 * float(np.sum(np.arctan(lu))), math.exp(-0.25 * float(np.sum(np.log1p(lu * lu)))) / u

    def whole(u: float) -> float:
        if u == 0.0:  # the limit u → 0 of sin θ(u) / (u ρ(u))
            return 0.5 * (total_weight - x)
        phi, amp = phase_amplitude(u)
        return math.sin(phi - omega * u) * amp

    def sin_phi(u: float) -> float:
        phi, amp = phase_amplitude(u)
        return math.sin(phi) * amp

    def cos_phi(u: float) -> float:
        phi, amp = phase_amplitude(u)
        return math.cos(phi) * amp

    def tail_bound(u: float) -> float:
        lu2 = (lam * u) ** 2
        d = float(np.sum(2.0 * lu2 / (1.0 + lu2)))
        return 4.0 * math.exp(-0.25 * float(np.sum(np.log1p(lu2)))) / d

    def phase_rate(u: float) -> float:
        return 0.5 * float(np.sum(lam / (1.0 + (lam * u) ** 2)))

    cut = 2.0**-30
    while cut < 2.0**60 and tail_bound(cut) > 1e-17 * math.pi:
        cut *= 2.0
    # a: the least u with φ′(u) ≤ ω/8 (φ′ ≤ Σλ/2 and decreases from there), and beyond 4/‖λ‖₂, the scale on
    # which the amplitude decays (QAWF's error estimates were 1e-7 where it started at an amplitude near 4)
    lo_u, hi_u = 0.0, 1.0
    while phase_rate(hi_u) > omega / 8.0 and hi_u < 2.0**60:
        lo_u, hi_u = hi_u, 2.0 * hi_u
    for _ in range(60):
        mid = 0.5 * (lo_u + hi_u)
        lo_u, hi_u = (mid, hi_u) if phase_rate(mid) > omega / 8.0 else (lo_u, mid)
    a = stretch * max(hi_u, 4.0 / math.sqrt(float(np.sum(lam * lam))))
    end = min(a, cut)
    pieces = int(min(4000, max(1, math.ceil(end * omega / (4.0 * math.pi)))))
    edges = np.linspace(0.0, end, pieces + 1)
    total, error = 0.0, 0.0
    with warnings.catch_warnings():
        # QUADPACK warns that 1e-16 absolute is beyond round-off; its error estimate is used instead
        warnings.simplefilter("ignore", scipy.integrate.IntegrationWarning)
        for u0, u1 in zip(edges[:-1], edges[1:], strict=True):
            value, err = scipy.integrate.quad(whole, float(u0), float(u1), epsabs=1e-16 / pieces, epsrel=1e-13, limit=200)
            total += value
            error += err
        if cut > a:
            for sign, f, weight in ((1.0, sin_phi, "cos"), (-1.0, cos_phi, "sin")):
                value, err = scipy.integrate.quad(f, a, np.inf, weight=weight, wvar=omega, epsabs=1e-16, limlst=200, limit=500)
                total += sign * value
                error += err
    return 0.5 + total / math.pi, error / math.pi


def _liu_tang_zhang_quantile(lam: np.ndarray, p_f: float) -> float:
    """The ``1 − p_f`` quantile of Liu, Tang & Zhang's (2009) central χ² approximation (:func:`quadratic_form_quantile`)."""
    c1, c2, c3 = (float(np.sum(lam**j)) for j in (1, 2, 3))
    dof = c2**3 / c3**2
    return c1 + math.sqrt(2.0 * c2) * (float(scipy.stats.chi2.isf(p_f, dof)) - dof) / math.sqrt(2.0 * dof)


def _weights(eigenvalues: object) -> np.ndarray:
    """The non-zero weights, ascending; round-off negatives (:data:`_PSD_RTOL`) are zero."""
    lam = real_array(eigenvalues, "eigenvalues").reshape(-1)
    if not np.all(np.isfinite(lam)):
        raise ArgumentError(f"eigenvalues must be finite; found {lam[~np.isfinite(lam)][0]!r}")
    top = float(np.max(np.abs(lam), initial=0.0))
    if lam.size and float(lam.min()) < -_PSD_RTOL * top:
        raise ArgumentError(f"eigenvalues must be ≥ 0 (weights of χ²_1 terms); found {float(lam.min()):.6g}")
    return np.sort(lam[lam > 0.0])


def _probability(value: object) -> float:
    p = real_number(value)
    if p is None or not 0.0 < p < 1.0:
        raise ArgumentError(f"P_f must be a false-alarm probability in (0, 1); got {shown(value)}")
    return p


def _whole(value: object, name: str, least: int) -> int:
    """A whole number ≥ ``least`` (an integral float is accepted)."""
    x = real_number(value)
    if x is None or not math.isfinite(x) or not x.is_integer() or x < least:
        raise ArgumentError(f"{name} must be a whole number ≥ {least}; got {shown(value)}")
    return int(x)


def _autocovariances(R_list: object, window: object) -> tuple[np.ndarray, int]:
    """``R(0) … R(N−1)`` as an ``(N, p, p)`` array (``R(0)`` symmetric) and ``N``."""
    n = _whole(window, "window", 1)
    r = real_array(R_list, "R_list")
    if r.ndim == 2:
        r = r[None]
    if r.ndim != 3 or r.shape[1] != r.shape[2] or r.shape[1] == 0:
        raise ShapeError(f"R_list must be a sequence of square p × p matrices R(0), R(1), …; got shape {r.shape}")
    if r.shape[0] < n:
        raise ShapeError(f"R_list holds R(0)…R({r.shape[0] - 1}); window {n} needs R(0)…R({n - 1})")
    if n * r.shape[1] > MAX_WINDOW_SIZE:
        raise ArgumentError(f"window × outputs is {n * r.shape[1]}; at most {MAX_WINDOW_SIZE} is supported")
    r = r[:n]
    if not np.all(np.isfinite(r)):
        bad = tuple(int(i) for i in np.argwhere(~np.isfinite(r))[0])
        raise ArgumentError(f"R_list contains a non-finite entry at index {bad}")
    r = r.copy()
    r[0] = as_covariance(r[0], "R_list[0]", r.shape[1])
    return r, n


def _covariance_eigenvalues(cov: np.ndarray, what: str) -> np.ndarray:
    """Eigenvalues of a covariance, round-off negatives set to zero; none positive is an :class:`ExistenceError`."""
    mu = scipy.linalg.eigvalsh(cov)
    top = float(np.max(np.abs(mu)))
    if float(mu[0]) < -_PSD_RTOL * top:
        raise ArgumentError(f"{what} is not positive semidefinite (eigenvalue {float(mu[0]):.6g}): not an autocovariance")
    if top == 0.0:
        raise ExistenceError(f"{what} is zero: the statistic is identically zero and has no threshold")
    return np.clip(mu, 0.0, None)
