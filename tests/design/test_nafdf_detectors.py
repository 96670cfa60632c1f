"""The NAFDF's fast detection as a choice of statistic on the EKF innovations: WSSR, CUSUM, GLR.

Truths: the normalisation against linear algebra; the CUSUM and GLR recursions of the step against their
definitions on the normalised innovations the step itself reports; the detectors' false-alarm rate against the
law their thresholds come from (Page's integral equation, Siegmund & Venkatraman's approximation), by Monte
Carlo through the generated C; the gain file's refusals.
"""

from __future__ import annotations

import copy
import json
import math

import casadi as ca
import numpy as np
import pytest
from fdisyn.codegen.library import codegen
from fdisyn.evaluation.metrics import poisson_time_interval
from fdisyn.detectors.sequential import cusum_arl, glr_arl
from fdisyn.problems import ship_propulsion as sp
from fdisyn.runtime.compiled import CompiledDiagnoser
from fdisyn.runtime.errors import ArgumentError, GainFileError
from fdisyn.runtime.gainfile import read_gain_file, write_gain_file
from fdisyn.synthesis.nafdf.design import nafdf
from fdisyn.synthesis.nafdf.payload import nafdf_budget_seconds, nafdf_from_gain_file, nafdf_gain_file
from fdisyn.synthesis.nafdf.step import _ldl, _normalised

WINDOWS = {"wssr": 10, "cusum": 10, "glr": 50}


@pytest.mark.parametrize("k", [1, 2, 3, 5])
def test_normalised_innovation_is_standard(k: int) -> None:
    """``w = D^{-1/2} U^{-T} b``: ``W A Wᵀ = I`` and ``‖w‖² = bᵀ A⁻¹ b`` to round-off (1e-12 relative: a
    triangular solve of a condition-≤-1e3 matrix)."""
    rng = np.random.default_rng(k)
    g = rng.standard_normal((k, k))
    a = g @ g.T + 0.1 * np.eye(k)
    sym, bs = ca.SX.sym("a", k, k), ca.SX.sym("b", k)
    lt, d = _ldl(sym)
    f = ca.Function("w", [sym, bs], [_normalised(lt, d, bs)])
    w_of = np.column_stack([np.asarray(f(a, e)).reshape(-1) for e in np.eye(k)])  # W, column by column
    np.testing.assert_allclose(w_of @ a @ w_of.T, np.eye(k), atol=1e-12 * np.linalg.cond(a))
    b = rng.standard_normal(k)
    w = np.asarray(f(a, b)).reshape(-1)
    assert abs(w @ w - b @ np.linalg.solve(a, b)) <= 1e-12 * np.linalg.cond(a) * (b @ b)


def _reference_statistic(det: str, w: np.ndarray, clear: np.ndarray, h: float, min_shift: float, window: int) -> np.ndarray:
    """The detector's statistic from its definition (scalar innovation): CUSUM ``max(S⁺, S⁻)`` with
    ``S± = min(max(0, S± ± δw − δ²/2), 2h)``; GLR ``max_{n≤M} (Σ_{last n} w)² / (2n)``; both restarted after the
    samples in ``clear`` (the step's re-parameterisations, dismissals and EKF resets)."""
    out = np.empty(w.size)
    sp_, sm = 0.0, 0.0
    since = 0  # first sample of the current GLR record
    for k, wk in enumerate(w):
        if det == "cusum":
            sp_ = min(max(0.0, sp_ + min_shift * wk - 0.5 * min_shift**2), 2 * h)
            sm = min(max(0.0, sm - min_shift * wk - 0.5 * min_shift**2), 2 * h)
            out[k] = max(sp_, sm)
        else:
            best = 0.0
            for n in range(1, window + 1):
                # onset sums older than the record are sums of the record (the state holds zeros before it)
                s = float(np.sum(w[max(k - n + 1, since) : k + 1]))
                best = max(best, s * s / (2 * n))
            out[k] = best
        if clear[k]:
            sp_, sm, since = 0.0, 0.0, k + 1
    return out


