"""Seeded random plants with a known answer, and independent existence tests, for the property campaign.

Every plant is built in well-conditioned coordinates ``x̄`` where its answer is known by construction, then handed
to fdisyn in badly scaled coordinates ``x = S x̄`` (``S`` diagonal, entries spread over up to six decades): a
similarity, so every transfer function, invariant zero, fixed mode and the existence of every design are those of
the well-conditioned model. The truths below are computed there, from first principles (Rosenbrock pencils, PBH
rank tests, exact sampling by the matrix exponential), and use nothing of fdisyn's.

UIO plants (:func:`uio_plant`): in coordinates where ``E = [0; I_q]`` and ``C = [C1 C2]``, an output-zeroing
input exists iff ``N C1 x1 = 0`` (``N`` the left null space of ``C2``), and then ``x2 = −M x1``; the invariant zeros
are the eigenvalues of ``Ā = A11 − A12 M`` unobservable from ``W = N C1``. Making ``ker W`` an ``Ā``-invariant
subspace with a chosen spectrum plants exactly those zeros; output injection ``A − K C`` then places the open-loop
eigenvalues without moving a zero (invariant zeros are invariant under output injection).

Beard plants (:func:`beard_plant`): a stable ``G`` with every fault direction's detection space invariant (an
eigenvector for a direction seen by the outputs, the plane ``{f, G f}`` for one that is not), outputs that tell the
residual directions apart, and ``A = G + L* C``: the gain ``L*`` is the known filter.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.signal

EPS = float(np.finfo(float).eps)


# --------------------------------------------------------------------------- independent truths


def zoh(a: np.ndarray, b: np.ndarray, ts: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold sampling: ``e^{[[A, B], [0, 0]] Ts}`` (Van Loan's block exponential)."""
    n, m = a.shape[0], b.shape[1]
    big = np.zeros((n + m, n + m))
    big[:n, :n], big[:n, n:] = a * ts, b * ts
    e = sla.expm(big)
    return e[:n, :n], e[:n, n:]


def noise_factor(a: np.ndarray, e: np.ndarray, ts: float) -> np.ndarray:
    """``B_J`` with ``B_J B_Jᵀ = ∫₀^Ts e^{Aτ} E Eᵀ e^{Aᵀτ} dτ`` (Van Loan 1978), as a symmetric square root."""
    n = a.shape[0]
    big = np.zeros((2 * n, 2 * n))
    big[:n, :n], big[:n, n:], big[n:, n:] = -a * ts, e @ e.T * ts, a.T * ts
    ex = sla.expm(big)
    phi = ex[n:, n:].T
    w = phi @ ex[:n, n:]
    w = 0.5 * (w + w.T)
    lam, v = np.linalg.eigh(w)
    return v @ np.diag(np.sqrt(np.clip(lam, 0.0, None))) @ v.T


def rank_of(m: np.ndarray, rel: float = 1e-9) -> int:
    s = np.linalg.svd(m, compute_uv=False)
    return int(np.sum(s > rel * max(s[0], 1e-300))) if s.size else 0


def invariant_zeros(a: np.ndarray, b: np.ndarray, c: np.ndarray, rng_seed: int = 1) -> np.ndarray:
    """Invariant zeros of ``(A, B, C, 0)``: the points where the Rosenbrock pencil ``[[A − zI, B], [C, 0]]`` loses rank.

    A tall or wide pencil is squared by a random projection of its longer side (its finite generalised eigenvalues,
    ``scipy.linalg.eigvals``, hold every zero and some spurious points); a candidate is kept where the smallest
    singular value of the full pencil, relative to its norm, is below 1e-8 (a true zero of this well-conditioned
    model sits at round-off, ~1e-15; a spurious point of a random projection at O(1e-3) or more).
    """
    n, m, p = a.shape[0], b.shape[1], c.shape[0]
    rng = np.random.default_rng(rng_seed)
    top = np.hstack([a, b])
    bot = np.hstack([c, np.zeros((p, m))])
    if p >= m:  # tall: combine the output rows
        proj = rng.standard_normal((m, p)) if p > m else np.eye(p)
        aa = np.vstack([top, proj @ bot])
        bb = np.zeros((n + m, n + m))
        bb[:n, :n] = np.eye(n)
    else:  # wide: combine the input columns
        proj = rng.standard_normal((m, p))
        aa = np.vstack([np.hstack([a, b @ proj]), np.hstack([c, np.zeros((p, p))])])
        bb = np.zeros((n + p, n + p))
        bb[:n, :n] = np.eye(n)
    cand = sla.eigvals(aa, bb)
    full = np.vstack([top, bot])
    scale = float(np.linalg.norm(full, 2))
    normal = min(n + p, n + m)
    out = []
    for z in cand[np.isfinite(cand)]:
        if abs(z) > 1e6 * scale:  # an infinite eigenvalue of the squared pencil, computed as a huge finite one
            continue
        pen = full.astype(complex).copy()
        pen[:n, :n] -= z * np.eye(n)
        s = np.linalg.svd(pen, compute_uv=False)
        if s[normal - 1] <= 1e-8 * max(scale, abs(z)):
            out.append(z)
    return np.array(out, dtype=complex)


