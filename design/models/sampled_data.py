"""The sampled-data plant of Qiu, Wen & Jiang (Control Theory & Applications 27(8), 2010, eqs. (1)–(3)):
Lemma 1's norm-invariant discretisation and the sampling checks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.linalg as sla
from fdisyn.models.linear import LinearPlant
from fdisyn.models.sampling import check_sample_time, van_loan, zoh
from fdisyn.numerics.linalg import as_matrix, psd_factor, unobservable_modes
from fdisyn.numerics.norms import DiscreteLTI
from fdisyn.runtime.errors import ArgumentError, ExistenceError, ShapeError

__all__ = ['SampledDataPlant', 'check_sampling', 'norm_invariant_discretisation']


# ---------------------------------------------------------------------------
# Lemma 1 and the sampled-data plant
# ---------------------------------------------------------------------------


def norm_invariant_discretisation(*, A: object, B: object, Ts: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lemma 1 (eq. (5)): ``(A_D, B_J, W)`` with ``‖S G‖_η = ‖G_J‖_η``.

    ``A_D = e^{A Ts}``, ``W = ∫₀^Ts e^{Aτ} B Bᵀ e^{Aᵀτ} dτ`` (Van Loan's block
    exponential) and ``B_J`` the full-column-rank factor ``B_J B_Jᵀ = W``
    (:func:`~fdisyn.numerics.linalg.psd_factor`, ``n × rank W``). ``W`` is the
    covariance of ``∫₀^Ts e^{A(Ts−τ)} B dβ(τ)`` for unit-intensity white noise
    ``dβ``, which is why the same matrix gives exact noise sampling. (The paper
    writes the sample time ``h``.)
    """
    Ts = check_sample_time(Ts, "Ts")
    a = as_matrix(A, "A")
    n = a.shape[0]
    if a.shape != (n, n):
        raise ShapeError(f"A must be square; got shape {a.shape}")
    b = as_matrix(B, "B", rows=n)
    ad = sla.expm(a * Ts)
    w = van_loan(a, b @ b.T, Ts)
    return ad, psd_factor(w, "W = ∫ e^{Aτ} B Bᵀ e^{Aᵀτ} dτ"), w


