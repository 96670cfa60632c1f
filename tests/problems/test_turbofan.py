"""The turbofan of Long & Wang, Aeroengine 43(5), 2017, section 2: the transcribed model's structural facts,
the grouping the paper made by hand, and the unknown-input direction estimated from the stand-in truth."""

from __future__ import annotations

import numpy as np
import pytest
from fdisyn.problems import turbofan as tf
from fdisyn.runtime.errors import ExistenceError
from fdisyn.synthesis.uio_gos import estimate_unknown_input, output_groups


def _idx(names, pool):
    return [pool.index(x) for x in names]


def test_rank_c_is_eight_and_both_paper_groups_complete_to_rank_twelve() -> None:
    # exact: the dependency T3 = T25 + (0.02969/0.04786) P3 holds between printed numbers, so rank is not tolerance-dependent
    s = np.linalg.svd(tf.C, compute_uv=False)
    assert np.linalg.matrix_rank(tf.C) == 8 and s[8] < 1e-14 * s[0]
    virtual = np.eye(12)[_idx(tf.PAPER_VIRTUAL, tf.STATES)]
    for group in tf.PAPER_GROUPS:
        rows = tf.C[_idx(group, tf.OUTPUTS)]
        assert np.linalg.matrix_rank(rows) == 8
        assert np.linalg.matrix_rank(np.vstack([rows, virtual])) == 12


def test_the_search_finds_the_paper_grouping_first() -> None:
    sols = output_groups(tf.C, outputs=tf.OUTPUTS)
    paper = {tuple(_idx(g, tf.OUTPUTS)) for g in tf.PAPER_GROUPS}
    assert all(len(s.groups) == 2 for s in sols)  # 9 sensors, bases of 8: two groups, no fewer
    assert set(sols[0].groups) == paper
    assert {frozenset(s.groups) for s in sols} >= {frozenset(paper)}


def test_open_loop_is_stable_with_engine_time_scales() -> None:
    lam = np.linalg.eigvals(tf.A)
    assert np.all(lam.real < 0)
    # slowest ≈ spool inertia (about 1 s), fastest ≈ gas-path volumes (about 10 ms)
    assert 0.3 < -lam.real.max() < 3 and 30 < -lam.real.min() < 200


def test_transcription_table_matches_the_matrices() -> None:
    import re

    rows = {"A": tf.STATES, "B": tf.STATES, "C": tf.OUTPUTS}
    cols = {"A": tf.STATES, "B": tf.INPUTS, "C": tf.STATES}
    checked = 0
    for position, _printed, value, _why in tf.TRANSCRIPTION:
        m = re.fullmatch(r"([ABC])\[(\w+), (\w+)\]", position)
        if m and re.fullmatch(r"-?[0-9.]+", value):
            mat = {"A": tf.A, "B": tf.B, "C": tf.C}[m[1]]
            assert mat[rows[m[1]].index(m[2]), cols[m[1]].index(m[3])] == float(value), position
            checked += 1
    assert checked >= 15


def _training() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n = int(120 / tf.TS)
    t = np.arange(n) * tf.TS
    u = np.zeros((n, 4))
    for t0, v in [(5, 1), (25, 0.3), (40, -0.5), (60, 0.8), (80, 0.0), (95, 1.2), (110, 0.5)]:
        u[t >= t0, 3] = v * tf.TRUTH.throttle_step
    y, x = tf.simulate_truth(u, [0])
    return u, y[0], x[0]


def test_estimated_unknown_input_is_the_spool_curvature() -> None:
    u, y, x = _training()
    g = _idx(tf.PAPER_GROUPS[0], tf.OUTPUTS)
    v = _idx(tf.PAPER_VIRTUAL, tf.STATES)
    est = estimate_unknown_input(tf.design_model(), tf.TS, u, y, x[:, v], group=g, virtual=v, d_rate=0.003, rank_gap=5)
    assert est.rank == 1
    # the truth's steady mismatch enters the N2 and N1 rows only: the estimate must lie in that plane
    e = est.E[:, 0] / np.linalg.norm(est.E[:, 0])
    assert np.linalg.norm(e[[10, 11]]) > 0.99
    with pytest.raises(ExistenceError, match="no clear rank gap"):
        estimate_unknown_input(tf.design_model(), tf.TS, u, y, x[:, v], group=g, virtual=v, d_rate=0.003, rank_gap=50)


# ------------------------------------------------------------------ the grouped bank, compiled


@pytest.fixture(scope="module")
def grouped(tmp_path_factory: pytest.TempPathFactory):  # noqa: ANN201 - (GosDesign, CompiledDiagnoser)
    from fdisyn.codegen.library import codegen
    from fdisyn.runtime.compiled import CompiledDiagnoser
    from fdisyn.runtime.gainfile import write_gain_file

    gd = tf.gos(tf.PAPER_GROUPS)
    d = tmp_path_factory.mktemp("turbofan_grouped")
    write_gain_file(gd.gain_file, d / "gains.json")
    return gd, CompiledDiagnoser(codegen(d).library, gd.gain_file)


