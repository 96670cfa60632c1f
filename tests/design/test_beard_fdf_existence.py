"""The Beard filter designs wherever one exists: seeded plants built around a known Beard gain (every fault direction's
detection space invariant, a stable spectrum inside the decay bound), designed with the default (optimised) and the
plain eigenstructure; the geometry's corner cases (no free eigenvalue outside the detection spaces, complex fixed
modes, an eigenvalue asked for more often than a block's outputs allow); the optimised design never worse than the
plain one by the NLP's own objective, and saying so when it cannot improve it."""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np
import pytest

import fdisyn
from fdisyn.models.linear import LinearPlant
from fdisyn.numerics.detection_filter import beard_gain, beard_structure, plain_eigenvalues
from fdisyn.numerics.robust_cones import implicit_thresholds
from fdisyn.runtime.errors import ArgumentError, ExistenceError
from fdisyn.synthesis.beard_fdf.eigenstructure import optimise_eigenstructure
from fdisyn.synthesis.beard_fdf.payload import beard_from_gain_file

TS = 0.1
RADIUS = 0.8
DECAY = -math.log(RADIUS) / TS


# --------------------------------------------------------------------------- plants with a known Beard gain


def _stable(rng: np.random.Generator, count: int, top: float, complex_pairs: int = 0) -> np.ndarray:
    """A real block with ``count`` eigenvalues of modulus below ``top`` (``complex_pairs`` of them complex pairs)."""
    blocks = []
    for _ in range(complex_pairs):
        r, phi = rng.uniform(0.2, top), rng.uniform(0.4, 2.5)
        blocks.append(r * np.array([[math.cos(phi), -math.sin(phi)], [math.sin(phi), math.cos(phi)]]))
    for _ in range(count - 2 * complex_pairs):
        blocks.append(np.array([[rng.uniform(-top, top)]]))
    out = np.zeros((count, count))
    o = 0
    for b in blocks:
        out[o : o + b.shape[0], o : o + b.shape[0]] = b
        o += b.shape[0]
    return out + np.triu(rng.uniform(-0.3, 0.3, (count, count)), 2 if complex_pairs else 1)  # the pairs stay complex


def known_beard_plant(seed: int, *, n: int, k: int, p: int, planes: int = 0, complex_rest: int = 0,
                      unstable: bool = False) -> dict[str, Any]:
    """``A = G + L₀ C`` with ``G = V M V⁻¹``: ``V = [T_1 … T_k, W]`` random, ``M`` block upper triangular with stable
    diagonal blocks (moduli below 0.6 < :data:`RADIUS`), so that every ``T_i`` is ``G``-invariant. ``T_i`` is the
    fault's line ``span f_i`` (``C f_i ≠ 0``), or for the first ``planes`` faults the plane ``span{f_i, g_i}`` with
    ``C f_i = 0`` (relative degree two). ``L₀`` is a Beard gain of the plant by construction: a filter exists.
    ``complex_rest``: complex pairs among the eigenvalues of the rest (fixed modes when ``p`` leaves no output for it)."""
    rng = np.random.default_rng(seed)
    dims = [2 if i < planes else 1 for i in range(k)]
    c = rng.standard_normal((p, n))
    v = rng.standard_normal((n, n))
    for i in range(planes):  # the plane's fault direction in ker C
        o = sum(dims[:i])
        null = np.linalg.svd(c)[2][p:].T
        v[:, o] = null @ rng.standard_normal(null.shape[1])
    m = np.zeros((n, n))
    o = 0
    for d in dims:
        m[o : o + d, o : o + d] = _stable(rng, d, 0.6)
        if d == 2:  # f = V e_o must leave ker C in one step: G f has a part along the plane's second column
            m[o + 1, o] = rng.uniform(0.3, 0.6) * rng.choice([-1.0, 1.0])
            m[o, o + 1] = 0.0
        o += d
    rest = n - o
    if rest:
        m[o:, o:] = _stable(rng, rest, 0.6, complex_rest)
        m[:o, o:] = rng.uniform(-0.5, 0.5, (o, rest))
    g = v @ m @ np.linalg.inv(v)
    l0 = rng.standard_normal((n, p)) * (1.5 if unstable else 0.3)
    a = g + l0 @ c
    fx = np.column_stack([v[:, sum(dims[:i])] for i in range(k)])
    spaces = [np.linalg.qr(v[:, sum(dims[:i]) : sum(dims[: i + 1])])[0] for i in range(k)]
    return {"A": a, "C": c, "Fx": fx, "L": l0, "G": g, "spaces": spaces}


