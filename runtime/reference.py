"""NumPy reference step of a linear diagnoser, built from its gain file alone.

It defines the semantics the generated C must reproduce (and is checked
against it in the tests). Per sample ``k``, for each generator ``g``:

1. ``u`` and the outputs ``g`` uses must be finite, and so must ``g``'s new
   state, residual and statistics (a finite but absurd value may overflow);
   otherwise the sample is skipped for ``g``: its state and persistence
   counters stay unchanged, its residual and statistics are reported as 0 and
   it raises no alarm. After an overflow ``g`` restarts at its next valid
   sample (rule 2), so one absurd value cannot leave it stuck.
2. At ``g``'s first valid sample its state starts at the equilibrium of the
   current input/output, ``ξ = Xu u + Xy y`` (so a plant already running in
   steady state produces no start-up transient).
3. ``r = Cr ξ + Du u + Dy y``;  ``ξ⁺ = Ar ξ + Bu u + By y``.

Then each statistic of ``g`` weighs ``q_j = r_gᵀ W_j r_g``: a χ² statistic is
``J_j = q_j``; a WSSR one (window ``N``) shifts ``q_j`` into its window —
the last ``N`` samples ``g`` did not skip, newest first, zeros for those not
seen yet — and ``J_j`` is the window's sum, added newest first (the order of
the generated C). A CUSUM statistic adds ``±a_i r − drift_i`` to each sum
``S_i^±``, clamps it to ``[0, 2·threshold]`` and reports the largest; a GLR one
shifts its onset sums ``d_i(n) ← d_i(n−1) + ρ_i(n−1)ᵀ W r`` (``d_i(1) =
ρ_i(0)ᵀ W r``) and reports ``max d_i(n)² / (2 c_i(n))`` (see
:class:`~fdisyn.runtime.gainfile.Evaluator`). A statistic's persistence counter counts
consecutive samples with ``J_j > threshold_j`` (reset by a sample below); its
flag is set when the counter reaches ``persistence``. A sequential statistic's
counter is instead its held alarm: 1 from ``J_j > threshold_j`` until ``J_j``
falls to its release level (a CUSUM: until every sum that crossed the
threshold has returned to 0). ``alarm`` is any flag. ``isolated``: with the decision's hypothesis test
(:class:`~fdisyn.runtime.gainfile.Isolation`), the evidence ``z ← λ z + B r``
sums the residuals of the generators whose statistics ran (0 for the others;
a sum that overflows starts again at 0) in the test's coordinates, and the named class, held in the
state, follows :func:`isolation_test` and :func:`held_class` (a sample on
which no statistic ran leaves the test's state as it was and names nothing);
without it, the
fault whose signature equals the flag pattern, else −1.
``status`` is 1 when any input or output of the sample was non-finite or a
generator skipped it on overflow; the state keeps a running count of such
samples.

Arrays are checked before they are used, here and at the ctypes boundary of
the compiled step alike (:func:`sample_vector`, :func:`sample_block`,
:func:`step_state`: one set of rules, one set of messages): ``u``, ``y`` and
the rows of ``U``, ``Y`` must have exactly the diagnoser's sizes (nothing is
reshaped: a transposed ``U`` is refused, not reread), hold real numbers
(floating point or integer, converted to float64; ``None``, booleans, complex
numbers, strings and objects are refused) and ``state`` must be the
diagnoser's float64 vector.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from fdisyn.runtime.errors import ArgumentError, ShapeError
from fdisyn.runtime.gainfile import GainFile, Isolation, release_level
from fdisyn.runtime.layout import linear_state_layout
from fdisyn.runtime.statistics import STATISTICS, glr_weights
from fdisyn.runtime.warmup import generator_warmup

__all__ = [
    "StepOutput", "RunResult", "LinearReference", "ChangeEstimate", "glr_estimates", "IsolationEvidence", "isolation_test",
    "isolation_evidence", "held_class", "sample_vector", "sample_block", "step_state",
]


def _real_array(a: object, name: str, expected: str) -> np.ndarray:
    """``a`` as an array of real numbers (no copy yet), or :class:`ArgumentError` naming ``name``."""
    if a is None:
        raise ArgumentError(f"{name} is None; expected real numbers of shape {expected}")
    try:
        arr = np.asarray(a)
    except (TypeError, ValueError) as exc:  # ragged nesting, unconvertible objects
        raise ArgumentError(f"{name} is not an array of numbers ({exc}); expected shape {expected}") from None
    if arr.dtype.kind not in "fiu":
        what = {"b": "booleans", "c": "complex numbers", "O": "Python objects", "U": "strings", "S": "bytes"}.get(arr.dtype.kind, str(arr.dtype))
        raise ArgumentError(f"{name} holds {what} (dtype {arr.dtype}); expected real numbers of shape {expected}")
    return arr


def _shape_text(shape: tuple[int | str, ...]) -> str:
    return "(" + ", ".join(str(d) for d in shape) + ("," if len(shape) == 1 else "") + ")"


def sample_vector(a: object, name: str, size: int) -> np.ndarray:
    """One sample's ``u`` or ``y``: exactly ``size`` real numbers, returned as a new contiguous float64 vector."""
    expected = _shape_text((size,))
    arr = _real_array(a, name, expected)
    if arr.shape != (size,):
        raise ShapeError(f"{name} has shape {_shape_text(arr.shape)}; expected {expected}")
    return np.array(arr, dtype=np.float64, order="C", copy=True)


