"""The Beard detection filter's step (Beard 1971; He, Zhang & Wu, Journal of Astronautics, c. 1999).

Truths: Beard's property (under fault ``i`` alone and no noise the residual never leaves ``S_i = C T_i``,
whatever the fault's time course), checked on simulated plants through the CasADi step; the NumPy
reference (:func:`beard_reference_run`, written independently from the specification) against the
CasADi step and the compiled C on traces with faults, noise, NaN, ±inf and an overflow; hand-computed
decisions on crafted residuals; and the gain-file reader's refusal of each corrupted field.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.signal
from fdisyn.codegen.library import codegen
from fdisyn.codegen.step import step_function
from fdisyn.synthesis.kinds import STEP_INPUTS, STEP_OUTPUTS
from fdisyn.numerics.certificate import Certificate, Check
from fdisyn.numerics.detection_filter import beard_gain
from fdisyn.runtime.compiled import CompiledDiagnoser
from fdisyn.runtime.errors import GainFileError
from fdisyn.runtime.gainfile import GainFile, read_gain_file, write_gain_file
from fdisyn.synthesis.beard_fdf import (
    BeardFilter,
    beard_from_gain_file,
    beard_gain_file,
    beard_reference_run,
    beard_step_function,
)
from fdisyn.synthesis.kinds import recovery_samples

KEYS = ("r", "J", "alarm", "isolated", "status")
HALF = math.pi / 2


# --------------------------------------------------------------------------- plants and filters


def orth(m: np.ndarray) -> np.ndarray:
    u, s, _ = np.linalg.svd(m, full_matrices=False)
    return u[:, : int(np.sum(s > 1e-9 * s[0]))]


def designed(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray, F: np.ndarray, ev: list, **decision: Any) -> BeardFilter:
    """A filter from :func:`beard_gain` on the discrete ``(A, C, F)``; its axes are ``orth(C T_i)``."""
    gain = beard_gain(A, C, F, ev)
    axes = tuple(orth(C @ s.basis) for s in gain.structure.spaces)
    return BeardFilter(A=A, B=B, C=C, D=D, L=gain.L, axes=axes, **decision)


def four_state(**decision: Any) -> tuple[BeardFilter, np.ndarray]:
    """4 states (spectral radius 0.9), C = I (every state measured), one input with a direct feedthrough, two component faults."""
    rng = np.random.default_rng(3)
    A = rng.standard_normal((4, 4))
    A *= 0.9 / np.max(np.abs(np.linalg.eigvals(A)))  # stable: round-off does not grow with the state
    B = rng.standard_normal((4, 1))
    D = 0.3 * rng.standard_normal((4, 1))
    F = rng.standard_normal((4, 2))
    return designed(A, B, np.eye(4), D, F, [[0.3], [0.5], [0.2, -0.1]], **decision), F


def pendulum(**decision: Any) -> tuple[BeardFilter, np.ndarray]:
    """The linearised pendulum on a cart of tests/design/test_detection_filter.py, ZOH-sampled at 10 ms:
    cart position and angle measured; fault 1 the cart force (the actuator), fault 2 a force on the cart alone.
    ``F_d = ∫_0^Ts e^{Aτ} dτ F``; each detection space is two-dimensional, its output image a line."""
    big_m, m, ell, grav = 1.0, 0.1, 0.5, 9.81
    A = np.array([[0, 1, 0, 0], [0, 0, -m * grav / big_m, 0], [0, 0, 0, 1], [0, 0, (big_m + m) * grav / (big_m * ell), 0]], dtype=float)
    F = np.array([[0, 1 / big_m, 0, -1 / (big_m * ell)], [0, 1.0, 0, 0]]).T
    C = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
    aug = sla.expm(np.block([[A, F], [np.zeros((2, 6))]]) * 0.01)
    Ad, Fd = aug[:4, :4], aug[:4, 4:]
    flt = designed(Ad, Fd[:, :1], C, np.zeros((2, 1)), Fd, [[0.6 + 0.2j, 0.6 - 0.2j], [0.5, 0.7], []], **decision)
    assert [a.shape[1] for a in flt.axes] == [1, 1]
    return flt, Fd


DECISION = dict(Y_th=[0.05, 0.05], window=5, h=0.05, explicit_level=0.01, persistence=2)
SCALE = {"four_state": 1.0, "pendulum": 0.01}
"""The pendulum's sampled faults reach the outputs 100 times weaker (Ts = 10 ms): so are its thresholds."""


