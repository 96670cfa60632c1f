"""A linear diagnoser switched on while its plant is moving: each generator's warm-up estimates its initial state by
least squares over its first samples (``fdisyn.runtime.warmup``) and holds its statistics until then.

Truths: the correction against NumPy's least-squares solve of the stacked transient; the alarm count of seeded
random plants (stable and unstable) already moving at switch-on against the Poisson bound of the design's own
false-alarm probability; a gap in the warm-up against a fresh start after it."""

from __future__ import annotations

from dataclasses import replace

import fdisyn
import numpy as np
import pytest
import scipy.linalg
import scipy.stats
from fdisyn.runtime.errors import GainFileError
from fdisyn.runtime.gainfile import read_gain_file, write_gain_file
from fdisyn.runtime.layout import linear_state_layout
from fdisyn.runtime.reference import LinearReference
from fdisyn.runtime.warmup import generator_warmup, warmup_constants
from fdisyn.synthesis.linear_diagnoser import WARMUP_RESIDUE, warmup_length

from tests.helpers import random_plant

P_F = 1e-3
PLANTS = range(10)
RUNS, T = 5, 60


def without_warmup(gf):  # noqa: ANN001, ANN201 - a gain file
    """The same diagnoser started at the equilibrium of its first sample (as before warm-ups)."""
    gens = tuple(replace(g, warmup=0) for g in gf.generators)
    lay = linear_state_layout(gens, gf.evaluators)
    return replace(gf, generators=gens, step=replace(gf.step, nstate=lay.size, init_state=np.zeros(lay.size)))


def moving(plant, samples: int, seed: int, scale: float = 10.0) -> tuple[np.ndarray, np.ndarray]:  # noqa: ANN001
    """A run that starts far from rest (``x₀ ~ N(0, scale² I)``), with inputs and unknown inputs wandering (random
    walks around an offset), the plant's own noise, no fault."""
    rng = np.random.default_rng(seed)
    lq, lr = np.linalg.cholesky(plant.Q), np.linalg.cholesky(plant.R)
    x = scale * rng.standard_normal(plant.n)
    U = 2.0 + 0.3 * np.cumsum(rng.standard_normal((samples, plant.m)), axis=0)
    d = np.cumsum(rng.standard_normal((samples, plant.E.shape[1])), axis=0)
    Y = np.zeros((samples, plant.p))
    for k in range(samples):
        Y[k] = plant.C @ x + plant.D @ U[k] + lr @ rng.standard_normal(plant.p)
        x = plant.A @ x + plant.B @ U[k] + plant.E @ d[k] + lq @ rng.standard_normal(plant.n)
    return U, Y


def test_the_correction_is_the_least_squares_initial_error() -> None:
    """A noiseless transient ``r_k = Cr Ar^k δ``: the accumulated sums and the correction remove ``Ar^N δ``
    exactly, and ``δ`` is NumPy's weighted least-squares solution of the stacked transient."""
    rng = np.random.default_rng(1)
    ns, nr, n = 4, 2, 6
    a = rng.standard_normal((ns, ns))
    a *= 0.9 / max(abs(np.linalg.eigvals(a)))
    cr = rng.standard_normal((nr, ns))
    w = np.array([[2.0, 0.3], [0.3, 0.5]])
    gen = type("G", (), {"Ar": a, "Cr": cr, "warmup": n})()
    gains, m = warmup_constants(gen, w)
    delta = rng.standard_normal(ns)
    phis = [cr @ np.linalg.matrix_power(a, k) for k in range(n)]
    acc = sum(gains[k] @ (phis[k] @ delta) for k in range(n))
    np.testing.assert_allclose(m @ acc, -np.linalg.matrix_power(a, n) @ delta, atol=1e-12)
    root = np.linalg.cholesky(w).T
    stacked = np.vstack([root @ p for p in phis])
    lstsq = np.linalg.lstsq(stacked, stacked @ delta, rcond=None)[0]
    np.testing.assert_allclose(lstsq, delta, atol=1e-12)


