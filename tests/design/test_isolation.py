"""Isolation from the residuals: the GLR across the fault classes' hypotheses and its held decision
(``fdisyn.synthesis.isolation``, ``Isolation`` in the gain file, the same rule in the NumPy reference and the C).

Truths: the evidence's law (the exponentially weighted residual sum's covariance against the Monte Carlo of seeded
random plants, through the step); the misfit's law under the true class (its rejection rate against the designed
level); on seeded random plants moving at switch-on, a sensor bias of each class is named right while it is
alarmed, never wrongly, and the name never changes from one class to another; a pair the design calls
indistinguishable is never named; the compiled step names what the reference names; a file without the test keeps
the flag-pattern decision."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import fdisyn
import numpy as np
import pytest
import scipy.stats
from fdisyn.runtime.compiled import CompiledDiagnoser
from fdisyn.runtime.errors import GainFileError
from fdisyn.runtime.gainfile import gain_file_from_dict, read_gain_file, write_gain_file
from fdisyn.runtime.layout import linear_state_layout
from fdisyn.runtime.reference import IsolationEvidence, LinearReference, held_class, isolation_evidence
from fdisyn.synthesis.residual import evidence_covariance

from tests.design.test_architecture_kind import simulate
from tests.design.test_startup import moving
from tests.helpers import random_plant

SEEDS = (0, 1, 5, 7)


def design(seed: int, **opts):  # noqa: ANN003, ANN201 - design options; a gain file
    plant = random_plant(seed, radius=0.9)
    return plant, fdisyn.design(plant, method="kalman_uio", **({"detector": "cusum", "arl0": 3600.0} | opts))


def test_the_evidence_has_the_designed_covariance() -> None:
    """The step's evidence ``z`` on a fault-free stationary run: its sample covariance over widely spaced samples
    (five memories apart, nearly independent) is the identity within five standard errors per entry, as the design
    says (``B V Bᵀ = I`` with ``V`` the exact ``Σ λ^{k+l} R(k−l)`` of :func:`evidence_covariance`), and ``|z|²``
    averages the evidence's dimension within five standard errors."""
    plant = random_plant(1, radius=0.9)
    gf = fdisyn.design(plant, method="kalman_uio", P_f=1e-3, isolation_memory=10)
    iso = gf.decision.isolation
    basis = np.asarray(iso.basis)
    v = evidence_covariance(gf.generators, plant, iso.forgetting)
    np.testing.assert_allclose(basis @ v @ basis.T, np.eye(basis.shape[0]), atol=1e-8)
    lay = linear_state_layout(gf.generators, gf.evaluators, gf.decision)
    ref = LinearReference(gf)
    T, gap = 24_000, 50
    Y = simulate(plant, T, 3, slice(0, 0), 0, 0.0)
    st, kept = ref.init_state(), []
    for k in range(T):
        ref.step(st, np.zeros(plant.m), Y[k])
        if k >= 200 and k % gap == 0:
            kept.append(st[lay["evidence"]].copy())
    z = np.array(kept)
    emp = z.T @ z / len(z)
    # each entry's standard error is sqrt((1 + δ_ij)/K) for unit-covariance Gaussian coordinates
    k = basis.shape[0]
    assert np.all(np.abs(emp - np.eye(k)) <= 5.0 * np.sqrt((1.0 + np.eye(k)) / len(z))), emp
    q = np.einsum("ki,ki->k", z, z)
    assert abs(q.mean() - k) <= 5.0 * np.sqrt(2.0 * k / len(z)), (q.mean(), k)


def test_the_true_class_is_rejected_at_the_designed_level() -> None:
    """A settled sensor bias: the true class's misfit is χ² with rank − dim degrees of freedom, so it is rejected
    on a fraction ``level`` of the samples (level 0.05 here to count it; ±50 %: the samples are correlated over
    the memory, about 30 effective ones per memory, so the count's spread is several times the binomial one)."""
    plant = random_plant(1, radius=0.9)
    gf = fdisyn.design(plant, method="kalman_uio", P_f=1e-3, false_isolation=0.05, isolation_memory=20)
    ref = LinearReference(gf)
    T, k0 = 40_000, 500
    f = 0
    sensor = plant.outputs.index(gf.faults[f])
    Y = simulate(plant, T, 4, slice(k0, T), sensor, 4.0 * np.sqrt(plant.R[sensor, sensor]))
    st, rejected, counted = ref.init_state(), 0, 0
    for k in range(T):
        ref.step(st, np.zeros(plant.m), Y[k])
        if k >= k0 + 400:
            test = isolation_evidence(gf, st)
            assert test is not None
            rejected += int(not test.plausible[f])
            counted += 1
    assert abs(rejected / counted - 0.05) <= 0.025, rejected / counted


