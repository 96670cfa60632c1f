"""The free eigenstructure of a Beard filter as an NLP: the gain that minimises the implicit cone half-angles.

Beard's conditions fix the detection spaces ``T_j``, not the gain: every ``L`` with
``(I − P_{T_j}) (A − L C) T_j = 0`` for all ``j`` keeps them invariant. Those equations are linear in ``L``, so
the admissible gains form an affine set ``L = L₀ + Σ θ_i N_i`` (:func:`admissible_gains`): the eigenvalues
*and* the eigenvectors the geometry leaves free, in one parameter vector ``θ``.

The NLP (CasADi, derivatives by AD, IPOPT) minimises ``t`` over ``θ``, the eigenvalues and the eigenvectors:

* ``c_j² ≤ t`` for every detection space, with ``c_j = √min(d, n−d) ‖(I ⊗ Π_j C Q_c) 𝒯_j⁻¹‖₂ / min_m ‖C T_j a_m‖`` the
  guaranteed cone half-angle per unit model error as ``σ → 0`` (:attr:`fdisyn.numerics.robust_cones.ImplicitBound.coefficient`;
  for a one-dimensional ``T_j`` the paper's first-order bound) — its spectral norm replaced by the Schatten-8
  norm ``(tr (XᵀX)⁴)^(1/8)`` (smooth, an upper bound, and within ``rank^(1/8)`` of it: the optimum bounds the
  certified value from above). ``T_j`` is fixed, so the Sylvester operator ``𝒯_j : P ↦ G_c P − P G_T`` is affine in
  ``θ`` and ``𝒯_j⁻¹`` a linear solve;
* the eigenvalues, through ``G_b a_m = λ_m a_m`` and ``‖a_m‖ = 1`` on every block ``b`` (constraints: no
  eigen-decomposition);
* every eigenvalue of ``G = A − L C`` real in ``[0, r]`` (the decay-rate bound ``r``; non-negative: no mode that
  alternates sign from sample to sample) and every two at least ``δ`` apart, so ``G`` is diagonalisable and no
  cone degenerates to a half-space. The eigenvalues are those of the blocks ``G_j = T_jᵀ G T_j`` and of the
  quotient ``G_s = Q_sᵀ G Q_s`` on the complement ``Q_s`` of ``Σ T_j`` (``G`` is block triangular there);
* the noise gain: ``tr Σ_ε ≤ γ² tr Σ_ε,plain``, ``Σ_ε = C P Cᵀ + R``, ``P = G P Gᵀ + Q + L R Lᵀ`` — the residual
  of the optimised filter is at most ``γ`` times as loud (RMS) as that of the plain one (every eigenvalue at ``r``);
* the fault gain: ``‖C (I − G)⁻¹ F_j‖_F ≥ ‖C (I − G_plain)⁻¹ F_j‖_F / γ`` — the steady residual of a constant
  fault is at least ``1/γ`` of the plain filter's. Without it the optimum puts a fault's eigenvalue at 0: the
  narrowest cone, and the weakest residual (a deadbeat mode passes a constant fault with gain 1, the plain one
  with ``1/(1 − r)``).

The objective is independent of ``σ`` (``Y_th = σ_d · b``): the optimal eigenstructure is the same for every
model-error bound. IPOPT starts from several assignments spread over ``[0, r]``; the best point is kept and
judged by an eigen-decomposition in the certificate, never by the NLP's own numbers.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np
from fdisyn.numerics.detection_filter import BeardStructure, beard_gain
from fdisyn.numerics.linalg import orth_basis, orth_complement
from fdisyn.numerics.robust_cones import implicit_thresholds, output_subspaces
from fdisyn.runtime.errors import ArgumentError, SolverError

__all__ = ["admissible_gains", "residual_covariance_trace", "EigenstructureResult", "optimise_eigenstructure"]


def admissible_gains(A: np.ndarray, C: np.ndarray, spaces: Sequence[np.ndarray]) -> tuple[np.ndarray, list[np.ndarray]]:
    """``L₀`` and a basis ``N_i`` (orthonormal in the Frobenius inner product) of the gains keeping every ``T_j`` invariant.

    ``(I − P_j)(A − L C) T_j = 0`` reads ``((C T_j)ᵀ ⊗ (I − P_j)) vec L = vec((I − P_j) A T_j)``.
    """
    n, p = A.shape[0], C.shape[0]
    rows, rhs = [], []
    for t in spaces:
        perp = np.eye(n) - t @ t.T
        rows.append(np.kron((C @ t).T, perp))
        rhs.append((perp @ A @ t).reshape(-1, order="F"))
    m = np.vstack(rows)
    l0 = np.linalg.lstsq(m, np.concatenate(rhs), rcond=None)[0]
    _, s, vh = np.linalg.svd(m)
    rank = int(np.sum(s > 1e-10 * max(float(s[0]), 1e-300)))
    null = vh[rank:]
    return l0.reshape((n, p), order="F"), [v.reshape((n, p), order="F") for v in null]


def residual_covariance_trace(G: np.ndarray, L: np.ndarray, C: np.ndarray, Q: np.ndarray, R: np.ndarray) -> float:
    """``tr(C P Cᵀ + R)`` with ``P = G P Gᵀ + Q + L R Lᵀ``: the residual's mean square under the design noise."""
    from fdisyn.numerics.linalg import dlyap

    p = dlyap(G, Q + L @ R @ L.T)
    return float(np.trace(C @ p @ C.T + R))


