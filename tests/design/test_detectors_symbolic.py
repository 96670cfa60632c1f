"""The symbolic detector updates of :mod:`fdisyn.detectors.symbolic` against the NumPy reference.

Each update is evaluated numerically (a CasADi ``Function`` of its inputs) sample by sample beside
:class:`fdisyn.runtime.reference.LinearReference` running a one-statistic diagnoser whose residual is its
output (``r = y``): before each sample the reference's state block and counter are fed to the update, after it
the update's ``J``, state and counter must equal the reference's.

Tolerance: ``1e-12`` relative (of the values' magnitude). The reference forms ``rᵀ W r`` and ``a_i r`` with
NumPy's matrix products, the updates with CasADi's, which may add the same products in another order: a
few units in the last place per sample, accumulated over at most the window. Decisions (counters, latches,
the hold) are compared exactly; a statistic within round-off of its threshold is not drawn on random data.
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from fdisyn.detectors.table import DETECTORS
from fdisyn.detectors.symbolic import (
    all_finite,
    chi2,
    cusum_latch,
    cusum_update,
    finite,
    glr_hold,
    glr_statistic,
    glr_update,
    persistence_count,
    wssr_held,
    wssr_threshold,
    wssr_update,
)
from fdisyn.runtime.gainfile import Decision, Evaluator, GainFile, Generator, StepSpec, release_level
from fdisyn.runtime.layout import linear_state_layout
from fdisyn.runtime.schema import EVALUATOR_KINDS, SEQUENTIAL_KINDS
from fdisyn.runtime.reference import LinearReference
from fdisyn.runtime.statistics import glr_weights

RTOL = 1e-12
P = 2  # residual size


def _diagnoser(ev: Evaluator, persistence: int = 1) -> GainFile:
    """One static generator ``r = y`` (``P`` outputs) and the one statistic ``ev``."""
    gen = Generator.from_canonical(
        name="g", outputs_used=tuple(range(P)), Ar=np.zeros((1, 1)), Bu=np.zeros((1, 1)), By=np.zeros((1, P)),
        Cr=np.zeros((P, 1)), Du=np.zeros((P, 1)), Dy=np.eye(P),
    )  # fmt: skip
    lay = linear_state_layout([gen], [ev])
    return GainFile(
        kind="linear", name="one", problem="one", design="one", Ts=1.0, inputs=("u",), outputs=tuple(f"y{i}" for i in range(P)), faults=("f",),
        step=StepSpec(nu=1, ny=P, nr=P, nj=1, nstate=lay.size, init_state=np.zeros(lay.size), residual_names=tuple(f"r{i}" for i in range(P)), statistic_names=("J",)),
        plant={"A": np.zeros((1, 1)), "B": np.zeros((1, 1)), "C": np.ones((P, 1)), "D": np.zeros((P, 1)), "E": np.zeros((1, 0)), "Q": np.eye(1), "R": np.eye(P)},
        generators=(gen,), evaluators=(ev,),
        decision=Decision(kind="signature_table", signatures=np.array([[1]]), persistence=persistence),
        certificate={"passed": True},
    )  # fmt: skip


def _W(rng: np.random.Generator) -> np.ndarray:
    a = rng.standard_normal((P, P))
    return a @ a.T + 0.5 * np.eye(P)


def _unit(a: np.ndarray) -> np.ndarray:
    return a / np.linalg.norm(a, axis=-1, keepdims=True)


def _evaluator(kind: str, rng: np.random.Generator, window: int = 1) -> Evaluator:
    W = _W(rng)
    common = dict(generator=0, P_f=0.01, dof=P, Sigma_r=np.linalg.inv(W), W=W)
    if kind in ("chi2", "wssr"):
        return Evaluator(kind=kind, threshold=6.0 * window, window=window, **common)  # type: ignore[arg-type]
    if kind == "cusum":
        a = _unit(rng.standard_normal((2, P)) @ W)  # directions μᵀ W lie in W's range
        return Evaluator(kind="cusum", threshold=4.0, directions=a, drift=np.array([0.3, 0.7]), hypotheses=("h0", "h1"), **common)  # type: ignore[arg-type]
    a = np.vstack([np.outer(np.ones(window), _unit(rng.standard_normal(P) @ W)) for _ in range(2)])
    info = np.concatenate([np.arange(1.0, window + 1.0)] * 2)
    if window > 1:
        info[0] = 0.0  # an onset too recent to have shown: weight 0, left out of J
    return Evaluator(kind="glr", threshold=3.0, window=window, directions=a, information=info, hypotheses=("h0", "h1"), **common)  # type: ignore[arg-type]


def _function(inputs: list[ca.SX], outputs: list[ca.SX]) -> ca.Function:
    return ca.Function("f", inputs, outputs)


def _close(a: object, b: object) -> bool:
    a, b = np.asarray(a, dtype=float).ravel(), np.asarray(b, dtype=float).ravel()
    return a.shape == b.shape and bool(np.all(np.abs(a - b) <= RTOL * (1.0 + np.maximum(np.abs(a), np.abs(b)))))


def _trace(rng: np.random.Generator, n: int, scale: float, shift: float = 0.0) -> np.ndarray:
    """Noise of standard deviation ``scale``; with ``shift``, added to every output in alternate stretches of
    40 samples (alarms raised, then released)."""
    on = (np.arange(n) // 40) % 2 == 1
    return scale * rng.standard_normal((n, P)) + shift * on[:, None]


def _run(gf: GainFile, Y: np.ndarray, update: ca.Function, block: str | None) -> tuple[int, int]:
    """Step the reference over ``Y``; before each sample evaluate ``update(r, block, counter)`` and compare it
    with the reference's ``J``, block and counter after it. Returns the number of samples the counter was
    nonzero, and of those the number with ``J`` at or below the threshold (a held alarm, or a count that has
    not reached the persistence yet), so that the tests can check they exercised the alarm rule."""
    ref = LinearReference(gf)
    lay = ref.layout
    st = ref.init_state()
    raised = held = 0
    for y in Y:
        old_block = st[lay[block]].copy() if block else np.zeros(0)
        old_counter = st[lay["counters"]][0]
        out = ref.step(st, np.zeros(1), y)
        J, new_block, counter = (np.asarray(v, dtype=float) for v in update(y, old_block, old_counter))
        assert out.status == 0
        assert _close(J, out.J[0]), (J, out.J)
        if block:
            assert _close(new_block, st[lay[block]]), (new_block, st[lay[block]])
        assert counter.item() == st[lay["counters"]][0]
        raised += st[lay["counters"]][0] > 0
        held += st[lay["counters"]][0] > 0 and out.J[0] <= gf.evaluators[0].threshold
    return raised, held


def _symbols(gf: GainFile, block: str | None) -> tuple[ca.SX, ca.SX, ca.SX]:
    size = linear_state_layout(gf.generators, gf.evaluators, gf.decision)[block].stop - linear_state_layout(gf.generators, gf.evaluators, gf.decision)[block].start if block else 0
    return ca.SX.sym("r", P), ca.SX.sym("block", size), ca.SX.sym("counter")


@pytest.mark.parametrize("persistence", [1, 3])
def test_chi2_and_the_persistence_counter_are_the_references(persistence):
    rng = np.random.default_rng(1)
    gf = _diagnoser(_evaluator("chi2", rng), persistence)
    r, _, c = _symbols(gf, None)
    J = chi2(r, gf.evaluators[0].W)
    fn = _function([r, ca.SX.sym("none", 0), c], [J, ca.SX(0, 1), persistence_count(J > gf.evaluators[0].threshold, c)])
    raised, _ = _run(gf, _trace(rng, 400, 1.6), fn, None)
    assert raised > 20


@pytest.mark.parametrize("window", [1, 2, 5])
def test_wssr_shift_and_sum_are_the_references(window):
    rng = np.random.default_rng(window)
    gf = _diagnoser(_evaluator("wssr", rng, window), 2)
    r, w, c = _symbols(gf, "window0")
    J, new, none = wssr_update(chi2(r, gf.evaluators[0].W), w)
    assert none is None
    fn = _function([r, w, c], [J, new, persistence_count(J > gf.evaluators[0].threshold, c)])
    raised, _ = _run(gf, _trace(rng, 300, 1.4), fn, "window0")
    assert raised > 10


def test_the_wssr_mean_over_the_samples_seen_is_the_references_sum_over_the_count():
    """The NAFDF's form (a fill count): ``J / min(k, N)``, held ``J / max(count, 1)``, its threshold looked up."""
    rng = np.random.default_rng(7)
    N = 4
    gf = _diagnoser(_evaluator("wssr", rng, N))
    ref = LinearReference(gf)
    r, w, c = _symbols(gf, "window0")
    L, new, filled = wssr_update(chi2(r, gf.evaluators[0].W), w, c)
    held, held_count = wssr_held(w, c)
    table = np.array([11.0, 7.0, 5.0, 3.0])
    fn = _function([r, w, c], [L, new, filled, held, held_count, wssr_threshold(filled, table), wssr_threshold(held_count, table)])
    st = ref.init_state()
    count, previous = 0.0, 0.0
    for k, y in enumerate(_trace(rng, 12, 1.0)):
        before = st[ref.layout["window0"]].copy()
        out = ref.step(st, np.zeros(1), y)
        v = [np.asarray(x, dtype=float).ravel() for x in fn(y, before, count)]
        assert v[2][0] == min(k + 1, N) and v[4][0] == max(count, 1.0)
        assert _close(v[0], out.J[0] / min(k + 1, N)) and _close(v[1], st[ref.layout["window0"]])
        assert _close(v[3], previous / max(count, 1.0))
        assert v[5][0] == table[min(k + 1, N) - 1] and v[6][0] == table[int(max(count, 1.0)) - 1]
        count, previous = v[2][0], out.J[0]


