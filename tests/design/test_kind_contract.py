"""Every registered diagnoser kind honours the step contract, in the manner of CasADi's ``check_codegen``
(test/python/helpers.py: generate the C, compile it, load it, evaluate it on the same inputs as the symbolic
function and compare every output).

For each kind of :func:`fdisyn.synthesis.kinds.all_kinds` (parametrised by name, so a kind registered later is held
by this test the moment it exists, and fails it until it has a test design in :data:`DESIGNS`), on one small
design and a trace with NaN and ±inf written into a few samples:

- the step's names, sizes and dense vectors are the contract's, from ``gf.step``, and ``init_state`` is finite;
- the exported C library (every symbol it exports prefixed by the diagnoser's name, its thresholds the gain
  file's) (:func:`fdisyn.export`, loaded by :class:`~fdisyn.runtime.compiled.CompiledDiagnoser`)
  against the CasADi step, and both against the kind's independent NumPy reference
  (:attr:`~fdisyn.synthesis.kinds.DiagnoserKind.reference`, where the kind has one): ``state``, ``r`` and ``J``
  to round-off, ``alarm``, ``isolated`` and ``status`` exactly;
- a non-finite sample has status 1; a sample with every value NaN leaves the state as it was but for the count of
  non-finite samples, which goes up by one;
- two instances of the library, stepped in turn on different traces, each give what it gives alone, and the
  whole-trace call gives what the per-sample calls give, bit for bit;
- the kind's fields work on the gain file (describe, certified, rate_unit, recovery_samples, the budget, the
  Lorden bound and window, the account or the note saying why there is none).

:func:`check_kind_contract` is the whole check, for any gain file; ARCHITECTURE.md's worked example of a new kind
runs it too (tests/design/test_architecture_kind.py).
"""

from __future__ import annotations

import ctypes
import math
import shutil
import subprocess
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import fdisyn
import numpy as np
import pytest
import scipy.linalg
from fdisyn.models.linear import LinearPlant
from fdisyn.codegen.step import step_function
from fdisyn.runtime.compiled import CompiledDiagnoser
from fdisyn.runtime.gainfile import GainFile, read_gain_file
from fdisyn.runtime.reference import RunResult
from fdisyn.simulation.plant_file import load_spec
from fdisyn.synthesis import kinds

from tests.helpers import random_plant

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "design" / "examples"

C_VS_CASADI = 1e-12
"""``max |C − CasADi| / max(1, |CasADi|)`` over ``state``, ``r`` and ``J``: the generated C performs CasADi's
operations in CasADi's order in IEEE double (no fast-math, no FMA contraction), so only libm may differ, by an ulp
(``log``, ``sqrt`` of the NAFDF's classifier and the Beard filter's angles). Measured: 0 on every kind."""

REFERENCE = 1e-10
"""``max |reference − CasADi| / max(1, |CasADi|)`` over ``state``, ``r`` and ``J``: the NumPy reference is written
independently, with NumPy's summation order and BLAS products; the differences are rounding errors of sums of terms
of the size of the state (at most ~1e3 on these traces), amplified by ``J``'s quadratic form and a window's sum.
Measured: 1.5e-12 (linear), 4.7e-14 (beard_fdf); the NAFDF has no reference."""


@dataclass(frozen=True)
class Design:
    """A small design of one kind and a trace to run it on."""

    gain_file: GainFile
    U: np.ndarray
    Y: np.ndarray


