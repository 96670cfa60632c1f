"""Nonlinear adaptive fault-detection filter, NAFDF (Zhou, Xi & Zhang 1991, fig. 1), as one CasADi step.

Zhou, Xi & Zhang, "Detection and diagnostics of parameter jump for a class of
nonlinear systems", Shanghai Jiao Tong University, c. 1991 (equation and
figure numbers below are theirs). The four blocks of their fig. 1 run inside
one CasADi ``Function``
``(state, u, y) → (state_next, r, J, alarm, isolated, status)``, the step
contract shared with every fdisyn diagnoser. It is pure SX with hand-unrolled
LDLᵀ factorisations (no linear-solver plugin), so it code-generates to
allocation-free C.

Block 1 — fast detection (eqs. (2.3)–(2.4)). An EKF on the model with
parameters ``θ_e`` (the nominal ``θ0`` until re-parameterised), in the
textbook filter form: at sample ``t``

    γ = y − h(x̂, θ_e),   V0 = H P Hᵀ + Q2,   K_f = P Hᵀ V0⁻¹             (2.3)
    x̂⁺ = f(x̂ + K_f γ, u, θ_e),   P⁺ = F [(I − K_f H) P (I − K_f H)ᵀ + K_f Q2 K_fᵀ] Fᵀ + Q1

(``H = ∂h/∂x`` at the prediction, ``F = ∂f/∂x`` at the filtered state, both
by CasADi AD; the Joseph form keeps ``P`` symmetric positive semidefinite).
WSSR (2.4): ``L(t) = (1/N) Σ_{j=t−N+1..t} γ(j)ᵀ V0(j)⁻¹ γ(j)``, kept as a
shift register of the ``N`` normalised squares. Under H0 each square is
``χ²(p)`` and they are independent (innovations of an exact Kalman filter are
white), so ``N·L ~ χ²(N p)``. Threshold rule ``"chi2"``: ``L > χ²_{1−P_f}(k p)/k``
with ``k = min(samples in the window, N)`` (exact also while the window
refills after a reset); rule ``"beta0"``: the paper's fixed ``L > β0``, only
on a full window.

Block 2 — the NF, joint state/parameter filter (2.5), a recursive
prediction-error (Gauss–Newton) filter in the sense of Ljung (IEEE TAC 24(1),
1979) and Zhou–Blanke (IEEE TAC 34(3), 1989), the paper's refs. [6], [7]. At
sample ``t``, from the predictions ``x̂(t)``, ``W(t) = ∂x̂(t)/∂θ`` made with
``θ̂(t−1)``:

    ε(t) = y(t) − h(x̂(t), θ̂(t−1)),    H_t = ∂h/∂x,   S = H_t P Hᵀ_t + Q2
    Φ(t) = (H_t W(t) + ∂h/∂θ)ᵀ                                     (∂ŷ/∂θ)ᵀ
    λ(t) = λ0 λ(t−1) + (1 − λ0) λ∞,   a(t) = a(t−1) / (a(t−1) + λ(t))
    R(t) = R(t−1) + a(t) [Φ S⁻¹ Φᵀ − R(t−1)]
    θ̂(t) = Π[θ̂(t−1) + β(t) R(t)⁻¹ Φ S⁻¹ ε],   β(t) = a(t)
    K = F_t P Hᵀ_t S⁻¹,   F_t = ∂f/∂x,  F_θ = ∂f/∂θ  (at x̂(t), u(t), θ̂(t−1))
    B_x(t) = [(F_t − K H_t) W(t) − K ∂h/∂θ] (θ̂(t) − θ̂(t−1))
    x̂(t+1) = f(x̂(t), u(t), θ̂(t)) + B_x(t) + K ε(t)
    W(t+1) = (F_t − K H_t) W(t) + F_θ − K ∂h/∂θ
    P(t+1) = (F_t − K H_t) P (F_t − K H_t)ᵀ + Q1 + K Q2 Kᵀ

Choices the paper leaves to its ref. [8], and why:

* ``Φ`` — the transposed gradient of the one-step prediction ``ŷ`` with
  respect to ``θ``, propagated through the filter by the sensitivity
  recursion for ``W`` (dropping ``∂K/∂θ``, the usual EKF-based RPE
  simplification; ``K`` is a function of ``P``, not of ``θ`` directly).
* ``a(t)`` — Ljung–Söderström's gain with a growing forgetting factor:
  ``λ(0) = forgetting_initial`` (0.95) forgets the bad early sensitivities
  quickly, ``λ → λ∞ = forgetting_final`` at rate ``λ0 = forgetting_rate``
  (0.99); ``a(0) = 1``. ``λ∞ = 1`` gives ``a(t) ~ 1/t`` (a consistent
  estimator); the default ``λ∞ = 0.99`` (a memory of ~100 samples) makes
  the converged estimate a stationary process, which the classifier needs:
  (2.6) and (2.7) compare the spread of ``θ̂`` over ``N1`` healthy samples
  with its spread after a re-convergence, and with ``a(t) ~ 1/t`` the first
  shrinks forever while the second restarts at every NF reset.
* ``β(t) = a(t)`` — the Gauss–Newton step, so that ``β R⁻¹`` is the
  recursive-least-squares parameter covariance ``(R(0) + Σ Φ S⁻¹ Φᵀ)⁻¹``
  up to forgetting; a separate ``β`` would bias the step length.
* ``Π`` — projection on the box ``[theta_lower, theta_upper]`` (Ljung's
  projection into the model set ``D_M``), so a transient estimate cannot make
  the predictor explode; unbounded by default.
* ``B_x`` — the first-order correction that makes ``x̂(t+1)`` the prediction
  under the *new* ``θ̂(t)``: ``x̂(t; θ̂(t)) ≈ x̂(t) + W Δθ̂`` and
  ``ε(t; θ̂(t)) ≈ ε − Φᵀ Δθ̂`` propagated through the predictor; the part
  ``F_θ Δθ̂`` is already in ``f(·, θ̂(t))``. Without it the state lags the
  parameter estimate.
* ``F_t``, ``H_t`` — Jacobians by CasADi AD; ``P`` in the Joseph form of
  (2.5)'s update (equal to ``F P Fᵀ + Q1 − K S Kᵀ`` for this ``K``).

Block 3 — modified Bayes classifier (2.6)–(2.8). Nominal statistics (2.6):
the mean ``μ̂_i0`` and variance ``σ̂²_i0`` (divided by the sample count) of
``θ̂_i`` over the first ``N1`` samples on which the NF has converged outside
an alarm episode, by Welford's recursion. The diagnoser must be started on a
healthy plant (Zhou, Xi & Zhang 1991 assume faults are infrequent, section 2).
A WSSR alarm ends an unfinished learning phase: with at least ``N2`` samples their statistics are
used, otherwise they are discarded and learning restarts after the episode —
learning on through an episode would take a faulty plant as nominal. Window statistics (2.7) over ``θ̂(t−1..t−N2)`` and
``d_i = σ²_i1/σ²_i0 − ln(σ²_i1/σ²_i2) − 1``, evaluated (and reported)
whenever the NF has converged since its last (re)initialisation (the paper's
reason for ``T1``: the transient after an NF reset moves every estimate).
Isolation follows detection, as in the paper's run (alarm at 712, NF reset,
isolation at 1000): ``d_i > W1`` for ``T1`` consecutive samples isolates
parameter ``i`` only within ``N2 + 2·T1`` samples after an alarm episode
closed. Without this gate the converged NF, which forgets, wanders, and the
spread ``σ̂²_i0`` of ``N1`` strongly autocorrelated samples underestimates
that wander: a long healthy run would eventually be "isolated". class 2 (severe) if also
``d_i > W2`` throughout, else 1; fault size (2.8)
``Δ_i = θ̂_i(τ + T1) − μ̂_i0`` at that sample. Class, size and the
``isolated`` output (the first parameter isolated; lowest index on a tie)
stay latched until the caller re-initialises the diagnoser.

Block 4 — mutual re-initialisation.
* *Converged* (the paper: "once the NF has estimated the parameters
  accurately"): at least ``N2`` NF updates since its (re)initialisation, the
  range ``max − min`` of every ``θ̂_i`` over the last ``N2`` samples is at
  most ``convergence_tolerance_i``, and the NF's own normalised innovations
  over those samples pass the ``χ²(N2 p)`` test at level
  ``convergence_level`` (the model with ``θ̂`` explains the data). It is
  sticky until the next NF (re)initialisation.
* *NF reset*: on a WSSR alarm, unless an episode is already open (an alarm
  whose NF reset has not yet led to an EKF re-parameterisation): ``θ̂ ← θ̂(0)``,
  ``P ← P(0)``, ``R ← R(0)``, ``W ← 0``, ``a, λ`` to their initial values,
  ``x̂`` kept (the paper: ``X̂(712) = X̂(712)``), windows and the
  classifier's run counters cleared. Alarms inside an open episode do not
  reset again: the EKF is known to be wrong until it is re-parameterised.
* *EKF re-parameterisation*: when the NF converges inside an open episode:
  ``θ_e ← θ̂``, ``P ← P(0)`` (the paper), and ``x̂_e ← x̂_NF`` (beyond the
  paper: the EKF's own state was estimated with the wrong model for the
  whole episode); the WSSR window is cleared and the episode closed.
* *Divergence*: a filter whose covariance (or ``R``) is not finite or not
  positive (semi)definite, or whose state or estimate is not finite, is
  re-initialised (EKF: ``P(0)`` and the NF's (else the initial) state; NF: as
  on an alarm, without opening an episode), the ``diverged`` statistic is 1
  for that sample and a counter in the state counts it. No output is ever
  NaN.
* *Skipped samples*: a non-finite ``u`` or ``y`` (tested as ``|v| < inf``
  with ``if_else``, which survives code generation) leaves the state unchanged
  except the ``skipped`` counter, raises no alarm and returns ``status = 1``.

Step contract (shared with the linear diagnosers). Inputs ``state[nstate]``,
``u[m]``, ``y[p]``; outputs ``state_next``, ``r[2p]``, ``J[3 + 4l + 2]``,
``alarm`` (the WSSR decision of this sample, 0/1), ``isolated`` (−1, or the
index of the first isolated parameter in ``plant.parameters``, which are the
fault names), ``status`` (0 processed, 1 skipped). All dense column vectors.

* ``r = [γ (EKF innovation, one per output: ekf_innovation_<y>),
  ε (NF innovation: nf_innovation_<y>)]``.
* ``J = [wssr (L(t)), wssr_threshold, ekf_nis (γᵀV0⁻¹γ), theta_hat_<θ>…,
  d_<θ>…, fault_class_<θ>… (0/1/2, latched), fault_size_<θ>… (latched),
  nf_converged, diverged]``.
* ``state`` blocks in order (matrices column-major; see :class:`StateLayout`):
  ``ekf_x[n], ekf_P[n×n], ekf_theta[l], wssr_buffer[N], wssr_count,
  nf_x[n], nf_P[n×n], nf_theta[l], nf_R[l×l], nf_W[n×l], nf_gain (a),
  nf_forgetting (λ), nf_age, nf_converged, theta_window[l×N2]
  (column j = θ̂(t−1−j)), nis_window[N2], nominal_count, nominal_mean[l],
  nominal_m2[l], nominal_frozen, count_w1[l], count_w2[l], fault_class[l],
  fault_size[l], isolated, episode_open, diagnosis_left, samples, skipped,
  alarm_resets, ekf_reparameterisations, ekf_divergence_resets,
  nf_divergence_resets``.

Limits (checked before anything is built or generated, at design time and
again on reading a gain file; each keeps one resource bounded, with room for
the documented problems — ship: ``N = 10``, ``N2 = 50``, 3 086 operations;
drive train: ``N = 50``, ``N2 = 200``, 11 202 operations):

* :data:`MAX_DIMENSION` states, inputs, outputs and parameters each;
* :data:`MAX_WINDOW` for the WSSR window ``N``, :data:`MAX_CLASSIFIER_WINDOW`
  for ``N2``, :data:`MAX_COUNT` for ``N1`` and ``T1`` (counters held in
  doubles, exact far beyond);
* :data:`MAX_STATE` entries in the diagnoser state (the layout is computed
  from the sizes before any array exists, so ``window = 1e9`` is refused
  without allocating it);
* :data:`MAX_STEP_INSTRUCTIONS` operations in the step (checked on the SX
  graph, before C is generated): the generated C grows by ~27 bytes per
  operation and gcc ``-O2`` time grows faster than linearly (measured: 3 086
  operations, 79 kB, 2 s; 18 921, 0.5 MB, 28 s; 38 237, 1.1 MB, 81 s);
* :data:`MAX_STEP_WORK` doubles of CasADi work memory. CasADi generates an
  SX step's work as local variables (its ``_SZ_W`` is 0), which gcc keeps in
  registers or spills to the stack of ``<name>_step``, next to the wrapper's
  ``next[NSTATE]`` copy of the state: the stack use is at most about
  ``8·(MAX_STEP_WORK + MAX_STATE)`` bytes = 96 KiB. Measured with
  ``gcc -O2 -fstack-usage``: ship 1.7 KiB, drive train 4.1 KiB, the ship
  with ``N = 1000`` 9.5 KiB — the state copy dominates.

Gain files. :func:`nafdf_payload` stores the model as data, not code:
``f`` and ``h`` as lists of elementary operations
(:func:`fdisyn.design.nonlinear.model_program`) that the reader validates
entry by entry before it builds anything, never as CasADi serialised
strings (deserialising untrusted bytes can crash inside CasADi, and a checksum
would only catch accidents: whoever edits the file can recompute it). The
reader (:func:`nafdf_from_gain_file`) then checks every other field against
what the payload implies — the settings as :func:`nafdf` checks them, the
limits, the threshold table against the rule, the layout, the names, the
initial state, the gain file's faults, sizes and fixed thresholds — and
rebuilds and re-certifies the design; a file whose certificate did not pass
is refused.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import casadi as ca
import numpy as np
import scipy.stats
from fdisyn.design.certificate import Certificate, Check, worst
from fdisyn.design.diagnoser import provenance
from fdisyn.design.linalg import real_array
from fdisyn.design.nonlinear import (
    NonlinearPlant,
    function_from_program,
    model_program,
    short_repr,
)
from fdisyn.design.sampling import check_sample_time
from fdisyn.design.step import register_step_builder
from fdisyn.runtime.errors import FdisynError, GainFileError, ShapeError, SpecError
from fdisyn.runtime.gainfile import GainFile, StepSpec

__all__ = [
    "MAX_CLASSIFIER_WINDOW",
    "MAX_COUNT",
    "MAX_DIMENSION",
    "MAX_STATE",
    "MAX_STEP_INSTRUCTIONS",
    "MAX_STEP_WORK",
    "MAX_WINDOW",
    "PAYLOAD_FORMAT",
    "PAYLOAD_VERSION",
    "NafdfDesign",
    "NafdfSettings",
    "StateLayout",
    "nafdf",
    "nafdf_extra_metrics",
    "nafdf_from_gain_file",
    "nafdf_from_payload",
    "nafdf_gain_file",
    "nafdf_payload",
    "step_from_payload",
    "wssr_threshold_table",
]

PAYLOAD_FORMAT = "fdisyn.nafdf"
PAYLOAD_VERSION = 2
"""Version 2 stores the model as validated operation lists (version 1 held CasADi serialised strings)."""

# Resource limits (module docstring).
MAX_DIMENSION = 30
"""Most states, inputs, outputs or parameters: the step unrolls LDLᵀ factorisations of n×n, p×p and l×l
matrices (~k³/3 operations each), so ~30 already fills :data:`MAX_STEP_INSTRUCTIONS`."""
MAX_WINDOW = 1000
"""Largest WSSR window ``N``: the window costs ~16 operations per sample (shift, sum, threshold lookup)."""
MAX_CLASSIFIER_WINDOW = 1000
"""Largest ``N2``: the classifier and convergence windows cost ~35 operations per sample and parameter."""
MAX_COUNT = 10**9
"""Largest ``N1`` and ``T1``: sample counters held in doubles (exact to 2⁵³)."""
MAX_STATE = 4096
"""Most entries of the diagnoser state (32 KiB; the generated step keeps a copy on the stack)."""
MAX_STEP_INSTRUCTIONS = 40_000
"""Most operations of the step (≈ 1 MB of C that gcc -O2 compiles in about a minute)."""
MAX_STEP_WORK = 8192
"""Most doubles of CasADi work memory (64 KiB): locals of the generated step, in registers or on its stack."""

# Names a payload may hold (the design's own and the signals'): identifiers of bounded length.
_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_MAX_NAME = 64
# The largest finite double: a threshold that can never be exceeded (JSON has no inf).
_NEVER = float(np.finfo(float).max)
# Variance floor of the classifier: keeps d_i finite when θ̂_i is constant to the last bit.
_VAR_FLOOR = 1e-280
# d_i reported when its formula overflows (only for |θ̂| beyond ~1e140).
_D_OVERFLOW = 1e300
# Largest normalised square kept in the WSSR window, so that the window sum cannot overflow.
_Q_CAP = 1e300
# Relative shift making a PSD covariance test tolerant of round-off (Joseph form: error ~ n·eps·‖P‖).
_PSD_SHIFT = 1e-12


# --------------------------------------------------------------------------- settings


@dataclass(frozen=True, eq=False)
class NafdfSettings:
    """Every design choice of the NAFDF, validated (see the module docstring for their meaning)."""

    x0: np.ndarray
    """Initial state estimate of both filters (the paper's ``x̂(0)``, section 3)."""
    P0: np.ndarray
    """Initial (and reset) state covariance of both filters (the paper's ``P(0)``)."""
    theta0: np.ndarray
    """Initial (and reset) NF parameter estimate (the paper's ``θ̂(0)``)."""
    R0: np.ndarray
    """Initial (and reset) NF information matrix (the paper's ``R(0)``, eq. (2.5))."""
    window: int
    """WSSR window ``N`` (2.4)."""
    threshold_rule: Literal["chi2", "beta0"]
    false_alarm_probability: float
    """``P_f`` of the WSSR test under H0 (rule ``"chi2"``)."""
    beta0: float | None
    """The paper's fixed WSSR threshold (rule ``"beta0"``)."""
    forgetting_initial: float
    forgetting_rate: float
    forgetting_final: float
    theta_lower: np.ndarray
    theta_upper: np.ndarray
    nominal_samples: int
    """``N1`` of (2.6)."""
    classifier_window: int
    """``N2`` of (2.7); also the convergence window."""
    W1: float
    W2: float
    T1: int
    convergence_tolerance: np.ndarray
    """Largest range of each ``θ̂_i`` over ``N2`` samples for the NF to count as converged."""
    convergence_level: float
    """Significance of the NF innovation test inside the convergence check."""
    u0: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """Nominal input: with ``x0`` and ``θ0`` the point where the model must be finite and where the
    certificate compares the AD Jacobians with central differences (not used by the step)."""

    def to_dict(self) -> dict[str, object]:
        out: dict[str, object] = {}
        for k, v in self.__dict__.items():
            if isinstance(v, np.ndarray):
                out[k] = [None if not math.isfinite(z) else float(z) for z in v.reshape(-1)] if v.ndim == 1 else v.tolist()
            else:
                out[k] = v
        return out


def _ro(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float, copy=True)
    a.setflags(write=False)
    return a


def _float_array(value: object, name: str) -> np.ndarray:
    try:
        return real_array(value, name)  # numbers only: "100" or true are refused, not converted
    except ShapeError:
        raise SpecError(f"{name} must be a number or an array of numbers; got {short_repr(value)}") from None


def _vec(value: object, name: str, size: int) -> np.ndarray:
    arr = _float_array(value, name)
    if arr.ndim == 0:
        arr = np.full(size, float(arr))
    arr = arr.reshape(-1)
    if arr.size != size:
        raise ShapeError(f"{name} has {arr.size} entries; expected {size}")
    return arr


def _finite_vec(value: object, name: str, size: int) -> np.ndarray:
    arr = _vec(value, name, size)
    if not np.all(np.isfinite(arr)):
        raise SpecError(f"{name} must be finite; got {short_repr(arr.tolist())}")
    return arr


def _spd(value: object, name: str, size: int) -> np.ndarray:
    arr = _float_array(value, name)
    if arr.ndim == 0:
        arr = float(arr) * np.eye(size)
    elif arr.ndim == 1 and arr.size == size:
        arr = np.diag(arr)
    if arr.shape != (size, size):
        raise ShapeError(f"{name} has shape {arr.shape}; expected ({size}, {size})")
    if not np.all(np.isfinite(arr)):
        raise ShapeError(f"{name} contains non-finite entries")
    if not np.allclose(arr, arr.T, rtol=1e-12, atol=0.0):
        raise ShapeError(f"{name} must be symmetric")
    ev = np.linalg.eigvalsh(arr)
    if ev[0] <= 0.0:
        raise ShapeError(f"{name} must be positive definite; smallest eigenvalue {ev[0]:.3g}")
    return 0.5 * arr + 0.5 * arr.T  # halves first: 1e308 + 1e308 would overflow


def _positive_int(value: object, name: str, maximum: int = MAX_COUNT) -> int:
    """A whole number in ``1..maximum`` (an integral float is accepted: TOML and JSON write ``1e3``)."""
    whole: int | None = None
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        whole = int(value)
    elif isinstance(value, (float, np.floating)) and math.isfinite(value) and float(value).is_integer():
        whole = int(value)
    if whole is None or whole < 1:
        raise SpecError(f"{name} must be a positive integer; got {short_repr(value)}")
    if whole > maximum:
        raise SpecError(f"{name} is {whole}; at most {maximum} is allowed (see the limits in fdisyn.design.nafdf)")
    return whole


def _number(value: object, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise SpecError(f"{name} must be a number; got {short_repr(value)}")
    try:
        return float(value)
    except OverflowError:
        raise SpecError(f"{name} must be a finite number; got {short_repr(value)}") from None


def _unit_open(value: float, name: str) -> float:
    v = _number(value, name)
    if not 0.0 < v < 1.0:
        raise SpecError(f"{name} must lie strictly between 0 and 1; got {short_repr(value)}")
    return v


def wssr_threshold_table(
    *, window: int, n_outputs: int, rule: Literal["chi2", "beta0"], false_alarm_probability: float, beta0: float | None
) -> np.ndarray:
    """Threshold on ``L = (1/k) Σ γᵀ V0⁻¹ γ`` for ``k = 1..N`` samples in the window (eq. (2.4)).

    ``"chi2"``: ``χ²_{1−P_f}(k p) / k`` — the exact ``(1 − P_f)`` quantile of
    ``L`` under H0 (``k L ~ χ²(k p)``). ``"beta0"``: the paper's ``β0`` on a
    full window, never exceeded on a partial one.
    """
    ks = np.arange(1, window + 1)
    if rule == "chi2":
        return np.array([scipy.stats.chi2.isf(false_alarm_probability, k * n_outputs) / k for k in ks])
    if rule == "beta0":
        if beta0 is None or not math.isfinite(beta0) or beta0 <= 0:
            raise SpecError(f"threshold_rule 'beta0' needs a positive finite beta0; got {beta0!r}")
        return np.where(ks == window, float(beta0), _NEVER)
    raise SpecError(f"threshold_rule must be 'chi2' or 'beta0'; got {rule!r}")


# --------------------------------------------------------------------------- state layout


@dataclass(frozen=True)
class StateLayout:
    """Named blocks of the diagnoser state vector; matrices stored column-major (CasADi's order).

    ``scalars`` names the blocks that are counters or flags (unpacked as ``float``);
    every other block with one column unpacks as a 1-D array, even of length one.
    """

    entries: tuple[tuple[str, int, int], ...]
    scalars: frozenset[str] = frozenset()
    matrices: frozenset[str] = frozenset()
    """Blocks that unpack as 2-D arrays whatever their size (covariances, sensitivities, windows)."""

    @property
    def size(self) -> int:
        return sum(r * c for _, r, c in self.entries)

    def offsets(self) -> dict[str, tuple[int, int, int]]:
        out, k = {}, 0
        for name, r, c in self.entries:
            out[name] = (k, r, c)
            k += r * c
        return out

    def unpack(self, vec: object) -> dict[str, np.ndarray | float]:
        """Split a state vector: scalars as float, columns as 1-D arrays, matrices as 2-D arrays."""
        v = np.asarray(vec, dtype=float).reshape(-1)
        if v.size != self.size:
            raise ShapeError(f"state has {v.size} entries; expected {self.size}")
        out: dict[str, np.ndarray | float] = {}
        for name, (k, r, c) in self.offsets().items():
            block = v[k : k + r * c]
            if name in self.scalars:
                out[name] = float(block[0])
            elif c == 1 and name not in self.matrices:
                out[name] = block.copy()
            else:
                out[name] = block.reshape((r, c), order="F").copy()
        return out

    def pack(self, values: Mapping[str, object]) -> np.ndarray:
        """Join named blocks into a state vector (every block required)."""
        missing = [name for name, _, _ in self.entries if name not in values]
        extra = sorted(set(values) - {name for name, _, _ in self.entries})
        if missing or extra:
            raise ShapeError(f"state blocks: missing {missing}, unknown {extra}")
        parts = []
        for name, r, c in self.entries:
            a = np.asarray(values[name], dtype=float)
            if a.size != r * c:
                raise ShapeError(f"state block {name!r} has {a.size} entries; expected {r}×{c}")
            parts.append(a.reshape((r, c)).reshape(-1, order="F") if a.ndim == 2 else a.reshape(-1))
        return np.concatenate(parts) if parts else np.zeros(0)

    def split_sx(self, sx: ca.SX) -> dict[str, ca.SX]:
        return {name: ca.reshape(sx[k : k + r * c], r, c) for name, (k, r, c) in self.offsets().items()}

    def join_sx(self, blocks: Mapping[str, ca.SX]) -> ca.SX:
        return ca.vertcat(*[ca.vec(ca.SX(blocks[name])) for name, _, _ in self.entries])

    def component_names(self) -> list[str]:
        out = []
        for name, r, c in self.entries:
            if name in self.scalars:
                out.append(name)
            elif c == 1 and name not in self.matrices:
                out.extend(f"{name}[{i}]" for i in range(r))
            else:
                out.extend(f"{name}[{i},{j}]" for j in range(c) for i in range(r))
        return out


def _layout(n: int, l: int, window: int, n2: int) -> StateLayout:
    one = (1, 1)
    entries = (
            ("ekf_x", n, 1),
            ("ekf_P", n, n),
            ("ekf_theta", l, 1),
            ("wssr_buffer", window, 1),
            ("wssr_count", *one),
            ("nf_x", n, 1),
            ("nf_P", n, n),
            ("nf_theta", l, 1),
            ("nf_R", l, l),
            ("nf_W", n, l),
            ("nf_gain", *one),
            ("nf_forgetting", *one),
            ("nf_age", *one),
            ("nf_converged", *one),
            ("theta_window", l, n2),
            ("nis_window", n2, 1),
            ("nominal_count", *one),
            ("nominal_mean", l, 1),
            ("nominal_m2", l, 1),
            ("nominal_frozen", *one),
            ("count_w1", l, 1),
            ("count_w2", l, 1),
            ("fault_class", l, 1),
            ("fault_size", l, 1),
            ("isolated", *one),
            ("episode_open", *one),
            ("diagnosis_left", *one),
            ("samples", *one),
            ("skipped", *one),
            ("alarm_resets", *one),
            ("ekf_reparameterisations", *one),
            ("ekf_divergence_resets", *one),
            ("nf_divergence_resets", *one),
    )
    return StateLayout(entries, _SCALAR_BLOCKS, frozenset({"ekf_P", "nf_P", "nf_R", "nf_W", "theta_window"}))


# Counters and flags of the state (every other block is a vector or matrix, whatever its size).
_SCALAR_BLOCKS = frozenset(
    {
        "wssr_count",
        "nf_gain",
        "nf_forgetting",
        "nf_age",
        "nf_converged",
        "nominal_count",
        "nominal_frozen",
        "isolated",
        "episode_open",
        "diagnosis_left",
        "samples",
        "skipped",
        "alarm_resets",
        "ekf_reparameterisations",
        "ekf_divergence_resets",
        "nf_divergence_resets",
    }
)


# --------------------------------------------------------------------------- SX helpers


def _all_finite(*exprs: ca.SX) -> ca.SX:
    """1 if every entry is finite, else 0 — as ``|v| < inf``, which code generation keeps."""
    ok = ca.SX(1)
    for e in exprs:
        v = ca.vec(ca.SX(e))
        for i in range(v.numel()):
            ok = ca.logic_and(ok, ca.fabs(v[i]) < ca.inf)
    return ok


def _sym(a: ca.SX) -> ca.SX:
    return 0.5 * (a + a.T)


def _ldl(a: ca.SX) -> tuple[ca.SX, list[ca.SX]]:
    """Unrolled LDLᵀ of a symmetric matrix without pivoting: unit lower ``L`` and the pivots ``d``.

    All pivots are positive iff the matrix is positive definite (Sylvester);
    the factorisation is then backward stable without pivoting.
    """
    k = a.shape[0]
    low = ca.SX.eye(k)
    d: list[ca.SX] = []
    for j in range(k):
        dj = a[j, j]
        for s in range(j):
            dj = dj - low[j, s] * low[j, s] * d[s]
        d.append(dj)
        for i in range(j + 1, k):
            v = a[i, j]
            for s in range(j):
                v = v - low[i, s] * low[j, s] * d[s]
            low[i, j] = v / dj
    return low, d


def _ldl_solve(low: ca.SX, d: list[ca.SX], b: ca.SX) -> ca.SX:
    """Solve ``L D Lᵀ x = b`` (``b`` may have several columns)."""
    k = low.shape[0]
    cols = []
    for c in range(b.shape[1]):
        z = [b[i, c] for i in range(k)]
        for i in range(k):
            for s in range(i):
                z[i] = z[i] - low[i, s] * z[s]
        z = [z[i] / d[i] for i in range(k)]
        for i in reversed(range(k)):
            for s in range(i + 1, k):
                z[i] = z[i] - low[s, i] * z[s]
        cols.append(ca.vertcat(*z))
    return ca.horzcat(*cols) if cols else ca.SX(k, 0)


def _positive(d: list[ca.SX]) -> ca.SX:
    ok = ca.SX(1)
    for dj in d:
        ok = ca.logic_and(ok, dj > 0)
    return ok


def _psd_ok(p: ca.SX) -> ca.SX:
    """Finite and positive semidefinite to round-off: LDLᵀ of ``P + δ I`` has positive pivots.

    ``δ = 1e-12·max diag P`` (plus the smallest normal number, for ``P = 0``)
    covers the ``n·eps·‖P‖`` round-off of the Joseph update.
    """
    k = p.shape[0]
    big = p[0, 0]
    for i in range(1, k):
        big = ca.fmax(big, p[i, i])
    delta = _PSD_SHIFT * ca.fabs(big) + float(np.finfo(float).tiny)
    _, d = _ldl(p + delta * ca.SX.eye(k))
    return ca.logic_and(_all_finite(p), _positive(d))


def _select(cond: ca.SX, a: ca.SX | ca.DM | float, b: ca.SX | ca.DM | float) -> ca.SX:
    """Entry-wise ``cond ? a : b`` (a true conditional in C: NaN in the other branch cannot leak)."""
    return ca.if_else(cond, ca.SX(a), ca.SX(b))


# --------------------------------------------------------------------------- the step


def _build_step(plant: NonlinearPlant, s: NafdfSettings, thresholds: np.ndarray, name: str) -> tuple[ca.Function, StateLayout]:
    n, m, p, l = plant.n, plant.m, plant.p, plant.l
    N, N2 = s.window, s.classifier_window
    lay = _layout(n, l, N, N2)
    D = plant.derivatives()
    Q1, Q2 = ca.DM(plant.Q1), ca.DM(plant.Q2)
    P0, R0 = ca.DM(s.P0), ca.DM(s.R0)
    x0, th0 = ca.DM(s.x0), ca.DM(s.theta0)
    I_n = ca.SX.eye(n)

    state = ca.SX.sym("state", lay.size)
    u = ca.SX.sym("u", m)
    y = ca.SX.sym("y", p)
    old = lay.split_sx(state)
    new = dict(old)

    # ---- block 1: EKF on the model θ_e (eq. (2.3)) --------------------------------------
    xe, Pe, the = old["ekf_x"], old["ekf_P"], old["ekf_theta"]
    _, _, _, he, He, _ = D(xe, u, the)  # h and ∂h/∂x at the prediction (u unused by h)
    gamma = y - he
    V0 = _sym(ca.mtimes([He, Pe, He.T]) + Q2)  # V0 = H P Hᵀ + Q2
    lv, dv = _ldl(V0)
    v0inv_gamma = _ldl_solve(lv, dv, gamma)
    nis_e = ca.dot(gamma, v0inv_gamma)  # γᵀ V0⁻¹ γ, χ²(p) under H0
    Kf = _ldl_solve(lv, dv, ca.mtimes(He, Pe)).T  # K_f = P Hᵀ V0⁻¹
    xe_f = xe + ca.mtimes(Kf, gamma)
    ikh = I_n - ca.mtimes(Kf, He)
    Pe_f = ca.mtimes([ikh, Pe, ikh.T]) + ca.mtimes([Kf, Q2, Kf.T])  # Joseph form
    fe, Fe, _, _, _, _ = D(xe_f, u, the)
    xe_next = fe
    Pe_next = _sym(ca.mtimes([Fe, Pe_f, Fe.T]) + Q1)
    ekf_ok = ca.logic_and(_all_finite(xe_next, nis_e), _psd_ok(Pe_next))
    ekf_ok = ca.logic_and(ekf_ok, _positive(dv))

    # ---- WSSR (eq. (2.4)) ---------------------------------------------------------------
    # a huge but finite square stays finite in the window sum (N · 1e300 < DBL_MAX)
    q_safe = ca.fmin(_select(_all_finite(nis_e), nis_e, 0.0), _Q_CAP)
    buf_old, cnt_old = old["wssr_buffer"], old["wssr_count"]
    buf_new = ca.vertcat(q_safe, buf_old[: N - 1]) if N > 1 else ca.SX(q_safe)
    cnt_new = ca.fmin(cnt_old + 1, N)
    wssr = ca.sum1(buf_new) / cnt_new  # L(t); unfilled slots are zero
    thr = _table_lookup(cnt_new, thresholds)
    alarm = ca.logic_and(wssr > thr, _all_finite(nis_e))

    # ---- block 2: NF, joint state/parameter filter (eq. (2.5)) --------------------------
    xn, Pn, thn, Rn, Wn = old["nf_x"], old["nf_P"], old["nf_theta"], old["nf_R"], old["nf_W"]
    _, Fn, Fth, hn, Hn, Hth = D(xn, u, thn)
    eps = y - hn  # ε(t)
    S = _sym(ca.mtimes([Hn, Pn, Hn.T]) + Q2)  # S = H P Hᵀ + Q2
    ls_, ds_ = _ldl(S)
    sinv_eps = _ldl_solve(ls_, ds_, eps)
    nis_n = ca.dot(eps, sinv_eps)
    Phi = (ca.mtimes(Hn, Wn) + Hth).T  # Φ = (∂ŷ/∂θ)ᵀ, l × p
    lam = s.forgetting_rate * old["nf_forgetting"] + (1.0 - s.forgetting_rate) * s.forgetting_final
    gain = old["nf_gain"] / (old["nf_gain"] + lam)  # a(t)
    sinv_phiT = _ldl_solve(ls_, ds_, Phi.T)
    Rn_new = _sym(Rn + gain * (ca.mtimes(Phi, sinv_phiT) - Rn))
    lr, dr = _ldl(Rn_new)
    step = gain * _ldl_solve(lr, dr, ca.mtimes(Phi, sinv_eps))  # β R⁻¹ Φ S⁻¹ ε with β = a(t)
    th_new = thn + step
    for i in range(l):  # Π: projection on the parameter box
        if math.isfinite(s.theta_lower[i]):
            th_new[i] = ca.fmax(th_new[i], s.theta_lower[i])
        if math.isfinite(s.theta_upper[i]):
            th_new[i] = ca.fmin(th_new[i], s.theta_upper[i])
    dth = th_new - thn
    K = _ldl_solve(ls_, ds_, ca.mtimes([Hn, Pn, Fn.T])).T  # K = F P Hᵀ S⁻¹
    FKH = Fn - ca.mtimes(K, Hn)
    Bx = ca.mtimes(ca.mtimes(FKH, Wn) - ca.mtimes(K, Hth), dth)
    fn_new, _, _, _, _, _ = D(xn, u, th_new)
    xn_next = fn_new + Bx + ca.mtimes(K, eps)
    Wn_next = ca.mtimes(FKH, Wn) + Fth - ca.mtimes(K, Hth)
    Pn_next = _sym(ca.mtimes([FKH, Pn, FKH.T]) + Q1 + ca.mtimes([K, Q2, K.T]))
    nf_ok = ca.logic_and(_all_finite(xn_next, Wn_next, th_new, Rn_new, nis_n), _psd_ok(Pn_next))
    nf_ok = ca.logic_and(nf_ok, ca.logic_and(_positive(dr), _positive(ds_)))

    # ---- windows at time t (θ̂(t−1..t−N2), NF innovations) and convergence -----------------
    win, nisw = old["theta_window"], old["nis_window"]
    full = old["nf_age"] >= N2
    settled = ca.SX(1)
    for i in range(l):
        lo_i, hi_i = win[i, 0], win[i, 0]
        for j in range(1, N2):
            lo_i, hi_i = ca.fmin(lo_i, win[i, j]), ca.fmax(hi_i, win[i, j])
        settled = ca.logic_and(settled, hi_i - lo_i <= float(s.convergence_tolerance[i]))
    nis_limit = float(scipy.stats.chi2.isf(s.convergence_level, N2 * p))
    explains = ca.sum1(nisw) <= nis_limit
    conv_old = old["nf_converged"]
    conv = ca.logic_or(conv_old, ca.logic_and(full, ca.logic_and(settled, explains)))
    conv = ca.logic_and(conv, nf_ok)

    # EKF re-parameterisation: the NF converges inside an open alarm episode (block 4)
    episode = old["episode_open"]
    reparam = ca.logic_and(ca.logic_and(conv, ca.logic_not(conv_old)), ca.logic_and(episode, nf_ok))
    # isolation follows detection: the classifier may decide for a limited time after the episode closes
    diag_left = _select(reparam, float(_diagnosis_samples(s)), old["diagnosis_left"])

    # ---- block 3: modified Bayes classifier (eqs. (2.6)–(2.8)) ---------------------------
    n1 = old["nominal_count"]
    nominal_ready = ca.logic_or(n1 >= s.nominal_samples, old["nominal_frozen"])
    armed = ca.logic_and(nominal_ready, conv)
    mu0 = old["nominal_mean"]
    var0 = ca.fmax(old["nominal_m2"] / ca.fmax(n1, 1), _VAR_FLOOR)
    d_stat, c1_new, c2_new, cls_new, size_new = [], [], [], [], []
    latch_now = []
    for i in range(l):
        row = win[i, :].T
        mu_i = ca.sum1(row) / N2
        var1 = ca.fmax(ca.sum1((row - mu0[i]) ** 2) / N2, _VAR_FLOOR)  # σ²_i1: about the nominal mean
        var2 = ca.fmax(ca.sum1((row - mu_i) ** 2) / N2, _VAR_FLOOR)  # σ²_i2: about the window mean
        di = var1 / var0[i] - ca.log(var1 / var2) - 1.0  # eq. (2.7)
        di = _select(_all_finite(di), di, _D_OVERFLOW)
        di = _select(armed, di, 0.0)
        deciding = ca.logic_and(armed, diag_left > 0)
        c1 = _select(ca.logic_and(deciding, di > s.W1), old["count_w1"][i] + 1, 0.0)
        c2 = _select(ca.logic_and(deciding, di > s.W2), old["count_w2"][i] + 1, 0.0)
        latch = ca.logic_and(old["fault_class"][i] == 0, c1 >= s.T1)
        cls_i = _select(latch, _select(c2 >= s.T1, 2.0, 1.0), old["fault_class"][i])
        size_i = _select(latch, th_new[i] - mu0[i], old["fault_size"][i])  # eq. (2.8)
        d_stat.append(di)
        c1_new.append(c1)
        c2_new.append(c2)
        cls_new.append(cls_i)
        size_new.append(size_i)
        latch_now.append(latch)
    iso_cand = ca.SX(-1.0)
    for i in reversed(range(l)):
        iso_cand = _select(latch_now[i], float(i), iso_cand)
    isolated = _select(old["isolated"] >= 0, old["isolated"], iso_cand)

    # nominal statistics (2.6), Welford: on a converged NF, outside an episode, until N1 samples
    learn = ca.logic_and(ca.logic_and(conv, ca.logic_not(old["episode_open"])), ca.logic_not(nominal_ready))
    n1_next = n1 + 1
    delta = th_new - mu0
    mean_next = mu0 + delta / n1_next
    m2_next = old["nominal_m2"] + delta * (th_new - mean_next)

    # ---- block 4: mutual re-initialisation ------------------------------------------------
    alarm_reset = ca.logic_and(alarm, ca.logic_not(episode))
    nf_reset = ca.logic_or(alarm_reset, ca.logic_not(nf_ok))
    episode_next = _select(reparam, 0.0, _select(alarm_reset, 1.0, episode))
    wssr_clear = ca.logic_or(reparam, ca.logic_not(ekf_ok))

    # EKF next state: normal, re-parameterised from the NF, or re-initialised after divergence
    xn_fallback = _select(_all_finite(xn_next), xn_next, x0)
    new["ekf_x"] = _select(ekf_ok, _select(reparam, xn_next, xe_next), xn_fallback)
    new["ekf_P"] = _select(ca.logic_and(ekf_ok, ca.logic_not(reparam)), Pe_next, P0)
    new["ekf_theta"] = _select(reparam, th_new, the)
    new["wssr_buffer"] = _select(wssr_clear, ca.SX.zeros(N, 1), buf_new)
    new["wssr_count"] = _select(wssr_clear, 0.0, cnt_new)

    # NF next state: normal or (re)initialised
    xe_fallback = _select(_all_finite(xe_next), xe_next, x0)
    new["nf_x"] = _select(nf_ok, xn_next, xe_fallback)
    new["nf_P"] = _select(nf_reset, P0, Pn_next)
    new["nf_theta"] = _select(nf_reset, th0, th_new)
    new["nf_R"] = _select(nf_reset, R0, Rn_new)
    new["nf_W"] = _select(nf_reset, ca.SX.zeros(n, l), Wn_next)
    new["nf_gain"] = _select(nf_reset, 1.0, gain)
    new["nf_forgetting"] = _select(nf_reset, s.forgetting_initial, lam)
    new["nf_age"] = _select(nf_reset, 0.0, old["nf_age"] + 1)
    new["nf_converged"] = _select(nf_reset, 0.0, conv)
    win_next = ca.horzcat(th_new, win[:, : N2 - 1]) if N2 > 1 else th_new
    new["theta_window"] = _select(nf_reset, ca.SX.zeros(l, N2), win_next)
    nis_safe = ca.fmin(_select(_all_finite(nis_n), nis_n, 0.0), _Q_CAP)
    nis_next = ca.vertcat(nis_safe, nisw[: N2 - 1]) if N2 > 1 else nis_safe
    new["nis_window"] = _select(nf_reset, ca.SX.zeros(N2, 1), nis_next)

    # An alarm ends an unfinished learning phase: with ≥ N2 samples their statistics are kept
    # (learning on after the episode could learn a faulty plant); with fewer they are discarded.
    cut = ca.logic_and(alarm_reset, ca.logic_and(n1 > 0, ca.logic_not(nominal_ready)))
    keep = ca.logic_and(cut, n1 >= N2)
    drop = ca.logic_and(cut, n1 < N2)
    new["nominal_count"] = _select(drop, 0.0, _select(learn, n1_next, n1))
    new["nominal_mean"] = _select(drop, ca.SX.zeros(l, 1), _select(learn, mean_next, mu0))
    new["nominal_m2"] = _select(drop, ca.SX.zeros(l, 1), _select(learn, m2_next, old["nominal_m2"]))
    new["nominal_frozen"] = ca.logic_or(old["nominal_frozen"], keep)
    new["count_w1"] = _select(nf_reset, ca.SX.zeros(l, 1), ca.vertcat(*c1_new))
    new["count_w2"] = _select(nf_reset, ca.SX.zeros(l, 1), ca.vertcat(*c2_new))
    new["fault_class"] = ca.vertcat(*cls_new)
    new["fault_size"] = ca.vertcat(*size_new)
    new["isolated"] = isolated
    new["episode_open"] = episode_next
    new["diagnosis_left"] = _select(nf_reset, 0.0, ca.fmax(diag_left - 1, 0.0))
    new["samples"] = old["samples"] + 1
    new["alarm_resets"] = old["alarm_resets"] + alarm_reset
    new["ekf_reparameterisations"] = old["ekf_reparameterisations"] + reparam
    new["ekf_divergence_resets"] = old["ekf_divergence_resets"] + ca.logic_not(ekf_ok)
    new["nf_divergence_resets"] = old["nf_divergence_resets"] + ca.logic_not(nf_ok)
    diverged = ca.logic_or(ca.logic_not(ekf_ok), ca.logic_not(nf_ok))

    r_proc = ca.vertcat(gamma, eps)
    J_proc = ca.vertcat(
        wssr,
        thr,
        q_safe,
        new["nf_theta"],
        ca.vertcat(*d_stat),
        new["fault_class"],
        new["fault_size"],
        new["nf_converged"],
        diverged,
    )

    # ---- skipped sample: nothing changes but the counter ---------------------------------
    held = dict(old)
    held["skipped"] = old["skipped"] + 1
    cnt_hold = ca.fmax(cnt_old, 1)
    J_hold = ca.vertcat(
        ca.sum1(buf_old) / cnt_hold,
        _table_lookup(cnt_hold, thresholds),
        0.0,
        thn,
        ca.SX.zeros(l, 1),
        old["fault_class"],
        old["fault_size"],
        old["nf_converged"],
        0.0,
    )
    ok_in = _all_finite(u, y)
    state_next = _select(ok_in, lay.join_sx(new), lay.join_sx(held))
    r_out = _select(ok_in, _sanitise(r_proc), ca.SX.zeros(2 * p, 1))
    J_out = _select(ok_in, _sanitise(J_proc), _sanitise(J_hold))
    alarm_out = _select(ok_in, alarm, 0.0)
    iso_out = _select(ok_in, isolated, old["isolated"])
    status = _select(ok_in, 0.0, 1.0)
    fun = ca.Function(
        name,
        [state, u, y],
        [state_next, r_out, J_out, alarm_out, iso_out, status],
        ["state", "u", "y"],
        ["state_next", "r", "J", "alarm", "isolated", "status"],
    )
    return fun, lay


def _diagnosis_samples(s: NafdfSettings) -> int:
    """How long after an episode closes the classifier may isolate: ``N2 + 2·T1`` samples.

    The NF has just converged on a fresh window, so a real jump shows as ``d_i > W1`` at once and
    isolates after ``T1`` samples; the margin of ``N2 + T1`` covers a slower crossing.
    """
    return s.classifier_window + 2 * s.T1


def _sanitise(v: ca.SX) -> ca.SX:
    """``±inf → ±DBL_MAX``, ``NaN → 0``: a last guard on the outputs (the filters' own checks come first)."""
    v = ca.SX(v)
    out = []
    for i in range(v.numel()):
        overflow = _select(v[i] > 0, _NEVER, _select(v[i] < 0, -_NEVER, 0.0))
        out.append(_select(ca.fabs(v[i]) < ca.inf, v[i], overflow))
    return ca.vertcat(*out)


def _table_lookup(k: ca.SX, table: np.ndarray) -> ca.SX:
    """``table[k − 1]`` for an integer-valued SX ``k`` in ``1..len(table)`` (a sum of exact one-hot terms)."""
    out = ca.SX(0)
    for i, val in enumerate(table):
        out = out + _select(k == i + 1, float(val), 0.0)
    return out


# --------------------------------------------------------------------------- design


@dataclass(frozen=True, eq=False)
class NafdfDesign:
    """A designed NAFDF: the plant, the settings, the WSSR thresholds and the step Function."""

    name: str
    plant: NonlinearPlant
    settings: NafdfSettings
    thresholds: np.ndarray
    """WSSR threshold on ``L`` for ``1..N`` samples in the window."""
    step: ca.Function
    layout: StateLayout
    certificate: Certificate
    r_names: tuple[str, ...] = field(default=())
    J_names: tuple[str, ...] = field(default=())

    @property
    def fault_names(self) -> tuple[str, ...]:
        """One fault per parameter: ``isolated = i`` names ``parameters[i]``."""
        return self.plant.parameters

    @property
    def nstate(self) -> int:
        return self.layout.size

    def init_state(self) -> np.ndarray:
        """The state of a freshly (re-)initialised diagnoser (the C side's ``_init``)."""
        return _init_state(self.plant, self.settings, self.layout)

    def unpack_state(self, state: object) -> dict[str, np.ndarray | float]:
        return self.layout.unpack(state)

    def pack_state(self, blocks: Mapping[str, object]) -> np.ndarray:
        return self.layout.pack(blocks)

    def run(self, *, u: object, y: object, state: object | None = None) -> dict[str, np.ndarray]:
        """Run the step over a whole record in one CasADi call (``mapaccum``).

        ``u``: ``(T, m)``, ``y``: ``(T, p)``. Returns the per-sample outputs as
        arrays with time along axis 0: ``state`` ``(T, nstate)`` (after each
        step), ``r``, ``J``, ``alarm``, ``isolated``, ``status``.
        """
        uu = np.asarray(u, dtype=float).reshape(-1, self.plant.m) if self.plant.m else np.zeros((np.asarray(y).shape[0], 0))
        yy = np.asarray(y, dtype=float).reshape(-1, self.plant.p)
        if uu.shape[0] != yy.shape[0]:
            raise ShapeError(f"u has {uu.shape[0]} samples and y has {yy.shape[0]}; expected equal lengths")
        s0 = self.init_state() if state is None else np.asarray(state, dtype=float).reshape(-1)
        T = yy.shape[0]
        out = self.step.mapaccum(T)(s0, uu.T, yy.T)
        names = ["state", "r", "J", "alarm", "isolated", "status"]
        res = {k: np.array(v, dtype=float).T for k, v in zip(names, out, strict=False)}
        for k in ("alarm", "isolated", "status"):
            res[k] = res[k].reshape(-1)
        return res


def nafdf(
    plant: NonlinearPlant,
    *,
    x0: object,
    P0: object,
    theta0: object | None = None,
    R0: object | None = None,
    window: int = 10,
    threshold_rule: Literal["chi2", "beta0"] = "chi2",
    false_alarm_probability: float = 0.01,
    beta0: float | None = None,
    forgetting_initial: float = 0.95,
    forgetting_rate: float = 0.99,
    forgetting_final: float = 0.99,
    theta_lower: object | None = None,
    theta_upper: object | None = None,
    nominal_samples: int = 200,
    classifier_window: int = 50,
    W1: float = 50.0,
    W2: float = 350.0,
    T1: int = 50,
    convergence_tolerance: object | None = None,
    convergence_level: float = 1e-3,
    u0: object | None = None,
    name: str = "nafdf",
) -> NafdfDesign:
    """Design the NAFDF of Zhou, Xi & Zhang 1991 (fig. 1, eqs. (2.3)–(2.8)) for ``plant``.

    Defaults: ``θ̂(0) = θ0`` (nominal), ``R(0) = I``, the paper's ``W1 = 50``,
    ``W2 = 350``, ``T1 = 50``; ``convergence_tolerance`` 5 % of ``|θ0_i|``
    (0.05 for a zero nominal) — set it to about twice the standard deviation
    of the converged estimate, which depends on the noise and the input;
    ``u0`` (the nominal input) zero. Every setting is validated and the
    sizes are held to the module's limits before anything is built. The
    model must be finite, with its Jacobians, at ``(x0, u0)`` for the nominal
    ``θ`` (the EKF's start) and for ``θ̂(0)`` (the NF's start). The returned
    design carries a certificate (AD Jacobians against central differences at
    ``x0``, a first step from the initial state that neither diverges nor
    skips, positive thresholds) and refuses to exist if it fails.
    """
    settings = _settings(
        plant,
        x0=x0,
        P0=P0,
        theta0=theta0,
        R0=R0,
        window=window,
        threshold_rule=threshold_rule,
        false_alarm_probability=false_alarm_probability,
        beta0=beta0,
        forgetting_initial=forgetting_initial,
        forgetting_rate=forgetting_rate,
        forgetting_final=forgetting_final,
        theta_lower=theta_lower,
        theta_upper=theta_upper,
        nominal_samples=nominal_samples,
        classifier_window=classifier_window,
        W1=W1,
        W2=W2,
        T1=T1,
        convergence_tolerance=convergence_tolerance,
        convergence_level=convergence_level,
        u0=u0,
    )
    if not isinstance(name, str) or not _IDENT.fullmatch(name) or len(name) > _MAX_NAME:
        raise SpecError(f"name must be an identifier of at most {_MAX_NAME} characters; got {short_repr(name)}")
    return _design(plant, settings, name=name)


def _check_sizes(plant: NonlinearPlant, window: int, classifier_window: int) -> None:
    """The limits that need no step: dimensions and state size (module docstring)."""
    for what, count in (("states", plant.n), ("inputs", plant.m), ("outputs", plant.p), ("parameters", plant.l)):
        if count > MAX_DIMENSION:
            raise SpecError(f"the plant has {count} {what}; the NAFDF allows at most {MAX_DIMENSION}")
    size = _layout(plant.n, plant.l, window, classifier_window).size
    if size > MAX_STATE:
        raise SpecError(
            f"the diagnoser state would have {size} entries (window {window}, classifier_window {classifier_window}, "
            f"{plant.n} states, {plant.l} parameters); at most {MAX_STATE} are allowed"
        )


def _settings(plant: NonlinearPlant, **kw: Any) -> NafdfSettings:
    """Validate the keywords of :func:`nafdf` (also applied to a gain file's stored settings).

    Sizes first (windows, counters, dimensions, state size), then every
    vector and matrix: shapes, finiteness, definiteness, ranges, the box.
    Raises :class:`SpecError` or :class:`ShapeError` naming the setting.
    """
    n, m, l = plant.n, plant.m, plant.l  # noqa: E741 — the paper's letter for dim θ
    window = _positive_int(kw["window"], "window", MAX_WINDOW)
    n2 = _positive_int(kw["classifier_window"], "classifier_window", MAX_CLASSIFIER_WINDOW)
    _check_sizes(plant, window, n2)
    th_nom = np.asarray(plant.theta_nominal)
    rule = kw["threshold_rule"]
    if rule not in ("chi2", "beta0"):
        raise SpecError(f"threshold_rule must be 'chi2' or 'beta0'; got {short_repr(rule)}")
    lo = np.full(l, -np.inf) if kw["theta_lower"] is None else _vec(kw["theta_lower"], "theta_lower", l)
    hi = np.full(l, np.inf) if kw["theta_upper"] is None else _vec(kw["theta_upper"], "theta_upper", l)
    if np.any(np.isnan(lo)) or np.any(np.isnan(hi)) or np.any(lo >= hi) or np.any(lo == np.inf) or np.any(hi == -np.inf):
        raise SpecError(f"theta_lower must be below theta_upper for every parameter; got {short_repr(lo.tolist())} and {short_repr(hi.tolist())}")
    tol = (
        np.where(th_nom != 0.0, 0.05 * np.abs(th_nom), 0.05)
        if kw["convergence_tolerance"] is None
        else _vec(kw["convergence_tolerance"], "convergence_tolerance", l)
    )
    if np.any(~np.isfinite(tol)) or np.any(tol <= 0):
        raise SpecError(f"convergence_tolerance must be positive and finite; got {short_repr(tol.tolist())}")
    th0 = th_nom.copy() if kw["theta0"] is None else _finite_vec(kw["theta0"], "theta0", l)
    beta0 = None if kw["beta0"] is None else _number(kw["beta0"], "beta0")
    if beta0 is not None and not (math.isfinite(beta0) and beta0 > 0):
        raise SpecError(f"beta0 must be a positive finite number; got {short_repr(kw['beta0'])}")
    settings = NafdfSettings(
        x0=_ro(_finite_vec(kw["x0"], "x0", n)),
        P0=_ro(_spd(kw["P0"], "P0", n)),
        theta0=_ro(th0),
        R0=_ro(_spd(np.eye(l) if kw["R0"] is None else kw["R0"], "R0", l)),
        window=window,
        threshold_rule=rule,
        false_alarm_probability=_unit_open(kw["false_alarm_probability"], "false_alarm_probability"),
        beta0=beta0,
        forgetting_initial=_unit_interval(kw["forgetting_initial"], "forgetting_initial"),
        forgetting_rate=_unit_open(kw["forgetting_rate"], "forgetting_rate"),
        forgetting_final=_unit_interval(kw["forgetting_final"], "forgetting_final"),
        theta_lower=_ro(lo),
        theta_upper=_ro(hi),
        nominal_samples=_positive_int(kw["nominal_samples"], "nominal_samples"),
        classifier_window=n2,
        W1=_number(kw["W1"], "W1"),
        W2=_number(kw["W2"], "W2"),
        T1=_positive_int(kw["T1"], "T1"),
        convergence_tolerance=_ro(tol),
        convergence_level=_unit_open(kw["convergence_level"], "convergence_level"),
        u0=_ro(np.zeros(m) if kw["u0"] is None else _finite_vec(kw["u0"], "u0", m)),
    )
    if not 0.0 <= settings.W1 < settings.W2 or not math.isfinite(settings.W2):
        raise SpecError(f"the classifier thresholds must satisfy 0 <= W1 < W2 < inf; got W1 = {kw['W1']}, W2 = {kw['W2']}")
    if np.any(settings.theta0 < lo) or np.any(settings.theta0 > hi):
        raise SpecError(
            f"theta0 = {short_repr(settings.theta0.tolist())} lies outside the parameter box "
            f"[{short_repr(lo.tolist())}, {short_repr(hi.tolist())}]"
        )
    return settings


def _unit_interval(value: float, name: str) -> float:
    v = _number(value, name)
    if not 0.0 < v <= 1.0:
        raise SpecError(f"{name} must lie in (0, 1]; got {short_repr(value)}")
    return v


def _names_r_J(plant: NonlinearPlant) -> tuple[tuple[str, ...], tuple[str, ...]]:
    r = tuple(f"ekf_innovation_{y}" for y in plant.outputs) + tuple(f"nf_innovation_{y}" for y in plant.outputs)
    par = plant.parameters
    J = (
        ("wssr", "wssr_threshold", "ekf_nis")
        + tuple(f"theta_hat_{q}" for q in par)
        + tuple(f"d_{q}" for q in par)
        + tuple(f"fault_class_{q}" for q in par)
        + tuple(f"fault_size_{q}" for q in par)
        + ("nf_converged", "diverged")
    )
    return r, J


def _design(plant: NonlinearPlant, settings: NafdfSettings, *, name: str, thresholds: np.ndarray | None = None) -> NafdfDesign:
    """Check the model at the filters' starting points, build the step within the limits, certify."""
    _check_model_finite(plant, settings)
    thr = (
        wssr_threshold_table(
            window=settings.window,
            n_outputs=plant.p,
            rule=settings.threshold_rule,
            false_alarm_probability=settings.false_alarm_probability,
            beta0=settings.beta0,
        )
        if thresholds is None
        else np.asarray(thresholds, dtype=float)
    )
    step, layout = _build_step(plant, settings, thr, name)
    _check_step_size(step, layout)
    r_names, J_names = _names_r_J(plant)
    draft = NafdfDesign(
        name=name,
        plant=plant,
        settings=settings,
        thresholds=_ro(thr),
        step=step,
        layout=layout,
        certificate=Certificate.of(name, []),
        r_names=r_names,
        J_names=J_names,
    )
    cert = _certify(draft)
    return NafdfDesign(**{**draft.__dict__, "certificate": cert})


def _check_model_finite(plant: NonlinearPlant, s: NafdfSettings) -> None:
    """The model and its Jacobians are finite where the filters start: ``(x0, u0)`` with the nominal
    ``θ`` (the EKF) and with ``θ̂(0)`` (the NF). Raises :class:`SpecError` naming the expression."""
    where = f"x0 = {short_repr(s.x0.tolist())}, u0 = {short_repr(s.u0.tolist())}"
    nominal = dict(zip(plant.parameters, plant.theta_nominal.tolist(), strict=True))
    plant.check_finite(x=s.x0, u=s.u0, theta=plant.theta_nominal, point=f"the EKF's start ({where}, nominal θ = {short_repr(nominal)})")
    if not np.array_equal(s.theta0, plant.theta_nominal):
        start = dict(zip(plant.parameters, s.theta0.tolist(), strict=True))
        plant.check_finite(x=s.x0, u=s.u0, theta=s.theta0, point=f"the NF's start ({where}, theta0 = {short_repr(start)})")


def _check_step_size(step: ca.Function, layout: StateLayout) -> None:
    """:data:`MAX_STEP_INSTRUCTIONS` and :data:`MAX_STEP_WORK`, on the SX graph, before any C exists."""
    count, work = int(step.n_instructions()), int(step.sz_w())
    if count > MAX_STEP_INSTRUCTIONS:
        raise SpecError(
            f"the NAFDF step has {count} operations; at most {MAX_STEP_INSTRUCTIONS} are allowed "
            "(the generated C would take too long to compile): reduce window, classifier_window, "
            "the number of states or parameters, or the size of the model"
        )
    if work > MAX_STEP_WORK:
        raise SpecError(
            f"the NAFDF step needs {work} doubles of work memory; at most {MAX_STEP_WORK} are allowed "
            f"(they are locals of the generated C step, on its stack with the {layout.size}-entry state)"
        )


def _init_state(plant: NonlinearPlant, s: NafdfSettings, layout: StateLayout) -> np.ndarray:
    """The state of a freshly (re-)initialised diagnoser, from the plant and the settings alone."""
    n, l = plant.n, plant.l  # noqa: E741 — the paper's letter for dim θ
    blocks: dict[str, object] = {
        "ekf_x": s.x0,
        "ekf_P": s.P0,
        "ekf_theta": plant.theta_nominal,
        "wssr_buffer": np.zeros(s.window),
        "wssr_count": 0.0,
        "nf_x": s.x0,
        "nf_P": s.P0,
        "nf_theta": s.theta0,
        "nf_R": s.R0,
        "nf_W": np.zeros((n, l)),
        "nf_gain": 1.0,
        "nf_forgetting": s.forgetting_initial,
        "nf_age": 0.0,
        "nf_converged": 0.0,
        "theta_window": np.zeros((l, s.classifier_window)),
        "nis_window": np.zeros(s.classifier_window),
        "nominal_count": 0.0,
        "nominal_mean": np.zeros(l),
        "nominal_m2": np.zeros(l),
        "nominal_frozen": 0.0,
        "count_w1": np.zeros(l),
        "count_w2": np.zeros(l),
        "fault_class": np.zeros(l),
        "fault_size": np.zeros(l),
        "isolated": -1.0,
        "episode_open": 0.0,
        "diagnosis_left": 0.0,
    }
    for c in ("samples", "skipped", "alarm_resets", "ekf_reparameterisations", "ekf_divergence_resets", "nf_divergence_resets"):
        blocks[c] = 0.0
    return layout.pack(blocks)


def _certify(design: NafdfDesign) -> Certificate:
    """AD against central differences, a first step that neither diverges nor skips, positive thresholds.

    Every aggregate goes through :func:`~fdisyn.design.certificate.worst`, so a
    NaN anywhere in the comparison makes the check fail instead of vanishing
    inside ``max``.
    """
    pl, s = design.plant, design.settings
    u0 = s.u0
    lin = pl.linearise(x=s.x0, u=u0, theta=pl.theta_nominal)
    fd = _central_difference_jacobians(pl, s.x0, u0, pl.theta_nominal)
    gaps = []
    for key in ("F_x", "F_theta", "H_x", "H_theta"):
        scale = worst(1.0, float(np.max(np.abs(lin[key]), initial=0.0)))
        gaps.append(float(np.max(np.abs(lin[key] - fd[key]), initial=0.0)) / scale)
    gap = worst(*gaps)
    st0 = design.init_state()
    outs = [np.asarray(o, dtype=float) for o in design.step(st0, u0, np.asarray(pl.h(s.x0, pl.theta_nominal)).reshape(-1))]
    diverged = float(outs[2].reshape(-1)[list(design.J_names).index("diverged")])
    first_ok = all(np.all(np.isfinite(o)) for o in outs) and diverged == 0.0 and float(outs[5].reshape(-1)[0]) == 0.0
    thr = design.thresholds
    checks = [
        Check(
            "AD Jacobians vs central differences at x0 (max relative)",
            gap,
            1e-6,
            "<=",
            "central differences with a step of 1e-6 relative are accurate to ~1e-9 times the third derivative; "
            "a larger gap means the AD graph is not the model",
        ),
        Check(
            "first step from the initial state on h(x0): finite, not diverged, not skipped",
            1.0 if first_ok else 0.0,
            1.0,
            ">=",
            "the filters start there; a step that diverges or skips at its own starting point would reset on every sample",
        ),
        Check(
            "WSSR thresholds positive",
            float(np.min(thr)),
            float(np.finfo(float).tiny),
            ">=",
            "a χ² quantile (or β0) is positive; zero would alarm on every sample",
        ),
    ]
    info = {
        "n_state": design.layout.size,
        "n_instructions": int(design.step.n_instructions()),
        "work_doubles": int(design.step.sz_w()),
        "wssr_threshold_full_window": float(thr[-1]),
    }
    return Certificate.of(design.name, checks, info).require()


def _central_difference_jacobians(pl: NonlinearPlant, x: np.ndarray, u: np.ndarray, th: np.ndarray) -> dict[str, np.ndarray]:
    """Central differences of ``f`` and ``h`` (for certificates and tests only, never for the filter)."""

    def fx(xx: np.ndarray, tt: np.ndarray) -> np.ndarray:
        return np.asarray(pl.f(xx, u, tt), dtype=float).reshape(-1)

    def hx(xx: np.ndarray, tt: np.ndarray) -> np.ndarray:
        return np.asarray(pl.h(xx, tt), dtype=float).reshape(-1)

    def jac(fun, a: np.ndarray, other: np.ndarray, wrt_first: bool) -> np.ndarray:  # type: ignore[no-untyped-def]
        cols = []
        for k in range(a.size):
            step = 1e-6 * max(1.0, abs(a[k]))
            e = np.zeros_like(a)
            e[k] = step
            if wrt_first:
                cols.append((fun(a + e, other) - fun(a - e, other)) / (2 * step))
            else:
                cols.append((fun(other, a + e) - fun(other, a - e)) / (2 * step))
        return np.array(cols).T

    return {
        "F_x": jac(fx, x, th, True),
        "F_theta": jac(fx, th, x, False),
        "H_x": jac(hx, x, th, True),
        "H_theta": jac(hx, th, x, False),
    }


# --------------------------------------------------------------------------- payload


def nafdf_payload(design: NafdfDesign) -> dict[str, object]:
    """A JSON-able description from which :func:`step_from_payload` rebuilds the identical step.

    The model is stored as data: ``f`` and ``h`` as
    :func:`~fdisyn.design.nonlinear.model_program` operation lists (exact:
    CasADi's own operation sequence, constants to the bit), which the reader
    validates entry by entry before building anything. Expression strings,
    when the plant came from them, are kept alongside for people to read; the
    reader re-parses them and refuses a file where they describe another
    model. The WSSR threshold table is stored as numbers (and checked
    against its rule on reading), so the rebuilt step is bit for bit the
    designed one. CasADi's version is recorded for provenance only.
    """
    pl, s = design.plant, design.settings
    return {
        "format": PAYLOAD_FORMAT,
        "version": PAYLOAD_VERSION,
        "name": design.name,
        "casadi_version": ca.CasadiMeta.version(),
        "plant": {
            "states": list(pl.states),
            "inputs": list(pl.inputs),
            "outputs": list(pl.outputs),
            "parameters": list(pl.parameters),
            "theta_nominal": [float(v) for v in pl.theta_nominal],
            "Q1": np.asarray(pl.Q1).tolist(),
            "Q2": np.asarray(pl.Q2).tolist(),
            "Ts": pl.Ts,
            "f": model_program(pl.f),
            "h": model_program(pl.h),
            "expressions": None if pl.expressions is None else json.loads(json.dumps(pl.expressions)),
            "units": dict(pl.units),
        },
        "settings": s.to_dict(),
        "wssr_thresholds": [float(v) for v in design.thresholds],
        "state_layout": [[nm, r, c] for nm, r, c in design.layout.entries],
        "init_state": [float(v) for v in design.init_state()],
        "r_names": list(design.r_names),
        "J_names": list(design.J_names),
        "fault_names": list(design.fault_names),
        "certificate": design.certificate.to_dict(),
    }


_PAYLOAD_FIELDS = frozenset(
    {
        "format",
        "version",
        "name",
        "casadi_version",
        "plant",
        "settings",
        "wssr_thresholds",
        "state_layout",
        "init_state",
        "r_names",
        "J_names",
        "fault_names",
        "certificate",
    }
)
_PLANT_FIELDS = frozenset(
    {"states", "inputs", "outputs", "parameters", "theta_nominal", "Q1", "Q2", "Ts", "f", "h", "expressions", "units"}
)
_SETTINGS_FIELDS = tuple(NafdfSettings.__dataclass_fields__)
# The WSSR table is recomputed on reading and compared at this relative tolerance: SciPy's χ² quantile is
# accurate to ~1e-14, so another SciPy version passes while any edit of the stored numbers is refused.
_TABLE_RTOL = 1e-9


class _Fields:
    """Typed access to one JSON object of a payload; every failure names the field (one line)."""

    def __init__(self, doc: object, where: str, *, required: frozenset[str] | tuple[str, ...], optional: frozenset[str] = frozenset()) -> None:
        if not isinstance(doc, Mapping):
            raise GainFileError(f"{where} must be an object; found {type(doc).__name__}")
        missing = sorted(set(required) - set(doc))
        unknown = sorted(str(k) for k in set(doc) - set(required) - set(optional))
        if missing or unknown:
            raise GainFileError(f"{where}: missing field(s) {missing}, unknown field(s) {short_repr(unknown)}")
        self.doc, self.where = doc, where

    def fail(self, key: str, expected: str) -> GainFileError:
        return GainFileError(f"{self.where}.{key} must be {expected}; found {short_repr(self.doc.get(key))}")

    def string(self, key: str) -> str:
        v = self.doc[key]
        if not isinstance(v, str):
            raise self.fail(key, "a string")
        return v

    def integer(self, key: str) -> int:
        v = self.doc[key]
        if isinstance(v, bool) or not isinstance(v, int):
            raise self.fail(key, "an integer")
        return v

    def number(self, key: str, *, allow_none: bool = False) -> float | None:
        v = self.doc[key]
        if v is None and allow_none:
            return None
        return _json_number(v, f"{self.where}.{key}")

    def numbers(self, key: str, size: int, *, allow_none: bool = False) -> np.ndarray:
        """A list of ``size`` finite numbers (``null`` → ±inf for the parameter box's open sides)."""
        v = self.doc[key]
        if not isinstance(v, list) or len(v) != size:
            raise self.fail(key, f"a list of {size} numbers")
        return np.array([np.nan if z is None and allow_none else _json_number(z, f"{self.where}.{key}") for z in v], dtype=float)

    def matrix(self, key: str, rows: int, cols: int) -> np.ndarray:
        v = self.doc[key]
        if not isinstance(v, list) or len(v) != rows or not all(isinstance(r, list) and len(r) == cols for r in v):
            raise self.fail(key, f"a {rows}×{cols} matrix (a list of {rows} rows of {cols} numbers)")
        return np.array([[_json_number(z, f"{self.where}.{key}") for z in r] for r in v], dtype=float).reshape(rows, cols)

    def names(self, key: str, *, allow_empty: bool = False) -> tuple[str, ...]:
        v = self.doc[key]
        if not isinstance(v, list) or not all(isinstance(z, str) for z in v):
            raise self.fail(key, "a list of names")
        if len(v) > MAX_DIMENSION or (not v and not allow_empty):
            raise self.fail(key, f"a list of 1 to {MAX_DIMENSION} names")
        bad = [z for z in v if not _IDENT.fullmatch(z) or len(z) > _MAX_NAME]
        if bad or len(set(v)) != len(v):
            raise self.fail(key, f"a list of distinct identifiers of at most {_MAX_NAME} characters")
        return tuple(v)


def _json_number(v: object, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise GainFileError(f"{where} must hold numbers; found {short_repr(v)}")
    try:
        out = float(v)
    except OverflowError:
        out = math.inf
    if not math.isfinite(out):
        raise GainFileError(f"{where} must hold finite numbers; found {short_repr(v)}")
    return out


@dataclass(frozen=True, eq=False)
class _Payload:
    """A validated payload: everything the step is built from, nothing built yet."""

    name: str
    plant: NonlinearPlant
    settings: NafdfSettings
    thresholds: np.ndarray
    layout: StateLayout
    fixed_thresholds: list[float | None] | None


def _wrap(where: str, fn: Any, *args: Any, **kw: Any) -> Any:
    """Call ``fn``; an fdisyn error it raises becomes a :class:`GainFileError` prefixed by ``where``."""
    try:
        return fn(*args, **kw)
    except GainFileError:
        raise
    except FdisynError as exc:
        raise GainFileError(f"{where}: {exc}") from None


def _read_plant(doc: object, where: str) -> NonlinearPlant:
    """The plant of a payload: sizes first, then the model programs, then the plant's own checks."""
    f = _Fields(doc, where, required=_PLANT_FIELDS)
    states, outputs, parameters = f.names("states"), f.names("outputs"), f.names("parameters")
    inputs = f.names("inputs", allow_empty=True)
    n, m, p, l = len(states), len(inputs), len(outputs), len(parameters)
    theta = f.numbers("theta_nominal", l)
    q1, q2 = f.matrix("Q1", n, n), f.matrix("Q2", p, p)
    ts = f.number("Ts", allow_none=True)
    if ts is not None:
        _wrap(f"{where}.Ts", check_sample_time, ts)
    units = f.doc["units"]
    if not isinstance(units, Mapping) or len(units) > 4 * MAX_DIMENSION or not all(
        isinstance(k, str) and isinstance(v, str) and len(k) <= _MAX_NAME and len(v) <= _MAX_NAME for k, v in units.items()
    ):
        raise f.fail("units", f"an object of at most {4 * MAX_DIMENSION} short names and unit strings")
    programs = {
        "f": _wrap(f"{where}.f", function_from_program, f.doc["f"], name="f", in_names=("x", "u", "theta"), in_sizes=(n, m, l), out_name="x_next", out_size=n),
        "h": _wrap(f"{where}.h", function_from_program, f.doc["h"], name="h", in_names=("x", "theta"), in_sizes=(n, l), out_name="y", out_size=p),
    }
    common = dict(
        states=states, inputs=inputs, outputs=outputs, parameters=parameters, nominal=dict(zip(parameters, theta.tolist(), strict=True)),
        Q1=q1, Q2=q2, Ts=ts, units=dict(units),
    )
    expressions = f.doc["expressions"]
    e = None if expressions is None else _Fields(expressions, f"{where}.expressions", required=frozenset({"f", "h", "constants"}))
    plant = _wrap(where, NonlinearPlant.create, f=programs["f"], h=programs["h"], expressions=expressions, **common)
    if e is not None:
        text = _wrap(f"{where}.expressions", NonlinearPlant.from_expressions, f=e.doc["f"], h=e.doc["h"], constants=e.doc["constants"], **common)
        for key in ("f", "h"):
            if model_program(getattr(text, key)) != model_program(getattr(plant, key)):
                raise GainFileError(f"{where}.expressions.{key} describe another model than {where}.{key}; the file was edited")
    return plant


def _read_payload(payload: object, where: str, *, gain_file: bool) -> _Payload:
    """Validate every field of a payload (and nothing built but the model's SX graph)."""
    optional = frozenset() if gain_file else frozenset({"thresholds"})
    required = _PAYLOAD_FIELDS | ({"thresholds"} if gain_file else frozenset())
    if isinstance(payload, Mapping) and payload.get("format") != PAYLOAD_FORMAT:
        raise GainFileError(f"{where}: payload format is {short_repr(payload.get('format'))}; expected {PAYLOAD_FORMAT!r}")
    if isinstance(payload, Mapping) and payload.get("version") != PAYLOAD_VERSION:
        raise GainFileError(
            f"{where}: payload version is {short_repr(payload.get('version'))}; this fdisyn reads version {PAYLOAD_VERSION} "
            "(the model as validated operation lists, not CasADi serialised strings): design it again"
        )
    top = _Fields(payload, where, required=frozenset(required), optional=optional)
    name = top.string("name")
    if not _IDENT.fullmatch(name) or len(name) > _MAX_NAME:
        raise top.fail("name", f"an identifier of at most {_MAX_NAME} characters")
    top.string("casadi_version")
    plant = _read_plant(top.doc["plant"], f"{where}.plant")
    n, m, l = plant.n, plant.m, plant.l  # noqa: E741 — the paper's letter for dim θ

    sf = _Fields(top.doc["settings"], f"{where}.settings", required=_SETTINGS_FIELDS)
    raw: dict[str, Any] = {
        "x0": sf.numbers("x0", n),
        "P0": sf.matrix("P0", n, n),
        "theta0": sf.numbers("theta0", l),
        "R0": sf.matrix("R0", l, l),
        "window": sf.integer("window"),
        "threshold_rule": sf.string("threshold_rule"),
        "false_alarm_probability": sf.number("false_alarm_probability"),
        "beta0": sf.number("beta0", allow_none=True),
        "forgetting_initial": sf.number("forgetting_initial"),
        "forgetting_rate": sf.number("forgetting_rate"),
        "forgetting_final": sf.number("forgetting_final"),
        "theta_lower": np.nan_to_num(sf.numbers("theta_lower", l, allow_none=True), nan=-np.inf),
        "theta_upper": np.nan_to_num(sf.numbers("theta_upper", l, allow_none=True), nan=np.inf),
        "nominal_samples": sf.integer("nominal_samples"),
        "classifier_window": sf.integer("classifier_window"),
        "W1": sf.number("W1"),
        "W2": sf.number("W2"),
        "T1": sf.integer("T1"),
        "convergence_tolerance": sf.numbers("convergence_tolerance", l),
        "convergence_level": sf.number("convergence_level"),
        "u0": sf.numbers("u0", m),
    }
    settings: NafdfSettings = _wrap(f"{where}.settings", _settings, plant, **raw)

    table = top.numbers("wssr_thresholds", settings.window)
    truth = _wrap(
        f"{where}.settings",
        wssr_threshold_table,
        window=settings.window,
        n_outputs=plant.p,
        rule=settings.threshold_rule,
        false_alarm_probability=settings.false_alarm_probability,
        beta0=settings.beta0,
    )
    if not np.allclose(table, truth, rtol=_TABLE_RTOL, atol=0.0):
        k = int(np.argmax(np.abs(table - truth) > _TABLE_RTOL * np.abs(truth)))
        raise GainFileError(
            f"{where}.wssr_thresholds[{k}] is {float(table[k])!r}; the settings (rule {settings.threshold_rule!r}, "
            f"P_f {settings.false_alarm_probability!r}, window {settings.window}) give {float(truth[k])!r}"
        )
    layout = _layout(n, l, settings.window, settings.classifier_window)
    if top.doc["state_layout"] != [[nm, r, c] for nm, r, c in layout.entries]:
        raise GainFileError(f"{where}.state_layout does not match the layout the settings imply ({layout.size} entries)")
    init = top.numbers("init_state", layout.size)
    expected = _init_state(plant, settings, layout)
    if not np.array_equal(init, expected):
        k = int(np.argmax(init != expected))
        raise GainFileError(
            f"{where}.init_state[{k}] ({layout.component_names()[k]}) is {float(init[k])!r}; the settings give {float(expected[k])!r}"
        )
    r_names, J_names = _names_r_J(plant)
    for key, want in (("r_names", r_names), ("J_names", J_names), ("fault_names", plant.parameters)):
        if top.doc[key] != list(want):
            raise GainFileError(f"{where}.{key} is {short_repr(top.doc[key])}; the plant implies {short_repr(list(want))}")
    cert = top.doc["certificate"]
    if not isinstance(cert, Mapping) or cert.get("passed") is not True:
        raise GainFileError(f"{where}.certificate did not pass (passed = {short_repr(cert.get('passed') if isinstance(cert, Mapping) else cert)}); a design that failed its verification is not built")
    fixed = None
    if "thresholds" in top.doc:
        fixed = _fixed_thresholds(J_names, plant, table, settings.W1)
        if top.doc["thresholds"] != fixed:
            raise GainFileError(
                f"{where}.thresholds is {short_repr(top.doc['thresholds'])}; expected {len(J_names)} entries "
                "(the full-window WSSR threshold on wssr, W1 on each d_θ, null elsewhere)"
            )
    return _Payload(name=name, plant=plant, settings=settings, thresholds=table, layout=layout, fixed_thresholds=fixed)


def _fixed_thresholds(J_names: tuple[str, ...], plant: NonlinearPlant, table: np.ndarray, W1: float) -> list[float | None]:
    """The alarm threshold per statistic the C API exports: WSSR on ``wssr``, ``W1`` on each ``d_θ``."""
    fixed = {"wssr": float(table[-1])} | {f"d_{q}": float(W1) for q in plant.parameters}
    return [fixed.get(j) for j in J_names]


def _build(parsed: _Payload, where: str) -> NafdfDesign:
    """Build and re-certify a validated payload's design (limits and model checks included)."""
    design = _wrap(where, _design, parsed.plant, parsed.settings, name=parsed.name, thresholds=parsed.thresholds)
    if design.layout.entries != parsed.layout.entries:  # the step's own layout: a guard on _build_step itself
        raise GainFileError(f"{where}: the rebuilt step's state layout differs from the payload's")
    return design


def nafdf_from_payload(payload: Mapping[str, object]) -> NafdfDesign:
    """Rebuild the design (plant, settings, step) from :func:`nafdf_payload`'s output alone.

    Every field is validated before the step is built (module docstring);
    the design is then re-certified. Raises :class:`GainFileError` naming the
    field, with what it holds and what was expected.
    """
    return _build(_read_payload(payload, "payload", gain_file=False), "payload")


def nafdf_from_gain_file(gf: GainFile) -> NafdfDesign:
    """The design of a ``kind = "nafdf"`` gain file, validated against the whole file.

    Beyond :func:`nafdf_from_payload`: the file's certificate must have
    passed, and its inputs, outputs, faults, sample time, step sizes, names,
    initial state and exported thresholds must be the ones the payload
    implies (a ``faults`` list that disagrees, an all-zero ``init_state`` or
    a short ``thresholds`` list is refused, not compiled).
    """
    where = "extensions.nafdf"
    if not isinstance(gf.certificate, Mapping) or gf.certificate.get("passed") is not True:
        passed = gf.certificate.get("passed") if isinstance(gf.certificate, Mapping) else None
        raise GainFileError(f"certificate.passed is {short_repr(passed)}; a design that failed its verification is not built")
    parsed = _read_payload(gf.extensions.get("nafdf"), where, gain_file=True)
    pl = parsed.plant
    r_names, J_names = _names_r_J(pl)
    init = _init_state(pl, parsed.settings, parsed.layout)
    st = gf.step
    for field_name, found, want in (
        ("inputs", gf.inputs, pl.inputs),
        ("outputs", gf.outputs, pl.outputs),
        ("faults", gf.faults, pl.parameters),
        ("Ts", gf.Ts, float(pl.Ts) if pl.Ts else 1.0),
        ("step.nu", st.nu, pl.m),
        ("step.ny", st.ny, pl.p),
        ("step.nr", st.nr, len(r_names)),
        ("step.nj", st.nj, len(J_names)),
        ("step.nstate", st.nstate, parsed.layout.size),
        ("step.residual_names", st.residual_names, r_names),
        ("step.statistic_names", st.statistic_names, J_names),
    ):
        if found != want:
            raise GainFileError(f"{field_name} is {short_repr(found)}; {where} implies {short_repr(want)}")
    if not np.array_equal(st.init_state, init):
        k = int(np.argmax(st.init_state != init))
        raise GainFileError(
            f"step.init_state[{k}] ({parsed.layout.component_names()[k]}) is {float(st.init_state[k])!r}; {where} implies {float(init[k])!r}"
        )
    return _build(parsed, where)


def step_from_payload(payload: Mapping[str, object]) -> ca.Function:
    """The step Function rebuilt from a payload (identical graph to the designed one)."""
    return nafdf_from_payload(payload).step


# --------------------------------------------------------------------------- gain file


def nafdf_gain_file(
    design: NafdfDesign, *, problem: str, design_name: str = "nafdf", name: str | None = None, options: Mapping[str, object] | None = None
) -> GainFile:
    """The gain file (kind ``"nafdf"``) of a design: the common fields plus the payload.

    ``extensions["nafdf"]`` holds :func:`nafdf_payload` and the fixed alarm
    thresholds per statistic (the full-window WSSR threshold on ``wssr``,
    ``W1`` on each Bayes distance ``d_θ``, none elsewhere). A model without a
    physical sample time uses ``Ts = 1`` (time counted in samples).
    """
    pl = design.plant
    payload = nafdf_payload(design)
    payload["thresholds"] = _fixed_thresholds(design.J_names, pl, design.thresholds, design.settings.W1)
    cert = design.certificate.to_dict()
    return GainFile(
        kind="nafdf",
        name=name or f"{problem}_{design_name}",
        problem=problem,
        design=design_name,
        Ts=float(pl.Ts) if pl.Ts else 1.0,
        inputs=tuple(pl.inputs),
        outputs=tuple(pl.outputs),
        faults=tuple(design.fault_names),
        step=StepSpec(
            nu=pl.m,
            ny=pl.p,
            nr=len(design.r_names),
            nj=len(design.J_names),
            nstate=design.nstate,
            init_state=design.init_state(),
            residual_names=tuple(design.r_names),
            statistic_names=tuple(design.J_names),
        ),
        certificate={"passed": bool(cert["passed"]), "nafdf": cert},
        provenance=provenance(options=dict(options or {})),
        extensions={"nafdf": payload},
    )


register_step_builder("nafdf", lambda gf: nafdf_from_gain_file(gf).step)


def nafdf_extra_metrics(scenario: Any, gf: GainFile, runs: Mapping[str, np.ndarray]) -> dict[str, float | None]:
    """Monte Carlo figures of a NAFDF beyond detection (a problem's ``extra_metrics``).

    ``scenario.params["fault_size"]`` maps each jumping parameter to its true
    jump ``θ_faulty − θ_0`` (absent or empty: fault-free). Fault-free: the
    fraction of runs with an isolation and alarm episodes per 10⁴ samples.
    Faulty: the fraction of runs whose latched parameter classes are exactly
    the jumping parameters, the median isolation delay in samples, and per
    jumping parameter the mean and standard deviation of the latched size
    estimate (2.8) minus the true jump, over the runs that classed it faulty.
    """
    names = list(gf.step.statistic_names)
    iso, alarm = runs["isolated"], runs["alarm"]
    last = runs["J"][:, -1, :]
    sizes = {str(q): float(v) for q, v in dict(scenario.params.get("fault_size") or {}).items()}
    if scenario.fault is None or not sizes:
        onsets = np.sum(np.diff(alarm, axis=1, prepend=0) > 0)
        return {
            "runs with an isolation": float(np.mean(np.any(iso >= 0, axis=1))),
            "alarm episodes per 10k samples": float(1e4 * onsets / alarm.size),
        }
    classes = np.stack([last[:, names.index(f"fault_class_{q}")] for q in gf.faults], axis=1)
    exact = np.all((classes > 0) == np.array([q in sizes for q in gf.faults])[None, :], axis=1)
    out: dict[str, float | None] = {"all parameter classes correct": float(np.mean(exact))}
    onset = int(round(float(scenario.onset or 0.0) / gf.Ts))
    found = [int(np.argmax(row[onset:] >= 0)) for row in iso if np.any(row[onset:] >= 0)]
    out["isolation delay median (samples)"] = float(np.median(found)) if found else None
    for q, true in sizes.items():
        sel = last[:, names.index(f"fault_class_{q}")] > 0
        err = last[sel, names.index(f"fault_size_{q}")] - true
        out[f"size error {q}: mean"] = float(err.mean()) if err.size else None
        out[f"size error {q}: sd"] = float(err.std(ddof=1)) if err.size > 1 else None
    return out