def decision(plant: str, **extra: Any) -> dict[str, Any]:
    out = dict(DECISION, **extra)
    out["h"] *= SCALE[plant]
    out["explicit_level"] *= SCALE[plant]
    return out

PLANTS: dict[str, Callable[..., tuple[BeardFilter, np.ndarray]]] = {"four_state": four_state, "pendulum": pendulum}


def certificate(flt: BeardFilter) -> Certificate:
    radius = float(np.max(np.abs(np.linalg.eigvals(flt.G))))
    return Certificate.of("beard_fdf", [Check("spectral_radius", radius, 1.0, "<=", "A − L C Schur stable")])


def gain_file(flt: BeardFilter, name: str = "beard_test") -> GainFile:
    return beard_gain_file(
        flt,
        name=name,
        problem="beard_test",
        design_name="beard_fdf",
        Ts=0.01,
        inputs=[f"u{j}" for j in range(flt.m)],
        outputs=[f"y{j}" for j in range(flt.p)],
        faults=[f"f{i}" for i in range(flt.k)],
        certificate=certificate(flt),
        options={"method": "beard_fdf"},
    )


def casadi_run(gf: GainFile, U: np.ndarray, Y: np.ndarray) -> dict[str, np.ndarray]:
    """The CasADi step sample by sample; ``state`` the state after each sample."""
    fn = step_function(gf)
    s = gf.step.init_state.copy()
    rows = []
    for u, y in zip(U, Y, strict=True):
        out = fn(s, u, y)
        s = np.array(out[0]).reshape(-1)
        rows.append((s, *(np.array(o, dtype=float).reshape(-1) for o in out[1:])))
    res = {key: np.array([row[i] for row in rows]) for i, key in enumerate(("state", *KEYS))}
    for key in ("alarm", "isolated", "status"):
        res[key] = res[key].reshape(-1)
    return res


def simulate(flt: BeardFilter, F: np.ndarray, U: np.ndarray, mu: np.ndarray, x0: np.ndarray, *, feedback: np.ndarray | None = None,
             noise: float = 0.0, rng: np.random.Generator | None = None) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """``x⁺ = A x + B u + F μ``, ``y = C x + D u`` (+ white noise); ``u = U − K x`` with a feedback ``K``."""
    x = np.array(x0, dtype=float)
    us, ys = [], []
    for t in range(U.shape[0]):
        u = U[t] - (feedback @ x if feedback is not None else 0.0)
        y = flt.C @ x + flt.D @ u + (noise * rng.standard_normal(flt.p) if rng is not None else 0.0)
        us.append(u)
        ys.append(y)
        x = flt.A @ x + flt.B @ u + F @ mu[t]
    return np.array(us), np.array(ys)


def fault_course(rng: np.random.Generator, T: int, start: int) -> np.ndarray:
    """An arbitrary fault signal: a random walk plus a sine plus steps, zero before ``start``."""
    t = np.arange(T)
    mu = np.cumsum(rng.standard_normal(T)) * 0.3 + np.sin(0.07 * t) + 2.0 * (t > start + 40) - 3.0 * (t > start + 90)
    mu[:start] = 0.0
    return mu


def steady(flt: BeardFilter, plant: str) -> tuple[np.ndarray | None, np.ndarray]:
    """A stabilising feedback for the (unstable) pendulum, and the initial state 0 with ``u0 = 0``: the
    filter's equilibrium start ``(I − G)⁻¹ (B u0 + L C x0)`` then equals the plant's state (no initial error)."""
    k = scipy.signal.place_poles(flt.A, flt.B, [0.95, 0.96, 0.97, 0.98]).gain_matrix if plant == "pendulum" else None
    return k, np.zeros(flt.n)


