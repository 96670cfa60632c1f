"""A linear diagnoser switched on while its plant is moving: each generator's warm-up estimates its initial state by
least squares over its first samples (``fdisyn.runtime.warmup``) and holds its statistics until then.

Truths: the correction against NumPy's least-squares solve of the stacked transient; the alarm count of seeded
random plants (stable and unstable) already moving at switch-on against the Poisson bound of the design's own
false-alarm probability; a gap in the warm-up against a fresh start after it."""

from __future__ import annotations

import warnings
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
    lay = linear_state_layout(gens, gf.evaluators, gf.decision)
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
    gains, m = warmup_constants(a, cr, n, w)
    delta = rng.standard_normal(ns)
    phis = [cr @ np.linalg.matrix_power(a, k) for k in range(n)]
    acc = sum(gains[k] @ (phis[k] @ delta) for k in range(n))
    np.testing.assert_allclose(m @ acc, -np.linalg.matrix_power(a, n) @ delta, atol=1e-12)
    root = np.linalg.cholesky(w).T
    stacked = np.vstack([root @ p for p in phis])
    lstsq = np.linalg.lstsq(stacked, stacked @ delta, rcond=None)[0]
    np.testing.assert_allclose(lstsq, delta, atol=1e-12)


def test_the_equilibrated_correction_does_not_depend_on_the_state_units() -> None:
    """The same transient in states scaled from 10⁻³ to 10⁶ (a user's metres beside micrometres): the Beard filter's
    correction, its information scaled to a unit diagonal, still removes it exactly. A relative cut-off on the unscaled
    information (eigenvalues spread by 10¹⁸), as a linear generator's, calls the small units' directions unseen and
    leaves their transient in the residual."""
    rng = np.random.default_rng(2)
    ns, nr, n = 4, 2, 6
    a = rng.standard_normal((ns, ns))
    a *= 0.8 / max(abs(np.linalg.eigvals(a)))
    cr = rng.standard_normal((nr, ns))
    units = 10.0 ** np.array([-3.0, 0.0, 3.0, 6.0])
    a_s, cr_s = units[:, None] * a / units[None, :], cr / units[None, :]
    delta = units * rng.standard_normal(ns)
    gains, m = warmup_constants(a_s, cr_s, n, None, equilibrate=True)
    acc = sum(gains[k] @ (cr_s @ np.linalg.matrix_power(a_s, k) @ delta) for k in range(n))
    want = -np.linalg.matrix_power(a_s, n) @ delta
    np.testing.assert_allclose((m @ acc) / units, want / units, rtol=0, atol=1e-9 * np.max(np.abs(delta / units)))
    assert warmup_length(a_s, cr_s, None, equilibrate=True) == warmup_length(a, cr, None, equilibrate=True)
    _, unscaled = warmup_constants(a_s, cr_s, n, None)
    assert np.max(np.abs((unscaled @ acc - want) / units)) > 1e-3 * np.max(np.abs(delta / units))


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
        assert warmup_length(g.Ar, g.Cr, w) == g.warmup and generator_warmup(gf, i) is not None
        # what the warm-up leaves of any initial error: at most WARMUP_RESIDUE of weighted energy, one sample fewer more
        gains, _ = warmup_constants(g.Ar, g.Cr, g.warmup, w)
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


# --------------------------------------------------------------------------- the Beard detection filter

BEARD_SEEDS = (1, 2, 4, 5, 6, 7, 12, 13, 15)
"""Seeded random plants of the property campaign a plain Beard filter is designed for (stable and unstable, 2–7 states, sample
times 3 ms–0.9 s, state scalings up to 10⁶)."""


def beard_moving(plant, samples: int, seed: int, scale: float = 10.0) -> tuple[np.ndarray, np.ndarray]:  # noqa: ANN001
    """A discrete plant's fault-free run from ``x₀`` ten process-noise levels away from rest, its input a random walk
    around an offset, its own noise (``Q``, ``R`` per sample)."""
    rng = np.random.default_rng(seed)
    lq = np.linalg.cholesky(np.asarray(plant.Q) + 1e-300 * np.eye(plant.n))
    lr = np.linalg.cholesky(np.asarray(plant.R))
    x = scale * np.sqrt(np.diag(plant.Q)) * rng.standard_normal(plant.n)
    U = 2.0 + 0.3 * np.cumsum(rng.standard_normal((samples, plant.m)), axis=0)
    Y = np.zeros((samples, plant.p))
    for k in range(samples):
        Y[k] = plant.C @ x + plant.D @ U[k] + lr @ rng.standard_normal(plant.p)
        x = plant.A @ x + plant.B @ U[k] + lq @ rng.standard_normal(plant.n)
    return U, Y