def unobservable_modes(a: np.ndarray, c: np.ndarray, region: str) -> list[complex]:
    """PBH: eigenvalues ``λ`` of ``A`` in ``region`` where ``[λI − A; C]`` loses rank (relative tolerance 1e-9)."""
    n = a.shape[0]
    out = []
    for lam in np.linalg.eigvals(a):
        if region == "discrete" and abs(lam) < 1.0 - 1e-9:
            continue
        if region == "continuous" and lam.real < -1e-9 * max(1.0, abs(lam)):
            continue
        m = np.vstack([lam * np.eye(n) - a, c])
        s = np.linalg.svd(m, compute_uv=False)
        if s[-1] <= 1e-9 * max(1.0, float(np.linalg.norm(m, 2))):
            out.append(complex(lam))
    return out


def uncontrollable_modes(a: np.ndarray, b: np.ndarray, region: str) -> list[complex]:
    return unobservable_modes(a.T, b.T, region)


def uio_conditions(ad: np.ndarray, ed: np.ndarray, c: np.ndarray, *, all_poles: bool = False) -> tuple[bool, str]:
    """Whether a discrete UIO exists for ``(A_D, E_D, C)``: ``rank(C E) = rank(E) = q``, ``p > q``, and every invariant
    zero of ``(A_D, E_D, C)`` strictly inside the unit circle (``(C, A1)`` detectable; Darouach, Zasadzinski & Xu,
    IEEE TAC 39(3), 1994). ``all_poles``: every pole assignable, i.e. no invariant zero at all (``(C, A1)`` observable)."""
    p, q = c.shape[0], ed.shape[1]
    if rank_of(ed) != q:
        return False, f"rank(E) < q = {q}"
    if rank_of(c @ ed) != q:
        return False, f"rank(C E) = {rank_of(c @ ed)} < rank(E) = {q}"
    if p <= q:
        return False, f"p = {p} outputs ≤ q = {q} unknown inputs: no residual left"
    z = invariant_zeros(ad, ed, c)
    if all_poles and z.size:
        return False, f"invariant zeros {np.round(z, 6).tolist()}: (C, A1) not observable, not every pole assignable"
    bad = z[np.abs(z) >= 1.0 - 1e-9]
    if bad.size:
        return False, f"invariant zeros {np.round(bad, 6).tolist()} on or outside the unit circle: (C, A1) not detectable"
    return True, f"rank(C E) = q = {q}, p = {p}, zeros {np.round(z, 4).tolist()}"