@pytest.fixture(scope="module")
def campaign() -> dict[str, int]:
    counts = {"before": 0, "after": 0, "statistic_samples": 0, "warmup_alarms": 0}
    for seed in PLANTS:
        plant = random_plant(seed, radius=min(1.1, 0.5 + 0.06 * seed))  # stable, then unstable from seed 9
        gf = fdisyn.design(plant, method="kalman_uio", P_f=P_F)
        assert all(g.warmup >= 1 for g in gf.generators)
        old = without_warmup(gf)
        for run in range(RUNS):
            U, Y = moving(plant, T, 100 * seed + run)
            after, before = LinearReference(gf).run(U, Y), LinearReference(old).run(U, Y)
            counts["after"] += int(after.alarm.sum())
            counts["before"] += int(before.alarm.sum())
            counts["warmup_alarms"] += int(after.alarm[: max(g.warmup for g in gf.generators)].sum())
            counts["statistic_samples"] += T * len(gf.evaluators)
    return counts


def test_a_plant_moving_at_switch_on_does_not_alarm(campaign: dict[str, int]) -> None:
    """Ten seeded plants, five runs of 60 samples each from a state ten noise levels away: the alarmed samples stay
    within the Poisson bound (10⁻⁶) of P_f per statistic and sample (8.4 expected, measured 10), where the
    start at one sample's equilibrium alarmed on 190 of the 3000 samples."""
    expected = P_F * campaign["statistic_samples"]
    bound = scipy.stats.poisson.isf(1e-6, expected)
    assert campaign["after"] <= bound, campaign
    assert campaign["before"] > 3 * bound, campaign  # the failure the warm-up removes is there without it
    assert campaign["warmup_alarms"] == 0


def test_the_statistics_run_from_the_sample_after_the_warmup(tmp_path) -> None:  # noqa: ANN001
    plant = random_plant(4)
    gf = fdisyn.design(plant, method="kalman_uio", P_f=P_F)
    n = max(g.warmup for g in gf.generators)
    U, Y = moving(plant, 40, 7)
    res = LinearReference(gf).run(U, Y)
    for j, ev in enumerate(gf.evaluators):
        w = gf.generators[ev.generator].warmup
        assert np.all(res.J[:w, j] == 0.0) and np.all(res.J[w:, j] > 0.0)
    assert not res.alarm[:n].any()
    # the file holds each warm-up and reads back; the design says it, and leaves at most WARMUP_RESIDUE behind
    write_gain_file(gf, tmp_path / "g.json")
    assert [g.warmup for g in read_gain_file(tmp_path / "g.json").generators] == [g.warmup for g in gf.generators]
    assert gf.certificate["bank"]["info"]["warmup_samples"] == {g.name: g.warmup for g in gf.generators}
    for i, g in enumerate(gf.generators):
        w = next(e.W for e in gf.evaluators if e.generator == i)
        assert warmup_length(g, w) == g.warmup and generator_warmup(gf, i) is not None
        # what the warm-up leaves of any initial error: at most WARMUP_RESIDUE of weighted energy, one sample fewer more
        gains, _ = warmup_constants(g, w)
        total = scipy.linalg.solve_discrete_lyapunov(g.Ar.T, g.Cr.T @ w @ g.Cr)
        seen = sum(gains[k] @ g.Cr @ np.linalg.matrix_power(g.Ar, k) for k in range(g.warmup))
        assert np.trace((total - seen) @ np.linalg.pinv(seen, rcond=1e-10, hermitian=True)) <= WARMUP_RESIDUE


def test_a_gap_in_the_warmup_restarts_it() -> None:
    """A non-finite output during the warm-up: every generator starts again at the next valid sample, exactly as a
    diagnoser switched on there."""
    plant = random_plant(4)
    gf = fdisyn.design(plant, method="kalman_uio", P_f=P_F)
    U, Y = moving(plant, 40, 8)
    Y[1, :] = np.nan
    gapped = LinearReference(gf).run(U, Y)
    fresh = LinearReference(gf).run(U[2:], Y[2:])
    np.testing.assert_array_equal(gapped.J[2:], fresh.J)
    np.testing.assert_array_equal(gapped.r[2:], fresh.r)


def test_a_warmup_out_of_range_is_refused() -> None:
    gf = fdisyn.design(random_plant(4), method="kalman_uio", P_f=P_F)
    with pytest.raises(GainFileError, match=r"warmup must be a whole number of samples in 0\.\.1000, found 1001"):
        replace(gf.generators[0], warmup=1001)
    with pytest.raises(GainFileError, match=r"warmup must be a whole number of samples in 0\.\.1000, found True"):
        replace(gf.generators[0], warmup=True)
