"""Generalised UIO banks for linearly dependent outputs (Long & Wang, Aeroengine 43(5), 2017).

Long & Wang, "A promoted design approach for unknown input observer",
Aeroengine 43(5), 2017, pp. 7–13; section and equation numbers below are
theirs. Three parts, each usable alone:

* **Grouping** (:func:`output_groups`, section 2, case 2). When ``rank C = r < p``
  the outputs are split into groups of linearly independent rows that
  together cover every sensor to diagnose. The search is exhaustive over the
  bases of the row matroid of ``C`` (subsets of ``r`` independent rows): the
  fewest groups that cover the sensors, ties broken by conditioning — the
  largest condition number of a group completed by its virtual outputs,
  smallest first. Every solution of the optimal size is returned, ranked, so
  a hand-made grouping can be checked against them.
* **Virtual outputs** (:func:`virtual_outputs`, section 2, case 1). States of
  the on-board model appended to a group until its rows span ``Rⁿ``: the
  ``n − r`` unit rows that minimise the condition number of the completed,
  row-normalised ``n × n`` matrix (exhaustive below 20 000 candidate sets,
  greedy above). They serve only to observe the unknown input.
* **The unknown-input direction from data** (:func:`estimate_unknown_input`,
  eq. (4)). ``d₁ = E d`` is taken as slowly varying and observed with the
  augmented model ``[ẋ; ḋ₁] = [[A, I], [0, 0]] [x; d₁] + [B; 0] u``, which
  needs ``n`` independent outputs: a group and its virtual outputs. The
  estimates over fault-free training data are stacked (states scaled by
  their magnitudes on the nominal model), and ``E`` is their dominant singular
  directions, the rank read from the largest gap ``σ_k / σ_{k+1}`` (Chen &
  Patton, *Robust Model-Based Fault Diagnosis for Dynamic Systems*, 1999,
  ch. 4: the optimal low-rank approximation of the mismatch).
* **The bank** (:func:`gos_diagnoser`, eqs. (5)–(6)): per group, one
  minimum-variance UIO (:func:`fdisyn.synthesis.uio.kalman_uio`) per sensor,
  fed every output of its group but that sensor (the generalised observer
  scheme, Frank, Automatica 26(3), 1990). A sensor fault then raises every
  statistic of the groups that hold the sensor except the one that excludes
  it: the signature table of the linear diagnoser isolates it.
"""

from __future__ import annotations

import itertools
import math
import os
import stat
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import PurePath
from typing import Any

import numpy as np
import scipy.linalg
from fdisyn.models.linear import LinearPlant
from fdisyn.numerics.certificate import Certificate, Check
from fdisyn.numerics.linalg import rank
from fdisyn.runtime.errors import ArgumentError, ExistenceError, FdisynError, ShapeError, TraceError
from fdisyn.runtime.gainfile import GainFile
from fdisyn.detectors.table import windowed_kinds
from fdisyn.runtime.names import shown
from fdisyn.runtime.trace import Trace, TraceReader
from fdisyn.synthesis.linear_diagnoser import (
    FaultClass,
    _sensor_indices,
    check_budget,
    check_min_fault,
    check_shifts,
    check_window,
    chosen_detector,
    default_fault_classes,
    linear_diagnoser,
)
from fdisyn.synthesis.isolation import FALSE_ISOLATION
from fdisyn.synthesis.registry import P_F, Option, at
from fdisyn.synthesis.residual import internal_form
from fdisyn.synthesis.uio import kalman_uio

__all__ = [
    "Grouping",
    "UnknownInputEstimate",
    "output_groups",
    "virtual_outputs",
    "completed_condition",
    "estimate_unknown_input",
    "gos_bank",
    "gos_diagnoser",
    "gos_design",
    "GosDesign",
    "uio_name",
]

EXHAUSTIVE_LIMIT = 20_000
"""Largest number of candidate sets (bases of ``C``'s rows, or virtual-output sets) searched exhaustively."""
RANK_GAP_MIN = 10.0
"""Smallest ``σ_q / σ_{q+1}`` accepted as a rank gap of the stacked unknown-input estimates: a factor of ten
separates the directions the mismatch drives from the estimation noise floor (measured on the turbofan: the
noise directions are within a factor of 2 of one another)."""


@dataclass(frozen=True)
class Grouping:
    """Groups of linearly independent outputs (indices into the plant's outputs) and their virtual outputs."""

    groups: tuple[tuple[int, ...], ...]
    virtual: tuple[tuple[int, ...], ...]
    """Per group, the state indices appended as virtual outputs (``n − rank`` of them)."""
    condition: float
    """The largest condition number of a group completed by its virtual outputs (row-normalised)."""


def _normalised(rows: np.ndarray) -> np.ndarray:
    norms = np.linalg.norm(rows, axis=1)
    return rows / np.where(norms > 0, norms, 1.0)[:, None]


