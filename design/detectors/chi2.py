"""χ² evaluation of a residual: ``J = rᵀ Σ_r⁺ r`` and its threshold from the law of ``J`` under the
fault-free hypothesis."""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np
import scipy.stats
from fdisyn.detectors.symbolic import Evaluated, LinearStatistic, above_threshold, chi2
from fdisyn.detectors.table import BankRequest, Detector, register
from fdisyn.numerics.account import SizeLaw, quadratic_sizes
from fdisyn.numerics.linalg import rank_tol
from fdisyn.runtime.errors import ArgumentError, ExistenceError
from fdisyn.runtime.gainfile import Evaluator

__all__ = ["chi2_threshold", "chi2_evaluator", "CHI2_RANK_RTOL", "DETECTOR"]


def chi2_threshold(P_f: float, dof: int) -> float:
    """``J_th`` with ``P(J > J_th) = P_f`` for ``J ~ χ²(dof)`` (eq. (19) of Hu, Sun,
    Jiang, He & Zhang, Acta Automatica Sinica 39(8), 2013).

    Hu et al. use ``P_f = 0.0003`` with one degree of freedom: ``J_th = 13.0704``
    (section 3).
    """
    if not 0.0 < P_f < 1.0:
        raise ArgumentError(f"P_f must be a false-alarm probability in (0, 1); got {P_f!r}")
    if int(dof) != dof or dof < 1:
        raise ArgumentError(f"dof must be a positive integer; got {dof!r}")
    return float(scipy.stats.chi2.isf(P_f, int(dof)))

CHI2_RANK_RTOL = 1e-6
"""Residual directions whose variance is below this fraction of the largest are
left out of the χ² statistic. Such a direction is not driven by noise in any
useful sense (for a plain UIO it is an exact function of the previous
residual); dividing by its variance would make the statistic hypersensitive
to any model error and amplify round-off in ``r`` by ``sqrt(cond Σ_r)``."""


def chi2_evaluator(generator: int, sigma_r: np.ndarray, P_f: float, *, rank_rtol: float = CHI2_RANK_RTOL) -> Evaluator:
    """χ² evaluator ``J = rᵀ W r`` (Hu, Sun, Jiang, He & Zhang, Acta Automatica Sinica 39(8), 2013, eqs. (18)–(19)).

    ``W`` is the pseudo-inverse of ``Σ_r`` on the eigen-directions with variance
    above ``rank_rtol`` times the largest, and ``dof`` their number, so that
    ``J ~ χ²(dof)`` for Gaussian ``r`` with covariance ``Σ_r``; the threshold
    is the ``1 − P_f`` quantile.
    """
    s = 0.5 * (np.asarray(sigma_r, dtype=float) + np.asarray(sigma_r, dtype=float).T)
    lam, vec = np.linalg.eigh(s)
    top = float(lam[-1]) if lam.size else 0.0
    keep = lam > max(rank_rtol * top, rank_tol(s))
    dof = int(np.sum(keep))
    if dof == 0:
        raise ExistenceError(f"the residual of generator {generator} has zero covariance: no χ² statistic exists")
    w = (vec[:, keep] / lam[keep]) @ vec[:, keep].T
    return Evaluator(
        kind="chi2",
        generator=generator,
        P_f=float(P_f),
        dof=dof,
        threshold=chi2_threshold(P_f, dof),
        Sigma_r=s,
        W=0.5 * (w + w.T),
    )


# --------------------------------------------------------------------------- the detector's entry


def _update(r: ca.SX, block: ca.SX | None, ev: Evaluator) -> Evaluated:
    return Evaluated(chi2(r, ev.W))


def _bank(request: BankRequest) -> tuple[list[Evaluator], list[Any], list[Any], dict[str, Any]]:
    evals = [chi2_evaluator(i, s, 1.0 / request.arl_samples) for i, s in enumerate(request.sigma_r)]
    return evals, list(request.generators), list(request.sigma_r), {}


DETECTOR = register(
    Detector(
        kind="chi2",
        doc="q = rᵀ W r per sample",
        windowed=False,
        no_window="window = {window} needs evaluator = 'wssr'; the χ² evaluator ('chi2') uses one sample",
        sequential=False,
        evaluators=_bank,
        statistic=LinearStatistic(None, False, _update, above_threshold),
        size_law=SizeLaw("chi2", "χ²: P(J > threshold) = 95 % (50 %) on a sample", quadratic_sizes),
        cited="per-sample χ²",
        null_law=lambda ev: (lambda x: scipy.stats.chi2.pdf(x, ev.dof), f"χ²({ev.dof})"),
    )
)
"""The χ² detector (:class:`~fdisyn.detectors.table.Detector`)."""
