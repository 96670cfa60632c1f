"""Small linear-algebra helpers shared by every design method.

One shape checker that names the offending matrix, numerical rank with a
stated tolerance, discrete Lyapunov solves, and Markov parameters.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import scipy.linalg as sla

from fdisyn.runtime.errors import ShapeError

__all__ = [
    "as_matrix",
    "check_shape",
    "as_square",
    "as_symmetric",
    "rank",
    "rank_tol",
    "dlyap",
    "spectral_radius",
    "markov_parameters",
    "rel_diff",
    "transfer_size",
    "undetectable_modes",
]


def as_matrix(value: object, name: str, *, rows: int | None = None, cols: int | None = None) -> np.ndarray:
    """Convert ``value`` to a finite 2-D float array, checking its shape.

    ``rows``/``cols`` of ``None`` accept any size. A 1-D input is read as a
    column when ``cols == 1`` and as a row when ``rows == 1``; otherwise it is
    refused, because guessing the orientation hides mistakes.
    """
    a = np.asarray(value, dtype=float)
    if a.ndim == 0:
        a = a.reshape(1, 1)
    elif a.ndim == 1:
        if cols == 1:
            a = a.reshape(-1, 1)
        elif rows == 1:
            a = a.reshape(1, -1)
        elif a.size == 0:
            a = a.reshape(rows or 0, cols or 0)
        else:
            raise ShapeError(
                f"{name} must be a 2-D matrix; got a 1-D array of length {a.size} "
                f"(expected shape ({_dim(rows)}, {_dim(cols)}))"
            )
    elif a.ndim > 2:
        raise ShapeError(f"{name} must be a 2-D matrix; got an array with shape {a.shape}")
    check_shape(a, name, rows=rows, cols=cols)
    if not np.all(np.isfinite(a)):
        bad = tuple(int(i) for i in np.argwhere(~np.isfinite(a))[0])
        raise ShapeError(f"{name} contains a non-finite entry at index {bad}: {a[bad]!r}")
    return a


def as_square(value: object, name: str) -> np.ndarray:
    """A finite square matrix (a state matrix), or :class:`ShapeError` naming it."""
    a = as_matrix(value, name)
    if a.shape[0] != a.shape[1]:
        raise ShapeError(f"{name} must be square; got shape {a.shape}")
    return a


def as_symmetric(value: object, name: str, n: int, *, psd: bool = False) -> np.ndarray:
    """A symmetric ``n × n`` matrix (symmetrised), optionally positive semidefinite.

    Symmetry is tested to 1e-10 relative (a covariance computed in floating
    point is symmetric to round-off); PSD allows eigenvalues down to
    −1e-12 times the largest.
    """
    a = as_matrix(value, name, rows=n, cols=n)
    scale = max(1.0, float(np.abs(a).max(initial=0.0)))
    if not np.allclose(a, a.T, rtol=0.0, atol=1e-10 * scale):
        raise ShapeError(f"{name} must be symmetric; max |{name} − {name}ᵀ| = {np.max(np.abs(a - a.T)):.3g}")
    a = 0.5 * (a + a.T)
    if psd and n:
        ev = np.linalg.eigvalsh(a)
        if ev[0] < -1e-12 * max(1.0, float(np.max(np.abs(ev)))):
            raise ShapeError(f"{name} must be positive semidefinite (a covariance); smallest eigenvalue {ev[0]:.3g}")
    return a


def _dim(d: int | None) -> str:
    return "any" if d is None else str(d)


def check_shape(a: np.ndarray, name: str, *, rows: int | None = None, cols: int | None = None) -> None:
    """Raise :class:`ShapeError` naming ``name`` unless ``a`` has the shape."""
    ok = a.ndim == 2 and (rows is None or a.shape[0] == rows) and (cols is None or a.shape[1] == cols)
    if not ok:
        raise ShapeError(f"{name} has shape {a.shape}; expected ({_dim(rows)}, {_dim(cols)})")


def rank_tol(a: np.ndarray) -> float:
    """The rank tolerance used throughout: ``max(shape) * eps * sigma_max``.

    This is the LAPACK/NumPy convention: singular values below it are
    indistinguishable from round-off of a backward-stable SVD.
    """
    if a.size == 0:
        return 0.0
    s = np.linalg.svd(a, compute_uv=False)
    return float(max(a.shape) * np.finfo(float).eps * (s[0] if s.size else 0.0))


def rank(a: np.ndarray) -> int:
    """Numerical rank with :func:`rank_tol`."""
    if a.size == 0:
        return 0
    s = np.linalg.svd(a, compute_uv=False)
    return int(np.sum(s > rank_tol(a)))


def dlyap(a: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Solve ``X = A X Aᵀ + Q`` (discrete Lyapunov) and symmetrise the result.

    Uses SciPy's Bartels–Stewart based solver; the caller checks stability.
    """
    x = sla.solve_discrete_lyapunov(a, q, method="bilinear" if a.shape[0] > 10 else "direct")
    return 0.5 * (x + x.T)


