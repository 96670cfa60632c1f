"""Nonlinear adaptive fault-detection filter, NAFDF (Zhou, Xi & Zhang 1991, fig. 1), as one CasADi step.

Zhou, Xi & Zhang, "Detection and diagnostics of parameter jump for a class of
nonlinear systems", Shanghai Jiao Tong University, c. 1991 (equation and
figure numbers below are theirs). The four blocks of their fig. 1 run inside
one CasADi ``Function``
``(state, u, y) → (state_next, r, J, alarm, isolated, status)``, the step
contract shared with every fdisyn diagnoser. It is pure SX with the LDLᵀ
factorisations unrolled by ``casadi.ldl`` (no linear-solver plugin), so it
code-generates to allocation-free C.

Block 1 — fast detection (eqs. (2.3)–(2.4)). An EKF on the model with
parameters ``θ_e`` (the nominal ``θ0`` until re-parameterised), in the
textbook filter form. The equations keep the paper's letters ``Q1``, ``Q2``
for the noise covariances, the plant's ``Q`` and ``R`` (``R(t)`` of block 2 is
the NF's own matrix). At sample ``t``

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

Beyond the paper, the fast detection is a choice (``detector``): the WSSR
above, or a sequential statistic on the normalised innovations
``w = D^{-1/2} U^{-T} γ`` (``V0 = Uᵀ D U`` from the same LDLᵀ; ``w ~ N(0, I_p)``
and ``‖w‖² = γᵀ V0⁻¹ γ``). ``"cusum"``: Page's CUSUM (Biometrika 41(1/2), 1954)
on each component and sign, ``S± = min(max(0, S± ± δ w_i − δ²/2), 2h)`` for the
designed shift ``δ = min_shift``, statistic ``max S``. ``"glr"``: the windowed
GLR (Willsky & Jones, IEEE TAC 21(1), 1976) of a constant shift of unknown
size on each component, ``max_{i, n ≤ M} d_i(n)² / (2n)`` over the onset sums
``d_i(n)`` of the last ``n`` samples, ``M = window``. Both restart on a
re-parameterisation, an EKF reset and a dismissal; their thresholds come from
the detector's false-alarm rate (:func:`detector_thresholds`).

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
stay latched until the caller re-initialises the diagnoser. Most jumps are
isolated before this classifier decides, from the NF's estimate itself
(block 4, "Isolation from the NF's estimate"), which latches the class and
size in the same outputs.

Block 4 — mutual re-initialisation.
* *The NF's own uncertainty.* With ``Ī(t) = R(t)/a(t)`` the recursion (2.5)
  reads ``Ī(t) = λ(t) Ī(t−1) + Φ S⁻¹ Φᵀ``, ``Ī(0) = R(0)`` (because
  ``(1 − a(t))/a(t) = λ(t)/a(t−1)``), and the step
  ``θ̂(t) = θ̂(t−1) + Ī(t)⁻¹ Φ S⁻¹ ε``: the recursive weighted least-squares
  (Gauss–Newton) estimate with forgetting of Ljung & Söderström (1983), whose
  information ``Ī`` is the exponentially weighted Fisher information of the
  innovations (``ε ~ N(0, S)`` with sensitivity ``Φᵀ``). So
  ``P_θ(t) = a(t) R(t)⁻¹ = Ī(t)⁻¹``, up to the innovation scale (``S`` is the
  model's innovation covariance; the innovation test below checks that
  scale). For a constant ``λ < 1`` and stationary ``Φ``,
  ``θ̂(t) − θ = Ī⁻¹ Σ_k λ^(t−k) Φ(k) S⁻¹ ν(k)`` (``ν`` the white innovations)
  gives

      Cov θ̂(t) = P_θ / (1 + λ),
      Cov[θ̂(t) − θ̂(t−N2)] = c P_θ,   c = 2 (1 − λ^N2) / (1 + λ),

  used with the NF's current ``λ(t)`` capped at ``1 − 1/age`` (``age``: NF
  updates since its (re)initialisation; with ``λ∞ = 1`` the estimate's memory
  is its age). ``σ_i² = (P_θ)_ii / (1 + λ)`` is the marginal variance of
  ``θ̂_i`` (the other parameters unknown); the statistic ``info_<θ>`` is
  ``1/σ_i²``, the Fisher information about ``θ_i``.
* *Settled* (at sample ``t``): (i) at least ``N2`` NF updates since its
  (re)initialisation, and the projection ``Π`` did not cut this sample's step
  (an estimate held at the box is no stationary point of the criterion);
  (ii) the drift ``δ = θ̂(t) − θ̂(t−N2)`` is explained by the estimate's
  uncertainty, ``δᵀ (c P_θ)⁻¹ δ = δᵀ R(t) δ / (a(t) c) ≤ χ²_{1−α}(l)``;
  (iii) the NF's normalised innovations over the window pass the
  ``χ²(N2 p)`` test (the model with ``θ̂`` explains the data); both tests at
  ``α = convergence_level``.
* *Converged* (the paper: "once the NF has estimated the parameters
  accurately"): settled, and at the same sample the data carry the
  information the classifier needs, ``W1 σ_i² ≤ isolable_jump_i²`` for every
  ``i`` — by (2.7) a jump ``Δ_i`` of a stationary estimate of spread ``σ_i``
  (which ``σ̂²_i0`` estimates) shows as ``d_i ≈ Δ_i²/σ_i²``, so a jump of
  ``isolable_jump_i`` reaches ``W1`` only then; ``info_<θ> ≥ W1 /
  isolable_jump²`` is the bound (default ``isolable_jump``: 50 % of
  ``|θ0_i|``, the paper's fault). Both flags (``nf_settled``: settled once)
  are sticky until the next NF (re)initialisation. ``P_θ`` is a local
  measure: where the model's sensitivities depend strongly on ``θ`` (the ship
  near ``a = 0``, an integrator) an estimate on a ridge of the criterion can
  look informative. With ``λ(t)`` still rising after a (re)initialisation the
  estimate's memory is short, so an early convergence also learns a wider
  nominal spread (2.6). The deprecated ``convergence_tolerance`` (before
  payload version 3: a fixed bound on the range of ``θ̂_i`` over ``N2``
  samples, whatever the data's information) is read as a bound on ``σ_i``:
  ``isolable_jump = √W1 · convergence_tolerance``.
* *Isolation from the NF's estimate* (beyond the paper, which arms its classifier only on a converged
  NF and so needs the information of a jump of ``isolable_jump`` in every parameter, before the fault
  as well as after it). Inside an open episode whose alarm stands, the settled NF's change
  ``δ = θ̂ − θ_e`` is tested against ``Σ = Cov θ̂`` (the stationary law above; doubled once the EKF
  holds an earlier estimate instead of the nominal ``θ0``, taken as known as well as the current one)
  by the generalised likelihood ratio of each single-parameter jump ``δ = Δ e_i``:
  ``g_i = (Σ⁻¹δ)_i² / (Σ⁻¹)_ii``, with the misfit ``δᵀΣ⁻¹δ − g_i`` of the others (the GLR of a change
  of unknown size in a known direction; Basseville & Nikiforov, *Detection of Abrupt Changes*,
  Prentice Hall, 1993). Hypothesis ``i``
  explains the estimate when ``g_i > χ²_{1−α}(1)`` and the misfit is at most ``χ²_{1−α}(l − 1)``,
  ``α = convergence_level``. Parameter ``i`` is isolated — the EKF re-parameterised on ``θ̂``, the
  class (2 when ``g_i > W2``) and the size ``δ_i`` latched — when hypothesis ``i`` alone explains the
  estimate now and also explains the estimate ``N2`` samples ago, the NF at least ``2·N2`` updates old
  (a fault arriving late in the NF's window, in an episode a false alarm opened, moves only the newest
  estimates; the first estimates after a reset travel from ``θ̂(0)``). ``isolated`` is then
  held; the classifier (2.6)–(2.8) may still latch the other parameters' classes after the
  re-parameterisation, and names the fault itself when the NF converged (below) without this test
  deciding. The test needs no nominal statistics: it decides under inputs too poor for the
  classifier's information law before the fault. Measured on the ship's excitation study (every
  family at every amplitude, both jumps, three runs): 123 of 126 runs isolated, none wrongly (before:
  52), median delay 111 samples after the fault (before: 150, over those 52); the other three are the
  constant input's ``a → a0/2``, not isolable.
* *Detected, not isolated*: the NF has converged and ``δᵀΣ⁻¹δ > χ²_{1−α}(l)`` but no single parameter
  explains the change: the episode stays open (the alarm holds, the EKF keeps its model, nothing is
  named, ``insufficient_excitation`` 0).
* *Detected, not isolable (insufficient excitation)*: inside an open episode
  the NF has settled, but neither does one parameter alone explain its estimate nor has it converged
  — the estimate is as good as the data allow, and they cannot tell which parameter moved (two
  hypotheses explain it, or none is significant and a jump of ``isolable_jump`` could hide). The episode
  stays open unless dismissed (below; the EKF keeps its model: a poorly
  determined ``θ̂`` would only raise the next alarm), ``isolated = −1``, the statistic
  ``insufficient_excitation`` is 1 and ``info_<θ>`` shows which parameter
  lacks information. It is also 1 when the EKF is re-parameterised without a parameter named and before
  any nominal statistics (2.6) exist (the excitation before the fault was insufficient for the
  classifier). Cleared by the next episode or an isolation; when the
  excitation returns, the NF's estimate decides and the episode closes as usual.
* *Dismissal* (a false alarm): at least ``N2`` samples into the episode the
  EKF's own normalised innovations over the last ``N2`` samples pass the
  ``χ²(N2 p)`` test at ``α`` — the WSSR's law over the NF's window — on
  ``N2`` consecutive samples (one passing window among many is what a
  slightly wrong model also produces). The data then demand no new model:
  the episode closes without re-parameterisation, whatever the NF estimated
  meanwhile (counted in the state's ``episodes_dismissed``). Without it one
  false alarm under too little excitation would hold the alarm on for as
  long as the input stays poor, and under any excitation a false alarm would
  hand the EKF a fresh, noisier estimate.
* *Alarm*: the output ``alarm`` is the WSSR decision or an open episode: it
  stays 1 from the detection until the EKF's re-parameterisation (or the
  episode's dismissal), one episode per fault whatever the excitation.
* *NF reset*: on a WSSR alarm, unless an episode is already open (an alarm
  whose NF reset has not yet led to an EKF re-parameterisation): ``θ̂ ← θ̂(0)``,
  ``P ← P(0)``, ``R ← R(0)``, ``W ← 0``, ``a, λ`` to their initial values,
  ``x̂`` kept (the paper: ``X̂(712) = X̂(712)``), windows and the
  classifier's run counters cleared. Alarms inside an open episode do not
  reset again: the EKF is known to be wrong until it is re-parameterised.
* *EKF re-parameterisation*: when, inside an open episode whose alarm stands
  (the EKF's innovations over the last ``N2`` samples fail the test above),
  the settled NF's estimate isolates a parameter (above) or the NF has
  converged with no change of ``θ``:
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
``u[m]``, ``y[p]``; outputs ``state_next``, ``r[2p]``, ``J[3 + 5l + 3]``,
``alarm`` (the WSSR decision of this sample or an open episode, 0/1), ``isolated`` (−1, or the
index of the first isolated parameter in ``plant.parameters``, which are the
fault names), ``status`` (0 processed, 1 skipped). All dense column vectors.

* ``r = [γ (EKF innovation, one per output: ekf_innovation_<y>),
  ε (NF innovation: nf_innovation_<y>)]``.
* ``J = [wssr (L(t)), wssr_threshold, ekf_nis (γᵀV0⁻¹γ), theta_hat_<θ>…,
  info_<θ>… (1/σ_i², 0 after an NF reset), d_<θ>…, fault_class_<θ>…
  (0/1/2, latched), fault_size_<θ>… (latched), nf_converged,
  insufficient_excitation, diverged]``; ``cusum, cusum_threshold`` or
  ``glr, glr_threshold`` in place of the first two for those detectors.
* ``state`` blocks in order (matrices column-major; see :class:`StateLayout`):
  ``ekf_x[n], ekf_P[n×n], ekf_theta[l], wssr_buffer[N], wssr_count,
  nf_x[n], nf_P[n×n], nf_theta[l], nf_R[l×l], nf_W[n×l], nf_gain (a),
  nf_forgetting (λ), nf_age, nf_settled, nf_converged, nf_info[l],
  theta_window[l×N2] (column j = θ̂(t−1−j)), nis_window[N2],
  ekf_nis_window[N2] (γᵀV0⁻¹γ, cleared with the NF), nominal_count,
  nominal_mean[l], nominal_m2[l], nominal_frozen, count_w1[l], count_w2[l],
  fault_class[l], fault_size[l], isolated, episode_open,
  insufficient_excitation, diagnosis_left, samples, skipped,
  alarm_resets, ekf_reparameterisations, episodes_dismissed, ekf_fit_run
  (consecutive passing windows), ekf_divergence_resets,
  nf_divergence_resets`` (``cusum_sums[2p]`` or ``glr_sums[p×M]`` in place of the WSSR's
  two blocks for those detectors).

Limits (constants of :mod:`fdisyn.synthesis.nafdf.settings`, checked before
anything is built or generated, at design time and again on reading a gain
file; each keeps one resource bounded, with room for
the documented problems — ship: ``N = 10``, ``N2 = 50``, 3 454 operations;
drive train: ``N = 50``, ``N2 = 200``, 12 342 operations):

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
  ``gcc -O2 -fstack-usage``: ship 2.2 KiB, drive train 5.7 KiB, the ship
  with ``N = 1000`` 9.9 KiB — the state copy dominates.

Gain files (:mod:`fdisyn.synthesis.nafdf.payload`). :func:`nafdf_payload`
stores the model as data, not code:
``f`` and ``h`` as lists of elementary operations
(:func:`fdisyn.models.casadi_program.model_program`) that the reader validates
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

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import casadi as ca
import numpy as np
from fdisyn.detectors.sequential import cusum_threshold, glr_threshold
from fdisyn.detectors.wssr import wssr_threshold_table
from fdisyn.models.nonlinear import NonlinearPlant
from fdisyn.numerics.certificate import Certificate, Check, worst
from fdisyn.numerics.linalg import frozen_array
from fdisyn.runtime.errors import ArgumentError, ShapeError
from fdisyn.runtime.gainfile import GainFile
from fdisyn.runtime.layout import StateLayout
from fdisyn.runtime.names import shown
from fdisyn.synthesis.nafdf.settings import _IDENT, _MAX_NAME, NafdfSettings, _settings
from fdisyn.synthesis.nafdf.step import _build_step, _check_step_size
from fdisyn.synthesis.kinds import ExtraMetrics

__all__ = ['NOT_ISOLABLE', 'NafdfDesign', 'nafdf', 'nafdf_diagnosis', 'nafdf_extra_metrics']

NOT_ISOLABLE = "detected, not isolable (insufficient excitation)"
"""The diagnosis of an episode whose data cannot resolve the jump (module docstring, block 4)."""


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
    isolable_jump: object | None = None,
    convergence_level: float = 1e-3,
    convergence_tolerance: object | None = None,
    u0: object | None = None,
    detector: Literal["wssr", "cusum", "glr"] = "wssr",
    min_shift: float | None = None,
    arl0: float | None = None,
    name: str = "nafdf",
) -> NafdfDesign:
    """Design the NAFDF of Zhou, Xi & Zhang 1991 (fig. 1, eqs. (2.3)–(2.8)) for ``plant``.

    Defaults: ``θ̂(0) = θ0`` (nominal), ``R(0) = I``, the paper's ``W1 = 50``,
    ``W2 = 350``, ``T1 = 50``; ``isolable_jump`` 50 % of ``|θ0_i|`` (0.5 for a
    zero nominal) — the smallest jump the classifier must isolate, from which
    the information the NF needs to converge follows (module docstring,
    block 4); ``convergence_tolerance`` is deprecated (read as
    ``isolable_jump = √W1 · convergence_tolerance``, with a ``FutureWarning``;
    not together with ``isolable_jump``); ``u0`` (the nominal input) zero. Every setting is validated and the
    sizes are held to the module's limits before anything is built. The
    model must be finite, with its Jacobians, at ``(x0, u0)`` for the nominal
    ``θ`` (the EKF's start) and for ``θ̂(0)`` (the NF's start). The returned
    design carries a certificate (AD Jacobians against central differences at
    ``x0``, a first step from the initial state that neither diverges nor
    skips, positive thresholds) and refuses to exist if it fails.

    ``detector`` is the fast detection's statistic on the EKF innovations: ``"wssr"`` (the paper's (2.4),
    ``window`` its length), ``"cusum"`` (Page's CUSUM on each normalised innovation and sign, tuned to a mean
    shift of ``min_shift`` standard deviations, default 1; given with another detector it is refused, and at or
    beyond :func:`~fdisyn.synthesis.nafdf.settings.largest_min_shift` of the budget, where the threshold would be 0)
    or ``"glr"`` (the windowed GLR of each normalised innovation
    over ``window`` onsets). ``arl0`` (seconds), when given, is the diagnoser's mean time between false alarms
    and sets the detector's false-alarm rate in place of ``false_alarm_probability``: ``1/(arl0/Ts − 2 N2)``
    per sample (a false alarm's episode lasts ``2 N2`` samples before its dismissal).
    """
    if convergence_tolerance is not None:
        warnings.warn(
            "the NAFDF option convergence_tolerance is deprecated: it is read as the largest standard deviation of "
            "θ̂_i (isolable_jump = √W1 · convergence_tolerance); give isolable_jump instead",
            FutureWarning,
            stacklevel=2,
        )
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
        isolable_jump=isolable_jump,
        convergence_tolerance=convergence_tolerance,
        convergence_level=convergence_level,
        u0=u0,
        detector=detector,
        min_shift=min_shift,
        arl0=arl0,
    )
    if not isinstance(name, str) or not _IDENT.fullmatch(name) or len(name) > _MAX_NAME:
        raise ArgumentError(f"name must be an identifier of at most {_MAX_NAME} characters; got {shown(name)}")
    return _design(plant, settings, name=name)


def detector_thresholds(plant: NonlinearPlant, settings: NafdfSettings) -> np.ndarray:
    """The fast detection's thresholds: the WSSR's table for ``1..N`` samples in the window (2.4), or the one
    threshold ``h`` of the CUSUM or GLR on the ``p`` normalised innovations.

    With ``ARL = 1/P_f`` samples (``false_alarm_probability``): the ``2p`` one-sided CUSUMs (each component,
    either sign, drift ``½ min_shift²``) share it as a union, ``h = cusum_threshold(2p·ARL, ½ min_shift²)``
    (:func:`~fdisyn.detectors.sequential.cusum_threshold`, Page's integral equation); the ``p`` scalar GLRs
    over ``M = window`` onsets likewise, ``h = glr_threshold(p·ARL, M)`` (Siegmund & Venkatraman 1995). The
    normalised innovations of an exact filter are independent across components and samples, so the union's
    rate is the sum of its members' (their alarms coincide with negligible probability). Each threshold is then
    multiplied by ``threshold_scale`` (1 unless the diagnoser is a point of an operating characteristic).
    """
    s = settings
    if s.detector == "cusum":
        table = np.array([cusum_threshold(2 * plant.p / s.false_alarm_probability, 0.5 * s.min_shift**2)])
    elif s.detector == "glr":
        table = np.array([glr_threshold(plant.p / s.false_alarm_probability, s.window)])
    else:
        table = wssr_threshold_table(
            window=s.window, n_outputs=plant.p, rule=s.threshold_rule, false_alarm_probability=s.false_alarm_probability, beta0=s.beta0
        )
    return table if s.threshold_scale == 1.0 else table * s.threshold_scale


def _names_r_J(plant: NonlinearPlant, detector: str = "wssr") -> tuple[tuple[str, ...], tuple[str, ...]]:
    r = tuple(f"ekf_innovation_{y}" for y in plant.outputs) + tuple(f"nf_innovation_{y}" for y in plant.outputs)
    par = plant.parameters
    J = (
        (detector, f"{detector}_threshold", "ekf_nis")
        + tuple(f"theta_hat_{q}" for q in par)
        + tuple(f"info_{q}" for q in par)
        + tuple(f"d_{q}" for q in par)
        + tuple(f"fault_class_{q}" for q in par)
        + tuple(f"fault_size_{q}" for q in par)
        + ("nf_converged", "insufficient_excitation", "diverged")
    )
    return r, J


def _design(plant: NonlinearPlant, settings: NafdfSettings, *, name: str, thresholds: np.ndarray | None = None) -> NafdfDesign:
    """Check the model at the filters' starting points, build the step within the limits, certify."""
    _check_model_finite(plant, settings)
    thr = detector_thresholds(plant, settings) if thresholds is None else np.asarray(thresholds, dtype=float)
    step, layout = _build_step(plant, settings, thr, name)
    _check_step_size(step, layout)
    r_names, J_names = _names_r_J(plant, settings.detector)
    draft = NafdfDesign(
        name=name,
        plant=plant,
        settings=settings,
        thresholds=frozen_array(thr),
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
    ``θ`` (the EKF) and with ``θ̂(0)`` (the NF). Raises :class:`ArgumentError` naming the expression."""
    where = f"x0 = {shown(s.x0.tolist())}, u0 = {shown(s.u0.tolist())}"
    nominal = dict(zip(plant.parameters, plant.theta_nominal.tolist(), strict=True))
    plant.check_finite(x=s.x0, u=s.u0, theta=plant.theta_nominal, point=f"the EKF's start ({where}, nominal θ = {shown(nominal)})")
    if not np.array_equal(s.theta0, plant.theta_nominal):
        start = dict(zip(plant.parameters, s.theta0.tolist(), strict=True))
        plant.check_finite(x=s.x0, u=s.u0, theta=s.theta0, point=f"the NF's start ({where}, theta0 = {shown(start)})")


def _init_state(plant: NonlinearPlant, s: NafdfSettings, layout: StateLayout) -> np.ndarray:
    """The state of a freshly (re-)initialised diagnoser, from the plant and the settings alone."""
    n, l = plant.n, plant.l  # noqa: E741 — the paper's letter for dim θ
    blocks: dict[str, object] = {
        "ekf_x": s.x0,
        "ekf_P": s.P0,
        "ekf_theta": plant.theta_nominal,
        "wssr_buffer": np.zeros(s.window),
        "wssr_count": 0.0,
        "cusum_sums": np.zeros(2 * plant.p),
        "glr_sums": np.zeros((plant.p, s.window)),
        "nf_x": s.x0,
        "nf_P": s.P0,
        "nf_theta": s.theta0,
        "nf_R": s.R0,
        "nf_W": np.zeros((n, l)),
        "nf_gain": 1.0,
        "nf_forgetting": s.forgetting_initial,
        "nf_age": 0.0,
        "nf_settled": 0.0,
        "nf_converged": 0.0,
        "nf_info": np.zeros(l),
        "theta_window": np.zeros((l, s.classifier_window)),
        "nis_window": np.zeros(s.classifier_window),
        "ekf_nis_window": np.zeros(s.classifier_window),
        "ekf_fit_run": 0.0,
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
        "insufficient_excitation": 0.0,
        "diagnosis_left": 0.0,
    }
    for c in ("samples", "skipped", "alarm_resets", "ekf_reparameterisations", "episodes_dismissed", "ekf_divergence_resets", "nf_divergence_resets"):
        blocks[c] = 0.0
    return layout.pack({name: blocks[name] for name, _, _ in layout.entries})


def _certify(design: NafdfDesign) -> Certificate:
    """AD against central differences, a first step that neither diverges nor skips, positive thresholds.

    Every aggregate goes through :func:`~fdisyn.numerics.certificate.worst`, so a
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
            f"{design.settings.detector.upper()} thresholds positive",
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
        ("wssr_threshold_full_window" if design.settings.detector == "wssr" else f"{design.settings.detector}_threshold"): float(thr[-1]),
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




def nafdf_diagnosis(
    statistic_names: Sequence[str],
    fault_names: Sequence[str],
    alarm: np.ndarray,
    isolated: np.ndarray,
    J: np.ndarray,
    onset: int,
) -> dict[str, Any]:
    """The diagnosis of one run from ``onset`` on (the step's outputs, C or CasADi, time along axis 0).

    ``verdict``: ``"isolated <θ>"`` (the latched ``isolated``), :data:`NOT_ISOLABLE` (the statistic
    ``insufficient_excitation`` is 1 at the end), ``"detected, not isolated"`` or ``"not detected"``;
    the detection and isolation delays in samples; the number of alarm episodes from ``onset`` on (a
    steady alarm makes one per fault); ``info`` — ``info_<θ>`` (``1/σ²``) at ``onset − 1`` and at the end.
    """
    names = list(statistic_names)
    alarm, isolated, J = np.asarray(alarm).reshape(-1), np.asarray(isolated).reshape(-1), np.asarray(J)
    after = alarm[onset:] > 0
    det, iso = np.flatnonzero(after), np.flatnonzero(isolated[onset:] >= 0)
    last = int(isolated[-1])
    if last >= 0:
        verdict = f"isolated {fault_names[last]}"
    elif J[-1, names.index("insufficient_excitation")] > 0:
        verdict = NOT_ISOLABLE
    else:
        verdict = "detected, not isolated" if det.size else "not detected"
    info = {q: (float(J[max(onset - 1, 0), names.index(f"info_{q}")]), float(J[-1, names.index(f"info_{q}")])) for q in fault_names}
    return {
        "verdict": verdict,
        "detection_delay": int(det[0]) if det.size else None,
        "isolation_delay": int(iso[0]) if iso.size else None,
        "alarm_episodes": int(np.sum(np.diff(np.concatenate([[False], after]).astype(int)) > 0)),
        "info": info,
    }


def _fault_sizes(scenario: Any) -> dict[str, float]:
    return {str(q): float(v) for q, v in dict(scenario.params.get("fault_size") or {}).items()}


def _nafdf_run(scenario: Any, gf: GainFile, run: Mapping[str, np.ndarray]) -> dict[str, Any]:
    """One run's share of :data:`nafdf_extra_metrics`: its isolations, alarm onsets, and the last sample's latched
    classes, sizes and excitation flag."""
    names = list(gf.step.statistic_names)
    iso, alarm = np.asarray(run["isolated"]), np.asarray(run["alarm"]).astype(np.int64)
    last = np.asarray(run["J"])[-1, :]
    sizes = _fault_sizes(scenario)
    if scenario.fault is None or not sizes:
        return {"isolated": bool(np.any(iso >= 0)), "onsets": int(np.sum(np.diff(alarm, prepend=0) > 0)), "samples": int(alarm.size)}
    classes = np.array([last[names.index(f"fault_class_{q}")] for q in gf.faults])
    onset = int(round(float(scenario.onset or 0.0) / gf.Ts))
    after = iso[onset:] >= 0
    return {
        "exact": bool(np.all((classes > 0) == np.array([q in sizes for q in gf.faults]))),
        "delay": int(np.argmax(after)) if np.any(after) else None,
        "not_isolable": bool(last[names.index("insufficient_excitation")] > 0),
        "errors": {
            q: float(last[names.index(f"fault_size_{q}")] - true) if last[names.index(f"fault_class_{q}")] > 0 else None
            for q, true in sizes.items()
        },
    }


def _nafdf_reduce(scenario: Any, gf: GainFile, runs: list[dict[str, Any]]) -> dict[str, float | None]:
    """The figures of :data:`nafdf_extra_metrics` from every run's :func:`_nafdf_run`, in run order."""
    sizes = _fault_sizes(scenario)
    if scenario.fault is None or not sizes:
        onsets = sum(r["onsets"] for r in runs)
        return {
            "runs with an isolation": float(np.mean([r["isolated"] for r in runs])),
            "alarm episodes per 10k samples": float(1e4 * onsets / sum(r["samples"] for r in runs)),
        }
    out: dict[str, float | None] = {"all parameter classes correct": float(np.mean([r["exact"] for r in runs]))}
    found = [r["delay"] for r in runs if r["delay"] is not None]
    out["isolation delay median (samples)"] = float(np.median(found)) if found else None
    out["runs detected, not isolable (insufficient excitation)"] = float(np.mean([r["not_isolable"] for r in runs]))
    for q in sizes:
        err = np.array([r["errors"][q] for r in runs if r["errors"][q] is not None], dtype=float)
        out[f"size error {q}: mean"] = float(err.mean()) if err.size else None
        out[f"size error {q}: sd"] = float(err.std(ddof=1)) if err.size > 1 else None
    return out


nafdf_extra_metrics = ExtraMetrics(per_run=_nafdf_run, reduce=_nafdf_reduce)
"""Monte Carlo figures of a NAFDF beyond detection (the ``nafdf`` kind's :attr:`~fdisyn.synthesis.kinds.DiagnoserKind.extra_metrics`).

``scenario.params["fault_size"]`` maps each jumping parameter to its true
jump ``θ_faulty − θ_0`` (absent or empty: fault-free). Fault-free: the
fraction of runs with an isolation and alarm episodes per 10⁴ samples.
Faulty: the fraction of runs whose latched parameter classes are exactly
the jumping parameters, the median isolation delay in samples, and per
jumping parameter the mean and standard deviation of the latched size
estimate (2.8) minus the true jump, over the runs that classed it faulty; and the fraction of runs
ending :data:`NOT_ISOLABLE`.
"""

