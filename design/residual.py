"""The canonical residual generator and its internal form.

Every linear method in fdisyn reduces to one discrete LTI form on the full
input and output vectors (ARCHITECTURE.md)::

    ξ(k+1) = Ar ξ(k) + Bu u(k) + By y(k)
    r(k)   = Cr ξ(k) + Du u(k) + Dy y(k)

Connected to the plant ``x⁺ = A x + B u + E d``, ``y = C x + D u`` it gives
the *internal form* (Varga's term) with state ``[x; ξ]``; a generator is
decoupled when the internal form's transfer from ``u`` and ``d`` to ``r`` is
identically zero.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from fdisyn.design.linalg import transfer_size
from fdisyn.design.plant import LinearPlant
from fdisyn.runtime.errors import ShapeError

__all__ = ["ResidualGenerator", "InternalForm"]


@dataclass(frozen=True, eq=False)
class ResidualGenerator:
    """``ξ⁺ = Ar ξ + Bu u + By y``, ``r = Cr ξ + Du u + Dy y`` on the full ``u``, ``y``."""

    name: str
    outputs_used: tuple[int, ...]
    Ar: np.ndarray
    Bu: np.ndarray
    By: np.ndarray
    Cr: np.ndarray
    Du: np.ndarray
    Dy: np.ndarray
    method: Mapping[str, object] = field(default_factory=dict)
    """The method's name and the paper's matrices by their letters (for the gain file)."""

    def __post_init__(self) -> None:
        ns = self.Ar.shape[0]
        nr = self.Cr.shape[0]
        m = self.Bu.shape[1]
        p = self.By.shape[1]
        for nm, mat, shape in (
            ("Ar", self.Ar, (ns, ns)),
            ("Bu", self.Bu, (ns, m)),
            ("By", self.By, (ns, p)),
            ("Cr", self.Cr, (nr, ns)),
            ("Du", self.Du, (nr, m)),
            ("Dy", self.Dy, (nr, p)),
        ):
            if mat.shape != shape:
                raise ShapeError(f"generator {self.name!r}: {nm} has shape {mat.shape}; expected {shape}")
        unused = [j for j in range(p) if j not in self.outputs_used]
        if unused and (np.any(self.By[:, unused]) or np.any(self.Dy[:, unused])):
            raise ShapeError(f"generator {self.name!r} reads outputs {unused} that are not in outputs_used")

    @property
    def n_state(self) -> int:
        return self.Ar.shape[0]

    @property
    def n_residual(self) -> int:
        return self.Cr.shape[0]

    def internal_form(self, plant: LinearPlant) -> InternalForm:
        """The generator connected to ``plant`` (discrete, same ``u``/``y``)."""
        if plant.p != self.By.shape[1] or plant.m != self.Bu.shape[1]:
            raise ShapeError(
                f"generator {self.name!r} is for {self.Bu.shape[1]} inputs/{self.By.shape[1]} outputs; "
                f"the plant has {plant.m}/{plant.p}"
            )
        n, ns = plant.n, self.n_state
        a = np.block([[plant.A, np.zeros((n, ns))], [self.By @ plant.C, self.Ar]])
        c = np.hstack([self.Dy @ plant.C, self.Cr])
        bu = np.vstack([plant.B, self.Bu + self.By @ plant.D])
        du = self.Du + self.Dy @ plant.D
        bd = np.vstack([plant.E, np.zeros((ns, plant.q))])
        bf = np.vstack([plant.Fx, np.zeros((ns, plant.Fx.shape[1]))])
        # additive sensor faults y = C x + D u + f_y enter like a second y input
        bs = np.vstack([np.zeros((n, plant.p)), self.By])
        return InternalForm(A=a, C=c, Bu=bu, Du=du, Bd=bd, Bf=bf, Bs=bs, Ds=self.Dy.copy())

    def dc_gain_y(self) -> np.ndarray:
        """Steady-state gain from ``y`` to ``r``: ``Dy + Cr (I − Ar)⁻¹ By``."""
        ns = self.n_state
        return self.Dy + self.Cr @ np.linalg.solve(np.eye(ns) - self.Ar, self.By)


@dataclass(frozen=True, eq=False)
class InternalForm:
    """State-space data of plant + generator, per input channel.

    Channels: ``u`` (known input), ``d`` (unknown input), ``f`` (component
    faults ``Fx``) and ``s`` (additive sensor faults, one per output).
    """

    A: np.ndarray
    C: np.ndarray
    Bu: np.ndarray
    Du: np.ndarray
    Bd: np.ndarray
    Bf: np.ndarray
    Bs: np.ndarray
    Ds: np.ndarray

    def coupling(self, channel: str) -> float:
        """Largest normalised Markov parameter from ``channel`` to ``r``.

        ``max_k ‖C A^k B‖ / (‖C‖ ‖A‖^k ‖B‖)`` over ``k < dim + 1`` together
        with ``‖D‖ / (‖C‖ ‖B‖ + ‖D‖)``: zero exactly when the channel is
        decoupled, and of order ``eps`` for an exactly decoupled generator
        computed in floating point, independently of the units of the plant.
        """
        b = getattr(self, "B" + channel)
        d = self.Du if channel == "u" else (self.Ds if channel == "s" else np.zeros((self.C.shape[0], b.shape[1])))
        return transfer_size(self.A, b, self.C, d)
