"""The isolation test of a linear bank: which fault class explains the residuals, by a generalised likelihood ratio
across the classes' hypotheses, with a designed false-isolation probability.

The step keeps the exponentially weighted sum of the stacked residual, ``s ← λ s + r``; without a fault it is
Gaussian with the covariance :func:`~fdisyn.synthesis.residual.evidence_covariance` ``V`` (exact, from the residuals'
autocovariances on the design's noise model). A fault of class ``f`` (any size, any sign, on each of its sensors
and components) moves its mean, once the generators have settled, into the span of the members' steady-state
residual responses ``M_f`` (:func:`~fdisyn.synthesis.residual.fault_steady_state`). The GLR of that hypothesis
against no fault is ``g_f = sᵀ V⁺ M_f (M_fᵀ V⁺ M_f)⁻¹ M_fᵀ V⁺ s``, and what it leaves, ``e_f = sᵀ V⁺ s − g_f``,
is χ² with ``rank V − rank M_f`` degrees of freedom when ``f`` is the fault (Basseville & Nikiforov, *Detection
of Abrupt Changes*, Prentice Hall 1993, section 4.2.8, the GLR of a change in a known subspace). Each class is
rejected or kept by its own test at the level ``α`` (the probability that the true class is rejected at one
sample); the diagnosis is the classes that are not rejected (Nyberg, *Model Based Fault Diagnosis*, Linköping
Studies in Science and Technology, Dissertation 591, 1999, structured hypothesis tests). The step names a class
only when every other plausible class contains it, and holds it (:class:`~fdisyn.runtime.gainfile.Isolation`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np
from fdisyn.models.linear import LinearPlant
from fdisyn.numerics.linalg import spectral_radius
from fdisyn.runtime.gainfile import Generator, Isolation
from fdisyn.runtime.schema import LIMITS, MAX_MAGNITUDE
from fdisyn.synthesis.residual import evidence_covariance, fault_steady_state, fault_step_response, internal_form

__all__ = ["FALSE_ISOLATION", "isolation_memory", "isolation_design"]

FALSE_ISOLATION = 1e-3
"""The default level of the isolation test: the probability that the true class is rejected at one sample. A
wrong class is named only when the true one is rejected and every other is too but one, so this bounds the chance
of a wrong name at a sample where one is given; the Monte Carlo measures the false isolations over whole runs."""

SPAN_RTOL = 1e-6
"""A direction of a class's span counts when its squared length in the precision's metric exceeds this fraction of
its member's own larger one, the designed steady shift's or its transient's sum's (the ``(1 − λ)``-scaled steady
shift and the transient's sum compared on one scale). Per member, since the test is about directions, not sizes: a
member the residuals see weakly (a sensor in other units, a component fault of unit size) keeps its span beside a
strongly seen one. A direction below it adds at most this fraction of a fault's noncentrality to its class's misfit
(it matters only for a fault a thousand times the designed minimum held for a memory), and one above it is resolved
to within the design's round-off divided by ``√SPAN_RTOL``."""

CANONICAL_RTOL = 1e-3
"""A coordinate axis's projection onto a class's span, once the axes before it are taken out, joins the span's
canonical basis when its squared length exceeds this (at most the reciprocal of the evidence's dimension, so the
pass always finds the span's rank; an axis at this length is resolved to within round-off divided by
``√CANONICAL_RTOL``)."""

PRECISION_RTOL = 1e-8
"""Directions of the evidence's covariance below this fraction of its largest eigenvalue are left out of its
pseudo-inverse: a residual combination with (nearly) no noise would weigh any model error as overwhelming evidence,
and its weight would follow the round-off of the design (a different BLAS kernel) instead of the plant."""

MEMORY_MIN, MEMORY_MAX = 50, 2000
"""The evidence's memory ``1/(1 − λ)`` is chosen in this range (samples)."""


def isolation_memory(gens: Sequence[Generator], windows: Sequence[int]) -> int:
    """The evidence's memory when not given: ten times the slowest generator's time constant (so the sum sees
    many correlation times and its Gaussian law holds) and four statistics' windows, within
    :data:`MEMORY_MIN`…:data:`MEMORY_MAX` samples."""
    tau = 0.0
    for g in gens:
        rho = spectral_radius(np.asarray(g.Ar)) if g.n_state else 0.0
        if 0.0 < rho < 1.0:
            tau = max(tau, -1.0 / math.log(rho))
    want = max(float(MEMORY_MIN), 10.0 * tau, 4.0 * max(windows, default=1))
    return int(min(MEMORY_MAX, math.ceil(want)))


def _members(f: Any) -> list[tuple[str, str]]:
    return [("sensor", s) for s in f.sensors] + [("component", c) for c in f.components]


SETTLE_MAX = 5000
"""The longest step response summed for a member's transient (samples)."""


def _stacked_response(gens: Sequence[Generator], plant: LinearPlant, sensors: np.ndarray, components: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(m, c)``: the stacked residuals' steady-state shift under a step fault and its transient's sum
    ``c = Σ_ℓ (ρ(ℓ) − m)`` (:func:`~fdisyn.synthesis.residual.fault_step_response` until it has settled).

    Once the transient has passed, the evidence's mean ``Σ_ℓ λ^{n−1−ℓ} ρ(ℓ)`` is ``(1 − λⁿ)/(1 − λ) m`` plus a
    multiple of (nearly) ``c``, whatever the time ``n`` since the onset; and a ramp's response, the step response
    summed, is ``(ℓ + 1) m + c``. So ``span{m, c}`` holds a member's steps and drifts of any size and age."""
    ms, cs = [], []
    for g in gens:
        steady = fault_steady_state(g, plant, sensors, components)
        rho_g = spectral_radius(internal_form(g, plant).A)
        lags = SETTLE_MAX if not 0.0 <= rho_g < 1.0 else int(min(SETTLE_MAX, max(50, math.ceil(40.0 / max(-math.log(max(rho_g, 1e-300)), 1e-12)))))
        rho = fault_step_response(g, plant, sensors, components, lags)
        m = np.asarray(rho[-1] if steady is None else steady, dtype=float).reshape(-1)
        ms.append(m)
        cs.append((rho - m).sum(axis=0))
    return np.concatenate(ms), np.concatenate(cs)


def isolation_design(
    plant: LinearPlant,
    gens: Sequence[Generator],
    faults: Sequence[Any],
    sizes: Mapping[str, tuple[np.ndarray, np.ndarray]],
    *,
    level: float = FALSE_ISOLATION,
    memory: int | None = None,
    windows: Sequence[int] = (),
) -> tuple[Isolation | None, dict[str, Any]]:
    """The isolation test of the bank ``gens`` for the fault classes ``faults``.

    Parameters
    ----------
    plant : LinearPlant
        The discrete plant the generators were designed on (its noise model gives the evidence's law).
    gens : sequence of Generator
        The generators, in the order of the stacked residual.
    faults : sequence
        The fault classes (``name``, ``sensors``, ``components``).
    sizes : mapping
        Each class's designed minimum fault ``(sensor biases, component faults)``: each member's share of it spans
        the class's hypothesis.
    level : float
        The test's level :data:`FALSE_ISOLATION`.
    memory : int or None
        The evidence's memory ``1/(1 − λ)`` in samples; ``None``: :func:`isolation_memory`.
    windows : sequence of int
        The statistics' windows (the default memory is at least four of them).

    Returns
    -------
    tuple
        The :class:`~fdisyn.runtime.gainfile.Isolation` (``None`` when it would exceed the gain file's size limit)
        and what the design found: the memory, the evidence's rank, each class's hypothesis dimension and, per pair
        of classes, the separation ``min_ν e_k`` under the other's designed minimum fault held for one memory
        (the noncentrality that rejects ``k``; a pair separated by less than the rejection level cannot be told
        apart at that size).
    """
    nr = sum(g.n_residual for g in gens)
    nf = len(faults)
    mem = isolation_memory(gens, windows) if memory is None else int(memory)
    lam = 1.0 - 1.0 / mem
    info: dict[str, Any] = {"memory_samples": mem, "level": float(level)}
    if nr * 2 * nf + 4 * nf * nf > LIMITS["isolation_coefficients"]:
        info["skipped"] = f"{nr} residuals and {nf} classes exceed the isolation test's size limit"
        return None, info
    v = evidence_covariance(gens, plant, lam)
    ev, vec = np.linalg.eigh(v)
    keep = ev > PRECISION_RTOL * max(float(ev[-1]), 1e-300)
    precision = (vec[:, keep] / ev[keep]) @ vec[:, keep].T
    precision = 0.5 * (precision + precision.T)
    rank = int(np.sum(keep))
    # each member's steady response at the class's designed size, scaled to the evidence's mean after one memory
    responses: list[np.ndarray] = []
    spans: list[np.ndarray] = []
    class_floors: list[np.ndarray] = []
    for f in faults:
        sens, comp = sizes[f.name]
        cols, shifts, floors = [], [], []
        for kind, name in _members(f):
            s1, c1 = np.zeros_like(sens), np.zeros_like(comp)
            if kind == "sensor":
                j = plant.outputs.index(name)
                s1[j] = sens[j]
            else:
                j = plant.component_faults.index(name)
                c1[j] = comp[j]
            steady, transient = _stacked_response(gens, plant, s1, c1)
            shifts.append(steady / (1.0 - lam))  # the evidence's mean once settled, at the designed size
            cols += [steady / (1.0 - lam), transient]
            # the member's own scale: its larger column's (none: a member the residuals do not see)
            seen = max(float(c @ precision @ c) for c in cols[-2:])
            floors += [SPAN_RTOL * seen if seen > 0.0 else np.inf] * 2
        responses.append(np.column_stack(shifts) if shifts else np.zeros((nr, 0)))
        spans.append(np.column_stack(cols) if cols else np.zeros((nr, 0)))
        class_floors.append(np.array(floors))
    if not any(np.isfinite(f).any() for f in class_floors):
        info["skipped"] = "the residuals see no fault class at steady state"
        return None, info
    # the evidence's coordinates: an orthonormal basis, in the precision's metric, of the union of the classes' spans
    # (what lies outside it tells no class from another); a direction the evidence does not see (a transient that
    # sums to nothing, a member the residuals do not see) is left out
    union = np.column_stack([m for m in spans if m.size])  # one member at least is seen (checked above)
    basis = (precision @ _gram_schmidt(union, precision, np.concatenate(class_floors))).T
    rank = basis.shape[0]
    rows, ranks = [], []
    for m, fl in zip(spans, class_floors, strict=True):
        # the class's span in the evidence's coordinates, where the noise is white: its canonical orthonormal basis
        q = _canonical(_gram_schmidt(basis @ m, np.eye(rank), fl)) if m.size else np.zeros((rank, 0))
        if not q.shape[1]:
            ranks.append(0)
            continue
        rows.append(q.T)
        ranks.append(q.shape[1])
    directions = np.vstack(rows) if rows and sum(ranks) else np.zeros((0, rank))
    chi2 = _chi2_isf()
    accept = np.array([chi2(level, max(k, 1)) for k in ranks])
    reject = np.array([chi2(level, rank - k) if rank - k >= 1 else MAX_MAGNITUDE for k in ranks])
    members = [set(_members(f)) for f in faults]
    nested = np.array([[int(k != f and members[f] <= members[k]) for k in range(nf)] for f in range(nf)], dtype=int)
    iso = Isolation(level=float(level), forgetting=lam, basis=basis, directions=directions,
                    ranks=np.array(ranks, dtype=int), accept=accept, reject=reject, nested=nested)
    iso = replace(iso, settle=_settle(iso, plant, gens, faults, sizes, mem))
    info.update(rank=rank, ranks={f.name: k for f, k in zip(faults, ranks, strict=True)}, settle_samples=iso.settle,
                separation=_separation(iso, faults, responses))
    return iso, info


SETTLE_FRACTION = 1e-2
"""A class's noise-free evidence has settled into its span once the span leaves less than this fraction of its
whitened energy unexplained (and never more later)."""


def _settle(iso: Isolation, plant: LinearPlant, gens: Sequence[Generator], faults: Sequence[Any],
            sizes: Mapping[str, tuple[np.ndarray, np.ndarray]], memory: int) -> int:
    """Alarmed samples before a class may be named: one more than the faulty samples after which every member's
    noise-free evidence (a step at its class's designed size, from rest) stays within :data:`SETTLE_FRACTION` of its
    class's span, at most ``memory``. Before then the transient of the true class may reject it while a wrong one fits."""
    from fdisyn.runtime.reference import isolation_test

    horizon = int(min(memory, 500))
    last = -1
    for f, cls in enumerate(faults):
        sens, comp = sizes[cls.name]
        for kind, name in _members(cls):
            s1, c1 = np.zeros_like(sens), np.zeros_like(comp)
            if kind == "sensor":
                s1[plant.outputs.index(name)] = sens[plant.outputs.index(name)]
            else:
                c1[plant.component_faults.index(name)] = comp[plant.component_faults.index(name)]
            rho = np.hstack([fault_step_response(g, plant, s1, c1, horizon) for g in gens]) @ np.asarray(iso.basis).T
            ev = np.zeros(rho.shape[1])
            for n in range(horizon):
                ev = iso.forgetting * ev + rho[n]
                test = isolation_test(iso, ev)
                energy = float(test.evidence[f] + test.misfit[f])
                if energy > 0.0 and test.misfit[f] > SETTLE_FRACTION * energy:
                    last = max(last, n)
    return int(min(memory, max(1, last + 2)))


def _gram_schmidt(m: np.ndarray, metric: np.ndarray, floors: np.ndarray) -> np.ndarray:
    """Columns spanning ``range(m)``, orthonormal in ``metric`` (``xᵀ metric y``), by Gram–Schmidt in the columns'
    order with a second pass (Giraud et al., Numerische Mathematik 101, 2005): column ``i`` whose remainder's squared
    length is at most ``floors[i]`` is left out. The result is unique for a given ``m`` (no eigenvector's arbitrary
    sign or rotation). The transposed rows times ``metric`` are the evidence's coordinates ``B`` (``B V Bᵀ = I``
    with ``V = metric⁺``: the evidence ``B s`` has unit covariance)."""
    kept: list[np.ndarray] = []
    for c, floor in zip(m.T, np.broadcast_to(floors, (m.shape[1],)), strict=True):
        v = np.asarray(c, dtype=float).copy()
        for _ in range(2):
            for b in kept:
                v = v - float(b @ metric @ v) * b
        norm2 = float(v @ metric @ v)
        if norm2 > floor:
            kept.append(v / np.sqrt(norm2))
    return np.column_stack(kept) if kept else np.zeros((m.shape[0], 0))


def _canonical(q: np.ndarray) -> np.ndarray:
    """The orthonormal basis of ``range(q)`` (``q`` orthonormal) that depends on the subspace alone: Gram–Schmidt of
    its projections of the coordinate axes, in their order (:data:`CANONICAL_RTOL`). The class's spanning vectors
    (a steady shift, a transient's sum) turn within the span with the design's round-off far more than the span
    does; the test reads only the span, and so does the gain file this way."""
    k, r = q.shape
    if r == k:
        return np.eye(k)
    if r == 0:
        return q
    proj = q @ q.T
    out = _gram_schmidt(proj, np.eye(k), np.full(k, min(CANONICAL_RTOL, 0.5 / k)))
    assert out.shape[1] == r, "the axes' projections span the class's span (their squared lengths sum to its rank)"
    return out


def _chi2_isf() -> Any:
    from scipy.stats import chi2

    return lambda p, k: float(chi2.isf(p, k))


def _separation(iso: Isolation, faults: Sequence[Any], responses: Sequence[np.ndarray]) -> dict[str, dict[str, float]]:
    """Per true class ``f`` and other class ``k``: the misfit ``e_k`` of the noise-free evidence under ``f``'s
    designed minimum fault (its members at their designed sizes, in the worst-aligned combination of unit size
    when ``f`` has several), against ``k``'s rejection level: a ratio above 1 means ``k`` is rejected there."""
    from fdisyn.runtime.reference import isolation_test

    out: dict[str, dict[str, float]] = {}
    for f, m in zip(faults, responses, strict=True):
        if not m.size:
            continue
        test = isolation_test(iso, np.asarray(iso.basis) @ m.sum(axis=1))
        out[f.name] = {
            k.name: round(float(test.misfit[i] / iso.reject[i]), 6) for i, k in enumerate(faults) if k.name != f.name
        }
    return out
