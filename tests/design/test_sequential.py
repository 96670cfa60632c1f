"""Sequential detectors of linear diagnosers: CUSUM and windowed GLR statistics, their thresholds from a
false-alarm budget in time, whitening, and the same recursions in the NumPy reference, the CasADi step and
the compiled C, checked against an independent implementation."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import scipy.stats
from fdisyn.app.pipeline import check_export
from fdisyn.codegen.library import codegen
from fdisyn.evaluation.built import Built
from fdisyn.evaluation.metrics import poisson_time_interval
from fdisyn.detectors.sequential import (
    cusum_arl,
    cusum_arl_siegmund,
    cusum_threshold,
    glr_arl,
    glr_threshold,
    lorden_delay,
    split_budget,
)
from fdisyn.runtime.compiled import CompiledDiagnoser
from fdisyn.runtime.errors import ArgumentError, GainFileError
from fdisyn.runtime.gainfile import gain_file_from_dict, read_gain_file, release_level, write_gain_file
from fdisyn.runtime.reference import LinearReference
from fdisyn.synthesis.registry import design
from fdisyn.synthesis.residual import dc_gain_y, long_run_covariance, residual_autocovariances, whitened, whiteness

from tests.helpers import random_plant

# ------------------------------------------------------------------------------------------------ the laws


@pytest.mark.parametrize("info", [0.05, 0.5, 2.0])
@pytest.mark.parametrize("h", [2.0, 5.0, 8.0])
def test_the_cusum_run_length_is_converged_and_near_siegmund(info, h):
    arl = cusum_arl(h, info)
    # Nyström on smooth kernels converges exponentially: twice the nodes agree to round-off of the solve
    assert arl == pytest.approx(cusum_arl(h, info, nodes=192), rel=1e-8)
    # Siegmund's corrected diffusion is O(σ²) off: measured within 6 % up to I = 2 (σ = 2), far closer below
    assert arl == pytest.approx(cusum_arl_siegmund(h, info), rel=0.08 if info > 1 else 0.02)
    delay = cusum_arl(h, info, shift=1.0)
    assert delay == pytest.approx(cusum_arl_siegmund(h, info, shift=1.0), rel=0.08 if info > 1 else 0.02)
    assert delay < arl


def _cusum_run_lengths(rng, info, h, runs, shift=0.0, cap=100_000):
    s = np.zeros(runs)
    t = np.zeros(runs, dtype=int)
    done = np.zeros(runs, dtype=bool)
    for k in range(1, cap):
        s = np.maximum(0.0, s + rng.normal(-info + 2 * info * shift, math.sqrt(2 * info), runs))
        new = (s > h) & ~done
        t[new], done = k, done | new
        if done.all():
            return t
    raise AssertionError("runs did not stop")


@pytest.mark.parametrize("shift", [0.0, 1.0])
def test_the_cusum_threshold_gives_its_run_length_by_monte_carlo(shift):
    info, target = 0.5, 300.0
    h = cusum_threshold(target, info)
    assert cusum_arl(h, info) == pytest.approx(target, rel=1e-9)
    expected = cusum_arl(h, info, shift=shift)
    t = _cusum_run_lengths(np.random.default_rng(7), info, h, 4000, shift)
    # the sample mean of 4000 run lengths: within 5 standard errors
    assert abs(t.mean() - expected) <= 5 * t.std() / math.sqrt(len(t)), (t.mean(), expected)


@pytest.mark.parametrize(("window", "target"), [(25, 1000), (60, 1000)])
def test_the_glr_threshold_approximation_against_monte_carlo(window, target):
    """Siegmund & Venkatraman's approximation is continuous in the onset; by Monte Carlo the GLR's mean run
    length is 0.83–1.04 of it for windows of 25–100 and ARL 10³–2·10⁴ (documented in ``glr_arl``)."""
    h = glr_threshold(target, window)
    assert glr_arl(h, window) == pytest.approx(target, rel=1e-9)
    rng = np.random.default_rng(3)
    runs = 1500  # a standard error of ~2.6 % of the run length: the band below is ~5 of them wide on each side
    d = np.zeros((runs, window))
    w = 0.5 / np.arange(1, window + 1)
    t = np.zeros(runs, dtype=int)
    done = np.zeros(runs, dtype=bool)
    k = 0
    while not done.all():
        k += 1
        z = rng.standard_normal(runs)
        d[:, 1:] = d[:, :-1] + z[:, None]
        d[:, 0] = z
        new = (np.max(d * d * w, axis=1) > h) & ~done
        t[new], done = k, done | new
    ratio, se = t.mean() / target, t.std() / math.sqrt(runs) / target
    assert 0.75 - 5 * se <= ratio <= 1.15 + 5 * se, ratio


def test_budget_split_and_lorden_bound():
    assert split_budget(6000.0, 4) == 24000.0
    assert lorden_delay(math.e**10, 0.5) == pytest.approx(20.0)
    with pytest.raises(ArgumentError):
        split_budget(0.0, 4)


def test_garwood_interval_holds_the_mean_time_between_events():
    # the exact Poisson interval: 10 events in 100 s; no event gives a lower end only
    lo, hi = poisson_time_interval(10, 100.0)
    assert lo == pytest.approx(100.0 / (scipy.stats.chi2.ppf(0.975, 22) / 2)) and hi == pytest.approx(100.0 / (scipy.stats.chi2.ppf(0.025, 20) / 2))
    assert poisson_time_interval(0, 100.0)[1] is None


# ------------------------------------------------------------------------------------------------ whitening


def test_whitening_makes_the_residual_white_and_keeps_its_information():
    """The whitened residual's autocovariances (of the composed generator, computed afresh) vanish, and a
    sensor bias brings it the same information as the long-run law of the coloured residual gives."""
    plant = random_plant(1)
    gf = design(plant, "uio_pole_placement", poles=[0.9, 0.85, 0.8, -0.7, 0.75])
    gen = gf.generators[0]
    assert whiteness(gen, plant) > 0.1  # coloured
    white = whitened(gen, plant)
    assert whiteness(white, plant) <= 1e-8
    sig = residual_autocovariances(white, plant, 0)[0]
    s_long = long_run_covariance(gen, plant)
    for j in gen.outputs_used:
        mu_raw, mu_white = dc_gain_y(gen)[:, j], dc_gain_y(white)[:, j]
        i_raw = 0.5 * mu_raw @ np.linalg.pinv(s_long, rcond=1e-9) @ mu_raw
        i_white = 0.5 * mu_white @ np.linalg.pinv(sig, rcond=1e-9) @ mu_white
        assert i_white == pytest.approx(i_raw, rel=1e-6)


# ------------------------------------------------------------------------------------------------ the recursions


def _simulate(plant, rng, n):
    """``n`` samples of the plant at rest with its own Gaussian noise and a random unknown input, u = 0."""
    lq, lr = np.linalg.cholesky(plant.Q), np.linalg.cholesky(plant.R)
    x = np.zeros(plant.n)
    Y = np.empty((n, plant.p))
    for k in range(n):
        Y[k] = plant.C @ x + lr @ rng.standard_normal(plant.p)
        x = plant.A @ x + lq @ rng.standard_normal(plant.n) + plant.E @ rng.standard_normal(plant.q)
    return np.zeros((n, plant.m)), Y


def _independent_statistics(gf, r, skipped):
    """CUSUM and GLR from the residual history, written from the definitions (not the shift registers).
    A skipped sample (a non-finite input: the bank here is one generator on every output) does not enter."""
    offsets = np.cumsum([0] + [g.n_residual for g in gf.generators])
    out = np.zeros((r.shape[0], len(gf.evaluators)))
    sums = {j: np.zeros((r.shape[0], 2 * e.directions.shape[0])) for j, e in enumerate(gf.evaluators) if e.kind == "cusum"}
    valid = np.flatnonzero(~skipped)
    for j, ev in enumerate(gf.evaluators):
        rg = r[valid, offsets[ev.generator] : offsets[ev.generator + 1]]
        if ev.kind == "cusum":
            up = np.zeros(ev.directions.shape[0])
            down = np.zeros(ev.directions.shape[0])
            for k in range(len(rg)):
                up = np.clip(up + ev.directions @ rg[k] - ev.drift, 0.0, 2 * ev.threshold)
                down = np.clip(down - ev.directions @ rg[k] - ev.drift, 0.0, 2 * ev.threshold)
                out[valid[k], j] = max(up.max(), down.max())
                sums[j][valid[k]] = np.concatenate([up, down])
        else:
            m = ev.window
            a = ev.directions.reshape(-1, m, rg.shape[1])  # hypothesis, lag, residual
            c = ev.information.reshape(-1, m)
            padded = np.vstack([np.zeros((m, rg.shape[1])), rg])  # no residual before the first sample
            for k in range(len(rg)):
                best = 0.0
                for n in range(1, m + 1):  # onset n samples ago: lags 0..n−1 over r(k−n+1..k)
                    d = np.einsum("hlr,lr->h", a[:, :n], padded[m + k - n + 1 : m + k + 1])
                    keep = c[:, n - 1] > 1e-12 * c[:, -1]
                    if keep.any():
                        best = max(best, float(np.max(d[keep] ** 2 / (2 * c[keep, n - 1]))))
                out[valid[k], j] = best
    return out, sums


def _alarms(gf, J, skipped, sums=None):
    """The held alarm of a sequential statistic: a GLR's raised above the threshold and held down to the release
    level; a CUSUM's while any sum that crossed the threshold has not returned to 0 (``sums``: its sums per
    sample). A skipped sample raises no alarm and leaves the held one as it was."""
    flags = np.zeros_like(J, dtype=int)
    for j, ev in enumerate(gf.evaluators):
        on = 0
        latch = None
        for k in range(len(J)):
            if skipped[k]:
                continue
            if ev.kind == "cusum":
                s = sums[j][k]
                latch = (s > ev.threshold) | ((latch if latch is not None else np.zeros(len(s), bool)) & (s > 0))
                on = int(latch.any())
            else:
                on = int(J[k, j] > ev.threshold or (on and J[k, j] > release_level(ev)))
            flags[k, j] = on
    return flags.any(axis=1).astype(int)


@pytest.mark.parametrize("detector", ["cusum", "glr"])
def test_reference_casadi_and_c_agree_with_an_independent_implementation(tmp_path, detector):
    plant = random_plant(1, radius=0.8)  # stable: a run from rest stays stationary
    extra = {"window": 8} if detector == "glr" else {}
    # one generator on all outputs (the bank is not what this test is about)
    gf = design(plant, "uio_pole_placement", poles=[0.9, 0.85, 0.8, -0.7, 0.75], detector=detector, arl0=100.0,
                bank=[list(plant.outputs)], **extra)
    assert all(e.kind == detector for e in gf.evaluators)
    d = tmp_path / detector
    write_gain_file(gf, d / "gains.json")
    assert read_gain_file(d / "gains.json").to_dict() == gf.to_dict()
    art = codegen(d)
    built = Built(gain_file=gf, directory=d, artifacts=art)
    U, Y = _simulate(plant, np.random.default_rng(11), 1500)
    Y[700:, 0] += 3.0 * math.sqrt(plant.R[0, 0])  # a 3σ bias: the statistics rise, alarm and hold
    Y[100, 1], U[300, 0] = np.nan, np.inf  # skipped samples
    chk = check_export(built, U, Y)
    assert chk.passed, chk.references
    res = built.diagnoser.run(U, Y)
    ref = LinearReference(gf).run(U, Y)
    skipped = ref.status == 1
    assert skipped.sum() == 2
    # the generator's warm-up: its first samples enter no statistic and raise no alarm (the skips come after it)
    warm = gf.generators[0].warmup
    assert 1 <= warm < 100 and not ref.alarm[:warm].any()
    skipped[:warm] = True
    indep, sums = _independent_statistics(gf, ref.r, skipped)
    # J: sums of ~10² terms of size ≤ 2h; 1e-10 of h is far above their round-off and far below any decision
    scale = max(e.threshold for e in gf.evaluators)
    assert np.max(np.abs(res.J - indep)) <= 1e-10 * scale
    np.testing.assert_array_equal(res.alarm, _alarms(gf, indep, skipped, sums))
    assert res.alarm[700:].mean() > 0.5 > res.alarm[:700].mean()  # the bias is seen, the noise mostly not


# ------------------------------------------------------------------------------------------------ the budget


def test_the_false_alarm_budget_holds_on_the_design_model(tmp_path):
    """Fault-free runs of the design model (its own Gaussian noise): the mean time between false alarms of a
    bank split by Bonferroni is at least the budget and at most the budget times the number of statistics
    (each statistic alone has that), plus the time an alarm is held, within Garwood's 99.9 % interval."""
    plant = random_plant(3, n=3, p=3, q=1)
    arl0 = 8.0  # s, Ts = 0.1: 80 samples for the bank, 240 for each of the three statistics
    bank = {"a": ["y0", "y1"], "b": ["y1", "y2"], "c": ["y0", "y2"]} if plant.outputs == ("y0", "y1", "y2") else None
    gf = design(plant, "kalman_uio", detector="cusum", arl0=arl0, bank=bank)
    d = tmp_path / "c"
    write_gain_file(gf, d / "gains.json")
    art = codegen(d)
    diag = CompiledDiagnoser(art.library, gf)
    rng = np.random.default_rng(5)
    runs, n = 20, 4000
    episodes, held = 0, 0
    for _ in range(runs):
        a = diag.run(*_simulate(plant, rng, n)).alarm[200:]  # after the start-up
        episodes += int(np.sum(a[1:] & ~a[:-1].astype(bool)) + a[0])
        held += int(a.sum())
    exposure = runs * (n - 200) * plant.Ts
    lo, hi = poisson_time_interval(episodes, exposure, level=0.999)
    mean_hold = held / max(episodes, 1) * plant.Ts
    assert hi is not None and hi >= arl0, (episodes, lo, hi)
    assert lo <= len(gf.evaluators) * arl0 + mean_hold, (episodes, lo, hi)


