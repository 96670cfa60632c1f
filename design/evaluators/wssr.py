"""The WSSR threshold table of the NAFDF's fast detection (Zhou, Xi & Zhang, c. 1991, eq. (2.4)).
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
import scipy.stats
from fdisyn.runtime.errors import ArgumentError

__all__ = ['wssr_threshold_table']

# The largest finite double: a threshold that can never be exceeded (JSON has no inf).
_NEVER = float(np.finfo(float).max)


def wssr_threshold_table(
    *, window: int, n_outputs: int, rule: Literal["chi2", "beta0"], false_alarm_probability: float, beta0: float | None
) -> np.ndarray:
    """Threshold on ``L = (1/k) Σ γᵀ V0⁻¹ γ`` for ``k = 1..N`` samples in the window (eq. (2.4)).

    ``"chi2"``: ``χ²_{1−P_f}(k p) / k`` — the exact ``(1 − P_f)`` quantile of
    ``L`` under H0 (``k L ~ χ²(k p)``). ``"beta0"``: the paper's ``β0`` on a
    full window, never exceeded on a partial one.
    """
    ks = np.arange(1, window + 1)
    if rule == "chi2":
        return np.array([scipy.stats.chi2.isf(false_alarm_probability, k * n_outputs) / k for k in ks])
    if rule == "beta0":
        if beta0 is None or not math.isfinite(beta0) or beta0 <= 0:
            raise ArgumentError(f"threshold_rule 'beta0' needs a positive finite beta0; got {beta0!r}")
        return np.where(ks == window, float(beta0), _NEVER)
    raise ArgumentError(f"threshold_rule must be 'chi2' or 'beta0'; got {rule!r}")