@pytest.fixture(scope="module")
def beard_campaign() -> dict[str, float]:
    from fdisyn.synthesis.beard_fdf.payload import beard_from_gain_file
    from fdisyn.synthesis.beard_fdf.reference import beard_reference_run

    from tests.property.campaign import seeded_case

    counts = {"before": 0, "after": 0, "expected": 0.0, "warmup_alarms": 0, "plants": 0}
    for seed in BEARD_SEEDS:
        case = seeded_case("beard_fdf", seed)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # ill-conditioned solves of the scaled plants' Lyapunov equations
            # the plain eigenstructure: the warm-up is the same least squares whatever the eigenvalues (and the NLP is slow)
            flt = beard_from_gain_file(fdisyn.design(case.plant, method="beard_fdf", eigenstructure="plain", **case.options))
        assert flt.warmup >= 1
        old = replace(flt, warmup=0)
        T = flt.warmup + flt.window + 60
        for run in range(RUNS):
            U, Y = beard_moving(case.plant, T, 100 * seed + run)
            after, before = beard_reference_run(flt, U, Y), beard_reference_run(old, U, Y)
            counts["after"] += int(after.alarm.sum())
            counts["before"] += int(before.alarm.sum())
            counts["warmup_alarms"] += int(after.alarm[: flt.warmup + flt.window].sum())
            counts["expected"] += float(flt.design_info["P_f"]) * (T - flt.warmup - flt.window + 1)
        counts["plants"] += 1
    return counts


def test_a_beard_filter_on_a_moving_plant_does_not_alarm(beard_campaign: dict[str, float]) -> None:
    """Nine seeded plants, five fault-free runs each from a state ten noise levels away, the input wandering: the
    alarmed samples stay within the Poisson bound (10⁻⁶) of the design's P_f per sample of a full window (the
    filter's own least-squares start); from one sample's equilibrium, as before the warm-up, they do not."""
    bound = scipy.stats.poisson.isf(1e-6, beard_campaign["expected"])
    assert beard_campaign["plants"] == len(BEARD_SEEDS)
    assert beard_campaign["after"] <= bound, beard_campaign
    assert beard_campaign["before"] > 3 * bound, beard_campaign
    assert beard_campaign["warmup_alarms"] == 0
    print(beard_campaign)


def test_a_gap_in_a_beard_warmup_restarts_it() -> None:
    """A non-finite output inside the Beard filter's warm-up: it starts again at the next valid sample, exactly as a
    filter switched on there; the window fills only after the warm-up."""
    from fdisyn.synthesis.beard_fdf.payload import beard_from_gain_file
    from fdisyn.synthesis.beard_fdf.reference import beard_reference_run

    from tests.property.campaign import seeded_case

    case = seeded_case("beard_fdf", 4)
    flt = beard_from_gain_file(fdisyn.design(case.plant, method="beard_fdf", eigenstructure="plain", **case.options))
    U, Y = beard_moving(case.plant, flt.warmup + flt.window + 30, 8)
    Y[1, 0] = np.nan
    gapped, fresh = beard_reference_run(flt, U, Y), beard_reference_run(flt, U[2:], Y[2:])
    np.testing.assert_array_equal(gapped.J[2:], fresh.J)
    np.testing.assert_array_equal(gapped.r[2:], fresh.r)
    first = flt.warmup + flt.window - 1  # the first sample with a full window of post-warm-up residuals
    assert np.all(fresh.J[:first] == 0.0) and np.all(fresh.J[first:, 0] > 0.0)


def test_warmups_beyond_their_size_limit_are_refused(tmp_path, monkeypatch) -> None:  # noqa: ANN001
    """The warm-ups' constants are multiply-adds of the generated C: a file whose warm-ups hold more than the limit
    is refused where it is read, and the design shortens warm-ups to fit it."""
    from fdisyn.runtime import schema
    from fdisyn.runtime.warmup import warmup_coefficients

    gf = fdisyn.design(random_plant(4), method="kalman_uio", P_f=P_F)
    write_gain_file(gf, tmp_path / "g.json")
    held = sum(warmup_coefficients(g.warmup, g.n_state, g.n_residual) for g in gf.generators)
    monkeypatch.setitem(schema.LIMITS, "warmup_coefficients", held - 1)
    with pytest.raises(GainFileError, match=rf"warm-ups hold {held} constants; at most {held - 1} are supported"):
        read_gain_file(tmp_path / "g.json")
    short = fdisyn.design(random_plant(4), method="kalman_uio", P_f=P_F)
    assert sum(warmup_coefficients(g.warmup, g.n_state, g.n_residual) for g in short.generators) <= held - 1


def test_the_nafdf_switched_on_a_running_ship_does_not_alarm() -> None:
    """The ship's NAFDF (Zhou, Xi & Zhang c. 1991) switched on with the plant anywhere from rest to far above
    its operating range (x(0) = 0, 3, 5; the documented input keeps x near 1.9): its filters start from the
    design's x̂(0) = 0 with P(0) = 100, which covers the unknown state, so the first 200 samples of 30
    fault-free runs raise no more alarm episodes than the WSSR's own P_f = 1e-4 allows (Poisson mean 0.6
    over 6000 samples: more than 5 with probability below 3·10⁻⁴; measured 0), and nothing is isolated."""
    from fdisyn.problems import ship_propulsion as sp
    from fdisyn.simulation.nonlinear import simulate_nonlinear

    dsg = sp.design()
    T = 200
    u = sp.input_signal(T)
    theta = np.tile(sp.plant().theta_nominal, (T, 1))
    episodes = 0
    for x0 in (0.0, 3.0, 5.0):
        for seed in range(10):
            _, y = simulate_nonlinear(sp.plant(), x0=[x0], u=u, theta=theta, rng=np.random.default_rng(seed))
            res = dsg.run(u=u, y=y)
            episodes += int(np.sum(np.diff(np.concatenate([[0.0], res["alarm"]])) > 0))
            assert np.all(res["isolated"] == -1), (x0, seed)
    assert episodes <= scipy.stats.poisson.isf(3e-4, 30 * T * 1e-4), episodes