# --------------------------------------------------------------------------- (a) Beard's property through the step


@pytest.mark.parametrize("plant", list(PLANTS))
@pytest.mark.parametrize("fault", [0, 1])
def test_a_fault_alone_keeps_the_residual_on_its_axis(plant: str, fault: int) -> None:
    flt, F = PLANTS[plant](**decision(plant))
    gf = gain_file(flt)
    rng = np.random.default_rng(10 + fault)
    T, start = 300, 20
    mu = np.zeros((T, flt.k))
    mu[:, fault] = fault_course(rng, T, start)
    K, x0 = steady(flt, plant)
    U = rng.standard_normal((T, flt.m))
    U[0] = 0.0  # u0 = 0: the plant is at the equilibrium the filter starts at
    Us, Ys = simulate(flt, F, U, mu, x0, feedback=K)
    got = casadi_run(gf, Us, Ys)
    axis = flt.axes[fault]
    r = got["r"]
    size = np.linalg.norm(r, axis=1)
    assert np.all(size[: start + 1] <= 1e-12 * np.max(size))  # no fault, no residual
    seen = size > 1e-6 * np.max(size)
    assert seen.sum() > T - start - 10
    off = np.linalg.norm(r - (r @ axis) @ axis.T, axis=1)
    assert np.max(np.arcsin(np.minimum(1.0, off[seen] / size[seen]))) <= 1e-9
    # the window mean stays on the axis too: its angle (J) is round-off where the mean is not
    jn = list(gf.step.statistic_names)
    angle = got["J"][:, jn.index(f"angle_f{fault}")]
    mean_seen = got["J"][:, jn.index("rho")] * flt.explicit_level > 1e-6 * np.max(size)
    assert mean_seen[start + flt.window :].sum() > 200
    assert np.max(angle[mean_seen]) <= 1e-9
    # what is isolated is this fault (the window mean is on its axis, far from the other one's cone)
    assert np.any(got["alarm"] == 1)
    assert set(got["isolated"][got["alarm"] == 1]) <= {fault, -1} and np.any(got["isolated"] == fault)
    assert np.all(got["isolated"][got["alarm"] == 0] == -1)


# --------------------------------------------------------------------------- (b) CasADi ≡ NumPy reference