@dataclass(frozen=True, eq=False)
class SampledDataPlant:
    """Eqs. (1)–(3): continuous plant, sampler, ZOH; with its discretisations.

    ``ẋ = A x + B u + E d + Fx f``, ``y = C x``, sampled every ``Ts`` — the
    letters of :class:`~fdisyn.models.linear.LinearPlant`; the paper writes
    ``B_u``, ``B_d``, ``B_f`` and ``h``. Discretisations: ``A_D``, ``B_D``
    (step-invariant, eq. (13), the paper's ``B_uD``), ``E_J``, ``Fx_J``
    (Lemma 1, the paper's ``B_dJ``, ``B_fJ``) and, for the paper's indirect
    comparison, ``E_D``, ``Fx_D`` (ZOH of the disturbance and fault, as if they
    were held between samples; the paper's ``B_dD``, ``B_fD``). The discrete
    systems are named by their input signal, as the paper and every
    certificate write them: :meth:`G_d` from ``d`` and :meth:`G_f` from ``f``
    to ``y``.

    Attributes
    ----------
    A, C : numpy.ndarray
        The continuous plant's state and output matrices.
    B : numpy.ndarray
        Known inputs ``u`` (the paper's ``B_u``).
    E : numpy.ndarray
        Disturbance ``d``, continuous white noise (the paper's ``B_d``).
    Fx : numpy.ndarray
        Faults ``f`` (the paper's ``B_f``).
    Ts : float
        Sample time (the paper's ``h``).
    A_D, B_D : numpy.ndarray
        ``e^{A Ts}`` and the step-invariant input matrix (eq. (13)).
    E_J, Fx_J : numpy.ndarray
        The norm-invariant input matrices of the disturbance and the fault (Lemma 1).
    W_E : numpy.ndarray
        ``E_J E_Jᵀ = ∫₀^Ts e^{Aτ} E Eᵀ e^{Aᵀτ} dτ``: also the covariance of the sampled unit-intensity disturbance.
    W_Fx : numpy.ndarray
        ``Fx_J Fx_Jᵀ``.
    E_D, Fx_D : numpy.ndarray
        The ZOH input matrices of the disturbance and the fault (the paper's indirect comparison).
    """

    A: np.ndarray
    B: np.ndarray
    E: np.ndarray
    Fx: np.ndarray
    C: np.ndarray
    Ts: float
    A_D: np.ndarray
    B_D: np.ndarray
    E_J: np.ndarray
    Fx_J: np.ndarray
    W_E: np.ndarray
    W_Fx: np.ndarray
    E_D: np.ndarray
    Fx_D: np.ndarray

    @classmethod
    def create(cls, *, A: object, B: object, E: object, Fx: object, C: object, Ts: float) -> SampledDataPlant:
        """Validate (shapes, ``Ts > 0``) and discretise.

        Parameters
        ----------
        A : array_like
            The state matrix (``n × n``).
        B, E, Fx : array_like
            The known inputs', disturbance's and faults' entries (``n`` rows each).
        C : array_like
            The output matrix (``p × n``).
        Ts : float
            The sample time in seconds.

        Returns
        -------
        SampledDataPlant
            The plant with its discretisations.

        Raises
        ------
        ArgumentError
            ``Ts`` is not a positive number, or a matrix does not hold real numbers.
        ShapeError
            A matrix whose size does not fit ``A``.
        """
        Ts = check_sample_time(Ts, "Ts")
        a = as_matrix(A, "A")
        n = a.shape[0]
        if a.shape != (n, n):
            raise ShapeError(f"A must be square; got shape {a.shape}")
        b = as_matrix(B, "B", rows=n, cols=None if np.ndim(np.asarray(B)) == 2 else 1)
        e = as_matrix(E, "E", rows=n, cols=None if np.ndim(np.asarray(E)) == 2 else 1)
        fx = as_matrix(Fx, "Fx", rows=n, cols=None if np.ndim(np.asarray(Fx)) == 2 else 1)
        c = as_matrix(C, "C", cols=n)
        ad, held = zoh(a, np.hstack([b, e, fx]), Ts)
        m, q = b.shape[1], e.shape[1]
        _, ej, we = norm_invariant_discretisation(A=a, B=e, Ts=Ts)
        _, fxj, wfx = norm_invariant_discretisation(A=a, B=fx, Ts=Ts)
        return cls(
            A=a,
            B=b,
            E=e,
            Fx=fx,
            C=c,
            Ts=Ts,
            A_D=ad,
            B_D=held[:, :m],
            E_J=ej,
            Fx_J=fxj,
            W_E=we,
            W_Fx=wfx,
            E_D=held[:, m : m + q],
            Fx_D=held[:, m + q :],
        )

    @classmethod
    def from_linear_plant(cls, plant: LinearPlant, *, Ts: float) -> SampledDataPlant:
        """From a continuous :class:`LinearPlant` (the same ``A``, ``B``, ``C``, ``E``, ``Fx``), sampled every ``Ts``.

        The paper's plant is strictly proper (``D = 0``) and noise enters
        through ``d``; a nonzero ``D`` is refused rather than dropped.

        Parameters
        ----------
        plant : LinearPlant
            A continuous plant with ``D = 0``.
        Ts : float
            The sample time in seconds.

        Returns
        -------
        SampledDataPlant
            The plant with its discretisations.

        Raises
        ------
        ArgumentError
            ``plant`` is discrete, or ``Ts`` is not a positive number.
        ExistenceError
            ``plant`` has a nonzero ``D``.
        """
        if plant.is_discrete:
            raise ArgumentError(f"the sampled-data design needs a continuous plant; this one has Ts = {plant.Ts}")
        if np.any(plant.D != 0):
            raise ExistenceError("the sampled-data plant must be strictly proper (D = 0, Qiu, Wen & Jiang 2010, eq. (1))")
        return cls.create(A=plant.A, B=plant.B, E=plant.E, Fx=plant.Fx, C=plant.C, Ts=Ts)

    @property
    def n(self) -> int:
        """The number of states."""
        return self.A.shape[0]

    @property
    def p(self) -> int:
        """The number of outputs."""
        return self.C.shape[0]

    @property
    def m(self) -> int:
        """The number of known inputs."""
        return self.B.shape[1]

    def G_d(self, *, model: Literal["norm_invariant", "zoh"] = "norm_invariant") -> DiscreteLTI:
        """From the disturbance ``d`` to ``y``: ``G_dJ = (A_D, E_J, C, 0)`` (Lemma 1) or the ZOH model ``(A_D, E_D, C, 0)``.

        Parameters
        ----------
        model : {"norm_invariant", "zoh"}
            ``"norm_invariant"``: the norm-invariant discretisation of Lemma 1; ``"zoh"``: the input held
            between samples.

        Returns
        -------
        DiscreteLTI
            The discrete system.

        Raises
        ------
        ArgumentError
            ``model`` is neither.
        """
        b = self._input(model, "d")
        return DiscreteLTI(A=self.A_D, B=b, C=self.C, D=np.zeros((self.p, b.shape[1])))

    def G_f(self, *, model: Literal["norm_invariant", "zoh"] = "norm_invariant") -> DiscreteLTI:
        """From the fault ``f`` to ``y``: ``G_fJ = (A_D, Fx_J, C, 0)`` (Lemma 1) or the ZOH model ``(A_D, Fx_D, C, 0)``.

        Parameters
        ----------
        model : {"norm_invariant", "zoh"}
            ``"norm_invariant"``: the norm-invariant discretisation of Lemma 1; ``"zoh"``: the input held
            between samples.

        Returns
        -------
        DiscreteLTI
            The discrete system.

        Raises
        ------
        ArgumentError
            ``model`` is neither.
        """
        b = self._input(model, "f")
        return DiscreteLTI(A=self.A_D, B=b, C=self.C, D=np.zeros((self.p, b.shape[1])))

    def _input(self, model: str, ch: str) -> np.ndarray:
        """The discrete input matrix of channel ``d`` or ``f`` under ``model``."""
        if model == "norm_invariant":
            return self.E_J if ch == "d" else self.Fx_J
        if model == "zoh":
            return self.E_D if ch == "d" else self.Fx_D
        raise ArgumentError(f"model must be 'norm_invariant' or 'zoh'; got {model!r}")

    def discrete_plant(self, *, model: Literal["norm_invariant", "zoh"] = "norm_invariant") -> LinearPlant:
        """The discrete :class:`LinearPlant` ``(A_D, B_D, C, E=E_J or E_D, Fx=Fx_J or Fx_D, Ts)``.

        Parameters
        ----------
        model : {"norm_invariant", "zoh"}
            ``"norm_invariant"``: the norm-invariant discretisation of Lemma 1; ``"zoh"``: the input held
            between samples.

        Returns
        -------
        LinearPlant
            The discrete plant, without noise covariances.

        Raises
        ------
        ArgumentError
            ``model`` is neither.
        """
        return LinearPlant.create(A=self.A_D, B=self.B_D, C=self.C, E=self._input(model, "d"), Fx=self._input(model, "f"), Ts=self.Ts)