def hostile(U: np.ndarray, Y: np.ndarray, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """``U``, ``Y`` with NaN, +inf and −inf written into a few outputs and a NaN into an input (as the export check's
    trace, :func:`fdisyn.app.pipeline.export_trace`)."""
    U, Y = U.copy(), Y.copy()
    rng = np.random.default_rng(seed)
    T = Y.shape[0]
    for k in rng.choice(np.arange(10, T), size=6, replace=False):
        Y[k, int(rng.integers(Y.shape[1]))] = [np.nan, np.inf, -np.inf][int(rng.integers(3))]
    if U.shape[1]:
        U[int(rng.integers(10, T)), 0] = np.nan
    return U, Y


def linear_design() -> Design:
    """``kalman_uio`` on a seeded random stable plant; a bias of five fault-free standard deviations on the first
    sensor from the middle of the trace."""
    plant = random_plant(11, n=3, p=3, q=1, radius=0.8)
    gf = fdisyn.design(plant, method="kalman_uio", P_f=1e-3, persistence=2, name="contract_linear")
    rng = np.random.default_rng(11)
    T = 600
    U = rng.standard_normal((T, plant.m))
    x = np.zeros(plant.n)
    Y = np.zeros((T, plant.p))
    lq, lr = np.linalg.cholesky(plant.Q), np.linalg.cholesky(plant.R)
    for k in range(T):
        Y[k] = plant.C @ x + plant.D @ U[k] + lr @ rng.standard_normal(plant.p)
        x = plant.A @ x + plant.B @ U[k] + plant.E @ rng.standard_normal(plant.E.shape[1]) + lq @ rng.standard_normal(plant.n)
    Y[T // 2 :, 0] += 5.0 * float(np.std(Y[: T // 2, 0]))
    U, Y = hostile(U, Y, 1)
    return Design(gf, U, Y)


def beard_design() -> Design:
    """``beard_fdf`` on a seeded random continuous plant (3 states, all measured, two component faults: each
    detection space exists generically), sampled by the method at 0.1 s; the first fault from the middle."""
    rng = np.random.default_rng(3)
    n, Ts = 3, 0.1
    A = rng.standard_normal((n, n))
    A = A * (0.8 / np.max(np.abs(np.linalg.eigvals(A)))) - np.eye(n)  # stable: every eigenvalue in Re s < −0.2
    mq = rng.standard_normal((n, n))
    plant = LinearPlant.create(
        A=A, B=rng.standard_normal((n, 1)), C=np.eye(n), Fx=rng.standard_normal((n, 2)),
        Q=1e-4 * (mq @ mq.T / n + 0.05 * np.eye(n)), R=1e-4 * np.eye(n), Ts=None,
    )  # fmt: skip
    gf = fdisyn.design(plant, method="beard_fdf", Ts=Ts, decay_rate=2.0, eigenstructure="plain", P_f=1e-3, persistence=2, name="contract_beard")
    # the plant sampled exactly (zero-order hold on u and on the fault), noise as designed
    aug = scipy.linalg.expm(np.block([[A, plant.B, plant.Fx], [np.zeros((3, n + 3))]]) * Ts)
    Ad, Bd, Fd = aug[:n, :n], aug[:n, n : n + 1], aug[:n, n + 1 :]
    T = 400
    U = rng.standard_normal((T, 1))
    mu = np.zeros((T, 2))
    mu[T // 2 :, 0] = 1.0
    x = np.zeros(n)
    Y = np.zeros((T, n))
    lq = np.linalg.cholesky(plant.Q * Ts)
    for k in range(T):
        Y[k] = x + 1e-2 * rng.standard_normal(n)
        x = Ad @ x + Bd @ U[k] + Fd @ mu[k] + lq @ rng.standard_normal(n)
    U, Y = hostile(U, Y, 4)
    return Design(gf, U, Y)


def plant_file_design(file: str, scenario: str, samples: int) -> Callable[[], Design]:
    """The example plant file's design, and its faulty scenario's first run (seed 0), cut to ``samples``."""

    def make() -> Design:
        problem = load_spec(EXAMPLES / file)
        gf = problem.design()
        batch = problem.run(scenario, [0])
        U, Y = hostile(batch.U[0][:samples], batch.Y[0][:samples], 2)
        return Design(gf, U, Y)

    return make


DESIGNS: dict[str, Callable[[], Design]] = {
    "linear": linear_design,
    "beard_fdf": beard_design,
    # a nonlinear plant with parameter faults: the ship of the NAFDF's paper, its fault a halved at sample 701
    "nafdf": plant_file_design("ship.toml", "a_half", 1500),
}
"""One small design per diagnoser kind (a seeded random plant where the kind allows one)."""


# --------------------------------------------------------------------------- the check


def casadi_run(fn: ca.Function, init: np.ndarray, U: np.ndarray, Y: np.ndarray) -> tuple[RunResult, np.ndarray]:
    """The CasADi step over the trace in one call (``mapaccum`` threads the state); also the state after each sample."""
    out = fn.mapaccum("run", Y.shape[0])(init, U.T, Y.T)
    states = np.asarray(out[0]).T
    res = RunResult(
        r=np.asarray(out[1]).T, J=np.asarray(out[2]).T, alarm=np.asarray(out[3]).ravel().astype(int),
        isolated=np.rint(np.asarray(out[4]).ravel()).astype(int), status=np.asarray(out[5]).ravel().astype(int),
        state=states[-1],
    )  # fmt: skip
    return res, states


def c_steps(cd: CompiledDiagnoser, U: np.ndarray, Y: np.ndarray) -> tuple[RunResult, np.ndarray]:
    """The C step sample by sample; also the state after each sample."""
    s = cd.init_state()
    outs, states = [], []
    for u, y in zip(U, Y, strict=True):
        outs.append(cd.step(s, u, y))
        states.append(s.copy())
    res = RunResult(
        r=np.array([o.r for o in outs]), J=np.array([o.J for o in outs]), alarm=np.array([o.alarm for o in outs]),
        isolated=np.array([o.isolated for o in outs]), status=np.array([o.status for o in outs]), state=states[-1],
    )  # fmt: skip
    return res, np.array(states)


def gap(a: np.ndarray, b: np.ndarray) -> float:
    """``max |a − b| / max(1, |b|)`` (0 for empty arrays)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.max(np.abs(a - b) / np.maximum(1.0, np.abs(b)), initial=0.0))


def decisions_equal(a: RunResult, b: RunResult, what: str) -> None:
    for key in ("alarm", "isolated", "status"):
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key), err_msg=f"{what}: {key}")


def check_step_contract(gf: GainFile) -> ca.Function:
    """The kind's step: the contract's names, the sizes of ``gf.step``, dense vectors; ``init_state`` finite."""
    fn = step_function(gf)  # what the C generator builds: the kind's step builder, its names checked
    assert tuple(fn.name_in()) == kinds.STEP_INPUTS and tuple(fn.name_out()) == kinds.STEP_OUTPUTS, fn
    st = gf.step
    for i, size in enumerate((st.nstate, st.nu, st.ny)):
        sp = fn.sparsity_in(i)
        assert (sp.size1(), sp.size2()) == (size, 1) and sp.is_dense(), f"input {fn.name_in(i)}: {sp.dim()}, expected {size}x1 dense"
    for i, size in enumerate((st.nstate, st.nr, st.nj, 1, 1, 1)):
        sp = fn.sparsity_out(i)
        assert (sp.size1(), sp.size2()) == (size, 1) and sp.is_dense(), f"output {fn.name_out(i)}: {sp.dim()}, expected {size}x1 dense"
    assert st.init_state.shape == (st.nstate,) and np.all(np.isfinite(st.init_state))
    assert len(st.residual_names) == st.nr and len(st.statistic_names) == st.nj
    return fn


def check_library_symbols(gf: GainFile, library: Path) -> None:
    """Every symbol the library exports starts with the diagnoser's name (two diagnosers link into one program;
    CasADi's ``check_symbols``), and its threshold table is the gain file's."""
    nm = shutil.which("nm")
    if nm is not None:
        listing = subprocess.run([nm, "-D", "--defined-only", str(library)], capture_output=True, text=True, check=True).stdout
        names = [line.split()[-1] for line in listing.splitlines() if line.strip()]
        stray = [n for n in names if not n.startswith(f"{gf.name}_") and n not in ("_init", "_fini")]
        assert names and not stray, f"symbols without the prefix {gf.name}_: {stray}"
    table = (ctypes.c_double * gf.step.nj).in_dll(ctypes.CDLL(str(library.resolve())), f"{gf.name}_thresholds")
    np.testing.assert_array_equal(np.array(table[:]), gf.thresholds)


def check_kind_fields(gf: GainFile) -> None:
    """Every field of the gain file's kind works on it."""
    kind = kinds.get_kind(gf.kind)
    assert isinstance(kind.summary, str) and kind.summary
    assert isinstance(kind.describe(gf), str) and kind.describe(gf)
    blocks = kind.certified(gf)
    assert isinstance(blocks, list) and blocks and all(isinstance(b, Mapping) and "checks" in b for b in blocks)
    assert isinstance(kind.rate_unit, str) and kind.rate_unit
    recovery = kind.recovery_samples(gf)
    assert isinstance(recovery, (int, np.integer)) and recovery >= 0 and kinds.recovery_samples(gf) == recovery
    budget = kinds.false_alarm_budget(gf)
    assert budget is None or (math.isfinite(budget) and budget > 0)
    if kind.lorden_bound is not None:
        nr = gf.step.nr
        bound = kind.lorden_bound(gf, np.full(nr, 3.0), np.eye(nr))
        assert bound is None or (bound[0] > 0 and bound[1] > 0), bound
    if kind.lorden_window is not None:
        assert kinds.lorden_window(gf) >= 1
    assert kind.budget_text is None or isinstance(kind.budget_text, str)
    # an account of what the diagnoser can see, or a line saying why the kind has none
    if kind.account_view is not None:
        view = kind.account_view(gf)
        assert len(view.statistic_names) == len(view.statistics)
    else:
        assert isinstance(kind.account_note, str) and kind.account_note
    assert kind.reference is None or callable(kind.reference)


def check_kind_contract(gf: GainFile, U: np.ndarray, Y: np.ndarray, directory: Path) -> dict[str, float]:
    """Every check of this module on ``gf`` over the trace ``U``, ``Y`` (which must hold a non-finite sample);
    the library is built in ``directory``. Returns the worst differences measured (``"C−CasADi"``,
    ``"reference−CasADi"``) and the number of samples that alarmed (``"alarms"``)."""
    fn = check_step_contract(gf)
    check_kind_fields(gf)
    # C ≡ CasADi ≡ reference
    fdisyn.export(gf, directory)
    built = read_gain_file(directory / "gains.json")
    library = directory / f"lib{gf.name}.so"
    cd = CompiledDiagnoser(library, built)
    np.testing.assert_array_equal(cd.init_state(), gf.step.init_state)
    check_library_symbols(gf, library)
    cas, cas_states = casadi_run(fn, gf.step.init_state, U, Y)
    c, c_states = c_steps(cd, U, Y)
    assert cas.status.sum() >= 1, "the trace holds no non-finite sample"
    worst = {"C−CasADi": max(gap(c_states, cas_states), gap(c.r, cas.r), gap(c.J, cas.J))}
    assert worst["C−CasADi"] <= C_VS_CASADI, worst
    decisions_equal(c, cas, "C against CasADi")
    assert set(np.unique(cas.alarm)) <= {0, 1} and set(np.unique(cas.isolated)) <= set(range(-1, len(gf.faults)))
    ref = kinds.reference_run(gf, U, Y)
    if ref is not None:
        worst["reference−CasADi"] = max(gap(ref.state, cas.state), gap(ref.r, cas.r), gap(ref.J, cas.J))
        assert worst["reference−CasADi"] <= REFERENCE, worst
        decisions_equal(ref, cas, "the NumPy reference against CasADi")
    # the whole-trace call is the per-sample calls
    whole = cd.run(U, Y)
    for key in ("r", "J", "alarm", "isolated", "status", "state"):
        np.testing.assert_array_equal(getattr(whole, key), getattr(c, key), err_msg=key)
    # a non-finite sample: status 1, and all-NaN leaves the state but for the count of non-finite samples
    bad = ~(np.isfinite(U).all(axis=1) & np.isfinite(Y).all(axis=1))
    assert np.all(cas.status[bad] == 1) and np.all(cas.status[~bad] == 0)
    assert np.all(np.isfinite(c_states)) and np.all(np.isfinite(c.r)) and np.all(np.isfinite(c.J))
    mid = Y.shape[0] // 2
    for state in (gf.step.init_state, c_states[mid]):
        s = state.copy()
        out = cd.step(s, np.full(gf.step.nu, np.nan), np.full(gf.step.ny, np.nan))
        assert out.status == 1 and out.alarm in (0, 1) and -1 <= out.isolated < len(gf.faults)
        moved = np.flatnonzero(s != state)
        assert moved.size == 1 and s[moved[0]] == state[moved[0]] + 1.0, f"state entries {moved.tolist()} moved"
        cas_next = np.asarray(fn(state, np.full(gf.step.nu, np.nan), np.full(gf.step.ny, np.nan))[0]).ravel()
        np.testing.assert_array_equal(cas_next, s)
    # two instances side by side, stepped in turn on different traces
    other = CompiledDiagnoser(library, built)
    U2, Y2 = U[::-1].copy(), Y[::-1].copy()
    alone, _ = c_steps(cd, U2, Y2)
    sa, sb = cd.init_state(), other.init_state()
    for k in range(Y.shape[0]):
        oa, ob = cd.step(sa, U[k], Y[k]), other.step(sb, U2[k], Y2[k])
        np.testing.assert_array_equal(oa.r, c.r[k])
        np.testing.assert_array_equal(ob.J, alone.J[k])
        assert (oa.alarm, oa.isolated, ob.alarm, ob.isolated) == (c.alarm[k], c.isolated[k], alone.alarm[k], alone.isolated[k])
    np.testing.assert_array_equal(sa, c.state)
    np.testing.assert_array_equal(sb, alone.state)
    worst["alarms"] = float(np.sum(cas.alarm))
    return worst


# --------------------------------------------------------------------------- every registered kind


@pytest.mark.parametrize("kind", kinds.kind_names())
def test_every_kind_honours_the_contract(kind: str, tmp_path: Path) -> None:
    if kind not in DESIGNS:
        pytest.fail(
            f"diagnoser kind {kind!r} has no test design: add a small design of it (on a seeded random plant where the "
            f"kind allows one) and a trace to DESIGNS in tests/design/test_kind_contract.py"
        )
    d = design_of(kind)
    assert d.gain_file.kind == kind
    worst = check_kind_contract(d.gain_file, d.U, d.Y, tmp_path)
    assert worst["alarms"] > 0, "the trace's fault raised no alarm: the decision went unchecked"


def test_every_kind_but_the_nafdf_has_an_independent_reference() -> None:
    """A kind without a NumPy reference is a decision made here: the NAFDF's EKF, re-estimation and classifier are
    written once, in CasADi, and its C is checked against that step only."""
    without = [k.name for k in kinds.all_kinds() if k.reference is None]
    assert without == ["nafdf"], f"kinds without a NumPy reference: {without}; give each its DiagnoserKind.reference, or say here why it has none"


def design_of(kind: str) -> Design:
    """The test design of ``kind``; a kind without one fails the test, saying where to add it."""
    if kind not in DESIGNS:
        pytest.fail(
            f"diagnoser kind {kind!r} has no test design: add a small design of it (on a seeded random plant where the "
            f"kind allows one) and a trace to DESIGNS in tests/design/test_kind_contract.py"
        )
    return DESIGNS[kind]()


def test_a_kind_registered_later_is_a_case_and_fails_without_a_design() -> None:
    new = kinds.register_kind(kinds.DiagnoserKind(name="contract_probe", summary="a kind with no test design", step_builder=lambda gf: None))
    try:
        assert "contract_probe" in kinds.kind_names()  # what the parametrisation reads
        with pytest.raises(pytest.fail.Exception, match="'contract_probe' has no test design: add .* to DESIGNS"):
            design_of(new.name)
    finally:
        kinds._KINDS.pop("contract_probe", None)
    assert set(DESIGNS) == set(kinds.kind_names()), "DESIGNS names a kind no module registers"
