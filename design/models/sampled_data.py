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


def norm_invariant_discretisation(*, A: object, B: object, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Lemma 1 (eq. (5)): ``(A_D, B_J, W)`` with ``‖S G‖_η = ‖G_J‖_η``.

    ``A_D = e^{Ah}``, ``W = ∫₀ʰ e^{Aτ} B Bᵀ e^{Aᵀτ} dτ`` (Van Loan's block
    exponential) and ``B_J`` the full-column-rank factor ``B_J B_Jᵀ = W``
    (:func:`~fdisyn.numerics.linalg.psd_factor`, ``n × rank W``). ``W`` is the
    covariance of ``∫₀ʰ e^{A(h−τ)} B dβ(τ)`` for unit-intensity white noise
    ``dβ``, which is why the same matrix gives exact noise sampling.
    """
    h = check_sample_time(h, "h")
    a = as_matrix(A, "A")
    n = a.shape[0]
    if a.shape != (n, n):
        raise ShapeError(f"A must be square; got shape {a.shape}")
    b = as_matrix(B, "B", rows=n)
    ad = sla.expm(a * h)
    w = van_loan(a, b @ b.T, h)
    return ad, psd_factor(w, "W = ∫ e^{Aτ} B Bᵀ e^{Aᵀτ} dτ"), w


@dataclass(frozen=True, eq=False)
class SampledDataPlant:
    """Eqs. (1)–(3): continuous plant, sampler, ZOH; with its discretisations.

    ``A_D``, ``B_uD`` (step-invariant, eq. (13)), ``B_dJ``, ``B_fJ`` (Lemma 1)
    and, for the paper's indirect comparison, ``B_dD``, ``B_fD`` (ZOH of the
    disturbance and fault, as if they were held between samples).
    """

    A: np.ndarray
    Bu: np.ndarray
    Bd: np.ndarray
    Bf: np.ndarray
    C: np.ndarray
    h: float
    A_D: np.ndarray
    B_uD: np.ndarray
    B_dJ: np.ndarray
    B_fJ: np.ndarray
    W_d: np.ndarray
    """``B_dJ B_dJᵀ``: also the covariance of the sampled unit-intensity disturbance."""
    W_f: np.ndarray
    B_dD: np.ndarray
    B_fD: np.ndarray

    @classmethod
    def create(cls, *, A: object, Bu: object, Bd: object, Bf: object, C: object, h: float) -> SampledDataPlant:
        """Validate (shapes, ``h > 0``) and discretise."""
        h = check_sample_time(h, "h")
        a = as_matrix(A, "A")
        n = a.shape[0]
        if a.shape != (n, n):
            raise ShapeError(f"A must be square; got shape {a.shape}")
        bu = as_matrix(Bu, "Bu", rows=n, cols=None if np.ndim(np.asarray(Bu)) == 2 else 1)
        bd = as_matrix(Bd, "Bd", rows=n, cols=None if np.ndim(np.asarray(Bd)) == 2 else 1)
        bf = as_matrix(Bf, "Bf", rows=n, cols=None if np.ndim(np.asarray(Bf)) == 2 else 1)
        c = as_matrix(C, "C", cols=n)
        ad, held = zoh(a, np.hstack([bu, bd, bf]), h)
        m, q = bu.shape[1], bd.shape[1]
        _, bdj, wd = norm_invariant_discretisation(A=a, B=bd, h=h)
        _, bfj, wf = norm_invariant_discretisation(A=a, B=bf, h=h)
        return cls(
            A=a,
            Bu=bu,
            Bd=bd,
            Bf=bf,
            C=c,
            h=h,
            A_D=ad,
            B_uD=held[:, :m],
            B_dJ=bdj,
            B_fJ=bfj,
            W_d=wd,
            W_f=wf,
            B_dD=held[:, m : m + q],
            B_fD=held[:, m + q :],
        )

    @classmethod
    def from_linear_plant(cls, plant: LinearPlant, *, h: float) -> SampledDataPlant:
        """From a continuous :class:`LinearPlant`: ``B → Bu``, ``E → Bd``, ``Fx → Bf``.

        The paper's plant is strictly proper (``D = 0``) and noise enters
        through ``d``; a nonzero ``D`` is refused rather than dropped.
        """
        if plant.is_discrete:
            raise ArgumentError(f"the sampled-data design needs a continuous plant; this one has Ts = {plant.Ts}")
        if np.any(plant.D != 0):
            raise ExistenceError("the sampled-data plant must be strictly proper (D = 0, Qiu, Wen & Jiang 2010, eq. (1))")
        return cls.create(A=plant.A, Bu=plant.B, Bd=plant.E, Bf=plant.Fx, C=plant.C, h=h)

    @property
    def n(self) -> int:
        return self.A.shape[0]

    @property
    def p(self) -> int:
        return self.C.shape[0]

    @property
    def m(self) -> int:
        return self.Bu.shape[1]

    def G_d(self, *, model: Literal["norm_invariant", "zoh"] = "norm_invariant") -> DiscreteLTI:
        """``G_dJ = (A_D, B_dJ, C, 0)`` (Lemma 1) or the ZOH model ``(A_D, B_dD, C, 0)``."""
        return DiscreteLTI(A=self.A_D, B=self.B_dJ if model == "norm_invariant" else self.B_dD, C=self.C, D=np.zeros((self.p, self._cols(model, "d"))))

    def G_f(self, *, model: Literal["norm_invariant", "zoh"] = "norm_invariant") -> DiscreteLTI:
        """``G_fJ = (A_D, B_fJ, C, 0)`` (Lemma 1) or the ZOH model ``(A_D, B_fD, C, 0)``."""
        return DiscreteLTI(A=self.A_D, B=self.B_fJ if model == "norm_invariant" else self.B_fD, C=self.C, D=np.zeros((self.p, self._cols(model, "f"))))

    def _cols(self, model: str, ch: str) -> int:
        if model == "norm_invariant":
            return (self.B_dJ if ch == "d" else self.B_fJ).shape[1]
        if model == "zoh":
            return (self.B_dD if ch == "d" else self.B_fD).shape[1]
        raise ArgumentError(f"model must be 'norm_invariant' or 'zoh'; got {model!r}")

    def discrete_plant(self, *, model: Literal["norm_invariant", "zoh"] = "norm_invariant") -> LinearPlant:
        """The discrete :class:`LinearPlant` ``(A_D, B_uD, C, E=B_dJ or B_dD, Fx=B_fJ or B_fD, Ts=h)``."""
        e = self.B_dJ if model == "norm_invariant" else self.B_dD
        fx = self.B_fJ if model == "norm_invariant" else self.B_fD
        if model not in ("norm_invariant", "zoh"):
            raise ArgumentError(f"model must be 'norm_invariant' or 'zoh'; got {model!r}")
        return LinearPlant.create(A=self.A_D, B=self.B_uD, C=self.C, E=e, Fx=fx, Ts=self.h)


# ---------------------------------------------------------------------------
# Sampling conditions (Theorem 1's assumptions)
# ---------------------------------------------------------------------------


def _nullity(mat: np.ndarray) -> int:
    s = np.linalg.svd(mat, compute_uv=False)
    tol = 1e3 * max(mat.shape) * np.finfo(float).eps * max(float(s[0]), np.finfo(float).tiny)
    return int(mat.shape[1] - np.sum(s > tol))


def _pathological_losses(a: np.ndarray, c: np.ndarray, h: float) -> list[tuple[complex, complex, int, int]]:
    """Groups of distinct eigenvalues of ``A`` that sampling maps onto one ``e^{λh}``
    *and* that lose observability doing so: ``(λ_i, λ_j, k, modes lost)`` with
    ``h (λ_i − λ_j) = 2πk·j`` (Chen & Francis, 1995, the pathological case)."""
    n = a.shape[0]
    lam = np.linalg.eigvals(a)
    ad = sla.expm(a * h)
    mu = np.exp(lam * h)
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
            k = int(round(((l1 - l2) * h / (2j * math.pi)).real))
            out.append((l1, l2, k, disc - cont))
    return out


def check_sampling(*, A: object, C: object, h: float, allow_pathological: bool = False) -> None:
    """Theorem 1's assumptions on the plant and the sampling.

    Raises :class:`ExistenceError` naming the condition:

    * ``(A, C)`` not detectable (an unstable mode, ``Re λ ≥ 0``, unobservable);
    * pathological sampling: distinct eigenvalues with ``h(λ_i − λ_j) = 2πk·j``
      whose images ``e^{λh}`` coincide and become unobservable from ``C``
      (``allow_pathological=True`` accepts this when ``(A_D, C)`` stays
      detectable, i.e. only stable modes are lost);
    * ``(A_D, C)`` not detectable.

    ``h ≤ 0`` or non-finite raises :class:`ArgumentError` (not a sample time).
    """
    h = check_sample_time(h, "h")
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
    ad = sla.expm(a * h)
    undetectable = unobservable_modes(ad, c, region="unstable-discrete")
    losses = _pathological_losses(a, c, h)
    if losses and (undetectable or not allow_pathological):
        l1, l2, k, lost = losses[0]
        raise ExistenceError(
            f"pathological sampling: h = {h:g} maps the eigenvalues λ = {l1:.6g} and {l2:.6g} of A "
            f"(h(λ1 − λ2) = 2π·{k}·j) onto one eigenvalue e^(λh) = {np.exp(l1 * h):.6g} of A_D, and {lost} mode(s) "
            "become unobservable from C (Theorem 1 of Qiu, Wen & Jiang 2010 assumes non-pathological sampling); "
            "choose h with h·|Im(λ1 − λ2)| ≠ 2πk"
            + ("" if undetectable else ", or pass allow_pathological=True (the lost modes are stable)")
        )
    if undetectable:
        raise ExistenceError(
            f"(A_D, C) is not detectable: the mode(s) μ = {[complex(round(z.real, 9), round(z.imag, 9)) for z in undetectable]} "
            f"of A_D = e^(A·{h:g}) with |μ| ≥ 1 are unobservable from C"
        )
