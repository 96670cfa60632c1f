"""What a designed bank of linear residual generators achieves on its plant: its weak and strong structure matrices
and each generator's fault-to-noise gap (Varga, *Solving Fault Diagnosis Problems: Linear Synthesis Techniques*,
Springer 2017, secs. 3.5 and 5.3; the functions ``fditspec``, ``fdisspec`` and ``fdif2ngap`` of his
FaultDetectionTools.jl).

For a generator ``r = Q(z) [y; u]`` on the plant, ``R_fj`` is the transfer from fault ``j`` to ``r`` and ``R_w`` the
transfer from the plant's noise, whitened: the process noise ``w = Q^½ ω₁`` and the sensor noise ``v = R^½ ω₂`` with
``ω`` of unit covariance, so ``R_w`` is in the units of the noise the plant declares. Varga's fault-to-noise gap of a
generator that should see the faults ``J`` is

    gap = ‖R_f,J‖∞₋ / ‖R_w‖∞,   ‖R_f,J‖∞₋ = min_{j ∈ J} ‖R_fj‖∞,

his *H∞₋ index*: the smallest H∞ norm over the fault columns, a worst case over faults of a best case over
frequencies. It is not fdisyn's H₋ index (:func:`fdisyn.numerics.norms.hminus_index`, the paper's
``inf_ω σ_min(G(e^{jω}))``, a worst case over frequencies and directions), which both are stated beside each other:
a residual that sees a fault only at one frequency has a large gap and a zero H₋ index. A gap is infinite when the
noise does not reach the residual (``R_w = 0``) and zero when a fault of ``J`` does not.

Every norm here is of a minimal realisation (SLICOT ``TB01PD``): on an unstable plant a generator's internal form is
unstable, while its responses are stable when its filter cancels the unstable modes (as the nullspace synthesis
ensures); a response whose minimal realisation is still unstable has an infinite norm. A continuous realisation is
mapped to discrete time by the bilinear transformation, which maps the imaginary axis onto the unit circle and so
keeps every H∞ norm (:func:`hinf_of`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from fdisyn.models.linear import LinearPlant
from fdisyn.numerics.linalg import psd_factor, spectral_radius, transfer_size
from fdisyn.numerics.norms import DiscreteLTI, hinf_norm, hminus_index
from fdisyn.numerics.pencils import minimal_realisation
from fdisyn.runtime.errors import ArgumentError
from fdisyn.runtime.gainfile import Generator
from fdisyn.synthesis.residual import internal_form
from fdisyn.synthesis.structure import STRONG_TOL, fault_entries

__all__ = [
    "GeneratorPerformance", "hinf_of", "noise_entries", "boundary_points", "relative_responses", "transfer_at", "generator_performance",
    "bank_performance", "WEAK_TOL",
]

WEAK_TOL = 1e-8
"""A fault reaches a generator when its relative response (:func:`relative_responses`) exceeds this at one of the
test points: an exactly decoupled transfer computed in floating point is below 1e-12 there, a seen one of order
one (the nullspace certificate's ``DECOUPLING_TOL``)."""


def boundary_points(count: int, continuous: bool) -> np.ndarray:
    """``count`` points of the stability boundary off the real axis (an integrator's pole is never hit): on the unit
    circle, or on the imaginary axis (the circle's points under the bilinear map)."""
    theta = np.pi * (np.arange(count) + 0.5) / count
    return 1j * np.tan(theta / 2) if continuous else np.exp(1j * theta)


def transfer_at(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray, z: complex) -> np.ndarray:
    """``C (zI − A)⁻¹ B + D`` at one point."""
    if a.shape[0] == 0:
        return d.astype(complex)
    return c @ np.linalg.solve(z * np.eye(a.shape[0]) - a, b) + d


def _responses(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray, zs: np.ndarray) -> np.ndarray:
    """``C (zI − A)⁻¹ B + D`` at every point of ``zs``: ``(points, rows, columns)``."""
    if a.shape[0] == 0:
        return np.broadcast_to(d.astype(complex), (zs.size, *d.shape)).copy()
    x = np.linalg.solve(zs[:, None, None] * np.eye(a.shape[0])[None] - a[None], np.broadcast_to(b.astype(complex), (zs.size, *b.shape)))
    return c[None] @ x + d[None]


def relative_responses(gen: Generator, plant: LinearPlant, points: Sequence[complex] | np.ndarray) -> dict[str, Any]:
    """The generator's responses at ``points`` from its own matrices and the plant's, each relative to the sizes of
    its factors: ``‖Q(λ) G(λ)‖ / (‖Q(λ)‖ ‖G(λ)‖)``, the largest over the points — zero to round-off exactly where a
    response is identically zero (a rational function of degree at most ``d`` that vanishes at more than ``2d``
    points is zero), of order one where it is not, whatever the units.

    Parameters
    ----------
    gen : Generator
        The residual generator on all the plant's outputs and inputs.
    plant : LinearPlant
        The plant, discrete or continuous (the points are then on the imaginary axis).
    points : array_like of complex
        The points (:func:`boundary_points`).

    Returns
    -------
    dict
        ``u``, ``d`` (the inputs' and unknown inputs' responses ``R_u = Q_y G_u + Q_u``, ``R_d = Q_y G_d``) and
        ``faults`` (one per fault in the plant's fault order).
    """
    a, c = np.asarray(plant.A, float), np.asarray(plant.C, float)
    _, bf, df = fault_entries(plant)
    m, q, nf = plant.m, plant.q, bf.shape[1]
    zs = np.asarray(points, dtype=complex)
    # the plant's responses from [u, d, faults] and the generator's from [y, u] at every point at once
    bp = np.hstack([np.asarray(plant.B, float), np.asarray(plant.E, float), bf])
    dp = np.hstack([np.asarray(plant.D, float), np.asarray(plant.Dd, float), df])
    gp = _responses(a, bp, c, dp, zs)
    gq = _responses(gen.Ar, np.hstack([gen.By, gen.Bu]), gen.Cr, np.hstack([gen.Dy, gen.Du]), zs)
    qy, qn = gq[:, :, : plant.p], np.linalg.norm(gq, axis=(1, 2))
    ru = rd = 0.0
    if m:
        ge = np.concatenate([gp[:, :, :m], np.broadcast_to(np.eye(m), (zs.size, m, m))], axis=1)
        ru = float(np.max(np.linalg.norm(gq @ ge, axis=(1, 2)) / np.maximum(qn * np.linalg.norm(ge, ord=2, axis=(1, 2)), 1e-300)))
    if q:
        gd = gp[:, :, m : m + q]
        rd = float(np.max(np.linalg.norm(qy @ gd, axis=(1, 2)) / np.maximum(qn * np.linalg.norm(gd, ord=2, axis=(1, 2)), 1e-300)))
    gf = gp[:, :, m + q :]
    fault = np.max(np.linalg.norm(qy @ gf, axis=1) / np.maximum(qn[:, None] * np.linalg.norm(gf, axis=1), 1e-300), axis=0) if nf else np.zeros(0)
    return {"u": ru, "d": rd, "faults": fault}


def _stable_discrete(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray, continuous: bool) -> DiscreteLTI | None:
    """A minimal discrete realisation with the same gains over the stability boundary (the bilinear map of a continuous
    one); ``None`` when the minimal realisation is unstable."""
    ar, br, cr = minimal_realisation(a, b, c)
    n = ar.shape[0]
    if continuous and n:
        if np.any(np.linalg.eigvals(ar).real >= -1e-12 * max(1.0, float(np.linalg.norm(ar, 1)))):
            return None
        inv = np.linalg.inv(np.eye(n) - ar)
        ar, br, cr, d = (np.eye(n) + ar) @ inv, math.sqrt(2.0) * inv @ br, math.sqrt(2.0) * cr @ inv, d + cr @ inv @ br
    if n and spectral_radius(ar) >= 1.0 - 1e-12:
        return None
    return DiscreteLTI(A=ar, B=br, C=cr, D=d)


def hinf_of(a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray, *, continuous: bool = False) -> float:
    """``‖C (λI − A)⁻¹ B + D‖∞`` of a minimal realisation; ``inf`` when that realisation is unstable.

    Parameters
    ----------
    a, b, c, d : numpy.ndarray
        The realisation.
    continuous : bool
        ``λ = s`` (the imaginary axis) instead of ``λ = z`` (the unit circle): mapped by the bilinear
        transformation ``s = (z − 1)/(z + 1)``, under which the norm is the same.

    Returns
    -------
    float
        The H∞ norm (SLICOT ``AB13DD`` through :func:`~fdisyn.numerics.norms.hinf_norm`).
    """
    b, c, d = np.atleast_2d(b), np.atleast_2d(c), np.atleast_2d(d)
    if b.shape[1] == 0 or c.shape[0] == 0:
        return 0.0
    sys = _stable_discrete(a, b, c, d, continuous)
    return math.inf if sys is None else float(hinf_norm(sys).value)


def noise_entries(plant: LinearPlant) -> tuple[np.ndarray, np.ndarray]:
    """``(B_w, D_w)``: the plant's whitened noise ``[w; v] = [Q^½ 0; 0 R^½] ω`` as inputs of the state and the outputs
    (full-column-rank factors, :func:`~fdisyn.numerics.linalg.psd_factor`)."""
    lq, lr = psd_factor(np.asarray(plant.Q, float), "Q"), psd_factor(np.asarray(plant.R, float), "R")
    bw = np.hstack([lq, np.zeros((plant.n, lr.shape[1]))])
    dw = np.hstack([np.zeros((plant.p, lq.shape[1])), lr])
    return bw, dw


@dataclass(frozen=True)
class GeneratorPerformance:
    """One generator on its plant: which faults it sees (weakly and at frequencies) and how far above its noise.

    Attributes
    ----------
    name : str
        The generator.
    weak : tuple of int
        ``1`` per fault (the plant's fault order) whose transfer to the residual is not identically zero.
    strong : tuple of int or None
        ``1`` per fault whose gain is nonzero at every one of the frequencies asked (``None``: none asked).
    fault_norms : tuple of float
        ``‖R_fj‖∞`` per fault (0 for a decoupled one).
    noise_norm : float
        ``‖R_w‖∞`` (0: the noise does not reach the residual).
    hinf_minus : float
        Varga's H∞₋ index over the faults it sees: ``min_j ‖R_fj‖∞``.
    gap : float
        ``hinf_minus / noise_norm`` (``inf`` without noise, 0 when it sees no fault).
    hminus : float
        fdisyn's H₋ index of ``R_f`` over the faults it sees, ``inf_ω σ_min`` (0 when they outnumber the residuals).
    gap_at : float or None
        The gap with the H∞₋ index taken at the frequencies asked only, ``min_j min_ω |R_fj(ω)| / ‖R_w‖∞`` (Varga's
        ``fdif2ngap`` with ``freq``); ``None``: none asked.
    """

    name: str
    weak: tuple[int, ...]
    strong: tuple[int, ...] | None
    fault_norms: tuple[float, ...]
    noise_norm: float
    hinf_minus: float
    gap: float
    hminus: float
    gap_at: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """The values as JSON-ready numbers (``inf`` as the string ``"inf"``)."""

        def num(x: float) -> float | str:
            return "inf" if math.isinf(x) else float(x)

        return {
            "name": self.name, "weak": list(self.weak), "strong": None if self.strong is None else list(self.strong),
            "fault_norms": [num(x) for x in self.fault_norms], "noise_norm": num(self.noise_norm),
            "hinf_minus": num(self.hinf_minus), "gap": num(self.gap), "hminus": num(self.hminus),
            "gap_at": None if self.gap_at is None else num(self.gap_at),
        }


def generator_performance(
    gen: Generator, plant: LinearPlant, *, frequencies: Sequence[float] | None = None, hminus: bool = True
) -> GeneratorPerformance:
    """Varga's ``fditspec``, ``fdisspec`` and ``fdif2ngap`` of one generator on its discrete plant (module docstring).

    Parameters
    ----------
    gen : Generator
        The residual generator (reading all the plant's outputs and inputs).
    plant : LinearPlant
        The plant it was designed for: discrete, or continuous for a continuous filter (norms over the imaginary axis).
    frequencies : sequence of float, optional
        Frequencies in rad/s for the strong structure (0: constant faults).
    hminus : bool
        Compute fdisyn's H₋ index too (a frequency sweep; ``nan`` when not asked).

    Returns
    -------
    GeneratorPerformance
        Its structure rows, norms and gap.

    Raises
    ------
    ArgumentError
        A frequency that is negative or beyond the Nyquist frequency.
    """
    cont = not plant.is_discrete
    form = internal_form(gen, plant)
    _, bf, df = fault_entries(plant)
    # each fault's input to the internal form: the plant's entry and, read by the generator, its part in the outputs
    fb = np.vstack([bf, gen.By @ df])
    fd = gen.Dy @ df
    rel = relative_responses(gen, plant, boundary_points(2 * (plant.n + gen.n_state) + 8, cont))["faults"]
    weak, norms = [], []
    for j in range(bf.shape[1]):
        seen = bool(rel[j] > WEAK_TOL)
        weak.append(int(seen))
        norms.append(hinf_of(form.A, fb[:, [j]], form.C, fd[:, [j]], continuous=cont) if seen else 0.0)
    bw, dw = noise_entries(plant)
    wb = np.vstack([bw, gen.By @ dw])
    wd = gen.Dy @ dw
    noise = hinf_of(form.A, wb, form.C, wd, continuous=cont) if wb.shape[1] and transfer_size(form.A, wb, form.C, wd) > WEAK_TOL else 0.0
    strong, at_freqs = None, None
    if frequencies is not None:
        lows = []
        top = math.inf if cont else math.pi / float(plant.Ts)  # type: ignore[arg-type]
        strong_row = []
        for j in range(bf.shape[1]):
            ok = bool(weak[j])
            for w in frequencies:
                if not 0.0 <= float(w) <= top:
                    raise ArgumentError(f"frequency {w} rad/s: expected a number in [0, {top:.6g}] (the Nyquist frequency at Ts = {plant.Ts:g} s)")
                z = 1j * float(w) if cont else np.exp(1j * float(w) * float(plant.Ts))  # type: ignore[arg-type]
                ar, br, cr = minimal_realisation(form.A, fb[:, [j]], form.C)
                g = (cr @ np.linalg.solve(z * np.eye(ar.shape[0]) - ar, br) if ar.size else 0.0) + fd[:, [j]]
                ok = ok and float(np.linalg.norm(g)) > STRONG_TOL * max(norms[j], 1e-300)
                if weak[j]:
                    lows.append(float(np.linalg.norm(g)))
            strong_row.append(int(ok))
        strong = tuple(strong_row)
        low = min(lows) if lows else 0.0
        at_freqs = 0.0 if low == 0.0 else (math.inf if noise == 0.0 else low / noise)
    seen_norms = [norms[j] for j in range(len(norms)) if weak[j]]
    hinf_minus = min(seen_norms) if seen_norms else 0.0
    gap = 0.0 if hinf_minus == 0.0 else (math.inf if noise == 0.0 else hinf_minus / noise)
    cols = [j for j in range(len(weak)) if weak[j]]
    index = 0.0 if hminus else math.nan
    if cols and hminus:
        sys = _stable_discrete(form.A, fb[:, cols], form.C, fd[:, cols], cont)
        if sys is not None:
            index = float(hminus_index(sys).value)
            # a zero of R_f evaluated in floating point (a wide residual, or a transmission zero on the boundary) is
            # round-off against the faults' norms: zero
            index = 0.0 if index <= 1e-12 * max(norms) else index
    return GeneratorPerformance(gen.name, tuple(weak), strong, tuple(norms), noise, hinf_minus, gap, index, at_freqs)


def bank_performance(generators: Sequence[Generator], plant: LinearPlant, *, frequencies: Sequence[float] | None = None) -> list[GeneratorPerformance]:
    """:func:`generator_performance` of every generator of a bank: its rows are the bank's weak (and strong)
    structure matrix, Varga's ``fditspec`` (``fdisspec``), and its gaps his ``fdif2ngap``.

    Parameters
    ----------
    generators : sequence of Generator
        The bank (a gain file's ``generators``).
    plant : LinearPlant
        The plant it was designed for (a continuous one is refused: discretise it at the gain file's ``Ts``).
    frequencies : sequence of float, optional
        Frequencies in rad/s for the strong structure.

    Returns
    -------
    list of GeneratorPerformance
        One per generator, in the bank's order.
    """
    return [generator_performance(g, plant, frequencies=frequencies) for g in generators]
