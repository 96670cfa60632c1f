"""The linear methods' property campaign: seeded random plants with a known answer through design → C → replay.

Each case (``tests/property/campaign.py``) is a plant built where its answer is known, handed to fdisyn badly scaled
(states spread over up to six decades), with the sample time anywhere from 1 ms to 1 s. The independent test
(``tests/property/plants.py``: Rosenbrock pencils, PBH tests, exact sampling, a known Beard gain) says whether a
design exists; then

* where it exists, ``fdisyn.design`` with the method's defaults must design, and the design is judged by an
  independent truth: every UIO generator's transfer from the unknown inputs is zero, a Beard filter keeps each
  fault's residual in its direction, a sampled-data observer is stable;
* where it does not, fdisyn must refuse with one of its own errors (never design, never a raw exception);
* the cases in :data:`COMPILED` go on through the generated C: the library's replay of a simulated trace (large
  unknown input, noise, a sensor step fault well above the detectable size) agrees with the Python reference to
  round-off, raises the alarm after the fault, and isolates it where the decision table can.

A design that fails where the independent test says one exists is a failing test. The cases failing today are
listed, each with its cause, in :data:`KNOWN_FAILURES` and marked ``xfail(strict=True)``: one that starts passing
fails the suite until it is taken off the list.
"""

from __future__ import annotations

import os

import numpy as np
import pytest
import scipy.stats

import fdisyn
from fdisyn.runtime.errors import FdisynError
from tests.property.campaign import METHODS, NAMED, PLANTS, all_cases
from tests.property.plants import Case, noise_factor

CASES = all_cases()

KNOWN_FAILURES: dict[str, str] = {
    "uio_pole_placement-seed0-n12-q1-p3-cont-stab-none-Ts2e-01-spread1e4":
        "CertificateError: method 'uio_pole_placement': option bank: none given, and no sensor has a generator on the other outputs; the generator on all outputs: UIO for the outputs ['y0', 'y1', 'y2']: design 'uio_pole_placement/poles' failed its certificate: assigned poles: max |achieved − requested| = 0.000273 (must be <= 1e-06: eigenvalue sensitivity of the assigned closed loop; KNV assignment is accurate well below this);…",
    "beard_fdf-seed0-n6-k1-p2-planes1-stab-Ts3e-01-spread1e2":
        "ExistenceError: method 'beard_fdf': faults 1 are not mutually detectable: the eigenvalue(s) -5.60075+0j of A − L C, fixed by the geometry, are not inside the unit circle for any gain that keeps every detection space invariant (faults 1 = 'f0')",
    "beard_fdf-seed3-n6-k2-p3-planes0-stab-Ts8e-02-spread1e6":
        "SolverError: IPOPT found no admissible eigenstructure from 6 starts (real eigenvalues in [0, 0.683883], 0.02 apart, noise gain ≤ 2.0): raise the decay bound or the noise gain",
}
"""Cases where the independent test says a design exists and fdisyn fails today: case id → the cause (the error)."""

TOO_SLOW_TO_FAIL = {"beard_fdf-seed3-n6-k2-p3-planes0-stab-Ts8e-02-spread1e6": 223.0}
"""Known failures not run in the suite: seconds the failing design takes (its IPOPT starts). Run them by hand
(``FDISYN_CAMPAIGN_ALL=1``) when the cause is fixed."""

COMPILED = {
    *NAMED,
}
"""Cases that go on through the generated C (a compile costs seconds): the named plants and the first seeded plant
per method that admits a design."""
for _m in METHODS:
    _first = next((c.id for c in CASES.values() if c.method == _m and c.exists and c.id not in NAMED), None)
    if _first is not None:
        COMPILED.add(_first)

DECOUPLING_TOL = 1e-7
"""Relative size ``‖G_ry(z) P_yd(z)‖ / (‖G_ry(z)‖ ‖P_yd(z)‖)`` of a UIO generator's transfer from the unknown inputs
at points off the unit circle. The design works in the user's coordinates, where ``cond(S)`` reaches 1e6: round-off
of a backward-stable construction is ~eps·cond(S)·κ(C E) ≈ 2e-16·1e6·κ, so 1e-7 holds for κ(C E) up to ~5e2 and
still catches any real coupling (an undecoupled generator gives O(1))."""
DIRECTION_TOL = 1e-7
"""Beard: the part of a fault's residual transfer outside its residual direction ``C T_i``, relative (the same
round-off argument as :data:`DECOUPLING_TOL`)."""
REPLAY_TOL = 1e-8
"""The compiled step against the Python reference: the same operations in another order, on states whose
magnitudes follow the user's scaling; the difference is round-off, ~eps·(condition of the generator's state
recursion)·|signal|, below 1e-8 relative to the largest |r| and |J| of the trace."""