def hostile_trace(flt: BeardFilter, F: np.ndarray, plant: str, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A noisy run with fault 0 then fault 1, NaN and ±inf sprinkled in u and y, and one overflowing sample."""
    rng = np.random.default_rng(seed)
    T = 400
    mu = np.zeros((T, flt.k))
    mu[100:200, 0] = fault_course(rng, 100, 0) + 3.0
    mu[250:350, 1] = fault_course(rng, 100, 0) - 3.0
    K, x0 = steady(flt, plant)
    U, Y = simulate(flt, F, rng.standard_normal((T, flt.m)), mu, x0, feedback=K, noise=0.002 * SCALE[plant], rng=rng)
    Y[rng.choice(T, 12, replace=False), rng.integers(0, flt.p, 12)] = rng.choice([np.nan, np.inf, -np.inf], 12)
    U[rng.choice(T, 5, replace=False), 0] = np.nan
    Y[220] = 1e300  # finite, but its square overflows the window's sum
    return U, Y


@pytest.mark.parametrize("plant", list(PLANTS))
@pytest.mark.parametrize(("rho", "warmup"), [(None, 0), (3.0, 0), (None, 6)])
def test_casadi_step_equals_the_numpy_reference(plant: str, rho: float | None, warmup: int) -> None:
    flt, F = PLANTS[plant](**decision(plant, rho=rho, warmup=warmup))
    gf = gain_file(flt)
    U, Y = hostile_trace(flt, F, plant, seed=5)
    got = casadi_run(gf, U, Y)
    ref = beard_reference_run(flt, U, Y)
    # round-off: ε = y − C x̂ cancels (|y| ~ 1, |ε| ~ 1e-4 on the pendulum) and ρ, the angles magnify it
    np.testing.assert_allclose(got["r"], ref.r, rtol=0, atol=1e-13)
    np.testing.assert_allclose(got["J"], ref.J, rtol=1e-10, atol=1e-12)
    for key in ("alarm", "isolated", "status"):
        np.testing.assert_array_equal(got[key], getattr(ref, key), err_msg=key)
    np.testing.assert_allclose(got["state"][-1], ref.state, rtol=1e-12, atol=1e-13)
    # the trace exercised what it claims: skips, the overflow (and the restart after it), alarms, both faults isolated
    assert ref.status.sum() >= 15 and ref.status[220] == 1
    assert got["state"][220][flt.layout["ready"]][0] == 0.0 and got["state"][221][flt.layout["ready"]][0] == 1.0
    assert set(ref.isolated[ref.alarm == 1]) >= {0, 1}
    assert np.all(np.isfinite(got["J"])) and np.all(np.isfinite(got["r"]))


# --------------------------------------------------------------------------- (c) the compiled C ≡ CasADi ≡ NumPy


@pytest.mark.parametrize("warmup", [0, 6])
def test_compiled_c_equals_casadi_and_the_reference(tmp_path, warmup: int) -> None:  # noqa: ANN001 - a path
    flt, F = four_state(**DECISION, warmup=warmup)
    gf = gain_file(flt, name="beard_four_state")
    write_gain_file(gf, tmp_path / "gains.json")
    cd = CompiledDiagnoser(codegen(tmp_path).library, read_gain_file(tmp_path / "gains.json"))
    U, Y = hostile_trace(flt, F, "four_state", seed=8)
    want = casadi_run(gf, U, Y)
    ref = beard_reference_run(flt, U, Y)
    s = cd.init_state()
    states, outs = [], []
    for u, y in zip(U, Y, strict=True):
        o = cd.step(s, u, y)
        states.append(s.copy())
        outs.append(o)
    got = {
        "state": np.array(states),
        "r": np.array([o.r for o in outs]),
        "J": np.array([o.J for o in outs]),
        **{key: np.array([getattr(o, key) for o in outs]) for key in ("alarm", "isolated", "status")},
    }
    for key in ("state", *KEYS):
        scale = np.maximum(1.0, np.abs(want[key]))
        assert np.max(np.abs(got[key] - want[key]) / scale) <= 1e-12, key
    for key in ("alarm", "isolated", "status"):
        np.testing.assert_array_equal(got[key], getattr(ref, key), err_msg=key)
    np.testing.assert_allclose(got["J"], ref.J, rtol=1e-12, atol=1e-12)
    whole = cd.run(U, Y)
    np.testing.assert_array_equal(whole.isolated, ref.isolated)
    assert set(ref.isolated) == {-1, 0, 1}


# --------------------------------------------------------------------------- (d) the decision on crafted residuals


def identity_filter(**decision: Any) -> BeardFilter:
    """``A = 0, L = 0, C = I``, no input: ``x̂ = 0`` and ``ε = y``; axes the two coordinate axes."""
    return BeardFilter(
        A=np.zeros((2, 2)), B=np.zeros((2, 0)), C=np.eye(2), D=np.zeros((2, 0)), L=np.zeros((2, 2)),
        axes=(np.array([[1.0], [0.0]]), np.array([[0.0], [1.0]])), **decision,
    )  # fmt: skip


def both_runs(flt: BeardFilter, Y: list[list[float]]) -> list[dict[str, np.ndarray]]:
    Ya = np.array(Y, dtype=float)
    U = np.zeros((Ya.shape[0], 0))
    ref = beard_reference_run(flt, U, Ya)
    got = casadi_run(gain_file(flt), U, Ya)
    for key in KEYS:
        np.testing.assert_allclose(got[key], getattr(ref, key), rtol=1e-14, atol=1e-15, err_msg=key)
    return [got, {key: getattr(ref, key) for key in KEYS}]


BASE = dict(window=2, h=0.5, explicit_level=0.1, persistence=1)


def test_one_cone_isolates_and_the_window_must_fill_first() -> None:
    for run in both_runs(identity_filter(Y_th=[0.1, 0.1], **BASE), [[1.0, 0.05]] * 4):
        np.testing.assert_array_equal(run["J"][0], np.zeros(6))
        assert run["alarm"].tolist() == [0, 1, 1, 1] and run["isolated"].tolist() == [-1, 0, 0, 0]
        s, rho, a0, a1, c0, c1 = run["J"][1]
        assert s == pytest.approx(math.hypot(1.0, 0.05)) and rho == pytest.approx(math.hypot(1.0, 0.05) / 0.1)
        assert a0 == pytest.approx(math.atan(0.05)) and a1 == pytest.approx(math.atan(1 / 0.05))
        assert c0 == pytest.approx(0.1 + math.asin(0.1 / math.hypot(1.0, 0.05))) == c1


def test_two_cones_detect_without_isolating_and_no_cone_neither() -> None:
    for run in both_runs(identity_filter(Y_th=[0.7, 0.7], **BASE), [[1.0, 1.0]] * 3):  # α = π/4 ≤ 0.7 + X in both
        assert run["alarm"].tolist() == [0, 1, 1] and run["isolated"].tolist() == [-1, -1, -1]
    for run in both_runs(identity_filter(Y_th=[0.1, 0.1], **BASE), [[1.0, 1.0]] * 3):  # α = π/4 > 0.1 + X in both
        assert run["alarm"].tolist() == [0, 1, 1] and run["isolated"].tolist() == [-1, -1, -1]


def test_a_fixed_rho_isolates_only_beyond_it() -> None:
    flt = identity_filter(Y_th=[0.1, 0.1], rho=20.0, **BASE)
    for run in both_runs(flt, [[1.0, 0.01]] * 3 + [[5.0, 0.05]] * 3):  # ρ = 10 < 20 (in cone 0 all the same), then 30, 50
        assert run["alarm"].tolist() == [0] + [1] * 5
        assert run["isolated"].tolist() == [-1, -1, -1, 0, 0, 0]
        assert run["J"][2, 2] <= run["J"][2, 4] and run["J"][3, 1] == pytest.approx(math.hypot(3.0, 0.03) / 0.1)
        np.testing.assert_allclose(run["J"][1:, 4:], 0.1 + math.asin(1 / 20.0), rtol=1e-15)


def test_a_zero_mean_has_every_angle_at_half_pi_and_no_nan() -> None:
    # ε alternates: the RMS is 1 (alarm) but the window mean is 0: ρ = 0, X = π/2, every cone the half-space
    for run in both_runs(identity_filter(Y_th=[0.0, 0.0], **BASE), [[1.0, 0.0], [-1.0, 0.0]] * 2):
        assert np.all(np.isfinite(run["J"]))
        np.testing.assert_array_equal(run["J"][1:, 1:], [[0.0, HALF, HALF, HALF, HALF]] * 3)
        assert run["alarm"].tolist() == [0, 1, 1, 1] and run["isolated"].tolist() == [-1] * 4


def test_persistence_and_a_skipped_sample() -> None:
    flt = identity_filter(Y_th=[0.1, 0.1], window=2, h=0.5, explicit_level=0.1, persistence=3)
    Y = [[1.0, 0.0]] * 4 + [[np.nan, 0.0]] + [[1.0, 0.0]] * 2 + [[0.0, 0.0]] * 2
    for run in both_runs(flt, Y):
        # exceedances from sample 1 on; the NaN sample neither counts nor resets; a small RMS resets
        assert run["alarm"].tolist() == [0, 0, 0, 1, 0, 1, 1, 1, 0]
        assert run["isolated"].tolist() == [-1, -1, -1, 0, -1, 0, 0, 0, -1]
        assert run["status"].tolist() == [0, 0, 0, 0, 1, 0, 0, 0, 0]
        np.testing.assert_array_equal(run["r"][4], [0.0, 0.0])
        np.testing.assert_array_equal(run["J"][4], np.zeros(6))
    state = beard_reference_run(flt, np.zeros((9, 0)), np.array(Y)).state
    assert flt.layout.unpack(state)["nonfinite"] == 1.0


# --------------------------------------------------------------------------- (e) the gain file


def test_round_trip_is_exact(tmp_path) -> None:  # noqa: ANN001 - a path
    flt, _ = pendulum(**DECISION, rho=2.5, design_info={"eigenvalues": [[0.6, 0.2], [0.6, -0.2]], "sigma": 0.1})
    gf = gain_file(flt)
    back = read_gain_file(write_gain_file(gf, tmp_path / "gains.json"))
    assert back.to_dict() == gf.to_dict()
    again = beard_from_gain_file(back)
    for key in ("A", "B", "C", "D", "L", "Y_th", "Xu", "Xy"):
        np.testing.assert_array_equal(getattr(again, key), getattr(flt, key))
    assert all(np.array_equal(a, b) for a, b in zip(again.axes, flt.axes, strict=True))
    assert (again.window, again.h, again.explicit_level, again.rho, again.persistence) == (5, 0.05, 0.01, 2.5, 2)
    assert again.design_info == flt.design_info == {"eigenvalues": [[0.6, 0.2], [0.6, -0.2]], "sigma": 0.1}
    assert gf.thresholds[0] == 0.05 and gf.thresholds[1] == 1.0 and np.all(np.isinf(gf.thresholds[2:]))
    assert gf.step.statistic_names == ("rms", "rho", "angle_f0", "angle_f1", "cone_f0", "cone_f1")
    assert gf.step.residual_names == ("eps_y0", "eps_y1")


def _set(key: str, value: Any) -> Callable[[dict], None]:
    def edit(doc: dict) -> None:
        doc[key] = value

    return edit


def _scale_axis(doc: dict) -> None:
    doc["axes"][1] = [[2 * v for v in row] for row in doc["axes"][1]]


def _nan_in(key: str) -> Callable[[dict], None]:
    def edit(doc: dict) -> None:
        doc[key][0][0] = float("nan")

    return edit


def _nudge(key: str) -> Callable[[dict], None]:
    def edit(doc: dict) -> None:
        doc[key][0][0] += 1e-6 * max(abs(v) for row in doc[key] for v in row)

    return edit


def _unstable(doc: dict) -> None:
    doc["L"] = [[0.0] * len(doc["L"][0]) for _ in doc["L"]]
    doc["A"] = [[2.0 * (i == j) for j in range(len(doc["A"]))] for i in range(len(doc["A"]))]


CORRUPTIONS = {
    "format": (_set("format", 2), r"beard_fdf\.format must be 1"),
    "missing": (lambda d: d.pop("h"), r"missing field\(s\) \['h'\]"),
    "unknown": (_set("extra", 1), r"unknown field\(s\) \['extra'\]"),
    "A_shape": (lambda d: d["A"].pop(), r"beard_fdf\.(A|B|L) must be"),
    "A_nan": (_nan_in("A"), r"beard_fdf\.A must be a 4×4 matrix of finite numbers"),
    "B_cols": (lambda d: [row.append(0.0) for row in d["B"]], r"beard_fdf\.B must be a 4×1 matrix"),
    "C_rows": (lambda d: d["C"].pop(), r"beard_fdf\.C must be a 2×4 matrix"),
    "D_text": (_set("D", "zero"), r"beard_fdf\.D must be a 2×1 matrix .*found 'zero'"),
    "L_shape": (_set("L", [[1.0, 2.0]]), r"beard_fdf\.L must be a 4×2 matrix"),
    "L_unstable": (_unstable, r"beard_fdf\.L must make A − L C Schur stable .*found spectral radius 2\.0"),
    "Xu": (_nudge("Xu"), r"beard_fdf\.Xu must be the equilibrium map"),
    "Xy": (_nudge("Xy"), r"beard_fdf\.Xy must be the equilibrium map"),
    "axes_count": (lambda d: d["axes"].pop(), r"beard_fdf\.axes must be a list of 2 matrices"),
    "axes_scaled": (_scale_axis, r"beard_fdf\.axes\[1\] must have orthonormal columns"),
    "axes_rows": (lambda d: d["axes"][0].pop(), r"beard_fdf\.axes must be a 2×d matrix"),
    "Y_th_large": (_set("Y_th", [0.1, 1.6]), r"beard_fdf\.Y_th must be a list of 2 angles in \[0, π/2\]"),
    "Y_th_negative": (_set("Y_th", [-0.1, 0.1]), r"beard_fdf\.Y_th must be"),
    "Y_th_short": (_set("Y_th", [0.1]), r"beard_fdf\.Y_th must be"),
    "window_zero": (_set("window", 0), r"beard_fdf\.window must be a whole number in 1\.\.1018"),
    "window_float": (_set("window", 5.0), r"beard_fdf\.window must be a whole number"),
    "window_huge": (_set("window", 1019), r"beard_fdf\.window must be a whole number in 1\.\.1018; found 1019"),
    "h_zero": (_set("h", 0.0), r"beard_fdf\.h must be a positive finite number; found 0\.0"),
    "h_bool": (_set("h", True), r"beard_fdf\.h must be a positive"),
    "explicit_level": (_set("explicit_level", -1.0), r"beard_fdf\.explicit_level must be a positive"),
    "rho_one": (_set("rho", 1.0), r"beard_fdf\.rho must be null \(online\) or a finite number > 1; found 1\.0"),
    "rho_text": (_set("rho", "2"), r"beard_fdf\.rho must be null"),
    "persistence_zero": (_set("persistence", 0), r"beard_fdf\.persistence must be a whole number in 1\.\.1000000000"),
    "persistence_huge": (_set("persistence", 10**10), r"beard_fdf\.persistence must be"),
    "thresholds": (_set("thresholds", [0.05, 2.0, None, None, None, None]), r"beard_fdf\.thresholds must be \[h, 1\.0\]"),
    "design": (_set("design", [1, 2]), r"beard_fdf\.design must be an object"),
    "warmup_negative": (_set("warmup", -1), r"beard_fdf\.warmup must be a whole number in 0\.\.1000; found -1"),
    "warmup_bool": (_set("warmup", True), r"beard_fdf\.warmup must be a whole number in 0\.\.1000; found True"),
    "warmup_huge": (_set("warmup", 1001), r"beard_fdf\.warmup must be a whole number in 0\.\.1000"),
    "warmup_state": (_set("warmup", 3), r"step\.nstate is 19; .* implies 23"),  # its accumulator is not in the state
}


@pytest.mark.parametrize("case", list(CORRUPTIONS))
def test_the_reader_refuses_each_corrupted_field(case: str) -> None:
    flt, _ = pendulum(**DECISION)
    gf = gain_file(flt)
    edit, message = CORRUPTIONS[case]
    doc = copy.deepcopy(gf.extensions["beard_fdf"])
    edit(doc)
    with pytest.raises(GainFileError, match=message) as info:
        beard_from_gain_file(replace(gf, extensions={"beard_fdf": doc}))
    assert "\n" not in str(info.value)


STEP_CORRUPTIONS = {
    "nstate": (lambda st: replace(st, nstate=st.nstate + 1, init_state=np.zeros(st.nstate + 1)), r"step\.nstate is 20; .* implies 19"),
    "init_state": (lambda st: replace(st, init_state=np.where(np.arange(st.nstate) == 4, 1.0, 0.0)), r"step\.init_state\[4\] \(ready\) is 1\.0"),
    "residual_names": (lambda st: replace(st, residual_names=("a", "b")), r"step\.residual_names is \('a', 'b'\)"),
    "statistic_names": (lambda st: replace(st, statistic_names=tuple(reversed(st.statistic_names))), r"step\.statistic_names is"),
}


@pytest.mark.parametrize("case", list(STEP_CORRUPTIONS))
def test_the_reader_refuses_a_step_that_disagrees_with_the_payload(case: str) -> None:
    flt, _ = pendulum(**DECISION)
    gf = gain_file(flt)
    edit, message = STEP_CORRUPTIONS[case]
    with pytest.raises(GainFileError, match=message):
        beard_from_gain_file(replace(gf, step=edit(gf.step)))


def test_the_reader_refuses_a_failed_certificate_and_another_kind() -> None:
    flt, _ = pendulum(**DECISION)
    gf = gain_file(flt)
    with pytest.raises(GainFileError, match=r"certificate\.passed is False"):
        beard_from_gain_file(replace(gf, certificate={"passed": False}))
    with pytest.raises(GainFileError, match=r"kind is 'nafdf'; expected 'beard_fdf'"):
        beard_from_gain_file(replace(gf, kind="nafdf", extensions={"nafdf": gf.extensions["beard_fdf"]}))


def test_the_registry_builds_the_step_and_the_recovery_window() -> None:
    flt, _ = four_state(**DECISION)
    gf = gain_file(flt)
    fn = step_function(gf)
    assert tuple(fn.name_in()) == STEP_INPUTS and tuple(fn.name_out()) == STEP_OUTPUTS
    same = beard_step_function(gf)
    s, u, y = gf.step.init_state, np.ones(1), np.arange(4.0)
    for a, b in zip(fn(s, u, y), same(s, u, y), strict=True):
        np.testing.assert_array_equal(np.array(a), np.array(b))
    # the window, then ‖G^j‖ ≤ 1e-3: independent truth by brute force over the powers of G
    settle = next(j for j in range(1000) if np.linalg.norm(np.linalg.matrix_power(flt.G, j), 2) <= 1e-3)
    assert recovery_samples(gf) == flt.window + settle


def test_compiled_c_without_inputs_on_crafted_residuals(tmp_path) -> None:  # noqa: ANN001 - a path
    """No input (``nu = 0``), a zero window mean (every angle π/2, no NaN from atan2(0, 0) or asin), a skipped
    sample and an overflow: the C agrees with the reference exactly where it decides and to round-off elsewhere."""
    flt = identity_filter(Y_th=[0.1, 0.1], window=2, h=0.5, explicit_level=0.1, persistence=1)
    gf = gain_file(flt, name="beard_crafted")
    write_gain_file(gf, tmp_path / "gains.json")
    cd = CompiledDiagnoser(codegen(tmp_path).library, gf)
    Y = np.array([[1.0, 0.0], [-1.0, 0.0], [1.0, 0.0], [np.inf, 0.0], [1.0, 0.05], [1.0, 0.05], [1e300, 1e300], [0.0, 2.0], [0.0, 2.0]])
    U = np.zeros((Y.shape[0], 0))
    got, ref = cd.run(U, Y), beard_reference_run(flt, U, Y)
    for key in ("alarm", "isolated", "status"):
        np.testing.assert_array_equal(getattr(got, key), getattr(ref, key), err_msg=key)
    np.testing.assert_allclose(got.J, ref.J, rtol=1e-14, atol=0)
    np.testing.assert_allclose(got.r, ref.r, rtol=1e-14, atol=0)
    np.testing.assert_array_equal(got.state, ref.state)
    assert got.J[1, 2] == got.J[2, 3] == HALF and ref.status.tolist() == [0, 0, 0, 1, 0, 0, 1, 0, 0]
    assert ref.isolated.tolist() == [-1, -1, -1, -1, 0, 0, -1, -1, 1]
