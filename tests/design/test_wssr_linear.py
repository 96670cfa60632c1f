"""The WSSR evaluator of linear diagnosers (Long & Wang, Aeroengine 43(5), 2017, section 2): its law, its
threshold, and the same windowed statistic in the NumPy reference, the CasADi step and the compiled C."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import scipy.stats
from fdisyn.app.pipeline import check_export
from fdisyn.codegen.library import codegen
from fdisyn.codegen.step import step_function
from fdisyn.evaluation.built import Built
from fdisyn.runtime.errors import ArgumentError, GainFileError
from fdisyn.runtime.gainfile import (
    Decision,
    Evaluator,
    GainFile,
    Generator,
    StepSpec,
    gain_file_from_dict,
    read_gain_file,
    write_gain_file,
)
from fdisyn.runtime.layout import linear_state_layout
from fdisyn.runtime.reference import LinearReference
from fdisyn.synthesis.linear_kind import linear_recovery_samples
from fdisyn.synthesis.registry import design
from fdisyn.synthesis.residual import internal_form, residual_autocovariances, residual_covariance

from tests.helpers import random_plant


def _window_covariance(R: np.ndarray, n: int) -> np.ndarray:
    """Covariance of ``[r(k); …; r(k−n+1)]``: blocks ``R(j − i)``, ``R(−τ) = R(τ)ᵀ``."""
    p = R.shape[1]
    out = np.empty((n * p, n * p))
    for i in range(n):
        for j in range(n):
            out[i * p : (i + 1) * p, j * p : (j + 1) * p] = R[j - i] if j >= i else R[i - j].T
    return out


# ------------------------------------------------------------------------------------------------ the law


@pytest.mark.parametrize("window", [1, 4, 12])
def test_the_innovation_of_the_minimum_variance_uio_gives_chi2_of_n_dof(window):
    plant = random_plant(1)
    gf = design(plant, "kalman_uio", P_f=1e-3, evaluator="wssr", window=window)
    for ev, gen in zip(gf.evaluators, gf.generators, strict=True):
        R = residual_autocovariances(gen, plant, max(window - 1, 3))
        np.testing.assert_allclose(R[0], ev.Sigma_r, rtol=1e-9, atol=1e-12 * np.abs(ev.Sigma_r).max())
        assert np.abs(R[1:]).max() <= 1e-8 * np.abs(R[0]).max()  # white: an innovation
        assert ev.kind == "wssr" and ev.window == window
        assert ev.threshold == pytest.approx(scipy.stats.chi2.isf(1e-3, window * ev.dof), rel=1e-6)


def test_a_coloured_residual_threshold_matches_a_monte_carlo_of_the_quadratic_form():
    plant = random_plant(1)
    window, p_f, draws = 6, 0.02, 400_000
    gf = design(plant, "uio_pole_placement", poles=[0.9, 0.85, 0.8, -0.7, 0.75], P_f=p_f, evaluator="wssr", window=window)
    ev, gen = gf.evaluators[0], gf.generators[0]
    R = residual_autocovariances(gen, plant, window - 1)
    assert np.abs(R[1]).max() > 0.1 * np.abs(R[0]).max()  # far from white
    np.testing.assert_allclose(R[0], residual_covariance(gen, plant), rtol=1e-9)
    chi2_value = scipy.stats.chi2.isf(p_f, window * ev.dof)
    assert abs(ev.threshold / chi2_value - 1.0) > 0.1  # the coloured law moves the threshold

    rng = np.random.default_rng(20170905)
    cov = _window_covariance(R, window)
    lam, vec = np.linalg.eigh(cov)
    factor = vec * np.sqrt(np.clip(lam, 0.0, None))
    stacked = rng.standard_normal((draws, cov.shape[0])) @ factor.T
    p = R.shape[1]
    J = sum(np.einsum("ki,ij,kj->k", stacked[:, l * p : (l + 1) * p], ev.W, stacked[:, l * p : (l + 1) * p]) for l in range(window))
    # binomial: P(|freq − P_f| > 5 σ) < 6e-7 for independent draws
    sigma = np.sqrt(p_f * (1.0 - p_f) / draws)
    assert abs(float(np.mean(J > ev.threshold)) - p_f) <= 5.0 * sigma
    assert abs(float(np.mean(J > chi2_value)) - p_f) > 5.0 * sigma  # the white-noise quantile would be wrong


def test_the_autocovariance_is_that_of_the_simulated_residual():
    """``R(1)``, ``R(2)`` of a coloured residual against a long simulation of plant + generator (noise Q, R)."""
    plant = random_plant(1)
    gen = design(plant, "uio_pole_placement", poles=[0.9, 0.85, 0.8, -0.7, 0.75]).generators[0]
    form = internal_form(gen, plant)
    R = residual_autocovariances(gen, plant, 2)
    rng = np.random.default_rng(7)
    steps = 200_000
    w = rng.multivariate_normal(np.zeros(plant.n), plant.Q, size=steps)
    v = rng.multivariate_normal(np.zeros(plant.p), plant.R, size=steps)
    z = np.zeros(form.A.shape[0])
    bw = np.vstack([np.eye(plant.n), np.zeros((gen.n_state, plant.n))])
    bv = np.vstack([np.zeros((plant.n, plant.p)), gen.By])
    r = np.empty((steps, gen.n_residual))
    for k in range(steps):
        r[k] = form.C @ z + gen.Dy @ v[k]
        z = form.A @ z + bw @ w[k] + bv @ v[k]
    r = r[1000:]
    scale = np.sqrt(np.outer(np.diag(R[0]), np.diag(R[0])))
    for tau in range(3):
        emp = r[tau:].T @ r[: len(r) - tau] / (len(r) - tau)
        assert np.abs(emp - R[tau]).max() <= 0.05 * scale.max(), tau


def test_an_integrating_plant_mode_the_residual_does_not_see_is_left_out():
    """The internal form of an integrating plant is not stable; the residual's law is that of its stable part."""
    plant = random_plant(3)
    a = plant.A.copy()
    a[0, :], a[:, 0] = 0.0, 0.0
    a[0, 0] = 1.0
    integrating = dataclasses.replace(plant, A=a)
    assert np.max(np.abs(internal_form(design(integrating, "kalman_uio").generators[0], integrating).A.diagonal())) >= 1.0
    gf = design(integrating, "kalman_uio", P_f=1e-3, evaluator="wssr", window=3)
    assert all(e.threshold == pytest.approx(scipy.stats.chi2.isf(1e-3, 3 * e.dof), rel=1e-6) for e in gf.evaluators)


