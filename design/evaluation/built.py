"""A built diagnoser: designed, its gain file written, its C generated, compiled and loaded.

The Monte Carlo (:mod:`fdisyn.evaluation.campaign`, its compiled form
:mod:`fdisyn.evaluation.compiled_campaign`) runs built diagnosers; a worker
process loads them again from their folders (:func:`load_built`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fdisyn.codegen.library import CodegenResult, codegen
from fdisyn.runtime.compiled import CompiledDiagnoser, library_path
from fdisyn.runtime.gainfile import GainFile, read_gain_file, write_gain_file
from fdisyn.simulation.problem import Problem

__all__ = ["Built", "build", "load_built"]


@dataclass(frozen=True, eq=False)
class Built:
    """A designed, written and compiled diagnoser."""

    gain_file: GainFile
    directory: Path
    artifacts: CodegenResult
    diagnoser: CompiledDiagnoser


def build(problem: Problem, design: str, directory: str | Path, **options: Any) -> Built:
    """Design, write ``DIR/gains.json``, generate and compile the C, load it."""
    d = Path(directory)
    gf = problem.design(design, **options)
    write_gain_file(gf, d / "gains.json")
    art = codegen(d)
    return Built(gain_file=gf, directory=d, artifacts=art, diagnoser=CompiledDiagnoser(art.library, gf))


def load_built(directory: str | Path) -> Built:
    """The :class:`Built` that :func:`build` left in ``directory`` (gain file and compiled library, loaded again)."""
    d = Path(directory)
    gf = read_gain_file(d / "gains.json")
    lib = library_path(d, gf)
    art = CodegenResult(directory=d, c_dir=d / "c", header=d / "c" / f"{gf.name}.h", library=lib, replay=d / "replay")
    return Built(gain_file=gf, directory=d, artifacts=art, diagnoser=CompiledDiagnoser(lib, gf))
