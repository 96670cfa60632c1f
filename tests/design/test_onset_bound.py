"""The onset-aware Lorden bound: the cumulative information of the fault's mean residual shift lag by lag after its
onset (Lai, IEEE Transactions on Information Theory 44(7), 1998), against independent truths — ``ln(ARL)/I`` for a
step, and the noise-free fault step response of a linear generator for the Monte Carlo's per-lag mean."""

from __future__ import annotations

import math

import numpy as np
import pytest
from fdisyn.detectors.sequential import lorden_delay, onset_lorden_delay
from fdisyn.evaluation.built import build
from fdisyn.evaluation.campaign import Campaign, ChunkTask, run_seed
from fdisyn.evaluation.metrics import ONSET_LAGS, MetricsAccumulator, delay_bound_ratio
from fdisyn.runtime.errors import ArgumentError
from fdisyn.simulation.problem import get_problem
from fdisyn.synthesis.kinds import lorden_bound, onset_lorden_bound
from fdisyn.synthesis.residual import fault_step_response
from hypothesis import given, settings
from hypothesis import strategies as st
from fdisyn.problems.sampled_data_example import noise_plant

SDE = get_problem("sampled_data_example")
RUNS = 60


@settings(max_examples=100, deadline=None)
@given(st.floats(1.5, 1e12), st.floats(1e-4, 50.0), st.integers(0, 300))
def test_a_step_gives_lordens_bound(arl0: float, info: float, lags: int) -> None:
    """A constant information per sample, over any number of measured lags and the tail: ``ln(ARL)/I``."""
    assert onset_lorden_delay(arl0, np.full(lags, info), info) == pytest.approx(lorden_delay(arl0, info), rel=1e-12)


def test_a_shift_that_builds_up_takes_longer_and_interpolates_between_samples() -> None:
    """Nothing on the onset sample and half of the information on the next: a sample and a half later than the
    step's bound of 4 samples; the crossing interpolated inside the sample that reaches ``ln(ARL)``."""
    arl0 = math.e**4
    assert onset_lorden_delay(arl0, [0.0, 0.5, 1.0, 1.0], 1.0) == pytest.approx(5.5)
    assert onset_lorden_delay(arl0, [0.0, 3.0, 2.0], 1.0) == pytest.approx(2.5)
    assert onset_lorden_delay(arl0, [0.0, 0.0], 0.0) == math.inf
    # an unbiased estimate may dip below 0: the first crossing of the cumulative sum (−1, 2, 4)
    assert onset_lorden_delay(arl0, [-1.0, 3.0, 2.0], 1.0) == pytest.approx(3.0)
    with pytest.raises(ArgumentError, match="≥ 0 in the tail"):
        onset_lorden_delay(arl0, [1.0], -1.0)
    with pytest.raises(ArgumentError, match="finite"):
        onset_lorden_delay(arl0, [np.nan], 1.0)


@pytest.fixture(scope="module")
def sde_built(tmp_path_factory: pytest.TempPathFactory):  # noqa: ANN201 - a Built
    return build(SDE, SDE.default_design, tmp_path_factory.mktemp("sde") / SDE.default_design)


def test_a_step_shift_of_a_linear_bank_gives_its_lorden_bound(sde_built) -> None:  # noqa: ANN001
    """Every lag shifted as the whole fault (a white residual's step, no transient): the kind's ``ln(ARL_j)/I_j``."""
    gf = sde_built.gain_file
    nr = sum(g.n_residual for g in gf.generators)
    shift = np.linspace(0.3, 1.1, nr)
    cov = np.eye(nr)
    step = lorden_bound(gf, shift, cov)
    assert step is not None
    got = onset_lorden_bound(gf, np.tile(shift, (17, 1)), shift, cov)
    assert got == pytest.approx(step[1], rel=1e-12)
    assert onset_lorden_bound(gf, np.zeros((0, nr)), shift, cov) == pytest.approx(step[1], rel=1e-12)
    with pytest.raises(ArgumentError, match="per-lag shifts"):
        onset_lorden_bound(gf, np.zeros((3, nr + 1)), shift, cov)


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "python"])
def test_the_campaigns_per_lag_mean_is_the_fault_step_response(sde_built, compiled: bool) -> None:  # noqa: ANN001
    """sampled_data_example's paper scenario through the compiled step (and the Python path): the Monte Carlo's mean
    residual shift at each lag after the onset equals the noise-free fault step response of its linear generator
    within 5 standard errors (the residual's fault-free standard deviation over √runs, and the fault-free mean's
    own), and its onset-aware bound is the one the step response gives, up to that scatter (20 %) — later than the
    step's ``ln(ARL)/I``, as the fault reaches the residual one sample after its onset."""
    d, gf = SDE.default_design, sde_built.gain_file
    name = "paper"
    sc = SDE.scenario(name)
    campaign = Campaign(SDE, {d: sde_built}, SDE.check_options({}), compiled=compiled)
    s = list(SDE.scenarios).index(name)
    acc = None
    for start in range(0, RUNS, 20):
        res = campaign.run(ChunkTask(name, s, start, tuple(run_seed(0, s, i) for i in range(start, start + 20))))
        if acc is None:
            acc = MetricsAccumulator(campaign.plan(sc, d, res.t), len(res.t))
        acc.add(res.summaries[d])
    assert acc is not None and acc.runs == RUNS
    lags = acc.plan.lags
    assert lags == min(ONSET_LAGS, int(acc.plan.on.sum()))
    on, off, n_on, n_off, off2 = acc.sums
    mean_off = off / n_off
    cov = (off2 - n_off * np.outer(mean_off, mean_off)) / (n_off - 1)
    measured = acc.lag_sums / RUNS - mean_off
    plant = noise_plant()  # the model the design was made on, with its fault's input Fx_D
    size = float(sc.params["size"])
    truth = np.hstack([fault_step_response(g, plant, np.zeros(len(gf.outputs)), np.array([size]), lags) for g in gf.generators])
    se = np.sqrt(np.diag(cov) / RUNS + np.diag(cov) / n_off)
    assert np.all(np.abs(measured - truth) <= 5.0 * se[None, :]), np.max(np.abs(measured - truth) / se)
    assert np.max(np.abs(truth)) > 10.0 * np.max(se), "the fault stands out of the scatter: the comparison says something"
    got = onset_lorden_bound(gf, measured, on / n_on - mean_off, cov, lag_noise=cov / RUNS)
    want = onset_lorden_bound(gf, truth, truth[-1], cov)
    assert got is not None and want is not None
    assert got == pytest.approx(want, rel=0.2)
    step = lorden_bound(gf, on / n_on - mean_off, cov)
    assert step is not None and got > step[1] + 0.5, "the onset sample carries nothing of the fault: the step's bound is too low"


def test_the_delay_ratio_is_over_the_onset_aware_bound() -> None:
    """:func:`delay_bound_ratio` over the bound it is given; the metrics keep the step's ratio beside it."""
    assert delay_bound_ratio(2.0, (float("nan"), 6.0)) == pytest.approx(0.5)