CASES = {  # id: (seed, structure); each is a corner of the geometry the default design met
    "no-free-rest": (1, {"n": 3, "k": 2, "p": 2}),
    "complex-fixed-modes": (2, {"n": 4, "k": 2, "p": 2, "complex_rest": 1}),
    "rest-of-two-through-one-output": (3, {"n": 4, "k": 2, "p": 3}),
    "triple-pole-through-one-output": (4, {"n": 4, "k": 1, "p": 2}),
    "plane-seen-through-one-output": (5, {"n": 4, "k": 1, "p": 2, "planes": 1}),
    "rest-of-three-through-two-outputs": (6, {"n": 4, "k": 1, "p": 3}),
    "unstable-open-loop": (7, {"n": 4, "k": 2, "p": 3, "unstable": True}),
    "three-faults-complex-fixed": (8, {"n": 5, "k": 3, "p": 3, "complex_rest": 1, "unstable": True}),
}


def _plant(case: str) -> tuple[LinearPlant, dict[str, Any]]:
    seed, structure = CASES[case]
    known = known_beard_plant(seed, **structure)
    n, p = known["C"].shape[1], known["C"].shape[0]
    k = known["Fx"].shape[1]
    plant = LinearPlant.create(A=known["A"], B=np.zeros((n, 1)), C=known["C"], Fx=known["Fx"], Q=1e-4 * np.eye(n),
                               R=1e-4 * np.eye(p), Ts=TS, component_faults=[f"f{i}" for i in range(k)])
    return plant, known


def _design(plant: LinearPlant, **options: Any) -> fdisyn.GainFile:
    return fdisyn.design(plant, method="beard_fdf", decay_rate=DECAY, window=10, **options)


def _residual_directions(gf: Any, plant: LinearPlant) -> float:
    """Largest angle between a fault's output error and its residual subspace along a random fault signal (an
    independent recursion: no subspace algebra)."""
    flt = beard_from_gain_file(gf)
    g = flt.A - flt.L @ flt.C
    rng = np.random.default_rng(0)
    worst = 0.0
    for j in range(plant.Fx.shape[1]):
        e = np.zeros(g.shape[0])
        axis = flt.axes[j]
        for _ in range(60):
            e = g @ e + plant.Fx[:, j] * rng.standard_normal()
            out = flt.C @ e
            if np.linalg.norm(out) <= 1e-12 * np.linalg.norm(flt.C, 2) * np.linalg.norm(e):
                continue  # round-off of C e = 0 (a plane's fault direction in ker C, its first sample): no direction
            worst = max(worst, float(np.linalg.norm(out - axis @ (axis.T @ out)) / np.linalg.norm(out)))
    return worst


def _block_radius(g: np.ndarray, spaces: list[np.ndarray]) -> float:
    """Spectral radius of ``G`` from its diagonal blocks in the basis ``[T_1 … T_k, (Σ T_i)^⊥]`` (each ``T_i``
    invariant: ``G`` is block triangular there)."""
    t = np.hstack(spaces)
    rest = np.linalg.svd(t.T)[2][t.shape[1] :].T
    parts = [np.linalg.eigvals(b.T @ g @ b) for b in spaces] + ([np.linalg.eigvals(rest.T @ g @ rest)] if rest.size else [])
    return float(np.max(np.abs(np.concatenate(parts))))


@pytest.mark.parametrize("case", list(CASES))
def test_the_known_gain_is_a_beard_filter(case: str) -> None:
    """The independent truth of each plant: its constructed gain keeps every fault's space invariant, inside the
    decay bound."""
    _, known = _plant(case)
    g = known["A"] - known["L"] @ known["C"]
    assert float(np.max(np.abs(np.linalg.eigvals(g)))) < RADIUS
    for t in known["spaces"]:
        assert np.linalg.norm(g @ t - t @ (t.T @ g @ t)) < 1e-9 * np.linalg.norm(g)