# ---------------------------------------------------------------------------
# Sampling conditions (Theorem 1's assumptions)
# ---------------------------------------------------------------------------


def _nullity(mat: np.ndarray) -> int:
    s = np.linalg.svd(mat, compute_uv=False)
    tol = 1e3 * max(mat.shape) * np.finfo(float).eps * max(float(s[0]), np.finfo(float).tiny)
    return int(mat.shape[1] - np.sum(s > tol))


def _pathological_losses(a: np.ndarray, c: np.ndarray, ts: float) -> list[tuple[complex, complex, int, int]]:
    """Groups of distinct eigenvalues of ``A`` that sampling maps onto one ``e^{λ Ts}``
    *and* that lose observability doing so: ``(λ_i, λ_j, k, modes lost)`` with
    ``Ts (λ_i − λ_j) = 2πk·j`` (Chen & Francis, 1995, the pathological case)."""
    n = a.shape[0]
    lam = np.linalg.eigvals(a)
    ad = sla.expm(a * ts)
    mu = np.exp(lam * ts)
    out: list[tuple[complex, complex, int, int]] = []
    seen: set[int] = set()
    for i in range(n):
        if i in seen:
            continue
        group = [j for j in range(n) if abs(mu[j] - mu[i]) <= 1e-8 * max(1.0, abs(mu[i]))]
        seen.update(group)
        distinct: list[complex] = []
        for j in group:
            if all(abs(lam[j] - d) > 1e-8 * max(1.0, abs(d)) for d in distinct):
                distinct.append(complex(lam[j]))
        if len(distinct) < 2:
            continue
        cont = sum(_nullity(np.vstack([d * np.eye(n) - a, c.astype(complex)])) for d in distinct)
        disc = _nullity(np.vstack([mu[i] * np.eye(n) - ad, c.astype(complex)]))
        if disc > cont:
            l1, l2 = distinct[0], distinct[1]
            k = int(round(((l1 - l2) * ts / (2j * math.pi)).real))
            out.append((l1, l2, k, disc - cont))
    return out