def completed_condition(C: np.ndarray, group: Sequence[int], states: Sequence[int]) -> float:
    """Condition number of ``[C_group; I_states]`` with unit-norm rows (``inf`` when singular or not square)."""
    c = np.asarray(C, dtype=float)
    n = c.shape[1]
    m = np.vstack([c[list(group)], np.eye(n)[list(states)]])
    if m.shape[0] != n:
        return math.inf
    s = np.linalg.svd(_normalised(m), compute_uv=False)
    return float(s[0] / s[-1]) if s[-1] > 1e-12 * s[0] else math.inf


def virtual_outputs(C: np.ndarray, group: Sequence[int], *, state_names: Sequence[str] | None = None) -> tuple[int, ...]:
    """The ``n − rank`` states that complete ``group``'s rows of ``C`` to a basis of ``Rⁿ``, best conditioned.

    Raises :class:`ExistenceError` when the group's rows are dependent.
    """
    c = np.asarray(C, dtype=float)
    n = c.shape[1]
    g = list(group)
    r = rank(c[g])
    if r != len(g):
        raise ExistenceError(f"the outputs {g} are linearly dependent (rank {r} < {len(g)}): a group must hold independent rows of C")
    need = n - r
    if math.comb(n, need) <= EXHAUSTIVE_LIMIT:
        best = min(itertools.combinations(range(n), need), key=lambda s: completed_condition(c, g, s))
    else:  # greedy: add the state that keeps the completed rows best conditioned
        chosen: list[int] = []
        for _ in range(need):
            def score(j: int) -> float:
                m = _normalised(np.vstack([c[g], np.eye(n)[[*chosen, j]]]))
                s = np.linalg.svd(m, compute_uv=False)
                return -float(s[-1])
            chosen.append(min((j for j in range(n) if j not in chosen), key=score))
        best = tuple(sorted(chosen))
    if not math.isfinite(completed_condition(c, g, best)):
        raise ExistenceError(f"no {need} states complete the outputs {g} to rank {n}")
    return tuple(best)


_completion = virtual_outputs  # the function, where an option of the same name shadows it


def output_groups(
    C: np.ndarray, sensors: Sequence[int] | None = None, *, outputs: Sequence[str] | None = None
) -> list[Grouping]:
    """Every grouping of fewest groups that covers ``sensors``, best conditioned first.

    A group is a basis of the row space of ``C`` (``rank C`` independent
    rows: the largest independent set, so each UIO keeps as many outputs as
    possible). Objective: (1) the number of groups, (2) the largest condition
    number of a group completed by its virtual outputs (:func:`virtual_outputs`).
    Raises :class:`ExistenceError` naming a sensor no independent group can hold
    (a zero row of ``C``).
    """
    c = np.asarray(C, dtype=float)
    p = c.shape[0]
    names = list(outputs) if outputs is not None else [f"y{i}" for i in range(p)]
    want = list(range(p)) if sensors is None else list(sensors)
    r = rank(c)
    zero = [names[i] for i in want if not np.any(c[i])]
    if zero:
        raise ExistenceError(f"sensor(s) {zero} have a zero row of C: no group of independent outputs can hold them")
    if math.comb(p, r) > EXHAUSTIVE_LIMIT:
        raise ArgumentError(
            f"{p} outputs of rank {r} give {math.comb(p, r)} candidate groups (more than {EXHAUSTIVE_LIMIT}); give the groups explicitly"
        )
    bases = [b for b in itertools.combinations(range(p), r) if rank(c[list(b)]) == r]
    virtual = {b: virtual_outputs(c, b) for b in bases}
    cond = {b: completed_condition(c, b, virtual[b]) for b in bases}
    for k in range(1, len(bases) + 1):
        found = [
            Grouping(groups=combo, virtual=tuple(virtual[b] for b in combo), condition=max(cond[b] for b in combo))
            for combo in itertools.combinations(bases, k)
            if set(want) <= set().union(*map(set, combo))
        ]
        if found:
            return sorted(found, key=lambda gr: gr.condition)
    missing = [names[i] for i in want if not any(i in b for b in bases)]
    raise ExistenceError(f"no group of linearly independent outputs covers the sensor(s) {missing}")


# --------------------------------------------------------------------------- the unknown-input direction


