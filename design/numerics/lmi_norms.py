"""LMI characterisations of discrete-time norms (the LMI design of the diagnostic observer is
:mod:`fdisyn.synthesis.lmi_observer`).

All problems are solved by Clarabel (interior point); they are posed in cvxpy,
except the H₋ index's KYP LMIs, assembled by hand (see below).

Norms (each verified against :mod:`fdisyn.numerics.norms` in the tests; Clarabel
tolerances: see ``_NORM_LADDER``):

``hinf_norm_lmi``
    Bounded real lemma: ``‖G‖∞ < γ`` iff some ``P ≻ 0`` gives
    ``[[AᵀPA − P + CᵀC, AᵀPB + CᵀD], [·, BᵀPB + DᵀD − γ²I]] ≺ 0``; minimise ``γ²``.
``h2_norm_lmi``
    ``‖G‖₂² = min trace(C X Cᵀ + D Dᵀ)`` over ``X − A X Aᵀ − B Bᵀ ⪰ 0`` (the
    minimiser is the controllability Gramian).
``hminus_index_lmi``
    KYP lemma for ``G~G ⪰ β² I`` on the circle: maximise ``β²`` subject to
    ``[[AᵀPA − P − CᵀC, AᵀPB − CᵀD], [·, BᵀPB − DᵀD + β²I]] ⪯ 0`` with ``P``
    symmetric (indefinite). For a band ``[ω₁, ω₂]`` the generalised KYP lemma
    (Iwasaki & Hara, IEEE TAC 50(1), 2005) adds ``Ψ ⊗ Q``, ``Q ⪰ 0``, with
    ``[z; 1]ᴴΨ[z; 1] ≥ 0`` on the band. A real system's band is ``±[ω₁, ω₂]``,
    i.e. ``cos ω₂ ≤ Re z ≤ cos ω₁``: one real multiplier for ``[0, ω₂]`` or
    ``[ω₁, π]`` (exact), two for an interior band (an S-procedure: sufficient,
    tight on 198 of 200 random systems), and the single-arc complex multiplier
    ``Ψ = [[0, e^{jθc}], [e^{−jθc}, −2cos θw]]``, ``θc = (ω₁+ω₂)/2``,
    ``θw = (ω₂−ω₁)/2`` (exact) as the interior band's fallback.
    Range and characterisation: ``inf_{ω∈[ω₁,ω₂]} σ_m(G(e^{jω}))`` for ``m``
    inputs, the same quantity :func:`fdisyn.numerics.norms.hminus_index` sweeps.
    The value is *certified*, not read off the solver: the multipliers of
    Clarabel's last iterate, whatever its status, are checked in NumPy to
    prove a lower bound, the sweep's ``σ_m`` at a frequency of the band is an
    attained upper bound, and they must agree to ``β² ± 1e-10·‖G‖∞²``
    (``HMINUS_TOL``; ``SdpResult.route``, ``.bracket``, ``.certificate``).
    These SDPs are assembled for Clarabel by hand (the complex one as its real
    ``2(n+m)`` embedding), so that the iterate is available on any status.
    Why: the complex multiplier alone, through cvxpy, ended in Clarabel's
    InsufficientProgress (``solver_error``) on 36–53 of 100 random interior
    bands, which ones depending on the OpenBLAS kernel; the real two-multiplier
    SDP reaches "solved" on ~90 % and every kernel certifies all 100.
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Iterator, Sequence

import clarabel
import cvxpy as cp
import numpy as np
from fdisyn.numerics.certificate import Certificate, Check
from fdisyn.numerics.linalg import dlyap
from fdisyn.numerics.norms import DiscreteLTI, check_band, hinf_norm, hminus_index
from fdisyn.numerics.sdp import (
    _CLARABEL_TIGHT,
    _NORM_LADDER,
    SdpResult,
    SdpStats,
    _balance,
    _psd_part,
    _require_stable,
    _scale,
    _solve,
    _sym,
    _val,
)
from fdisyn.runtime.errors import CertificateError, SolverError
from scipy import sparse

__all__ = ['HMINUS_TOL', 'h2_norm_lmi', 'hinf_norm_lmi', 'hminus_index_lmi']


def _kyp_lhs(a: np.ndarray, b: np.ndarray, band: tuple[float, float] | None):
    """``Nᴴ (Φ ⊗ P + Ψ ⊗ Q) N`` with ``N = [[A, B], [I, 0]]`` and the band's multiplier.

    Returns ``(expr, P, Q, constraints)``. Full circle: ``Q`` absent (plain
    KYP). Otherwise the generalised KYP multiplier of the module docstring.
    """
    n, m = b.shape
    lo, hi = check_band(band)
    nmat = np.block([[a, b], [np.eye(n), np.zeros((n, m))]])
    if lo == 0.0 and hi == math.pi:
        p = cp.Variable((n, n), symmetric=True)
        mid = cp.bmat([[p, np.zeros((n, n))], [np.zeros((n, n)), -p]])
        return nmat.T @ mid @ nmat, p, None, []
    # Mirror ω → −ω (real system): [0, ω₂] ↦ |θ| ≤ ω₂; [ω₁, π] ↦ |θ − π| ≤ π − ω₁.
    if lo == 0.0:
        theta_c, theta_w = 0.0, hi
    elif hi == math.pi:
        theta_c, theta_w = math.pi, math.pi - lo
    else:
        theta_c, theta_w = 0.5 * (lo + hi), 0.5 * (hi - lo)
    real = theta_c in (0.0, math.pi)
    if real:
        p = cp.Variable((n, n), symmetric=True)
        q = cp.Variable((n, n), symmetric=True)
        sign = math.cos(theta_c)  # e^{jθc} = ±1
        mid = cp.bmat([[p, sign * q], [sign * q, -p - 2.0 * math.cos(theta_w) * q]])
    else:
        p = cp.Variable((n, n), hermitian=True)
        q = cp.Variable((n, n), hermitian=True)
        e = complex(math.cos(theta_c), math.sin(theta_c))
        mid = cp.bmat([[p, e * q], [np.conj(e) * q, -p - 2.0 * math.cos(theta_w) * q]])
    return nmat.T @ mid @ nmat, p, q, [q >> 0]


def hinf_norm_lmi(sys: DiscreteLTI) -> SdpResult:
    """``‖G‖∞`` by the bounded real lemma (whole circle).

    A band-limited version by the generalised KYP lemma is not offered: with
    Clarabel it ends ``optimal_inaccurate`` (errors ~3e-6) on interior bands,
    outside the 1e-6 relative agreement with the sweep that the norm LMIs are held to; :func:`fdisyn.numerics.norms.hinf_norm`
    takes a band (by the sweep).
    """
    _require_stable(sys, "H∞ norm LMI")
    if sys.n_in == 0 or sys.n_out == 0:
        return SdpResult(0.0, None)
    s = _scale(sys)
    g = _balance(sys)
    c, d = g.C / s, g.D / s
    t = cp.Variable(nonneg=True)
    lhs, p, _, cons = _kyp_lhs(g.A, g.B, None)
    m = g.n_in
    theta = np.block([[c.T @ c, c.T @ d], [d.T @ c, d.T @ d]])
    tail = cp.bmat([[np.zeros((g.n, g.n)), np.zeros((g.n, m))], [np.zeros((m, g.n)), -t * np.eye(m)]])
    cons = cons + [_sym(lhs + theta + tail) << 0, p >> 0]
    prob = cp.Problem(cp.Minimize(t), cons)
    stats = _solve(
        prob,
        what="H∞ norm (bounded real lemma)",
        settings=_NORM_LADDER,
        meaning={"infeasible": "no γ bounds the gain: A has an eigenvalue on or outside the unit circle"},
    )
    return SdpResult(s * math.sqrt(max(float(_val(t)), 0.0)), stats)


def h2_norm_lmi(sys: DiscreteLTI) -> SdpResult:
    """``‖G‖₂ = √min trace(C X Cᵀ + D Dᵀ)`` s.t. ``X − A X Aᵀ − B Bᵀ ⪰ 0``."""
    _require_stable(sys, "H2 norm LMI")
    if sys.n == 0:
        return SdpResult(float(np.linalg.norm(sys.D)), None)
    s = _scale(sys)
    g = _balance(sys)
    c, d = g.C / s, g.D / s
    x = cp.Variable((g.n, g.n), symmetric=True)
    cons = [_sym(x - g.A @ x @ g.A.T - g.B @ g.B.T) >> 0]
    prob = cp.Problem(cp.Minimize(cp.trace(c @ x @ c.T) + float(np.trace(d @ d.T))), cons)
    stats = _solve(
        prob,
        what="H2 norm (Gramian LMI)",
        settings=_NORM_LADDER,
        meaning={"infeasible": "no X dominates the Gramian: A is not Schur stable"},
    )
    return SdpResult(s * math.sqrt(max(float(_val(prob)), 0.0)), stats)


# ---------------------------------------------------------------------------
# H₋ index: KYP LMIs assembled for Clarabel by hand, multipliers verified in NumPy
# ---------------------------------------------------------------------------

HMINUS_TOL = 1e-10
"""Agreement demanded of the H₋ bracket: ``β_hi² − β_lo² ≤ HMINUS_TOL·‖G‖∞²``.

