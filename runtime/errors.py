"""The exceptions fdisyn raises, design side and runtime side alike: one taxonomy.

=====================  ==============================================================
``ArgumentError``      a keyword's value or type (an option out of its domain, an
                       unknown method or option name, a model that is not one:
                       ``NominalValueError``, ``NonDifferentiableError``)
``ShapeError``         a matrix or signal of the wrong shape
``FileError``          a file that is missing, corrupt, foreign or invalid, or a
                       path that cannot be written: ``SpecError`` (plant files
                       and problem names), ``GainFileError``, ``TraceError``
                       (CSV), ``BuildError`` (compiling or loading generated C)
``ExistenceError``     a condition the method needs does not hold for this plant
``SolverError``        a numerical solver failed; ``CertificateError``: a design
                       failed its verification against an independent truth
``MonteCarloError``    a Monte Carlo run failed twice, or its workers could not
                       be reached
``InternalError``      a bug in fdisyn: an invariant that should hold did not
=====================  ==============================================================

Every exception names what is wrong and what was expected, so that a user can
act on the message alone; the command line prints it as one line and exits
with status 2 (3 for an ``InternalError``). They also subclass the built-in
exception a caller would naturally catch (``ValueError`` for bad values, shapes
and files, ``RuntimeError`` for solver failures, ``OSError`` for compiling).
"""

from __future__ import annotations


class FdisynError(Exception):
    """Base class of every fdisyn exception."""


class ArgumentError(FdisynError, ValueError):
    """A keyword argument or option has a wrong value or type.

    The message names the argument, the value given and what is expected.
    """


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


class CertificateError(SolverError):
    """A design failed its verification against an independent truth.

    A design that fails its certificate is an error, never a warning.
    """


class FileError(FdisynError, ValueError):
    """A file fdisyn reads is missing, corrupt, foreign or invalid, or a path it writes cannot be
    written; the message names the file and the place."""


class GainFileError(FileError):
    """A gain file is corrupt, of a foreign format or of another version."""


class TraceError(FileError):
    """A data trace (CSV or array) is malformed: missing column, bad header."""


class SpecError(FileError):
    """A plant specification (TOML file or problem name) is invalid.

    Only the plant-file reader and the problem lookup raise it; a bad value
    given in Python is an :class:`ArgumentError`, which the reader re-raises
    as a ``SpecError`` naming the file and the key.
    """


class BuildError(FileError, OSError):
    """Compiling or loading generated C failed."""


class MonteCarloError(FdisynError, RuntimeError):
    """A Monte Carlo run failed again when retried (the message names the scenario, the run, its seed and the
    error), or the processes or Dask scheduler meant to run it could not be reached."""


class NominalValueError(ArgumentError):
    """A model parameter has no (finite) nominal value.

    The nonlinear adaptive fault-detection filter (Zhou, Xi & Zhang, Shanghai
    Jiao Tong University, c. 1991) runs its EKF on
    the nominal model, so every parameter ``θ_i`` needs one. The message names
    the parameters without a value and the ones that were given.
    """


class NonDifferentiableError(ArgumentError):
    """A model expression uses an operation without a derivative everywhere.

    Every Jacobian and parameter sensitivity of a nonlinear plant comes from
    automatic differentiation; ``abs``, ``min``/``max``, comparisons,
    ``floor``, ``if_else`` and the like have kinks or jumps where the
    linearisation is undefined. The message names the operation and where it
    occurs.
    """


class InternalError(FdisynError, RuntimeError):
    """An invariant of fdisyn itself did not hold: a bug to report, not a user error."""