@dataclass(frozen=True, eq=False)
class UnknownInputEstimate:
    """``E`` from fault-free data: dominant directions of the observed mismatch ``d̂₁``."""

    E: np.ndarray
    """``n × q``: the columns ``S u_i`` (``u_i`` the left singular vectors of the scaled estimates)."""
    singular_values: np.ndarray
    """Of the scaled, stacked ``d̂₁`` (divided by ``√N``: RMS units)."""
    rank: int
    gap: float
    """``σ_q / σ_{q+1}``."""
    scale: np.ndarray
    """The state scaling ``S`` (RMS of each state on the nominal model over the training input)."""
    d_hat: np.ndarray
    """``N × n``: the estimates ``d̂₁(k)`` (physical units)."""
    group: tuple[int, ...]
    virtual: tuple[int, ...]
    burn_in: int
    """Samples left out at the start (the estimator's transient)."""

    Ts: float

    def left_out(self) -> np.ndarray:
        """``N' × n``: the mismatch ``E`` leaves out, ``d̂₁ − E E⁺ d̂₁`` after the burn-in (physical units: the
        part the UIOs are not decoupled from)."""
        d = self.d_hat[self.burn_in :]
        return d - d @ np.linalg.pinv(self.E).T @ self.E.T

    def left_out_intensity(self, max_lag: float) -> np.ndarray:
        """``n × n``: the intensity of the white noise with the left-out mismatch's low-frequency power.

        The long-run covariance ``Ts · Σ_k w_k R(k)`` over lags ``|k| Ts ≤ max_lag`` with Bartlett weights
        ``w_k = 1 − |k|/(L+1)`` (Newey & West, Econometrica 55(3), 1987: positive semi-definite). A slowly
        varying mismatch has ``R(k) ≈ R(0)`` over many samples, so treating it as white with covariance
        ``Ts · R(0)`` would understate its effect on the state by its correlation time over ``Ts``.
        """
        rest = self.left_out()
        rest = rest - rest.mean(axis=0)
        nn = rest.shape[0]
        lags = min(int(max_lag / self.Ts), nn - 1)
        w = rest.T @ rest / nn
        for k in range(1, lags + 1):
            g = rest[k:].T @ rest[:-k] / nn
            w = w + (1.0 - k / (lags + 1)) * (g + g.T)
        w = self.Ts * 0.5 * (w + w.T)
        return w


def estimate_unknown_input(
    plant: LinearPlant,
    Ts: float,
    U: np.ndarray,
    Y: np.ndarray,
    X_virtual: np.ndarray,
    *,
    group: Sequence[int],
    virtual: Sequence[int],
    d_rate: float = 1.0,
    virtual_noise: float = 1e-3,
    burn_in: float = 2.0,
    rank_gap: float = RANK_GAP_MIN,
    rank_max: int | None = None,
    rank_fixed: int | None = None,
) -> UnknownInputEstimate:
    """Observe ``d₁`` with the augmented model of Long & Wang 2017, eq. (4), and take ``E`` from its SVD.

    ``plant`` is the continuous design model (its ``R``: the sensor noise);
    ``U`` (``N × m``), ``Y`` (``N × p``) fault-free training samples and
    ``X_virtual`` (``N × len(virtual)``) the virtual outputs (states of the
    on-board model). Sampled exactly (``d₁`` held over a sample), the
    augmented model is observed by a steady-state Kalman filter with ``d₁`` a
    random walk whose increments have standard deviation ``d_rate · S · √Ts``
    per sample (``S`` the state scale) and virtual outputs read with noise
    ``virtual_noise · S``. The rank is the ``q`` of the largest gap
    ``σ_q / σ_{q+1} ≥ rank_gap`` (``q ≤ rank_max``); no such gap is an
    :class:`ExistenceError` naming the singular values. ``rank_fixed`` takes that
    many directions whatever the gap (which is still reported).
    """
    if plant.is_discrete:
        raise ArgumentError("estimate_unknown_input needs the continuous design model (d₁ enters ẋ, Long & Wang 2017, eq. (4))")
    n, m = plant.n, plant.m
    u = np.asarray(U, dtype=float)
    y = np.asarray(Y, dtype=float)
    xv = np.asarray(X_virtual, dtype=float)
    g, v = list(group), list(virtual)
    if u.ndim != 2 or u.shape[1] != m or y.shape != (u.shape[0], plant.p) or xv.shape != (u.shape[0], len(v)):
        raise ShapeError(f"training data: U N×{m}, Y N×{plant.p}, X_virtual N×{len(v)} with one N; got {u.shape}, {y.shape}, {xv.shape}")
    if not (np.all(np.isfinite(u)) and np.all(np.isfinite(y)) and np.all(np.isfinite(xv))):
        raise ArgumentError("training data hold NaN or inf; give fault-free, complete samples")
    a, b = np.asarray(plant.A), np.asarray(plant.B)
    # exact sampling of [x; d₁; u] with u and d₁ held over the sample
    big = np.zeros((2 * n + m, 2 * n + m))
    big[:n, :n], big[:n, n : 2 * n], big[:n, 2 * n :] = a, np.eye(n), b
    ed = scipy.linalg.expm(big * Ts)
    phi, gam, gb = ed[:n, :n], ed[:n, n : 2 * n], ed[:n, 2 * n :]
    # state scale: RMS of the nominal model's response to the training input
    xn = np.zeros(n)
    traj = np.empty((u.shape[0], n))
    for k in range(u.shape[0]):
        traj[k] = xn
        xn = phi @ xn + gb @ u[k]
    scale = np.sqrt(np.mean(traj**2, axis=0))
    scale = np.where(scale > 1e-12 * max(float(scale.max()), 1e-300), scale, max(float(scale.max()), 1.0))
    az = np.block([[phi, gam], [np.zeros((n, n)), np.eye(n)]])
    bz = np.vstack([gb, np.zeros((n, m))])
    cg, dg = np.asarray(plant.C)[g], np.asarray(plant.D)[g]
    cz = np.vstack([np.hstack([cg, np.zeros((len(g), n))]), np.hstack([np.eye(n)[v], np.zeros((len(v), n))])])
    rz = scipy.linalg.block_diag(np.asarray(plant.R)[np.ix_(g, g)], np.diag((virtual_noise * scale[v]) ** 2))
    qz = scipy.linalg.block_diag(np.zeros((n, n)), np.diag((d_rate * scale) ** 2 * Ts))
    if rank(cz) < n:
        raise ExistenceError(f"the outputs {g} and virtual states {v} have rank {rank(cz)} < n = {n}: d₁ is not observable")
    try:
        p = scipy.linalg.solve_discrete_are(az.T, cz.T, qz + 1e-12 * np.eye(2 * n) * float(np.max(np.diag(qz))), rz)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise ExistenceError(f"the augmented observer of d₁ has no stabilising Kalman gain: {exc}") from exc
    kgain = p @ cz.T @ np.linalg.inv(cz @ p @ cz.T + rz)  # filter (measurement-update) gain
    z = np.zeros(2 * n)
    meas = np.hstack([y[:, g] - u @ dg.T, xv])
    dh = np.empty((u.shape[0], n))
    for k in range(u.shape[0]):
        z = z + kgain @ (meas[k] - cz @ z)
        dh[k] = z[n:]
        z = az @ z + bz @ u[k]
    keep = int(round(burn_in / Ts))
    stack = (dh[keep:] / scale).T / math.sqrt(max(dh.shape[0] - keep, 1))
    uu, s, _ = np.linalg.svd(stack, full_matrices=False)
    ratios = s[:-1] / np.maximum(s[1:], np.finfo(float).tiny)
    top = len(ratios) if rank_max is None else min(rank_max, len(ratios))
    if top < 1:
        raise ArgumentError(f"rank_max must be ≥ 1; got {rank_max}")
    if rank_fixed is not None:
        if not 1 <= rank_fixed < n:
            raise ArgumentError(f"the rank of E must be in 1..{n - 1}; got {rank_fixed}")
        qi = rank_fixed - 1
    else:
        qi = int(np.argmax(ratios[:top]))
    if rank_fixed is None and ratios[qi] < rank_gap:
        raise ExistenceError(
            f"the unknown-input estimate has no clear rank gap: largest σ_k/σ_(k+1) = {ratios[qi]:.3g} (k = {qi + 1}) < {rank_gap:g}; "
            f"singular values {np.array2string(s, precision=3)}; give E explicitly or train on richer data"
        )
    q = qi + 1
    return UnknownInputEstimate(
        E=scale[:, None] * uu[:, :q],
        singular_values=s,
        rank=q,
        gap=float(ratios[qi]),
        scale=scale,
        d_hat=dh,
        group=tuple(g),
        virtual=tuple(v),
        burn_in=keep,
        Ts=float(Ts),
    )