@pytest.mark.parametrize("det", ["cusum", "glr"])
def test_step_recursion_against_its_definition(det: str) -> None:
    """Over 1500 samples with the paper's fault (an alarm, an episode, a re-parameterisation), the step's
    statistic equals its definition on the normalised innovation ``w = sign(γ)·√(γᵀV0⁻¹γ)`` (one output) to
    1e-9·h (round-off of sums of ≤ 50 terms of order 1)."""
    dsg = sp.design(detector=det, arl0=2000.0, window=WINDOWS[det])
    b = sp.PROBLEM.run(sp.fault_scenario("a_half", {"a": 0.5}, length=1500), [3])
    res = dsg.run(u=b.U[0], y=b.Y[0])
    names = list(dsg.J_names)
    w = np.sign(res["r"][:, 0]) * np.sqrt(res["J"][:, names.index("ekf_nis")])
    st = [dsg.unpack_state(s) for s in res["state"]]
    counters = np.array([[s["ekf_reparameterisations"], s["episodes_dismissed"], s["ekf_divergence_resets"]] for s in st]).sum(axis=1)
    clear = np.diff(counters, prepend=0.0) > 0
    assert clear.sum() >= 1, "the run must restart the detector at least once"
    h = float(dsg.thresholds[0])
    want = _reference_statistic(det, w, clear, h, dsg.settings.min_shift, dsg.settings.window)
    np.testing.assert_allclose(res["J"][:, 0], want, rtol=0, atol=1e-9 * h)
    np.testing.assert_allclose(res["J"][:, 1], h, rtol=0, atol=0)
    first = int(np.argmax(want > h))
    assert res["alarm"][first] == 1 and not np.any(res["alarm"][:first])


@pytest.fixture(scope="module")
def compiled(tmp_path_factory: pytest.TempPathFactory):
    """The ship's NAFDF per detector, its false-alarm rate set to 1/300 per sample, compiled once."""
    out = {}
    for det in ("cusum", "glr"):
        d = tmp_path_factory.mktemp(det)
        gf = nafdf_gain_file(sp.design(detector=det, arl0=400.0, window=WINDOWS[det]), problem="ship_propulsion")
        write_gain_file(gf, d / "gains.json")
        out[det] = (CompiledDiagnoser(codegen(d).library, gf), gf)
    return out


@pytest.mark.parametrize("det", ["cusum", "glr"])
def test_false_alarm_rate_against_the_law(compiled, det: str) -> None:
    """Fault-free, the detector's mean run length outside alarm episodes is the one its threshold was solved
    for, ``arl0/Ts − 2 N2`` = 300 samples.

    The run lengths are renewal intervals (the statistic restarts at 0 when an episode is dismissed), so the
    episode count over the time outside episodes is Poisson-like: Garwood's 99.9 % interval on the mean run
    length must meet the law's band. CUSUM: Page's integral equation is exact for independent N(0, 1)
    innovations, and the ship's EKF linearises ``0.1 a x²`` (measured: 2 % short of it), band [0.9, 1.1].
    GLR: Siegmund & Venkatraman's approximation, within [0.75, 1.15] of Monte Carlo for windows 25–100 (the
    sequential-detector tests)."""
    cd, gf = compiled[det]
    b = sp.PROBLEM.run(sp.fault_scenario("ff", None, length=20_000), list(range(100, 106)))
    episodes = free = 0
    for i in range(len(b.seeds)):
        a = cd.run(b.U[i], b.Y[i]).alarm
        episodes += int(np.sum(np.diff(a, prepend=0) > 0))
        free += int(np.sum(a == 0))
    lo, hi = poisson_time_interval(episodes, float(free), level=0.999)
    assert hi is not None
    design = nafdf_from_gain_file(gf)
    h, p = float(design.thresholds[0]), 1
    if det == "cusum":
        law = 1.0 / (2 * p / cusum_arl(h, 0.5 * design.settings.min_shift**2))
        band = (0.9, 1.1)
    else:
        law = glr_arl(h, design.settings.window) / p
        band = (0.75, 1.15)
    assert math.isclose(law, 1.0 / design.settings.false_alarm_probability, rel_tol=1e-6)
    assert episodes >= 150, episodes
    assert lo <= band[1] * law and hi >= band[0] * law, (free / episodes, lo, hi, law)
    assert nafdf_budget_seconds(gf) == 400.0


@pytest.mark.parametrize("det", ["cusum", "glr"])
def test_the_paper_fault_is_detected_and_isolated(compiled, det: str) -> None:
    """The paper's fault (a → a0/2 at 701) through the compiled step, at the tight budget of the fixture:
    each of 4 runs alarms within 40 samples of the onset (the WSSR's measured delay is ~10) and isolates
    ``a``; false alarms before the onset are allowed (300-sample run length), so the first alarm at or after
    the onset counts."""
    cd, _ = compiled[det]
    b = sp.PROBLEM.run(sp.fault_scenario("a_half", {"a": 0.5}), list(range(20, 24)))
    onset = int(b.scenario.onset)
    for i in range(len(b.seeds)):
        res = cd.run(b.U[i], b.Y[i])
        assert np.any(res.alarm[onset : onset + 40]), i
        assert res.isolated[-1] == 0, i


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"detector": "chi2"}, r"detector must be one of 'wssr', 'cusum', 'glr'; got 'chi2'"),
        ({"detector": "cusum", "threshold_rule": "beta0", "beta0": 0.5}, r"threshold_rule 'beta0' is the paper's WSSR threshold"),
        ({"detector": "cusum", "arl0": 100.0}, r"arl0 = 100 s leaves no time between false alarms: .* expected arl0 > 102 s"),
        ({"detector": "cusum", "min_shift": 0.0}, r"min_shift must be a number of standard deviations in \[1e-06, 1e\+06\]"),
        ({"detector": "glr", "window": 1001}, r"window .* at most 1000"),
    ],
)
def test_settings_errors_name_what_is_wrong(kw: dict, match: str) -> None:
    with pytest.raises(ArgumentError, match=match):
        nafdf(sp.plant(), x0=[0.0], P0=100.0, theta0=[0.0, 0.0], **kw)


