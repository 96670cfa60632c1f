"""The canonical residual generator connected to its plant (the internal form).

Every linear method in fdisyn reduces to one discrete LTI form on the full
input and output vectors (the gain file's ``generators``, see ``runtime/REFERENCE.md``), held by
:class:`fdisyn.runtime.gainfile.Generator`::

    ξ(k+1) = Ar ξ(k) + Bu u(k) + By y(k)
    r(k)   = Cr ξ(k) + Du u(k) + Dy y(k)

Connected to the plant ``x⁺ = A x + B u + E d``, ``y = C x + D u`` it gives
the *internal form* (Varga's term) with state ``[x; ξ]``; a generator is
decoupled when the internal form's transfer from ``u`` and ``d`` to ``r`` is
identically zero.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from fdisyn.detectors.window import residual_autocovariance
from fdisyn.models.linear import LinearPlant
from fdisyn.numerics.linalg import dlyap, spectral_radius, transfer_size
from fdisyn.runtime.errors import ExistenceError, ShapeError, SolverError
from fdisyn.runtime.gainfile import Generator

__all__ = [
    "InternalForm",
    "internal_form",
    "dc_gain_y",
    "residual_covariance",
    "residual_autocovariances",
    "embed_outputs",
    "whiteness",
    "whitened",
    "fault_step_response",
    "fault_steady_state",
    "long_run_covariance",
    "evidence_covariance",
    "WHITE_RTOL",
]


@dataclass(frozen=True, eq=False)
class InternalForm:
    """State-space data of plant + generator, per input channel.

    Channels: ``u`` (known input), ``d`` (unknown input), ``f`` (component
    faults) and ``s`` (additive sensor faults, one per output). The input
    matrices are named by channel, like the generator's ``Bu`` and ``By``:
    ``Bd = [E; By Dd]`` and ``Bf = [Fx; By Df]`` carry the plant's ``E`` and ``Fx`` (and their
    feed-through ``Dd``, ``Df`` to the outputs, read by the generator: ``Dd = Dy Dd``, ``Df = Dy Df``).
    """

    A: np.ndarray
    C: np.ndarray
    Bu: np.ndarray
    Du: np.ndarray
    Bd: np.ndarray
    Bf: np.ndarray
    Bs: np.ndarray
    Ds: np.ndarray
    Dd: np.ndarray
    Df: np.ndarray

    def coupling(self, channel: str) -> float:
        """Largest normalised Markov parameter from ``channel`` to ``r``
        (:func:`fdisyn.numerics.linalg.transfer_size`): zero exactly when the
        channel is decoupled, of order ``eps`` for an exactly decoupled
        generator computed in floating point, independently of units."""
        b = getattr(self, "B" + channel)
        d = getattr(self, "D" + channel)
        return transfer_size(self.A, b, self.C, d)


def internal_form(gen: Generator, plant: LinearPlant) -> InternalForm:
    """``gen`` connected to ``plant`` (discrete, the same ``u`` and ``y``)."""
    if plant.p != gen.By.shape[1] or plant.m != gen.Bu.shape[1]:
        raise ShapeError(
            f"generator {gen.name!r} is for {gen.Bu.shape[1]} inputs/{gen.By.shape[1]} outputs; the plant has {plant.m}/{plant.p}"
        )
    n, ns = plant.n, gen.n_state
    a = np.block([[plant.A, np.zeros((n, ns))], [gen.By @ plant.C, gen.Ar]])
    c = np.hstack([gen.Dy @ plant.C, gen.Cr])
    bu = np.vstack([plant.B, gen.Bu + gen.By @ plant.D])
    du = gen.Du + gen.Dy @ plant.D
    bd = np.vstack([plant.E, gen.By @ plant.Dd])
    bf = np.vstack([plant.Fx, gen.By @ plant.Df])
    # additive sensor faults y = C x + D u + f_y enter like a second y input
    bs = np.vstack([np.zeros((n, plant.p)), gen.By])
    return InternalForm(A=a, C=c, Bu=bu, Du=du, Bd=bd, Bf=bf, Bs=bs, Ds=gen.Dy.copy(), Dd=gen.Dy @ plant.Dd, Df=gen.Dy @ plant.Df)


def dc_gain_y(gen: Generator) -> np.ndarray:
    """Steady-state gain from ``y`` to ``r``: ``Dy + Cr (I − Ar)⁻¹ By``."""
    return gen.Dy + gen.Cr @ np.linalg.solve(np.eye(gen.n_state) - gen.Ar, gen.By) if gen.n_state else gen.Dy.copy()


def residual_covariance(gen: Generator, plant: LinearPlant) -> np.ndarray:
    """Steady-state covariance of ``r`` under the plant's noise ``w ~ N(0, Q)``, ``v ~ N(0, R)``.

    From the internal form: ``Σ = A_i Σ A_iᵀ + B_w Q B_wᵀ + B_v R B_vᵀ`` with
    ``B_w = [I; 0]``, ``B_v = [0; By]``; then ``Σ_r = C_i Σ C_iᵀ + Dy R Dyᵀ``
    (``v(k)`` is independent of the state at ``k``).

    An unstable plant makes the internal form unstable, yet the residual of an
    observer-based generator is stationary: it sees only the estimation error,
    whose dynamics are stable. When the internal form is not Schur stable, the
    covariance is taken on its stable quotient, the modes on or outside the unit
    circle removed (:func:`residual_autocovariances`, ``τ = 0``): the residual is
    exactly the output of that quotient driven by the same noise. A Schur stable
    internal form is solved as above, unchanged.

    Parameters
    ----------
    gen : Generator
        The residual generator, on the plant's full input and output vectors.
    plant : LinearPlant
        The discrete plant with its noise covariances ``Q`` and ``R``.

    Returns
    -------
    numpy.ndarray
        ``Σ_r``, symmetric, ``(nr, nr)``.

    Raises
    ------
    ExistenceError
        When the residual sees a mode of the plant on or outside the unit
        circle: it then has no stationary law.
    """
    form = internal_form(gen, plant)
    if spectral_radius(form.A) >= 1.0 - 1e-12:  # as _stationary_model: an integrator sampled exactly may be 1 − eps
        a, k, c, dn, w = _stationary_model(gen, plant)
        s = c @ dlyap(a, k @ w @ k.T) @ c.T + dn @ w @ dn.T
        return 0.5 * (s + s.T)
    bw, bv = _noise_inputs(gen, plant)
    sig = dlyap(form.A, bw @ plant.Q @ bw.T + bv @ plant.R @ bv.T)
    s = form.C @ sig @ form.C.T + gen.Dy @ plant.R @ gen.Dy.T
    return 0.5 * (s + s.T)


def _noise_inputs(gen: Generator, plant: LinearPlant) -> tuple[np.ndarray, np.ndarray]:
    """How the plant's noise enters the internal form: ``B_w = [I; 0]`` (process), ``B_v = [0; By]`` (sensors)."""
    n, ns = plant.n, gen.n_state
    return np.vstack([np.eye(n), np.zeros((ns, n))]), np.vstack([np.zeros((n, plant.p)), gen.By])


