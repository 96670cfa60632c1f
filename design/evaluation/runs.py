"""What a chunk of Monte Carlo runs gives: every design's outputs over the runs, and the runs' signals.

Both ways of running a chunk give it: the Python simulator and the diagnosers'
C steps (:func:`fdisyn.evaluation.campaign.simulate_and_diagnose`), and the
fused C library (:mod:`fdisyn.evaluation.compiled_campaign`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from fdisyn.simulation.problem import Batch

__all__ = ["DesignRuns", "ChunkRuns"]


@dataclass(frozen=True, eq=False)
class DesignRuns:
    """One design's outputs over a chunk of ``R`` runs of ``N`` samples."""

    r: np.ndarray
    """``(R, N, nr)`` float64."""
    J: np.ndarray
    """``(R, N, nj)`` float64."""
    alarm: np.ndarray
    """``(R, N)`` bool: the step's alarm output (any statistic)."""
    isolated: np.ndarray
    """``(R, N)`` int32, −1: none."""
    status: np.ndarray
    """``(R, N)`` int8, 1: a sample with a non-finite input."""


@dataclass(frozen=True, eq=False)
class ChunkRuns:
    """A chunk of runs of one scenario: their seeds, the sample times and every design's outputs."""

    seeds: tuple[int, ...]
    t: np.ndarray
    designs: Mapping[str, DesignRuns]
    batch: Batch | None
    """The simulated ``U``, ``Y`` and extra signals of these runs, when asked for (figures, examples)."""
