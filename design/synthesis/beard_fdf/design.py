"""The design of a Beard fault detection filter with robust decision cones (He, Zhang & Wu, Journal of Astronautics, c. 1999).

Steps (each documented where it is computed):

1. the exactly sampled plant (a fault through a held actuator is piecewise constant, so the sampled filter keeps
   Beard's property exactly; a discrete plant is used as given) and the fault directions: the columns of ``Fx``
   and, per sensor fault on output ``j``, the pair ``[f_s, A f_s]`` with ``f_s = C⁺ e_j`` (the sensor fault
   ``y = C x + e_j ν`` is the state fault ``x̄ = x + f_s ν``, driven by ``f_s ν(k+1) − A f_s ν(k)``);
2. the detection spaces and the existence conditions (:func:`fdisyn.numerics.detection_filter.beard_structure`);
3. the gain: the eigenvalues given, or every free eigenvalue at the decay bound ``r = e^{−a Ts}`` (*plain*), or the
   eigenstructure NLP (*optimised*, :mod:`fdisyn.synthesis.beard_fdf.eigenstructure`);
4. the implicit thresholds ``Y_th`` (:mod:`fdisyn.numerics.robust_cones`), checked by sampling;
5. the explicit level ``ε̄`` and the magnitude threshold ``h``: the ``1 − P_f`` quantiles of the fault-free window
   mean norm and window RMS — from fault-free records when given (they carry the model error the noise model
   lacks), else from the law of the residual under the design noise (:mod:`fdisyn.detectors.window`);
6. the certificate and the gain file (kind ``beard_fdf``).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from fdisyn.models.linear import LinearPlant
from fdisyn.numerics.certificate import Certificate, Check
from fdisyn.numerics.detection_filter import beard_gain, beard_structure, plain_eigenvalues
from fdisyn.numerics.linalg import orth_basis, orth_complement
from fdisyn.numerics.robust_cones import (
    HALF_PI,
    implicit_thresholds,
    output_subspaces,
    sampled_angles,
    sampled_model_error,
    subspace_angle,
)
from fdisyn.detectors.sequential import MAX_ARL_SAMPLES
from fdisyn.runtime.errors import ArgumentError, ExistenceError
from fdisyn.runtime.gainfile import GainFile, signals_block
from fdisyn.runtime.schema import MAX_MAGNITUDE, SCALAR_STEP_LIMITS
from fdisyn.runtime.names import shown
from fdisyn.runtime.warmup import longest_warmup
from fdisyn.synthesis.beard_fdf.eigenstructure import RADIUS_TOL, optimise_eigenstructure, residual_covariance_trace
from fdisyn.synthesis.beard_fdf.payload import NSTATE_MARGIN, BeardFilter, beard_gain_file
from fdisyn.synthesis.beard_fdf.reference import beard_reference_run
from fdisyn.synthesis.linear_diagnoser import warmup_length
from fdisyn.synthesis.registry import at

__all__ = ["design_beard_fdf", "fault_directions", "cone_geometry"]

_INVARIANCE_TOL = 1e-9
_DRAW_ENTRIES = 2**24
"""Most numbers the drawn model errors may hold at once (``draws × n²``, 128 MiB)."""
_DECAY_MIN = 1e-6
"""Smallest ``decay_rate·Ts``: the certificate checks the spectral radius against ``e^(−decay_rate·Ts) + RADIUS_TOL``,
and the gain file needs it below 1."""
_DIRECTION_TOL = 1e-8


def fault_directions(plant: LinearPlant, sensor_faults: Sequence[str]) -> tuple[list[np.ndarray], tuple[str, ...]]:
    """The fault groups of the (discrete) plant and their names: ``Fx``'s columns, then each sensor fault's pair."""
    groups = [plant.Fx[:, i : i + 1] for i in range(plant.Fx.shape[1])]
    names = list(plant.component_faults)
    cplus = np.linalg.pinv(plant.C)
    for s in sensor_faults:
        if s not in plant.outputs:
            raise ArgumentError(f"sensor fault {s!r} is not an output; expected one of {list(plant.outputs)}")
        fs = cplus[:, plant.outputs.index(s)]
        if np.linalg.norm(plant.C @ fs - np.eye(plant.p)[:, plant.outputs.index(s)]) > 1e-9:
            raise ExistenceError(f"sensor fault {s!r}: C has dependent rows, no state direction reproduces output {s!r} alone")
        groups.append(np.column_stack([fs, plant.A @ fs]))
        names.append(s)
    if not groups:
        raise ArgumentError("the plant has no faults: give Fx (component faults) or sensor faults")
    return groups, tuple(names)


def cone_geometry(axes: Sequence[np.ndarray], Y: np.ndarray) -> dict[str, Any]:
    """Angles between the residual subspaces, and when the cones ``X + Y_i`` are disjoint.

    Cones ``i`` and ``j`` (half-angles ``X + Y_i``, ``X + Y_j``) are disjoint when ``2X + Y_i + Y_j < θ_ij`` (the
    smallest principal angle between ``S_i`` and ``S_j``), i.e. when ``ρ > 1 / sin((θ_ij − Y_i − Y_j)/2)``.
    """
    k = len(axes)
    theta = np.zeros((k, k))
    rho_min = np.zeros((k, k))
    for i in range(k):
        for j in range(k):
            if i == j:
                continue
            s = np.linalg.svd(axes[i].T @ axes[j], compute_uv=False)
            theta[i, j] = float(np.arccos(min(1.0, float(s[0]))))
            gap = theta[i, j] - Y[i] - Y[j]
            rho_min[i, j] = 1.0 / np.sin(gap / 2) if gap > 0 else np.inf
    off = ~np.eye(k, dtype=bool)
    overlapping = [[i, j] for i in range(k) for j in range(i + 1, k) if not np.isfinite(rho_min[i, j])]
    return {
        "axis_angles_deg": np.degrees(theta).tolist(),
        "rho_disjoint": [[None if not np.isfinite(v) else float(v) for v in row] for row in rho_min],
        "rho_disjoint_max": (float(np.max(rho_min[off])) if np.all(np.isfinite(rho_min[off])) else None) if k > 1 else 1.0,
        "overlapping_pairs": overlapping,
    }


def _check_sizes(pd: LinearPlant, window: int, where: str) -> None:
    """The window the diagnoser state can hold, refused before anything is allocated for it.

    The state holds ``window·p + n + 5`` entries and a gain file at most ``SCALAR_STEP_LIMITS["nstate"]`` with a margin of
    :data:`~fdisyn.synthesis.beard_fdf.payload.NSTATE_MARGIN` (:func:`~fdisyn.synthesis.beard_fdf.payload.beard_from_gain_file`).
    """
    n, p = int(pd.A.shape[0]), int(pd.C.shape[0])
    most = (SCALAR_STEP_LIMITS["nstate"] - NSTATE_MARGIN - n) // max(p, 1)
    if window > most:
        raise ArgumentError(
            f"{at(where, 'window')} = {window}: the diagnoser state holds window × outputs + states + 5 entries, at most "
            f"{SCALAR_STEP_LIMITS['nstate'] - NSTATE_MARGIN + 5}; expected window ≤ {max(most, 0)} for {p} outputs and {n} states"
        )


def _levels_from_records(flt: BeardFilter, records: Sequence[tuple[np.ndarray, np.ndarray]], P_f: float, where: str) -> tuple[float, float]:
    """``(h, ε̄)``: the ``1 − P_f`` quantiles of the window RMS and window-mean norm over fault-free records."""
    s_all, m_all = [], []
    for i, rec in enumerate(records):
        try:
            u, y = (np.asarray(v, dtype=float) for v in rec)
        except (TypeError, ValueError):
            raise ArgumentError(f"{at(where, 'fault_free')}[{i}] must be a pair (U, Y) of arrays") from None
        if u.ndim != 2 or y.ndim != 2 or u.shape[0] != y.shape[0] or u.shape[1] != flt.m or y.shape[1] != flt.p:
            raise ArgumentError(f"{at(where, 'fault_free')}[{i}]: U must be N × {flt.m} and Y N × {flt.p}; got {u.shape}, {y.shape}")
        out = beard_reference_run(flt, u, y)
        full = np.arange(flt.window - 1, u.shape[0])  # the statistics are defined once the window is full
        s_all.append(out.J[full, 0])
        m_all.append(out.J[full, 1] * flt.explicit_level)
    s, m = np.concatenate(s_all), np.concatenate(m_all)
    if s.size < 10.0 / P_f:
        raise ArgumentError(
            f"{at(where, 'fault_free')}: {s.size} full-window samples cannot estimate the 1 − {P_f:.3g} quantile (the "
            f"magnitude test's rate per sample: P_f, or Ts/arl0); expected at least {int(np.ceil(10 / P_f))} (10 / rate): "
            "longer records, or a larger P_f or shorter arl0"
        )
    if not (np.all(np.isfinite(s)) and np.all(np.isfinite(m))):
        raise ArgumentError(f"{at(where, 'fault_free')}: the records hold non-finite samples")
    return float(np.quantile(s, 1 - P_f, method="higher")), float(np.quantile(m, 1 - P_f, method="higher"))


def magnitude_rate(P_f: float | None, arl0: float | None, ts: float, where: str) -> float:
    """The magnitude test's false-alarm rate per sample: ``P_f``, or ``Ts/arl0`` for a budget in time.

    The window RMS exceeds its ``1 − P_f`` quantile on a fraction ``P_f`` of the fault-free samples, and a false
    alarm (an episode of exceedances) starts on at most that many, so ``P_f = Ts/arl0`` keeps the mean time between
    false alarms at least ``arl0`` (the same rule as a linear bank's χ² and WSSR statistics).

    Parameters
    ----------
    P_f : float or None
        The rate per sample given (the per-sample choice); None: from ``arl0``.
    arl0 : float or None
        The filter's mean time between false alarms (s).
    ts : float
        The filter's sample time (s).
    where : str
        Prefixes the message (see :func:`~fdisyn.synthesis.registry.at`).

    Returns
    -------
    float
        The rate per sample, in (0, 1).

    Raises
    ------
    ArgumentError
        Neither is given, or ``arl0`` is at most one sample or beyond the quantiles' working domain.
    """
    if arl0 is None:
        if P_f is None:
            raise ArgumentError(f"{where}: give the false-alarm budget: arl0 (s) or P_f (per sample)")
        return float(P_f)
    samples = float(arl0) / ts
    if not 1.0 < samples <= MAX_ARL_SAMPLES:
        raise ArgumentError(
            f"{at(where, 'arl0')} = {shown(arl0)} s is {samples:.3g} samples at Ts = {ts:g} s; expected "
            + (f"arl0 > {ts:.6g} s (one sample)" if samples <= 1.0 else f"arl0 ≤ {MAX_ARL_SAMPLES * ts:.6g} s ({MAX_ARL_SAMPLES:g} samples)")
        )
    return 1.0 / samples


def design_beard_fdf(
    plant: LinearPlant,
    *,
    name: str,
    problem: str | None = None,
    record: Mapping[str, object] | None = None,
    where: str = "method 'beard_fdf'",
    Ts: float | None = None,
    eigenvalues: Sequence[Sequence[complex]] | None = None,
    decay_rate: float | None = None,
    eigenstructure: str = "optimised",
    sigma: float = 0.0,
    rho: float | None = None,
    explicit_level: float | None = None,
    h: float | None = None,
    window: int = 20,
    P_f: float | None = None,
    arl0: float | None = None,
    persistence: int = 1,
    noise_gain: float = 2.0,
    separation: float = 0.02,
    sensor_faults: Sequence[str] = (),
    fault_free: Sequence[tuple[np.ndarray, np.ndarray]] | None = None,
    draws: int = 200,
) -> GainFile:
    """A certified Beard filter with robust decision cones (module docstring). Options as the method's."""
    if not isinstance(plant, LinearPlant):
        raise ArgumentError(f"{where}: expected a LinearPlant, got {type(plant).__name__}")
    if plant.is_discrete:
        if Ts is not None and float(Ts) != float(plant.Ts):  # type: ignore[arg-type]
            raise ArgumentError(f"{at(where, 'Ts')}: the plant is discrete with Ts = {plant.Ts}; leave Ts out")
        pd, ts_c = plant, None
    else:
        if Ts is None:
            raise ArgumentError(f"{at(where, 'Ts')}: a continuous plant needs the sample time Ts of the filter")
        pd, ts_c = plant.discretise(Ts), float(Ts)
    ts = float(pd.Ts)  # type: ignore[arg-type]
    _check_sizes(pd, int(window), where)
    if decay_rate is not None and not float(decay_rate) * ts >= _DECAY_MIN:
        raise ArgumentError(
            f"{at(where, 'decay_rate')} = {shown(decay_rate)}: the decay bound e^(−decay_rate·Ts) is 1 to within {_DECAY_MIN:g}, "
            f"no stable filter is told apart from it; expected decay_rate ≥ {_DECAY_MIN / ts:.3g} 1/s at Ts = {ts:g} s"
        )
    groups, fault_names = fault_directions(pd, sensor_faults)
    ad, c = np.asarray(pd.A), np.asarray(pd.C)
    numbered = ", ".join(f"{i + 1} = {n!r}" for i, n in enumerate(fault_names))
    try:
        st = beard_structure(ad, c, groups)
    except ExistenceError as exc:  # the geometry numbers the faults: name them
        raise ExistenceError(f"{where}: {exc} (faults {numbered}){_sampling_note(plant, sensor_faults, ts_c)}") from None
    spaces = [s.basis for s in st.spaces]
    axes = output_subspaces(c, spaces)
    k = len(spaces)
    if eigenvalues is not None and [len(e) for e in eigenvalues] != list(st.free_counts):
        raise ArgumentError(
            f"{at(where, 'eigenvalues')}: expected {k + 1} lists of lengths {list(st.free_counts)} (the detection spaces of "
            f"{', '.join(map(repr, fault_names))}, then the rest); got {len(eigenvalues)} of lengths {[len(e) for e in eigenvalues]}"
        )

    # the gain
    if eigenvalues is None and decay_rate is None:
        raise ArgumentError(f"{where}: give decay_rate (every eigenvalue of A − L C inside |z| ≤ e^(−decay_rate·Ts)) or eigenvalues")
    radius = float(np.exp(-float(decay_rate) * ts)) if decay_rate is not None else None
    plain_l, plain_ev = None, None
    if radius is not None:
        plain_ev = plain_eigenvalues(st, radius, separation)
        try:
            _check_fixed_modes(st.fixed, radius, float(decay_rate), ts, ts_c, where, numbered)  # type: ignore[arg-type]
            plain_l = beard_gain(ad, c, groups, plain_ev).L
        except ExistenceError as exc:
            text = str(exc) if str(exc).startswith(where) else f"{where}: {exc} (faults {numbered})"
            raise ExistenceError(f"{text}{_sampling_note(plant, sensor_faults, ts_c)}") from None
    info: dict[str, Any] = {}
    if eigenvalues is not None:
        ev = [list(np.exp(np.asarray(e, dtype=complex) * ts)) if ts_c is not None else list(e) for e in eigenvalues]
        gain = beard_gain(ad, c, groups, ev).L
        kind = "assigned"
        assigned = np.concatenate([np.asarray(e, dtype=complex) for e in ev])
    elif eigenstructure == "plain":
        assert plain_l is not None
        gain, kind = plain_l, "plain"
        assert plain_ev is not None
        assigned = np.concatenate([np.asarray(e, dtype=complex) for e in plain_ev])
    elif eigenstructure == "optimised":
        assert plain_l is not None and radius is not None
        q_d, r_d = np.asarray(pd.Q), np.asarray(pd.R)
        if not residual_covariance_trace(ad - plain_l @ c, plain_l, c, q_d, r_d) > 0:
            raise ArgumentError(f"{where}: the optimised eigenstructure bounds the residual noise by that of the plain one; give Q or R")
        plain_gains = [float(np.linalg.norm(c @ np.linalg.solve(np.eye(ad.shape[0]) - ad + plain_l @ c, f))) for f in groups]
        res = optimise_eigenstructure(
            ad, c, groups, st, radius=radius, Q=q_d, R=r_d, noise_gain=noise_gain, separation=separation, plain_gain=plain_l,
        )
        gain, kind = res.L, "optimised"
        assigned = np.concatenate(res.eigenvalues).astype(complex)
        info["fault_gain_ratio"] = [
            float(np.linalg.norm(c @ np.linalg.solve(np.eye(ad.shape[0]) - ad + res.L @ c, f))) / gp for f, gp in zip(groups, plain_gains, strict=True)
        ]
        info["nlp"] = {"objective": _finite(res.objective), "plain_objective": _finite(res.plain_objective),
                       "noise_ratio": res.noise_ratio, "starts": res.starts, "iterations": res.iterations,
                       "return_status": res.return_status, "source": res.source}
        if res.note is not None:
            info["nlp"]["note"] = res.note
            warnings.warn(f"{where}: {res.note}", UserWarning, stacklevel=2)
    else:
        raise ArgumentError(f"{at(where, 'eigenstructure')} must be 'optimised' or 'plain'; got {eigenstructure!r}")
    g = ad - gain @ c

    # the implicit thresholds and their sampled check
    with np.errstate(over="ignore", invalid="ignore"):
        sigma_d = sampled_model_error(plant.A, ts_c, float(sigma))
    if not (math.isfinite(sigma_d) and sigma_d <= MAX_MAGNITUDE):
        raise ArgumentError(
            f"{at(where, 'sigma')} = {shown(sigma)}: the bound it gives on the sampled model error overflows "
            f"(it grows as e^(sigma·Ts)); expected a model error well below {min(MAX_MAGNITUDE, 700.0 / (ts_c or 1.0)):.3g}"
        )
    bound = implicit_thresholds(g, c, spaces, sigma_d)
    y_th = bound.Y
    if sigma > 0 and draws * ad.shape[0] ** 2 > _DRAW_ENTRIES:
        raise ArgumentError(
            f"{at(where, 'draws')} = {draws}: the model errors drawn hold draws × states² = {draws * ad.shape[0] ** 2} numbers; "
            f"expected draws ≤ {_DRAW_ENTRIES // ad.shape[0] ** 2} for {ad.shape[0]} states"
        )
    if sigma > 0 and draws > 0:
        ang = sampled_angles(plant.A, ts_c, gain, c, spaces, bound, float(sigma), draws=draws, seed=0)
        worst_angle = ang.max(axis=0)
    else:
        worst_angle = np.zeros(k)
    informative = y_th < HALF_PI
    # The sampled angles are computed (expm, the Sylvester solve of the continued subspace, eig), each backward
    # stable: they are the exact angles of a model off by round-off, an error of about n·ε·‖G‖₂ on top of the
    # model error drawn. So the angle they may show is the bound at σ_d plus that error, not at σ_d alone: else a
    # tiny sigma compares round-off angles with a threshold ∝ sigma and fails by a nonsense ratio. For any sigma
    # that matters the floor moves the bound by ~1e-15 relative; a sigma below round-off checks like sigma = 0.
    y_check = y_th
    if sigma > 0 and draws > 0 and np.any(informative):
        rounding = ad.shape[0] * float(np.finfo(float).eps) * max(float(np.linalg.norm(g, 2)), float(np.linalg.norm(ad, 2)))
        y_check = np.maximum(y_th, implicit_thresholds(g, c, spaces, sigma_d + rounding).Y)
    excess = max([float(worst_angle[j] / y_check[j]) for j in range(k) if informative[j] and y_check[j] > 0], default=0.0)
    tightness = [float(worst_angle[j] / y_check[j]) if informative[j] and y_check[j] > 0 else None for j in range(k)]

    # the warm-up: the filter's initial error estimated by least squares over its first samples (a plant running at
    # switch-on is at no equilibrium), within what the size limits leave to its constants
    n_x, p_y = ad.shape[0], c.shape[0]
    room = SCALAR_STEP_LIMITS["nstate"] - NSTATE_MARGIN - int(window) * p_y - 2 * n_x >= 0
    warmup = warmup_length(g, c, None, most=longest_warmup([(n_x, p_y)], SCALAR_STEP_LIMITS["warmup_coefficients"]), equilibrate=True) if room else 0
    info["warmup_samples"] = warmup

    # the explicit level and the magnitude threshold
    provisional = BeardFilter(
        A=ad, B=np.asarray(pd.B), C=c, D=np.asarray(pd.D), L=gain, axes=axes, Y_th=y_th, window=int(window),
        h=1.0, explicit_level=1.0, rho=rho, persistence=int(persistence), design_info={}, warmup=warmup,
    )
    source = "given"
    if h is None or explicit_level is None:
        P_f = magnitude_rate(P_f, arl0, ts, where)
        info["P_f"] = P_f
        if arl0 is not None:
            info["arl0_s"] = float(arl0)
        if fault_free is not None:
            h_est, e_est = _levels_from_records(provisional, fault_free, P_f, where)
            source = f"fault-free records ({len(fault_free)})"
        else:
            from fdisyn.detectors.window import beard_residual_autocovariance, window_mean_level, window_rms_threshold

            q, r = np.asarray(pd.Q), np.asarray(pd.R)
            if not (np.trace(q) > 0 or np.trace(r) > 0):
                raise ArgumentError(f"{where}: h and explicit_level need fault_free records or the noise covariances Q, R")
            rl = beard_residual_autocovariance(ad, c, gain, q, r, int(window) - 1)
            h_est, e_est = window_rms_threshold(rl, int(window), P_f), window_mean_level(rl, int(window), P_f)
            source = "the law of the residual under the design noise (Q, R)"
        h = float(h_est) if h is None else float(h)
        explicit_level = float(e_est) if explicit_level is None else float(explicit_level)

    # the certificate
    checks = []
    for j, t in enumerate(spaces):
        res_inv = float(np.linalg.norm(g @ t - t @ (t.T @ g @ t), 2)) / max(float(np.linalg.norm(g, 2)), 1e-300)
        checks.append(Check(f"detection space of {fault_names[j]} invariant under A − L C (relative residual)", res_inv,
                            _INVARIANCE_TOL, "<=", "Beard's condition, to round-off of the construction"))
    eig_g = _block_spectrum(g, spaces)
    expected = np.concatenate([assigned, st.fixed])
    err = _spectrum_distance(eig_g, expected)
    checks.append(Check("eigenvalues of A − L C as assigned (max distance)", err, 1e-6,
                        "<=", "pole assignment is accurate well below this for the separated eigenvalues used"))
    rad = float(np.max(np.abs(eig_g))) if eig_g.size else 0.0
    checks.append(Check("spectral radius of A − L C (over its invariant blocks)", rad, radius + RADIUS_TOL if radius is not None else 1.0 - 1e-9, "<=",
                        "the decay-rate bound" if radius is not None else "a stable filter"))
    direction = _simulated_directions(g, c, groups, axes)
    checks.append(Check("residual direction under each fault, by simulation (max angle to C T, rad)", direction, _DIRECTION_TOL,
                        "<=", "every fault's residual stays in its subspace C T after any fault signal"))
    sv = np.linalg.svd(np.hstack(axes), compute_uv=False)
    checks.append(Check("output separability: smallest singular value of [C T_1 … C T_k] (orthonormal bases)", float(sv[-1]),
                        1e-8, ">=", "independent residual subspaces"))
    if sigma > 0 and draws > 0 and np.any(informative):
        checks.append(Check("largest sampled residual-direction angle / Y_th", excess, 1.0, "<=",
                            f"{draws} random model errors of norm sigma and the first-order worst cases, exact eigen-directions "
                            "(Y_th bounds the whole continued invariant subspace: Stewart's theorem)"))
    cones = cone_geometry(axes, y_th)
    info.update({
        "eigenstructure": kind,
        "eigenvalues_z": [[float(z.real), float(z.imag)] for z in eig_g],
        "detection_space_dims": [s.dim for s in st.spaces],
        "sigma": float(sigma), "sigma_d": sigma_d,
        "Y_th_deg": np.degrees(y_th).tolist(),
        "Y_first_order_deg": np.degrees(bound.first_order).tolist(),
        "Y_per_unit_sigma_d": [None if not np.isfinite(v) else float(v) for v in bound.coefficient],
        "stewart_kappa": [None if not np.isfinite(v) else float(v) for v in bound.eta],
        "separation": [None if not np.isfinite(v) else float(v) for v in bound.separation],
        "sampled_angle_deg": np.degrees(worst_angle).tolist(),
        "sampled_over_first_order": [float(worst_angle[j] / bound.first_order[j]) if 0 < bound.first_order[j] < HALF_PI else None for j in range(k)],
        "bound_tightness": tightness,
        "levels_from": source,
        "cones": cones,
        "decay_radius": radius,
    })
    if cones["overlapping_pairs"]:
        info["overlap"] = (f"the cones of {', '.join(f'{fault_names[i]} and {fault_names[j]}' for i, j in cones['overlapping_pairs'])} "
                           "overlap at every fault size: those faults are detected, not isolated")
    cert = Certificate.of(name, checks, info).require()
    flt = BeardFilter(
        A=ad, B=np.asarray(pd.B), C=c, D=np.asarray(pd.D), L=gain, axes=axes, Y_th=y_th, window=int(window),
        h=float(h), explicit_level=float(explicit_level), rho=rho, persistence=int(persistence), design_info=info,
        warmup=warmup,
    )
    return beard_gain_file(
        flt, name=name, problem=problem or name, design_name=f"beard_fdf_{kind}", Ts=ts, inputs=tuple(pd.inputs),
        outputs=tuple(pd.outputs), faults=fault_names, certificate=cert, options=record,
        signals=signals_block(pd.units, pd.labels, pd.inputs, pd.outputs, fault_names),
    )


def _block_spectrum(g: np.ndarray, spaces: Sequence[np.ndarray]) -> np.ndarray:
    """The eigenvalues of ``G`` as those of its diagonal blocks in the basis ``[T_1 … T_k, (Σ T_i)^⊥]``.

    Every ``T_i`` is invariant (certified separately), so ``G`` is block triangular there and its spectrum is the
    union of the blocks' spectra. Computed per block, an eigenvalue shared by two blocks (the plain filter puts the
    decay bound in every one) keeps its accuracy; ``eig(G)`` sees a defective eigenvalue there and splits it by
    ``√ε`` times the coupling (2e-7 is common), past the decay bound. When the ``T_i`` overlap (unobservable modes
    lie in all of them) it is ``eig(G)``.
    """
    if not spaces:
        return np.linalg.eigvals(g)
    stacked = np.hstack(spaces)
    basis = orth_basis(stacked, 1e-10)
    if basis.shape[1] != stacked.shape[1]:
        return np.linalg.eigvals(g)
    rest = orth_complement(basis)
    parts = [np.linalg.eigvals(t.T @ g @ t) for t in spaces]
    if rest.shape[1]:
        parts.append(np.linalg.eigvals(rest.T @ g @ rest))
    return np.concatenate(parts).astype(complex)


def _sampling_note(plant: LinearPlant, sensor_faults: Sequence[str], ts: float | None) -> str:
    """For a continuous plant whose sampled model has no Beard filter: whether the continuous model has one, at which
    fixed modes, and what the sampling changed ("" when it has none either, or the plant is discrete).

    Sampling keeps ``(C, e^{A Ts})``'s geometry only generically: a held fault enters as ``∫ e^{Aτ} dτ f``, the
    detection spaces of the sampled plant can differ in dimension (a sampling zero), and a fixed mode ``s`` of the
    continuous filter need not become ``e^{s Ts}`` — a mode the sampled geometry fixes may lie outside the unit
    circle (Åström, Hagander & Sternby, Automatica 20(1), 1984).
    """
    if ts is None:
        return ""
    try:
        groups, _ = fault_directions(plant, sensor_faults)
        st = beard_structure(np.asarray(plant.A), np.asarray(plant.C), groups)
        beard_gain(np.asarray(plant.A), np.asarray(plant.C), groups, [[-1.0] * m for m in st.free_counts], discrete=False)
    except Exception:  # noqa: BLE001 - no continuous filter either (or none this check can build): nothing to add
        return ""
    fixed = ", ".join(f"{z.real:.6g}" if z.imag == 0 else f"{z.real:.6g}{z.imag:+.6g}j" for z in st.fixed) or "none"
    try:
        sampled = beard_structure(np.asarray(plant.discretise(ts).A), np.asarray(plant.C), fault_directions(plant.discretise(ts), sensor_faults)[0])
        dims = f"; the detection spaces have dimensions {[s.dim for s in sampled.spaces]} sampled against {[s.dim for s in st.spaces]} continuous"
    except ExistenceError:
        dims = ""
    modes = f"fixed modes s = {fixed} 1/s, in the left half-plane" if st.fixed.size else "no fixed mode"
    return (f"; the continuous model has a Beard filter (detection spaces of dimensions {[s.dim for s in st.spaces]}, "
            f"{modes}): the ZOH sampling at Ts = {ts:g} s broke it{dims}; "
            "expected a Ts at which the sampled model keeps that geometry (try shorter ones)")


def _finite(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def _check_fixed_modes(fixed: np.ndarray, radius: float, decay_rate: float, ts: float, ts_c: float | None, where: str,
                       numbered: str) -> None:
    """Refuse a decay bound that a fixed mode of ``A − L C`` (no admissible gain moves it) does not meet."""
    slow = [complex(z) for z in fixed if abs(z) > radius + 1e-9 and abs(z) < 1.0 - 1e-10]
    if not slow:
        return
    worst = max(abs(z) for z in slow)
    shown_z = ", ".join(f"{z.real:.6g}" if z.imag == 0 else f"{z.real:.6g}{z.imag:+.6g}j" for z in slow)
    plane = (f" (s = {', '.join(f'{w:.6g}' for w in np.log(np.asarray(slow, dtype=complex)) / ts)} 1/s)") if ts_c is not None else ""
    raise ExistenceError(
        f"{at(where, 'decay_rate')} = {shown(decay_rate)}: the eigenvalue(s) {shown_z}{plane} of A − L C are fixed by the "
        f"geometry (no gain that keeps every detection space invariant moves them) and lie outside the decay bound "
        f"|z| ≤ e^(−decay_rate·Ts) = {radius:.6g}; expected decay_rate ≤ {-math.log(worst) / ts:.6g} 1/s (faults {numbered})"
    )


def _spectrum_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Largest distance between the eigenvalues ``a`` and the assigned ``b``, matched one to one, over the simple
    ones of ``b``: an eigenvalue assigned several times through fewer outputs forms a Jordan block, which round-off
    splits by ``ε^(1/m)`` — the decay bound checks those."""
    import scipy.optimize

    if a.size != b.size:
        return float("inf")
    cost = np.abs(a[:, None] - b[None, :])
    r, c = scipy.optimize.linear_sum_assignment(cost)
    if not a.size:
        return 0.0
    near = np.abs(b[:, None] - b[None, :]) <= 1e-6 * np.maximum(1.0, np.abs(b))[:, None]
    simple = near.sum(axis=1) == 1
    return float(max((cost[i, j] for i, j in zip(r, c, strict=True) if simple[j]), default=0.0))


def _simulated_directions(g: np.ndarray, c: np.ndarray, groups: Sequence[np.ndarray], axes: Sequence[np.ndarray], samples: int = 200) -> float:
    """Largest angle between ``C e`` and ``S_j`` along ``e⁺ = G e + F_j μ`` from ``e = 0``, random ``μ`` (seeded).

    An independent truth of Beard's property: a plain recursion, no subspace algebra. Samples whose output is
    below 1e-9 of the largest so far, or below 1e-9 of ``‖C‖₂ ‖e‖``, are skipped (the first samples of a fault with
    ``C f = 0``: their direction is round-off).
    """
    rng = np.random.default_rng(1)
    worst = 0.0
    c_norm = float(np.linalg.norm(c, 2))
    for f, s in zip(groups, axes, strict=True):
        e = np.zeros(g.shape[0])
        big = 0.0
        for _ in range(samples):
            e = g @ e + f @ rng.standard_normal(f.shape[1])
            out = c @ e
            size = float(np.linalg.norm(out))
            big = max(big, size)
            if size > 1e-9 * big and size > 1e-9 * c_norm * float(np.linalg.norm(e)):
                worst = max(worst, subspace_angle(out, s))
    return worst
