"""Small linear-algebra functions shared by every design method.

The validators every model and setting is read with — numbers only
(:func:`real_array`), matrices and vectors of a stated shape that name the
offending argument (:func:`as_matrix`, :func:`as_square`, :func:`as_vector`),
symmetric matrices and covariances (:func:`as_symmetric`,
:func:`as_covariance`), read-only copies (:func:`frozen_array`) — then
numerical rank with a stated tolerance, the discrete Lyapunov solve, and
Markov parameters.
"""

from __future__ import annotations

import numpy as np
from fdisyn.runtime.errors import ArgumentError, ExistenceError, ShapeError
from fdisyn.runtime.names import shown
from fdisyn.runtime.values import real_number

__all__ = [
    "real_array",
    "frozen_array",
    "as_matrix",
    "as_vector",
    "check_shape",
    "as_square",
    "as_symmetric",
    "as_covariance",
    "rank",
    "rank_tol",
    "dlyap",
    "spectral_radius",
    "markov_parameters",
    "rel_diff",
    "transfer_size",
    "psd_factor",
    "normal_rank",
    "unobservable_modes",
    "state_balancing",
]


def real_array(value: object, name: str) -> np.ndarray:
    """``value`` (a number, nested lists of numbers or a numeric array) as a float array.

    Numbers only: NumPy's ``asarray(…, dtype=float)`` would read the string
    ``"1.5"`` as 1.5 and ``true`` as 1.0, and raise ``OverflowError`` on an
    integer beyond the double range — values of a plant file are refused
    here instead (:class:`ArgumentError` naming ``name``), never converted;
    ragged rows are a :class:`ShapeError`.
    """
    if isinstance(value, np.ndarray) and value.dtype.kind in "fiu":
        return value.astype(float)
    try:
        leaves = np.asarray(value, dtype=object)
    except ValueError:  # rows of different lengths
        raise ShapeError(f"{name} must be a number or a matrix of numbers (rows of one length)") from None
    for x in leaves.flat:
        if real_number(x) is None:
            raise ArgumentError(f"{name} must hold numbers only; found {shown(x)}")
    try:
        return leaves.astype(float)
    except OverflowError:
        raise ArgumentError(f"{name} holds an integer beyond the range of a double; expected a finite number") from None


def frozen_array(a: object) -> np.ndarray:
    """A read-only float copy (plants, designs and settings are immutable)."""
    out = np.array(a, dtype=float, copy=True)
    out.setflags(write=False)
    return out


def as_vector(value: object, name: str, size: int, *, fill: bool = False) -> np.ndarray:
    """``size`` numbers (:func:`real_array`) as a 1-D float array; nested lists are flattened.

    With ``fill``, a single number stands for all ``size`` entries. Raises
    :class:`ShapeError` naming ``name`` for another number of entries.
    """
    a = real_array(value, name)
    if fill and a.ndim == 0:
        a = np.full(size, float(a))
    a = a.reshape(-1)
    if a.size != size:
        raise ShapeError(f"{name} has {a.size} entries; expected {size}")
    return a


def as_matrix(value: object, name: str, *, rows: int | None = None, cols: int | None = None) -> np.ndarray:
    """Convert ``value`` to a finite 2-D float array, checking its shape.

    ``rows``/``cols`` of ``None`` accept any size. A 1-D input is read as a
    column when ``cols == 1`` and as a row when ``rows == 1``; otherwise it is
    refused, because guessing the orientation hides mistakes. Entries must
    be numbers (:func:`real_array`).
    """
    a = real_array(value, name)
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
        raise ArgumentError(f"{name} contains a non-finite entry at index {bad}: {a[bad]!r}")
    return a


def as_square(value: object, name: str) -> np.ndarray:
    """A finite square matrix (a state matrix), or :class:`ShapeError` naming it."""
    a = as_matrix(value, name)
    if a.shape[0] != a.shape[1]:
        raise ShapeError(f"{name} must be square; got shape {a.shape}")
    return a


def as_symmetric(value: object, name: str, n: int, *, psd: bool = False, definite: bool = False) -> np.ndarray:
    """A symmetric ``n × n`` matrix (symmetrised), optionally positive semidefinite or definite.

    Symmetry is tested to 1e-10 relative (a covariance computed in floating
    point is symmetric to round-off); PSD allows eigenvalues down to
    −1e-12 times the largest; ``definite`` wants the smallest above zero.
    """
    a = as_matrix(value, name, rows=n, cols=n)
    scale = max(1.0, float(np.abs(a).max(initial=0.0)))
    if not np.allclose(a, a.T, rtol=0.0, atol=1e-10 * scale):
        raise ArgumentError(f"{name} must be symmetric; max |{name} − {name}ᵀ| = {np.max(np.abs(a - a.T)):.3g}")
    a = 0.5 * a + 0.5 * a.T  # halves first: 1e308 + 1e308 would overflow
    if (psd or definite) and n:
        ev = np.linalg.eigvalsh(a)
        if definite and ev[0] <= 0.0:
            raise ArgumentError(f"{name} must be positive definite; smallest eigenvalue {ev[0]:.3g}")
        if ev[0] < -1e-12 * max(1.0, float(np.max(np.abs(ev)))):
            raise ArgumentError(f"{name} must be positive semidefinite (a covariance); smallest eigenvalue {ev[0]:.3g}")
    return a