# --------------------------------------------------------------------------- the bank


def uio_name(group_index: int, excluded: str) -> str:
    """``g<k>_no_<sensor>``: the UIO of group ``k`` that does not read ``sensor``."""
    return f"g{group_index + 1}_no_{excluded}"


def gos_bank(
    plant: LinearPlant, groups: Sequence[Sequence[int]], *, sensors: Sequence[int] | None = None
) -> tuple[list[Any], list[np.ndarray], list[Certificate]]:
    """Per group, one minimum-variance UIO per diagnosed sensor, fed the group's other outputs.

    ``plant`` is the discrete design model with its unknown-input matrix
    ``E``. Each UIO's existence (``rank(Cⁱ E) = rank(E)``, ``(Cⁱ, A1)``
    detectable) is checked by :func:`~fdisyn.synthesis.uio.uio_structure`;
    a failure names the group and the excluded sensor. Returns the generators
    (on the full output vector), their residual covariances and certificates.
    """
    want = set(range(plant.p) if sensors is None else sensors)
    gens, sigmas, certs = [], [], []
    for gi, group in enumerate(groups):
        for s in group:
            if s not in want:
                continue
            used = [j for j in group if j != s]
            name = uio_name(gi, plant.outputs[s])
            try:
                d = kalman_uio(plant.select_outputs(used))
            except FdisynError as exc:
                raise type(exc)(f"group {gi + 1} {[plant.outputs[j] for j in group]}, the UIO without {plant.outputs[s]}: {exc}") from exc
            decoupling = internal_form(d.generator(name, used, plant.p), plant).coupling("d")
            cert = Certificate.of(
                name,
                [
                    *d.certificate.checks,
                    Check(
                        "internal form: largest normalised Markov parameter d → r",
                        decoupling,
                        1e-9,
                        "<=",
                        "the residual of a UIO does not see d: Tᵢ E = 0 makes every Markov parameter vanish to round-off",
                    ),
                ],
                d.certificate.info,
            ).require()
            gens.append(d.generator(name, used, plant.p))
            sigmas.append(d.Sigma_r)
            certs.append(cert)
    return gens, sigmas, certs


DEFAULT_DETECTOR = "wssr"
"""The bank's statistic when neither ``detector`` nor ``evaluator`` is given: the paper's WSSR."""

