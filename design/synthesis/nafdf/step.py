"""The NAFDF step as one CasADi SX function (Zhou, Xi & Zhang, c. 1991, fig. 1).
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import scipy.stats
from fdisyn.detectors.symbolic import all_finite as _all_finite
from fdisyn.detectors.symbolic import (
    cusum_update,
    finite,
    glr_statistic,
    glr_update,
    largest,
    persistence_count,
    shift_in,
    window_sum,
    wssr_held,
    wssr_threshold,
    wssr_update,
)
from fdisyn.detectors.wssr import _NEVER
from fdisyn.models.nonlinear import NonlinearPlant
from fdisyn.runtime.errors import ArgumentError
from fdisyn.runtime.layout import StateLayout
from fdisyn.synthesis.nafdf.settings import (
    _D_OVERFLOW,
    _PSD_SHIFT,
    _Q_CAP,
    _VAR_FLOOR,
    _W_CAP,
    MAX_STEP_INSTRUCTIONS,
    MAX_STEP_WORK,
    NafdfSettings,
    _layout,
)

# --------------------------------------------------------------------------- SX helpers


def _sym(a: ca.SX) -> ca.SX:
    return 0.5 * (a + a.T)


def _ldl(a: ca.SX) -> tuple[ca.SX, ca.SX]:
    """LDLᵀ of a symmetric matrix without pivoting (``casadi.ldl``, natural order): ``Lᵀ`` and the pivots ``d``.

    ``Lᵀ`` holds the strictly upper part of the unit triangular factor; only
    the upper triangle of ``a`` is read. All pivots are positive iff the matrix
    is positive definite (Sylvester); the factorisation is then backward stable
    without pivoting. The AMD reordering is off, so the pivots are the ratios of
    leading principal minors; a NaN in the upper triangle makes a pivot NaN,
    which fails the ``d > 0`` test of :func:`_positive`.
    """
    d, lt, _ = ca.ldl(a, False)
    return lt, d


def _ldl_solve(lt: ca.SX, d: ca.SX, b: ca.SX) -> ca.SX:
    """Solve ``L D Lᵀ x = b`` (``b`` may have several columns) with the factors of :func:`_ldl`."""
    return ca.ldl_solve(b, d, lt, list(range(d.numel())))


def _inverse_diagonal(lt: ca.SX, d: ca.SX) -> list[ca.SX]:
    """The diagonal of ``A⁻¹`` from the factors of :func:`_ldl` (``A = Uᵀ diag(d) U``, ``U = I + Lᵀ``).

    ``(A⁻¹)_ii = Σ_{k≥i} (U⁻¹)_ik² / d_k``, with the unit upper triangular ``V = U⁻¹`` by back
    substitution, ``V_ik = −Σ_{i<j≤k} U_ij V_jk``: ~k³/3 operations, a third of solving for all of ``A⁻¹``.
    """
    k = d.numel()
    v = [[ca.SX(0.0)] * k for _ in range(k)]
    for i in reversed(range(k)):
        v[i][i] = ca.SX(1.0)
        for c in range(i + 1, k):
            acc = ca.SX(0.0)
            for j in range(i + 1, c + 1):
                acc = acc - lt[i, j] * v[j][c]
            v[i][c] = acc
    return [sum((v[i][c] ** 2 / d[c] for c in range(i + 1, k)), 1.0 / d[i]) for i in range(k)]


def _normalised(lt: ca.SX, d: ca.SX, b: ca.SX) -> ca.SX:
    """``D^{-1/2} U^{-T} b`` with the factors of :func:`_ldl` (``A = Uᵀ D U``, ``U = I + Lᵀ``): for ``b ~ N(0, A)``
    a vector ``N(0, I)``, whose squared norm is ``bᵀ A⁻¹ b`` (forward substitution, ~k²/2 operations)."""
    k = d.numel()
    z: list[ca.SX] = []
    for i in range(k):
        zi = b[i]
        for j in range(i):
            zi = zi - lt[j, i] * z[j]
        z.append(zi)
    return ca.vertcat(*[z[i] / ca.sqrt(ca.fmax(d[i], float(np.finfo(float).tiny))) for i in range(k)])


def _positive(d: ca.SX) -> ca.SX:
    ok = ca.SX(1)
    for j in range(d.numel()):
        ok = ca.logic_and(ok, d[j] > 0)
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
    lay = _layout(n, l, N, N2, s.detector, p)
    D = plant.derivatives()
    Q, R = ca.DM(plant.Q), ca.DM(plant.R)  # noise covariances (the paper's Q1, Q2), not the NF's R(t) = nf_R
    P0, R0 = ca.DM(s.P0), ca.DM(s.R0)
    x0, th0 = ca.DM(s.x0), ca.DM(s.theta0)
    I_n = ca.SX.eye(n)

    state = ca.SX.sym("state", lay.size)
    u = ca.SX.sym("u", m)
    y = ca.SX.sym("y", p)
    old = _split_sx(lay, state)
    new = dict(old)

    # ---- block 1: EKF on the model θ_e (eq. (2.3)) --------------------------------------
    xe, Pe, the = old["ekf_x"], old["ekf_P"], old["ekf_theta"]
    _, _, _, he, He, _ = D(xe, u, the)  # h and ∂h/∂x at the prediction (u unused by h)
    gamma = y - he
    V0 = _sym(ca.mtimes([He, Pe, He.T]) + R)  # V0 = H P Hᵀ + R
    lv, dv = _ldl(V0)
    v0inv_gamma = _ldl_solve(lv, dv, gamma)
    nis_e = ca.dot(gamma, v0inv_gamma)  # γᵀ V0⁻¹ γ, χ²(p) under H0
    Kf = _ldl_solve(lv, dv, ca.mtimes(He, Pe)).T  # K_f = P Hᵀ V0⁻¹
    xe_f = xe + ca.mtimes(Kf, gamma)
    ikh = I_n - ca.mtimes(Kf, He)
    Pe_f = ca.mtimes([ikh, Pe, ikh.T]) + ca.mtimes([Kf, R, Kf.T])  # Joseph form
    fe, Fe, _, _, _, _ = D(xe_f, u, the)
    xe_next = fe
    Pe_next = _sym(ca.mtimes([Fe, Pe_f, Fe.T]) + Q)
    ekf_ok = ca.logic_and(_all_finite(xe_next, nis_e), _psd_ok(Pe_next))
    ekf_ok = ca.logic_and(ekf_ok, _positive(dv))

    # ---- fast detection on the EKF innovations: WSSR (eq. (2.4)), CUSUM or GLR ---------------
    # a huge but finite square stays finite in the window sum (N · 1e300 < DBL_MAX)
    q_safe = ca.fmin(_select(_all_finite(nis_e), nis_e, 0.0), _Q_CAP)
    if s.detector == "wssr":
        buf_old, cnt_old = old["wssr_buffer"], old["wssr_count"]
        stat, buf_new, cnt_updated = wssr_update(q_safe, buf_old, cnt_old)  # L(t); unfilled slots are zero
        assert cnt_updated is not None  # given a count, the update returns the new one
        cnt_new: ca.SX = cnt_updated
        thr = wssr_threshold(cnt_new, thresholds)
        stat_hold, cnt_hold = wssr_held(buf_old, cnt_old)
        thr_hold = wssr_threshold(cnt_hold, thresholds)
    else:
        # normalised innovations w = D^{-1/2} U^{-T} γ (V0 = Uᵀ D U, U = I + Lᵀ): N(0, I) under H0, ‖w‖² = γᵀ V0⁻¹ γ
        w = _normalised(lv, dv, gamma)
        w = _select(_all_finite(w), ca.fmax(ca.fmin(w, _W_CAP), -_W_CAP), ca.SX.zeros(p, 1))
        h = float(thresholds[0])
        thr = thr_hold = ca.SX(h)
        if s.detector == "cusum":
            # Page's CUSUM per component and sign, tuned to a shift of min_shift: increment δ w − δ²/2, capped at 2h
            dlt = float(s.min_shift)
            sums_old = old["cusum_sums"]
            stat, sums_new = cusum_update(w, sums_old, 0.5 * dlt * dlt, h, shift=dlt)
            stat_hold = largest(sums_old)
        else:
            # windowed GLR per component (Willsky & Jones 1976, constant signature): onset sums d(n) of the last
            # n = 1..M samples, statistic max d(n)²/(2n); the oldest onset leaves the window. The state holds
            # them p × M (component fastest); the update reads them component-major.
            M = N
            d_old = old["glr_sums"]
            d_new = ca.reshape(glr_update(ca.vec(ca.repmat(w.T, M, 1)), ca.vec(d_old.T), M), M, p).T
            inv2n = np.tile(0.5 / np.arange(1, M + 1), (p, 1))
            stat = glr_statistic(d_new, inv2n)
            stat_hold = glr_statistic(d_old, inv2n)
    alarm = ca.logic_and(stat > thr, _all_finite(nis_e))

    # ---- block 2: NF, joint state/parameter filter (eq. (2.5)) --------------------------
    xn, Pn, thn, Rn, Wn = old["nf_x"], old["nf_P"], old["nf_theta"], old["nf_R"], old["nf_W"]
    _, Fn, Fth, hn, Hn, Hth = D(xn, u, thn)
    eps = y - hn  # ε(t)
    S = _sym(ca.mtimes([Hn, Pn, Hn.T]) + R)  # S = H P Hᵀ + R
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
    inside = ca.SX(1)  # Π leaves the step alone (a projected estimate is held, not settled)
    for i in range(l):  # Π: projection on the parameter box
        if math.isfinite(s.theta_lower[i]):
            inside = ca.logic_and(inside, th_new[i] > s.theta_lower[i])
            th_new[i] = ca.fmax(th_new[i], s.theta_lower[i])
        if math.isfinite(s.theta_upper[i]):
            inside = ca.logic_and(inside, th_new[i] < s.theta_upper[i])
            th_new[i] = ca.fmin(th_new[i], s.theta_upper[i])
    dth = th_new - thn
    K = _ldl_solve(ls_, ds_, ca.mtimes([Hn, Pn, Fn.T])).T  # K = F P Hᵀ S⁻¹
    FKH = Fn - ca.mtimes(K, Hn)
    Bx = ca.mtimes(ca.mtimes(FKH, Wn) - ca.mtimes(K, Hth), dth)
    fn_new, _, _, _, _, _ = D(xn, u, th_new)
    xn_next = fn_new + Bx + ca.mtimes(K, eps)
    Wn_next = ca.mtimes(FKH, Wn) + Fth - ca.mtimes(K, Hth)
    Pn_next = _sym(ca.mtimes([FKH, Pn, FKH.T]) + Q + ca.mtimes([K, R, K.T]))
    nf_ok = ca.logic_and(_all_finite(xn_next, Wn_next, th_new, Rn_new, nis_n), _psd_ok(Pn_next))
    nf_ok = ca.logic_and(nf_ok, ca.logic_and(_positive(dr), _positive(ds_)))

    # ---- windows at time t (θ̂(t−1..t−N2), NF innovations) and convergence -----------------
    win, nisw = old["theta_window"], old["nis_window"]
    age = old["nf_age"] + 1  # NF updates since its (re)initialisation, this one included
    full = old["nf_age"] >= N2
    # the NF's own uncertainty (module docstring, "Converged"): P_θ = a R⁻¹, stationary law with memory λ_m
    lam_m = ca.fmin(lam, 1.0 - 1.0 / age)
    r_inv = _inverse_diagonal(lr, dr)  # P_θ,ii = a (R⁻¹)_ii
    info = ca.vertcat(*[(1.0 + lam_m) / (gain * r_inv[i]) for i in range(l)])  # 1/σ²_i
    drift = th_new - win[:, N2 - 1]  # θ̂(t) − θ̂(t−N2)
    c_drift = 2.0 * (1.0 - lam_m**N2) / (1.0 + lam_m)
    q_drift = ca.dot(drift, ca.mtimes(Rn_new, drift)) / (gain * c_drift)  # driftᵀ (c P_θ)⁻¹ drift
    drift_limit = float(scipy.stats.chi2.isf(s.convergence_level, l))
    nis_limit = float(scipy.stats.chi2.isf(s.convergence_level, N2 * p))
    explains = window_sum(nisw) <= nis_limit
    settled_now = ca.logic_and(ca.logic_and(full, inside), ca.logic_and(q_drift <= drift_limit, explains))
    informative = ca.SX(1)
    for i in range(l):  # info_i = 1/σ_i² ≥ W1 / isolable_jump_i² (in that order: no overflow for any jump)
        bound = s.W1 / float(s.isolable_jump[i]) / float(s.isolable_jump[i])
        if not math.isfinite(bound):
            informative = ca.SX(0)
        elif bound > 0.0:
            informative = ca.logic_and(informative, info[i] >= bound)
    settled_old, conv_old = old["nf_settled"], old["nf_converged"]
    settled = ca.logic_and(ca.logic_or(settled_old, settled_now), nf_ok)
    conv = ca.logic_and(ca.logic_or(conv_old, ca.logic_and(settled_now, informative)), nf_ok)  # both tests now

    # which parameter moved, from the data (module docstring, "Isolation from the NF's estimate"): the
    # change δ = θ̂ − θ_e against Σ = Cov θ̂ + Cov θ_e; for each single-parameter hypothesis its GLR
    # g_i = (Σ⁻¹δ)_i² / (Σ⁻¹)_ii and the misfit q − g_i of the others, q = δᵀ Σ⁻¹ δ
    cov_nf = _sym(gain * _ldl_solve(lr, dr, ca.SX.eye(l)) / (1.0 + lam_m))
    # θ_e: the nominal (exact) until the first re-parameterisation, then an earlier NF estimate, whose
    # covariance is taken as the current one (the state keeps no copy: a gain file's layout stands)
    sigma = cov_nf * _select(old["ekf_reparameterisations"] > 0, 2.0, 1.0)
    lsg, dsg_ = _ldl(sigma)
    s_inv = _inverse_diagonal(lsg, dsg_)
    moved_limit = float(scipy.stats.chi2.isf(s.convergence_level, 1))
    rest_limit = float(scipy.stats.chi2.isf(s.convergence_level, l - 1)) if l > 1 else math.inf  # l = 1: nothing else

    def hypotheses(theta: ca.SX) -> tuple[ca.SX, list[ca.SX], list[ca.SX]]:
        dlt = theta - the
        zz = _ldl_solve(lsg, dsg_, dlt)
        qq = ca.dot(dlt, zz)
        ok = ca.logic_and(_positive(dsg_), _all_finite(qq))
        gs = [zz[i] * zz[i] / s_inv[i] for i in range(l)]
        return qq, gs, [ca.logic_and(ok, ca.logic_and(g > moved_limit, qq - g <= rest_limit)) for g in gs]

    # the same hypothesis must explain the estimate now and N2 samples ago, when the NF had itself seen N2
    # samples: a jump inside the NF's window (an episode opened by a false alarm, the fault arriving late in
    # it) biases the newest estimate only, and the first estimates after a reset travel from θ̂(0)
    delta = th_new - the
    q_all, glr, now = hypotheses(th_new)
    _, _, before = hypotheses(win[:, N2 - 1])
    sig_ok = ca.logic_and(_positive(dsg_), _all_finite(q_all))
    aged = old["nf_age"] >= 2 * N2
    accepted = [ca.logic_and(aged, ca.logic_and(a, b)) for a, b in zip(now, before, strict=True)]
    n_accepted = sum((_select(a, 1.0, 0.0) for a in accepted), ca.SX(0.0))
    n_plausible = sum((_select(a, 1.0, 0.0) for a in now), ca.SX(0.0))
    unique = ca.logic_and(n_accepted == 1, n_plausible == 1)  # no other hypothesis explains the estimate
    changed = ca.logic_and(sig_ok, q_all > float(scipy.stats.chi2.isf(s.convergence_level, l)))
    # resolved: one parameter explains the change, or the NF has converged (the data carry the classifier's
    # information) and θ has not changed; a change no single parameter explains holds the episode open
    resolved = ca.logic_or(unique, ca.logic_and(informative, ca.logic_not(changed)))
    several = ca.logic_and(ca.logic_and(informative, changed), n_plausible == 0)

    # dismissal (a false alarm): inside the episode the EKF's own model explains every window of N2
    # samples, Σ γᵀ V0⁻¹ γ ≤ χ²_{1−α}(N2 p), N2 times in a row — the data demand no new model
    episode = old["episode_open"]
    fits = ca.logic_and(ca.logic_and(episode, full), window_sum(old["ekf_nis_window"]) <= nis_limit)
    fit_run = persistence_count(fits, old["ekf_fit_run"])
    dismiss = fit_run >= N2
    # EKF re-parameterisation: the NF has converged inside an open episode whose alarm stands (block 4)
    reparam = ca.logic_and(ca.logic_and(ca.logic_and(settled, resolved), ca.logic_not(fits)), ca.logic_and(episode, nf_ok))
    iso_data = ca.SX(-1.0)
    for i in reversed(range(l)):
        iso_data = _select(ca.logic_and(reparam, accepted[i]), float(i), iso_data)
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
        c1 = persistence_count(ca.logic_and(deciding, di > s.W1), old["count_w1"][i])
        c2 = persistence_count(ca.logic_and(deciding, di > s.W2), old["count_w2"][i])
        latch = ca.logic_and(old["fault_class"][i] == 0, c1 >= s.T1)
        cls_i = _select(latch, _select(c2 >= s.T1, 2.0, 1.0), old["fault_class"][i])
        size_i = _select(latch, th_new[i] - mu0[i], old["fault_size"][i])  # eq. (2.8)
        named = ca.logic_and(old["isolated"] < 0, iso_data == i)  # isolated from the data: class and size now
        cls_i = _select(named, _select(glr[i] > s.W2, 2.0, 1.0), cls_i)
        size_i = _select(named, delta[i], size_i)
        d_stat.append(di)
        c1_new.append(c1)
        c2_new.append(c2)
        cls_new.append(cls_i)
        size_new.append(size_i)
        latch_now.append(latch)
    iso_cand = ca.SX(-1.0)
    for i in reversed(range(l)):
        iso_cand = _select(latch_now[i], float(i), iso_cand)
    isolated = _select(old["isolated"] >= 0, old["isolated"], _select(iso_data >= 0, iso_data, iso_cand))

    # nominal statistics (2.6), Welford: on a converged NF, outside an episode, until N1 samples
    learn = ca.logic_and(ca.logic_and(conv, ca.logic_not(old["episode_open"])), ca.logic_not(nominal_ready))
    n1_next = n1 + 1
    delta = th_new - mu0
    mean_next = mu0 + delta / n1_next
    m2_next = old["nominal_m2"] + delta * (th_new - mean_next)

    # ---- block 4: mutual re-initialisation ------------------------------------------------
    alarm_reset = ca.logic_and(alarm, ca.logic_not(episode))
    nf_reset = ca.logic_or(alarm_reset, ca.logic_not(nf_ok))
    episode_next = _select(ca.logic_or(reparam, dismiss), 0.0, _select(alarm_reset, 1.0, episode))
    any_latch = ca.SX(0)
    for latch in latch_now:
        any_latch = ca.logic_or(any_latch, latch)
    # detected, not isolable (insufficient excitation): inside an episode the NF has settled without the
    # information to converge, or it converged without a nominal reference (2.6) to classify against
    starved = ca.logic_and(ca.logic_and(episode, settled), ca.logic_not(ca.logic_or(ca.logic_or(resolved, several), dismiss)))
    unnamed = ca.logic_and(ca.logic_not(unique), ca.logic_not(nominal_ready))
    insufficient = _select(
        ca.logic_or(ca.logic_or(alarm_reset, any_latch), dismiss),
        0.0,
        _select(starved, 1.0, _select(reparam, unnamed, old["insufficient_excitation"])),
    )
    detector_clear = ca.logic_or(reparam, ca.logic_not(ekf_ok))

    # EKF next state: normal, re-parameterised from the NF, or re-initialised after divergence
    xn_fallback = _select(_all_finite(xn_next), xn_next, x0)
    new["ekf_x"] = _select(ekf_ok, _select(reparam, xn_next, xe_next), xn_fallback)
    new["ekf_P"] = _select(ca.logic_and(ekf_ok, ca.logic_not(reparam)), Pe_next, P0)
    new["ekf_theta"] = _select(reparam, th_new, the)
    if s.detector == "wssr":
        new["wssr_buffer"] = _select(detector_clear, ca.SX.zeros(N, 1), buf_new)
        new["wssr_count"] = _select(detector_clear, 0.0, cnt_new)
    elif s.detector == "cusum":  # sequential evidence also restarts when a false alarm is dismissed
        new["cusum_sums"] = _select(ca.logic_or(detector_clear, dismiss), ca.SX.zeros(2 * p, 1), sums_new)
    else:
        new["glr_sums"] = _select(ca.logic_or(detector_clear, dismiss), ca.SX.zeros(p, N), d_new)

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
    new["nf_settled"] = _select(nf_reset, 0.0, settled)
    new["nf_converged"] = _select(nf_reset, 0.0, conv)
    new["nf_info"] = _select(nf_reset, ca.SX.zeros(l, 1), _select(nf_ok, info, 0.0))
    win_next = ca.horzcat(th_new, win[:, : N2 - 1]) if N2 > 1 else th_new
    new["theta_window"] = _select(nf_reset, ca.SX.zeros(l, N2), win_next)
    nis_safe = ca.fmin(_select(_all_finite(nis_n), nis_n, 0.0), _Q_CAP)
    nis_next = shift_in(nis_safe, nisw)
    new["nis_window"] = _select(nf_reset, ca.SX.zeros(N2, 1), nis_next)
    ekf_nis_next = shift_in(q_safe, old["ekf_nis_window"])
    new["ekf_nis_window"] = _select(nf_reset, ca.SX.zeros(N2, 1), ekf_nis_next)
    new["ekf_fit_run"] = _select(ca.logic_or(nf_reset, dismiss), 0.0, fit_run)

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
    new["insufficient_excitation"] = insufficient
    new["diagnosis_left"] = _select(nf_reset, 0.0, ca.fmax(diag_left - 1, 0.0))
    new["samples"] = old["samples"] + 1
    new["alarm_resets"] = old["alarm_resets"] + alarm_reset
    new["ekf_reparameterisations"] = old["ekf_reparameterisations"] + reparam
    new["episodes_dismissed"] = old["episodes_dismissed"] + dismiss
    new["ekf_divergence_resets"] = old["ekf_divergence_resets"] + ca.logic_not(ekf_ok)
    new["nf_divergence_resets"] = old["nf_divergence_resets"] + ca.logic_not(nf_ok)
    diverged = ca.logic_or(ca.logic_not(ekf_ok), ca.logic_not(nf_ok))

    r_proc = ca.vertcat(gamma, eps)
    J_proc = ca.vertcat(
        stat,
        thr,
        q_safe,
        new["nf_theta"],
        new["nf_info"],
        ca.vertcat(*d_stat),
        new["fault_class"],
        new["fault_size"],
        new["nf_converged"],
        insufficient,
        diverged,
    )

    # ---- skipped sample: nothing changes but the counter ---------------------------------
    held = dict(old)
    held["skipped"] = old["skipped"] + 1
    J_hold = ca.vertcat(
        stat_hold,
        thr_hold,
        0.0,
        thn,
        old["nf_info"],
        ca.SX.zeros(l, 1),
        old["fault_class"],
        old["fault_size"],
        old["nf_converged"],
        old["insufficient_excitation"],
        0.0,
    )
    ok_in = _all_finite(u, y)
    state_next = _select(ok_in, _join_sx(lay, new), _join_sx(lay, held))
    r_out = _select(ok_in, _sanitise(r_proc), ca.SX.zeros(2 * p, 1))
    J_out = _select(ok_in, _sanitise(J_proc), _sanitise(J_hold))
    alarm_out = _select(ok_in, ca.logic_or(alarm, episode_next), 0.0)  # steady while an episode is open
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
        out.append(_select(finite(v[i]), v[i], overflow))
    return ca.vertcat(*out)


def _split_sx(layout: StateLayout, sx: ca.SX) -> dict[str, ca.SX]:
    """The blocks of a symbolic state vector, each ``rows × cols`` (column-major, as :class:`StateLayout` stores them)."""
    return {name: ca.reshape(sx[k : k + r * c], r, c) for name, (k, r, c) in layout.offsets().items()}


def _join_sx(layout: StateLayout, blocks: dict[str, ca.SX]) -> ca.SX:
    """A symbolic state vector from its named blocks (:func:`_split_sx` inverted)."""
    return ca.vertcat(*[ca.vec(ca.SX(blocks[name])) for name, _, _ in layout.entries])


def _check_step_size(step: ca.Function, layout: StateLayout) -> None:
    """:data:`MAX_STEP_INSTRUCTIONS` and :data:`MAX_STEP_WORK`, on the SX graph, before any C exists."""
    count, work = int(step.n_instructions()), int(step.sz_w())
    if count > MAX_STEP_INSTRUCTIONS:
        raise ArgumentError(
            f"the NAFDF step has {count} operations; at most {MAX_STEP_INSTRUCTIONS} are allowed "
            "(the generated C would take too long to compile): reduce window, classifier_window, "
            "the number of states or parameters, or the size of the model"
        )
    if work > MAX_STEP_WORK:
        raise ArgumentError(
            f"the NAFDF step needs {work} doubles of work memory; at most {MAX_STEP_WORK} are allowed "
            f"(they are locals of the generated C step, on its stack with the {layout.size}-entry state)"
        )