def as_covariance(value: object, name: str, n: int, *, definite: bool = False) -> np.ndarray:
    """An ``n × n`` covariance from a number (times ``I``), a vector (the diagonal) or a matrix.

    Then :func:`as_symmetric` with ``psd`` (and ``definite`` when asked): a
    :class:`ShapeError` names ``name`` for non-numbers, a wrong shape,
    asymmetry or a negative (``definite``: a non-positive) eigenvalue.
    """
    a = real_array(value, name)  # numbers only: "1e-2" or true are refused, not converted
    if a.ndim <= 1 and not np.all(np.isfinite(a)):  # before the arithmetic: inf · I would put nan off the diagonal
        raise ArgumentError(f"{name} must hold finite variances; got {shown(value)}")
    if a.ndim == 0:
        a = float(a) * np.eye(n)
    elif a.ndim == 1 and a.size == n:
        a = np.diag(a)
    return as_symmetric(a, name, n, psd=True, definite=definite)


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


def dlyap(a: np.ndarray, q: np.ndarray, *, refine: bool = True) -> np.ndarray:
    """Solve ``X = A X Aᵀ + Q`` (discrete Lyapunov): ``X = Σ_k A^k Q A^kᵀ`` by Smith's doubling.

    fdisyn's one Lyapunov solver: residual covariances, Gramians (H2 norms,
    balancing and scaling of the SDPs), the shift of the H₋ index LMI; ``Q``
    is positive semidefinite in every use. ``X ← X + A_k X A_kᵀ``,
    ``A_k ← A_k²``: a sum of PSD terms, so nothing cancels whatever the
    transient growth of a non-normal ``A`` (a Kronecker-product solve of
    ``(I − A ⊗ A) vec X = vec Q`` was observed 1e-5 off at
    cond(eigenvectors) = 800); against 50-digit solutions of that Kronecker
    system, ≤ 2e-16 relative on six random 4-state ``A`` with ``‖A‖₂`` from
    9e3 to 2.6e7 at ``ρ(A) ≤ 0.35``. The sum stops when the last increment
    is at round-off and ``‖A_k‖₂ ≤ 1/2``, so the remaining tail is below it
    too; ``ρ(A) ≥ 1`` (no solution of that form) raises
    :class:`ExistenceError` when the sum overflows or after 80 doublings.

    The residual ``A X Aᵀ + Q − X`` of the sum grows with ``‖A‖₂²``: for the
    strongly non-normal ``F`` of minimum-variance UIOs of random plants
    (‖F‖₂ = 328 at ρ(F) = 0.34) it was 1.3e-10 of ``‖X‖``. ``refine`` (the
    default) adds one step of iterative refinement — the residual, solved
    by the same sum, as a correction — which brings it to round-off, as the
    UIO certificate's Lyapunov-residual check requires. The Gramians of the
    SDP side (scaling and balancing, the H2 norm and fault normalisation,
    the H₋ LMI's shift) are sums without it (``refine=False``): none needs a
    smaller residual, and the singular (ZOH) case of the LMI observer turns
    round-off in its balancing Gramian into a different "optimal_inaccurate"
    first SDP (measured: its certificate gap moved from 2e-5 to 1.4e-3 of γ,
    over the 1e-3 bound, when the Gramians changed by 1e-16). The result is
    symmetrised.
    """
    x = _lyapunov_sum(a, q)
    if refine:
        r = a @ x @ a.T + q - x
        x = x + _lyapunov_sum(a, r)
    return 0.5 * (x + x.T)


def _lyapunov_sum(a: np.ndarray, q: np.ndarray) -> np.ndarray:
    """``Σ_k A^k Q A^kᵀ`` by Smith's doubling (:func:`dlyap`), symmetrised."""
    x = 0.5 * (q + q.T)
    ak = a.copy()
    with np.errstate(over="ignore", invalid="ignore"):  # an unstable A overflows: refused below
        for _ in range(80):
            inc = ak @ x @ ak.T
            x = x + inc
            if not np.all(np.isfinite(x)):
                break
            if np.linalg.norm(inc) <= np.finfo(float).eps * np.linalg.norm(x) and np.linalg.norm(ak, 2) <= 0.5:
                return 0.5 * (x + x.T)
            ak = ak @ ak
    raise ExistenceError(f"the Lyapunov sum did not converge: spectral radius of A is {spectral_radius(a):.12g}")