def sample_block(a: object, name: str, width: int, rows: int | None = None) -> np.ndarray:
    """``U`` or ``Y`` over a trace: exactly ``rows × width`` real numbers (``rows`` free when ``None``).

    Returned as a new C-contiguous float64 array. Nothing is reshaped: a
    transposed or flattened block is refused.
    """
    expected = _shape_text(("N" if rows is None else rows, width))
    arr = _real_array(a, name, expected)
    if arr.ndim != 2 or arr.shape[1] != width or (rows is not None and arr.shape[0] != rows):
        raise ShapeError(f"{name} has shape {_shape_text(arr.shape)}; expected {expected} (one row per sample)")
    return np.array(arr, dtype=np.float64, order="C", copy=True)


def step_state(state: object, nstate: int) -> np.ndarray:
    """The state a per-sample step updates in place: a writeable, C-contiguous float64 vector of ``nstate``.

    It is not converted (a converted copy would leave the caller's state
    unchanged); anything else is refused before it reaches the step.
    """
    if (
        not isinstance(state, np.ndarray)
        or state.dtype != np.float64
        or state.shape != (nstate,)
        or not state.flags.c_contiguous
        or not state.flags.writeable
    ):
        found = (
            f"{type(state).__name__}"
            if not isinstance(state, np.ndarray)
            else f"dtype {state.dtype}, shape {_shape_text(state.shape)}"
            + ("" if state.flags.c_contiguous else ", not contiguous")
            + ("" if state.flags.writeable else ", read-only")
        )
        raise ShapeError(
            f"state must be a writeable, contiguous float64 array of shape {_shape_text((nstate,))} "
            f"(the step updates it in place); found {found}"
        )
    return state


@dataclass(frozen=True)
class StepOutput:
    r: np.ndarray
    J: np.ndarray
    alarm: int
    isolated: int
    status: int


@dataclass(frozen=True)
class RunResult:
    """A diagnoser's outputs over a trace (one row per sample)."""

    r: np.ndarray
    J: np.ndarray
    alarm: np.ndarray
    isolated: np.ndarray
    status: np.ndarray
    state: np.ndarray
    """State after the last sample."""

    @property
    def nonfinite_samples(self) -> int:
        return int(np.sum(self.status == 1))


@dataclass(frozen=True)
class ChangeEstimate:
    """What a GLR statistic's state says about the change it sees (Willsky & Jones 1976)."""

    statistic: str
    hypothesis: str
    """The fault class(es) of the most likely hypothesis."""
    onset_samples_ago: int
    """The maximising onset: the change started this many samples ago (1: at the last sample)."""
    size: float
    """The estimated size ``d/c`` in multiples of the designed minimum fault of the hypothesis's first class
    (its sign included)."""
    J: float