def _params() -> list:
    out = []
    for cid in CASES:
        run = cid not in TOO_SLOW_TO_FAIL or bool(os.environ.get("FDISYN_CAMPAIGN_ALL"))
        marks = [pytest.mark.xfail(strict=True, run=run, reason=KNOWN_FAILURES[cid])] if cid in KNOWN_FAILURES else []
        out.append(pytest.param(cid, marks=marks, id=cid))
    return out


# --------------------------------------------------------------------------- the generator's own answer


def test_each_plant_carries_its_planted_answer() -> None:
    """The independent test finds what each plant was built to have: the planted zero of a UIO plant (and no
    other), the known Beard gain; and a second route agrees with the first (PBH on ``(C, A1)``, ``A1 = (I − E (C E)⁺
    C) A``: its unobservable modes are the invariant zeros when ``rank C E = q``)."""
    from tests.property.plants import invariant_zeros, unobservable_modes

    seen = 0
    for c in CASES.values():
        planted = c.extra.get("zeros_planted")
        if not planted or c.continuous:
            continue
        g = c.discrete_good()
        z = invariant_zeros(g["A"], g["E"], g["C"])
        assert z.size == len(planted) and np.allclose(np.sort(z.real), np.sort(planted), atol=1e-8), (c.id, z, planted)
        t = np.eye(g["A"].shape[0]) - g["E"] @ np.linalg.pinv(g["C"] @ g["E"]) @ g["C"]
        modes = unobservable_modes(t @ g["A"], g["C"], "all")
        assert np.allclose(np.sort(np.real(modes)), np.sort(planted), atol=1e-6), (c.id, modes, planted)
        seen += 1
    assert seen >= 5
    assert all(c.exists for c in CASES.values() if c.method == "beard_fdf")


# --------------------------------------------------------------------------- the campaign


@pytest.mark.parametrize("case_id", _params())
def test_design_where_the_independent_test_says_one_exists(case_id: str, tmp_path) -> None:  # noqa: ANN001
    case = CASES[case_id]
    if not case.exists:
        with pytest.raises(FdisynError):
            fdisyn.design(case.plant, method=case.method, **case.options)
        return
    gf = fdisyn.design(case.plant, method=case.method, **case.options)
    if case.method == "beard_fdf":
        _beard_truth(case, gf)
    elif case.method in ("lmi", "sampled_data_observer"):
        _stable_truth(gf)
    else:
        _decoupling_truth(case, gf)
    if case_id in COMPILED:
        _replay(case, gf, tmp_path)


def _points(rng: np.random.Generator, k: int = 4) -> np.ndarray:
    return 1.3 * np.exp(1j * rng.uniform(0.05, np.pi - 0.05, k))


def _transfer(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray, z: complex) -> np.ndarray:
    return c @ np.linalg.solve(z * np.eye(a.shape[0]) - a, b) + d


def _decoupling_truth(case: Case, gf) -> None:  # noqa: ANN001
    """Every generator's transfer from the unknown inputs, ``G_ry(z) C (zI − A_D)⁻¹ E_D``, is zero (the plant's side
    from the well-conditioned model: a transfer function does not depend on the coordinates)."""
    g = case.discrete_good()
    rng = np.random.default_rng(7)
    for gen in gf.generators:
        for z in _points(rng):
            gry = _transfer(gen.Ar, gen.By, gen.Cr, gen.Dy, z)
            pyd = _transfer(g["A"], g["E"], g["C"], np.zeros((g["C"].shape[0], g["E"].shape[1])), z)
            rel = np.linalg.norm(gry @ pyd, 2) / (np.linalg.norm(gry, 2) * np.linalg.norm(pyd, 2))
            assert rel <= DECOUPLING_TOL, f"{gen.name}: the residual's transfer from the unknown inputs at z = {z:.3f} is {rel:.3g} (relative)"


def _stable_truth(gf) -> None:  # noqa: ANN001
    for gen in gf.generators:
        rho = float(np.max(np.abs(np.linalg.eigvals(gen.Ar)))) if gen.Ar.size else 0.0
        assert rho < 1.0, f"{gen.name}: spectral radius of Ar {rho}"


