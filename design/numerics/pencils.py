"""The system pencil of a state-space model: normal rank, left minimal indices and polynomial left null vectors.

For ``G(λ) = C (λI − A)⁻¹ B + D`` the system pencil is

    S(λ) = [A − λI  B]
           [C       D]

Its normal rank is ``n + rank G``, and for a minimal realisation its left Kronecker indices are the left minimal
indices of ``G``: the row degrees ``ν₁ ≤ ν₂ ≤ …`` of a minimal polynomial basis of the rational left null space of
``G`` (Van Dooren & Verghese, *Linear Algebra Appl.* 1979; Varga, *Solving Fault Diagnosis Problems*, Springer
2017, sec. 9.1). The polynomial null vectors of degree at most ``k`` then span

    Σᵢ max(0, k − νᵢ + 1)

dimensions (:func:`null_dimension`). The pencil reductions are SLICOT's through slycot: ``TB01PD`` (a minimal
realisation by orthogonal staircase reductions) and ``AG08BD`` (the normal rank and the Kronecker indices).
:func:`polynomial_left_null` writes the null vectors of a bounded degree out as a block Toeplitz null space, for
their values at a given point.
"""

from __future__ import annotations

import numpy as np
import slycot

from fdisyn.runtime.errors import SolverError

__all__ = ["left_kronecker_indices", "minimal_realisation", "normal_rank", "null_dimension", "polynomial_left_null"]

TOEPLITZ_ENTRIES = 4_000_000
"""Largest block Toeplitz matrix (entries) :func:`polynomial_left_null` forms: its SVD then takes about a second
and 100 MB."""