# ------------------------------------------------------------------------------------------------ errors


def test_options_of_the_sequential_detectors_are_checked():
    plant = random_plant(1)
    with pytest.raises(ArgumentError, match=r"persistence = 3 with detector 'cusum'"):
        design(plant, "kalman_uio", detector="cusum", persistence=3)
    with pytest.raises(ArgumentError, match=r"detector = 'glr' but evaluator = 'wssr'"):
        design(plant, "kalman_uio", detector="glr", evaluator="wssr")
    with pytest.raises(ArgumentError, match=r"window = 5 needs detector = 'wssr' or 'glr'"):
        design(plant, "kalman_uio", detector="cusum", window=5)
    with pytest.raises(ArgumentError, match=r"option arl0 = -1: expected a positive number of seconds"):
        design(plant, "kalman_uio", detector="cusum", arl0=-1)
    with pytest.raises(ArgumentError, match=r"min_fault names \['nope'\]"):
        design(plant, "kalman_uio", detector="cusum", min_fault={"nope": 1.0})


def test_arl0_sets_the_chi2_threshold_by_the_split_budget():
    plant = random_plant(1)
    gf = design(plant, "kalman_uio", arl0=50.0)
    share = split_budget(50.0 / plant.Ts, len(gf.evaluators))
    for e in gf.evaluators:
        assert e.P_f == pytest.approx(1.0 / share) and e.threshold == pytest.approx(scipy.stats.chi2.isf(1.0 / share, e.dof))


