"""The public Python API: ``fdisyn.design``, ``fdisyn.export``, ``fdisyn.load``, ``fdisyn.methods``.

::

    plant = fdisyn.LinearPlant.from_control(sys, n_unknown=1, Q=Q, R=R)
    gf = fdisyn.design(plant, method="kalman_uio", P_f=1e-4)   # a certified GainFile
    fdisyn.export(gf, "motor")                                  # what `fdisyn codegen` builds
    mon = fdisyn.load("motor")                                  # a Monitor over the compiled step
    fdisyn.methods()                                            # the registered method names

Each function is what a command of the command line does, from Python:
``design`` is ``fdisyn design`` on a plant object (through the method
registry, :mod:`fdisyn.synthesis.registry`), ``export`` writes ``gains.json``
and runs ``fdisyn codegen`` on it, ``load`` is
:meth:`fdisyn.runtime.monitor.Monitor.from_directory`. The design side is
imported when ``design``, ``export`` or ``methods`` is first called, so
``load`` needs only the runtime.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Literal

from fdisyn.runtime.errors import ArgumentError, FileError
from fdisyn.runtime.gainfile import GainFile, write_gain_file
from fdisyn.runtime.monitor import Monitor

__all__ = ["design", "export", "load", "methods"]


def design(plant: Any, method: str, *, name: str | None = None, **options: Any) -> GainFile:
    """Design a diagnoser for ``plant`` with a registered ``method``; a certified :class:`GainFile`.

    Parameters
    ----------
    plant : LinearPlant, SampledDataPlant or NonlinearPlant
        The plant to diagnose (the method says which kinds of plant it takes).
    method : str
        A registered design method (:func:`methods`; ``fdisyn methods NAME`` describes one).
    name : str, optional
        The diagnoser's name, the prefix of its C API (a C identifier); default: the method's.
    **options
        The method's options (``fdisyn methods NAME`` lists them, with their defaults), e.g. ``P_f``.

    Returns
    -------
    GainFile
        The diagnoser, its certificate passed.

    Raises
    ------
    ArgumentError
        An unknown method or option, or a value outside its domain.
    ExistenceError
        A plant the method cannot design for (the message names the condition that fails).
    CertificateError
        A design that fails its verification.

    Examples
    --------
    >>> gf = fdisyn.design(plant, method="kalman_uio", P_f=1e-4)  # doctest: +SKIP
    >>> gf.faults  # doctest: +SKIP
    ('y0', 'y1', 'y2')
    """
    from fdisyn.synthesis.registry import design as registry_design

    return registry_design(plant, method, name=name, **options)


def methods() -> list[str]:
    """The names of the registered design methods.

    Returns
    -------
    list of str
        The names :func:`design` takes as ``method``.
    """
    from fdisyn.synthesis.registry import method_names

    return list(method_names())


def export(gf: GainFile, directory: str | Path) -> Path:
    """Write ``gf`` to ``directory`` as ``fdisyn codegen`` builds it; return the directory.

    ``DIR/gains.json``, the C sources in ``DIR/c/``, the shared library
    ``DIR/lib<name>.so`` with its build manifest and the replay program
    ``DIR/replay``. The generated step is checked against the gain file before
    it is written (see :mod:`fdisyn.codegen.library`).

    Parameters
    ----------
    gf : GainFile
        The diagnoser (from :func:`design` or ``read_gain_file``).
    directory : str or Path
        The folder to build in: an existing folder, or one that can be created.

    Returns
    -------
    Path
        ``directory``.

    Raises
    ------
    ArgumentError
        ``gf`` is not a gain file, or ``directory`` is not a path.
    FileError
        ``directory`` cannot be written: an existing file, a place that cannot hold a folder (``/proc``), a
        folder without write permission, or ``gains.json`` in it a folder (the message names the path).
    BuildError
        The C compiler failed.
    """
    from fdisyn.codegen.library import codegen

    if not isinstance(gf, GainFile):
        raise ArgumentError(f"gf must be a GainFile (from fdisyn.design or read_gain_file); got {type(gf).__name__}")
    if not isinstance(directory, (str, Path)):
        raise ArgumentError(f"directory must be a path (str or pathlib.Path); got {type(directory).__name__}")
    d = Path(directory)
    _writable_folder(d)
    try:
        write_gain_file(gf, d / "gains.json")
    except OSError as exc:
        raise FileError(f"cannot write {d / 'gains.json'}: {exc.strerror or exc}; expected a folder fdisyn can write in") from exc
    codegen(d)
    return d


def _writable_folder(d: Path) -> None:
    """Refuse an export folder that cannot be written, naming the path, what is wrong and what to give instead."""
    remedy = "give fdisyn.export a folder you can write in (it is created if missing)"
    if d.exists() and not d.is_dir():
        raise FileError(f"export folder {d} is a file; {remedy}")
    try:
        d.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise FileError(f"cannot create the export folder {d}: {exc.strerror or exc}; {remedy}") from exc
    if (d / "gains.json").is_dir():
        raise FileError(f"{d / 'gains.json'} is a folder, where the diagnoser's gain file goes; remove it or {remedy}")
    if not os.access(d, os.W_OK | os.X_OK):
        raise FileError(f"export folder {d} is not writable; {remedy}")


def load(directory: str | Path, *, backend: Literal["compiled", "reference", "auto"] = "compiled") -> Monitor:
    """The :class:`Monitor` of the diagnoser that :func:`export` (or ``fdisyn codegen``) built in ``directory``.

    It runs the compiled library (``backend="compiled"``), loaded only if it
    was built from that very ``gains.json``; ``"reference"`` runs the NumPy
    reference of a linear gain file instead, ``"auto"`` the library when there
    is one. ``mon.update(u, y)`` returns a :class:`~fdisyn.runtime.monitor.Verdict`
    (``.alarm``, ``.fault``, ``.isolated``, ``.J``, ``.r``, ``.time``).

    Parameters
    ----------
    directory : str or Path
        A folder written by :func:`export` or ``fdisyn codegen``.
    backend : {"compiled", "reference", "auto"}
        What runs the step: the C library, the NumPy reference, or the library when there is one.

    Returns
    -------
    Monitor
        The diagnoser at its initial state.

    Raises
    ------
    ArgumentError
        ``backend`` is none of the three.
    GainFileError
        ``DIR/gains.json`` is missing or not a valid gain file.
    BuildError
        The library is missing (``"compiled"``) or was not built from that ``gains.json``.

    Examples
    --------
    >>> mon = fdisyn.load("motor")  # doctest: +SKIP
    >>> mon.update([0.0], [0.0, 0.0]).alarm  # doctest: +SKIP
    False
    """
    if backend not in ("compiled", "reference", "auto"):
        raise ArgumentError(f"backend must be 'compiled', 'reference' or 'auto'; got {backend!r}")
    return Monitor.from_directory(directory, backend=backend)