The LMI determines ``β²`` for the whole system (its multipliers see every
frequency, not only the band's) scaled to ``‖G‖ ~ 1``, so its natural
accuracy is absolute in ``β²`` relative to the whole circle's ``‖G‖∞²``. In
``β`` that is ≤ 5e-11 relative when ``β ≈ ‖G‖∞`` and ``5e-11·‖G‖∞²/β``
absolute in general (at worst ``1e-5·‖G‖∞``, when ``β ≈ 1e-5·‖G‖∞``).
Measured over 100 random systems each (n ≤ 10, spectral radius ≤ 0.99) on the
OpenBLAS kernels SkylakeX, Haswell, Zen and SandyBridge, none refused: median
``(β_hi² − β_lo²)/‖G‖∞²`` 4e-14 (whole circle), 5e-13 (half bands), 2e-12
(interior bands, 7–8 of 100 through the level repair of :func:`_prove`); on
100 harder ones (n ≤ 16, radius ≤ 0.995) 5e-12, 2–3 needing the complex
multiplier."""

_PHI = np.array([[1.0, 0.0], [0.0, -1.0]])
"""``[z; 1]ᴴ Φ [z; 1] = |z|² − 1``: zero on the unit circle (the multiplier ``P``)."""

# An eigenvalue computed by LAPACK is exact for a matrix within ~n·eps·‖M‖ of
# the given one; the LMI check allows that much above zero.
_ROUNDOFF = 16 * np.finfo(float).eps


def _psi_re_above(c: float) -> np.ndarray:
    """``ψ(z) = 2 Re z − 2c``: non-negative on the arcs ``|ω| ≤ arccos c``."""
    return np.array([[0.0, 1.0], [1.0, -2.0 * c]])


def _psi_re_below(c: float) -> np.ndarray:
    """``ψ(z) = 2c − 2 Re z``: non-negative on the arcs ``|ω| ≥ arccos c``."""
    return np.array([[0.0, -1.0], [-1.0, 2.0 * c]])


def _psi_arc(lo: float, hi: float) -> np.ndarray:
    """``ψ(z) = 2cos(ω − θc) − 2cos θw``: non-negative on the single arc ``[ω₁, ω₂]`` (complex)."""
    tc, tw = 0.5 * (lo + hi), 0.5 * (hi - lo)
    e = complex(math.cos(tc), math.sin(tc))
    return np.array([[0.0, e], [e.conjugate(), -2.0 * math.cos(tw)]])


def _hminus_routes(lo: float, hi: float) -> list[tuple[str, list[np.ndarray]]]:
    """The multiplier sets for the band, in the order they are tried.

    A real system has ``σ(G(e^{−jω})) = σ(G(e^{jω}))``, so the band may be read
    as ``±[ω₁, ω₂]``, i.e. ``cos ω₂ ≤ Re z ≤ cos ω₁``: one real half-plane for
    ``[0, ω₂]`` or ``[ω₁, π]`` (Iwasaki & Hara's multiplier with ``θc ∈ {0, π}``,
    exact), the intersection of two for an interior band ("strip": an
    S-procedure with two real multipliers, sufficient but not always tight —
    measured 2 of 200 random systems short of the sweep by more than
    ``HMINUS_TOL``). The single-arc complex multiplier of Iwasaki & Hara,
    necessary and sufficient, is the interior band's second route: its real
    ``2(n+m)`` embedding is the SDP on which Clarabel stalls most (status
    "solved" on at most 7 of 60 random interior bands, the rest
    InsufficientProgress or AlmostSolved at an accuracy that depends on the
    BLAS kernel), while the strip reaches "solved" on ~90 %.
    """
    if lo == 0.0 and hi == math.pi:
        return [("kyp", [])]
    if lo == 0.0:
        return [("gkyp", [_psi_re_above(math.cos(hi))])]
    if hi == math.pi:
        return [("gkyp", [_psi_re_below(math.cos(lo))])]
    return [
        ("gkyp-strip", [_psi_re_above(math.cos(hi)), _psi_re_below(math.cos(lo))]),
        ("gkyp-complex", [_psi_arc(lo, hi)]),
    ]


def _hermitian_basis(n: int, *, complex_: bool) -> np.ndarray:
    """A basis of real symmetric (or Hermitian) ``n × n`` matrices, shape ``(k, n, n)``."""
    mats = []
    for a in range(n):
        h = np.zeros((n, n), dtype=complex)
        h[a, a] = 1.0
        mats.append(h)
    for a in range(n):
        for b in range(a + 1, n):
            h = np.zeros((n, n), dtype=complex)
            h[a, b] = h[b, a] = 1.0
            mats.append(h)
            if complex_:
                h = np.zeros((n, n), dtype=complex)
                h[a, b], h[b, a] = 1j, -1j
                mats.append(h)
    out = np.array(mats).reshape(len(mats), n, n)
    return out if complex_ else out.real.copy()


def _embed(f: np.ndarray) -> np.ndarray:
    """``[[Re F, −Im F], [Im F, Re F]]`` (stacked): PSD iff the Hermitian ``F`` is; identity on real input."""
    if not np.iscomplexobj(f):
        return f
    re, im = f.real, f.imag
    return np.concatenate([np.concatenate([re, -im], -1), np.concatenate([im, re], -1)], -2)


def _svec(f: np.ndarray) -> np.ndarray:
    """Clarabel's PSD-triangle vectorisation of (stacked) symmetric matrices: upper triangle by columns, ·√2 off the diagonal."""
    k = f.shape[-1]
    cols, rows = np.tril_indices(k)  # (j ≥ i) row-major of the lower triangle = (i ≤ j) column-major of the upper
    w = np.where(rows == cols, 1.0, math.sqrt(2.0))
    return f[..., rows, cols] * w


def _schur_top(m: np.ndarray, n: int) -> float | None:
    """``sup{t : M + t·diag(0, I) ⪯ 0}``; ``None`` unless the leading ``n × n`` block is negative definite.

    With ``−M₁₁ = L Lᴴ`` and ``X = L⁻¹ M₁₂``: ``M + t·diag(0, I) ⪯ 0`` iff
    ``M₂₂ + XᴴX + tI ⪯ 0`` (Schur complement).
    """
    if n:
        try:
            low = np.linalg.cholesky(-m[:n, :n])
        except np.linalg.LinAlgError:
            return None
        x = np.linalg.solve(low, m[:n, n:])
        sc = m[n:, n:] + x.conj().T @ x
    else:
        sc = m
    return -float(np.max(np.linalg.eigvalsh(0.5 * (sc + sc.conj().T))))


_CLARABEL_STATUS = {"Solved": cp.OPTIMAL, "AlmostSolved": cp.OPTIMAL_INACCURATE}


class _KypLmi:
    """The H₋ index's (generalised) KYP LMI as Clarabel conic data, and its a-posteriori check.

    ``F(P, Q₁, …, t) = Nᴴ(Φ ⊗ P + Σₖ Ψₖ ⊗ Qₖ)N − [C D]ᴴ[C D] + t·diag(0, I) ⪯ 0``,
    ``Qₖ ⪰ 0``, ``N = [[A, B], [I, 0]]``. For ``z = e^{jω}``, ``x = (zI − A)⁻¹Bu``
    and ``v = [x; u]``, ``vᴴFv = Σₖ ψₖ(z)·xᴴQₖx − |G(z)u|² + t|u|²`` with
    ``ψₖ(z) = [z; 1]ᴴΨₖ[z; 1]``; so ``F ⪯ 0`` proves ``|G(z)u|² ≥ t|u|²`` at every
    ``z`` where all ``ψₖ(z) ≥ 0`` — for *any* numerical ``P`` and PSD ``Qₖ``.
    That sufficiency is all :meth:`certify` relies on; the solver only proposes
    multipliers, and its status is recorded, not trusted.

    Assembled without cvxpy: real multipliers give a real LMI of size ``n + m``;
    a complex ``Ψ`` makes ``P``, ``Qₖ`` Hermitian and every cone the real
    embedding ``[[Re F, −Im F], [Im F, Re F]] ⪰ 0`` (written here, so that the
    iterate is available whatever Clarabel's status).
    """

    def __init__(self, a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray, psis: Sequence[np.ndarray]) -> None:
        n, m = b.shape
        self.n, self.m = n, m
        self.psis = list(psis)
        self.complex = any(np.iscomplexobj(p) and bool(np.any(np.imag(p) != 0)) for p in self.psis)
        self._nn = (np.hstack([a, b]), np.hstack([np.eye(n), np.zeros((n, m))]))
        cd = np.hstack([c, d])
        self.theta = -cd.T @ cd
        self.e_in = np.zeros((n + m, n + m))
        self.e_in[n:, n:] = np.eye(m)
        self.basis = _hermitian_basis(n, complex_=self.complex)
        self.nb = len(self.basis)
        self.lifted = np.concatenate([self._lift(_PHI, self.basis)] + [self._lift(p, self.basis) for p in self.psis])
        # P₀ = Σ (Aᵀ)ᵏAᵏ solves AᵀP₀A − P₀ = −I: Nᵀ(Φ ⊗ P₀)N has state block −I (see certify).
        self._shift = self._lift(_PHI, dlyap(a.T, np.eye(n), refine=False)[None])[0].real

    def _lift(self, mult: np.ndarray, h: np.ndarray) -> np.ndarray:
        """``Nᴴ(M ⊗ H)N = Σᵢⱼ Mᵢⱼ NᵢᵀHNⱼ`` for a stack of ``H`` (``N₁ = [A B]``, ``N₂ = [I 0]``)."""
        k = self.n + self.m
        out = np.zeros((len(h), k, k), dtype=complex)
        for i in range(2):
            for j in range(2):
                if mult[i, j] != 0:
                    out += mult[i, j] * np.einsum("ai,kab,bj->kij", self._nn[i], h, self._nn[j])
        return out if self.complex else out.real.copy()

    def solve(self, *, what: str, level: float | None = None) -> tuple[np.ndarray, SdpStats]:
        """Maximise ``t`` (``level=None``), or the margin ``s`` in ``F(P, Q, level) + sI ⪯ 0``.

        Returns the last iterate ``[multiplier coordinates…, t or s]`` whatever
        the status (a failed solve yields NaNs or multipliers that fail
        :meth:`certify`), and the solve's statistics.
        """
        k = self.n + self.m
        nv = self.nb * (1 + len(self.psis)) + 1
        last = self.e_in if level is None else np.eye(k)
        const = self.theta if level is None else self.theta + level * self.e_in
        # Clarabel: A x + s = b, s in the cones; here s = svec(−F).
        a_lmi = np.concatenate([_svec(_embed(self.lifted)), _svec(_embed(last.astype(self.lifted.dtype)))[None]]).T
        blocks_a, blocks_b = [a_lmi], [-_svec(_embed(const.astype(self.lifted.dtype)))]
        kk = 2 * k if self.complex else k
        cones = [clarabel.PSDTriangleConeT(kk)]
        q_vec = _svec(_embed(self.basis))  # (nb, ·)
        for r in range(len(self.psis)):
            a_q = np.zeros((q_vec.shape[1], nv))
            a_q[:, self.nb * (r + 1) : self.nb * (r + 2)] = -q_vec.T
            blocks_a.append(a_q)
            blocks_b.append(np.zeros(q_vec.shape[1]))
            cones.append(clarabel.PSDTriangleConeT(2 * self.n if self.complex else self.n))
        cost = np.zeros(nv)
        cost[-1] = -1.0
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        for key, val in _CLARABEL_TIGHT.items():
            setattr(settings, key, val)
        t0 = time.perf_counter()
        sol = clarabel.DefaultSolver(
            sparse.csc_matrix((nv, nv)), cost, sparse.csc_matrix(np.vstack(blocks_a)), np.concatenate(blocks_b), cones, settings
        ).solve()
        status = str(sol.status)
        stats = SdpStats(
            what=what,
            status=_CLARABEL_STATUS.get(status, re.sub(r"(?<!^)(?=[A-Z])", "_", status).lower()),
            solve_time=float(sol.solve_time),
            wall_time=time.perf_counter() - t0,
            iterations=int(sol.iterations),
            n_scalar_variables=nv,
        )
        return np.asarray(sol.x, dtype=float), stats

    def certify(self, x: np.ndarray) -> tuple[float, float] | None:
        """The largest ``t`` the multipliers in ``x`` prove, and the LMI's top eigenvalue there over its norm.

        Each ``Qₖ`` is projected onto the PSD cone (an interior-point iterate may
        carry −1e-10 eigenvalues) and ``F`` rebuilt from the projection. ``t`` is
        the Schur-complement bound (:func:`_schur_top`); where the state block
        is tight (singular) or, through the solver's residual, slightly
        indefinite, ``P`` is shifted by ``ε‖F‖P₀`` (``AᵀP₀A − P₀ = −I``), which
        makes that block ``⪯ −ε‖F‖I`` for ``O(ε)`` of ``t``; the best ``ε`` of a
        ladder is kept. ``t`` is then lowered by a few ulps of ``‖F‖`` and the
        whole LMI's largest eigenvalue checked ``≤ _ROUNDOFF·‖F‖`` — the check
        that makes ``t`` a proven bound. ``None`` when no ``ε`` works.
        """
        if not np.all(np.isfinite(x)):
            return None
        nb = self.nb
        m0 = np.tensordot(x[:nb], self.lifted[:nb], 1) + self.theta
        for r, psi in enumerate(self.psis):
            q = np.tensordot(x[nb * (r + 1) : nb * (r + 2)], self.basis, 1)
            m0 = m0 + self._lift(psi, _psd_part(q)[None])[0]
        m0 = 0.5 * (m0 + m0.conj().T)
        size = max(float(np.linalg.norm(m0, 2)), 1.0)
        best: tuple[float, np.ndarray] | None = None
        for eps in (0.0, 1e-14, 1e-13, 1e-12, 1e-11, 1e-10, 1e-9, 1e-8, 1e-7, 1e-6):
            me = m0 + eps * size * self._shift
            t = _schur_top(me, self.n)
            if t is not None and (best is None or t > best[0]):
                best = (t, me)
        if best is None:
            return None
        t, me = best
        t -= 4 * np.finfo(float).eps * (size + abs(t))
        norm = float(np.linalg.norm(me, 2)) + abs(t)
        top = float(np.max(np.linalg.eigvalsh(me + t * self.e_in))) / norm
        if top > _ROUNDOFF * (self.n + self.m):
            return None
        return t, top


def _prove(
    lm: _KypLmi, name: str, what: str, t_hi: float, tol: float
) -> Iterator[tuple[str, SdpStats, tuple[float, float] | None]]:
    """Proven lower bounds on ``β²`` from one multiplier set, as ``(route, stats, certify result)``.

    First the multipliers that maximise ``β²``; if they do not come within
    ``tol`` of ``t_hi``, those of a feasibility SDP at the level ``t_hi − tol``
    that maximises the LMI's margin, blended with the former: ``F`` is affine
    in the multipliers, so a small share of a strictly feasible point repairs
    the maximiser's residual (its ``β²`` is accurate, but the iterate lies a
    solver tolerance outside the cone) at little cost in ``β²``. Measured on
    the failures of the maximiser alone: within 0.6·tol, where the level
    SDP's own multipliers give 1·tol at best.
    """
    x_max, st = lm.solve(what=f"{what}, {name}")
    cert = lm.certify(x_max)
    yield name, st, cert
    if cert is not None and t_hi - cert[0] <= tol:
        return
    x_lev, st = lm.solve(what=f"{what}, {name} at β² = {t_hi - tol:.6g}", level=t_hi - tol)
    shares = (0.0, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2, 3e-2, 0.1, 0.3, 1.0)
    certs = [c for c in (lm.certify((1.0 - w) * x_max + w * x_lev) for w in shares) if c is not None]
    yield f"{name}-level", st, max(certs, default=None, key=lambda c: c[0])


def hminus_index_lmi(sys: DiscreteLTI, *, band: tuple[float, float] | None = None) -> SdpResult:
    """``inf_{ω∈band} σ_m(G(e^{jω}))`` for ``m`` inputs, certified; ``0`` when ``p < m``.

    The value is a *proven* lower bound ``β_lo``: KYP multipliers (module
    docstring), proposed by Clarabel and checked in NumPy by
    :meth:`_KypLmi.certify` whatever the solver's status. It is returned only
    once it meets an *attained* upper bound ``β_hi``, ``σ_m`` at a frequency of
    the band found by the sweep :func:`fdisyn.numerics.norms.hminus_index`, to
    ``β_hi² − β_lo² ≤ HMINUS_TOL·‖G‖∞²``. ``SdpResult.bracket`` is
    ``(β_lo, β_hi)``, ``.certificate`` holds both checks and the attempts,
    ``.route`` names what closed the gap, tried in this order:

    ``kyp`` (whole circle), ``gkyp`` (``[0, ω₂]``, ``[ω₁, π]``), ``gkyp-strip`` (interior)
        maximise ``β²`` with the band's real multipliers (:func:`_hminus_routes`);
    ``gkyp-complex`` (interior)
        the same with the single-arc complex multiplier, when the strip's
        relaxation is not tight for this system;
    ``…-level``
        the route's multipliers repaired by a feasibility SDP at a level just
        below ``β_hi²`` (:func:`_prove`).

    Raises :class:`SolverError` when no route closes the gap (the message gives
    both bounds and every status), :class:`CertificateError` when multipliers
    prove more than a frequency attains (impossible in exact arithmetic: the
    sweep or the check is wrong).
    """
    _require_stable(sys, "H₋ index LMI")
    lo, hi = check_band(band)
    if sys.n_in == 0 or sys.n_out < sys.n_in:
        return SdpResult(0.0, None, route="none")
    what = "H₋ index (KYP lemma)" if (lo, hi) == (0.0, math.pi) else f"H₋ index on [{lo:.4g}, {hi:.4g}] (generalised KYP)"
    upper = hminus_index(sys, band=band)
    gain = hinf_norm(sys).value
    if gain == 0.0:  # G ≡ 0 (C = 0, D = 0): nothing to prove
        return SdpResult(0.0, None, route="none", bracket=(0.0, 0.0))
    s = _scale(sys)
    # A similarity with cond(T) ≤ 1e4 moves the data by ≤ ~1e4·eps relative,
    # far below HMINUS_TOL, so multipliers proven for it hold for sys.
    g = _balance(sys, max_cond=1e4)
    c, d = g.C / s, g.D / s
    t_hi = (upper.value / s) ** 2
    tol = HMINUS_TOL * (gain / s) ** 2

    def lower(t: float) -> float:
        return s * math.sqrt(max(t, 0.0))

    attempts: list[tuple[str, SdpStats, tuple[float, float] | None]] = []
    for name, psis in _hminus_routes(lo, hi):
        for route, st, cert in _prove(_KypLmi(g.A, g.B, c, d, psis), name, what, t_hi, tol):
            attempts.append((route, st, cert))
            if cert is None:
                continue
            t_lo, top = cert
            if t_lo > t_hi + tol:
                raise CertificateError(
                    f"{what}: KYP multipliers prove ‖G‖₋ ≥ {lower(t_lo):.10g} but σ_m(G(e^(jω))) = "
                    f"{upper.value:.10g} at ω = {upper.omega:.10g} in the band; the sweep or the LMI check is wrong"
                )
            if t_hi - t_lo > tol:
                continue
            b_lo = min(lower(t_lo), upper.value)
            certificate = Certificate.of(
                f"hminus_index_lmi/{route}",
                [
                    Check(
                        "largest eigenvalue of the KYP LMI at β_lo², over its norm",
                        top,
                        _ROUNDOFF * (g.n + g.n_in),
                        "<=",
                        "the multipliers prove σ_m(G(e^(jω))) ≥ β_lo on the band, to the round-off of an eigenvalue",
                    ),
                    Check(
                        "(β_hi² − β_lo²) / ‖G‖∞²",
                        (t_hi - t_lo) * (s / gain) ** 2,
                        HMINUS_TOL,
                        "<=",
                        "the proven lower bound meets σ_m at a frequency of the band (the sweep)",
                    ),
                ],
                {
                    "route": route,
                    "band": (lo, hi),
                    "lower": b_lo,
                    "upper": upper.value,
                    "omega": upper.omega,
                    "attempts": [(a, st_.status) for a, st_, _ in attempts],
                },
            ).require()
            # Times and iterations summed over every SDP this value needed.
            total = SdpStats(
                what=what,
                status=st.status,
                solve_time=float(sum(a[1].solve_time for a in attempts)),
                wall_time=float(sum(a[1].wall_time for a in attempts)),
                iterations=int(sum(a[1].iterations or 0 for a in attempts)),
                n_scalar_variables=st.n_scalar_variables,
            )
            return SdpResult(b_lo, total, route=route, bracket=(b_lo, upper.value), certificate=certificate)
    proven = [cert[0] for _, _, cert in attempts if cert is not None]
    best = f"{lower(max(proven)):.6g}" if proven else "none"
    statuses = ", ".join(f"{route}: {st.status}" for route, st, _ in attempts)
    raise SolverError(
        f"{what}: no KYP multipliers prove a value within {HMINUS_TOL:g}·‖G‖∞² of the {upper.value:.6g} "
        f"attained at ω = {upper.omega:.6g} (best proven lower bound: {best}; Clarabel {statuses}); "
        "try a minimal realisation of lower order, or the sweep norms.hminus_index"
    )