def test_every_uio_is_decoupled_from_the_estimated_e(grouped) -> None:  # noqa: ANN001
    from fdisyn.synthesis.residual import internal_form

    gd, _ = grouped
    assert gd.estimate.rank == tf.E_RANK == 2
    assert gd.groups == tuple(tuple(_idx(g, tf.OUTPUTS)) for g in tf.PAPER_GROUPS)
    for gen in gd.gain_file.generators:
        # every Markov parameter from d to r vanishes to round-off (relative to the generator's own gains)
        assert internal_form(gen, gd.plant).coupling("d") <= 1e-9, gen.name
        # and the generator does see the sensors it reads: not a residual that is decoupled from everything
        assert internal_form(gen, gd.plant).C.any()


def test_the_wssr_follows_its_law_without_a_fault(grouped) -> None:  # noqa: ANN001
    """On the design model with an arbitrary, large unknown input, every UIO's WSSR is χ²(N·dof): its
    residual is the white innovation of a steady-state Kalman filter, decoupled from d."""
    from scipy import stats

    gd, cd = grouped
    pl = gd.plant
    rng = np.random.default_rng(7)
    n = 12_500
    t = np.arange(n) * tf.TS
    u = tf.throttle(t)
    d = 50.0 * np.cumsum(rng.standard_normal((n, pl.q)), axis=0)  # a random walk far above the noise
    w = rng.multivariate_normal(np.zeros(pl.n), np.asarray(pl.Q), n)
    v = rng.multivariate_normal(np.zeros(pl.p), np.asarray(pl.R), n)
    x = np.zeros(pl.n)
    y = np.empty((n, pl.p))
    for k in range(n):
        y[k] = pl.C @ x + pl.D @ u[k] + v[k]
        x = pl.A @ x + pl.B @ u[k] + pl.E @ d[k] + w[k]
    res = cd.run(u, y)
    ev = gd.gain_file.evaluators
    window = ev[0].window
    # the threshold is the χ²(N·dof) quantile (a white residual), to the quantile solver's accuracy
    for e in ev:
        assert e.threshold == pytest.approx(stats.chi2.isf(e.P_f, window * e.dof), rel=1e-6)
    # non-overlapping windows after the filters' transient are independent draws of χ²(N·dof)
    ends = np.arange(2000 + window - 1, n, window)
    q95 = np.array([stats.chi2.ppf(0.95, window * e.dof) for e in ev])
    exceed = int(np.sum(res.J[ends] > q95))
    trials = ends.size * len(ev)
    # 5σ binomial bound around 5 %: a wrong law (a residual that still carries d, a wrong W) moves it by far more
    assert abs(exceed - 0.05 * trials) <= 5 * np.sqrt(trials * 0.05 * 0.95), (exceed, trials)
    assert not res.alarm[2000:].any() or res.alarm[2000:].mean() < 1e-3


@pytest.mark.parametrize("kind", [*tf.FAULT_KINDS, "open_circuit"])
def test_every_single_sensor_fault_is_detected_and_isolated(grouped, kind: str) -> None:  # noqa: ANN001
    """Two runs of every sensor's fault: detected after onset, and isolated as that sensor — except a T42 bias,
    which the UIOs without T5 cannot see (the second direction of E lies in T4 and P4, which T42 reads)."""
    gd, cd = grouped
    gf = gd.gain_file
    sensors = ["P3"] if kind == "open_circuit" else list(tf.OUTPUTS)
    for s in sensors:
        sc = tf.SCENARIOS["P3_open_circuit" if kind == "open_circuit" else f"{s}_{kind}"]
        b = tf.PROBLEM.run(sc, [0, 1])
        for i in range(2):
            res = cd.run(b.U[i], b.Y[i])
            after = b.t >= sc.onset
            assert res.alarm[after].any(), (s, kind, i)
            isolated = res.isolated[after]
            if (s, kind) == ("T42", "bias"):
                masked = [k for k, g in enumerate(gf.generators) if g.name.endswith("_no_T5")]
                late = b.t[after] >= sc.onset + 5.0
                assert (res.J[after][late][:, masked] < np.asarray(gf.thresholds)[masked]).mean() > 0.99
                assert not np.any((isolated >= 0) & (isolated != gf.faults.index(s)))
                continue
            # isolated (the pattern of silent UIOs matches the sensor) at some sample, never as another sensor;
            # on samples where a small fault's statistics dip below threshold the pattern is incomplete (-1)
            assert np.any(isolated == gf.faults.index(s)), (s, kind, i)
            assert not np.any((isolated >= 0) & (isolated != gf.faults.index(s))), (s, kind, i, np.unique(isolated, return_counts=True))