def glr_estimates(gf: GainFile, state: np.ndarray) -> list[ChangeEstimate]:
    """The most likely hypothesis, onset and size of every GLR statistic of ``gf`` from a step ``state``
    (the state after a sample: the C ``<prefix>_state`` array or :attr:`Monitor.state`). The step's outputs
    are unchanged by this; it reads the onset sums ``d_i(n)`` the state holds."""
    lay = linear_state_layout(gf.generators, gf.evaluators, gf.decision)
    st = step_state(np.asarray(state, dtype=np.float64).copy(), gf.step.nstate)
    out = []
    for j, ev in enumerate(gf.evaluators):
        if not STATISTICS[ev.kind].onset_sums:
            continue
        d = st[lay[f"sequential{j}"]]
        w = glr_weights(ev.information, ev.window)
        terms = d * d * w
        best = int(np.argmax(terms))
        h, n = divmod(best, ev.window)
        c = np.asarray(ev.information)[best]
        out.append(
            ChangeEstimate(
                statistic=gf.step.statistic_names[j],
                hypothesis=ev.hypotheses[h],
                onset_samples_ago=n + 1,
                size=float(d[best] / c) if w[best] > 0 else 0.0,
                J=float(terms[best]),
            )
        )
    return out


@dataclass(frozen=True)
class IsolationEvidence:
    """What the isolation test says of each fault class at one sample (:func:`isolation_test`)."""

    evidence: np.ndarray
    """``g_f``: the GLR of a shift in the class's span (χ² with ``ranks[f]`` degrees of freedom when the class's
    fault is absent)."""
    misfit: np.ndarray
    """``e_f``: what the class's span leaves unexplained (χ² with ``rank V − ranks[f]`` degrees of freedom when the
    class's fault is present)."""
    plausible: np.ndarray
    """The data do not reject the class (``e_f ≤ reject[f]``)."""
    supported: np.ndarray
    """Plausible, and its evidence passes ``accept[f]``."""
    candidate: int
    """The supported class every other plausible class contains, −1 when there is none."""


def isolation_test(iso: Isolation, s: np.ndarray) -> IsolationEvidence:
    """The hypothesis test of :class:`~fdisyn.runtime.gainfile.Isolation` on the evidence ``s``.

    Parameters
    ----------
    iso : Isolation
        The decision's test.
    s : numpy.ndarray
        The evidence ``z`` (the state's ``evidence`` block, ``len(basis)`` entries).

    Returns
    -------
    IsolationEvidence
        Each class's evidence, misfit and verdicts, and the candidate the rule names.
    """
    s = np.asarray(s, dtype=float)
    q = float(s @ s)
    proj = np.asarray(iso.directions) @ s if np.asarray(iso.directions).size else np.zeros(0)
    ranks = np.asarray(iso.ranks, dtype=int)
    ends = np.cumsum(ranks)
    g = np.array([float(np.sum(proj[e - k : e] ** 2)) for e, k in zip(ends, ranks, strict=True)])
    misfit = q - g
    plausible = misfit <= np.asarray(iso.reject)
    supported = plausible & (g >= np.asarray(iso.accept))
    nested = np.asarray(iso.nested, dtype=int)
    candidate = -1
    for f in range(len(ranks)):
        others = [k for k in range(len(ranks)) if k != f and plausible[k] and not nested[f][k]]
        if supported[f] and not others:
            candidate = f
            break
    return IsolationEvidence(evidence=g, misfit=misfit, plausible=plausible, supported=supported, candidate=candidate)


def held_class(named: int, alarm: bool, test: IsolationEvidence, settled: bool = True, pattern: int = -1) -> int:
    """The class the decision names after a sample, from the one it held before.

    While the alarm is raised, when no class is named the test's candidate is (once the alarm has been raised
    for the test's ``settle`` samples: ``settled``), else the class whose signature equals the flag pattern
    (``pattern``, −1: none); a named class is replaced only when the test names another: either the named class is
    no longer plausible, or the test's candidate is a class the named one contains (every plausible class contains
    the candidate), so a name the flag pattern or an early sample gave to a class of several members narrows to the
    member the evidence singles out. While the test names nothing the name is held; when the alarm falls nothing
    is named.

    Parameters
    ----------
    named : int
        The class named before the sample (−1: none).
    alarm : bool
        The sample's alarm.
    test : IsolationEvidence
        The sample's :func:`isolation_test`.
    settled : bool
        The alarm has been raised for at least ``settle`` samples.
    pattern : int
        The class whose signature equals the flag pattern, −1 when none does.

    Returns
    -------
    int
        The class named now, −1 for none.
    """
    if not alarm:
        return -1
    candidate = test.candidate if settled else -1
    if candidate >= 0:
        return candidate
    return named if named >= 0 else pattern