def _bias_runs(plant, gf, f: int, size: float, runs: int, T: int = 500, k0: int = 150) -> dict[str, float]:  # noqa: ANN001
    ref = LinearReference(gf)
    sensor = plant.outputs.index(gf.faults[f].split("|")[0].split("+")[0])
    out = {"alarmed": 0, "right": 0, "wrong": 0, "switches": 0, "before": 0}
    for r in range(runs):
        U, Y = moving(plant, T, 1000 + r, scale=1.0)
        Y[k0:, sensor] += size * np.sqrt(plant.R[sensor, sensor])
        res = ref.run(U, Y)
        iso, alarm = res.isolated[k0 + 50 :], res.alarm[k0 + 50 :]
        out["alarmed"] += int(alarm.sum())
        out["right"] += int(np.sum(iso == f))
        out["wrong"] += int(np.sum((iso >= 0) & (iso != f)))
        named = res.isolated[res.isolated >= 0]
        out["switches"] += int(np.sum(named[1:] != named[:-1]))
        out["before"] += int(np.sum(res.isolated[:k0] >= 0))
    return out


@pytest.mark.parametrize("seed", SEEDS)
def test_a_sensor_bias_is_named_right_and_held(seed: int) -> None:
    """Each class of a seeded random plant's bank, biased at 6σ and 12σ while the plant moves: wherever the design
    separates the class from the others (its separation table: every other class rejected at 4× the designed
    minimum fault held for one memory) it is named on at least 90 % of its alarmed samples; no other class is ever
    named, and a name never changes to another class."""
    plant, gf = design(seed)
    sep = gf.certificate["bank"]["info"]["isolation"]["separation"]
    for f, name in enumerate(gf.faults):
        separated = name in sep and all(r * 16.0 >= 1.0 for r in sep[name].values())
        for size in (6.0, 12.0):
            got = _bias_runs(plant, gf, f, size, runs=3)
            assert got["wrong"] == 0 and got["switches"] == 0, (name, size, got)
            if separated and got["alarmed"] > 100:
                assert got["right"] >= 0.9 * got["alarmed"], (name, size, got, sep[name])


def test_classes_alike_at_steady_state_are_never_confused() -> None:
    """Seed 0's bank sees y0's and y1's steady shifts along one direction (separation ratios ~10⁻⁵): a bias on either
    is never named as the other. Only the transient after the step tells them apart, so a name, when one comes, comes
    from it; once the transient is forgotten (ten memories later) the evidence leaves both plausible again."""
    plant, gf = design(0)
    sep = gf.certificate["bank"]["info"]["isolation"]["separation"]
    assert sep["y0"]["y1"] < 1e-3 and sep["y1"]["y0"] < 1e-3
    for f in (0, 1):
        got = _bias_runs(plant, gf, f, 12.0, runs=2)
        assert got["alarmed"] > 500 and got["wrong"] == 0 and got["switches"] == 0, got
    memory = int(round(1.0 / (1.0 - gf.decision.isolation.forgetting)))
    ref = LinearReference(gf)
    T = 100 + 10 * memory
    U, Y = moving(plant, T, 5, scale=1.0)
    Y[100:, 0] += 12.0 * np.sqrt(plant.R[0, 0])
    st = ref.init_state()
    for k in range(T):
        ref.step(st, U[k], Y[k])
    test = isolation_evidence(gf, st)
    assert test is not None and test.plausible[0] and test.plausible[1] and test.candidate == -1


def test_the_held_class_changes_only_on_evidence() -> None:
    def ev(plausible: list[bool], candidate: int) -> IsolationEvidence:
        p = np.array(plausible)
        return IsolationEvidence(evidence=np.zeros(3), misfit=np.zeros(3), plausible=p, supported=p, candidate=candidate)

    assert held_class(-1, True, ev([True, False, False], 0)) == 0
    assert held_class(0, True, ev([True, True, False], -1)) == 0  # still plausible, nothing singled out: held
    # still plausible, but the test singles out a class it contains (class 0 holds class 1's members): narrowed
    assert held_class(0, True, ev([True, True, False], 1)) == 1
    assert held_class(-1, True, ev([True, True, False], -1), pattern=2) == 2  # nothing from the test: the pattern
    assert held_class(2, True, ev([True, True, False], 0), settled=False) == 2  # not settled: the test is not heard
    assert held_class(0, True, ev([False, False, False], -1)) == 0  # rejected, but nothing else named: held
    assert held_class(0, True, ev([False, True, False], 1)) == 1  # rejected and another named: changed
    assert held_class(1, False, ev([False, True, False], 1)) == -1  # the alarm fell: cleared