def spectral_radius(a: np.ndarray) -> float:
    """Largest eigenvalue modulus of a square matrix (0 for an empty one)."""
    if a.size == 0:
        return 0.0
    return float(np.max(np.abs(np.linalg.eigvals(a))))


def markov_parameters(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray, count: int) -> list[np.ndarray]:
    """``[D, C B, C A B, …, C A^{count-2} B]``: the first ``count`` Markov parameters.

    A discrete LTI system's transfer function is zero iff its first ``n + 1``
    Markov parameters vanish (Cayley–Hamilton), ``n`` the state dimension.
    """
    out = [d]
    ab = b
    for _ in range(count - 1):
        out.append(c @ ab)
        ab = a @ ab
    return out


def transfer_size(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> float:
    """Largest normalised Markov parameter of ``(A, B, C, D)``: zero iff the transfer is zero.

    ``max(‖D‖/(‖C‖‖B‖ + ‖D‖), max_k ‖C A^k B‖ / (‖C‖ ‖A‖^k ‖B‖))`` over
    ``k ≤ n`` (Cayley–Hamilton). Independent of units and of order ``eps`` for
    a transfer that cancels exactly in exact arithmetic.
    """
    tiny = np.finfo(float).tiny
    if b.shape[1] == 0 or c.shape[0] == 0:
        return 0.0
    nc, nb = float(np.linalg.norm(c, 2)), float(np.linalg.norm(b, 2))
    na = max(float(np.linalg.norm(a, 2)), tiny)
    params = markov_parameters(a, b, c, d, a.shape[0] + 2)
    nd = float(np.linalg.norm(d, 2))
    worst = nd / max(nc * nb + nd, tiny)
    for k, mk in enumerate(params[1:]):
        worst = max(worst, float(np.linalg.norm(mk, 2)) / max(nc * nb * na**k, tiny))
    return worst


def rel_diff(a: np.ndarray, b: np.ndarray) -> float:
    """Normwise relative difference ``‖a − b‖_F / max(‖b‖_F, tiny)``."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    nb = float(np.linalg.norm(b))
    return float(np.linalg.norm(a - b)) / max(nb, np.finfo(float).tiny)


def block_diag(blocks: Sequence[np.ndarray]) -> np.ndarray:
    """Block-diagonal matrix of possibly empty blocks."""
    return sla.block_diag(*blocks) if blocks else np.zeros((0, 0))


def undetectable_modes(a: np.ndarray, c: np.ndarray, *, margin: float = 1e-10) -> list[complex]:
    """Eigenvalues ``λ`` of ``A`` with ``|λ| ≥ 1 − margin`` that ``C`` cannot see (PBH test).

    ``(C, A)`` is detectable iff the list is empty: ``rank [λI − A; C] = n`` for
    every such ``λ``. The rank decision allows 1000× the SVD round-off.
    """
    n = a.shape[0]
    out = []
    for lam in np.linalg.eigvals(a):
        if abs(lam) < 1.0 - margin:
            continue
        pbh = np.vstack([lam * np.eye(n) - a, np.asarray(c, dtype=complex)])
        s = np.linalg.svd(pbh, compute_uv=False)
        if s[-1] <= max(pbh.shape) * np.finfo(float).eps * s[0] * 1e3:
            out.append(complex(lam))
    return out