def orth_basis(m: np.ndarray, tol: float) -> np.ndarray:
    """Orthonormal basis of the column space of ``m`` (columns of order one): singular values above ``tol``."""
    if m.shape[1] == 0:
        return np.zeros((m.shape[0], 0))
    u, s, _ = np.linalg.svd(m, full_matrices=False)
    return u[:, : int(np.sum(s > tol))]


def orth_complement(v: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the orthogonal complement of the span of the orthonormal columns ``v``."""
    n, d = v.shape
    if d == 0:
        return np.eye(n)
    q, _ = np.linalg.qr(v, mode="complete")
    return q[:, d:]


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


def psd_factor(w: np.ndarray, name: str = "W") -> np.ndarray:
    """Full-column-rank factor ``B`` with ``B Bᵀ = W`` for a PSD matrix ``W``.

    ``B = U_r diag(√λ_r)`` from the eigendecomposition ``W = U Λ Uᵀ``, keeping
    the ``r`` eigenvalues above :func:`rank_tol`-style round-off
    (``n·eps·λ_max``), so ``B`` is ``n × r`` with orthogonal columns. Every
    other factor with ``r`` columns is ``B U`` for an orthogonal ``U``. A
    rank-deficient ``W`` (an uncontrollable mode) gives fewer columns rather
    than zero columns, which matters for the H₋ index: zero input columns
    would make it zero. Eigenvalues below ``−n·eps·λ_max`` mean ``W`` is not
    PSD and raise :class:`ShapeError`.
    """
    n = as_square(w, name).shape[0]
    if n == 0:
        return np.zeros((0, 0))
    lam, u = np.linalg.eigh(as_symmetric(w, name, n))
    tol = n * np.finfo(float).eps * max(float(lam[-1]), 0.0)
    if lam[0] < -tol * 1e3:
        raise ArgumentError(f"{name} must be positive semidefinite; smallest eigenvalue {lam[0]:.3g} (largest {lam[-1]:.3g})")
    keep = lam > tol
    # Largest eigenvalue first; fix each column's sign (largest entry positive)
    # so that the factor is a deterministic function of W.
    lam, u = lam[keep][::-1], u[:, keep][:, ::-1]
    idx = np.argmax(np.abs(u), axis=0)
    u = u * np.sign(u[idx, np.arange(u.shape[1])])[None, :]
    return u * np.sqrt(lam)[None, :]


def normal_rank(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray) -> int:
    """Normal rank of ``G(z) = C (zI − A)⁻¹ B + D``.

    ``rank [[A − zI, B], [C, D]] = n + rank G(z)`` for every ``z`` that is not
    a pole; the maximum over a few fixed points off the unit circle and off the
    real axis is the normal rank (a rank drop at all of them at once would
    need every point to be an invariant zero, and a finite zero set cannot
    contain them all). Rank tolerance: :func:`rank_tol` of the Rosenbrock matrix.
    """
    n = a.shape[0]
    best = 0
    for z in (1.37 * np.exp(0.61j), 0.53 * np.exp(2.29j), 2.11 * np.exp(-1.13j)):
        ros = np.block([[a - z * np.eye(n), b], [c, d]]).astype(complex)
        s = np.linalg.svd(ros, compute_uv=False)
        tol = max(ros.shape) * np.finfo(float).eps * (s[0] if s.size else 0.0) * 1e2
        best = max(best, int(np.sum(s > tol)) - n)
    return best


def unobservable_modes(a: np.ndarray, c: np.ndarray, *, region: str) -> list[complex]:
    """Eigenvalues of ``A`` in ``region`` that are unobservable from ``C`` (PBH test).

    ``region`` is ``"unstable-continuous"`` (``Re λ ≥ 0``), ``"unstable-discrete"``
    (``|λ| ≥ 1``) or ``"all"``. A mode is unobservable when
    ``[λI − A; C]`` loses rank; the smallest singular value is compared with
    ``1e3·max(shape)·eps·σ_max`` (a rank decision with three digits of margin
    over backward-stable round-off). The test is made on the pair in the
    units it is written in no more: each row of ``C`` is divided by its norm
    (the sensors' units) and the states are balanced first
    (:func:`state_balancing`, an exact power-of-two similarity), so the
    answer does not change when a state is measured in mm rather than m.
    """
    a = np.asarray(a, dtype=float)
    c = np.asarray(c, dtype=float)
    n = a.shape[0]
    out: list[complex] = []
    if n and c.size:
        norms = np.linalg.norm(c, axis=1)
        c = c[norms > 0] / norms[norms > 0, None]
        s = state_balancing(a, np.zeros((n, 0)), c)
        a, c = a / s[:, None] * s[None, :], c * s[None, :]
    for lam in np.linalg.eigvals(a):
        if region == "unstable-continuous" and lam.real < -1e-10 * max(1.0, abs(lam)):
            continue
        if region == "unstable-discrete" and abs(lam) < 1.0 - 1e-10:
            continue
        pbh = np.vstack([lam * np.eye(n) - a, c.astype(complex)])
        s = np.linalg.svd(pbh, compute_uv=False)
        if s[-1] <= 1e3 * max(pbh.shape) * np.finfo(float).eps * max(s[0], np.finfo(float).tiny):
            out.append(complex(lam))
    return out


BALANCE_MAX_EXPONENT = 200
"""The largest power of two (either way) :func:`state_balancing` scales a state by: ``2^±200 ≈ 1.6e±60`` keeps
every scaled entry of a plant (at most 1e150, :data:`fdisyn.runtime.schema.MAX_MAGNITUDE`) far from overflow
and underflow."""


def state_balancing(a: np.ndarray, inputs: np.ndarray, outputs: np.ndarray) -> np.ndarray:
    """A diagonal state scaling ``s`` (powers of two) that balances ``[[A, inputs], [outputs, 0]]``.

    The Parlett–Reinsch iteration of LAPACK's ``gebal`` (and SLICOT's ``TB01ID``, which balances a system
    matrix ``[[A, B], [C, 0]]``) on the states alone: in ``x = diag(s) x̃``, the plant's matrices become
    ``S⁻¹ A S``, ``S⁻¹ B``, ``C S``, and each state ``i`` is rescaled by the power of two that brings the norm
    of its column (``A`` off the diagonal, then ``outputs``) and of its row (``A`` off the diagonal, then
    ``inputs``) closest together, as long as that shrinks their sum of squares by 5 % or more; sweeps repeat
    until no state changes. Powers of two make the similarity exact in floating point (only exponents change),
    so a design on the scaled plant maps back to the user's states without round-off; and the scaled plant is
    the iteration's fixed point, so balancing it again gives ``s = 1`` exactly, as does any plant whose states
    are balanced already. The exponents are kept within ±:data:`BALANCE_MAX_EXPONENT`.

    Parameters
    ----------
    a : ndarray
        ``n × n`` state matrix.
    inputs : ndarray
        ``n × k`` columns entering the states (unknown-input and noise directions, each in its own unit).
    outputs : ndarray
        ``p × n`` rows reading the states (sensors, each in its own unit).

    Returns
    -------
    ndarray
        ``n`` positive powers of two, the typical state magnitudes ``s`` (``x = diag(s) x̃``).
    """
    a = np.abs(np.asarray(a, dtype=float))
    n = a.shape[0]
    off = a.copy()
    np.fill_diagonal(off, 0.0)
    ins = np.abs(np.asarray(inputs, dtype=float)).reshape(n, -1)
    outs = np.abs(np.asarray(outputs, dtype=float)).reshape(-1, n)
    # entries at round-off of the largest are zeros (e^(A Ts) = −I has off-diagonal 1e-16s): balancing them
    # would scale a state by 2^±200
    top = max(float(np.max(m, initial=0.0)) for m in (a, ins, outs))
    tiny = 4.0 * max(n, 1) * np.finfo(float).eps * top
    off, ins, outs = (np.where(m > tiny, m, 0.0) for m in (off, ins, outs))
    col_out = np.sum(outs**2, axis=0)
    row_in = np.sum(ins**2, axis=1)
    e = np.zeros(n)
    for _ in range(64 * max(n, 1)):
        changed = False
        for i in range(n):
            s = np.exp2(e)
            col = float(np.sum((off[:, i] * s[i] / s) ** 2) + col_out[i] * s[i] ** 2)
            row = float(np.sum((off[i, :] * s / s[i]) ** 2) + row_in[i] / s[i] ** 2)
            if not (col > 0.0 and row > 0.0 and np.isfinite(col) and np.isfinite(row)):
                continue
            k = float(np.round(0.25 * np.log2(row / col)))  # col·4^k ≈ row/4^k
            k = float(np.clip(e[i] + k, -BALANCE_MAX_EXPONENT, BALANCE_MAX_EXPONENT) - e[i])
            if k != 0.0 and col * 4.0**k + row / 4.0**k < 0.95 * (col + row):
                e[i] += k
                changed = True
        if not changed:
            break
    return np.exp2(e)