# ------------------------------------------------------------------------------------------------ runtime


def _toy(window: int = 3, persistence: int = 1, threshold: float = 20.0) -> GainFile:
    """Two generators ``r_i = y_i`` (``q_i = y_i²``): generator 0 has a WSSR statistic, generator 1 a χ² one."""
    gens = []
    for i in range(2):
        dy = np.zeros((1, 2))
        dy[0, i] = 1.0
        by = np.zeros((1, 2))
        by[0, i] = 0.5
        gens.append(Generator.from_canonical(name=f"g{i}", outputs_used=(i,), Ar=[[0.5]], Bu=np.zeros((1, 1)), By=by, Cr=np.zeros((1, 1)), Du=np.zeros((1, 1)), Dy=dy))
    evs = [
        Evaluator(kind="wssr", generator=0, P_f=0.05, dof=1, threshold=threshold, Sigma_r=np.eye(1), W=np.eye(1), window=window),
        Evaluator(kind="chi2", generator=1, P_f=0.05, dof=1, threshold=4.0, Sigma_r=np.eye(1), W=np.eye(1)),
    ]
    lay = linear_state_layout(gens, evs)
    return GainFile(
        kind="linear", name="toy", problem="toy", design="toy", Ts=0.1, inputs=("u",), outputs=("y0", "y1"), faults=("y0", "y1", "both"),
        step=StepSpec(nu=1, ny=2, nr=2, nj=2, nstate=lay.size, init_state=np.zeros(lay.size), residual_names=("r0", "r1"), statistic_names=("J0", "J1")),
        plant={"A": np.eye(1) * 0.5, "B": np.zeros((1, 1)), "C": np.ones((2, 1)), "D": np.zeros((2, 1)), "E": np.zeros((1, 0)), "Q": np.eye(1), "R": np.eye(2)},
        generators=tuple(gens), evaluators=tuple(evs),
        decision=Decision(kind="signature_table", signatures=np.array([[1, 0], [0, 1], [1, 1]]), persistence=persistence),
        certificate={"passed": True},
    )


def test_the_window_sums_the_last_valid_samples_and_skips_status_1_samples():
    gf = _toy(window=3)
    y0 = [1.0, 2.0, np.nan, 3.0, np.inf, 4.0, 0.0, 0.0, 0.0]
    Y = np.column_stack([y0, np.ones(len(y0))])
    U = np.zeros((len(y0), 1))
    U[7, 0] = np.nan  # a non-finite input: every generator skips the sample
    expected = [1.0, 5.0, 0.0, 14.0, 0.0, 29.0, 25.0, 0.0, 16.0]  # start-up: fewer than 3 terms; skipped: 0
    ref = LinearReference(gf).run(U, Y)
    np.testing.assert_array_equal(ref.J[:, 0], expected)
    np.testing.assert_array_equal(ref.status, [0, 0, 1, 0, 1, 0, 0, 1, 0])
    np.testing.assert_array_equal(ref.alarm, [0, 0, 0, 0, 0, 1, 1, 0, 0])  # 29 and 25 > 20
    lay = linear_state_layout(gf.generators, gf.evaluators, gf.decision)
    np.testing.assert_array_equal(ref.state[lay["window0"]], [0.0, 0.0, 16.0])  # newest first: k = 8, 6, 5
    # the CasADi step, sample by sample, agrees exactly
    fn = step_function(gf)
    st = gf.step.init_state.copy()
    for k in range(len(y0)):
        out = fn(st, U[k], Y[k])
        st = np.asarray(out[0]).ravel()
        assert float(out[2][0]) == expected[k], k
    np.testing.assert_array_equal(st, ref.state)