@pytest.fixture(scope="module")
def cusum_gain_file():
    """A CUSUM bank of a random plant, designed once for the corruptions below (its thresholds solve Page's
    integral equation: seconds of work each time)."""
    return design(random_plant(1), "kalman_uio", detector="cusum", arl0=5.0)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda e: e.update(drift=[-1.0] * len(e["drift"])), "drift must hold one positive number per direction"),
        (lambda e: e.update(directions=[row[:-1] for row in e["directions"]]), "directions: expected"),
        (lambda e: e.pop("directions"), "directions"),
        (lambda e: e.update(window=3), "window must be 1 for a 'cusum' evaluator"),
    ],
)
def test_a_corrupt_cusum_evaluator_is_refused_with_one_line(cusum_gain_file, edit, message):
    doc = json.loads(json.dumps(cusum_gain_file.to_dict()))
    edit(doc["evaluators"][0])
    with pytest.raises(GainFileError) as info:
        gain_file_from_dict(doc)
    assert message in str(info.value) and "\n" not in str(info.value), str(info.value)


def test_a_sequential_file_with_persistence_is_refused():
    gf = design(random_plant(1), "kalman_uio", detector="glr", arl0=5.0, window=6)
    doc = json.loads(json.dumps(gf.to_dict()))
    doc["decision"]["persistence"] = 2
    with pytest.raises(GainFileError, match="persistence must be 1 with a sequential"):
        gain_file_from_dict(doc)
    doc = json.loads(json.dumps(gf.to_dict()))
    doc["evaluators"][0]["information"] = doc["evaluators"][0]["information"][::-1]
    with pytest.raises(GainFileError, match="nondecreasing cumulative informations"):
        gain_file_from_dict(doc)


