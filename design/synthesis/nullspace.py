"""The nullspace method: one least-order residual generator per row of a structure matrix (Varga, *Solving Fault
Diagnosis Problems: Linear Synthesis Techniques*, Springer 2017, Procedures EFD and EFDI, secs. 5.2–5.3; the
functions ``efdsyn`` and ``efdisyn`` of his FaultDetectionTools.jl).

For a row ``s`` (one entry per fault in the plant's fault order, :func:`~fdisyn.synthesis.structure.fault_entries`)
the faults with ``s_j = 0`` join the unknown inputs: the residual ``r = Q(z) [y; u]`` must annihilate
``G_e = [G_u G_d G_f,zeros; I 0 0]``. The polynomial left null vectors of ``G_e``'s system pencil of the row's least
order ``k`` (:mod:`fdisyn.synthesis.structure`) are computed as a block Toeplitz null space
(:func:`~fdisyn.numerics.pencils.polynomial_left_null`); a combination ``v(z)`` of them that sees every fault of
the row, over the stable denominator ``φ(z) = (z − pole)ᵏ``, is the filter ``Q = v/φ``: a generator of order ``k``
in observable canonical form, written as fdisyn's canonical generator. Without ``structure`` the bank is one
generator for detection: the row of every fault the plant lets a residual see (``efdsyn``).

The certificate is independent of that construction: ``R_u = Q_y G_u + Q_u`` and ``R_d = Q_y G_d`` evaluated from
the generator's own matrices and the plant's at points on the unit circle (a rational function of degree at most
``n + k`` that vanishes at more points than twice that is zero), each fault's response against the row, the order
against the least order and the poles against the requested ones; the certificate's information holds the filter's
fault-to-noise gap (:mod:`fdisyn.synthesis.gap`, computed by SLICOT ``AB13DD`` on the filter's own responses).

The combination of the row's null vectors: ``synthesis = "exact"`` (Varga's ``efdsyn``/``efdisyn``) takes a generic
one, checked to see every fault of its row; ``"approximate"`` (``afdsyn``/``afdisyn``) the one of the largest
fault-to-noise gap, ``min_j ‖R_fj‖∞ / ‖R_w‖∞`` with the noise of the plant's ``Q`` and ``R``, maximised on a grid of
the stability boundary from several starts (Nelder–Mead). Varga's procedures go further where the noise can be
whitened: they divide the filter by the quasi-co-outer factor of ``R_w`` (``goifac``), which raises its order; fdisyn
keeps the least order and a common pole, so its gap is the best at that order and pole, not the supremum over all
filters; the pole, unless given, is chosen for the gap from 0, 0.1, …, 0.9 (:data:`POLE_CHOICES`; 0 makes the filter
a parity relation of finite memory, which on fast-sampled plants often has the largest gap).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from fdisyn.models.linear import LinearPlant
from fdisyn.numerics.certificate import Certificate, Check
from fdisyn.runtime.errors import ArgumentError, ExistenceError
from fdisyn.runtime.gainfile import GainFile, Generator
from fdisyn.runtime.names import shown
from fdisyn.synthesis.gap import boundary_points, generator_performance, noise_entries, relative_responses, transfer_at
from fdisyn.synthesis.residual import embed_outputs, residual_covariance
from fdisyn.synthesis.registry import is_real as is_number
from fdisyn.synthesis.structure import FaultPencils, StructureAnalysis, fault_entries, frequency_points

__all__ = ["DECOUPLING_TOL", "SYNTHESES", "nullspace_generator", "row_filter", "least_order_filter", "analyse_gaps"]

SYNTHESES = ("approximate", "exact")
"""How a row's least-degree null vectors are combined (:func:`row_filter`)."""

DECOUPLING_TOL = 1e-8
"""``‖R_u(z)‖`` and ``‖R_d(z)‖`` relative to ``‖Q(z)‖ ‖G_e(z)‖`` at the test points, and a decoupled fault's
response relative to ``‖Q(z)‖ ‖G_fj(z)‖``: the filter is the exact null vector of a pencil whose rank decisions are
made on the balanced plant, so its products with the plant vanish to round-off (measured below 1e-12 on the seeded
plants of the tests), while a fault the residual sees stays above :data:`SEEN_TOL`."""

SEEN_TOL = 1e-6
"""A fault the row asks for must reach at least this (same relative measure) at one of the test points."""

