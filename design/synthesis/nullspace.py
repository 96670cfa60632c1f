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
against the least order and the poles against the requested ones. Varga's approximate syntheses (``afdsyn``,
``afdisyn``: the combination chosen for the fault-to-noise gap) are not here yet: the combination is a fixed
generic one, checked to see every fault of its row.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from fdisyn.models.linear import LinearPlant
from fdisyn.numerics.certificate import Certificate, Check
from fdisyn.runtime.errors import ArgumentError, ExistenceError
from fdisyn.runtime.gainfile import GainFile, Generator
from fdisyn.runtime.names import shown
from fdisyn.synthesis.residual import embed_outputs, residual_covariance
from fdisyn.synthesis.structure import FaultPencils, fault_entries

__all__ = ["DECOUPLING_TOL", "nullspace_generator"]

DECOUPLING_TOL = 1e-8
"""``‖R_u(z)‖`` and ``‖R_d(z)‖`` relative to ``‖Q(z)‖ ‖G_e(z)‖`` at the test points, and a decoupled fault's
response relative to ``‖Q(z)‖ ‖G_fj(z)‖``: the filter is the exact null vector of a pencil whose rank decisions are
made on the balanced plant, so its products with the plant vanish to round-off (measured below 1e-12 on the seeded
plants of the tests), while a fault the residual sees stays above :data:`SEEN_TOL`."""

SEEN_TOL = 1e-6
"""A fault the row asks for must reach at least this (same relative measure) at one of the test points."""

COMBINATION_SEED = 20170501
"""The seed of the generic null vector (a fixed standard normal draw projected onto the null space): fixed, so a
design is reproducible, and a projection, so it does not depend on the basis a BLAS kernel's SVD returns."""


def _points(n: int, k: int) -> np.ndarray:
    """``2 (n + k) + 8`` points on the unit circle, off the real axis (an integrator's pole at 1 is avoided)."""
    count = 2 * (n + k) + 8
    return np.exp(1j * (np.pi * (np.arange(count) + 0.5) / count))


def _transfer(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray, z: complex) -> np.ndarray:
    if a.shape[0] == 0:
        return d.astype(complex)
    return c @ np.linalg.solve(z * np.eye(a.shape[0]) - a, b) + d


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


