"""The χ² law of the statistics on fault-free data, with proper bounds.

The minimum-variance UIO's residual is the innovation of an optimal filter: white
and Gaussian with covariance Σ_r, so its samples of J = rᵀ Σ_r⁺ r are i.i.d.
χ²(dof). Under that law the exceedance count over N samples is Binomial(N, P_f);
the tests accept the central 1 − 1e-6 of it (and of the Kolmogorov–Smirnov
statistic), so a correct implementation fails for a new seed with probability
1e-6, while a Σ_r off by a few percent is caught.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.stats
from fdisyn.evaluation.built import build
from fdisyn.evaluation.metrics import binomial_interval
from fdisyn.problems.wind_turbine import PROBLEM

ALPHA = 1e-6


@pytest.fixture(scope="module")
def fault_free_J(tmp_path_factory):
    b = build(PROBLEM, "kalman_uio", tmp_path_factory.mktemp("chi2") / "d", P_f=0.01)
    batch = PROBLEM.run("fault_free", range(5))
    # drop the first 50 samples of each run: the equilibrium start leaves a short transient
    js = np.concatenate([b.diagnoser.run(batch.U[i], batch.Y[i]).J[50:] for i in range(5)])
    return b.gain_file, js


def test_exceedance_count_is_binomial(fault_free_J):
    gf, js = fault_free_J
    n = js.shape[0]
    lo, hi = binomial_interval(n, 0.01, alpha=ALPHA)
    for j in range(js.shape[1]):
        count = int(np.sum(js[:, j] > gf.thresholds[j]))
        assert lo <= count <= hi, (gf.step.statistic_names[j], count, (lo, hi))


def test_statistic_follows_chi2(fault_free_J):
    gf, js = fault_free_J
    for j, ev in enumerate(gf.evaluators):
        res = scipy.stats.kstest(js[:, j], scipy.stats.chi2(ev.dof).cdf)
        assert res.pvalue > ALPHA, (gf.step.statistic_names[j], res)


def test_statistic_samples_are_white(fault_free_J):
    # lag-1 correlation of J: zero for i.i.d. samples; |ρ̂| < 5/√N holds with probability > 1 − 1e-6
    _, js = fault_free_J
    n = js.shape[0]
    for j in range(js.shape[1]):
        x = js[:, j] - js[:, j].mean()
        rho = float(x[1:] @ x[:-1] / (x @ x))
        assert abs(rho) < 5 / np.sqrt(n)


def test_a_wrong_covariance_is_caught(fault_free_J):
    # the same data judged with Σ_r scaled by 1.1: the binomial bound rejects it
    gf, js = fault_free_J
    n = js.shape[0]
    lo, hi = binomial_interval(n, 0.01, alpha=ALPHA)
    count = int(np.sum(js[:, 0] / 1.1 > gf.thresholds[0]))
    assert not lo <= count <= hi