def test_a_chi2_gain_file_is_written_without_window_and_reads_back_with_window_1(tmp_path):
    gf = _toy(window=4)
    doc = gf.to_dict()
    assert doc["evaluators"][0]["window"] == 4 and "window" not in doc["evaluators"][1]
    back = read_gain_file(write_gain_file(gf, tmp_path / "gains.json"))
    assert [e.window for e in back.evaluators] == [4, 1]
    assert linear_state_layout(back.generators, back.evaluators).size == gf.step.nstate


@pytest.mark.parametrize(
    ("index", "edit", "message"),
    [
        (0, {"window": 0}, "window must be a whole number of samples in 1..100000, found 0"),
        (0, {"window": 100_001}, "in 1..100000, found 100001"),
        (0, {"window": 2.5}, "field 'window' must be an integer, found 2.5"),
        (0, {"window": "3"}, "field 'window' must be an integer, found '3'"),
        (0, {"window": True}, "field 'window' must be an integer, found True"),
        (0, {"window": None}, "missing field 'window'"),
        (1, {"window": 2}, "window must be 1 for a 'chi2' evaluator"),
        (0, {"kind": "sprt"}, "kind 'sprt' is not supported (supported: 'chi2', 'wssr', 'cusum', 'glr')"),
        (0, {"kind": "cusum"}, "missing field 'directions'"),
        (0, {"window": 5}, "step sizes"),  # the state no longer matches the window
    ],
)
def test_bad_evaluator_values_are_refused_with_one_line(index, edit, message):
    doc = json.loads(json.dumps(_toy(window=3).to_dict()))
    for key, value in edit.items():
        if value is None:
            del doc["evaluators"][index][key]
        else:
            doc["evaluators"][index][key] = value
    with pytest.raises(GainFileError) as info:
        gain_file_from_dict(doc)
    text = str(info.value)
    assert message in text and "\n" not in text, text


def test_the_options_refuse_a_window_without_wssr():
    plant = random_plant(1)
    with pytest.raises(ArgumentError, match=r"option window = 5 needs detector = 'wssr' or 'glr'"):
        design(plant, "kalman_uio", window=5)
    with pytest.raises(ArgumentError, match=r"option evaluator = 'bogus': expected 'chi2', 'wssr', 'cusum' or 'glr'"):
        design(plant, "kalman_uio", evaluator="bogus")
    with pytest.raises(ArgumentError, match=r"option window = 0: expected a whole number of samples in 1..100000"):
        design(plant, "kalman_uio", evaluator="wssr", window=0)
    gf = design(plant, "kalman_uio")  # the default: χ², as before
    assert all(e.kind == "chi2" and e.window == 1 for e in gf.evaluators)
    assert "window" not in json.dumps(gf.to_dict()["evaluators"])


def test_reference_casadi_and_compiled_c_agree_on_random_data_with_nan_samples(tmp_path):
    plant = random_plant(1)
    gf = design(plant, "uio_pole_placement", poles=[0.9, 0.85, 0.8, -0.7, 0.75], evaluator="wssr", window=7, P_f=1e-3)
    d = tmp_path / "wssr"
    write_gain_file(gf, d / "gains.json")
    art = codegen(d)
    built = Built(gain_file=gf, directory=d, artifacts=art)
    rng = np.random.default_rng(11)
    n = 3000
    U = rng.normal(size=(n, plant.m))
    Y = rng.normal(size=(n, plant.p))
    Y[100, 0], Y[500, 1], Y[900, :] = np.nan, np.inf, -np.inf
    U[1200, 0] = np.nan
    Y[1201:1260, 0] = np.nan
    chk = check_export(built, U, Y)
    assert chk.passed, chk.references
    res = built.diagnoser.run(U, Y)
    ref = LinearReference(gf).run(U, Y)
    # check_export above holds r and J to their rounding-error scale; this normwise bound only catches gross
    # errors: the state to 1e-12, J (a window of 7 squared residuals, each carrying the generator's round-off,
    # ~κ·ε ≈ 1e3·2.2e-16, twice for the square) to 7·2·2.2e-13 ≈ 3e-12, with a 30× margin
    for name, tol in (("J", 1e-10), ("state", 1e-12)):
        a, b = getattr(res, name), getattr(ref, name)
        assert np.linalg.norm(a - b) <= tol * np.linalg.norm(b), name
    np.testing.assert_array_equal(res.alarm, ref.alarm)
    assert linear_recovery_samples(gf) > 6  # the window holds a fault's last samples 6 more samples