def nullspace_generator(
    plant: LinearPlant, row: Sequence[int], name: str, *, pole: float = 0.5, pencils: FaultPencils | None = None
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
    pole : float
        The filter's poles, all at this real value in ``(−1, 1)``.
    pencils : FaultPencils, optional
        The plant's pencils, when a bank shares them (default: computed here).

    Returns
    -------
    tuple
        ``(generator on all outputs, its residual covariance, its certificate)``.

    Raises
    ------
    ExistenceError
        The row is not achievable (the message says which faults decoupling its zeros hides).
    """
    names, bf, df = fault_entries(plant)
    row = [int(v) for v in row]
    pen = FaultPencils(plant) if pencils is None else pencils
    verdict = pen.verdict(row)
    if not verdict["achievable"]:
        raise ExistenceError(f"generator {name!r}: its row {row} over faults {list(names)} is not achievable: {verdict['why']}")
    k = least = int(verdict["least_order"])
    zeros = frozenset(j for j, v in enumerate(row) if v == 0)
    ones = [j for j, v in enumerate(row) if v == 1]
    # back to the user's units: the pencil saw y / out and u · k_u
    unscale = np.concatenate([1.0 / pen.out, pen.k_u])
    rng = np.random.default_rng(COMBINATION_SEED)
    p = plant.p
    test = _points(plant.n, k)
    for _ in range(8):
        v = pen.null_vectors(zeros, k, toward=rng)[0] * unscale[None, :]
        v = v / max(float(np.max(np.abs(v))), 1e-300)
        ar, bq, cr, dq = _realise(v, k, float(pole))
        # a decoupled sensor fault is a sensor the filter does not read (its columns are round-off): left out
        used = [i for i in range(p) if row[i] == 1]
        gen = embed_outputs(Generator.from_canonical(
            name=name, outputs_used=range(len(used)), Ar=ar, Bu=bq[:, p:], By=bq[:, used], Cr=cr, Du=dq[:, p:], Dy=dq[:, used],
            method={"design": "nullspace", "row": row, "order": k, "least_order": least, "pole": float(pole)},
        ), used, p)
        checks, seen = _checks(plant, gen, row, bf, df, test, least, float(pole))
        if all(seen[j] for j in ones):
            break
    return gen, residual_covariance(gen, plant), Certificate.of(name, checks, info={"row": row, "order": k, "least_order": least})


def _checks(
    plant: LinearPlant, gen: Generator, row: Sequence[int], bf: np.ndarray, df: np.ndarray, points: np.ndarray, least: int, pole: float
) -> tuple[list[Check], dict[int, bool]]:
    """The generator's certificate from its own matrices and the plant's (module docstring)."""
    a, c = np.asarray(plant.A, float), np.asarray(plant.C, float)
    ru = rd = 0.0
    fault = np.zeros(len(row))
    for z in points:
        q = np.hstack([_transfer(gen.Ar, gen.By, gen.Cr, gen.Dy, z), _transfer(gen.Ar, gen.Bu, gen.Cr, gen.Du, z)])
        qy = q[:, : plant.p]
        gu = _transfer(a, np.asarray(plant.B, float), c, np.asarray(plant.D, float), z)
        ge = np.vstack([gu, np.eye(plant.m)]) if plant.m else np.zeros((plant.p, 0))
        qn = float(np.linalg.norm(q))
        if plant.m:
            ru = max(ru, float(np.linalg.norm(q @ ge)) / max(qn * float(np.linalg.norm(ge, 2)), 1e-300))
        if plant.q:
            gd = _transfer(a, np.asarray(plant.E, float), c, np.zeros((plant.p, plant.q)), z)
            rd = max(rd, float(np.linalg.norm(qy @ gd)) / max(qn * float(np.linalg.norm(gd, 2)), 1e-300))
        for j in range(len(row)):
            g = _transfer(a, bf[:, [j]], c, df[:, [j]], z)
            fault[j] = max(fault[j], float(np.linalg.norm(qy @ g)) / max(qn * float(np.linalg.norm(g)), 1e-300))
    why = "exact decoupling: the filter is a null vector of the plant's pencil; round-off only"
    checks = [
        Check("max relative |R_u(z)| on the unit circle", ru, DECOUPLING_TOL, "<=", why),
        Check("max relative |R_d(z)| on the unit circle", rd, DECOUPLING_TOL, "<=", why),
    ]
    seen = {}
    for j, want in enumerate(row):
        seen[j] = fault[j] >= SEEN_TOL
        if want:
            checks.append(Check(f"fault {j}: relative response (seen)", float(fault[j]), SEEN_TOL, ">=", "the row asks the residual to see it"))
        else:
            checks.append(Check(f"fault {j}: relative response (decoupled)", float(fault[j]), DECOUPLING_TOL, "<=", why))
    checks.append(Check("order of the filter − least order of the row", float(gen.n_state - least), 0.0, "<=",
                        "the least order the structure analysis gives (left minimal indices)"))
    achieved = np.linalg.eigvals(gen.Ar) if gen.n_state else np.zeros(0)
    spread = float(np.max(np.abs(achieved - pole))) if achieved.size else 0.0
    checks.append(Check("filter poles: max |eig(Ar) − pole|", spread, 1e-4 ** (1.0 / max(1, gen.n_state)) if gen.n_state > 1 else 1e-9, "<=",
                        "a k-fold pole moves by (round-off)^(1/k) under perturbation; the filter's A is exact"))
    return checks, seen


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
    structure: Any = None, pole: float = 0.5, Ts: float | None = None, P_f: float, persistence: int,
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
    pole : float
        The filters' poles (all at this value, in ``(−1, 1)``).
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
    designed = [nullspace_generator(discrete, r, f"r{i}_" + "".join(str(v) for v in r), pole=pole, pencils=pen) for i, r in enumerate(rows)]
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
        Option("pole", 0.5, "the poles of every filter (discrete, all at this value)", "a number in (-1, 1)",
               lambda v: is_real(v) and -1 < v < 1),
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
        )
    )


_register()