_DECOUPLED_RTOL = 1e-9
"""A mode the residual does not see: its output direction ``‖C_i U₁‖`` below this fraction of ``‖C_i‖``
(round-off of an exact decoupling is ~1e-15 times the conditioning; cf. the UIO's ``DECOUPLING_TOL``)."""


def residual_autocovariances(gen: Generator, plant: LinearPlant, lags: int) -> np.ndarray:
    """``R(τ) = E[r(k+τ) r(k)ᵀ]``, ``τ = 0..lags``, of ``gen``'s residual on ``plant`` under its noise ``Q``, ``R``.

    The internal form driven by ``n = [w; v] ~ N(0, blkdiag(Q, R))`` through ``K = [B_w, B_v]`` with the
    feedthrough ``[0, Dy]`` (as :func:`residual_covariance`, which is ``R(0)``), by
    :func:`fdisyn.detectors.window.residual_autocovariance`. A plant with modes on or outside the unit circle
    (an integrator, say) has a stationary residual only if the residual does not see them: then the internal
    form's real Schur form, ordered with those modes first (``A_i = U [[A₁₁, A₁₂], [0, A₂₂]] Uᵀ``), has
    ``C_i U₁ = 0`` and the residual is the output of the stable quotient ``(A₂₂, U₂ᵀ K, C_i U₂)``. Raises
    :class:`ExistenceError` when it does see one (no stationary law).
    """
    a, k, c, dn, w = _stationary_model(gen, plant)
    return residual_autocovariance(a, k, c, dn, w, lags)