def test_cusum_sums_and_latches_are_the_references():
    rng = np.random.default_rng(3)
    ev = _evaluator("cusum", rng)
    gf = _diagnoser(ev)
    r, s, c = _symbols(gf, "sequential0")
    J, sums = cusum_update(ca.mtimes(ca.DM(ev.directions), r), s[:4], ev.drift, ev.threshold)
    latches, latched = cusum_latch(sums, s[4:], ev.threshold)
    fn = _function([r, s, c], [J, ca.vertcat(sums, latches), ca.if_else(latched, 1, 0)])
    raised, held = _run(gf, _trace(rng, 400, 0.7, 1.5), fn, "sequential0")
    assert raised > 10 and held > 5  # latched below the threshold until the sum returns to 0


def test_the_cusum_tuned_to_a_shift_is_the_references_with_scaled_directions():
    """The NAFDF's form: increments ``δ (±w) − δ²/2`` are the reference's with directions ``δ I`` and drift ``δ²/2``."""
    rng = np.random.default_rng(4)
    dlt = 1.3
    ev = Evaluator(kind="cusum", generator=0, P_f=0.01, dof=P, threshold=3.0, Sigma_r=np.eye(P), W=np.eye(P),
                   directions=dlt * np.eye(P), drift=np.full(P, 0.5 * dlt * dlt), hypotheses=("h0", "h1"))  # fmt: skip
    gf = _diagnoser(ev)
    r, s, c = _symbols(gf, "sequential0")
    J, sums = cusum_update(r, s[: 2 * P], 0.5 * dlt * dlt, ev.threshold, shift=dlt)
    latches, latched = cusum_latch(sums, s[2 * P :], ev.threshold)
    fn = _function([r, s, c], [J, ca.vertcat(sums, latches), ca.if_else(latched, 1, 0)])
    raised, held = _run(gf, _trace(rng, 400, 1.0, 1.5), fn, "sequential0")
    assert raised > 10 and held > 5