def sampled_data_conditions(a: np.ndarray, e: np.ndarray, c: np.ndarray, ts: float) -> tuple[bool, str]:
    """Whether the sampled-data observer exists (Qiu, Wen & Jiang, Control Theory & Applications 27(8), 2010): E ≠ 0,
    ``(A, C)`` and ``(e^{A Ts}, C)`` detectable, and the DTARS of ``G_J = (A_D, B_J, C, 0)`` has a stabilising solution:
    no uncontrollable mode of ``(A_D, B_J)`` and no invariant zero of ``G_J`` on the unit circle."""
    if not np.any(e):
        return False, "E = 0"
    if unobservable_modes(a, c, "continuous"):
        return False, "(A, C) not detectable"
    ad = sla.expm(a * ts)
    if unobservable_modes(ad, c, "discrete"):
        return False, "(A_D, C) not detectable (pathological sampling)"
    bj = noise_factor(a, e, ts)
    u, s, _ = np.linalg.svd(bj)
    bj = u[:, s > 1e-10 * s[0]] * s[s > 1e-10 * s[0]]
    on_circle = [lam for lam in uncontrollable_modes(ad, bj, "discrete") if abs(abs(lam) - 1) < 1e-9]
    if on_circle:
        return False, f"(A_D, B_J) has uncontrollable modes on the unit circle {on_circle}"
    z = invariant_zeros(ad, bj, c)
    zc = z[np.abs(np.abs(z) - 1.0) < 1e-7]
    if zc.size:
        return False, f"G_J has invariant zeros on the unit circle {zc.tolist()}"
    return True, "detectable, no unit-circle zeros or uncontrollable modes of G_J"


def beard_certificate(ad: np.ndarray, c: np.ndarray, spaces: Sequence[np.ndarray], gain: np.ndarray, radius: float) -> tuple[bool, str]:
    """A Beard filter exists with every eigenvalue inside ``radius`` when ``gain`` is one: each detection space
    ``A − L C``-invariant, the residual directions ``C T_i`` independent, the spectral radius ``< radius``."""
    g = ad - gain @ c
    for i, t in enumerate(spaces):
        q, _ = np.linalg.qr(t)
        res = np.linalg.norm(g @ q - q @ (q.T @ g @ q), 2) / np.linalg.norm(g, 2)
        if res > 1e-9:
            return False, f"space {i} not invariant under the known gain ({res:.2e})"
    axes = [np.linalg.qr(c @ t)[0][:, : rank_of(c @ t)] for t in spaces]
    if rank_of(np.hstack(axes)) != sum(a.shape[1] for a in axes):
        return False, "residual directions C T_i dependent"
    rho = float(np.max(np.abs(np.linalg.eigvals(g))))
    if not rho < radius:
        return False, f"spectral radius {rho:.6g} ≥ the decay radius {radius:.6g}"
    return True, f"a gain with every detection space invariant and spectral radius {rho:.4g} < {radius:.4g}"


# --------------------------------------------------------------------------- the plants


@dataclass
class Case:
    """One seeded plant: the user's plant (badly scaled), its well-conditioned model, the design options and the truth."""

    id: str
    method: str
    plant: Any
    """The :class:`fdisyn.LinearPlant` handed to fdisyn (user coordinates ``x = S x̄``)."""
    good: dict[str, np.ndarray]
    """The well-conditioned model: ``A, B, C, E, Fx`` (continuous when ``continuous``), and ``S``."""
    Ts: float
    continuous: bool
    options: dict[str, Any]
    exists: bool
    why: str
    extra: dict[str, Any] = field(default_factory=dict)

    def discrete_good(self) -> dict[str, np.ndarray]:
        """The well-conditioned discrete model the design works on (sampled exactly here when continuous)."""
        g = self.good
        if not self.continuous:
            return dict(g)
        held = np.hstack([g["B"], g["E"], g["Fx"]])
        ad, hd = zoh(g["A"], held, self.Ts)
        m, q = g["B"].shape[1], g["E"].shape[1]
        return {**g, "A": ad, "B": hd[:, :m], "E": hd[:, m : m + q], "Fx": hd[:, m + q :]}


def log_uniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def state_scaling(rng: np.random.Generator, n: int, decades: float) -> np.ndarray:
    """Diagonal entries spanning exactly ``decades`` (one at 1, one at 10^decades, the rest log-uniform between)."""
    u = rng.uniform(0.0, decades, n)
    if n >= 2 and decades > 0:
        idx = rng.permutation(n)[:2]
        u[idx[0]], u[idx[1]] = 0.0, decades
    return 10.0**u


def user_plant(good: dict[str, np.ndarray], s: np.ndarray, *, Qc: np.ndarray, R: np.ndarray, Ts: float | None, **names: Any) -> Any:
    """The plant in coordinates ``x = S x̄``: ``S A S⁻¹, S B, C S⁻¹, S E, S Fx, S Q S``."""
    from fdisyn.models.linear import LinearPlant

    si = 1.0 / s
    return LinearPlant.create(
        A=s[:, None] * good["A"] * si[None, :],
        B=s[:, None] * good["B"],
        C=good["C"] * si[None, :],
        E=s[:, None] * good["E"] if good["E"].size else None,
        Fx=s[:, None] * good["Fx"] if good["Fx"].size else None,
        Q=s[:, None] * Qc * s[None, :],
        R=R,
        Ts=Ts,
        **names,
    )