def check_sampling(*, A: object, C: object, Ts: float, allow_pathological: bool = False) -> None:
    """Theorem 1's assumptions on the plant and the sampling.

    Raises :class:`ExistenceError` naming the condition:

    * ``(A, C)`` not detectable (an unstable mode, ``Re λ ≥ 0``, unobservable);
    * pathological sampling: distinct eigenvalues with ``Ts(λ_i − λ_j) = 2πk·j``
      whose images ``e^{λ Ts}`` coincide and become unobservable from ``C``
      (``allow_pathological=True`` accepts this when ``(A_D, C)`` stays
      detectable, i.e. only stable modes are lost);
    * ``(A_D, C)`` not detectable.

    ``Ts ≤ 0`` or non-finite raises :class:`ArgumentError` (not a sample time).
    """
    Ts = check_sample_time(Ts, "Ts")
    a = as_matrix(A, "A")
    n = a.shape[0]
    if a.shape != (n, n):
        raise ShapeError(f"A must be square; got shape {a.shape}")
    c = as_matrix(C, "C", cols=n)
    bad = unobservable_modes(a, c, region="unstable-continuous")
    if bad:
        raise ExistenceError(
            f"(A, C) is not detectable: the mode(s) λ = {[complex(round(z.real, 9), round(z.imag, 9)) for z in bad]} "
            "with Re λ ≥ 0 are unobservable from C (Theorem 1 of Qiu, Wen & Jiang 2010 assumes (A, C) detectable)"
        )
    ad = sla.expm(a * Ts)
    undetectable = unobservable_modes(ad, c, region="unstable-discrete")
    losses = _pathological_losses(a, c, Ts)
    if losses and (undetectable or not allow_pathological):
        l1, l2, k, lost = losses[0]
        raise ExistenceError(
            f"pathological sampling: Ts = {Ts:g} maps the eigenvalues λ = {l1:.6g} and {l2:.6g} of A "
            f"(Ts(λ1 − λ2) = 2π·{k}·j) onto one eigenvalue e^(λ·Ts) = {np.exp(l1 * Ts):.6g} of A_D, and {lost} mode(s) "
            "become unobservable from C (Theorem 1 of Qiu, Wen & Jiang 2010 assumes non-pathological sampling); "
            "choose Ts with Ts·|Im(λ1 − λ2)| ≠ 2πk"
            + ("" if undetectable else ", or pass allow_pathological=True (the lost modes are stable)")
        )
    if undetectable:
        raise ExistenceError(
            f"(A_D, C) is not detectable: the mode(s) μ = {[complex(round(z.real, 9), round(z.imag, 9)) for z in undetectable]} "
            f"of A_D = e^(A·{Ts:g}) with |μ| ≥ 1 are unobservable from C"
        )