@pytest.mark.parametrize("case", list(CASES))
def test_every_plant_with_a_beard_filter_designs_plain_and_optimised(case: str) -> None:
    plant, known = _plant(case)
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        optimised = _design(plant)
    plain = _design(plant, eigenstructure="plain")
    for gf in (optimised, plain):
        assert gf.certificate["passed"]
        flt = beard_from_gain_file(gf)
        # per block of the known spaces: the plain filter shares the decay bound between the blocks, a defective
        # eigenvalue of the whole matrix that eig splits by √ε times the coupling (1e-6 here)
        assert _block_radius(flt.A - flt.L @ flt.C, known["spaces"]) <= RADIUS + 1e-7
        assert _residual_directions(gf, plant) < 1e-7
    nlp = optimised.certificate["beard_fdf"]["info"]["nlp"]
    # never worse than the plain design by the NLP's own objective (None: infinite, a shared eigenvalue)
    plain_objective = math.inf if nlp["plain_objective"] is None else nlp["plain_objective"]
    objective = math.inf if nlp["objective"] is None else nlp["objective"]
    assert objective <= plain_objective
    flt, flt_plain = beard_from_gain_file(optimised), beard_from_gain_file(plain)
    spaces = [s.basis for s in beard_structure(flt.A, flt.C, [plant.Fx[:, [j]] for j in range(plant.Fx.shape[1])]).spaces]
    ours = np.max(implicit_thresholds(flt.A - flt.L @ flt.C, flt.C, spaces, 1.0).coefficient)
    theirs = np.max(implicit_thresholds(flt_plain.A - flt_plain.L @ flt_plain.C, flt.C, spaces, 1.0).coefficient)
    assert ours <= theirs * (1 + 1e-9)


# --------------------------------------------------------------------------- corner cases, one by one


def test_no_free_eigenvalue_outside_the_detection_spaces_is_not_a_failure() -> None:
    plant, known = _plant("no-free-rest")
    st = beard_structure(plant.A, plant.C, [plant.Fx[:, [0]], plant.Fx[:, [1]]])
    assert st.free_counts == (1, 1, 0) and st.fixed.size == 1  # the rest is one fixed mode
    gf = _design(plant)
    nlp = gf.certificate["beard_fdf"]["info"]["nlp"]
    assert nlp["starts"] > 0 and nlp["source"] in ("ipopt", "start", "plain")


def test_complex_fixed_modes_design_optimised() -> None:
    plant, _ = _plant("complex-fixed-modes")
    st = beard_structure(plant.A, plant.C, [plant.Fx[:, [0]], plant.Fx[:, [1]]])
    assert st.free_counts[-1] == 0 and np.any(np.abs(st.fixed.imag) > 0.1)
    gf = _design(plant)
    info = gf.certificate["beard_fdf"]["info"]
    assert info["eigenstructure"] == "optimised" and info["nlp"]["source"] in ("ipopt", "start")
    eig = np.asarray(info["eigenvalues_z"])
    for z in st.fixed:  # the fixed modes are still there, the free ones moved off them
        assert np.min(np.hypot(eig[:, 0] - z.real, eig[:, 1] - z.imag)) < 1e-8


def test_the_plain_assignment_repeats_an_eigenvalue_only_as_often_as_the_outputs_allow() -> None:
    """A rest of three dimensions seen through one output: three copies of the decay bound would be a Jordan block
    (Ackermann's formula places it 1e-3 off); the plain assignment spreads them 'separation' apart below it."""
    plant, _ = _plant("triple-pole-through-one-output")
    st = beard_structure(plant.A, plant.C, [plant.Fx[:, [0]]])
    assert st.free_counts[-1] == 3 and st.output_ranks[-1] == 1
    assert plain_eigenvalues(st, 0.8, 0.02) == [[0.8], pytest.approx([0.8, 0.78, 0.76])]
    assert plain_eigenvalues(st, 0.03, 0.02)[-1] == pytest.approx([0.03, 0.02, 0.01])  # within [0, r] whatever r
    gf = _design(plant, eigenstructure="plain")
    eig = np.asarray(gf.certificate["beard_fdf"]["info"]["eigenvalues_z"])
    np.testing.assert_allclose(np.sort(eig[:, 0]), [0.76, 0.78, 0.8, 0.8], atol=1e-9)
    check = next(c for c in gf.certificate["beard_fdf"]["checks"] if c["name"].startswith("eigenvalues of A − L C as assigned"))
    assert check["value"] < 1e-9