DEFAULT_WINDOW = 25
"""The window of :data:`DEFAULT_DETECTOR` when ``window`` is not given (samples)."""


def gos_diagnoser(
    plant: LinearPlant,
    groups: Sequence[Sequence[int]],
    *,
    name: str,
    problem: str,
    design: str,
    P_f: float,
    persistence: int = 1,
    evaluator: str = DEFAULT_DETECTOR,
    window: int | None = DEFAULT_WINDOW,
    sensors: Sequence[int] | None = None,
    faults: Sequence[FaultClass] | None = None,
    arl0: float | None = None,
    min_fault: Mapping[str, float] | None = None,
    options: Mapping[str, object] | None = None,
    where: str = "",
    shifts: Sequence[float] | None = None,
    false_isolation: float = FALSE_ISOLATION,
    isolation_memory: int | None = None,
) -> GainFile:
    """The gain file of the generalised observer scheme: :func:`gos_bank` with the linear diagnoser's statistics.

    Faults default to one class per diagnosed sensor, named after it; ``where`` prefixes a refused budget.
    """
    gens, sigmas, certs = gos_bank(plant, groups, sensors=sensors)
    if faults is None:
        diag = set(range(plant.p) if sensors is None else sensors)
        faults = [f for f in default_fault_classes(plant, gens) if all(plant.outputs.index(s) in diag for s in f.sensors) and not f.components]
    return linear_diagnoser(
        name=name,
        problem=problem,
        design=design,
        plant=plant,
        generators=gens,
        sigma_r=sigmas,
        P_f=P_f,
        faults=faults,
        certificates=certs,
        persistence=persistence,
        evaluator=evaluator,
        window=window,
        arl0=arl0,
        min_fault=min_fault,
        options=options,
        where=where,
        shifts=shifts,
        false_isolation=false_isolation,
        isolation_memory=isolation_memory,
    )


# --------------------------------------------------------------------------- the method


def _state_indices(value: Any, where: str, plant: LinearPlant) -> list[int]:
    if not isinstance(value, (list, tuple)) or not value:
        raise ArgumentError(f"{where} must be 'auto' or a non-empty list of state names, got {shown(value)}")
    idx: list[int] = []
    for j, s in enumerate(value):
        if not isinstance(s, str) or s not in plant.states:
            raise ArgumentError(f"{where}[{j}]: no state {shown(s)}; states are {list(plant.states)}")
        if plant.states.index(s) in idx:
            raise ArgumentError(f"{where} names state {s!r} twice")
        idx.append(plant.states.index(s))
    return idx


def _groups_option(value: Any, where: str, plant: LinearPlant | None) -> Any:
    if value == "auto" or plant is None:
        return value
    label = at(where, "groups")
    if not isinstance(value, (list, tuple)) or not value:
        raise ArgumentError(f"{label} must be 'auto' or a non-empty list of groups of output names, got {shown(value)}")
    return tuple(tuple(_sensor_indices(g, plant, f"{label}[{gi}]")) for gi, g in enumerate(value))


def _virtual_option(value: Any, where: str, plant: LinearPlant | None) -> Any:
    if value == "auto" or plant is None:
        return value
    return tuple(_state_indices(value, at(where, "virtual_outputs"), plant))


def _sensors_option(value: Any, where: str, plant: LinearPlant | None) -> Any:
    if plant is None:
        return value
    return tuple(_sensor_indices(value, plant, at(where, "sensors")))


def _training_option(value: Any, where: str, plant: LinearPlant | None) -> Any:
    """A trace CSV's path (a plant file's, resolved against its folder) or a :class:`~fdisyn.runtime.trace.Trace`."""
    if isinstance(value, Trace):
        return value
    if not isinstance(value, (str, PurePath)) or not str(value) or "\x00" in str(value):
        raise ArgumentError(f"{at(where, 'training')} must be the path of a trace CSV, got {shown(value)}")
    return str(value)


def _statistics(plant: LinearPlant, groups: Sequence[Sequence[int]], sensors: Sequence[int] | None) -> int:
    """The statistics of the bank :func:`gos_bank` builds: one per diagnosed sensor of each group."""
    want = set(range(plant.p) if sensors is None else sensors)
    return sum(1 for g in groups for s in g if s in want)