def _spectrum(rng: np.random.Generator, n: int, omega: float, unstable: bool) -> np.ndarray:
    """``n`` distinct eigenvalues (rad/s): real and complex pairs, decays in [0.2, 2]·ω; one real one at
    +[0.02, 0.08]·ω when ``unstable``."""
    ev: list[complex] = []
    if unstable:
        ev.append(complex(rng.uniform(0.02, 0.08) * omega))
    while len(ev) < n:
        re = -omega * rng.uniform(0.2, 2.0)
        if n - len(ev) >= 2 and rng.random() < 0.4:
            im = omega * rng.uniform(0.2, 1.5)
            ev += [complex(re, im), complex(re, -im)]
        else:
            ev.append(complex(re))
    return np.array(ev)


def real_form(spectrum: Sequence[complex]) -> np.ndarray:
    """A real block-diagonal matrix with the eigenvalues ``spectrum`` (closed under conjugation)."""
    ev = sorted(np.asarray(spectrum, dtype=complex), key=lambda z: (z.real, abs(z.imag), z.imag))
    blocks, done = [], [False] * len(ev)
    for i, z in enumerate(ev):
        if done[i]:
            continue
        done[i] = True
        if abs(z.imag) < 1e-14:
            blocks.append(np.array([[z.real]]))
        else:
            j = next(j for j in range(len(ev)) if not done[j] and abs(ev[j] - z.conjugate()) < 1e-12)
            done[j] = True
            blocks.append(np.array([[z.real, z.imag], [-z.imag, z.real]]))
    return sla.block_diag(*blocks)


def injection(a: np.ndarray, c: np.ndarray, spectrum: Sequence[complex]) -> np.ndarray:
    """An output injection ``K`` with ``eig(A − K C) = spectrum`` (``(C, A)`` observable)."""
    n = a.shape[0]
    u, s, vt = np.linalg.svd(c)
    r = int(np.sum(s > 1e-10 * s[0]))
    back = (u[:, :r] / s[:r]).T  # C = U_r S_r V_r: K C = K_r V_r with K = K_r S_r⁻¹ U_rᵀ
    if r == n:  # C invertible on the state: A − K C is any matrix
        return (a - real_form(spectrum)) @ np.linalg.pinv(c)
    with warnings.catch_warnings():  # YT's robustness iteration may stop early: the poles are placed all the same
        warnings.simplefilter("ignore", UserWarning)
        kr = scipy.signal.place_poles(a.T, vt[:r].T, np.asarray(spectrum), maxiter=3).gain_matrix.T
    return kr @ back


def _orthogonal(rng: np.random.Generator, n: int) -> np.ndarray:
    q, r = np.linalg.qr(rng.standard_normal((n, n)))
    return q * np.sign(np.diag(r))[None, :]