@pytest.mark.parametrize("window", [1, 3, 6])
def test_glr_onset_sums_statistic_and_hold_are_the_references(window):
    rng = np.random.default_rng(10 + window)
    ev = _evaluator("glr", rng, window)
    gf = _diagnoser(ev)
    r, s, c = _symbols(gf, "sequential0")
    sums = glr_update(ca.mtimes(ca.DM(ev.directions), r), s, window)
    J = glr_statistic(sums, glr_weights(ev.information, window))
    fn = _function([r, s, c], [J, sums, glr_hold(J, c, ev.threshold, release_level(ev))])
    raised, held = _run(gf, _trace(rng, 400, 1.0, 1.5), fn, "sequential0")
    assert raised > 10 and held > 5  # held down to the release level


def test_the_glr_statistic_is_the_same_in_either_layout():
    """The NAFDF keeps its onset sums ``p × M`` (component fastest): the statistic is the largest weighted
    square whatever the order the sums are stored in."""
    rng = np.random.default_rng(5)
    M = 4
    d = ca.SX.sym("d", P, M)
    w = np.tile(0.5 / np.arange(1, M + 1), (P, 1))
    fn = _function([d], [glr_statistic(d, w), glr_statistic(ca.vec(d.T), w.reshape(-1))])
    for _ in range(20):
        v = rng.standard_normal((P, M))
        a, b = (float(x) for x in fn(v))
        assert a == b == float(np.max(v * v * w))