def _beard_truth(case: Case, gf) -> None:  # noqa: ANN001
    """Each fault's residual ``C (zI − A + L C)⁻¹ f_i`` lies in its direction ``C T_i`` (the known spaces), and every
    eigenvalue of ``A − L C`` is inside the decay radius."""
    from fdisyn.synthesis.beard_fdf.payload import beard_from_gain_file

    flt = beard_from_gain_file(gf)
    s = case.good["S"]
    g = case.discrete_good()
    gain = flt.L / s[:, None]  # L in the well-conditioned coordinates: x = S x̄
    acl = g["A"] - gain @ g["C"]
    rho = float(np.max(np.abs(np.linalg.eigvals(acl))))
    assert rho <= case.extra["radius"] + 1e-7, f"spectral radius {rho} above the decay radius {case.extra['radius']}"
    rng = np.random.default_rng(7)
    for i, t in enumerate(case.good["spaces"]):
        ct = np.linalg.qr(g["C"] @ t)[0]
        proj = np.eye(ct.shape[0]) - ct @ ct.T
        for z in _points(rng):
            r = _transfer(acl, g["Fx"][:, i : i + 1], g["C"], np.zeros((g["C"].shape[0], 1)), z)
            rel = np.linalg.norm(proj @ r) / np.linalg.norm(r)
            assert rel <= DIRECTION_TOL, f"fault {i}: residual {rel:.3g} outside its direction C T at z = {z:.3f}"


# --------------------------------------------------------------------------- through the C