# ------------------------------------------------------------------ the detectors at one false-alarm budget


def test_the_detector_variants_share_the_grouped_banks_budget() -> None:
    variants = [v for v in tf.PROBLEM.variants if v["options"].get("arl0") is not None]
    assert [v["options"]["detector"] for v in variants] == [d for d, _ in tf.DETECTORS] == ["wssr", "cusum", "glr"]
    assert {v["options"]["arl0"] for v in variants} == {tf.DETECTOR_ARL0}
    for v in variants:
        assert v["label"].endswith(f" at arl0 = {tf.DETECTOR_ARL0:g} s")
        assert v["designs"] == ["grouped"] and v["runs"] == 50
        assert v["scenarios"][0] == "fault_free" and set(v["scenarios"]) <= set(tf.SCENARIOS)
        assert {tf.SCENARIOS[s].fault for s in v["scenarios"][1:]} == {"T5", "T25", "P3", "T42"}
        tf.PROBLEM.check_options(v["options"])
    # the WSSR at that budget is the paper's bank: each of its 16 statistics gets Ts/(16 arl0) per sample, the problem's P_f
    statistics = sum(len(g) for g in tf.PAPER_GROUPS)
    assert tf.TS / (statistics * tf.DETECTOR_ARL0) == pytest.approx(tf.PROBLEM.options["P_f"], rel=1e-12)


def test_the_glr_of_the_grouped_bank_is_a_table_step_within_the_limits() -> None:
    """The GLR the detector comparison adds: its onset sums (a window of 100 onsets over more than 100 hypotheses) make
    the largest step of the problems; it is within the gain file's limits, written as loops over constant tables, and
    its stack frame within the bound the header states."""
    from fdisyn.codegen.library import STACK_LIMIT_BYTES, step_stack_bytes
    from fdisyn.runtime.schema import LIMITS
    from fdisyn.synthesis.linear_step import TABLE_INSTRUCTIONS, _scalar_estimate, linear_step_function

    gf = tf._designs()["grouped"](P_f=tf.PROBLEM.options["P_f"], persistence=1, window=25, detector="glr", arl0=tf.DETECTOR_ARL0)
    size = tf.glr_size(gf)
    assert size["window"] == 100 and size["hypotheses"] > 100
    assert size["nstate"] == gf.step.nstate <= LIMITS["nstate"] and size["coefficients"] <= LIMITS["coefficients"]
    assert min(size["lorden_samples"]) > 25  # the window holds the weakest hypotheses' delays twice over (clipped to 100)
    assert _scalar_estimate(gf) > 4 * TABLE_INSTRUCTIONS  # far beyond straight-line code
    fn = linear_step_function(gf)
    assert fn.is_a("MXFunction")
    assert step_stack_bytes(fn, gf.step.nstate) <= STACK_LIMIT_BYTES


def test_labels_name_what_the_gain_file_names(grouped) -> None:  # noqa: ANN001
    gd, _ = grouped
    gf = gd.gain_file
    names = {*gf.inputs, *gf.outputs, *gf.faults, *gf.step.residual_names, *gf.step.statistic_names, *(g.name for g in gf.generators)}
    assert not sorted(names - set(tf.PROBLEM.labels))
    assert set(tf.PROBLEM.designs) <= set(tf.PROBLEM.labels)


def test_claims_of_the_structure_and_the_grouping() -> None:
    from tests.helpers import check_claims, claims_context, scenario_metrics

    faulty = {f"{s}_{k}": scenario_metrics(f"{s}_{k}", s, detection_delay_mean_s=0.5, isolation_accuracy=1.0)
              for s in tf.OUTPUTS for k in tf.FAULT_KINDS}
    faulty["T42_bias"] = scenario_metrics("T42_bias", "T42", detection_delay_mean_s=0.5, isolation_accuracy=0.1)
    faulty["P3_open_circuit"] = scenario_metrics("P3_open_circuit", "P3", detection_delay_mean_s=0.1, isolation_accuracy=1.0)
    ff = scenario_metrics("fault_free", false_alarm_runs=0.02)
    metrics = {d: {**faulty, "fault_free": ff} for d in ("grouped", "ungrouped")}
    claims = tf.PROBLEM.claims(claims_context(tf.PROBLEM, [{"label": "default", "metrics": metrics}]))
    check_claims(claims)
    assert [c.verdict for c in claims] == ["reproduced", "reproduced", "reproduced", "differs", "differs"]
    assert "T42" in claims[3].ours and "separation" in claims[3].why  # where the design records which pair it cannot part