def test_an_eigenvalue_given_more_often_than_the_outputs_allow_is_refused_in_fdisyn_words() -> None:
    plant, _ = _plant("rest-of-three-through-two-outputs")
    st = beard_structure(plant.A, plant.C, [plant.Fx[:, [0]]])
    assert st.free_counts[-1] == 3 and st.output_ranks[-1] == 2
    with pytest.raises(ArgumentError) as err:
        beard_gain(plant.A, plant.C, [plant.Fx[:, [0]]], [[0.5], [0.5, 0.5, 0.5]])
    msg = str(err.value)
    assert "eigenvalues[1] (the rest of the state space): 0.5 is asked for 3 times" in msg
    assert "2 independent outputs" in msg and "rank(B)" not in msg and "\n" not in msg
    # twice is what two outputs allow: placed exactly
    gain = beard_gain(plant.A, plant.C, [plant.Fx[:, [0]]], [[0.5], [0.5, 0.5, 0.3]]).L
    eig = np.sort(np.linalg.eigvals(plant.A - gain @ plant.C).real)
    np.testing.assert_allclose(eig, [0.3, 0.5, 0.5, 0.5], atol=1e-6)  # the certificate's bound on assigned ones


def test_a_fixed_mode_outside_the_decay_bound_names_the_largest_decay_rate() -> None:
    plant, _ = _plant("complex-fixed-modes")
    st = beard_structure(plant.A, plant.C, [plant.Fx[:, [0]], plant.Fx[:, [1]]])
    slow = float(np.max(np.abs(st.fixed)))
    with pytest.raises(ExistenceError) as err:
        fdisyn.design(plant, method="beard_fdf", decay_rate=-math.log(slow) / TS * 1.5, window=10)
    msg = str(err.value)
    assert "decay_rate" in msg and "fixed by the geometry" in msg and f"{-math.log(slow) / TS:.6g}" in msg


def test_the_optimised_design_returns_the_plain_one_and_says_so_when_nothing_beats_it() -> None:
    """A noise gain of 1 with the NLP unable to keep the residual as quiet as the plain filter's: the result is a
    feasible design, never an error."""
    plant, _ = _plant("no-free-rest")
    groups = [plant.Fx[:, [0]], plant.Fx[:, [1]]]
    st = beard_structure(plant.A, plant.C, groups)
    plain = beard_gain(plant.A, plant.C, groups, plain_eigenvalues(st, RADIUS, 0.02)).L
    res = optimise_eigenstructure(plant.A, plant.C, groups, st, radius=RADIUS, Q=np.asarray(plant.Q), R=np.asarray(plant.R),
                                  noise_gain=1.0, separation=0.02, plain_gain=plain, max_starts=0)
    assert res.source == "plain" and np.array_equal(res.L, plain) and "plain eigenstructure is used" in res.note
    with pytest.warns(UserWarning, match="the plain eigenstructure is used"):
        gf = _design(plant, noise_gain=1.0, separation=0.9)  # 0.9 apart: no start fits, the NLP never runs
    assert gf.certificate["passed"] and gf.certificate["beard_fdf"]["info"]["nlp"]["source"] == "plain"


def test_a_filter_that_sampling_breaks_is_named_with_the_continuous_one() -> None:
    """The textbook plant with its actuator driven by the mass: the continuous filter exists (f_push's plane, f_act's
    line), but the sampled f_push has a one-dimensional detection space and its sampling zero near −1 is a fixed mode."""
    a = np.array([[0.0, 1.0, 0.0], [0.01, 0.0, 1.0], [0.5, 0.0, -1.0]])
    plant = LinearPlant.create(A=a, B=[[0.0], [0.0], [1.0]], C=[[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
                               Fx=[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], Q=np.diag([0.0, 1e-4, 1e-4]), R=1e-4 * np.eye(2),
                               component_faults=["f_push", "f_act"])
    with pytest.raises(ExistenceError) as err:
        fdisyn.design(plant, method="beard_fdf", Ts=0.1, decay_rate=2.0)
    msg = str(err.value)
    assert "the continuous model has a Beard filter (detection spaces of dimensions [2, 1], no fixed mode)" in msg
    assert "the ZOH sampling at Ts = 0.1 s broke it" in msg and "[1, 1] sampled against [2, 1] continuous" in msg
    assert "-0.999997" in msg and "\n" not in msg
    discrete = LinearPlant.create(A=plant.discretise(0.1).A, C=plant.C, Fx=plant.discretise(0.1).Fx, R=plant.R, Ts=0.1)
    with pytest.raises(ExistenceError) as err:  # a discrete plant has no continuous model to name
        fdisyn.design(discrete, method="beard_fdf", decay_rate=2.0)
    assert "continuous model" not in str(err.value)