def test_the_compiled_step_names_what_the_reference_names(tmp_path: Path) -> None:
    plant, gf = design(1)
    built = fdisyn.export(gf, tmp_path / "c")
    compiled = CompiledDiagnoser(built / f"lib{gf.name}.so", gf)
    U, Y = moving(plant, 600, 11, scale=1.0)
    Y[200:, 1] += 8.0 * np.sqrt(plant.R[1, 1])
    Y[400:, 2] += 8.0 * np.sqrt(plant.R[2, 2])
    got, want = compiled.run(U, Y), LinearReference(gf).run(U, Y)
    assert np.array_equal(got.alarm, want.alarm) and np.array_equal(got.isolated, want.isolated)
    assert (want.isolated >= 0).sum() > 100
    np.testing.assert_allclose(got.state, want.state, rtol=1e-9, atol=1e-9 * np.abs(want.state).max())


def test_a_file_without_the_test_keeps_the_flag_pattern(tmp_path: Path) -> None:
    """A gain file written before the test existed (no ``decision.isolation``) reads, and names the fault whose
    signature equals the flag pattern, in the reference and the compiled step alike."""
    plant, gf = design(1, detector="chi2", arl0=None, P_f=1e-3)
    dec = replace(gf.decision, isolation=None)
    lay = linear_state_layout(gf.generators, gf.evaluators, dec)
    old = replace(gf, decision=dec, step=replace(gf.step, nstate=lay.size, init_state=np.zeros(lay.size)))
    write_gain_file(old, tmp_path / "old.json")
    back = read_gain_file(tmp_path / "old.json")
    assert back.decision.isolation is None and "isolation" not in back.to_dict()["decision"]
    U, Y = moving(plant, 400, 12, scale=1.0)
    Y[150:, 0] += 12.0 * np.sqrt(plant.R[0, 0])
    want = LinearReference(back).run(U, Y)
    sig = np.asarray(back.decision.signatures)
    flags = want.J > np.asarray(back.thresholds)[None, :]
    expect = np.array([next((f for f in range(len(sig)) if np.array_equal(sig[f], row)), -1) for row in flags.astype(int)])
    assert np.array_equal(want.isolated, expect)
    built = fdisyn.export(back, tmp_path / "c")
    got = CompiledDiagnoser(built / f"lib{back.name}.so", back).run(U, Y)
    assert np.array_equal(got.isolated, want.isolated)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: d["isolation"].__setitem__("level", 0.7), r"decision.isolation.level must be a probability in \(0, 0.5\)"),
        (lambda d: d["isolation"].__setitem__("forgetting", 1.0), r"decision.isolation.forgetting must be in \[0, 1\)"),
        (lambda d: d["isolation"]["basis"].pop(), r"decision.isolation.directions: expected shape"),
        (lambda d: d["isolation"]["basis"][0].pop(), r"matrix 'basis' has rows of different lengths"),
        (lambda d: d["isolation"].__setitem__("ranks", [1, 1]), "decision.isolation.ranks must hold 3 integers in"),
        (lambda d: d["isolation"].__setitem__("reject", [0.0, 1.0, 1.0]), "decision.isolation.reject must hold 3 positive numbers"),
        (lambda d: d["isolation"]["nested"][0].__setitem__(0, 1), "decision.isolation.nested must hold only 0 and 1 with a zero diagonal"),
        (lambda d: d["isolation"]["accept"].__setitem__(0, "x"), "field 'accept' must be a list of numbers"),
    ],
)
def test_a_broken_isolation_test_is_refused_by_name(edit, message: str) -> None:  # noqa: ANN001
    _, gf = design(1)
    doc = gf.to_dict()
    edit(doc["decision"])
    with pytest.raises(GainFileError, match=message):
        gain_file_from_dict(doc)


def test_the_levels_are_the_chi2_quantiles() -> None:
    _, gf = design(1, false_isolation=0.01)
    iso = gf.decision.isolation
    rank = np.asarray(iso.basis).shape[0]
    for k, a, r in zip(iso.ranks, iso.accept, iso.reject, strict=True):
        assert a == pytest.approx(scipy.stats.chi2.isf(0.01, max(k, 1)))
        assert r == pytest.approx(scipy.stats.chi2.isf(0.01, rank - k))