def uio_plant(
    rng: np.random.Generator,
    *,
    n: int,
    q: int,
    p: int,
    spectrum: Sequence[complex],
    zeros: Sequence[float] = (),
    scale: float = 1.0,
    faults: int = 1,
) -> dict[str, np.ndarray]:
    """``(A, B, C, E, Fx)`` with ``rank(C E) = q``, exactly the invariant zeros ``zeros`` (real) of ``(A, E, C)`` and
    the eigenvalues ``spectrum``, in well-conditioned coordinates (``scale``: the size of the random blocks, the
    plant's frequency for a continuous one). The plane (s or z) is the caller's: the construction is algebraic."""
    n1, kz = n - q, len(zeros)
    assert p > q and kz <= n1
    c2 = rng.standard_normal((p, q))
    nn = sla.null_space(c2.T).T  # r × p, N C2 = 0
    r = nn.shape[0]
    w = np.hstack([np.zeros((r, kz)), rng.standard_normal((r, n1 - kz))])
    mm = rng.standard_normal((q, n1))
    c1 = c2 @ mm + nn.T @ w
    abar = scale * rng.standard_normal((n1, n1)) / math.sqrt(n1)
    abar[kz:, :kz] = 0.0
    if kz:
        abar[:kz, :kz] = np.diag(np.asarray(zeros, dtype=float)) + np.triu(scale * 0.3 * rng.standard_normal((kz, kz)), 1)
    a12 = scale * rng.standard_normal((n1, q)) / math.sqrt(n)
    a11 = abar + a12 @ mm
    a0 = np.block([[a11, a12], [scale * rng.standard_normal((q, n1)) / math.sqrt(n), scale * rng.standard_normal((q, q))]])
    c = np.hstack([c1, c2])
    e = np.vstack([np.zeros((n1, q)), np.eye(q)])
    a = a0 - injection(a0, c, spectrum) @ c
    qm = _orthogonal(rng, n)
    a, c, e = qm @ a @ qm.T, c @ qm.T, qm @ e
    c = c / np.linalg.norm(c, axis=1, keepdims=True)
    e = e / np.linalg.norm(e, axis=0, keepdims=True)
    b = rng.standard_normal((n, 1))
    fx = rng.standard_normal((n, faults))
    fx /= np.linalg.norm(fx, axis=0, keepdims=True)
    return {"A": a, "B": b / np.linalg.norm(b), "C": c, "E": e, "Fx": fx}


def beard_plant(rng: np.random.Generator, *, n: int, k: int, p: int, radius: float, planes: int = 0, unstable: bool = False) -> dict[str, Any]:
    """A discrete ``(A, B, C, Fx)`` with ``k`` fault directions and a known Beard gain ``L*``: ``G = A − L* C`` stable
    (spectral radius ≤ 0.95·radius), each direction's detection space ``G``-invariant (the first ``k − planes`` seen
    by the outputs, ``C f ≠ 0``: an eigenvector; the last ``planes`` with ``C f = 0``: the plane ``{f, G f}``), the
    residual directions independent. ``A``'s eigenvalues are placed by output injection (one at 1.02–1.05 when
    ``unstable``)."""
    dims = [1] * (k - planes) + [2] * planes
    assert sum(dims) <= n and p >= k
    v = _orthogonal(rng, n)
    gb = np.zeros((n, n))
    col = 0
    spaces_b = []
    for d in dims:
        if d == 1:
            gb[col, col] = radius * rng.uniform(0.3, 0.95)
        else:
            l1, l2 = radius * rng.uniform(0.3, 0.95, 2)
            gb[col : col + 2, col : col + 2] = [[0.0, -l1 * l2], [1.0, l1 + l2]]  # companion: f ↦ G f ↦ …
        spaces_b.append((col, d))
        col += d
    rest = n - col
    if rest:
        ev = radius * rng.uniform(0.2, 0.95, rest)
        t = np.eye(rest) + 0.3 * np.triu(rng.standard_normal((rest, rest)), 1)  # a similarity of diag(ev): its eigenvalues kept
        gb[col:, col:] = t @ np.diag(ev) @ np.linalg.inv(t)
        gb[:col, col:] = 0.3 * radius * rng.standard_normal((col, rest))
    g = v @ gb @ v.T
    spaces = [v[:, c0 : c0 + d] for c0, d in spaces_b]
    fx = np.column_stack([v[:, c0] for c0, _ in spaces_b])
    # C: sees the eigenvector directions, not the plane's f (C f = 0), and C G f ≠ 0
    c = rng.standard_normal((p, n))
    for c0, d in spaces_b:
        if d == 2:
            f = v[:, c0]
            c = c - np.outer(c @ f, f)
    c /= np.linalg.norm(c, axis=1, keepdims=True)
    open_loop = radius * rng.uniform(0.3, 0.98, n)
    if unstable:
        open_loop[0] = rng.uniform(1.02, 1.05)
    kk = injection(g, c, open_loop)  # eig(G − K C) = open_loop
    a = g - kk @ c
    gain = -kk  # A − L* C = G
    b = rng.standard_normal((n, 1))
    return {"A": a, "B": b / np.linalg.norm(b), "C": c, "E": np.zeros((n, 0)), "Fx": fx, "L": gain, "spaces": spaces}
