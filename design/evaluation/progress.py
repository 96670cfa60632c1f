"""Progress bars of the long steps (designing, compiling, the Monte Carlo): one helper, in one place.

A bar (tqdm) shows the count, the rate and the time left on stderr. It stays
quiet when stderr is not a terminal (a log file, a test, CI) and everywhere
after :func:`set_quiet` (``fdisyn --quiet``).
"""

from __future__ import annotations

import sys
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar

T = TypeVar("T")

__all__ = ["bar", "tracked", "set_quiet", "quiet", "note", "phase", "phase_seconds", "peak_memory_bytes"]

_QUIET = [False]


def set_quiet(value: bool = True) -> None:
    """No progress bar from now on (``value=False``: bars again where stderr is a terminal)."""
    _QUIET[0] = bool(value)


def quiet() -> bool:
    """Whether bars are off: :func:`set_quiet`, or stderr is not a terminal."""
    return _QUIET[0] or not (hasattr(sys.stderr, "isatty") and sys.stderr.isatty())


def note(text: str) -> None:
    """One line ``text`` on stderr, a terminal or not, unless :func:`set_quiet` (``fdisyn --quiet``): what a long
    step is about to do, where a bar would be too late or is not drawn.

    Parameters
    ----------
    text : str
        The line, without its line break.
    """
    if not _QUIET[0]:
        print(text, file=sys.stderr, flush=True)


@contextmanager
def bar(total: int | None, desc: str, unit: str = "it", *, shown: bool = True) -> Iterator[Any]:
    """A progress bar of ``total`` steps named ``desc``; ``.update(n)`` advances it, ``.set_postfix_str(s)`` says
    what it is at. Quiet (a bar that draws nothing) as :func:`quiet` says, or when not ``shown``."""
    from tqdm import tqdm

    off = quiet() or not shown
    with tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, disable=off, dynamic_ncols=True, mininterval=0.5) as b:
        yield b


def tracked(items: Iterable[T], desc: str, unit: str = "it") -> Iterator[T]:
    """``items`` one by one, behind a bar named ``desc`` (quiet as :func:`quiet` says)."""
    seq = list(items)
    with bar(len(seq), desc, unit) as b:
        for item in seq:
            b.set_postfix_str(str(item))
            yield item
            b.update(1)


_PHASES: dict[tuple[str, str], float] = {}
"""Seconds spent per (problem, phase) in this process, each phase's own time (its nested phases' excluded)."""
_OPEN: list[list[float]] = []
"""The phases running: ``[start, nested seconds]``, innermost last."""


@contextmanager
def phase(problem: str, name: str) -> Iterator[None]:
    """Time one phase of the main job (design, generate and compile, …) of ``problem``; a phase opened inside
    another is counted for itself only. Read with :func:`phase_seconds`.

    Parameters
    ----------
    problem : str
        The problem's name.
    name : str
        The phase.
    """
    import time

    entry = [time.perf_counter(), 0.0]
    _OPEN.append(entry)
    try:
        yield
    finally:
        _OPEN.remove(entry)
        elapsed = time.perf_counter() - entry[0]
        key = (problem, name)
        _PHASES[key] = _PHASES.get(key, 0.0) + elapsed - entry[1]
        if _OPEN:
            _OPEN[-1][1] += elapsed


def phase_seconds() -> dict[tuple[str, str], float]:
    """The seconds of every (problem, phase) timed so far in this process (:func:`phase`).

    Returns
    -------
    dict
        ``(problem, phase) → seconds``.
    """
    return dict(_PHASES)


def peak_memory_bytes() -> tuple[int, int]:
    """The largest resident memory of this process and of its finished child processes (compilers, workers) so far,
    in bytes (``(0, 0)`` where the platform does not say).

    Returns
    -------
    tuple of int
        ``(this process, largest child)``.
    """
    try:
        import resource
    except ImportError:  # pragma: no cover - Windows
        return 0, 0
    unit = 1 if sys.platform == "darwin" else 1024  # ru_maxrss: bytes on macOS, KiB elsewhere
    return (int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * unit,
            int(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss) * unit)