@dataclass(frozen=True)
class EigenstructureResult:
    """The optimised gain and what the NLP reported."""

    L: np.ndarray
    eigenvalues: tuple[np.ndarray, ...]
    """Per detection space, then the rest (real)."""
    objective: float
    """``max_m b_m`` per unit model error (the Schatten-8 surrogate the NLP minimised)."""
    noise_ratio: float
    """RMS of the residual under the design noise, relative to the plain assignment's."""
    starts: int
    iterations: int
    return_status: str


def _spread_starts(counts: Sequence[int], radius: float, separation: float, limit: int = 6) -> list[list[list[float]]]:
    """Initial eigenvalue assignments: every eigenvalue distinct on ``[0, r]``, blocks in several orders."""
    total = sum(counts)
    grid = np.linspace(0.0, radius, total + 2)[1:-1] if total > 1 else np.array([0.5 * radius])
    if total > 1 and grid[1] - grid[0] < separation:
        raise ArgumentError(
            f"{total} eigenvalues {separation} apart do not fit in [0, {radius:.6g}]: lower the separation or raise the decay bound"
        )
    out = []
    for order in itertools.islice(itertools.permutations(range(len(counts))), limit):
        vals = list(grid)
        lists: list[list[float]] = [[] for _ in counts]
        for b in order:
            for _ in range(counts[b]):
                lists[b].append(float(vals.pop(0)))
        out.append(lists)
    return out


