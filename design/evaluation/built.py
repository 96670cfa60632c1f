"""A built diagnoser: designed, its gain file written, its C generated, compiled and loaded.

The Monte Carlo (:mod:`fdisyn.evaluation.campaign`, its compiled form
:mod:`fdisyn.evaluation.compiled_campaign`) runs built diagnosers; a worker
process loads them again from their folders (:func:`load_built`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fdisyn.codegen.library import CodegenResult, codegen
from fdisyn.runtime.compiled import CompiledDiagnoser, library_path
from fdisyn.evaluation.progress import phase
from fdisyn.runtime.errors import GainFileError
from fdisyn.runtime.gainfile import GainFile, gain_file_sha256, read_gain_file, without_clock, write_gain_file
from fdisyn.runtime.names import DIAGNOSER_NAME_MAX
from fdisyn.simulation.problem import Problem

__all__ = ["Built", "build", "load_built", "threshold_copies"]


@dataclass(frozen=True, eq=False)
class Built:
    """A designed, written and compiled diagnoser (a threshold copy: its sources, compiled on first use)."""

    gain_file: GainFile
    directory: Path
    artifacts: CodegenResult
    loaded: CompiledDiagnoser | None = None
    """The compiled step once loaded (:attr:`diagnoser`); ``None`` until then."""

    @property
    def diagnoser(self) -> CompiledDiagnoser:
        """The compiled step, loaded on first use. A diagnoser built with its sources only
        (:func:`threshold_copies`: the compiled Monte Carlo compiles them into its own library) is compiled then,
        in ``directory`` (:func:`~fdisyn.codegen.library.codegen` with ``reuse``)."""
        if self.loaded is None:
            lib = self.artifacts.library
            if not lib.is_file():
                lib = codegen(self.directory, reuse=True).library
            object.__setattr__(self, "loaded", CompiledDiagnoser(lib, self.gain_file))
        assert self.loaded is not None
        return self.loaded


def build(problem: Problem, design: str, directory: str | Path, **options: Any) -> Built:
    """Design, write ``DIR/gains.json``, generate and compile the C, load it.

    A design equal to the one ``DIR`` already holds but for its date and solver durations
    (:func:`~fdisyn.runtime.gainfile.without_clock`) keeps that gain file, and its build where this fdisyn and
    compiler would make the same (:func:`~fdisyn.codegen.library.codegen` with ``reuse``): a second run of the main
    job compiles only what changed.
    """
    d = Path(directory)
    with phase(problem.name, "design"):
        gf = problem.design(design, **options)
    old = _same_design(d / "gains.json", gf)
    with phase(problem.name, "generate and compile"):
        if old is None:
            write_gain_file(gf, d / "gains.json")
        else:
            gf = old
        art = codegen(d, reuse=old is not None)
    built = Built(gain_file=gf, directory=d, artifacts=art)
    built.diagnoser  # loaded now: a build that cannot load fails here, not in the Monte Carlo
    return built


def _same_design(path: Path, gf: GainFile) -> GainFile | None:
    """The gain file at ``path`` when it is ``gf`` but for its clock (:func:`~fdisyn.runtime.gainfile.without_clock`),
    else ``None`` (none there, unreadable, or another design)."""
    if not path.is_file():
        return None
    try:
        old = read_gain_file(path)
    except (OSError, GainFileError):
        return None
    return old if gain_file_sha256(without_clock(old)) == gain_file_sha256(without_clock(gf)) else None


def load_built(directory: str | Path) -> Built:
    """The :class:`Built` that :func:`build` left in ``directory`` (gain file and compiled library, loaded again)."""
    d = Path(directory)
    gf = read_gain_file(d / "gains.json")
    lib = library_path(d, gf)
    art = CodegenResult(directory=d, c_dir=d / "c", header=d / "c" / f"{gf.name}.h", library=lib, replay=d / "replay")
    return Built(gain_file=gf, directory=d, artifacts=art)


def threshold_copies(
    built: Mapping[str, Built], directory: str | Path, scales: Sequence[float] | None = None, *, sources_only: bool = True
) -> dict[str, dict[float, Built]]:
    """Each design's copies with its thresholds scaled, built beside it, for the designs whose operating
    characteristic does not follow from one run's statistics and whose kind makes such copies
    (:attr:`fdisyn.synthesis.kinds.DiagnoserKind.threshold_scaled`; a NAFDF restarts its learning after an alarm).

    Parameters
    ----------
    built : Mapping of str to Built
        The designs.
    directory : str or Path
        Where the copies are built: ``DIR/<design>/<k>`` for the ``k``-th scale.
    scales : sequence of float, optional
        The scales (default :data:`~fdisyn.evaluation.metrics.COPY_SCALES`); 1, the design itself, is not copied.
    sources_only : bool
        Generate each copy's C without compiling its own library (default): the compiled Monte Carlo compiles it
        into the campaign's library, and a copy's :attr:`Built.diagnoser` compiles it on first use (the Python path).
        ``False``: compile every copy now.

    Returns
    -------
    dict
        ``{design: {scale: Built}}`` for the designs copied (the others left out).
    """
    from fdisyn.evaluation.metrics import COPY_SCALES, operating_plan
    from fdisyn.synthesis.kinds import get_kind

    out: dict[str, dict[float, Built]] = {}
    for name, b in built.items():
        gf = b.gain_file
        scaled = get_kind(gf.kind).threshold_scaled
        if scaled is None or operating_plan(gf, float(gf.Ts)) is not None:
            continue
        copies = {}
        for k, s in enumerate(COPY_SCALES if scales is None else scales):
            if float(s) == 1.0:
                continue
            d = Path(directory) / name / str(k)
            suffix = f"_x{k}"  # the copy's C prefix: the design's, cut to leave room (DIAGNOSER_NAME_MAX)
            copy = scaled(gf, float(s), gf.name[: DIAGNOSER_NAME_MAX - len(suffix)].rstrip("_") + suffix)
            old = _same_design(d / "gains.json", copy)
            if old is None:
                write_gain_file(copy, d / "gains.json")
            else:
                copy = old
            art = codegen(d, reuse=old is not None, sources_only=sources_only)
            copies[float(s)] = Built(gain_file=copy, directory=d, artifacts=art)
        out[name] = copies
    return out
