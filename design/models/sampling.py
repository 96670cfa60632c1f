"""Exact sampling of continuous-time linear systems.

``zoh`` is the step-invariant (zero-order-hold) discretisation; ``van_loan``
samples continuous white noise exactly, the integral that also gives the
norm-invariant input matrix of Qiu, Wen & Jiang (Control Theory &
Applications 27(8), 2010), Lemma 1:
``B_J B_Jᵀ = ∫₀ʰ e^{Aτ} B Bᵀ e^{Aᵀτ} dτ``.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
from fdisyn.numerics.linalg import as_matrix
from fdisyn.runtime.errors import ArgumentError
from fdisyn.runtime.names import shown
from fdisyn.runtime.values import real_number

__all__ = ["zoh", "van_loan", "check_sample_time", "EXP_LIMIT", "RESOLUTION"]


def check_sample_time(h: object, name: str = "Ts") -> float:
    """``h`` as a float if it is a positive, finite sample time in seconds.

    Parameters
    ----------
    h : object
        The sample time as given: a real number (:func:`~fdisyn.runtime.values.real_number`); a string
        such as ``"1_0"`` or ``"１"`` and a boolean are refused, never converted.
    name : str
        How the message names it (the key or keyword the caller wrote).

    Returns
    -------
    float

    Raises
    ------
    ArgumentError
        ``h`` is not a number, or not positive and finite.
    """
    hf = real_number(h)
    if hf is None:
        raise ArgumentError(f"{name} must be a positive number of seconds; got {type(h).__name__} {shown(h)}")
    if not np.isfinite(hf) or hf <= 0.0:
        raise ArgumentError(f"{name} must be a positive, finite number of seconds; got {shown(h)}")
    return hf


EXP_LIMIT = float(np.log(np.finfo(float).max))
"""≈ 709.8: ``e^x`` overflows a double beyond it. Sampling computes ``e^{±A h}``,
so ``max |Re λ(A)| · h`` must stay below it."""


RESOLUTION = float(np.finfo(float).eps)
"""≈ 2.2e-16, the double's resolution beside 1. When ``‖A‖₂ · h`` is below it, every entry of ``A h`` is lost
beside the identity: ``e^{A h}`` is ``I`` to the last bit of its diagonal (every pole at 1) and the plant's
dynamics are gone from the sampled model. Sampling needs ``‖A‖₂ · h ≥ RESOLUTION``."""


def _works(a: np.ndarray, lam: np.ndarray, name: str, short: bool) -> str:
    """The sample times that sample ``a`` (eigenvalues ``lam``), the violated bound first (``short``: the lower):
    ``lo`` = :data:`RESOLUTION` / ‖A‖₂ (the identity, below) and ``hi`` = :data:`EXP_LIMIT` / max |Re λ| (overflow,
    beyond)."""
    size = float(np.linalg.norm(a, 2)) if a.size and np.all(np.isfinite(a)) else 0.0
    rate = float(np.max(np.abs(lam.real), initial=0.0))
    lo = f"{name} ≥ {RESOLUTION / size:.4g} s" if size > 0 else ""
    hi = f"{name} < {EXP_LIMIT / rate:.4g} s" if rate > 0 else ""
    first, then = (lo, hi) if short else (hi, lo)
    if not first:
        return f"expected a {'longer' if short else 'shorter'} {name}"
    return f"expected {first}" + (f" (and {then.split(' ', 1)[1]})" if then else "")


def _expm(big: np.ndarray, a: np.ndarray, h: float, name: str) -> np.ndarray:
    """``expm(big · h)``, refused by name when it overflows or when ``h`` is too short to carry ``A``.

    ``big`` holds ``A`` (and, for Van Loan, ``−A``): a sample time so long that
    ``e^{|Re λ| h}`` exceeds the largest double gives infinities (and NumPy
    warnings) instead of a model; one so short that ``‖A‖₂·h`` is below
    :data:`RESOLUTION` gives ``e^{A h} = I`` to rounding (the plant's dynamics are
    lost). The error names ``name`` and the range of sample times that works.
    """
    shown_h = f"{h:g}"  # finite and positive: as written, never an overflow of it
    finite = bool(a.size) and bool(np.all(np.isfinite(a)))
    size = float(np.linalg.norm(a, 2)) if finite else 0.0
    lam = np.linalg.eigvals(a) if finite else np.zeros(0, dtype=complex)
    if size > 0 and size * h < RESOLUTION:
        raise ArgumentError(
            f"{name} = {shown_h} s is too short to sample this model: e^(A·{name}) rounds to the identity (‖A‖ = "
            f"{size:.4g} 1/s, and ‖A‖·{name} = {size * h:.3g} is below the double's resolution {RESOLUTION:.3g}: the "
            f"sampled model loses the plant's dynamics); {_works(a, lam, name, True)}"
        )
    with np.errstate(over="ignore", invalid="ignore"):
        try:
            e = sla.expm(big * h)
        except (ValueError, np.linalg.LinAlgError):  # big · h already overflowed to inf
            e = np.full(big.shape, np.inf)
    if not np.all(np.isfinite(e)):
        rate = float(np.max(np.abs(lam.real), initial=0.0))
        why = (f"e^(±A·{name}) overflows (the fastest mode has |Re λ| = {rate:.4g} 1/s, and |Re λ|·{name} must stay below "
               f"{EXP_LIMIT:.0f})" if rate > 0 else "the entries of the sampled matrices overflow")
        raise ArgumentError(f"{name} = {shown_h} s is too long to sample this model: {why}; {_works(a, lam, name, False)}")
    return e


def zoh(a: np.ndarray, b: np.ndarray, h: float, *, name: str = "Ts") -> tuple[np.ndarray, np.ndarray]:
    """Step-invariant sampling: ``A_D = e^{A h}``, ``B_D = ∫₀ʰ e^{Aτ} dτ B``.

    Computed from one matrix exponential of ``[[A, B], [0, 0]] h`` (exact up to
    the accuracy of ``expm``; no inverse of ``A`` is needed, so singular ``A``
    such as a free rigid-body mode is fine). Qiu, Wen & Jiang 2010 write ``B_D``
    as ``B_uD`` (eq. (13)); the wind-turbine drive train of Hu, Sun, Jiang, He
    & Zhang (Acta Automatica Sinica 39(8), 2013) is continuous while their
    method is discrete-time (eqs. (1), (12)), so it is sampled this way.
    """
    h = check_sample_time(h, name)
    a = as_matrix(a, "A")
    n = a.shape[0]
    b = as_matrix(b, "B", rows=n)
    m = b.shape[1]
    big = np.zeros((n + m, n + m))
    big[:n, :n] = a
    big[:n, n:] = b
    e = _expm(big, a, h, name)
    return e[:n, :n], e[:n, n:]


def van_loan(a: np.ndarray, w: np.ndarray, h: float, *, name: str = "Ts") -> np.ndarray:
    """``∫₀ʰ e^{Aτ} W e^{Aᵀτ} dτ`` by Van Loan's block exponential.

    With ``W = B Bᵀ`` this is ``B_J B_Jᵀ`` of Qiu, Wen & Jiang 2010, Lemma 1; with ``W`` the
    intensity of continuous white noise it is the covariance of the sampled
    noise ``w_k = ∫ e^{A(h−τ)} dW`` (Van Loan, IEEE TAC 23(3), 1978).
    """
    h = check_sample_time(h, name)
    a = as_matrix(a, "A")
    n = a.shape[0]
    w = as_matrix(w, "W", rows=n, cols=n)
    big = np.zeros((2 * n, 2 * n))
    big[:n, :n] = -a
    big[:n, n:] = w
    big[n:, n:] = a.T
    e = _expm(big, a, h, name)
    phi22 = e[n:, n:]  # e^{Aᵀh}
    q = phi22.T @ e[:n, n:]
    return 0.5 * (q + q.T)