def _stationary_model(gen: Generator, plant: LinearPlant) -> tuple[np.ndarray, ...]:
    """``(A, K, C, Dn, W)``: the residual as the output of a stable system driven by white noise ``n ~ N(0, W)``
    (the internal form, or its stable quotient; see :func:`residual_autocovariances`)."""
    form = internal_form(gen, plant)
    bw, bv = _noise_inputs(gen, plant)
    k = np.hstack([bw, bv])
    dn = np.hstack([np.zeros((gen.n_residual, plant.n)), gen.Dy])
    w = scipy.linalg.block_diag(plant.Q, plant.R)
    a, c = form.A, form.C
    if spectral_radius(a) >= 1.0 - 1e-12:  # an integrator sampled exactly may come out at 1 − eps
        t, u, unstable = scipy.linalg.schur(a, output="real", sort=lambda re, im: re * re + im * im >= 1.0 - 1e-12)
        seen = float(np.linalg.norm(c @ u[:, :unstable]))
        # relative to the sizes of c's terms Dy C and Cr: a residual that sees no state at all (a static
        # combination of the outputs with Dy C = 0) has a c of round-off size, and round-off is what it sees
        terms = float(np.linalg.norm(gen.Dy, 2) * np.linalg.norm(plant.C, 2) + np.linalg.norm(gen.Cr, 2))
        if not seen <= _DECOUPLED_RTOL * max(float(np.linalg.norm(c)), terms, 1e-300):
            raise ExistenceError(
                f"the residual of generator {gen.name!r} sees a mode of the plant on or outside the unit circle "
                f"(output direction {seen:.3g}): it has no stationary law and no windowed threshold"
            )
        a, k, c = t[unstable:, unstable:], (u.T @ k)[unstable:], (c @ u)[:, unstable:]
    return a, k, c, dn, w


WHITE_RTOL = 1e-8
"""A residual counts as white when no lag-1…``lags`` autocorrelation of its normalised form exceeds this
(an exact innovation's are round-off, ~1e-14; the paper gains of a UIO bank give 0.1–1)."""


def whiteness(gen: Generator, plant: LinearPlant, lags: int = 50) -> float:
    """``max_{1 ≤ τ ≤ lags} ‖T R(τ) Tᵀ‖₂`` with ``Tᵀ T = R(0)⁺``: the largest autocorrelation of ``gen``'s residual."""
    r = residual_autocovariances(gen, plant, lags)
    lam, vec = np.linalg.eigh(0.5 * (r[0] + r[0].T))
    keep = lam > 1e-12 * max(float(lam[-1]), 1e-300)
    t = (vec[:, keep] / np.sqrt(lam[keep])).T
    return max((float(np.linalg.norm(t @ r[k] @ t.T, 2)) for k in range(1, lags + 1)), default=0.0)