def _check(plant: Any, opts: Mapping[str, Any], where: str) -> None:
    kind = chosen_detector(opts.get("detector"), opts.get("evaluator"), where, default=DEFAULT_DETECTOR)
    check_window(kind, opts["window"], where)
    check_min_fault(kind, opts.get("min_fault"), where)
    check_shifts(kind, opts.get("shifts"), where)
    if isinstance(plant, LinearPlant):
        if plant.is_discrete and opts["Ts"] is not None:
            raise ArgumentError(f"{at(where, 'Ts')} = {shown(opts['Ts'])}: the plant is discrete (Ts = {plant.Ts}); give Ts for a continuous plant only")
        if not plant.is_discrete and opts["Ts"] is None:
            raise ArgumentError(f"{where}: missing option 'Ts': expected a positive sample time in seconds to sample the continuous plant")
        if opts["training"] is not None and plant.is_discrete:
            raise ArgumentError(
                f"{at(where, 'training')}: estimating E needs the continuous model (d₁ enters ẋ, Long & Wang 2017, eq. (4)); "
                "give [model].time = 'continuous' or E itself"
            )
        if opts["training"] is None and plant.q == 0:
            raise ArgumentError(f"{where}: the UIO bank needs the unknown-input matrix E: give [model].E, or the option training to estimate it")
    if opts["training"] is None and opts["virtual_outputs"] != "auto":
        raise ArgumentError(f"{at(where, 'virtual_outputs')} is read only with the option training (they observe d₁ while E is estimated)")
    ts = plant.Ts if isinstance(plant, LinearPlant) and plant.is_discrete else opts.get("Ts")
    if ts is not None:
        # the bank's size is known here when the groups are given; with 'auto' only P_f is checked (gos_design
        # checks arl0 once the groups are chosen, naming it the same way)
        groups = opts["groups"]
        count = _statistics(plant, groups, opts["sensors"]) if isinstance(plant, LinearPlant) and groups != "auto" else None
        if count or opts.get("arl0") is None:
            check_budget(kind, opts.get("P_f", P_F.default), opts.get("arl0"), float(ts), count or 1, where)