def test_a_capped_persistence_count_stops_at_the_cap():
    """The Beard filter's counter (its NumPy twin: ``min(counter + 1, persistence)`` while exceeding, else 0)."""
    e, c = ca.SX.sym("e"), ca.SX.sym("c")
    fn = _function([e, c], [persistence_count(e, c, cap=3), persistence_count(e, c)])
    for exceed, count in [(1, 0), (1, 2), (1, 3), (0, 3), (1, 7)]:
        capped, free = (float(x) for x in fn(exceed, count))
        assert capped == (min(count + 1, 3) if exceed else 0.0) and free == (count + 1 if exceed else 0.0)


@pytest.mark.parametrize("kind", ["chi2", "wssr", "cusum", "glr"])
def test_a_value_the_reference_skips_on_overflow_is_not_finite_in_the_update(kind):
    """A finite but absurd residual: the reference skips the sample (status 1) exactly when the update's
    value or state is not finite, which is the test the linear step skips it by."""
    rng = np.random.default_rng(20)
    ev = _evaluator(kind, rng, 3 if kind in ("wssr", "glr") else 1)
    gf = _diagnoser(ev)
    stat = DETECTORS[kind].statistic
    block = f"{stat.block}0" if stat.block else None
    r, s, _ = _symbols(gf, block)
    value = stat.evaluate(r, s if block else None, ev)
    fn = _function([r, s], [all_finite(value.J, *([value.state] if value.state is not None else []))])
    ref = LinearReference(gf)
    st = ref.init_state()
    seen = set()
    for scale in [1.0, 1e150, 1e200, 1e300, 1.0, 1e-300, 1e160]:
        y = scale * rng.standard_normal(P)
        before = st[ref.layout[block]].copy() if block else np.zeros(0)
        ok = bool(float(fn(y, before)))
        out = ref.step(st, np.zeros(1), y)
        assert ok == (out.status == 0), (scale, ok, out.status)
        seen.add(ok)
    if kind in ("chi2", "wssr"):  # q = rᵀ W r overflows; a CUSUM's or GLR's clamp or square may not
        assert seen == {True, False}


def test_finite_is_false_for_nan_and_infinities_only():
    x = ca.SX.sym("x", 6)
    fn = _function([x], [finite(x), all_finite(x)])
    v = np.array([0.0, -1e308, 1.7976931348623157e308, np.nan, np.inf, -np.inf])
    flags, every = fn(v)
    assert np.asarray(flags).ravel().tolist() == [1, 1, 1, 0, 0, 0] and float(every) == 0.0
    assert float(fn(np.r_[v[:3], 1.0, 2.0, 3.0])[1]) == 1.0


def test_every_statistic_kind_of_a_gain_file_has_its_symbolic_update_and_the_linear_step_names_none():
    """A statistic kind the gain file accepts is evaluated by the linear step through its entry of
    detector's entry alone (:data:`fdisyn.detectors.table.DETECTORS`): its state block and sequential flag agree
    with the file's layout."""
    import inspect

    import fdisyn.synthesis.linear_step as linear_step

    assert set(DETECTORS) == set(EVALUATOR_KINDS)
    for kind, stat in ((k, d.statistic) for k, d in DETECTORS.items()):
        assert stat.sequential == (kind in SEQUENTIAL_KINDS)
        gf = _diagnoser(_evaluator(kind, np.random.default_rng(0), 1 if kind in ("chi2", "cusum") else 2))
        blocks = {name for name, _, _ in linear_state_layout(gf.generators, gf.evaluators, gf.decision).entries}
        assert (stat.block is None) == ({"window0", "sequential0"}.isdisjoint(blocks))
        assert stat.block is None or f"{stat.block}0" in blocks
    source = inspect.getsource(linear_step)
    assert not [kind for kind in EVALUATOR_KINDS if f'"{kind}"' in source or f"'{kind}'" in source]