def _padded(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Copies in the shapes SLICOT's reductions work in (``B`` ``n × max(m, p)``, ``C`` ``max(1, m, p) × n``)."""
    n, m, p = A.shape[0], B.shape[1], C.shape[0]
    bw = np.zeros((n, max(m, p, 1)))
    bw[:, :m] = B
    cw = np.zeros((max(1, m, p), n))
    cw[:p] = C
    return np.array(A, dtype=float, order="F"), np.asfortranarray(bw), np.asfortranarray(cw)


def minimal_realisation(A: np.ndarray, B: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A minimal realisation of ``C (λI − A)⁻¹ B``: the uncontrollable and unobservable parts removed (SLICOT
    ``TB01PD``, balanced first).

    Parameters
    ----------
    A, B, C : numpy.ndarray
        The realisation (``n × n``, ``n × m``, ``p × n``).

    Returns
    -------
    tuple of numpy.ndarray
        ``(Ar, Br, Cr)`` of the minimal order.
    """
    n, m, p = A.shape[0], B.shape[1], C.shape[0]
    if n == 0 or m == 0 or p == 0:
        return np.zeros((0, 0)), np.zeros((0, m)), np.zeros((p, 0))
    a, b, c = _padded(A, B, C)
    try:
        ar, br, cr, nr = slycot.tb01pd(n, m, p, a, b, c, job="M", equil="S")
    except slycot.exceptions.SlycotError as exc:  # pragma: no cover - argument errors only
        raise SolverError(f"the minimal realisation (SLICOT TB01PD) failed: {exc}") from exc
    return np.array(ar[:nr, :nr]), np.array(br[:nr, :m]), np.array(cr[:p, :nr])


def _ag08bd(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray) -> tuple[int, list[int]]:
    """``(normal rank of G, left Kronecker indices of the system pencil)`` (SLICOT ``AG08BD`` with ``E = I``,
    balanced). ``AB08ND``, the routine for ``E = I``, reported a normal rank of 2 for 3 × 3 systems of rank 3 with a
    rank-one ``D`` (through slycot 0.7.1); ``AG08BD``'s staircase agrees with the rank at random points."""
    n, m, p = A.shape[0], B.shape[1], C.shape[0]
    if p == 0:
        return 0, []
    if n == 0:  # a constant G = D
        rank = int(np.linalg.matrix_rank(D)) if m else 0
        return rank, [0] * (p - rank)
    if m == 0:  # no columns: the rows of [A − λI; C] alone
        m, B, D = 1, np.zeros((n, 1)), np.zeros((p, 1))
    try:
        out = slycot.ag08bd(n, n, m, p, np.array(A, float), np.eye(n), np.array(B, float), np.array(C, float), np.array(D, float), equil="S")
    except slycot.exceptions.SlycotError as exc:  # pragma: no cover - argument errors only
        raise SolverError(f"the system pencil's reduction (SLICOT AG08BD) failed: {exc}") from exc
    return int(out[2]) - n, sorted(int(k) for k in out[7])


def normal_rank(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray) -> int:
    """The normal rank of ``G(λ) = C (λI − A)⁻¹ B + D``: its rank at almost every ``λ`` (SLICOT ``AG08BD``).

    Parameters
    ----------
    A, B, C, D : numpy.ndarray
        Any realisation (minimal or not: the normal rank does not depend on it).

    Returns
    -------
    int
        The normal rank (0 for no inputs or no outputs).
    """
    if B.shape[1] == 0 or C.shape[0] == 0:
        return 0
    return _ag08bd(A, B, C, D)[0]


def left_kronecker_indices(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: np.ndarray) -> tuple[int, ...]:
    """The left Kronecker indices of the system pencil of this realisation, ascending (SLICOT ``AG08BD``): the
    row degrees of a minimal basis of its polynomial left null vectors ``[w(λ) v(λ)]``, whose ``v`` annihilates
    ``G`` and makes ``v C (λI − A)⁻¹`` polynomial, i.e. cancels every mode of the realisation, excited or not by
    these inputs. For a minimal realisation (:func:`minimal_realisation`) they are the left minimal indices of
    ``G``.

    Parameters
    ----------
    A, B, C, D : numpy.ndarray
        The realisation.

    Returns
    -------
    tuple of int
        The indices.
    """
    p = C.shape[0]
    if B.shape[1] == 0 and A.shape[0] == 0:
        return (0,) * p
    rank, kron = _ag08bd(A, B, C, D)
    if len(kron) != p - rank:  # pragma: no cover - SLICOT's own consistency
        raise SolverError(f"the system pencil gave {len(kron)} left Kronecker indices for a left null space of dimension {p - rank}")
    return tuple(kron)


def null_dimension(indices: tuple[int, ...] | list[int], k: int) -> int:
    """Dimension of the polynomial left null vectors of degree at most ``k`` for left Kronecker indices ``indices``:
    ``Σᵢ max(0, k − νᵢ + 1)`` (every such vector is a polynomial combination of the minimal basis with degrees
    bounded by the basis' predictable degrees).

    Parameters
    ----------
    indices : sequence of int
        The left Kronecker indices (:func:`left_kronecker_indices`).
    k : int
        The degree bound.

    Returns
    -------
    int
        The dimension.
    """
    return int(sum(max(0, k - v + 1) for v in indices))


def polynomial_left_null(M: np.ndarray, N: np.ndarray, k: int, count: int) -> np.ndarray:
    """A basis of the polynomial row vectors ``x(λ) = Σᵢ₌₀ᵏ xᵢ λⁱ`` with ``x(λ) (M − λ N) = 0``, as the rows of
    ``[x₀ … x_k]``, given their number ``count`` (:func:`null_dimension` of the pencil's left minimal indices).

    ``x (M − λN) = 0`` coefficient by coefficient is ``x₀ M = 0``, ``xᵢ M − xᵢ₋₁ N = 0`` (``1 ≤ i ≤ k``) and
    ``x_k N = 0``: the left null space of a block Toeplitz matrix, the left singular vectors of its ``count``
    smallest singular values (the dimension is known, so no rank tolerance is needed).

    Parameters
    ----------
    M, N : numpy.ndarray
        The pencil's two matrices (``r × c`` each).
    k : int
        The degree bound.
    count : int
        The dimension of the null space.

    Returns
    -------
    numpy.ndarray
        ``(count, (k + 1) r)``.

    Raises
    ------
    SolverError
        The Toeplitz matrix would exceed :data:`TOEPLITZ_ENTRIES`.
    """
    r, c = M.shape
    rows, cols = (k + 1) * r, (k + 2) * c
    if rows * cols > TOEPLITZ_ENTRIES:
        raise SolverError(
            f"the null vectors of degree {k} of a pencil of {r} × {c} need a Toeplitz matrix of {rows} × {cols}, above "
            f"{TOEPLITZ_ENTRIES:,} entries; analyse a smaller plant or omit the frequencies (weak structure)"
        )
    if count == 0:
        return np.zeros((0, rows))
    t = np.zeros((rows, cols))
    for i in range(k + 1):
        t[i * r : (i + 1) * r, i * c : (i + 1) * c] = M
        t[i * r : (i + 1) * r, (i + 1) * c : (i + 2) * c] = -N
    u = np.linalg.svd(t, full_matrices=True)[0]
    return u[:, rows - count :].T