def _training_data(training: Any, plant: LinearPlant, virtual: Sequence[int], Ts: float, where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``U``, ``Y`` and the virtual states of a training trace, sampled every ``Ts``."""
    names = [plant.states[j] for j in virtual]
    label = at(where, "training")
    if isinstance(training, Trace):
        trace = training
        missing = [s for s in names if s not in trace.extra]
        if missing:
            raise ArgumentError(f"{label}: the trace has no column for the virtual output(s) {missing}")
        xv = np.column_stack([np.asarray(trace.extra[s], dtype=float) for s in names]) if names else np.zeros((trace.t.shape[0], 0))
        u, y, t = trace.U, trace.Y, trace.t
        if trace.inputs != plant.inputs or trace.outputs != plant.outputs:
            raise ArgumentError(f"{label}: the trace's inputs and outputs {list(trace.inputs + trace.outputs)} are not the plant's")
    else:
        try:
            trace = _read_training(training, plant.inputs, (*plant.outputs, *names))
        except TraceError as exc:
            raise TraceError(f"{label} {training}: {exc}") from None
        u, y, xv, t = trace.U, trace.Y[:, : plant.p], trace.Y[:, plant.p :], trace.t
    if t.shape[0] < 10:
        raise ArgumentError(f"{label}: {t.shape[0]} samples; the estimate needs a training run of many samples")
    t = np.asarray(t, dtype=float)
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:  # a NaN passes every comparison below unnoticed
        raise ArgumentError(
            f"{label}: the time t of sample {int(bad[0]) + 1} is {float(t[bad[0]])!r}; expected a finite time every Ts = {Ts:g} s"
        )
    step = np.diff(t)
    if not np.all(np.abs(step - Ts) <= 1e-6 * Ts):
        raise ArgumentError(f"{label}: the trace's time steps range over [{step.min():.6g}, {step.max():.6g}] s; expected every Ts = {Ts:g} s")
    return np.asarray(u, dtype=float), np.asarray(y, dtype=float), np.asarray(xv, dtype=float)


def _read_training(path: str, inputs: Sequence[str], outputs: Sequence[str]) -> Trace:
    """The trace CSV ``path`` (the replay grammar), which must be a regular file.

    A training trace is data a user may have received, like a plant file: a
    FIFO would block the design until some writer appeared, a device such as
    ``/dev/zero`` would be read without end. The file is opened without
    waiting (``O_NONBLOCK``) and anything but a regular file is refused before
    a byte is read. Errors are :class:`TraceError` (the caller adds the option's name).
    """
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as exc:
        raise TraceError(f"cannot read it: {exc.strerror or exc}") from None
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise TraceError("not a regular file (a FIFO, a device or a directory); expected a trace CSV")
    with os.fdopen(fd, "rb") as fh:
        try:
            blocks = list(TraceReader(fh, path, inputs=inputs, outputs=outputs).blocks())
        except OSError as exc:
            raise TraceError(f"cannot read it: {exc.strerror or exc}") from None
    m = len(inputs)
    data = np.concatenate(blocks) if blocks else np.zeros((0, 1 + m + len(outputs)))
    return Trace(t=data[:, 0], inputs=tuple(inputs), outputs=tuple(outputs), U=data[:, 1 : 1 + m], Y=data[:, 1 + m :])


@dataclass(frozen=True, eq=False)
class GosDesign:
    """What :func:`gos_design` chose besides the gain file: the groups, the virtual outputs and the ``E`` estimate."""

    gain_file: GainFile
    groups: tuple[tuple[int, ...], ...]
    virtual: tuple[int, ...] | None
    estimate: UnknownInputEstimate | None
    plant: LinearPlant
    """The discrete design plant (``E`` estimated or given, scaled states)."""


def gos_design(
    plant: LinearPlant,
    *,
    name: str,
    problem: str | None = None,
    record: Mapping[str, object] | None = None,
    where: str = "",
    P_f: float,
    persistence: int = 1,
    evaluator: str | None = None,
    window: int | None = None,
    detector: str | None = None,
    arl0: float | None = None,
    min_fault: Mapping[str, float] | None = None,
    shifts: Sequence[float] | None = None,
    faults: Sequence[FaultClass] | None = None,
    Ts: float | None = None,
    false_isolation: float = FALSE_ISOLATION,
    isolation_memory: int | None = None,
    groups: Any = "auto",
    virtual_outputs: Any = "auto",
    sensors: Sequence[int] | None = None,
    training: Any = None,
    d_rate: float = 1.0,
    rank_gap: float = RANK_GAP_MIN,
    E_rank: int | None = None,
) -> GosDesign:
    """The generalised UIO bank of Long & Wang 2017 on ``plant``, every choice of the paper made from data.

    ``groups``: ``"auto"`` (:func:`output_groups`, the best-conditioned of the
    fewest groups) or explicit groups of output indices, which must cover
    ``sensors`` (default: every output). ``training`` (a trace with the inputs,
    the outputs and the virtual outputs' state columns, fault-free, sampled
    every ``Ts``) estimates ``E`` (:func:`estimate_unknown_input`, on the first
    group completed by ``virtual_outputs``; ``E_rank`` overrides the rank the
    gap gives); the process noise of a plant without one becomes the mismatch
    ``E`` leaves out, as white noise of the same low-frequency power
    (:meth:`UnknownInputEstimate.left_out_intensity` over lags up to three
    times the slowest open-loop time constant). The UIOs are designed in states
    scaled by the estimate's state magnitudes (their residuals do not depend
    on it). Without ``training`` the plant's own ``E`` is decoupled.
    """
    where = where or "method 'kalman_uio_gos'"
    evaluator = chosen_detector(detector, evaluator, where, default=DEFAULT_DETECTOR)
    if window is None:
        window = DEFAULT_WINDOW if evaluator == DEFAULT_DETECTOR else None if evaluator in windowed_kinds() else 1
    want = tuple(range(plant.p)) if sensors is None else tuple(sensors)
    if groups == "auto":
        try:
            grouping = output_groups(plant.C, want, outputs=plant.outputs)[0].groups
        except ExistenceError as exc:
            raise ExistenceError(f"{at(where, 'groups')} = 'auto': {exc}") from None
    else:
        grouping = tuple(tuple(g) for g in groups)
        uncovered = [plant.outputs[s] for s in want if not any(s in g for g in grouping)]
        if uncovered:
            raise ArgumentError(
                f"{at(where, 'groups')}: sensor(s) {uncovered} are in no group; every diagnosed sensor must be in one "
                "(or leave them out with the option sensors)"
            )
    ts = plant.Ts if plant.is_discrete else Ts
    if ts is not None:  # the budget against the bank's size, before E is estimated
        check_budget(evaluator, P_f, arl0, float(ts), _statistics(plant, grouping, want), where)
    est, virt = None, None
    model = plant
    if training is not None:
        g0 = grouping[0]
        if virtual_outputs == "auto":
            c = np.asarray(plant.C)
            basis: list[int] = []
            for j in g0:  # a group of dependent outputs (an ungrouped bank): complete an independent subset
                if rank(c[[*basis, j]]) > len(basis):
                    basis.append(j)
            try:
                virt = _completion(c, basis)
            except ExistenceError as exc:
                raise ExistenceError(f"{at(where, 'virtual_outputs')} = 'auto', group 1 {[plant.outputs[j] for j in g0]}: {exc}") from None
        else:
            virt = tuple(virtual_outputs)
        u, y, xv = _training_data(training, plant, virt, ts, where)  # type: ignore[arg-type]
        try:
            est = estimate_unknown_input(
                plant, ts, u, y, xv, group=g0, virtual=virt, d_rate=d_rate, rank_gap=rank_gap, rank_fixed=E_rank  # type: ignore[arg-type]
            )
        except ExistenceError as exc:
            raise ExistenceError(f"{at(where, 'training')}: group 1 {[plant.outputs[j] for j in g0]}: {exc}") from None
        q_model = np.asarray(plant.Q)
        if not np.any(q_model):
            lam = np.linalg.eigvals(np.asarray(plant.A)).real
            slowest = 1.0 / float(np.min(-lam)) if np.all(lam < 0) else 0.0
            q_model = est.left_out_intensity(max(3.0 * slowest, 10 * ts))  # type: ignore[operator]
        model = LinearPlant.create(
            A=plant.A, B=plant.B, C=plant.C, D=plant.D, E=est.E, Fx=plant.Fx, Q=0.5 * (q_model + q_model.T), R=plant.R,
            states=plant.states, inputs=plant.inputs, outputs=plant.outputs,
            unknown_inputs=tuple(f"d{i + 1}" for i in range(est.rank)), component_faults=plant.component_faults,
            # the estimated unknown inputs replace the plant's: their units and labels go with them
            units={k: v for k, v in plant.units.items() if k not in plant.unknown_inputs},
            labels={k: v for k, v in plant.labels.items() if k not in plant.unknown_inputs},
        )
    discrete = model if model.is_discrete else model.discretise(ts)  # type: ignore[arg-type]
    if est is not None:
        discrete = discrete.scaled(est.scale)
    info = {
        "groups": [[plant.outputs[j] for j in g] for g in grouping],
        **({} if virt is None else {"virtual_outputs": [plant.states[j] for j in virt]}),
        **(
            {}
            if est is None
            else {"E_rank": est.rank, "E_gap": est.gap, "E_singular_values": [float(x) for x in est.singular_values], "E": est.E.tolist()}
        ),
    }
    gf = gos_diagnoser(
        discrete,
        grouping,
        name=name,
        problem=problem or name,
        design="kalman_uio_gos",
        P_f=P_f,
        persistence=persistence,
        evaluator=evaluator,
        window=window,
        sensors=want,
        faults=faults,
        arl0=arl0,
        min_fault=min_fault,
        options={**(record or {}), "chosen": info},
        where=where,
        shifts=shifts,
        false_isolation=false_isolation,
        isolation_memory=isolation_memory,
    )
    return GosDesign(gain_file=gf, groups=grouping, virtual=virt, estimate=est, plant=discrete)


def _register() -> None:
    from fdisyn.synthesis.linear_diagnoser import (
        EVALUATOR, FALSE_ISOLATION_OPTION, FAULTS, ISOLATION_MEMORY, LINEAR_WINDOW, MIN_FAULT, SHIFTS, TS,
    )
    from fdisyn.synthesis.registry import ARL0, DETECTOR, P_F, PERSISTENCE, Method, is_count, is_real, register

    options = (
        P_F,
        ARL0,
        PERSISTENCE,
        replace(DETECTOR, doc=DETECTOR.doc.replace("(default: evaluator's value)", "(default: evaluator's value, 'wssr')")),
        replace(EVALUATOR, doc="the statistic of each generator (the same option as detector, its earlier name; default 'wssr')"),
        replace(LINEAR_WINDOW, default=None, doc="WSSR window N in samples, or the GLR's onset window (default 25 for 'wssr', chosen for 'glr')"),
        MIN_FAULT,
        SHIFTS,
        FAULTS,
        FALSE_ISOLATION_OPTION,
        ISOLATION_MEMORY,
        TS,
        Option(
            "groups",
            "auto",
            "groups of linearly independent outputs, one UIO per diagnosed sensor in each: 'auto' (fewest groups, best conditioned) or a list of lists of output names",
            "'auto' or a list of lists of output names",
            lambda v: v == "auto" or isinstance(v, (list, tuple)),
            _groups_option,
        ),
        Option(
            "virtual_outputs",
            "auto",
            "states of the model that complete the first group to rank n while E is estimated: 'auto' (best conditioned) or a list of state names",
            "'auto' or a list of state names",
            lambda v: v == "auto" or isinstance(v, (list, tuple)),
            _virtual_option,
        ),
        Option("sensors", None, "the outputs to diagnose (default: all)", "a list of output names", lambda v: isinstance(v, (list, tuple)), _sensors_option),
        Option(
            "training",
            None,
            "fault-free training data to estimate E from: a trace CSV (columns t, the inputs, the outputs and the virtual outputs' states)",
            "the path of a trace CSV",
            lambda v: isinstance(v, (str, PurePath, Trace)),
            _training_option,
        ),
        Option(
            "d_rate",
            1.0,
            "random-walk rate of d₁ in the estimator, in state magnitudes per second (smaller: smoother, slower estimate)",
            "a positive number",
            lambda v: is_real(v) and v > 0,
        ),
        Option(
            "E_rank",
            None,
            "the rank of the estimated E, overriding the gap rule (default: read from the largest gap ≥ rank_gap)",
            "a whole number ≥ 1",
            is_count,
        ),
        Option(
            "rank_gap",
            RANK_GAP_MIN,
            "smallest singular-value ratio σ_q/σ_(q+1) accepted as the rank gap of the E estimate",
            "a number > 1",
            lambda v: is_real(v) and v > 1,
        ),
    )

    def design(plant: LinearPlant, *, name: str, problem: str | None = None, record: Mapping[str, object] | None = None, where: str = "", **opts: Any) -> GainFile:
        return gos_design(plant, name=name, problem=problem, record=record, where=where, **opts).gain_file

    register(
        Method(
            name="kalman_uio_gos",
            plant_kind="linear",
            summary="generalised observer scheme: per group of independent outputs, one minimum-variance UIO per sensor fed the others; E estimated from training data",
            reference="Long & Wang, Aeroengine 43(5), 2017, eqs. (4)-(6), section 2; Frank, Automatica 26(3), 1990",
            options=options,
            design=design,
            diagnoser_kind="linear",
            check=_check,
            samples_itself=True,
        )
    )


_register()