GAP_FLOOR = 1e-3
"""The approximate synthesis keeps every fault of the row at least this fraction of the response the best combination
could give it alone: Varga's gap is scale-free in the faults, and where it is as large for a combination that all but
loses one fault (e.g. a row whose noise enters with only some of its faults), the optimum would drift to a residual
that sees that fault a million times weaker than it could."""

GAP_PULL = 1e-3
"""The weight of the pull towards the chosen start in the approximate synthesis's objective (times the squared
distance of unit combinations, at most 4): it makes the optimum unique where the gap is flat, and costs at most
0.4 % of the gap."""

GAP_GAIN = 1.01
"""The approximate synthesis keeps the generic combination of the exact synthesis unless its optimum raises the gap
by more than this factor: equal gaps are no reason to leave the combination that sees every fault generically."""

POLE_CHOICES = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9)
"""The poles a filter's common pole is chosen from when none is given: the one of the largest gap (0 makes the filter a
parity relation of finite memory); 0.5 when the noise does not reach the residual."""

POLE_TIE = 1.01
"""Gaps within this factor of the largest are equal for the choice of the pole, and the slowest of their poles is
taken: the H∞ gap does not see the noise's variance, which a slower filter lowers and a χ² threshold follows."""

DEFAULT_POLE = 0.5

COMBINATION_SEED = 20170501
"""The seed of the generic null vector (a fixed standard normal draw projected onto the null space): fixed, so a
design is reproducible, and a projection, so it does not depend on the basis a BLAS kernel's SVD returns."""