def whitened(gen: Generator, plant: LinearPlant) -> Generator:
    """``gen`` followed by the whitening filter of its residual: the residual becomes its innovation.

    The residual is the output of a stable system driven by the plant's noise (:func:`_stationary_model`:
    ``z⁺ = A z + K n``, ``r = C z + Dn n``). Its steady-state Kalman predictor ``ẑ⁺ = A ẑ + L (r − C ẑ)``
    (the filtering DARE with ``Q = K W Kᵀ``, ``R = Dn W Dnᵀ``, ``S = K W Dnᵀ``:
    :func:`fdisyn.numerics.riccati.solve_filter_dare`) makes ``e = r − C ẑ`` white (Anderson & Moore, Optimal
    Filtering, Prentice-Hall 1979, section 5.3), with the same information about a fault as ``r``. Composed
    with the generator, in canonical form on state ``[ξ; ẑ]``::

        Ar' = [[Ar, 0], [L Cr, A − L C]],  Bu' = [Bu; L Du],  By' = [By; L Dy],
        Cr' = [Cr, −C],                    Du' = Du,          Dy' = Dy.

    A residual that is already white (:data:`WHITE_RTOL`) is returned unchanged. One that is not is first
    projected on the directions its χ² statistic keeps (variance above
    :data:`fdisyn.detectors.chi2.CHI2_RANK_RTOL` of the largest, the eigenvectors of its covariance): a
    direction without noise of its own would make the innovation model singular.
    """
    if whiteness(gen, plant) <= WHITE_RTOL:
        return gen
    from fdisyn.detectors.chi2 import CHI2_RANK_RTOL
    from fdisyn.numerics.riccati import solve_filter_dare

    lam, vec = np.linalg.eigh(residual_autocovariances(gen, plant, 0)[0])
    keep = lam > CHI2_RANK_RTOL * max(float(lam[-1]), 1e-300)
    if not np.all(keep):
        t = vec[:, keep][:, ::-1].T  # largest variance first
        gen = Generator.from_canonical(
            name=gen.name, outputs_used=gen.outputs_used, Ar=gen.Ar, Bu=gen.Bu, By=gen.By,
            Cr=t @ gen.Cr, Du=t @ gen.Du, Dy=t @ gen.Dy, method={**dict(gen.method), "projection": t},
        )
    a, k, c, dn, w = _stationary_model(gen, plant)
    try:
        sol = solve_filter_dare(a, c, k @ w @ k.T, dn @ w @ dn.T, k @ w @ dn.T)
    except (ExistenceError, SolverError):
        # Modes the residual does not see (those a decoupling generator cancels) put pairs λ, 1/λ̄ in the DARE
        # pencil whose split into stable and unstable is left to round-off; the residual is the output of the
        # observable part alone, so its predictor is designed there (Anderson & Moore 1979, section 5.3).
        a, k, c = _observable_part(a, k, c)
        sol = solve_filter_dare(a, c, k @ w @ k.T, dn @ w @ dn.T, k @ w @ dn.T)
    lg = sol.L
    ns, nz = gen.n_state, a.shape[0]
    ar = np.block([[gen.Ar, np.zeros((ns, nz))], [lg @ gen.Cr, a - lg @ c]])
    return Generator.from_canonical(
        name=gen.name,
        outputs_used=gen.outputs_used,
        Ar=ar,
        Bu=np.vstack([gen.Bu, lg @ gen.Du]),
        By=np.vstack([gen.By, lg @ gen.Dy]),
        Cr=np.hstack([gen.Cr, -c]),
        Du=gen.Du,
        Dy=gen.Dy,
        method={**dict(gen.method), "whitening_L": lg},
    )


