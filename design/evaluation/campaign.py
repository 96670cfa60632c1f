"""A Monte Carlo campaign's results, one chunk of runs at a time."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from fdisyn.models.problem import Batch

__all__ = ["DesignRuns", "ChunkRuns"]


@dataclass(frozen=True, eq=False)
class DesignRuns:  # one design, a chunk of R runs of N samples
    r: np.ndarray  # (R, N, nr) float64
    J: np.ndarray  # (R, N, nj) float64
    alarm: np.ndarray  # (R, N) bool  (the step's alarm output, any statistic)
    isolated: np.ndarray  # (R, N) int32 (−1: none)
    status: np.ndarray  # (R, N) int8 (1: non-finite sample)


@dataclass(frozen=True, eq=False)
class ChunkRuns:
    seeds: tuple[int, ...]
    t: np.ndarray  # (N,)
    designs: Mapping[str, DesignRuns]
    batch: Batch | None  # the simulated U, Y, extra of these runs when asked for (figures, examples)
