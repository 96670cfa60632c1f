"""The Monitor: stream inputs and outputs through a diagnoser, sample by sample.

Typical use in a deployment script::

    mon = Monitor.from_directory(".fdisyn/wind_turbine/kalman_uio")
    for u, y in stream:
        d = mon.update(u, y)
        if d.alarm:
            print(d.time, "fault:", d.fault)

It runs the compiled C step when the directory holds one (``fdisyn codegen``),
else the NumPy reference of a linear gain file. The gain file is read with
:func:`read_gain_file` (validated; a failed certificate is refused) and a
library is loaded only if it was built from exactly that gain file (see
:mod:`fdisyn.runtime.compiled`); ``u``, ``y``, ``U`` and ``Y`` are checked
by the backend with the same rules and messages for both.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Literal, cast

import numpy as np
from fdisyn.runtime.compiled import CompiledDiagnoser, library_path
from fdisyn.runtime.errors import ArgumentError, BuildError
from fdisyn.runtime.gainfile import GainFile, read_gain_file
from fdisyn.runtime.names import shown
from fdisyn.runtime.reference import ChangeEstimate, LinearReference, RunResult, glr_estimates

__all__ = ["BACKENDS", "Verdict", "Monitor", "fault_label"]


@dataclass(frozen=True)
class Verdict:
    """What the diagnoser says about one sample (:meth:`Monitor.update`).

    Attributes
    ----------
    time : float
        The sample's time in seconds since the first sample (``samples × Ts``).
    alarm : bool
        A fault is detected.
    isolated : int
        Index of the isolated fault in the gain file's ``faults``; −1 when none is isolated.
    fault : str or None
        Name of the isolated fault (``None``: no alarm, or detected but not isolated).
    J : numpy.ndarray
        The statistics, one per ``step.statistic_names``.
    r : numpy.ndarray
        The residuals, one per ``step.residual_names``.
    skipped : bool
        The sample held a non-finite value and was skipped where it mattered.
    fault_label : str or None
        The isolated fault's readable name from the gain file's ``signals.labels`` (``"rotor speed sensor"`` style
        text the design's plant gave its signals; a fault of several signals joins theirs with `` + `` or `` | ``,
        a signal without a label keeps its name); ``None`` when :attr:`fault` is.
    """

    time: float
    alarm: bool
    isolated: int
    fault: str | None
    """Name of the isolated fault (``None``: no alarm, or detected but not isolated)."""
    J: np.ndarray
    r: np.ndarray
    skipped: bool
    """The sample held a non-finite value and was skipped where it mattered."""
    fault_label: str | None = None
    """The isolated fault's readable name (the gain file's labels; its name where it has none)."""


def fault_label(fault: str | None, labels: Mapping[str, str]) -> str | None:
    """The readable name of ``fault`` (a fault name of a gain file): each signal's label, joined as the name joins them.

    Parameters
    ----------
    fault : str or None
        A fault name: signal names joined by ``+`` (at once) or ``|`` (classes not told apart).
    labels : Mapping of str to str
        A readable name per signal (a gain file's ``signals.labels``); a signal without one keeps its name.

    Returns
    -------
    str or None
        ``None`` for ``None``; ``fault`` itself when no signal of it has a label.
    """
    if fault is None:
        return None
    # a fault name is signal names and the operators + and | between them (fdisyn.runtime.names)
    parts = re.split(r"([+|])", fault)
    return "".join(f" {p} " if p in ("+", "|") else labels.get(p, p) for p in parts)


BACKENDS = ("auto", "compiled", "reference")
"""What runs the step: ``"compiled"`` the C library, ``"reference"`` the NumPy reference, ``"auto"`` the library when there is one."""


Backend = Literal["auto", "compiled", "reference"]


def _backend(backend: object) -> Backend:
    if isinstance(backend, str) and backend in BACKENDS:
        return cast(Backend, backend)
    raise ArgumentError(f"backend = {shown(backend)}: expected 'auto', 'compiled' or 'reference'")


class Monitor:
    """Runs one diagnoser over a stream; keeps its state and counts bad samples.

    Build one with :func:`fdisyn.load` (a folder written by ``fdisyn export``), :meth:`from_directory`, or from
    a :class:`~fdisyn.runtime.gainfile.GainFile` (the constructor).

    Attributes
    ----------
    gf : GainFile
        The diagnoser it runs.
    backend : {"compiled", "reference"}
        What runs the step: the C library or the NumPy reference.
    state : numpy.ndarray
        The step's state after the last sample.
    samples : int
        Samples processed since the last :meth:`reset`.
    skipped_samples : int
        Of those, the samples that held a non-finite value.
    units, labels : dict of str to str
        The unit and the readable name of each signal the gain file describes (its optional ``signals`` block:
        inputs, outputs and component faults; empty without it), e.g. ``mon.units["omega_r"] == "rad/s"``.

    Examples
    --------
    >>> mon = fdisyn.load("motor")  # doctest: +SKIP
    >>> v = mon.update(u, y)  # doctest: +SKIP
    >>> v.alarm, v.fault  # doctest: +SKIP
    (False, None)
    """

    def __init__(self, gf: GainFile, *, library: str | Path | None = None, backend: Literal["auto", "compiled", "reference"] = "auto") -> None:
        """Run ``gf`` by ``backend``.

        Parameters
        ----------
        gf : GainFile
            The diagnoser.
        library : str or Path, optional
            The compiled library built from ``gf`` (``fdisyn codegen``).
        backend : {"auto", "compiled", "reference"}
            ``"auto"``: the library when one is given, else the NumPy reference.

        Raises
        ------
        ArgumentError
            ``backend`` is none of the three (it is never guessed), or a ``library`` is given with
            ``backend="reference"`` (it would not run).
        BuildError
            ``"compiled"`` without a library, or a library not built from ``gf``.
        """
        backend = _backend(backend)
        if not isinstance(gf, GainFile):
            raise ArgumentError(
                f"Monitor takes a GainFile (fdisyn.load or fdisyn.design gives one), got {type(gf).__name__}; "
                "for a folder written by fdisyn export or fdisyn codegen use Monitor.from_directory(path)"
            )
        if backend == "reference" and library is not None:
            raise ArgumentError(
                f"library = {shown(str(library))} with backend = 'reference': the NumPy reference runs no library; "
                "give backend = 'compiled' (or 'auto') to run it, or leave library out"
            )
        self.gf = gf
        if backend == "reference" or (backend == "auto" and library is None):
            self.impl: CompiledDiagnoser | LinearReference = LinearReference(gf)
        else:
            if library is None:
                raise BuildError("backend='compiled' needs the path of the compiled library")
            self.impl = CompiledDiagnoser(library, gf)
        self.backend = "reference" if isinstance(self.impl, LinearReference) else "compiled"
        self.units = gf.units
        self.labels = gf.labels
        self.reset()

    @classmethod
    def from_directory(cls, directory: str | Path, *, backend: Literal["auto", "compiled", "reference"] = "auto") -> Monitor:
        """Load ``DIR/gains.json`` and, if present, ``DIR/lib<name>.so``.

        A library that was not built from this very ``gains.json`` (or that
        changed since it was built) raises :class:`BuildError` saying to run
        ``fdisyn codegen DIR``; it is never run, nor silently replaced by the
        reference.

        Parameters
        ----------
        directory : str or Path
            A folder written by ``fdisyn export`` or ``fdisyn codegen``.
        backend : {"auto", "compiled", "reference"}
            ``"auto"``: the library when the folder holds one, else the NumPy reference.

        Returns
        -------
        Monitor
            At its initial state.

        Raises
        ------
        ArgumentError
            ``backend`` is none of the three (before anything is read).
        GainFileError
            ``gains.json`` is missing or not a valid gain file.
        BuildError
            The library was not built from this ``gains.json``, or ``"compiled"`` and there is none.
        """
        backend = _backend(backend)
        d = Path(directory)
        gf = read_gain_file(d / "gains.json")
        lib = library_path(d, gf)
        if backend == "compiled" or (backend == "auto" and lib.exists()):
            return cls(gf, library=lib, backend="compiled")
        return cls(gf, backend="reference")

    def reset(self) -> None:
        """Back to the initial state (as after ``<prefix>_init``)."""
        self.state = self.impl.init_state()
        self.samples = 0
        self.skipped_samples = 0

    def update(self, u: np.ndarray, y: np.ndarray) -> Verdict:
        """Process one sample.

        Parameters
        ----------
        u : numpy.ndarray
            The ``nu`` inputs of this sample (real numbers; checked by the backend, never coerced).
        y : numpy.ndarray
            The ``ny`` outputs of this sample.

        Returns
        -------
        Verdict
            What the diagnoser says about the sample.

        Raises
        ------
        ArgumentError
            ``u`` or ``y`` does not hold real numbers.
        ShapeError
            ``u`` or ``y`` is not a vector of ``nu`` (``ny``) entries.
        """
        out = self.impl.step(self.state, u, y)
        t = self.samples * self.gf.Ts
        self.samples += 1
        self.skipped_samples += out.status
        iso = int(out.isolated)
        return Verdict(
            time=t,
            alarm=bool(out.alarm),
            isolated=iso,
            fault=self.gf.faults[iso] if iso >= 0 else None,
            J=out.J,
            r=out.r,
            skipped=bool(out.status),
            fault_label=fault_label(self.gf.faults[iso], self.labels) if iso >= 0 else None,
        )

    def change_estimates(self) -> list[ChangeEstimate]:
        """Each GLR statistic's most likely fault class, onset and size now (:func:`glr_estimates`)."""
        return glr_estimates(self.gf, self.state)

    def run(self, U: np.ndarray, Y: np.ndarray) -> RunResult:
        """Process a whole block of samples, continuing from the current state.

        Parameters
        ----------
        U : numpy.ndarray
            The inputs, one row per sample (``N × nu``).
        Y : numpy.ndarray
            The outputs, one row per sample (``N × ny``).

        Returns
        -------
        RunResult
            The residuals, statistics, alarms and isolated faults of every sample, and the final state.

        Raises
        ------
        ArgumentError
            ``U`` or ``Y`` does not hold real numbers.
        ShapeError
            ``U`` or ``Y`` does not have ``nu`` (``ny``) columns, or they differ in rows.
        """
        res = self.impl.run(U, Y, state=self.state)
        self.state = res.state
        self.samples += len(res.alarm)
        self.skipped_samples += res.nonfinite_samples
        return res