def isolation_evidence(gf: GainFile, state: np.ndarray) -> IsolationEvidence | None:
    """The isolation test on the evidence a step ``state`` holds (the state after a sample: the C
    ``<prefix>_state`` array or :attr:`Monitor.state`); ``None`` for a decision without the test. It says
    which classes the data still leave plausible when nothing is named."""
    if gf.kind != "linear" or gf.decision is None or gf.decision.isolation is None:
        return None
    lay = linear_state_layout(gf.generators, gf.evaluators, gf.decision)
    st = step_state(np.asarray(state, dtype=np.float64).copy(), gf.step.nstate)
    return isolation_test(gf.decision.isolation, st[lay["evidence"]])


class LinearReference:
    """The reference implementation of a ``kind = "linear"`` gain file."""

    def __init__(self, gf: GainFile) -> None:
        if gf.kind != "linear":
            raise ArgumentError(f"the NumPy reference implements linear diagnosers; this gain file is of kind {gf.kind!r}")
        self.gf = gf
        self.layout = linear_state_layout(gf.generators, gf.evaluators, gf.decision)
        self.thresholds = gf.thresholds
        assert gf.decision is not None
        self.signatures = np.asarray(gf.decision.signatures, dtype=int)
        self.persistence = int(gf.decision.persistence)
        offsets = np.cumsum([0] + [g.n_residual for g in gf.generators])
        self.release = [release_level(e) for e in gf.evaluators]
        self.statistics = [STATISTICS[e.kind] for e in gf.evaluators]
        self.prepared = [s.prepare(e) for s, e in zip(self.statistics, gf.evaluators, strict=True)]
        self.r_slices = [slice(int(offsets[i]), int(offsets[i + 1])) for i in range(len(gf.generators))]
        # looked up once rather than at every sample: the state's blocks by name, the outputs each generator
        # reads and the statistics each feeds
        self.blocks = {name: self.layout[name] for name, _, _ in self.layout.entries}
        self.outputs_used = [list(gen.outputs_used) for gen in gf.generators]
        self.statistics_of = [[j for j, ev in enumerate(gf.evaluators) if ev.generator == g] for g in range(len(gf.generators))]
        # each generator's warm-up: its length and constants (the first statistic's weight), None without one
        self.warmup = [generator_warmup(gf, g) for g in range(len(gf.generators))]

    def init_state(self) -> np.ndarray:
        return self.gf.step.init_state.copy()

    def step(self, state: np.ndarray, u: np.ndarray, y: np.ndarray) -> StepOutput:
        """Advance ``state`` in place by one sample and return the outputs (arrays checked first)."""
        st = self.gf.step
        return self._advance(step_state(state, st.nstate), sample_vector(u, "u", st.nu), sample_vector(y, "y", st.ny))

    def _advance(self, state: np.ndarray, u: np.ndarray, y: np.ndarray) -> StepOutput:
        gf, lay = self.gf, self.blocks
        fin_u, fin_y = np.isfinite(u), np.isfinite(y)
        all_u = bool(fin_u.all())
        us = np.where(fin_u, u, 0.0)
        ys = np.where(fin_y, y, 0.0)
        r = np.zeros(gf.step.nr)
        jv = np.zeros(gf.step.nj)
        ready = state[lay["ready"]]
        counters = state[lay["counters"]]
        flags = np.zeros(gf.step.nj, dtype=int)
        overflow = False
        r_live = np.zeros(gf.step.nr)  # the residuals of the generators whose statistics ran: the evidence's input
        ran = False
        for g, gen in enumerate(gf.generators):
            n_warm = gen.warmup
            if not (all_u and fin_y[self.outputs_used[g]].all()):
                if ready[g] < n_warm:  # a gap in the warm-up: it starts again at the next valid sample
                    ready[g] = 0.0
                continue
            sl = lay[f"xi{g}"]
            xi = gen.Xu @ us + gen.Xy @ ys if ready[g] == 0.0 else state[sl]
            live = ready[g] >= n_warm  # the warm-up done: the statistics run
            acc = None
            with np.errstate(over="ignore", invalid="ignore"):
                rg = gen.Cr @ xi + gen.Du @ us + gen.Dy @ ys
                xi_next = gen.Ar @ xi + gen.Bu @ us + gen.By @ ys
                warm = self.warmup[g]
                if not live and warm is not None:
                    gains, correction = warm
                    k = int(ready[g])
                    acc = (0.0 if k == 0 else state[lay[f"acc{g}"]]) + gains[k] @ rg
                    if k == n_warm - 1:  # the last warm-up sample: its least-squares initial error removed
                        xi_next = xi_next + correction @ acc
                        acc = np.zeros_like(acc)  # used: the accumulator is emptied
                evs = self.statistics_of[g]  # evaluated in the warm-up too: an absurd sample overflows as it would later
                # q = rᵀ W r of every non-sequential statistic first, then each statistic's update in order
                jg = {j: float(rg @ gf.evaluators[j].W @ rg) for j in evs if not self.statistics[j].sequential}
                windows = {}
                for j in evs:
                    stat = self.statistics[j]
                    if stat.update is not None:
                        old = state[lay[f"{stat.block}{j}"]]
                        jg[j], windows[j] = stat.update(gf.evaluators[j], rg, jg.get(j), old, self.prepared[j])
            # a finite but absurd value can overflow: the sample is then skipped like a non-finite one
            if not (np.isfinite(rg).all() and np.isfinite(xi_next).all() and np.isfinite(list(jg.values())).all()
                    and (acc is None or np.isfinite(acc).all())):
                overflow = True
                ready[g] = 0.0  # restart at the next valid sample: the state may hold an absurd value
                continue
            ready[g] = min(ready[g] + 1.0, n_warm + 1.0)
            state[sl] = xi_next
            if acc is not None:
                state[lay[f"acc{g}"]] = acc
            r[self.r_slices[g]] = rg
            if not live:  # the warm-up: the statistics are held
                continue
            r_live[self.r_slices[g]] = rg
            ran = True
            for j, window in windows.items():
                state[lay[f"{self.statistics[j].block}{j}"]] = window
            for j, value in jg.items():
                jv[j] = value
                counters[j] = self.statistics[j].counter(
                    gf.evaluators[j], value, counters[j], self.thresholds[j], self.release[j], windows.get(j)
                )
                flags[j] = int(counters[j] >= self.persistence)
        state[lay["ready"]] = ready
        state[lay["counters"]] = counters
        bad = overflow or not (all_u and fin_y.all())
        if bad:
            state[lay["nonfinite"]] += 1.0
        alarm = bool(flags.any())
        iso = gf.decision.isolation  # type: ignore[union-attr]
        match = np.flatnonzero((self.signatures == flags[None, :]).all(axis=1))
        pattern = int(match[0]) if match.size else -1
        if iso is None:
            isolated = pattern
        elif not ran:  # no statistic ran (a non-finite or warm-up sample): the test keeps its state, no alarm, no name
            isolated = -1
        else:
            with np.errstate(over="ignore", invalid="ignore"):
                evidence = iso.forgetting * state[lay["evidence"]] + np.asarray(iso.basis) @ r_live
            if not np.isfinite(evidence).all():  # an overflow: the evidence starts again
                evidence = np.zeros_like(evidence)
            state[lay["evidence"]] = evidence
            with np.errstate(over="ignore", invalid="ignore"):
                test = isolation_test(iso, evidence)
            age = min(float(state[lay["age"]][0]) + 1.0, float(iso.settle)) if alarm else 0.0
            state[lay["age"]] = age
            isolated = held_class(int(state[lay["named"]][0]) - 1, alarm, test, age >= iso.settle, pattern)
            state[lay["named"]] = isolated + 1
        return StepOutput(r=r, J=jv, alarm=int(alarm), isolated=isolated, status=int(bad))

    def run(self, U: np.ndarray, Y: np.ndarray, state: np.ndarray | None = None) -> RunResult:
        """Run over a trace: ``U`` is ``N × nu``, ``Y`` is ``N × ny``; ``state`` (copied) defaults to the initial one."""
        spec = self.gf.step
        Y = sample_block(Y, "Y", spec.ny)
        n = Y.shape[0]
        U = sample_block(U, "U", spec.nu, rows=n)
        st = self.init_state() if state is None else sample_vector(state, "state", spec.nstate)
        out_r = np.zeros((n, self.gf.step.nr))
        out_j = np.zeros((n, self.gf.step.nj))
        out_a = np.zeros(n, dtype=int)
        out_i = np.zeros(n, dtype=int)
        out_s = np.zeros(n, dtype=int)
        for k in range(n):
            o = self._advance(st, U[k], Y[k])
            out_r[k], out_j[k], out_a[k], out_i[k], out_s[k] = o.r, o.J, o.alarm, o.isolated, o.status
        return RunResult(r=out_r, J=out_j, alarm=out_a, isolated=out_i, status=out_s, state=st)
