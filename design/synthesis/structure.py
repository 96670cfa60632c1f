"""Which faults a plant's sensors can detect and which they can tell apart: the achievable fault signatures of
linear residual generators (Varga, *Solving Fault Diagnosis Problems: Linear Synthesis Techniques*, Springer 2017,
secs. 3.5 and 5.4; the functions ``fdigenspec`` and ``fdichkspec`` of his FaultDetectionTools.jl).

The model is Varga's synthesis model in fdisyn's letters,

    x⁺ = A x + B u + E d + Fx f_c        (ẋ for a continuous plant)
    y  = C x + D u + f_s,

with the faults in the plant's fault order: one sensor fault per output (``f_s``, in the order of the outputs),
then the component faults (``f_c``, the columns of ``Fx``). A residual generator ``r = Q(λ) [y; u]`` must have
``R_u = 0`` and ``R_d = 0``: ``Q`` is in the left null space of ``G_e = [G_u G_d; I 0]``. A binary row ``s`` (one
entry per fault) is an *achievable specification* when a scalar ``Q`` gives ``R_fj ≠ 0`` where ``s_j = 1`` and
``R_fj = 0`` where ``s_j = 0``.

*Weak* (the transfer functions nonzero): decoupling the faults ``D`` as well leaves fault ``j`` visible iff the
normal rank of ``[G_d G_fD G_fj]`` exceeds that of ``[G_d G_fD]`` (a generic member of the null space then sees
every such fault at once). The faults that decoupling ``D`` hides along with it form its closure; the achievable
rows are the complements of the closed sets, found by adding one fault at a time from the closure of the empty
set (Varga's recursion of ``genspec_in`` visits the same sets). Normal ranks come from the system pencil
(:func:`fdisyn.numerics.pencils.normal_rank`).

*Least order* of a row: the smallest McMillan degree of a scalar filter achieving it. A filter of order ``k`` is
``v(λ)/φ(λ)`` with ``v`` a polynomial null vector of degree ``k``; fault ``j`` is seen at degree ``k`` iff the null
vectors of degree at most ``k`` for ``D`` outnumber those for ``D ∪ {j}``, counted from the left minimal indices of
the two null spaces (:func:`fdisyn.numerics.pencils.null_dimension`).

On a plant with modes on or beyond the stability boundary (an integrator, an unstable mode) the filter must also
cancel those modes in its responses to the noise and to every fault, so that its residual is stationary and
``R_f`` stable (Varga's synthesis problems ask for both): the pencils are then built on a realisation that keeps
every mode the noise or a fault excites, and the least orders are those of such filters (they may exceed the
rational least orders of ``G_e``).

*Strong* at frequencies ``Ω`` (a persistent fault of that frequency; 0 for a constant one): ``R_fj(λ) ≠ 0`` at
``λ = jω`` (continuous) or ``e^{jωTs}`` (discrete) for every ``ω`` in ``Ω``. Every admissible filter is a rational
combination of a minimal polynomial basis ``N(λ)``, so ``R_fj(λ₀)`` can be made nonzero iff
``N(λ₀) [G_fj(λ₀); 0] ≠ 0``; ``N(λ₀)`` is spanned by the values at ``λ₀`` of the polynomial null vectors of the
largest minimal index (:func:`fdisyn.numerics.pencils.polynomial_left_null`). As in ``fdigenspec``, a strong row is
a weak row whose every 1 is strong at every frequency. Unlike FaultDetectionTools.jl, whose strong test compares
the gain with an absolute level (``FDGainTol = 0.01``, in the user's units), fdisyn tests for a structural zero
relative to the sizes of ``N(λ₀)`` and ``G_fj(λ₀)`` (:data:`STRONG_TOL`), so the answer does not depend on units.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from fdisyn.models.linear import LinearPlant
from fdisyn.numerics.pencils import left_kronecker_indices, minimal_realisation, normal_rank, null_dimension, polynomial_left_null
from fdisyn.runtime.errors import ArgumentError

__all__ = ["MAX_ROWS", "STRONG_TOL", "FaultPencils", "StructureAnalysis", "analyse_structure", "check_structure", "fault_entries", "structure_matrices"]

MAX_ROWS = 4096
"""Most achievable rows the analysis enumerates. Faults in general position on ``p`` sensors give every subset
of fewer than ``p`` of them (2ᵖ rows); beyond this the analysis stops and says so."""

STRONG_TOL = 1e-8
"""A fault's response at a frequency counts as zero below this: ``G_fj(λ₀)`` relative to the sizes of its terms
``C (λ₀I − A)⁻¹ b_j`` and ``d_j``, and ``N(λ₀) G_fj(λ₀)`` relative to ``‖N(λ₀)‖ ‖G_fj(λ₀)‖``. A structural zero
leaves round-off (~1e-15 after the solve and the Toeplitz SVD), while a response this small relative to its own
terms is zero for any threshold a residual could have."""

POLE_TOL = 1e-8
"""A frequency closer than this (relative to ``max(1, |λ|)``) to a pole of the plant is refused: the fault's
response there is not a finite number."""


@dataclass(frozen=True, eq=False)
class StructureAnalysis:
    """The achievable specifications of a plant (:func:`analyse_structure`).

    Attributes
    ----------
    faults : tuple of str
        The plant's faults, in its fault order: the sensor faults (the outputs' names), then the component faults.
    kind : str
        ``"weak"`` or ``"strong"``.
    frequencies : tuple of float
        The strong structure's frequencies (rad/s); empty for the weak structure.
    rows : numpy.ndarray
        The achievable rows, ``0``/``1`` integers, one column per fault; the row with the most ones first.
    least_orders : tuple of int
        Per row, the least order of a scalar filter that achieves it.
    basis_sizes : tuple of int
        Per row, the number of residuals of a minimal null-space basis that achieves it (Varga's ``rdims``).
    basis_orders : tuple of int
        Per row, the order of that basis (Varga's ``orders``: the sum of its left minimal indices).
    decoupled : tuple of tuple of str
        Per row, the faults it decouples (its zeros), by name.
    discrete : bool
        The analysis is of a discrete plant (``λ = z``); else continuous (``λ = s``).
    gaps : tuple of float or None
        Per row, the fault-to-noise gap of its least-order filter with every pole at :attr:`pole`, the combination
        chosen for the gap (:func:`fdisyn.synthesis.nullspace.analyse_gaps`; ``inf``: the noise does not reach it);
        ``None`` when not computed.
    pole : float or None
        The filters' pole the gaps are for.
    """

    faults: tuple[str, ...]
    kind: str
    frequencies: tuple[float, ...]
    rows: np.ndarray
    least_orders: tuple[int, ...]
    basis_sizes: tuple[int, ...]
    basis_orders: tuple[int, ...]
    decoupled: tuple[tuple[str, ...], ...]
    discrete: bool
    gaps: tuple[float, ...] | None = None
    pole: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """The analysis as JSON-ready data (``fdisyn analyse --json``)."""
        gaps = self.gaps if self.gaps is not None else (None,) * len(self.least_orders)
        return {
            "faults": list(self.faults),
            "kind": self.kind,
            "frequencies_rad_s": list(self.frequencies),
            "domain": "discrete" if self.discrete else "continuous",
            **({} if self.pole is None else {"pole": self.pole}),
            "rows": [
                {"signature": [int(v) for v in row], "least_order": lo, "basis_size": bs, "basis_order": bo, "decoupled": list(dec),
                 **({} if gap is None else {"gap": "inf" if math.isinf(gap) else float(gap)})}
                for row, lo, bs, bo, dec, gap in zip(
                    self.rows, self.least_orders, self.basis_sizes, self.basis_orders, self.decoupled, gaps, strict=True)
            ],
        }


def _linear(plant: Any) -> LinearPlant:
    """The linear plant analysed: a ``LinearPlant`` as it is, a ``SampledDataPlant`` as its exact sampling."""
    if isinstance(plant, LinearPlant):
        return plant
    discrete = getattr(plant, "discrete_plant", None)
    if callable(discrete):
        return discrete(model="zoh")
    raise ArgumentError(
        f"the structure analysis needs a linear plant (a LinearPlant or a SampledDataPlant); got {type(plant).__name__}: "
        "linearise a nonlinear plant at its operating point first"
    )


def fault_entries(plant: LinearPlant) -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
    """The plant's faults in its fault order and where they enter: ``(names, Bf, Df)``, a sensor fault adding to its
    output (``Df`` a column of the identity) and a component fault entering the state through its column of ``Fx``
    and the outputs through its column of the plant's ``Df``.

    Parameters
    ----------
    plant : LinearPlant
        The plant.

    Returns
    -------
    tuple
        ``(names, Bf (n × nf), Df (p × nf))``.
    """
    n, p = plant.n, plant.p
    nc = len(plant.component_faults)
    bf = np.hstack([np.zeros((n, p)), np.asarray(plant.Fx, float).reshape(n, nc)])
    df = np.hstack([np.eye(p), np.asarray(plant.Df, float).reshape(p, nc)])
    return tuple(plant.outputs) + tuple(plant.component_faults), bf, df


class FaultPencils:
    """The plant's transfer matrices with subsets of its faults decoupled, balanced, with their normal ranks, left
    minimal indices and polynomial null vectors (cached): what the structure analysis and the nullspace synthesis
    (:mod:`fdisyn.synthesis.nullspace`) compute on.

    Parameters
    ----------
    plant : LinearPlant
        The plant; its faults in its fault order (:func:`fault_entries`).
    """

    def __init__(self, plant: LinearPlant) -> None:
        self.names, bf, df = fault_entries(plant)
        # the user's units out, exactly (powers of two): the states balanced (LinearPlant.balancing), every sensor's
        # row of [C D] and every input's, unknown input's and fault's column of the model at unit size; a
        # structure does not depend on any of these scalings, the pencil's rank decisions do
        s = plant.balancing() if plant.n else np.ones(0)
        a = np.asarray(plant.A, float) * s[None, :] / s[:, None]
        c = np.asarray(plant.C, float) * s[None, :]
        d = np.asarray(plant.D, float)
        out = _pow2(np.hypot(np.linalg.norm(c, axis=1), np.linalg.norm(d, axis=1)))[:, None]
        c, d, df = c / out, d / out, df / out

        def unit(x: Any, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            x = np.asarray(x, float) / s[:, None]
            k = _pow2(np.hypot(np.linalg.norm(x, axis=0), np.linalg.norm(y, axis=0)))
            return x / k[None, :], y / k[None, :], k

        b, d, k_u = unit(plant.B, d)
        e, dd, _ = unit(plant.E, np.asarray(plant.Dd, float) / out)
        bf, df, _ = unit(bf, df)
        self.out, self.k_u = out[:, 0], k_u  # the pencil sees y / out and u · k_u
        self.A, self.B, self.C, self.D, self.E, self.Dd, self.bf, self.df = a, b, c, d, e, dd, bf, df
        # a plant with modes on or beyond the stability boundary: the filter must cancel them in its responses to the
        # noise and to every fault too (R_w and R_f stable, as Varga's synthesis asks), so the pencils keep every
        # mode the noise or a fault excites (hidden inputs of the realisation, not columns of the pencil)
        poles = np.linalg.eigvals(a) if plant.n else np.zeros(0)
        self.unstable = bool(np.any(np.abs(poles) >= 1 - 1e-9) if plant.Ts is not None else np.any(poles.real >= -1e-9))
        lam, vec = np.linalg.eigh(np.asarray(plant.Q, float) / np.outer(s, s)) if plant.n else (np.zeros(0), np.zeros((0, 0)))
        noise = vec * np.sqrt(np.clip(lam, 0.0, None))[None, :]
        self.hidden = np.hstack([bf, noise[:, np.any(noise != 0, axis=0)]]) if self.unstable else np.zeros((plant.n, 0))
        self.n, self.p, self.m, self.q = plant.n, plant.p, plant.m, plant.q
        self._rank: dict[frozenset[int], int] = {}
        self._indices: dict[frozenset[int], tuple[int, ...]] = {}
        self._null: dict[tuple[frozenset[int], int], np.ndarray] = {}

    def _columns(self, faults: frozenset[int]) -> tuple[np.ndarray, np.ndarray]:
        """``(B, D)`` of ``[G_d G_f,faults]``."""
        idx = sorted(faults)
        b = np.hstack([self.E, self.bf[:, idx]])
        d = np.hstack([self.Dd, self.df[:, idx]])
        return b, d

    def rank(self, faults: frozenset[int]) -> int:
        """Normal rank of ``[G_d G_f,faults]``."""
        if faults not in self._rank:
            b, d = self._columns(faults)
            self._rank[faults] = normal_rank(self.A, b, self.C, d)
        return self._rank[faults]

    def extended(self, faults: frozenset[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """A realisation of ``G_e = [G_u G_d G_f,faults; I 0 0]`` (outputs ``y`` then ``u``)."""
        b, d = self._columns(faults)
        m, k = self.m, b.shape[1]
        be = np.hstack([self.B, b])
        ce = np.vstack([self.C, np.zeros((m, self.n))])
        de = np.block([[self.D, d], [np.eye(m), np.zeros((m, k))]])
        return self.A, be, ce, de

    def realisation(self, faults: frozenset[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The realisation of ``G_e`` (:meth:`extended`) the pencils are built on: minimal, but for an unstable plant
        keeping the modes the noise and the faults excite (:attr:`hidden`)."""
        a, b, c, d = self.extended(faults)
        ar, br, cr = minimal_realisation(a, np.hstack([b, self.hidden]), c)
        return ar, br[:, : b.shape[1]], cr, d

    def indices(self, faults: frozenset[int]) -> tuple[int, ...]:
        """Left Kronecker indices of :meth:`realisation` with ``faults`` decoupled: the left minimal indices of
        ``G_e`` for a stable plant."""
        if faults not in self._indices:
            self._indices[faults] = left_kronecker_indices(*self.realisation(faults))
        return self._indices[faults]

    def seen(self, j: int, decoupled: frozenset[int]) -> bool:
        """Fault ``j`` is weakly detectable with ``decoupled`` decoupled."""
        return self.rank(decoupled | {j}) > self.rank(decoupled)

    def closure(self, decoupled: frozenset[int]) -> frozenset[int]:
        """``decoupled`` and every fault hidden by decoupling it."""
        return decoupled | {j for j in range(len(self.names)) if j not in decoupled and not self.seen(j, decoupled)}

    def least_order(self, decoupled: frozenset[int], faults: Sequence[int]) -> int:
        """Least degree of a null vector seeing every one of ``faults`` with ``decoupled`` decoupled."""
        base = self.indices(decoupled)
        others = [self.indices(decoupled | {j}) for j in faults]
        for k in range(max(base, default=0) + 1):
            if all(null_dimension(base, k) > null_dimension(o, k) for o in others):
                return k
        raise AssertionError("a weakly detectable fault is seen by the whole basis")  # pragma: no cover

    def null_vectors(self, decoupled: frozenset[int], k: int, toward: np.random.Generator | None = None) -> np.ndarray:
        """A basis of the polynomial left null vectors of degree ``≤ k`` of ``G_e`` with ``decoupled`` decoupled:
        their ``[y; u]`` coefficients, ``(count, k + 1, p + m)`` (degree-major), in the balanced units (the
        pencil sees ``y / out`` and ``u · k_u``). With ``toward``, one vector instead (``count = 1``): the orthogonal
        projection of a standard normal draw from it onto the span of the basis's ``[y; u]`` parts, which depends
        neither on the basis the SVD returns nor on the state coordinates of the realisation (another BLAS kernel
        may return others)."""
        a, b, c, d = self.realisation(decoupled)
        nr, rows = a.shape[0], c.shape[0]
        mm = np.block([[a, b], [c, d]])
        nn = np.zeros_like(mm)
        nn[:nr, :nr] = np.eye(nr)
        count = null_dimension(self.indices(decoupled), k)
        if (decoupled, k) not in self._null:
            self._null[(decoupled, k)] = polynomial_left_null(mm, nn, k, count)
        x = self._null[(decoupled, k)].reshape(-1, k + 1, nr + rows)[:, :, nr:]
        if toward is not None and not x.shape[0]:
            x = np.zeros((1, k + 1, rows))
        elif toward is not None:
            # the projection of a draw onto the span of the [y; u] parts: neither the basis the SVD returns nor the
            # realisation's state coordinates (another BLAS kernel's) enter it
            q, _ = np.linalg.qr(x.reshape(x.shape[0], -1).T)
            flat = q @ (q.T @ toward.standard_normal(q.shape[0]))
            x = flat.reshape(1, k + 1, rows)
        return x

    def null_values(self, decoupled: frozenset[int], k: int, lam: complex) -> np.ndarray:
        """The values at ``λ`` of the ``y`` parts of a basis of the polynomial null vectors of degree ``≤ k``."""
        x = self.null_vectors(decoupled, k)
        return np.einsum("cdw,d->cw", x, lam ** np.arange(k + 1))[:, : self.p]

    def verdict(self, row: Sequence[int], points: Sequence[complex] = (), frequencies: Sequence[float] = ()) -> dict[str, Any]:
        """Whether ``row`` is achievable (weakly, or strongly at ``points``, the ``frequencies`` in the plant's
        domain), its least order and why not (:func:`check_structure`)."""
        nf = len(self.names)
        zeros = frozenset(j for j in range(nf) if row[j] == 0)
        ones = [j for j in range(nf) if row[j] == 1]
        hidden = [self.names[j] for j in ones if not self.seen(j, zeros)]
        if hidden:
            return {"achievable": False, "least_order": None, "why": f"decoupling {sorted(self.names[j] for j in zeros)} hides {hidden}"}
        order = self.least_order(zeros, ones) if ones else 0
        if points and ones:
            top = max(self.indices(zeros), default=0)
            if not self.strong(zeros, ones, top, points):
                weak = [self.names[j] for j in ones if not self.strong(zeros, [j], top, points)]
                return {"achievable": False, "least_order": None,
                        "why": f"{weak} have a zero response at {list(frequencies)} rad/s once {sorted(self.names[j] for j in zeros)} are decoupled"}
            order = next(k for k in range(order, top + 1) if self.strong(zeros, ones, k, points))
        return {"achievable": True, "least_order": order, "why": ""}

    def response(self, j: int, lam: complex) -> np.ndarray:
        """``G_fj(λ)``, exact zeros where it is zero to round-off of its terms ``C (λI − A)⁻¹ b`` and ``d``."""
        x = np.linalg.solve(lam * np.eye(self.n) - self.A, self.bf[:, j]) if self.n else np.zeros(0)
        g = self.C @ x + self.df[:, j]
        terms = float(np.linalg.norm(self.C, 2) * np.linalg.norm(x) + np.linalg.norm(self.df[:, j])) if self.n else float(np.linalg.norm(g))
        return g if float(np.linalg.norm(g)) > STRONG_TOL * terms else np.zeros_like(g)

    def strong(self, decoupled: frozenset[int], faults: Sequence[int], k: int, points: Sequence[complex]) -> bool:
        """Every one of ``faults`` has a nonzero response at every point for a null vector of degree ``≤ k``."""
        for lam in points:
            v = self.null_values(decoupled, k, lam)
            size_v = float(np.linalg.norm(v, 2)) if v.size else 0.0
            for j in faults:
                g = self.response(j, lam)
                scale = size_v * float(np.linalg.norm(g))
                if not scale > 0 or not float(np.linalg.norm(v @ g)) > STRONG_TOL * scale:
                    return False
        return True


def _pow2(x: np.ndarray) -> np.ndarray:
    """The powers of two nearest to the positive entries of ``x`` (1 for zeros)."""
    x = np.asarray(x, float)
    return np.where(x > 0, np.exp2(np.round(np.log2(np.where(x > 0, x, 1.0)))), 1.0)


def frequency_points(plant: LinearPlant, frequencies: Sequence[float]) -> list[complex]:
    """The frequencies (rad/s) as points of the plant's domain (``e^{jωTs}`` or ``jω``), refused above the Nyquist
    frequency and at the plant's poles (an :class:`ArgumentError` that says which)."""
    out = []
    poles = np.linalg.eigvals(np.asarray(plant.A, float)) if plant.n else np.zeros(0)
    for w in frequencies:
        if plant.Ts is not None:
            if w > np.pi / plant.Ts * (1 + 1e-12):
                raise ArgumentError(
                    f"frequency {w:g} rad/s is above the Nyquist frequency π/Ts = {np.pi / plant.Ts:g} rad/s of the plant's "
                    f"sample time {plant.Ts:g} s; give frequencies from 0 to {np.pi / plant.Ts:g} rad/s"
                )
            lam = complex(np.exp(1j * w * plant.Ts))
        else:
            lam = complex(1j * w)
        near = poles[np.abs(poles - lam) <= POLE_TOL * max(1.0, abs(lam))]
        if near.size:
            raise ArgumentError(
                f"frequency {w:g} rad/s is a pole of the plant (λ = {lam:.6g}): a fault's response there is not finite; "
                "give frequencies away from the plant's poles (an integrating plant has one at 0 rad/s)"
            )
        out.append(lam)
    return out


def _checked(plant: Any, kind: str, frequencies: Sequence[float] | None) -> tuple[LinearPlant, tuple[float, ...]]:
    """The plant and the frequencies, checked."""
    if kind not in ("weak", "strong"):
        raise ArgumentError(f"kind must be 'weak' or 'strong'; got {kind!r}")
    lin = _linear(plant)
    if kind == "weak":
        if frequencies is not None:
            raise ArgumentError("frequencies are for the strong structure: give kind='strong' with them, or omit them")
        return lin, ()
    freqs = (0.0,) if frequencies is None else tuple(frequencies)
    if not freqs or not all(isinstance(w, int | float) and not isinstance(w, bool) and np.isfinite(w) and w >= 0 for w in freqs):
        raise ArgumentError(f"frequencies must be finite numbers ≥ 0 in rad/s (0: constant faults); got {list(freqs)!r}")
    return lin, tuple(float(w) for w in freqs)


def analyse_structure(plant: Any, *, kind: Literal["weak", "strong"] = "weak", frequencies: Sequence[float] | None = None) -> StructureAnalysis:
    """The achievable specifications of ``plant``, with each row's least order (Varga's ``fdigenspec`` and
    ``fdichkspec``; the module docstring gives the method).

    Parameters
    ----------
    plant : LinearPlant or SampledDataPlant
        The plant (a sampled-data plant is analysed on its exact ZOH sampling).
    kind : {"weak", "strong"}
        The weak structure (nonzero transfer functions) or the strong one (nonzero responses at ``frequencies``).
    frequencies : sequence of float, optional
        The strong structure's frequencies in rad/s (default ``[0]``: constant faults).

    Returns
    -------
    StructureAnalysis
        The rows, the faults they decouple, their least orders and basis sizes.

    Raises
    ------
    ArgumentError
        A plant that is not linear, a bad kind or frequency, or more than :data:`MAX_ROWS` rows.
    """
    lin, freqs = _checked(plant, kind, frequencies)
    pen = FaultPencils(lin)
    nf = len(pen.names)
    everything = frozenset(range(nf))
    start = pen.closure(frozenset())
    seen_sets = {start}
    queue = deque([start])
    while queue:
        flat = queue.popleft()
        for j in range(nf):
            if j in flat:
                continue
            nxt = pen.closure(flat | {j})
            if nxt not in seen_sets:
                if len(seen_sets) >= MAX_ROWS:
                    raise ArgumentError(
                        f"the plant has more than {MAX_ROWS} achievable specifications over its {nf} faults; check a given "
                        "structure matrix instead (fdisyn.synthesis.structure.check_structure)"
                    )
                seen_sets.add(nxt)
                queue.append(nxt)
    flats = [f for f in seen_sets if f != everything]
    points = frequency_points(lin, freqs) if kind == "strong" else []
    rows, orders, sizes, borders, dec = [], [], [], [], []
    for flat in flats:
        verdict = pen.verdict([0 if j in flat else 1 for j in range(nf)], points, freqs)
        if not verdict["achievable"]:  # weakly it is (a closed set): not at the frequencies
            continue
        order = verdict["least_order"]
        rows.append([0 if j in flat else 1 for j in range(nf)])
        orders.append(order)
        ind = pen.indices(flat)
        sizes.append(len(ind))
        borders.append(sum(ind))
        dec.append(tuple(pen.names[j] for j in sorted(flat)))
    key = sorted(range(len(rows)), key=lambda i: (-sum(rows[i]), [-v for v in rows[i]]))
    return StructureAnalysis(
        faults=pen.names, kind=kind, frequencies=freqs,
        rows=np.array([rows[i] for i in key], dtype=int).reshape(len(rows), nf),
        least_orders=tuple(orders[i] for i in key), basis_sizes=tuple(sizes[i] for i in key),
        basis_orders=tuple(borders[i] for i in key), decoupled=tuple(dec[i] for i in key), discrete=lin.Ts is not None,
    )


def structure_matrices(plant: Any, *, kind: Literal["weak", "strong"] = "weak", frequencies: Sequence[float] | None = None) -> np.ndarray:
    """The achievable rows of a structure matrix for ``plant``: every fault signature a scalar residual with
    ``R_u = 0`` and ``R_d = 0`` can have (Varga's ``fdigenspec``).

    Parameters
    ----------
    plant : LinearPlant or SampledDataPlant
        The plant; its faults are its sensor faults (one per output) then its component faults.
    kind : {"weak", "strong"}
        Nonzero transfer functions (weak) or nonzero responses at ``frequencies`` (strong).
    frequencies : sequence of float, optional
        For the strong structure, in rad/s (default ``[0]``: constant faults).

    Returns
    -------
    numpy.ndarray
        ``0``/``1`` integers, one row per achievable specification, one column per fault in the plant's fault
        order (:func:`analyse_structure` gives the names, the least orders and the decoupled faults).

    Examples
    --------
    >>> import fdisyn
    >>> plant = fdisyn.LinearPlant.create(A=[[0.5, 0.0], [0.0, 0.3]], C=[[1.0, 0.0], [0.0, 1.0]], Ts=0.1)
    >>> fdisyn.structure_matrices(plant)
    array([[1, 1],
           [1, 0],
           [0, 1]])
    """
    return analyse_structure(plant, kind=kind, frequencies=frequencies).rows


def check_structure(
    plant: Any, structure: Any, *, kind: Literal["weak", "strong"] = "weak", frequencies: Sequence[float] | None = None
) -> list[dict[str, Any]]:
    """Whether each row of a given structure matrix is achievable, and its least order (Varga's ``fdichkspec``).

    Parameters
    ----------
    plant : LinearPlant or SampledDataPlant
        The plant.
    structure : array_like
        ``0``/``1`` rows, one column per fault in the plant's fault order.
    kind, frequencies
        As for :func:`analyse_structure`.

    Returns
    -------
    list of dict
        Per row: ``achievable`` (bool), ``least_order`` (``None`` when not achievable) and ``why`` (which faults the
        row needs seen that decoupling its zeros hides, or which it cannot see strongly; ``""`` when achievable).
    """
    lin, freqs = _checked(plant, kind, frequencies)
    pen = FaultPencils(lin)
    nf = len(pen.names)
    s = np.asarray(structure)
    if s.ndim != 2 or s.shape[1] != nf or not np.all((s == 0) | (s == 1)):
        raise ArgumentError(f"structure must be 0/1 rows of {nf} entries (faults {list(pen.names)}); got an array of shape {s.shape}")
    points = frequency_points(lin, freqs) if kind == "strong" else []
    return [pen.verdict(row, points, freqs) for row in s.astype(int)]