def _realise(v: np.ndarray, k: int, pole: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``v(z)/φ(z)`` with ``v(z) = Σᵢ vᵢ zⁱ`` (rows of ``v``) and ``φ = (z − pole)ᵏ``: observable canonical
    ``(Ar, B, Cr, D)``, ``B`` and ``D`` over the filter's inputs."""
    phi = np.poly(np.full(k, pole))[::-1] if k else np.ones(1)  # a₀ … a_{k−1}, 1
    d = v[k]
    if k == 0:
        return np.zeros((0, 0)), np.zeros((0, v.shape[1])), np.zeros((1, 0)), d[None, :]
    ar = np.zeros((k, k))
    ar[1:, :-1] = np.eye(k - 1)
    ar[:, -1] = -phi[:k]
    b = v[:k] - phi[:k, None] * d[None, :]
    cr = np.zeros((1, k))
    cr[0, -1] = 1.0
    return ar, b, cr, d[None, :]


def _grid(plant: LinearPlant, pole: float, count: int = 160) -> np.ndarray:
    """Points of the plant's stability boundary the gap is optimised on: the unit circle, or the imaginary axis over
    the decades of the plant's and the filter's poles; off the real axis, so an integrator's pole is never hit."""
    if plant.is_discrete:
        return np.exp(1j * np.pi * (np.arange(count) + 0.5) / count)
    mags = np.abs(np.concatenate([np.linalg.eigvals(np.asarray(plant.A, float)) if plant.n else np.zeros(0), [pole]]))
    mags = mags[mags > 0]
    lo, hi = (float(np.min(mags)), float(np.max(mags))) if mags.size else (1.0, 1.0)
    return 1j * np.logspace(np.log10(lo) - 3, np.log10(hi) + 3, count)


class _GridGap:
    """``min_j max_λ |h·F_j(λ)| / max_λ ‖h·W(λ)‖`` on the grid for unit ``h`` (``F``: faults × count × points, ``W``:
    points × count × noise inputs); 0 when a fault's response is below :data:`GAP_FLOOR` of the most any unit ``h``
    gets from it, the noise's ignored below round-off (then the gap is infinite)."""

    def __init__(self, fault: np.ndarray, noise: np.ndarray, *, at_points: bool = False) -> None:
        nf, count, g = fault.shape
        self.reduce = np.min if at_points else np.max  # the faults' H∞ norm on the grid, or their least gain at the points
        self.shape_f, self.shape_w = (nf, g), (noise.shape[0], noise.shape[2])
        # count × everything: one product with h per evaluation
        self.fault = np.ascontiguousarray(np.transpose(fault, (1, 0, 2)).reshape(count, -1))
        self.noise = np.ascontiguousarray(np.transpose(noise, (1, 0, 2)).reshape(count, -1))
        self.floor = GAP_FLOOR * np.max(np.linalg.norm(fault, axis=1), axis=1)
        self.noise_floor = 1e-12 * float(np.max(np.linalg.norm(noise, axis=(1, 2)))) if noise.size else 0.0

    def __call__(self, h: np.ndarray) -> float:
        top_f = self.reduce(np.abs(h @ self.fault).reshape(self.shape_f), axis=1)
        if not np.all(top_f > self.floor):
            return 0.0
        if not self.noise.size:
            return math.inf
        top_w = float(np.sqrt(np.max(np.sum(np.abs(h @ self.noise).reshape(self.shape_w) ** 2, axis=1))))
        return math.inf if not top_w > self.noise_floor else float(np.min(top_f)) / top_w


def _best_combination(
    basis: np.ndarray, plant: LinearPlant, fault_cols: list[tuple[np.ndarray, np.ndarray]], pole: float, start: np.ndarray, at: Sequence[complex] = ()
) -> np.ndarray:
    """The combination of the null vectors ``basis`` (count × (k + 1) × (p + m), user units) of the largest
    fault-to-noise gap on :func:`_grid`: of the generic one ``start``, each basis direction and each fault's
    generalised eigenvector of its energy against the noise's, the first within :data:`GAP_GAIN` of the best, then
    polished by Nelder–Mead on the grid's gap pulled towards it (:data:`GAP_PULL`). ``start`` is a vector of the space (``(k + 1) × (p + m)``). With points ``at`` (frequencies of a strong
    structure), the faults' H∞ norm is replaced by their least gain at those points (Varga's gap with ``freq``)."""
    from scipy.optimize import minimize

    count, k = basis.shape[0], basis.shape[1] - 1
    bw, dw = noise_entries(plant)
    if count == 1 or not bw.shape[1]:
        return start
    # an orthonormal basis of the same space that does not depend on the one the SVD returned: the projector onto it
    # applied to fixed draws, orthonormalised in a fixed order
    flat = basis.reshape(count, -1)
    qx, _ = np.linalg.qr(flat.T)
    draws = np.random.default_rng(COMBINATION_SEED + 1).standard_normal((flat.shape[1], count))
    canon, _ = np.linalg.qr(qx @ (qx.T @ draws))
    flat = canon.T
    basis = flat.reshape(count, k + 1, -1)
    grid = np.concatenate([_grid(plant, pole), np.asarray(at, dtype=complex)])
    p, n = plant.p, plant.n
    a, c = np.asarray(plant.A, float), np.asarray(plant.C, float)
    bf = np.stack([b for b, _ in fault_cols], axis=1)
    df = np.stack([d for _, d in fault_cols], axis=1)
    entries_b, entries_d = np.hstack([bf, bw]), np.hstack([df, dw])
    if n:
        res = np.linalg.solve(grid[:, None, None] * np.eye(n)[None] - a[None], np.broadcast_to(entries_b.astype(complex), (grid.size, *entries_b.shape)))
        g_all = c[None] @ res + entries_d[None]
    else:
        g_all = np.broadcast_to(entries_d.astype(complex), (grid.size, *entries_d.shape))
    phi = np.prod([grid - pole for _ in range(k)], axis=0) if k else np.ones(grid.size)
    vy = np.einsum("cdw,gd->cgw", basis[:, :, :p], grid[:, None] ** np.arange(k + 1)[None, :]) / phi[None, :, None]
    resp = np.einsum("cgw,gwe->gce", vy, g_all)  # points × count × (faults, noise)
    nf, na = bf.shape[1], len(at)
    fault = np.transpose(resp[grid.size - na :, :, :nf] if na else resp[:, :, :nf], (2, 1, 0))
    noise = resp[: grid.size - na, :, nf:]
    if not np.any(noise):
        return start
    gap = _GridGap(fault, noise, at_points=bool(na))
    def unit(h: np.ndarray) -> np.ndarray:
        """``h`` of unit length, its largest entry positive (``h`` and ``−h`` are the same filter)."""
        h = h / max(float(np.linalg.norm(h)), 1e-300)
        return h * (1.0 if h[int(np.argmax(np.abs(h)))] >= 0 else -1.0)

    start_h = unit(flat @ start.reshape(-1))  # the generic combination in the canonical basis
    wn = np.real(np.einsum("gcv,gev->ce", noise, noise.conj()))
    wn = wn + 1e-12 * float(np.trace(wn)) * np.eye(count)
    cands = [start_h, *np.eye(count)]
    for f in fault:
        lam, vec = np.linalg.eig(np.linalg.solve(wn, np.real(f @ f.conj().T)))
        cands.append(unit(np.real(vec[:, int(np.argmax(np.real(lam)))])))
    values = [gap(h) for h in cands]
    top = max(values)
    # the first start within GAP_GAIN of the best: the generic combination unless another is clearly better
    k0 = next(i for i, v in enumerate(values) if v >= top / GAP_GAIN)
    chosen, ref = cands[k0], max(values[k0], 1e-300)

    def cost(h: np.ndarray) -> float:
        u = unit(h)
        # the gap, less a small pull towards the start: where the gap is flat along a family of combinations (a row
        # whose noise enters with only some of its faults) the optimum is then the member nearest the start, the
        # same on every BLAS kernel, instead of wherever the simplex stopped
        return -min(gap(u) / ref, 1e300) * (1.0 - GAP_PULL * float(np.sum((u - chosen) ** 2)))

    res = minimize(cost, chosen, method="Nelder-Mead", options={"xatol": 1e-10, "fatol": 1e-14, "maxiter": 400 * count})
    polished = unit(res.x)
    if gap(polished) > GAP_GAIN * values[k0]:
        chosen, k0 = polished, -1
    if k0 == 0:
        return start
    return np.einsum("c,cdw->dw", chosen, basis)


def row_filter(
    plant: LinearPlant, row: Sequence[int], *, pole: float, pencils: FaultPencils | None = None, synthesis: str = "approximate",
    frequencies: Sequence[float] | None = None,
) -> tuple[np.ndarray, int]:
    """The numerator ``v(λ) = Σᵢ vᵢ λⁱ`` of a row's least-order filter ``Q = v/(λ − pole)ᵏ`` (discrete or continuous).

    Parameters
    ----------
    plant : LinearPlant
        The plant, discrete or continuous (``λ`` is ``z`` or ``s``).
    row : sequence of int
        ``0``/``1`` per fault in the plant's fault order.
    pole : float
        The filter's poles (its denominator matters to the gap).
    pencils : FaultPencils, optional
        The plant's pencils, when a bank shares them.
    synthesis : {"approximate", "exact"}
        ``"exact"`` (Varga's ``efdsyn``/``efdisyn``): a generic combination of the row's least-degree null vectors,
        the same on every BLAS kernel; ``"approximate"`` (``afdsyn``/``afdisyn``): the combination of the largest
        fault-to-noise gap (the same when the noise does not reach the residual, or one vector spans the row).
    frequencies : sequence of float, optional
        Frequencies (rad/s) at which every fault of the row must have a nonzero response (the strong structure; the
        order is then the least that achieves it) and at which the approximate synthesis measures the faults' gains.

    Returns
    -------
    tuple
        ``(v, k)``: ``v`` (``(k + 1) × (p + m)``, coefficients of ``[y; u]`` in the user's units, scaled to a largest
        entry 1) and the order ``k``.

    Raises
    ------
    ExistenceError
        The row is not achievable (the message says which faults decoupling its zeros hides).
    """
    names, bf, df = fault_entries(plant)
    row = [int(v) for v in row]
    pen = FaultPencils(plant) if pencils is None else pencils
    at = frequency_points(plant, frequencies) if frequencies else []
    verdict = pen.verdict(row, at, tuple(frequencies or ()))
    if not verdict["achievable"]:
        kind = f"strongly at {list(frequencies or ())} rad/s" if at else "achievable"
        raise ExistenceError(f"its row {row} over faults {list(names)} is not {kind}: {verdict['why']}")
    k = int(verdict["least_order"])
    zeros = frozenset(j for j, v in enumerate(row) if v == 0)
    ones = [j for j, v in enumerate(row) if v == 1]
    unscale = np.concatenate([1.0 / pen.out, pen.k_u])  # back to the user's units: the pencil saw y / out and u · k_u
    rng = np.random.default_rng(COMBINATION_SEED)
    test = boundary_points(2 * (plant.n + k) + 8, not plant.is_discrete)
    a, c = np.asarray(plant.A, float), np.asarray(plant.C, float)
    g = [[transfer_at(a, bf[:, [j]], c, df[:, [j]], z)[:, 0] for j in ones] for z in [*test, *at]]

    def sizes(v: np.ndarray) -> np.ndarray:
        """Each fault's relative response at each point (rows: the test points, then the strong points)."""
        vz = [(z ** np.arange(k + 1)) @ v for z in [*test, *at]]
        return np.array([[float(abs(vv[: plant.p] @ gj)) / max(float(np.linalg.norm(vv)) * float(np.linalg.norm(gj)), 1e-300) for gj in gz]
                         for vv, gz in zip(vz, g, strict=True)]).reshape(len(vz), len(ones))

    for _ in range(8):  # a generic draw sees every fault of the row (at every strong point); one that does not is drawn again
        v = pen.null_vectors(zeros, k, toward=rng)[0] * unscale[None, :]
        v = v / max(float(np.max(np.abs(v))), 1e-300)
        rel = sizes(v)
        if not ones or (np.all(np.max(rel[: len(test)], axis=0) > SEEN_TOL) and np.all(rel[len(test) :] > SEEN_TOL)):
            break
    if synthesis == "approximate" and ones:
        basis = pen.null_vectors(zeros, k) * unscale[None, None, :]
        v = _best_combination(basis, plant, [(bf[:, j], df[:, j]) for j in ones], pole, v, at)
        v = v / max(float(np.max(np.abs(v))), 1e-300)
    return v, k


def nullspace_generator(
    plant: LinearPlant, row: Sequence[int], name: str, *, pole: float | None = None, pencils: FaultPencils | None = None,
    synthesis: str = "approximate", frequencies: Sequence[float] | None = None,
) -> tuple[Generator, np.ndarray, Certificate]:
    """The least-order generator of one row of a structure matrix on a discrete plant (module docstring).

    Parameters
    ----------
    plant : LinearPlant
        The discrete plant.
    row : sequence of int
        ``0``/``1`` per fault in the plant's fault order (1: the residual sees it; 0: decoupled).
    name : str
        The generator's name.
    pole : float, optional
        The filter's poles, all at this real value in ``(−1, 1)``; default: the one of :data:`POLE_CHOICES` of the
        largest fault-to-noise gap.
    pencils : FaultPencils, optional
        The plant's pencils, when a bank shares them (default: computed here).
    synthesis : {"approximate", "exact"}
        How the row's null vectors are combined (:func:`row_filter`).
    frequencies : sequence of float, optional
        Frequencies (rad/s) of a strong structure: every fault of the row must show there, the gap is measured there
        (:func:`row_filter`), and the certificate checks it.

    Returns
    -------
    tuple
        ``(generator on all outputs, its residual covariance, its certificate)``.

    Raises
    ------
    ExistenceError
        The row is not achievable (the message says which faults decoupling its zeros hides).
    """
    row = [int(v) for v in row]
    pen = FaultPencils(plant) if pencils is None else pencils
    try:
        if pole is None:
            tried = []
            for c in POLE_CHOICES:
                vc, kc = row_filter(plant, row, pole=c, pencils=pen, synthesis=synthesis, frequencies=frequencies)
                trial = _row_generator(plant, row, name, vc, kc, c, {})
                try:  # on an unstable plant a filter must cancel the unstable modes to round-off; one that does not is passed over
                    residual_covariance(trial, plant)
                except ExistenceError:
                    continue
                perf_c = generator_performance(trial, plant, frequencies=frequencies, hminus=False)
                tried.append((perf_c.gap if perf_c.gap_at is None else perf_c.gap_at, c, vc, kc))
            if not tried or all(math.isinf(t[0]) for t in tried):
                pole = DEFAULT_POLE
                v, k = row_filter(plant, row, pole=pole, pencils=pen, synthesis=synthesis, frequencies=frequencies)
            else:
                best = max(t[0] for t in tried)
                # of the gaps within POLE_TIE of the best, the slowest pole: the least noise variance for the same gap
                _, pole, v, k = [t for t in tried if t[0] >= best / POLE_TIE][-1]
        else:
            v, k = row_filter(plant, row, pole=pole, pencils=pen, synthesis=synthesis, frequencies=frequencies)
    except ExistenceError as exc:
        raise ExistenceError(f"generator {name!r}: {exc}") from None
    least = k
    gen = _row_generator(plant, row, name, v, k, pole, {
        "design": "nullspace", "row": row, "order": k, "least_order": least, "pole": float(pole), "synthesis": synthesis,
        **({"frequencies": [float(w) for w in frequencies]} if frequencies else {})})
    checks = _checks(plant, gen, row, boundary_points(2 * (plant.n + k) + 8, False), least, float(pole))
    for w, z in zip(frequencies or (), frequency_points(plant, frequencies) if frequencies else (), strict=True):
        rel = relative_responses(gen, plant, [z])["faults"]
        checks += [Check(f"fault {j} at {w:g} rad/s: relative response (strong)", float(rel[j]), SEEN_TOL, ">=",
                         "the strong structure asks the residual to see it at this frequency") for j, want in enumerate(row) if want]
    perf = generator_performance(gen, plant, frequencies=frequencies).to_dict()
    info = {"row": row, "order": k, "least_order": least, "synthesis": synthesis, "pole": float(pole), "gap": perf["gap"],
            "hinf_minus": perf["hinf_minus"], "noise_norm": perf["noise_norm"], **({"gap_at": perf["gap_at"]} if frequencies else {})}
    return gen, residual_covariance(gen, plant), Certificate.of(name, checks, info=info)


def _row_generator(plant: LinearPlant, row: Sequence[int], name: str, v: np.ndarray, k: int, pole: float, method: Mapping[str, Any]) -> Generator:
    """The generator ``v(λ)/(λ − pole)ᵏ`` in observable canonical form, reading only the sensors whose faults the row
    sees (a decoupled sensor fault is a sensor the filter does not read: its columns are round-off)."""
    p = plant.p
    ar, bq, cr, dq = _realise(v, k, float(pole))
    used = [i for i in range(p) if row[i] == 1]
    return embed_outputs(Generator.from_canonical(
        name=name, outputs_used=range(len(used)), Ar=ar, Bu=bq[:, p:], By=bq[:, used], Cr=cr, Du=dq[:, p:], Dy=dq[:, used], method=dict(method),
    ), used, p)


def least_order_filter(
    plant: LinearPlant, row: Sequence[int], *, pole: float, synthesis: str = "approximate", name: str = "q", pencils: FaultPencils | None = None
) -> Generator:
    """A row's least-order filter ``v(λ)/(λ − pole)ᵏ`` (:func:`row_filter`) as a generator, on a discrete or a
    continuous plant (then a continuous filter: its matrices are those of ``ẋ = Ar x + …``), uncertified: the
    nullspace method's design (:func:`nullspace_generator`) certifies its discrete filters.

    Parameters
    ----------
    plant : LinearPlant
        The plant.
    row : sequence of int
        ``0``/``1`` per fault in the plant's fault order.
    pole : float
        The filter's poles.
    synthesis : {"approximate", "exact"}
        How the row's null vectors are combined.
    name : str
        The generator's name.
    pencils : FaultPencils, optional
        The plant's pencils, when shared.

    Returns
    -------
    Generator
        The filter, reading the sensors whose faults the row sees and every input.
    """
    r = [int(x) for x in row]
    v, k = row_filter(plant, r, pole=float(pole), pencils=pencils, synthesis=synthesis)
    return _row_generator(plant, r, name, v, k, float(pole), {"design": "nullspace", "row": r, "order": k, "pole": float(pole), "synthesis": synthesis})


def analyse_gaps(analysis: StructureAnalysis, plant: Any, *, pole: float | None = None) -> StructureAnalysis:
    """``analysis`` with the fault-to-noise gap of each row's least-order filter (Varga's ``fdif2ngap`` of the filter
    his ``afdsyn`` would design at the least order): the combination of the row's null vectors of the largest gap
    (:func:`row_filter`), every pole at ``pole``.

    Parameters
    ----------
    analysis : StructureAnalysis
        The plant's analysis (:func:`~fdisyn.synthesis.structure.analyse_structure`).
    plant : LinearPlant or SampledDataPlant
        The plant analysed.
    pole : float, optional
        The filters' poles: in ``(−1, 1)`` for a discrete plant (default 0.5), negative for a continuous one (default
        −1 rad/s). A gap depends on it: the same null vector over another denominator weighs the frequencies otherwise.

    Returns
    -------
    StructureAnalysis
        The analysis with :attr:`~StructureAnalysis.gaps` and :attr:`~StructureAnalysis.pole`.

    Raises
    ------
    ArgumentError
        A pole outside the plant's stability region.
    """
    from dataclasses import replace

    from fdisyn.synthesis.structure import _linear

    lin = _linear(plant)
    if pole is None:
        pole = 0.5 if lin.is_discrete else -1.0
    ok = is_number(pole) and (-1.0 < float(pole) < 1.0 if lin.is_discrete else float(pole) < 0.0)
    if not ok:
        raise ArgumentError(f"pole {shown(pole)}: expected a number in (-1, 1) for a discrete plant" if lin.is_discrete
                            else f"pole {shown(pole)}: expected a negative number (rad/s) for a continuous plant")
    pen = FaultPencils(lin)
    gaps = []
    for row in analysis.rows:
        gaps.append(generator_performance(least_order_filter(lin, row, pole=float(pole), pencils=pen), lin, hminus=False).gap)
    return replace(analysis, gaps=tuple(gaps), pole=float(pole))


def _checks(plant: LinearPlant, gen: Generator, row: Sequence[int], points: np.ndarray, least: int, pole: float) -> list[Check]:
    """The generator's certificate from its own matrices and the plant's (module docstring)."""
    rel = relative_responses(gen, plant, points)
    why = "exact decoupling: the filter is a null vector of the plant's pencil; round-off only"
    checks = [
        Check("max relative |R_u(z)| on the unit circle", rel["u"], DECOUPLING_TOL, "<=", why),
        Check("max relative |R_d(z)| on the unit circle", rel["d"], DECOUPLING_TOL, "<=", why),
    ]
    for j, want in enumerate(row):
        if want:
            checks.append(Check(f"fault {j}: relative response (seen)", float(rel["faults"][j]), SEEN_TOL, ">=", "the row asks the residual to see it"))
        else:
            checks.append(Check(f"fault {j}: relative response (decoupled)", float(rel["faults"][j]), DECOUPLING_TOL, "<=", why))
    checks.append(Check("order of the filter − least order of the row", float(gen.n_state - least), 0.0, "<=",
                        "the least order the structure analysis gives (left minimal indices)"))
    achieved = np.linalg.eigvals(gen.Ar) if gen.n_state else np.zeros(0)
    spread = float(np.max(np.abs(achieved - pole))) if achieved.size else 0.0
    checks.append(Check("filter poles: max |eig(Ar) − pole|", spread, 1e-4 ** (1.0 / max(1, gen.n_state)) if gen.n_state > 1 else 1e-9, "<=",
                        "a k-fold pole moves by (round-off)^(1/k) under perturbation; the filter's A is exact"))
    return checks


def _structure_rows(plant: LinearPlant, structure: Any, where: str) -> list[list[int]]:
    """The rows of ``structure`` (default: the detection row), checked against the plant's faults."""
    names = fault_entries(plant)[0]
    if structure is None:
        from fdisyn.synthesis.structure import analyse_structure

        rows = analyse_structure(plant).rows
        if not len(rows):
            raise ExistenceError(f"{where}no residual decoupled from the unknown inputs sees any fault of {list(names)}")
        return [[int(v) for v in rows[0]]]
    s = np.asarray(structure, dtype=object)
    if s.ndim != 2 or s.shape[1] != len(names) or not all(v in (0, 1) and not isinstance(v, bool) for v in s.ravel()):
        raise ArgumentError(f"{where}structure must be rows of {len(names)} entries 0 or 1 (faults {list(names)}); got {shown(structure)}")
    return [[int(v) for v in r] for r in s]


def nullspace_design(
    plant: LinearPlant, *, name: str, problem: str | None = None, record: Mapping[str, object] | None = None, where: str = "",
    structure: Any = None, pole: float | None = None, synthesis: str = "approximate", frequencies: Sequence[float] | None = None,
    Ts: float | None = None, P_f: float, persistence: int,
    evaluator: str | None = None, window: int | None = None, detector: str | None = None, arl0: float | None = None,
    min_fault: Mapping[str, float] | None = None, shifts: Sequence[float] | None = None, faults: Any = None,
    false_isolation: float | None = None, isolation_memory: int | None = None,
) -> GainFile:
    """The nullspace bank: one least-order generator per row of ``structure`` (:func:`nullspace_generator`), with the
    linear diagnoser's statistics, thresholds and decision table.

    Parameters
    ----------
    plant : LinearPlant
        The plant (a continuous one is designed on its exact sampling at ``Ts``).
    name, problem, record, where
        As for every method (:mod:`fdisyn.synthesis.registry`).
    structure : array_like, optional
        ``0``/``1`` rows, one per residual, one column per fault (default: one row for detection).
    pole : float, optional
        The filters' poles (all at this value, in ``(−1, 1)``; default: each filter's chosen for its gap,
        :func:`nullspace_generator`).
    synthesis : {"approximate", "exact"}
        How each row's null vectors are combined (:func:`row_filter`).
    frequencies : sequence of float, optional
        Frequencies (rad/s) at which every fault a row sees must show (the strong structure, certified), and at
        which the gap is measured (e.g. ``[0]`` for persistent faults).
    Ts, P_f, persistence, evaluator, window, detector, arl0, min_fault, shifts, faults, false_isolation, isolation_memory
        The linear diagnoser's options (:func:`~fdisyn.synthesis.linear_diagnoser.linear_diagnoser`).

    Returns
    -------
    GainFile
        The certified diagnoser.
    """
    from fdisyn.synthesis.isolation import FALSE_ISOLATION
    from fdisyn.synthesis.linear_diagnoser import chosen_detector, default_fault_classes, linear_diagnoser

    at = f"{where}: " if where else ""
    if plant.is_discrete:
        discrete = plant
    elif Ts is None:
        raise ArgumentError(f"{at}a continuous plant needs Ts, the sample time of its exact sampling")
    else:
        discrete = plant.discretise(Ts)
    rows = _structure_rows(discrete, structure, at)
    pen = FaultPencils(discrete)
    freqs = None if frequencies is None else [float(w) for w in frequencies]
    if freqs is not None:
        try:
            frequency_points(discrete, freqs)
        except ArgumentError as exc:
            raise ArgumentError(f"{at}frequencies: {exc}") from None
    designed = [nullspace_generator(discrete, r, f"r{i}_" + "".join(str(v) for v in r), pole=pole, pencils=pen, synthesis=synthesis, frequencies=freqs)
                for i, r in enumerate(rows)]
    gens = [g for g, _, _ in designed]
    kind = chosen_detector(detector, evaluator, where)
    return linear_diagnoser(
        name=name, problem=problem or name, design="nullspace", plant=discrete, generators=gens, sigma_r=[s for _, s, _ in designed],
        P_f=P_f, faults=faults if faults is not None else default_fault_classes(discrete, gens), certificates=[c for _, _, c in designed],
        persistence=persistence, evaluator=kind, window=window, arl0=arl0, min_fault=min_fault, options=record, where=where,
        shifts=shifts, false_isolation=FALSE_ISOLATION if false_isolation is None else false_isolation, isolation_memory=isolation_memory,
    )


def _register() -> None:
    from fdisyn.synthesis.linear_diagnoser import (
        EVALUATOR, FALSE_ISOLATION_OPTION, FAULTS, ISOLATION_MEMORY, LINEAR_WINDOW, MIN_FAULT, SHIFTS, TS,
    )
    from fdisyn.synthesis.registry import ARL0, DETECTOR, P_F, PERSISTENCE, Method, Option, is_real, register

    options = (
        P_F, ARL0, PERSISTENCE, DETECTOR, EVALUATOR, LINEAR_WINDOW, MIN_FAULT, SHIFTS, FAULTS, FALSE_ISOLATION_OPTION, ISOLATION_MEMORY, TS,
        Option(
            "structure", None,
            "the structure matrix: one row per residual, one 0/1 entry per fault (the sensors, then the component faults; "
            "1: the residual sees it, 0: decoupled); default one row for detection (fdisyn analyse lists the achievable rows)",
            "a list of lists of 0 and 1",
            lambda v: isinstance(v, (list, tuple)) and all(isinstance(r, (list, tuple)) for r in v),
        ),
        Option("pole", None, "the poles of every filter (discrete, all at this value; default: each filter's chosen from "
               "0, 0.1, …, 0.9 for the largest fault-to-noise gap, 0.5 without noise)", "a number in (-1, 1)",
               lambda v: is_real(v) and -1 < v < 1),
        Option("synthesis", "approximate",
               "how each row's least-degree null vectors are combined: 'approximate' for the largest fault-to-noise gap "
               "(Varga's afdsyn/afdisyn at the least order), 'exact' a generic combination (efdsyn/efdisyn)",
               "'approximate' or 'exact'", lambda v: v in SYNTHESES),
        Option("frequencies", None,
               "frequencies in rad/s at which every fault a row sees must show, certified (the strong structure), and at "
               "which the approximate synthesis measures the faults' gains for the gap (e.g. [0] for persistent faults); "
               "default: none, the weak structure and the faults' H∞ norms",
               "a non-empty list of numbers ≥ 0 (rad/s)",
               lambda v: isinstance(v, (list, tuple)) and len(v) > 0 and all(is_real(w) and w >= 0 for w in v)),
    )

    def design(plant: LinearPlant, *, name: str, problem: str | None = None, record: Mapping[str, object] | None = None, where: str = "", **opts: Any) -> GainFile:
        return nullspace_design(plant, name=name, problem=problem, record=record, where=where, **opts)

    register(
        Method(
            name="nullspace",
            plant_kind="linear",
            summary="one least-order residual generator per row of a structure matrix (`fdisyn analyse` lists the achievable "
            "rows), decoupling inputs, unknown inputs and the row's other faults exactly",
            reference="Varga, Solving Fault Diagnosis Problems, Springer 2017, Procedures EFD and EFDI (secs. 5.2-5.3)",
            options=options,
            design=design,
            diagnoser_kind="linear",
            feedthrough=True,
        )
    )


_register()