def _observable_part(a: np.ndarray, k: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(a, k, c)`` restricted to the states ``c`` observes: on an orthonormal basis ``V`` of the row space of the
    observability matrix (its singular values above ``n·ε`` of the largest), the unobserved subspace is
    ``a``-invariant, so ``z_o⁺ = Vᵀ a V z_o + Vᵀ k n``, ``r = c V z_o + Dn n`` gives the same residual."""
    n = a.shape[0]
    blocks, m = [], c
    for _ in range(n):
        blocks.append(m)
        m = m @ a
    _, sv, vt = np.linalg.svd(np.vstack(blocks))
    rank = int(np.sum(sv > n * np.finfo(float).eps * max(float(sv[0]), 1e-300))) if sv.size else 0
    v = vt[:rank].T
    return v.T @ a @ v, v.T @ k, c @ v


def long_run_covariance(gen: Generator, plant: LinearPlant) -> np.ndarray:
    """``Σ_τ R(τ) = H(1) W H(1)ᵀ``, ``H(1) = C (I − A)⁻¹ K + Dn`` (:func:`_stationary_model`): the residual's
    spectral density at zero frequency. A constant mean shift ``μ`` of a stationary Gaussian residual brings
    ``½ μᵀ (Σ_τ R(τ))⁺ μ`` nats of Kullback–Leibler information per sample in the long run — ``½ μᵀ Σ_r⁺ μ`` for
    a white residual, and the same for a residual and its whitened form."""
    a, k, c, dn, w = _stationary_model(gen, plant)
    h = c @ np.linalg.solve(np.eye(a.shape[0]) - a, k) + dn
    s = h @ w @ h.T
    return 0.5 * (s + s.T)


def evidence_covariance(gens: Sequence[Generator], plant: LinearPlant, forgetting: float) -> np.ndarray:
    """The stationary covariance of ``s = Σ_{k≥0} λ^k r(t − k)``, ``r`` the generators' stacked residuals.

    The generators are driven by the same plant noise, so their residuals are correlated: the stacked residual
    is the output of the block-diagonal stack of their stationary models (:func:`_stationary_model`), and
    ``Var s = Σ_{k,l} λ^{k+l} R(k − l) = (R(0) + X + Xᵀ)/(1 − λ²)`` exactly, with
    ``X = Σ_{τ≥1} λ^τ R(τ) = C ((I − λA)⁻¹ − I) P Cᵀ + λ C (I − λA)⁻¹ K W Dnᵀ`` (``P`` the stationary state
    covariance; ``R(τ)`` as in :func:`fdisyn.detectors.window.residual_autocovariance`). ``λ → 1`` tends to
    the long-run covariance times ``1/(1 − λ²)``.
    """
    lam = float(forgetting)
    if not 0.0 <= lam < 1.0:
        raise ShapeError(f"forgetting = {lam}: expected a number in [0, 1)")
    models = [_stationary_model(g, plant) for g in gens]
    a = scipy.linalg.block_diag(*[m[0] for m in models])
    k = np.vstack([m[1] for m in models])
    c = scipy.linalg.block_diag(*[m[2] for m in models])
    dn = np.vstack([m[3] for m in models])
    w = models[0][4]
    n = a.shape[0]
    p_state = dlyap(a, k @ w @ k.T) if n else np.zeros((0, 0))
    r0 = c @ p_state @ c.T + dn @ w @ dn.T
    inv = np.linalg.inv(np.eye(n) - lam * a) if n else np.zeros((0, 0))
    x = c @ (inv - np.eye(n)) @ p_state @ c.T + lam * c @ inv @ k @ w @ dn.T
    v = (r0 + x + x.T) / (1.0 - lam * lam)
    return 0.5 * (v + v.T)


def fault_steady_state(gen: Generator, plant: LinearPlant, sensors: np.ndarray, components: np.ndarray) -> np.ndarray | None:
    """The residual's steady-state shift under a step fault (:func:`fault_step_response` at ``ℓ → ∞``):
    ``C (I − A)⁻¹ b + d`` on the internal form; ``None`` when the internal form is not Schur stable (the
    step response then tells whether it settles)."""
    form = internal_form(gen, plant)
    if spectral_radius(form.A) >= 1.0:
        return None
    b = form.Bs @ np.asarray(sensors, dtype=float) + form.Bf @ np.asarray(components, dtype=float)
    d = form.Ds @ np.asarray(sensors, dtype=float) + form.Df @ np.asarray(components, dtype=float)
    return form.C @ np.linalg.solve(np.eye(form.A.shape[0]) - form.A, b) + d


def fault_step_response(gen: Generator, plant: LinearPlant, sensors: np.ndarray, components: np.ndarray, lags: int) -> np.ndarray:
    """``ρ(ℓ)``, ``ℓ = 0 … lags − 1``: the residual ``ℓ`` samples after a step fault appears, from rest.

    ``sensors`` (one entry per output) is the additive sensor bias, ``components`` (one per column of
    ``Fx``) the component fault; the internal form's response (:func:`internal_form`), shape ``(lags, nr)``.
    """
    form = internal_form(gen, plant)
    b = form.Bs @ np.asarray(sensors, dtype=float) + form.Bf @ np.asarray(components, dtype=float)
    d = form.Ds @ np.asarray(sensors, dtype=float) + form.Df @ np.asarray(components, dtype=float)
    out = np.empty((int(lags), gen.n_residual))
    z = np.zeros(form.A.shape[0])
    for ell in range(int(lags)):
        out[ell] = form.C @ z + d
        z = form.A @ z + b
    return out


def embed_outputs(gen: Generator, outputs_used: Sequence[int], n_outputs: int) -> Generator:
    """``gen`` designed on a subset of the sensors, on the full output vector of ``n_outputs``.

    Its ``By``/``Dy`` columns move to ``outputs_used``; the others are zero.
    """
    idx = [int(j) for j in outputs_used]
    if gen.By.shape[1] != len(idx):
        raise ShapeError(f"generator {gen.name!r} reads {gen.By.shape[1]} outputs; outputs_used lists {len(idx)}")
    by = np.zeros((gen.n_state, n_outputs))
    dy = np.zeros((gen.n_residual, n_outputs))
    by[:, idx] = gen.By
    dy[:, idx] = gen.Dy
    return Generator.from_canonical(
        name=gen.name, outputs_used=idx, Ar=gen.Ar, Bu=gen.Bu, By=by, Cr=gen.Cr, Du=gen.Du, Dy=dy, method=gen.method
    )