# ------------------------------------------------------------------------------------------------ every entry point


def test_plant_files_and_problems_take_the_detector_and_the_budget(tmp_path, data_dir):
    """A plant file's ``[design] detector``/``arl0`` and a built-in problem's options reach the design; a bad
    value is one line naming the key."""
    from fdisyn.simulation.plant_file import load_spec
    from fdisyn.problems.sampled_data_example import PROBLEM
    from fdisyn.runtime.errors import SpecError

    text = (data_dir / "dc_motor.toml").read_text(encoding="utf-8")
    path = tmp_path / "motor.toml"
    path.write_text(text.replace('arl0 = 3600.0 ', 'detector = "glr"\narl0 = 30.0\n# '), encoding="utf-8")
    gf = load_spec(path).design()
    assert all(e.kind == "glr" for e in gf.evaluators)
    assert gf.certificate["bank"]["info"]["arl0_s"] == 30.0
    path.write_text(text.replace('arl0 = 3600.0 ', 'detector = "cusum"\npersistence = 2\n# '), encoding="utf-8")
    with pytest.raises(SpecError, match=r"\[design\]\.persistence = 2 with detector 'cusum'") as info:
        load_spec(path).design()
    assert "\n" not in str(info.value)
    gf = PROBLEM.design("direct", detector="cusum", arl0=1000.0)
    assert gf.name == "sampled_data_example_direct_cusum" and gf.evaluators[0].kind == "cusum"
    with pytest.raises(ArgumentError, match=r"option detector = 'sprt': expected 'chi2', 'wssr', 'cusum' or 'glr'"):
        PROBLEM.design("direct", detector="sprt")


