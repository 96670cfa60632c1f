"""The exceptions fdisyn raises, design side and runtime side alike.

Every exception names what is wrong and what was expected, so that a user can
act on the message alone. They subclass the built-in exception a caller would
naturally catch (``ValueError`` for bad values and shapes, ``RuntimeError`` for
solver and certificate failures, ``OSError`` for compiler and file problems).
"""

from __future__ import annotations


class FdisynError(Exception):
    """Base class of every fdisyn exception."""


class ShapeError(FdisynError, ValueError):
    """A matrix or signal has the wrong shape.

    The message names the matrix, the expected and the found shape.
    """


class ExistenceError(FdisynError, ValueError):
    """A condition the method needs does not hold for this plant.

    Example: ``rank(C E) = rank(E)`` for an unknown-input observer
    (Hu, Sun, Jiang, He & Zhang, Acta Automatica Sinica 39(8), 2013, eq. (3)),
    or detectability of ``(C, A1)``.
    """


class SolverError(FdisynError, RuntimeError):
    """A numerical solver failed (infeasible, unbounded, not converged).

    The message carries the solver's status and what to try.
    """


class CertificateError(FdisynError, RuntimeError):
    """A design failed its verification against an independent truth.

    A design that fails its certificate is an error, never a warning.
    """


class GainFileError(FdisynError, ValueError):
    """A gain file is corrupt, of a foreign format or of another version."""


class TraceError(FdisynError, ValueError):
    """A data trace (CSV or array) is malformed: missing column, bad header."""


class SpecError(FdisynError, ValueError):
    """A plant specification (TOML file or problem name) is invalid."""


class BuildError(FdisynError, OSError):
    """Compiling or loading generated C failed."""


class NominalValueError(SpecError):
    """A model parameter has no (finite) nominal value.

    The nonlinear adaptive fault-detection filter (Zhou, Xi & Zhang, Shanghai
    Jiao Tong University, c. 1991) runs its EKF on
    the nominal model, so every parameter ``θ_i`` needs one. The message names
    the parameters without a value and the ones that were given.
    """


class NonDifferentiableError(SpecError):
    """A model expression uses an operation without a derivative everywhere.

    Every Jacobian and parameter sensitivity of a nonlinear plant comes from
    automatic differentiation; ``abs``, ``min``/``max``, comparisons,
    ``floor``, ``if_else`` and the like have kinks or jumps where the
    linearisation is undefined. The message names the operation and where it
    occurs.
    """
