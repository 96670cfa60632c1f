"""The geometry of Beard's fault detection filter: detection spaces, their existence conditions, the gain.

Beard's filter (Beard, MIT thesis, 1971; He, Zhang & Wu, Journal of Astronautics, c. 1999) is the full-order
observer ``x̂⁺ = A x̂ + B u + L (y − C x̂)`` (``x̂̇`` in continuous time) whose gain makes the output error
``ε = C e`` of a fault ``i`` stay in a fixed subspace ``C T_i`` of the output space, whatever the fault signal
``μ_i``: with ``e⁺ = (A − L C) e + f_i μ_i`` and ``T_i ∋ f_i`` invariant under ``A − L C``, ``e`` never leaves
``T_i`` when it starts there. Massoumnia (IEEE Transactions on Automatic Control 31(9), 1986) states the design
geometrically; with ``𝒲 ∩ ker C`` written ``𝒲_C``:

* the *detection space* of ``f_i`` is the smallest ``(C, A)``-unobservability subspace containing ``span f_i``
  — a subspace that is the unobservable subspace of ``(H C, A − L C)`` for some output injection ``L`` and some
  output map ``H`` (:func:`detection_space`);
* *output separability*: the images ``C T_1, …, C T_k`` are independent, so that the output direction names the
  fault (:func:`check_output_separability`);
* no fault lies in the unobservable subspace of ``(C, A)`` (it would never reach the output,
  :func:`check_faults_observable`);
* *mutual detectability*: one gain makes every ``T_i`` invariant with a stable spectrum. The eigenvalues it cannot
  move are the *fixed modes* (:func:`beard_structure` lists them, :func:`beard_gain` refuses unstable ones).

Everything here holds for a discrete ``(A_d, C)`` and a continuous ``(A, C)`` alike — invariance does not know
the time axis; only the stability test of the fixed modes does (``discrete=``).

Rank decisions. The problem is first scaled, ``A/‖A‖₂``, ``C/‖C‖₂``, every fault column to unit length: the
subspaces do not change and every vector the algorithms stack has entries of order one. A singular value of an
orthonormal-basis product counts when it exceeds ``tol``, by default ``1e3 · n · eps`` (three digits over the
round-off of a backward-stable SVD, as :func:`fdisyn.numerics.linalg.unobservable_modes`); the decisions are
hence independent of the units of ``A``, ``C`` and ``f``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import scipy.linalg as sla
import scipy.signal
from fdisyn.numerics.linalg import as_matrix, as_square, orth_basis, orth_complement
from fdisyn.runtime.errors import ArgumentError, CertificateError, ExistenceError, ShapeError

__all__ = [
    "DetectionSpace",
    "BeardStructure",
    "BeardGain",
    "conditioned_invariant",
    "detection_space",
    "unobservable_subspace",
    "check_faults_observable",
    "check_output_separability",
    "beard_structure",
    "beard_gain",
    "plain_eigenvalues",
    "fault_groups",
]


class DetectionSpace(NamedTuple):
    """A detection space: an orthonormal basis (``n × dim``, columns) and its dimension."""

    basis: np.ndarray
    dim: int


@dataclass(frozen=True)
class BeardStructure:
    """What the geometry fixes before any eigenvalue is chosen (:func:`beard_structure`).

    The spectrum of every admissible ``A − L C`` (every ``T_i`` invariant) is the union of

    * ``free_counts[i]`` eigenvalues on ``T_i`` (modulo the unobservable subspace ``N`` of ``(C, A)``),
      ``i < k`` — all free: ``(C, A)`` observable on ``T_i / N`` makes the restriction fully assignable;
    * ``free_counts[k]`` free eigenvalues on the rest ``X / (N + Σ T_i)``;
    * ``fixed``: the unobservable modes of ``(C, A)`` (on ``N``, in every ``T_i``) and the modes of
      ``X / (N + Σ T_i)`` no output outside ``Σ C T_i`` observes — the fixed modes of mutual detectability.
    """

    spaces: tuple[DetectionSpace, ...]
    """The detection space of each fault (:func:`detection_space`)."""
    free_counts: tuple[int, ...]
    """How many eigenvalues :func:`beard_gain` takes per block: one entry per fault, then the rest."""
    fixed: np.ndarray
    """The eigenvalues of ``A − L C`` that no admissible ``L`` moves (complex)."""
    unobservable: np.ndarray
    """Those of ``fixed`` that are unobservable modes of ``(C, A)`` (complex)."""
    output_ranks: tuple[int, ...] = ()
    """Per block (as :attr:`free_counts`), the number of independent outputs that observe its free part: an
    eigenvalue can be placed at most that many times there (:func:`plain_eigenvalues`)."""


@dataclass(frozen=True)
class BeardGain:
    """A Beard detection-filter gain and the geometry it was built on (:func:`beard_gain`)."""

    L: np.ndarray
    """The gain (``n × p``): every detection space is ``(A − L C)``-invariant."""
    structure: BeardStructure
    """The detection spaces, the free-eigenvalue counts and the fixed modes."""


# --------------------------------------------------------------------------- subspace arithmetic


def _default_tol(n: int) -> float:
    return 1e3 * max(n, 1) * np.finfo(float).eps


def _null(m: np.ndarray, tol: float) -> np.ndarray:
    """Orthonormal basis of the kernel of ``m`` (rows of order one): right singular vectors with σ ≤ ``tol``."""
    n = m.shape[1]
    if m.shape[0] == 0:
        return np.eye(n)
    _, s, vh = np.linalg.svd(m, full_matrices=True)
    return vh[int(np.sum(s > tol)) :].T.conj()


def _min_conditioned_invariant(a: np.ndarray, c: np.ndarray, f: np.ndarray, tol: float) -> np.ndarray:
    """``W*``: ``W_0 = span f``, ``W_{j+1} = span f + A (W_j ∩ ker C)`` to its fixed point (scaled data)."""
    w = orth_basis(f, tol)
    for _ in range(a.shape[0] + 1):
        inter = w @ _null(c @ w, tol)  # W_j ∩ ker C
        nxt = orth_basis(np.hstack([f, a @ inter]), tol)
        if nxt.shape[1] == w.shape[1]:
            return nxt
        w = nxt
    return w  # W_j grows at each step until it stops, so n + 1 steps always reach the fixed point


def _min_unobservability(a: np.ndarray, c: np.ndarray, w: np.ndarray, tol: float) -> np.ndarray:
    """``T*``: ``T_0 = X``, ``T_{j+1} = W* + (A⁻¹ T_j ∩ ker C)`` to its fixed point (scaled data).

    ``A⁻¹ T_j ∩ ker C = ker [C; (I − P_{T_j}) A]`` — the preimage needs no inverse of ``A``.
    """
    n = a.shape[0]
    t = np.eye(n)
    for _ in range(n + 1):
        pre = _null(np.vstack([c, a - t @ (t.T @ a)]), tol)
        nxt = orth_basis(np.hstack([w, pre]), tol)
        if nxt.shape[1] == t.shape[1]:
            return nxt
        t = nxt
    return t  # T_j shrinks at each step until it stops


def _scaled(a: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, float]:
    """``A/‖A‖₂``, ``C/‖C‖₂`` and the two norms (1 for a zero matrix)."""
    na = float(np.linalg.norm(a, 2)) if a.size else 0.0
    nc = float(np.linalg.norm(c, 2)) if c.size else 0.0
    na, nc = (na if na > 0 else 1.0), (nc if nc > 0 else 1.0)
    return a / na, c / nc, na, nc


def _unit_columns(f: np.ndarray, name: str) -> np.ndarray:
    norms = np.linalg.norm(f, axis=0)
    if np.any(norms == 0.0):
        raise ArgumentError(f"{name} has a zero column (fault {int(np.argmin(norms)) + 1}); a fault direction must be nonzero")
    return f / norms


def _pair(a: object, c: object) -> tuple[np.ndarray, np.ndarray]:
    am = as_square(a, "A")
    return am, as_matrix(c, "C", cols=am.shape[0])


# --------------------------------------------------------------------------- the detection space


def conditioned_invariant(a: object, c: object, f: object, *, tol: float | None = None) -> np.ndarray:
    """Orthonormal basis of ``W*``, the smallest ``(C, A)``-invariant subspace containing ``span f``.

    A subspace ``𝒲`` is ``(C, A)``-invariant (conditioned invariant) when ``A (𝒲 ∩ ker C) ⊂ 𝒲`` — equivalently
    ``(A − L C) 𝒲 ⊂ 𝒲`` for some ``L`` (Massoumnia, IEEE TAC 31(9), 1986, section II). The smallest one
    containing ``span f`` is the limit of the increasing sequence

        W_0 = span f,     W_{j+1} = span f + A (W_j ∩ ker C),

    reached after at most ``n`` steps. For a single fault with ``C A^j f = 0`` for ``j < ν − 1`` and
    ``C A^{ν−1} f ≠ 0`` it is ``span {f, A f, …, A^{ν−1} f}`` (Beard 1971).
    """
    am, cm = _pair(a, c)
    fm = _unit_columns(as_matrix(f, "f", rows=am.shape[0]), "f")
    as_, cs, _, _ = _scaled(am, cm)
    return _min_conditioned_invariant(as_, cs, fm, _default_tol(am.shape[0]) if tol is None else tol)


def detection_space(a: object, c: object, f: object, *, tol: float | None = None) -> DetectionSpace:
    """The detection space of the fault direction(s) ``f``: the smallest ``(C, A)``-unobservability subspace ⊇ ``span f``.

    Massoumnia (IEEE TAC 31(9), 1986, section III): with ``W*`` the smallest conditioned-invariant subspace
    containing ``span f`` (:func:`conditioned_invariant`), ``H`` any matrix with ``ker H = C W*`` and ``G`` any
    gain with ``(A − G C) W* ⊂ W*``,

        T = ⟨ker H C | A − G C⟩ = the largest (A − G C)-invariant subspace of  W* + ker C,

    the unobservable subspace of ``(H C, A − G C)``. The injection matters — the largest ``A``-invariant subspace
    of ``ker H C`` need not contain ``f`` at all. ``T`` is computed without choosing ``G`` or ``H``, by the
    unobservability subspace algorithm (dual of Wonham's controllability subspace algorithm):

        T_0 = X,     T_{j+1} = W* + (A⁻¹ T_j ∩ ker C),

    a decreasing sequence whose limit (after at most ``n`` steps) is ``T``. Every unobservability subspace
    contains the unobservable subspace ``N`` of ``(C, A)``.

    For a single fault, ``(C, A)`` observable: ``dim T = ν + z`` with ``ν`` the relative degree (as in
    :func:`conditioned_invariant`) and ``z`` the number of invariant zeros of ``(A, f, C)``; with one output
    (``p = 1``) ``T`` is the whole state space.

    ``tol``: rank threshold on the scaled problem (module docstring). Returns an orthonormal basis and its dimension.
    """
    am, cm = _pair(a, c)
    n = am.shape[0]
    fm = _unit_columns(as_matrix(f, "f", rows=n), "f")
    tl = _default_tol(n) if tol is None else tol
    as_, cs, _, _ = _scaled(am, cm)
    w = _min_conditioned_invariant(as_, cs, fm, tl)
    t = _min_unobservability(as_, cs, w, tl)
    return DetectionSpace(t, t.shape[1])


def unobservable_subspace(a: object, c: object, *, tol: float | None = None) -> np.ndarray:
    """Orthonormal basis of the unobservable subspace ``N = ⟨ker C | A⟩`` of ``(C, A)``.

    The same algorithm as :func:`detection_space` with ``W* = 0``: ``N_0 = X``, ``N_{j+1} = A⁻¹ N_j ∩ ker C``.
    """
    am, cm = _pair(a, c)
    n = am.shape[0]
    as_, cs, _, _ = _scaled(am, cm)
    return _min_unobservability(as_, cs, np.zeros((n, 0)), _default_tol(n) if tol is None else tol)


# --------------------------------------------------------------------------- existence conditions


def check_faults_observable(a: object, c: object, f: object, *, tol: float | None = None) -> None:
    """Raise :class:`ExistenceError` when a fault direction lies in the unobservable subspace of ``(C, A)``.

    Such a fault never reaches the output (``C (zI − A)⁻¹ f_i ≡ 0``): ``W*_i ⊂ ker C``, so ``C T_i = 0``.
    """
    am, cm = _pair(a, c)
    n = am.shape[0]
    fm = _unit_columns(as_matrix(f, "F", rows=n), "F")
    tl = _default_tol(n) if tol is None else tol
    as_, cs, _, _ = _scaled(am, cm)
    nb = _min_unobservability(as_, cs, np.zeros((n, 0)), tl)
    hidden = [i + 1 for i in range(fm.shape[1]) if np.linalg.norm(fm[:, i] - nb @ (nb.T @ fm[:, i])) <= tl]
    if hidden:
        raise ExistenceError(
            f"fault(s) {_faults(hidden)} lie in the unobservable subspace of (C, A): they never reach the output, "
            "no detection filter sees them"
        )


def check_output_separability(c: object, spaces: Sequence[DetectionSpace | np.ndarray], *, tol: float | None = None) -> None:
    """Raise :class:`ExistenceError` unless the output images ``C T_1, …, C T_k`` are independent.

    Output separability (Massoumnia, IEEE TAC 31(9), 1986, section IV): ``C T_i ∩ Σ_{j≠i} C T_j = 0`` for every
    ``i``, i.e. ``rank [C T_1, …, C T_k] = Σ rank C T_i``; without it one output direction belongs to two faults
    and the residual cannot tell them apart. The message names the first fault whose image meets those of the
    earlier ones, and which.
    """
    cm = as_matrix(c, "C")
    bases = [np.asarray(s.basis if isinstance(s, DetectionSpace) else s, dtype=float) for s in spaces]
    for i, b in enumerate(bases):
        if b.ndim != 2 or b.shape[0] != cm.shape[1]:
            raise ShapeError(f"detection space {i + 1} has shape {b.shape}; expected ({cm.shape[1]}, any)")
    tl = _default_tol(cm.shape[1]) if tol is None else tol
    cs = cm / max(float(np.linalg.norm(cm, 2)) if cm.size else 0.0, np.finfo(float).tiny)
    images = [orth_basis(cs @ orth_basis(b, tl), tl) for b in bases]
    for i in range(1, len(images)):
        if orth_basis(np.hstack(images[: i + 1]), tl).shape[1] == sum(m.shape[1] for m in images[: i + 1]):
            continue
        partners = [j + 1 for j in range(i) if orth_basis(np.hstack([images[j], images[i]]), tl).shape[1]
                    < images[j].shape[1] + images[i].shape[1]]
        others = partners or list(range(1, i + 1))
        raise ExistenceError(
            f"the faults are not output separable: the output directions C T of fault {i + 1} and of fault(s) "
            f"{_faults(others)} are dependent, so the residual direction cannot tell them apart"
        )


def _faults(idx: Sequence[int]) -> str:
    return ", ".join(str(i) for i in idx)


# --------------------------------------------------------------------------- the gain


@dataclass(frozen=True)
class _Geometry:
    """Scaled coordinates of the construction (see :func:`beard_gain`)."""

    structure: BeardStructure
    q: np.ndarray  # orthonormal basis of N^⊥ (n × n̄)
    a: np.ndarray  # Ā = Qᵀ A_s Q
    c: np.ndarray  # C̄ = C_s Q
    blocks: tuple[np.ndarray, ...]  # V̄_1, …, V̄_k, V̄_c: bases of T̄_i and of (Σ T̄_i)^⊥ in X̄ = N^⊥
    outputs: tuple[np.ndarray, ...]  # U_1, …, U_k, U_c: orthonormal bases of C̄ T̄_i and of (Σ C̄ T̄_i)^⊥
    pairs: tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...]  # per block: X_b, U_bᵀ C̄ V̄_b, its unobservable part
    friend: np.ndarray  # L̄_0: a common friend of the T̄_i
    na: float
    nc: float
    tol: float


def fault_groups(f: object, n: int) -> list[np.ndarray]:
    """The faults of ``F``: a matrix (one fault per column) or a list of ``n × c`` matrices (a fault per matrix, e.g.
    a sensor fault's two directions); every column scaled to unit length."""
    if isinstance(f, (list, tuple)) and f and all(np.ndim(np.asarray(g, dtype=object)) == 2 for g in f):
        groups = [_unit_columns(as_matrix(g, f"F[{i}]", rows=n), f"F[{i}]") for i, g in enumerate(f)]
    else:
        fm = _unit_columns(as_matrix(f, "F", rows=n), "F")
        groups = [fm[:, i : i + 1] for i in range(fm.shape[1])]
    if not groups or any(g.shape[1] == 0 for g in groups):
        raise ArgumentError("F has no fault directions; expected one fault direction per column (or a list of matrices)")
    return groups


def _geometry(a: object, c: object, f: object, tol: float | None) -> _Geometry:
    am, cm = _pair(a, c)
    n = am.shape[0]
    groups = fault_groups(f, n)
    tl = _default_tol(n) if tol is None else tol
    check_faults_observable(am, cm, np.hstack(groups), tol=tl)
    as_, cs, na, nc = _scaled(am, cm)
    spaces = []
    for g in groups:
        t = _min_unobservability(as_, cs, _min_conditioned_invariant(as_, cs, g, tl), tl)
        spaces.append(DetectionSpace(t, t.shape[1]))
    check_output_separability(cs, spaces, tol=tl)

    # X̄ = N^⊥: N is invariant under every A − L C and lies in ker C; on X̄ the pair (C̄, Ā) is observable
    nb = _min_unobservability(as_, cs, np.zeros((n, 0)), tl)
    q = orth_complement(nb)
    abar, cbar = q.T @ as_ @ q, cs @ q
    vbars = [orth_basis(q.T @ s.basis, tl) for s in spaces]  # T̄_i = Qᵀ T_i (T_i = N ⊕ (T_i ∩ N^⊥))
    tsum = orth_basis(np.hstack(vbars), tl) if vbars else np.zeros((q.shape[1], 0))
    if tsum.shape[1] != sum(v.shape[1] for v in vbars):
        # output separability and observability of (C̄, Ā) make the sum direct: T̄_i ∩ Σ_{j≠i} T̄_j is
        # (A − L C)-invariant and inside ker C, hence 0
        raise ExistenceError(
            f"the detection spaces of faults {_faults(range(1, len(vbars) + 1))} are not independent modulo the "
            "unobservable subspace of (C, A) (rank decisions at the tolerance: try a larger tol)"
        )
    vc = orth_complement(tsum)
    outs = [orth_basis(cbar @ v, tl) for v in vbars]
    uc = orth_complement(orth_basis(np.hstack(outs), tl)) if outs else np.eye(cbar.shape[0])

    # a common friend: (I − P_i)(Ā − L̄ C̄) V̄_i = 0 for every i — linear in L̄, solvable by output separability
    nbar, p = abar.shape[0], cbar.shape[0]
    rows, rhs = [], []
    for v in vbars:
        perp = np.eye(nbar) - v @ v.T
        rows.append(np.kron((cbar @ v).T, perp))
        rhs.append((perp @ abar @ v).reshape(-1, order="F"))
    if rows:
        sol = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)[0]
        friend = sol.reshape((nbar, p), order="F")
    else:
        friend = np.zeros((nbar, p))
    g = abar - friend @ cbar
    for i, v in enumerate(vbars):
        if np.linalg.norm((np.eye(nbar) - v @ v.T) @ g @ v) > 1e3 * tl:
            raise ExistenceError(f"no gain makes the detection space of fault {i + 1} invariant (rank decisions at the tolerance)")

    # each diagonal block X_b = V̄_bᵀ (Ā − L̄_0 C̄) V̄_b with its output map U_bᵀ C̄ V̄_b; the unobservable part of
    # that pair is fixed (N's modes are fixed as well)
    pairs, ranks = [], []
    for v, u in zip((*vbars, vc), (*outs, uc), strict=True):
        x, cx = v.T @ g @ v, u.T @ cbar @ v
        pairs.append((x, cx, _min_unobservability(_unit(x), _unit(cx), np.zeros((x.shape[0], 0)), tl)))
        ranks.append(_output_rank(cx @ orth_complement(pairs[-1][2]), tl))
    fixed_blocks = [np.linalg.eigvals(nu.T @ x @ nu) * na for x, _, nu in pairs if nu.shape[1]]
    unobs = np.linalg.eigvals(nb.T @ as_ @ nb) * na if nb.shape[1] else np.zeros(0, dtype=complex)
    structure = BeardStructure(
        spaces=tuple(spaces),
        free_counts=tuple(x.shape[0] - nu.shape[1] for x, _, nu in pairs),
        fixed=np.concatenate([unobs, *fixed_blocks]).astype(complex),
        unobservable=unobs.astype(complex),
        output_ranks=tuple(ranks),
    )
    return _Geometry(structure, q, abar, cbar, (*vbars, vc), (*outs, uc), tuple(pairs), friend, na, nc, tl)


def _output_rank(co: np.ndarray, tol: float) -> int:
    """The rank :func:`_place_observable_part` compresses the outputs of an observable pair to."""
    if co.size == 0:
        return 0
    ss = np.linalg.svd(co, compute_uv=False)
    return int(np.sum(ss > tol * float(ss[0]))) if ss[0] > 0 else 0


def _unit(m: np.ndarray) -> np.ndarray:
    s = float(np.linalg.norm(m, 2)) if m.size else 0.0
    return m / s if s > 0 else m


def beard_structure(a: object, c: object, f: object, *, tol: float | None = None) -> BeardStructure:
    """The detection spaces of the columns of ``F``, the free-eigenvalue counts and the fixed modes.

    Checks the existence conditions that do not depend on the time axis — every fault observable
    (:func:`check_faults_observable`) and output separability (:func:`check_output_separability`) — and raises
    :class:`ExistenceError` naming the faults when one fails. See :class:`BeardStructure` and :func:`beard_gain`.
    """
    return _geometry(a, c, f, tol).structure


def plain_eigenvalues(structure: BeardStructure, radius: float, spacing: float) -> list[list[float]]:
    """The plain assignment: every free eigenvalue at ``radius`` where that can be placed exactly, else spread below it.

    A block whose free part is observed through as many independent outputs as it has free eigenvalues
    (:attr:`BeardStructure.output_ranks`) takes ``radius`` on all of them exactly (its placement is a scalar
    block). Any other block gets distinct eigenvalues ``radius, radius − s, radius − 2s, …`` with
    ``s = min(spacing, radius / m)`` (all within ``(0, radius]``): a repeated eigenvalue there would be a Jordan
    block or an ill-conditioned one, which round-off moves by ``ε^(1/m)`` (a triple pole through one output lands
    1e-3 away) — beyond the decay bound it was meant to meet.

    Parameters
    ----------
    structure
        The geometry (:func:`beard_structure`).
    radius
        The decay bound ``r`` (z-plane, ``0 < r < 1``).
    spacing
        The distance between the eigenvalues of a block that cannot take ``radius`` several times.

    Returns
    -------
    list of list of float
        One list per block, of lengths :attr:`BeardStructure.free_counts`: the ``eigenvalues`` of :func:`beard_gain`.
    """
    ranks = structure.output_ranks or tuple(0 for _ in structure.free_counts)
    out = []
    for m, rank in zip(structure.free_counts, ranks, strict=True):
        step = 0.0 if rank >= m else min(float(spacing), float(radius) / m)
        out.append([float(radius) - step * i for i in range(m)])
    return out


def beard_gain(
    a: object,
    c: object,
    f: object,
    eigenvalues: Sequence[Sequence[complex]],
    *,
    discrete: bool = True,
    tol: float | None = None,
) -> BeardGain:
    """A gain ``L`` making every detection space ``T_i`` of the columns ``f_i`` of ``F`` ``(A − L C)``-invariant.

    ``eigenvalues`` has ``k + 1`` entries (``k`` faults): the eigenvalues of ``A − L C`` on ``T_i`` (modulo the
    unobservable subspace ``N`` of ``(C, A)``) for each fault, then those on the rest of the state space; their
    lengths are :attr:`BeardStructure.free_counts` (:func:`beard_structure`), each closed under conjugation. The
    spectrum of ``A − L C`` is their union with :attr:`BeardStructure.fixed`. Those fixed modes must be stable
    (inside the unit circle for ``discrete``, in the open left half plane otherwise) — mutual detectability —
    or :class:`ExistenceError` names them and the faults.

    Construction (Massoumnia, IEEE TAC 31(9), 1986, section IV), on the scaled problem:

    1. Restrict to ``X̄ = N^⊥`` (``Ā = Qᵀ A Q``, ``C̄ = C Q``; ``N`` is invariant under every ``A − L C``, its
       spectrum fixed); there ``(C̄, Ā)`` is observable and ``T̄_i = Qᵀ T_i`` form a direct sum.
    2. A common friend ``L̄_0``: the minimum-norm solution of the linear equations
       ``(I − P_{T̄_i}) (Ā − L̄ C̄) T̄_i = 0``, ``i = 1…k`` (solvable under output separability).
    3. In the basis ``V = [V̄_1, …, V̄_k, V̄_c]`` (``V̄_c`` spanning ``(Σ T̄_i)^⊥``), ``V⁻¹ (Ā − L̄_0 C̄) V`` is
       block upper triangular with diagonal blocks ``X_1, …, X_k, Z``. With ``U = [U_1, …, U_k, U_c]`` bases of
       ``C̄ T̄_i`` and of their complement, and ``Π_i`` the rows of ``U⁻¹`` of block ``i``, the gains
       ``ΔL_i = V̄_i M_i Π_i`` change ``X_i`` alone into ``X_i − M_i (U_iᵀ C̄ V̄_i)`` and keep every ``T̄_j``
       invariant (``Π_i C̄ T̄_j = 0`` for ``j ≠ i``); ``ΔL_c = V̄_c M_c Π_c`` changes ``Z`` alone into
       ``Z − M_c (U_cᵀ C̄ V̄_c)``. Each ``M`` is an observer pole placement on its block
       (:func:`scipy.signal.place_poles`, Kautsky–Nichols–Van Dooren; Ackermann's formula for one output),
       restricted to the observable part of the block's pair. Every ``(U_iᵀ C̄ V̄_i, X_i)`` is observable
       (an unobservable eigenvector in ``T̄_i ∩ ker C̄`` would be one of ``(C̄, Ā)``): all ``dim T̄_i``
       eigenvalues on a detection space are free. The unobservable part of ``(U_cᵀ C̄ V̄_c, Z)`` is fixed.
    4. ``L = ‖A‖/‖C‖ · Q (L̄_0 + Σ ΔL_i + ΔL_c)``; the invariance of every ``T_i`` is verified
       (:class:`CertificateError` when it fails).
    """
    geo = _geometry(a, c, f, tol)
    st = geo.structure
    k = len(st.spaces)
    unstable = [complex(x) for x in st.fixed if (abs(x) >= 1.0 - 1e-10 if discrete else x.real >= -1e-10 * max(1.0, abs(x)))]
    if unstable:
        where = "of (C, A), unobservable" if any(np.isclose(x, st.unobservable).any() for x in unstable) else "fixed by the geometry"
        raise ExistenceError(
            f"faults {_faults(range(1, k + 1))} are not mutually detectable: the eigenvalue(s) "
            f"{', '.join(f'{x:.6g}' for x in unstable)} of A − L C, {where}, are not "
            f"{'inside the unit circle' if discrete else 'in the open left half plane'} for any gain that keeps "
            "every detection space invariant"
        )
    if isinstance(eigenvalues, (str, bytes)) or len(eigenvalues) != k + 1:
        raise ArgumentError(
            f"eigenvalues must be {k + 1} lists (one per fault, then the rest) of lengths {list(st.free_counts)}; "
            f"got {eigenvalues!r}"
        )
    gbar = geo.friend.copy()
    umat = np.hstack(geo.outputs)
    uinv = np.linalg.inv(umat)
    start = 0
    for b, (v, u, (x, cx, nu)) in enumerate(zip(geo.blocks, geo.outputs, geo.pairs, strict=True)):
        pi = uinv[start : start + u.shape[1]]
        start += u.shape[1]
        given = _eigenvalue_list(eigenvalues[b], b, k, st.free_counts[b])
        _check_multiplicity(given, st.output_ranks[b] if st.output_ranks else given.size, b, k)
        want = given / geo.na
        gbar = gbar + v @ _place_observable_part(x, cx, nu, want, _block_name(b, k), geo.tol) @ pi
    gain = geo.q @ gbar * (geo.na / geo.nc)
    am, cm = _pair(a, c)
    closed = am - gain @ cm
    scale = max(float(np.linalg.norm(closed, 2)), np.finfo(float).tiny)
    for i, s in enumerate(st.spaces):
        res = float(np.linalg.norm(closed @ s.basis - s.basis @ (s.basis.T @ closed @ s.basis), 2)) / scale
        if res > 1e-8:
            raise CertificateError(f"the detection space of fault {i + 1} is not (A − L C)-invariant: relative residual {res:.3g}")
    return BeardGain(gain, st)


def _block_name(b: int, k: int) -> str:
    return f"the detection space of fault {b + 1}" if b < k else "the rest of the state space"


def _eigenvalue_list(value: Sequence[complex], b: int, k: int, count: int) -> np.ndarray:
    label = f"eigenvalues[{b}] ({_block_name(b, k)})"
    try:
        ev = np.asarray(value, dtype=complex).reshape(-1)
    except (TypeError, ValueError):
        raise ArgumentError(f"{label} must be a list of {count} numbers; got {value!r}") from None
    if ev.size != count:
        raise ArgumentError(f"{label} must have {count} eigenvalues (the free ones there); got {ev.size}")
    if not np.all(np.isfinite(ev)):
        raise ArgumentError(f"{label} must be finite; got {value!r}")
    if ev.size and np.max(np.abs(np.sort_complex(ev) - np.sort_complex(ev.conj()))) > 1e-12 * max(1.0, float(np.max(np.abs(ev)))):
        raise ArgumentError(f"{label} must be closed under conjugation (a real gain); got {value!r}")
    return ev


def _place_observable_part(x: np.ndarray, cx: np.ndarray, nu: np.ndarray, want: np.ndarray, label: str, tol: float) -> np.ndarray:
    """``M`` with ``σ(X − M C_x) = want ∪ σ(X|nu)``, ``nu`` the unobservable subspace of ``(C_x, X)`` (kept fixed)."""
    if want.size == 0:
        return np.zeros((x.shape[0], cx.shape[0]))
    ob = orth_complement(nu)  # nu is X-invariant: X in the basis [ob, nu] is block lower triangular
    xo, co = ob.T @ x @ ob, cx @ ob
    # compress the outputs to full row rank (place_poles wants an input matrix of full column rank)
    uu, ss, vh = np.linalg.svd(co, full_matrices=False)
    r = int(np.sum(ss > tol * float(ss[0])))
    cr = vh[:r]
    if r == 1:
        kr = _ackermann(xo.T, cr.T, want)
    else:
        try:
            kr = scipy.signal.place_poles(xo.T, cr.T, want).gain_matrix
        except ValueError as exc:
            raise ArgumentError(f"cannot place the eigenvalues asked for on {label} (pole placement: {exc}); "
                                "expected eigenvalues a few 1e-3 apart") from None
    mo = kr.T  # xo − mo cr
    return ob @ mo @ (np.diag(1.0 / ss[:r]) @ uu[:, :r].T)


def _check_multiplicity(ev: np.ndarray, rank: int, b: int, k: int) -> None:
    """Refuse an eigenvalue asked for more often than the block's outputs can place it (more than once through one
    output is Ackermann's formula, exact: a single Jordan block)."""
    if ev.size == 0 or rank <= 1:
        return
    values, counts = np.unique(np.round(ev, 12), return_counts=True)
    if counts.max() > rank:
        z = complex(values[int(np.argmax(counts))])
        raise ArgumentError(
            f"eigenvalues[{b}] ({_block_name(b, k)}): {_shown_complex(z)} is asked for {int(counts.max())} times, but that "
            f"block is observed through {rank} independent outputs, so one eigenvalue can be placed there at most {rank} "
            f"times; expected at most {rank} copies of each value (spread the others, e.g. {_shown_complex(z)} and values "
            "0.01 to 0.05 below it)"
        )


def _shown_complex(z: complex) -> str:
    z = complex(z)
    return f"{z.real:.6g}" if z.imag == 0 else f"{z.real:.6g}{z.imag:+.6g}j"


def _ackermann(a: np.ndarray, b: np.ndarray, poles: np.ndarray) -> np.ndarray:
    """``K`` with ``σ(A − b K) = poles`` for one input (Ackermann's formula; repeated poles allowed)."""
    m = a.shape[0]
    ctrb = np.hstack([np.linalg.matrix_power(a, j) @ b for j in range(m)])
    coeffs = np.real(np.poly(poles))
    phi = sum((coeffs[j] * np.linalg.matrix_power(a, m - j) for j in range(m + 1)), np.zeros_like(a))
    e = np.zeros((1, m))
    e[0, -1] = 1.0
    return np.asarray(e @ sla.solve(ctrb, phi))
