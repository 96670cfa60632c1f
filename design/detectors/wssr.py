"""Windowed weighted sums of squared residuals (WSSR) and their thresholds.

* The threshold table of the NAFDF's fast detection (Zhou, Xi & Zhang, c. 1991, eq. (2.4)):
  :func:`wssr_threshold_table`.
* The WSSR evaluator of a linear residual generator (Long & Wang, Aeroengine 43(5), 2017, section 2):
  :func:`wssr_evaluator`, threshold from the residual's autocovariance over the window.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any, Literal

import casadi as ca
import numpy as np
import scipy.stats
from fdisyn.detectors.chi2 import chi2_evaluator
from fdisyn.detectors.symbolic import Evaluated, LinearStatistic, above_threshold, chi2, wssr_update
from fdisyn.detectors.table import BankRequest, Detector, register
from fdisyn.detectors.window import window_energy_quantile
from fdisyn.numerics.account import SizeLaw, window_context, window_sizes
from fdisyn.runtime.errors import ArgumentError, ShapeError
from fdisyn.runtime.gainfile import Evaluator
from fdisyn.runtime.schema import MAX_MAGNITUDE
from fdisyn.runtime.statistics import MAX_WSSR_WINDOW
from fdisyn.runtime.names import shown

__all__ = ['wssr_threshold_table', 'wssr_evaluator', 'whitened_autocovariances', 'DETECTOR', 'SIZE_LAW']

# The largest finite double: what the NAFDF step saturates an overflowed statistic to (JSON has no inf).
_NEVER = float(np.finfo(float).max)


def wssr_threshold_table(
    *, window: int, n_outputs: int, rule: Literal["chi2", "beta0"], false_alarm_probability: float, beta0: float | None
) -> np.ndarray:
    """Threshold on ``L = (1/k) Σ γᵀ V0⁻¹ γ`` for ``k = 1..N`` samples in the window (eq. (2.4)).

    ``"chi2"``: ``χ²_{1−P_f}(k p) / k`` — the exact ``(1 − P_f)`` quantile of
    ``L`` under H0 (``k L ~ χ²(k p)``). ``"beta0"``: the paper's ``β0`` on a
    full window and, on a partial one, the largest number a gain file holds
    (``MAX_MAGNITUDE``, 1e150): a level no statistic of a filter that has not
    diverged reaches, so the rule alarms on full windows only.
    """
    ks = np.arange(1, window + 1)
    if rule == "chi2":
        return np.array([scipy.stats.chi2.isf(false_alarm_probability, k * n_outputs) / k for k in ks])
    if rule == "beta0":
        if beta0 is None or not math.isfinite(beta0) or beta0 <= 0:
            raise ArgumentError(f"threshold_rule 'beta0' needs a positive finite beta0; got {beta0!r}")
        return np.where(ks == window, float(beta0), MAX_MAGNITUDE)
    raise ArgumentError(f"threshold_rule must be 'chi2' or 'beta0'; got {rule!r}")


def wssr_evaluator(generator: int, sigma_r: np.ndarray, R_list: np.ndarray, P_f: float, window: int) -> Evaluator:
    """WSSR evaluator ``J(k) = Σ_{l<N} r(k−l)ᵀ W r(k−l)`` over ``N = window`` samples (Long & Wang, Aeroengine
    43(5), 2017, section 2), the runtime's ``kind = "wssr"`` (:class:`~fdisyn.runtime.gainfile.Evaluator`).

    ``W`` and ``dof`` are the χ² evaluator's (:func:`~fdisyn.detectors.chi2.chi2_evaluator` on ``sigma_r``).
    The threshold is the exact ``1 − P_f`` quantile of ``J`` under no fault with Gaussian noise: with
    ``T = Λ^{−1/2} Vᵀ`` on the ``dof`` kept directions (``Tᵀ T = W``), ``J`` is the energy of the window of
    ``T r``, whose autocovariance is ``T R(τ) Tᵀ``, so ``J ~ Σ λ_i χ²_1`` with ``λ`` the eigenvalues of
    ``(I_N ⊗ T) Σ_window (I_N ⊗ T)ᵀ`` — those of ``(I_N ⊗ W^{1/2}) Σ_window (I_N ⊗ W^{1/2})`` without its
    zeros — (:func:`~fdisyn.detectors.window.window_energy_quantile`). ``R_list`` holds ``R(0) … R(N−1)``
    of the residual, ``R(τ) = E[r(k+τ) r(k)ᵀ]`` (:func:`fdisyn.synthesis.residual.residual_autocovariances`).
    A white residual (the innovation of a minimum-variance UIO) gives ``χ²_{1−P_f}(N·dof)``; ``N = 1`` is
    the χ² evaluator's threshold up to the quantile's accuracy. The threshold is that of a full window: at
    start-up, with fewer than ``N`` samples in it, ``J`` sums fewer terms and alarms less (conservative).
    """
    n = _window(window)
    chi2 = chi2_evaluator(generator, sigma_r, P_f)
    rz = whitened_autocovariances(chi2, R_list, n)
    return replace(chi2, kind="wssr", window=n, threshold=window_energy_quantile(rz, n, P_f))


def whitened_autocovariances(chi2: Evaluator, R_list: np.ndarray, lags: int) -> np.ndarray:
    """``T R(τ) Tᵀ``, ``τ < lags``: the autocovariances of ``T r`` with ``T = Λ^{−1/2} Vᵀ`` on the ``dof`` kept
    directions of a χ² evaluator (``Tᵀ T = W``), so that ``q = rᵀ W r = ‖T r‖²``.

    Parameters
    ----------
    chi2 : Evaluator
        The χ² evaluator of the residual (:func:`~fdisyn.detectors.chi2.chi2_evaluator`: its ``W`` and ``dof``).
    R_list : numpy.ndarray
        ``R(0) … R(lags−1)`` of the residual (at least ``lags`` of them).
    lags : int
        How many.

    Returns
    -------
    numpy.ndarray
        ``lags × dof × dof``.

    Raises
    ------
    ShapeError
        ``R_list`` holds fewer lags or matrices of another size.
    """
    lam, vec = np.linalg.eigh(chi2.W)
    t = np.sqrt(lam[-chi2.dof :])[:, None] * vec[:, -chi2.dof :].T
    r = np.asarray(R_list, dtype=float)
    if r.ndim != 3 or r.shape[0] < lags or r.shape[1:] != chi2.W.shape:
        raise ShapeError(f"R_list must hold R(0)…R({lags - 1}), each {chi2.W.shape}; got shape {r.shape}")
    return np.einsum("ai,tij,bj->tab", t, r[:lags], t)


def _window(value: object) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 1 <= int(value) <= MAX_WSSR_WINDOW:
        raise ArgumentError(f"window must be a whole number of samples in 1..{MAX_WSSR_WINDOW}; got {shown(value)}")
    return int(value)


# --------------------------------------------------------------------------- the detector's entry


def _update(r: ca.SX, block: ca.SX | None, ev: Evaluator) -> Evaluated:
    assert block is not None
    J, window, _ = wssr_update(chi2(r, ev.W), block)
    return Evaluated(J, window)


def _bank(request: BankRequest) -> tuple[list[Evaluator], list[Any], list[Any], dict[str, Any]]:
    n = 1 if request.window is None else int(request.window)
    evals = [
        wssr_evaluator(i, s, request.autocovariances(g, n - 1), 1.0 / request.arl_samples, n)
        for i, (g, s) in enumerate(zip(request.generators, request.sigma_r, strict=True))
    ]
    return evals, list(request.generators), list(request.sigma_r), {}


SIZE_LAW = SizeLaw(
    "wssr",
    "WSSR: P(J > threshold) = 95 % (50 %) over a window (four-moment law of Liu, Tang & Zhang 2009)",
    window_sizes,
    window_context,
)
"""The WSSR's smallest detectable fault: its window's noncentral quadratic form (:func:`fdisyn.numerics.account.window_sizes`)."""

DETECTOR = register(
    Detector(
        kind="wssr",
        doc="the sum of q over the last window samples",
        windowed=True,
        no_window="",
        sequential=False,
        evaluators=_bank,
        statistic=LinearStatistic("window", False, _update, above_threshold),
        size_law=SIZE_LAW,
        cited="WSSR (Long & Wang, Aeroengine 43(5), 2017, section 2)",
        window_doc="WSSR window N in samples (Long & Wang, Aeroengine 43(5), 2017, section 2)",
        window_default="1",
    )
)
"""The WSSR detector (:class:`~fdisyn.detectors.table.Detector`)."""