def optimise_eigenstructure(
    A: np.ndarray,
    C: np.ndarray,
    F: Sequence[np.ndarray],
    structure: BeardStructure,
    *,
    radius: float,
    Q: np.ndarray,
    R: np.ndarray,
    noise_gain: float,
    separation: float,
    plain_trace: float,
    plain_fault_gains: Sequence[float],
) -> EigenstructureResult:
    """The NLP of the module docstring on the discrete ``(A, C)`` with the fault groups ``F`` (one matrix per fault).

    ``plain_fault_gains``: ``‖C (I − G_plain)⁻¹ F_j‖_F`` of the plain filter, per fault."""
    n, p = A.shape[0], C.shape[0]
    if structure.unobservable.size:
        raise ArgumentError(
            "the optimised eigenstructure needs (C, A) observable (its unobservable modes lie in every detection space); "
            "use eigenstructure = 'plain' or give the eigenvalues"
        )
    if np.any(np.abs(structure.fixed.imag) > 0) or np.any((structure.fixed.real < 0) | (structure.fixed.real > radius)):
        raise ArgumentError(
            f"the fixed modes {[complex(z) for z in structure.fixed]} of A − L C are not real in [0, {radius:.6g}]: the optimised "
            "eigenstructure assigns real eigenvalues there; use eigenstructure = 'plain' or give the eigenvalues"
        )
    spaces = [s.basis for s in structure.spaces]
    k = len(spaces)
    axes = output_subspaces(C, spaces)
    l0, basis = admissible_gains(A, C, spaces)
    theta = ca.SX.sym("theta", len(basis))
    lsym = ca.DM(l0) + sum((theta[i] * ca.DM(b) for i, b in enumerate(basis)), ca.SX.zeros(n, p))
    g = ca.DM(A) - ca.mtimes(lsym, ca.DM(C))
    qs = orth_complement(orth_basis(np.hstack(spaces), 1e-10))
    blocks = [*spaces, qs]
    counts = [b.shape[1] for b in blocks]
    lam = ca.SX.sym("lam", n)
    vecs = [ca.SX.sym(f"a{b}", counts[b], counts[b]) for b in range(k + 1)]
    t = ca.SX.sym("t")
    cons, lbg, ubg = [], [], []

    def add(expr: Any, lo: float, hi: float) -> None:
        cons.append(ca.vec(expr))
        size = int(ca.vec(expr).numel())
        lbg.extend([lo] * size)
        ubg.extend([hi] * size)

    start = 0
    for b, basis_b in enumerate(blocks):
        gb = ca.mtimes([ca.DM(basis_b.T), g, ca.DM(basis_b)])
        for i in range(counts[b]):
            a = vecs[b][:, i]
            li = lam[start + i]
            add(ca.mtimes(gb, a) - li * a, 0.0, 0.0)
            add(ca.sumsqr(a), 1.0, 1.0)
        if b < k:  # the first-order coefficient of the guaranteed cone of fault b
            qc = orth_complement(basis_b)
            d_b, m_b = counts[b], qc.shape[1]
            gc = ca.mtimes([ca.DM(qc.T), g, ca.DM(qc)])
            sylvester = ca.kron(ca.DM.eye(d_b), gc) - ca.kron(gb.T, ca.DM.eye(m_b))
            across = (np.eye(p) - axes[b] @ axes[b].T) @ C @ qc
            op = ca.solve(sylvester.T, ca.DM(np.kron(np.eye(d_b), across)).T).T
            gram = ca.mtimes(op.T, op)
            power = ca.mtimes(gram, gram)
            power = ca.mtimes(power, power)  # (XᵀX)⁴: its trace is ‖X‖₈⁸; t bounds the coefficient² (Schatten-8)
            for i in range(counts[b]):  # the denominator: the smallest image ‖C T a_m‖ of the block's eigenvectors
                image2 = ca.sumsqr(ca.mtimes(ca.DM(C @ basis_b), vecs[b][:, i]))
                add(ca.trace(power) ** 0.25 * float(min(d_b, m_b)) - t * image2, -ca.inf, 0.0)
        start += counts[b]
    for i in range(n):
        for j in range(i + 1, n):
            add((lam[i] - lam[j]) ** 2, separation**2, ca.inf)
    # the noise gain: vec P = (I − G ⊗ G)⁻¹ vec(Q + L R Lᵀ)
    big = ca.DM.eye(n * n) - ca.kron(g, g)
    pv = ca.solve(big, ca.vec(ca.DM(Q) + ca.mtimes([lsym, ca.DM(R), lsym.T])))
    pm = ca.reshape(pv, n, n)
    add(ca.trace(ca.mtimes([ca.DM(C), pm, ca.DM(C.T)])) + float(np.trace(R)), -ca.inf, noise_gain**2 * plain_trace)
    for fj, gain_j in zip(F, plain_fault_gains, strict=True):
        steady = ca.mtimes(ca.DM(C), ca.solve(ca.DM.eye(n) - g, ca.DM(fj)))
        add(ca.sumsqr(steady), (gain_j / noise_gain) ** 2, ca.inf)

    x = ca.vertcat(theta, lam, *[ca.vec(v) for v in vecs], t)
    nx = int(x.numel())
    lbx = np.concatenate([np.full(len(basis), -np.inf), np.zeros(n), np.full(nx - len(basis) - n - 1, -np.inf), [0.0]])
    ubx = np.concatenate([np.full(len(basis), np.inf), np.full(n, radius), np.full(nx - len(basis) - n, np.inf)])
    opts: dict[str, Any] = {"print_time": False, "ipopt.print_level": 0, "ipopt.sb": "yes", "ipopt.tol": 1e-10, "ipopt.max_iter": 1000}
    solver = ca.nlpsol("beard_eigenstructure", "ipopt", {"x": x, "f": t, "g": ca.vertcat(*cons)}, opts)

    basis_mat = np.stack([b.reshape(-1, order="F") for b in basis], axis=1) if basis else np.zeros((n * p, 0))
    best: tuple[float, np.ndarray, dict[str, Any]] | None = None
    tried = 0
    for ev in _spread_starts(counts, radius, separation):
        try:
            lg = beard_gain(A, C, F, ev).L
        except (ArgumentError, ValueError):
            continue
        tried += 1
        th0 = np.linalg.lstsq(basis_mat, (lg - l0).reshape(-1, order="F"), rcond=None)[0] if basis else np.zeros(0)
        g0 = A - lg @ C
        lam0: list[float] = []
        vec0: list[np.ndarray] = []
        for basis_b in blocks:
            w, v = np.linalg.eig(basis_b.T @ g0 @ basis_b)
            order = np.argsort(w.real)
            lam0.extend(w.real[order])
            v = np.real(v[:, order])
            vec0.append(v / np.linalg.norm(v, axis=0))
        b0 = implicit_thresholds(g0, C, spaces, 1.0).coefficient
        x0 = np.concatenate([th0, lam0, *[v.reshape(-1, order="F") for v in vec0], [float(np.max(b0)) ** 2 * 2.0 + 1e-12]])
        sol = solver(x0=x0, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
        stats = solver.stats()
        if not stats.get("success", False) and stats.get("return_status") not in {"Solved_To_Acceptable_Level"}:
            continue
        xs = np.asarray(sol["x"]).reshape(-1)
        if best is None or float(xs[-1]) < best[0]:
            best = (float(xs[-1]), xs, dict(stats))
    if best is None:
        raise SolverError(
            f"IPOPT found no admissible eigenstructure from {tried} starts (real eigenvalues in [0, {radius:.6g}], "
            f"{separation} apart, noise gain ≤ {noise_gain}): raise the decay bound or the noise gain"
        )
    xs = best[1]
    gain = l0 + sum((xs[i] * b for i, b in enumerate(basis)), np.zeros((n, p)))
    lams, start = [], len(basis)
    for c_ in counts:
        lams.append(np.sort(xs[start : start + c_]))
        start += c_
    g_opt = A - gain @ C
    ratio = float(np.sqrt(residual_covariance_trace(g_opt, gain, C, Q, R) / plain_trace))
    return EigenstructureResult(
        L=gain,
        eigenvalues=tuple(lams),
        objective=float(np.sqrt(best[0])),
        noise_ratio=ratio,
        starts=tried,
        iterations=int(best[2].get("iter_count", -1)),
        return_status=str(best[2].get("return_status")),
    )