def test_the_glr_state_estimates_the_onset_and_size_of_a_bias():
    """A bias of 2 minimum faults on one sensor from sample 600: at sample 700 the GLR of a generator reading that
    sensor places the onset ≈ 100 samples ago and the size ≈ 2 (the residual noise leaves a few samples and a
    few per cent)."""
    from fdisyn.runtime.monitor import Monitor

    plant = random_plant(1, radius=0.8)
    gf = design(plant, "kalman_uio", detector="glr", arl0=50.0, window=150, bank=[list(plant.outputs)])  # one generator
    U, Y = _simulate(plant, np.random.default_rng(2), 700)
    Y[600:, 0] += 2.0 * math.sqrt(plant.R[0, 0])
    mon = Monitor(gf)
    mon.run(U, Y)
    est = {e.statistic: e for e in mon.change_estimates()}
    seen = est[gf.step.statistic_names[0]]
    assert seen.hypothesis.split("|")[0] == "y0" and abs(seen.onset_samples_ago - 100) <= 10, seen
    assert seen.size == pytest.approx(2.0, rel=0.25), seen


def test_the_export_check_follows_a_cusum_over_its_memory(tmp_path, monkeypatch):
    """A CUSUM sums its terms until it is clamped, so the residuals' rounding (large terms: a motor at 100 rad/s,
    residuals of 0.05) adds up over that memory: C and the NumPy reference, which round differently, differ by
    ~10⁻⁹ on J ≈ 2 and pass; a term wrong by 10⁻⁷ of the threshold, as a mistyped constant of the update would
    make it, adds up the same way and fails (10⁻⁸ is at the tolerance here: the check's sensitivity on this plant,
    five orders below any decision)."""
    import dataclasses

    import fdisyn
    from fdisyn.app.pipeline import export_trace
    from fdisyn.evaluation.built import build

    a = np.array([[-100.0, -5.0, 0.0], [50.0, -0.1, 0.0], [0.0, 1.0, 0.0]])
    plant = fdisyn.LinearPlant.create(A=a, B=[[100.0], [0.0], [0.0]], C=np.eye(3), E=[[0.0], [-1000.0], [0.0]],
                                      Q=np.diag([1e-4, 1e-3, 1e-10]), R=np.diag([1e-4, 2.5e-3, 1e-6]), outputs=["i", "w", "th"])  # fmt: skip
    prob = fdisyn.problem(plant, name="motor", Ts=0.001, designs={"cusum": {"method": "kalman_uio", "detector": "cusum"}},
                          simulation={"duration": 4.0, "inputs": [{"kind": "step", "amplitude": 6.0, "start": 0.5}]},
                          scenarios=[{"name": "w_bias", "duration": 4.0, "fault": "w", "onset": 2.0,
                                      "sensor_faults": [{"sensor": "w", "kind": "offset", "value": 1.0}]}])  # fmt: skip
    U, Y = export_trace(prob)
    built = build(prob, "cusum", tmp_path / "cusum")
    chk = check_export(built, U, Y)
    assert chk.passed, chk.references
    good = built.diagnoser.run(U, Y)
    h = np.array([e.threshold for e in built.gain_file.evaluators])
    J, run = good.J.copy(), np.zeros(len(h))
    for k in range(len(J)):  # each sum off by 1e-7 h per term since it was last clamped (at 0 or 2h)
        clamped = (good.J[k] == 0.0) | (good.J[k] == 2.0 * h)
        run = np.where(clamped, 0.0, run + 1e-7 * h)
        J[k] += run
    monkeypatch.setattr(built.diagnoser, "run", lambda u, y: dataclasses.replace(good, J=J))
    assert not check_export(built, U, Y).passed