def test_gain_file_refusals_and_version_3(tmp_path) -> None:
    """A CUSUM gain file reads back to the same step; an edited threshold, detector, budget or rate is refused
    in one line; a version-3 payload (the WSSR, before the detector choice) still reads."""
    gf = nafdf_gain_file(sp.design(detector="cusum", arl0=2000.0), problem="ship_propulsion")
    write_gain_file(gf, tmp_path / "gains.json")
    doc = json.loads((tmp_path / "gains.json").read_text())
    back = read_gain_file(tmp_path / "gains.json")
    assert nafdf_from_gain_file(back).step.serialize() == sp.design(detector="cusum", arl0=2000.0).step.serialize()

    def refused(edit, match: str) -> None:  # noqa: ANN001
        d = copy.deepcopy(doc)
        edit(d["extensions"]["nafdf"])
        (tmp_path / "bad.json").write_text(json.dumps(d))
        with pytest.raises(GainFileError, match=match):
            nafdf_from_gain_file(read_gain_file(tmp_path / "bad.json"))

    refused(lambda p: p["detector_thresholds"].__setitem__(0, 1.0), r"detector_thresholds\[0\] is 1.0; the settings \(detector 'cusum'")
    refused(lambda p: p["settings"].__setitem__("arl0", 3000.0), r"false_alarm_probability is .*; arl0 = 3000.0 s gives")
    refused(lambda p: p["settings"].__setitem__("false_alarm_probability", 0.01), r"false_alarm_probability is 0.01; arl0 = 2000.0 s gives")
    refused(lambda p: p["settings"].__setitem__("detector", "glr"), r"extensions.nafdf")

    wssr = nafdf_gain_file(sp.design(), problem="ship_propulsion")
    write_gain_file(wssr, tmp_path / "w.json")
    d3 = json.loads((tmp_path / "w.json").read_text())
    p3 = d3["extensions"]["nafdf"]
    p3["version"] = 3
    p3["wssr_thresholds"] = p3.pop("detector_thresholds")
    for key in ("detector", "min_shift", "arl0"):
        del p3["settings"][key]
    (tmp_path / "v3.json").write_text(json.dumps(d3))
    assert nafdf_from_gain_file(read_gain_file(tmp_path / "v3.json")).step.serialize() == sp.design().step.serialize()


def test_lorden_information_of_a_known_shift() -> None:
    """``I = ½ μᵀ Σ⁻¹ μ`` on the EKF innovation part and ``ln(1/P_f)/I``: a shift of one standard deviation
    gives I = ½ and a bound of 2 ln(ARL)."""
    from fdisyn.synthesis.nafdf.payload import nafdf_lorden_bound

    gf = nafdf_gain_file(sp.design(detector="glr", arl0=2000.0, window=50), problem="ship_propulsion")
    sd = 0.3
    info, bound = nafdf_lorden_bound(gf, np.array([sd, 5.0]), np.diag([sd**2, 1.0]))
    assert math.isclose(info, 0.5, rel_tol=1e-12)
    assert math.isclose(bound, 2 * math.log(1900.0), rel_tol=1e-12)  # the NF's ε (second residual) is not read


def test_the_budget_hooks_of_each_kind() -> None:
    """The registry's hooks the Monte Carlo uses: a NAFDF's budget is its arl0 (or ``Ts·(1/P_f + 2 N2)``) and
    its fault shift is measured over the ``N2`` samples before the EKF can adapt; a linear diagnoser's over the
    whole fault."""
    from fdisyn.problems import wind_turbine as wt
    from fdisyn.synthesis.kinds import false_alarm_budget, lorden_window

    by_arl0 = nafdf_gain_file(sp.design(detector="cusum", arl0=2000.0), problem="ship_propulsion")
    by_pf = nafdf_gain_file(sp.design(), problem="ship_propulsion")
    assert false_alarm_budget(by_arl0) == 2000.0
    assert false_alarm_budget(by_pf) == 1e4 + 100.0
    assert lorden_window(by_arl0) == 50
    linear = wt.PROBLEM.designs["kalman_uio"](detector="glr", arl0=60.0)
    assert lorden_window(linear) is None and false_alarm_budget(linear) == 60.0