def _simulate(case: Case, gf, steps: int, onset: int, fault: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # noqa: ANN001
    """A trace of the well-conditioned model sampled exactly: a random input, a large random unknown input (100×
    the noise), the design noise, and ``fault`` added to the outputs from ``onset``. The outputs are those the
    user's plant gives (``y`` does not depend on the state coordinates)."""
    g = case.discrete_good()
    rng = np.random.default_rng(11)
    n, p = g["A"].shape[0], g["C"].shape[0]
    s = case.good["S"]
    qd = np.asarray(case.plant.Q) / s[:, None] / s[None, :]  # Q in x̄
    if case.continuous:
        wq = noise_factor(case.good["A"], np.linalg.cholesky(qd + 1e-300 * np.eye(n)) if np.any(qd) else np.zeros((n, n)), case.Ts)
    else:
        lam, v = np.linalg.eigh(qd)
        wq = v * np.sqrt(np.clip(lam, 0, None))
    rv = np.linalg.cholesky(np.asarray(case.plant.R) + 1e-300 * np.eye(p))
    x = np.zeros(n)
    U = 0.1 * rng.standard_normal((steps, g["B"].shape[1]))
    Y = np.zeros((steps, p))
    dsize = 100.0 * max(1e-2, float(np.sqrt(np.max(np.diag(qd))))) if g["E"].size else 0.0
    for k in range(steps):
        Y[k] = g["C"] @ x + rv @ rng.standard_normal(p) + (fault if k >= onset else 0.0)
        d = dsize * rng.standard_normal(g["E"].shape[1])
        x = g["A"] @ x + g["B"] @ U[k] + g["E"] @ d + wq @ rng.standard_normal(wq.shape[1])
    return U, Y


def _replay(case: Case, gf, tmp_path) -> None:  # noqa: ANN001
    from fdisyn.runtime.reference import LinearReference

    out = fdisyn.export(gf, tmp_path / "diag")
    mon = fdisyn.load(out)
    # the fault: a step on the first output the diagnoser reads, 30× the size a statistic notices in steady state
    j = 0
    steps, onset = 400, 200
    size = _fault_size(gf, j)
    fault = np.zeros(gf.step.ny)
    fault[j] = size
    U, Y = _simulate(case, gf, steps, onset, fault)
    res = mon.run(U, Y)
    from fdisyn.synthesis.beard_fdf.payload import beard_from_gain_file
    from fdisyn.synthesis.beard_fdf.reference import beard_reference_run

    ref = LinearReference(gf).run(U, Y) if gf.kind == "linear" else beard_reference_run(beard_from_gain_file(gf), U, Y)
    # Round-off in r follows the terms it is summed from, not r: on an unstable plant the outputs grow to 1e6
    # while the decoupled residual stays near the noise. Each generator's r = Cr ξ + Du u + Dy y sums terms of
    # about |Dy|·|y| and |Cr (I − Ar)⁻¹ By|·|y| (ξ follows y through the generator's own gain), likewise for u;
    # J is quadratic in r, so its relative error is twice r's.
    fin_r = np.isfinite(ref.r)
    r_max = max(1.0, float(np.max(np.abs(ref.r[fin_r])))) if fin_r.any() else 1.0
    terms = r_max
    for gen in getattr(gf, "generators", ()) or ():
        dc = np.linalg.solve(np.eye(gen.Ar.shape[0]) - gen.Ar, np.hstack([gen.Bu, gen.By])) if gen.Ar.size else np.zeros((0, 0))
        gain = np.linalg.norm(np.hstack([gen.Du, gen.Dy]), 2) + (np.linalg.norm(gen.Cr @ dc, 2) if dc.size else 0.0)
        terms = max(terms, gain * float(np.max(np.abs(np.hstack([U, Y])), initial=0.0)))
    for name in ("r", "J"):
        a, b = getattr(res, name), getattr(ref, name)
        fin = np.isfinite(b)
        scale = max(1.0, float(np.max(np.abs(b[fin])))) if fin.any() else 1.0
        scale *= (2.0 if name == "J" else 1.0) * terms / r_max
        assert np.array_equal(np.isfinite(a), fin) and np.max(np.abs(a[fin] - b[fin]), initial=0.0) <= REPLAY_TOL * scale, name
    assert np.array_equal(res.alarm, ref.alarm) and np.array_equal(res.isolated, ref.isolated)
    # quiet from switch-on: none in the warm-up, and the fault-free stretch's alarmed samples within the Poisson
    # bound (10⁻⁶) of the statistics' false-alarm probabilities (persistence only lowers the rate)
    if gf.kind == "linear":
        warm = max((g.warmup for g in gf.generators), default=0)
        expected = onset * sum(float(ev.P_f) for ev in gf.evaluators)
    else:
        flt = beard_from_gain_file(gf)
        warm, expected = flt.warmup + flt.window - 1, onset * float(flt.design_info["P_f"])
    assert not res.alarm[:warm].any(), f"an alarm in the warm-up of {warm} samples"
    assert int(res.alarm[:onset].sum()) <= scipy.stats.poisson.isf(1e-6, expected), (
        f"{int(res.alarm[:onset].sum())} alarmed samples of {onset} fault-free ones ({expected:.3g} expected)")
    if size is None:
        return
    assert res.alarm[onset:].any(), f"a step of {size:.3g} on output {gf.outputs[j]} raised no alarm"
    if gf.kind == "linear":
        cls = next((i for i, f in enumerate(gf.faults) if gf.outputs[j] in f.split("|")), None)
        sig = np.asarray(gf.decision.signatures) if gf.decision is not None else None
        if cls is not None and sig is not None and sum(np.array_equal(sig[cls], row) for row in sig) == 1:
            late = res.isolated[-50:]
            assert np.mean(late == cls) > 0.9, f"the step on {gf.outputs[j]} isolated as {set(late.tolist())}, expected {cls} ({gf.faults[cls]})"


def _fault_size(gf, j: int) -> float | None:  # noqa: ANN001
    """30× the steady-state step on output ``j`` at which the most sensitive statistic reaches its threshold
    (``μᵀ W μ = threshold`` with ``μ = G_ry(1) e_j``); ``None`` when no statistic sees it in steady state."""
    if gf.kind != "linear":
        from fdisyn.synthesis.beard_fdf.payload import beard_from_gain_file

        flt = beard_from_gain_file(gf)
        gss = flt.C @ np.linalg.solve(np.eye(flt.A.shape[0]) - flt.A + flt.L @ flt.C, -flt.L) + np.eye(flt.C.shape[0])
        mu = np.linalg.norm(gss[:, j])
        return None if mu < 1e-12 else 30.0 * float(flt.h) / mu
    best = None
    for ev in gf.evaluators:
        gen = gf.generators[ev.generator]
        mu = _transfer(gen.Ar, gen.By, gen.Cr, gen.Dy, 1.0)[:, j].real
        nc = float(mu @ ev.W @ mu) * ev.window
        if nc > 1e-20 * max(1.0, float(np.trace(ev.W))):
            a = 30.0 * float(np.sqrt(ev.threshold / nc))
            best = a if best is None else min(best, a)
    return best
