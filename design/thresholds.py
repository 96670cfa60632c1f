"""Thresholds from the law of a statistic under the fault-free hypothesis."""

from __future__ import annotations

import scipy.stats
from fdisyn.runtime.errors import ShapeError

__all__ = ["chi2_threshold"]


def chi2_threshold(P_f: float, dof: int) -> float:
    """``J_th`` with ``P(J > J_th) = P_f`` for ``J ~ χ²(dof)`` (eq. (19) of Hu, Sun,
    Jiang, He & Zhang, Acta Automatica Sinica 39(8), 2013).

    Hu et al. use ``P_f = 0.0003`` with one degree of freedom: ``J_th = 13.0704``
    (section 3).
    """
    if not 0.0 < P_f < 1.0:
        raise ShapeError(f"P_f must be a false-alarm probability in (0, 1); got {P_f!r}")
    if int(dof) != dof or dof < 1:
        raise ShapeError(f"dof must be a positive integer; got {dof!r}")
    return float(scipy.stats.chi2.isf(P_f, int(dof)))
