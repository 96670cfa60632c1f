"""Certificates: what a design was verified against, and how well.

Every design builds a :class:`Certificate` of named checks. Each check holds
the measured value, the bound it must meet and the reason for that bound.
``Certificate.require()`` turns any failed check into a
:class:`~fdisyn.runtime.errors.CertificateError`: a design that fails its
certificate is an error, not a warning.

A measurement that is NaN or infinite proves nothing, so a check whose value
or bound is not finite fails, whatever its relation. Aggregates must keep a
NaN visible: Python's ``max(0.0, nan)`` is ``0.0`` (every comparison with NaN
is false), so a worst case over several measurements is taken with
:func:`worst`, which returns NaN as soon as one of them is NaN.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Literal

from fdisyn.runtime.errors import CertificateError
from fdisyn.runtime.jsondata import to_jsonable

__all__ = ["Check", "Certificate", "distinct_digits", "worst"]


def distinct_digits(value: float, bound: float) -> tuple[str, str]:
    """``value`` and ``bound`` with the fewest significant digits (at least 3) that tell them apart.

    A failed check must show its violation: ``0.951 (must be <= 0.951)`` hides it, ``0.9512295 (must be <=
    0.9512294)`` shows it. Equal numbers (or a NaN) are shown with 3 digits.

    Parameters
    ----------
    value, bound
        The measured value and the bound it was checked against.

    Returns
    -------
    tuple of str
        The two numbers as text, with the same number of significant digits.
    """
    v, b = float(value), float(bound)
    for digits in range(3, 18):
        sv, sb = f"{v:.{digits}g}", f"{b:.{digits}g}"
        if sv != sb or not (math.isfinite(v) and math.isfinite(b)) or v == b:
            return sv, sb
    return repr(v), repr(b)


def worst(*values: float) -> float:
    """The largest of ``values``, or NaN if any of them is NaN (``max`` would drop it).

    ``worst()`` of nothing is ``0.0``: no measurement, no deviation.
    """
    out = 0.0 if not values else -math.inf
    for v in values:
        fv = float(v)
        if math.isnan(fv):
            return math.nan
        out = fv if fv > out else out
    return out


@dataclass(frozen=True)
class Check:
    """One verified quantity: ``value <relation> bound``, with the reason for the bound.

    It passes only if both ``value`` and ``bound`` are finite numbers: a NaN
    or infinite measurement (a diverged solver, an overflowed model) or bound
    (a tolerance scaled by a NaN condition number) cannot certify anything.

    Attributes
    ----------
    name : str
        What is checked (``"residual_gain"``, say).
    value : float
        The measured quantity.
    bound : float
        What it must meet.
    relation : {"<=", ">="}
        How ``value`` must compare with ``bound``.
    reason : str
        Why the bound is what it is (a message shows it when the check fails).

    Examples
    --------
    >>> Check("gain", 0.5, 1.0, "<=", "contraction").passed
    True
    >>> Check("gain", float("nan"), 1.0, "<=", "contraction").passed
    False
    """

    name: str
    value: float
    bound: float
    relation: Literal["<=", ">="]
    reason: str

    @property
    def passed(self) -> bool:
        """``value <relation> bound``, both finite."""
        v, b = float(self.value), float(self.bound)
        if not (math.isfinite(v) and math.isfinite(b)):
            return False
        return v <= b if self.relation == "<=" else v >= b

    def to_dict(self) -> dict[str, object]:
        """The check as the gain file's certificate records it (with ``passed``)."""
        return {
            "name": self.name,
            "value": float(self.value),
            "bound": float(self.bound),
            "relation": self.relation,
            "passed": self.passed,
            "reason": self.reason,
        }


@dataclass(frozen=True)
class Certificate:
    """A named set of checks plus informational figures (not pass/fail).

    Attributes
    ----------
    subject : str
        What is certified (the design's name).
    checks : tuple of Check
        The verified quantities; the certificate passes when all of them do.
    info : Mapping of str to object
        Informational figures (recorded, never pass/fail).
    """

    subject: str
    checks: tuple[Check, ...]
    info: Mapping[str, object] = field(default_factory=dict)

    @classmethod
    def of(cls, subject: str, checks: Iterable[Check], info: Mapping[str, object] | None = None) -> Certificate:
        """A certificate from any iterable of checks.

        Parameters
        ----------
        subject : str
            What is certified.
        checks : iterable of Check
            The verified quantities.
        info : Mapping of str to object, optional
            Informational figures.

        Returns
        -------
        Certificate
            The certificate (``checks`` as a tuple, ``info`` copied).
        """
        return cls(subject=subject, checks=tuple(checks), info=dict(info or {}))

    @property
    def passed(self) -> bool:
        """Every check passed."""
        return all(c.passed for c in self.checks)

    def failed(self) -> list[Check]:
        """The checks that did not pass, in order."""
        return [c for c in self.checks if not c.passed]

    def require(self) -> Certificate:
        """Return ``self`` if every check passed, else raise :class:`CertificateError`.

        Returns
        -------
        Certificate
            ``self``.

        Raises
        ------
        CertificateError
            One line naming every failed check, its value, its bound and the reason for the bound.
        """
        bad = self.failed()
        if bad:
            lines = "; ".join(f"{c.name} = {v} (must be {c.relation} {b}: {c.reason})" for c in bad for v, b in [distinct_digits(c.value, c.bound)])
            raise CertificateError(f"design {self.subject!r} failed its certificate: {lines}")
        return self

    def to_dict(self) -> dict[str, object]:
        """The certificate as the gain file records it (plain JSON values)."""
        return {
            "subject": self.subject,
            "passed": self.passed,
            "checks": [c.to_dict() for c in self.checks],
            "info": to_jsonable(self.info),
        }
