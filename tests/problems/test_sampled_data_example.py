"""The example of Qiu, Wen & Jiang (Control Theory & Applications 27(8), 2010) through the pipeline:
designs, the χ² law, detection, C export, the TOML route."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.stats
from fdisyn.app.cli import main
from fdisyn.app.examples import EXAMPLES
from fdisyn.app.pipeline import EXPORT_TOL, check_export, export_trace
from fdisyn.evaluation.built import build
from fdisyn.evaluation.metrics import binomial_interval
from fdisyn.problems.sampled_data_example import PROBLEM
from fdisyn.runtime.gainfile import read_gain_file

from tests.helpers import check_values, coupling_markov

DATA = EXAMPLES


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    root = tmp_path_factory.mktemp("sd")
    return {d: build(PROBLEM, d, root / d) for d in PROBLEM.designs}


def test_every_design_certifies_and_the_direct_residual_is_white_unit(built):
    for name, b in built.items():
        checks = check_values(b.gain_file.certificate)
        optimum = [v for k, vs in checks.items() if k.startswith("|J − J*| / J*") for v in vs]
        assert len(optimum) == (0 if name == "lmi" else 3)  # Theorem 1's J* for η = ∞, 2, −
        assert max(optimum, default=0.0) <= 1e-12  # measured ≤ 7e-16; the certificate allows 1e-8
        for gen in b.gain_file.generators:
            assert max(abs(np.linalg.eigvals(gen.Ar))) < 1.0 - 1e-9  # Schur, recomputed here
            # the known input never reaches the residual (measured ≤ 3e-17 relative)
            assert coupling_markov(b.gain_file.plant, gen)[0] <= 1e-12
    ev = built["direct"].gain_file.evaluators[0]
    # G_rψ G_dJ co-inner and d of unit intensity: the residual covariance is I (round-off only)
    np.testing.assert_allclose(ev.Sigma_r, np.eye(2), atol=1e-12)
    assert ev.dof == 2 and built["indirect"].gain_file.evaluators[0].dof == 1


def test_chi2_law_of_the_direct_statistic(built):
    b = built["direct"]
    batch = PROBLEM.run("fault_free", range(500))
    js = np.concatenate([b.diagnoser.run(batch.U[i], batch.Y[i]).J[5:, 0] for i in range(500)])
    lo, hi = binomial_interval(js.size, 1e-3, alpha=1e-6)  # fails with probability 1e-6 if the law is right
    assert lo <= int(np.sum(js > b.gain_file.thresholds[0])) <= hi
    assert scipy.stats.kstest(js, scipy.stats.chi2(2).cdf).pvalue > 1e-6


@pytest.mark.parametrize("design", ["direct", "indirect", "lmi"])
def test_the_paper_fault_is_detected_one_sample_after_onset(built, design):
    b = built[design]
    batch = PROBLEM.run("paper", range(20))
    for i in range(20):
        alarm = b.diagnoser.run(batch.U[i], batch.Y[i]).alarm
        # the step at 60 s reaches the outputs at the next sample; a 9-σ fault is seen at once
        assert alarm[61:].mean() > 0.95 and alarm[61] == 1


@pytest.mark.parametrize("design", ["direct", "indirect", "lmi"])
def test_generated_c_agrees_with_the_references(built, design):
    U, Y = export_trace(PROBLEM)
    chk = check_export(built[design], U, Y)
    for v in chk.references.values():
        assert max(v["r"], v["J"], v["state"]) <= EXPORT_TOL and v["decisions_equal"]


def test_toml_route_gives_the_same_observer(built, tmp_path):
    spec = str(DATA / "sampled_data.toml")
    assert main(["design", spec, "--out", str(tmp_path)]) == 0
    gf = read_gain_file(tmp_path / "gains.json")
    ref = built["direct"].gain_file.generators[0]
    g = gf.generators[0]
    for k in ("Ar", "Bu", "By", "Cr", "Dy"):
        np.testing.assert_allclose(getattr(g, k), getattr(ref, k), rtol=1e-12, atol=1e-14)
    assert gf.faults == ("y1|y2|f",)  # one generator reads every sensor and feels the fault: one class
    assert main(["codegen", str(tmp_path)]) == 0
    trace = tmp_path / "t.csv"
    assert main(["simulate", spec, "--scenario", "fault_step", "--seed", "3", "--out", str(trace)]) == 0
    assert main(["replay", str(tmp_path), str(trace), str(tmp_path / "o.csv")]) == 0
    out = np.genfromtxt(tmp_path / "o.csv", delimiter=",", names=True)
    assert out["alarm"][out["t"] >= 61].mean() > 0.95


def test_toml_lmi_method(tmp_path):
    text = (DATA / "sampled_data.toml").read_text().replace('method = "sampled_data_observer"', 'method = "lmi"')
    spec = tmp_path / "lmi.toml"
    spec.write_text(text)
    assert main(["design", str(spec), "--out", str(tmp_path / "d")]) == 0
    assert read_gain_file(tmp_path / "d" / "gains.json").design == "lmi"


def test_toml_refuses_two_names_for_one_matrix(tmp_path, capsys):
    text = (DATA / "sampled_data.toml").read_text().replace("h = 1.0", "h = 1.0\nTs = 1.0")
    spec = tmp_path / "both.toml"
    spec.write_text(text)
    assert main(["design", str(spec), "--out", str(tmp_path / "d")]) == 2
    assert "gives both 'h' and 'Ts'" in capsys.readouterr().err


def test_labels_name_what_the_gain_files_name(built):
    for name, b in built.items():
        gf = b.gain_file
        names = {name, *gf.inputs, *gf.outputs, *gf.faults, *gf.step.residual_names, *gf.step.statistic_names}
        assert not sorted(names - set(PROBLEM.labels)), name


def test_claims_say_why_the_indirect_design_detects_what_the_paper_says_it_cannot():
    from tests.helpers import check_claims, claims_context, scenario_metrics

    found = scenario_metrics("paper", "f", missed_detection_rate=0.0, detection_delay_mean_s=1.0)
    ctx = claims_context(PROBLEM, [{"label": "default", "metrics": {"direct": {"paper": found}, "indirect": {"paper": found}}}])
    claims = PROBLEM.claims(ctx)
    check_claims(claims)
    verdicts = {c.claim.split(" (")[0]: c.verdict for c in claims}
    assert verdicts["The direct design detects the fault of 10 at 60 s"] == "reproduced"
    assert verdicts["The indirect design cannot detect the fault of 10 at 60 s"] == "differs"
    assert verdicts["Designing on the sampled-data system beats discretising first"] == "reproduced"
    assert verdicts["Optimal observer gain E of the direct design"] == "reproduced"  # the paper's "H"
    assert verdicts["Optimal observer gain L of the direct design"] == "differs"  # L[0,0] = e⁻¹ printed 0.38
    assert PROBLEM.model() is not None and PROBLEM.model().Ts == 1.0


def test_the_shift_sweep_sets_the_whitened_shift(tmp_path):
    """The delay-against-shift sweep scales the paper's fault so that its whitened shift is 0.25σ … 4σ: the
    information per sample the Monte Carlo then measures is ``σ²/2`` (a bias scaled by ``k`` shifts the residual by
    ``k`` times: the information by ``k²``), within the estimate's error; the fault acts long enough for the smallest
    shift, and the delay over the bound counts the faulty samples seen (an alarm on the first is one), over the
    onset-aware bound (the step's ratio kept beside it)."""
    from fdisyn.app.pipeline import SHIFT_SPAN, shift_sweep
    from fdisyn.evaluation.evaluate import evaluate

    opts = {"detector": "cusum", "arl0": 1000.0, "shifts": [0.25, 0.5, 1.0, 2.0, 4.0]}
    b = {"direct": build(PROBLEM, "direct", tmp_path / "direct", **opts)}
    ev = evaluate(PROBLEM, b, runs=10, scenarios=["paper"], workers=1, **opts)
    sweep = shift_sweep(PROBLEM, b, ev, runs=10, workers=1, **opts)
    assert sweep is not None and sweep.scenario == "paper" and list(sweep.metrics) == ["direct"]
    for s, m in sweep.metrics["direct"].items():
        # 10 runs of ≥ 800 faulty samples: the mean shift's relative error is ≲ 1/(0.25 √8000) ≈ 4.5 % at 0.25σ
        assert m.fault_information == pytest.approx(s * s / 2, rel=0.2), s
        assert m.samples_per_run * m.Ts - PROBLEM.scenario("paper").onset >= SHIFT_SPAN * m.lorden_bound_samples * m.Ts * 0.8
        assert m.stationary_bound_ratio == pytest.approx((m.detection_delay_mean_samples + 1) / m.lorden_bound_samples)
        assert m.onset_bound_samples is not None
        assert m.delay_bound_ratio == pytest.approx((m.detection_delay_mean_samples + 1) / m.onset_bound_samples)
    # the fault reaches the residual a sample after its onset: where the step's bound is under two samples, the
    # onset-aware one is about a sample longer
    big = sweep.metrics["direct"][4.0]
    assert big.lorden_bound_samples < 2.0 and big.onset_bound_samples > big.lorden_bound_samples + 0.5
