"""Where each part of a diagnoser's state lives: named blocks of the state vector.

A diagnoser's state is one float64 vector, the ``state[nstate]`` of its step
and of the generated C. A :class:`StateLayout` names its blocks in order,
each ``rows × cols`` and stored column-major (CasADi's order), so that the
runtime, the designs and the reports read the same entries by the same names:
the linear layout is :func:`linear_state_layout`, the
NAFDF's is written into its gain file (``extensions.nafdf.state_layout``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from fdisyn.runtime.errors import ShapeError
from fdisyn.runtime.statistics import STATISTICS

__all__ = ["StateLayout", "linear_state_layout"]


@dataclass(frozen=True)
class StateLayout:
    """Named blocks of a state vector, ``(name, rows, cols)`` in order; matrices stored column-major.

    ``scalars`` names the blocks that are counters or flags (unpacked as ``float``);
    every other block with one column unpacks as a 1-D array, even of length one.
    """

    entries: tuple[tuple[str, int, int], ...]
    scalars: frozenset[str] = frozenset()
    matrices: frozenset[str] = frozenset()
    """Blocks that unpack as 2-D arrays whatever their size (covariances, sensitivities, windows)."""

    @property
    def size(self) -> int:
        """Entries of the whole state vector (``nstate``)."""
        return sum(r * c for _, r, c in self.entries)

    def offsets(self) -> dict[str, tuple[int, int, int]]:
        """``name → (first entry, rows, cols)``."""
        out, k = {}, 0
        for name, r, c in self.entries:
            out[name] = (k, r, c)
            k += r * c
        return out

    def __getitem__(self, name: str) -> slice:
        """The entries of block ``name`` in the state vector."""
        k, r, c = self.offsets()[name]
        return slice(k, k + r * c)

    def unpack(self, vec: object) -> dict[str, np.ndarray | float]:
        """Split a state vector: scalars as float, columns as 1-D arrays, matrices as 2-D arrays."""
        v = np.asarray(vec, dtype=float).reshape(-1)
        if v.size != self.size:
            raise ShapeError(f"state has {v.size} entries; expected {self.size}")
        out: dict[str, np.ndarray | float] = {}
        for name, (k, r, c) in self.offsets().items():
            block = v[k : k + r * c]
            if name in self.scalars:
                out[name] = float(block[0])
            elif c == 1 and name not in self.matrices:
                out[name] = block.copy()
            else:
                out[name] = block.reshape((r, c), order="F").copy()
        return out

    def pack(self, values: Mapping[str, object]) -> np.ndarray:
        """Join named blocks into a state vector (every block required)."""
        missing = [name for name, _, _ in self.entries if name not in values]
        extra = sorted(set(values) - {name for name, _, _ in self.entries})
        if missing or extra:
            raise ShapeError(f"state blocks: missing {missing}, unknown {extra}")
        parts = []
        for name, r, c in self.entries:
            a = np.asarray(values[name], dtype=float)
            if a.size != r * c:
                raise ShapeError(f"state block {name!r} has {a.size} entries; expected {r}×{c}")
            parts.append(a.reshape((r, c)).reshape(-1, order="F") if a.ndim == 2 else a.reshape(-1))
        return np.concatenate(parts) if parts else np.zeros(0)

    def component_names(self) -> list[str]:
        """One name per entry: ``block`` for a scalar, ``block[i]`` for a column, ``block[i,j]`` for a matrix."""
        out = []
        for name, r, c in self.entries:
            if name in self.scalars:
                out.append(name)
            elif c == 1 and name not in self.matrices:
                out.extend(f"{name}[{i}]" for i in range(r))
            else:
                out.extend(f"{name}[{i},{j}]" for j in range(c) for i in range(r))
        return out


def linear_state_layout(generators: Sequence[Any], evaluators: Sequence[Any], decision: Any = None) -> StateLayout:
    """Where each part of a linear diagnoser's state vector lives.

    ``xi<g>``: generator ``g``'s state; ``counters``: one persistence counter
    per statistic; ``ready``: per generator, its valid samples since it started
    (0 until its first valid sample initialises it at equilibrium), counted up
    to its ``warmup`` + 1 — its statistics run from the sample after the
    ``warmup``-th, and a non-finite sample before then restarts it; ``nonfinite``: the number of
    samples that held a non-finite input or output; ``window<j>``: for each
    WSSR statistic ``j``, the ``q`` of its generator's last ``window`` valid
    samples, newest first (a shift register: each valid sample shifts it by
    one and writes ``q`` at the top; zeros not yet overwritten are the samples
    not seen yet, so ``J`` — the sum of the register — needs no fill count,
    and the step has no index arithmetic, which the symbolic step would spell
    out as one comparison per entry anyway); ``sequential<j>``: for each CUSUM
    statistic its sums ``S_i^+``, ``S_i^−`` then their latches (1 from crossing the
    threshold until the sum returns to 0), for each GLR statistic its onset sums ``d_i(n)``
    (hypothesis-major, ``n = 1 … M``). A sequential statistic's persistence
    counter holds its raised alarm (1) or 0. ``acc<g>``: for each generator with a
    warm-up, its accumulated ``Σ Φ_kᵀ W r_k`` (:mod:`fdisyn.runtime.warmup`). With a ``decision`` that isolates
    by the hypothesis test (:class:`~fdisyn.runtime.gainfile.Isolation`): ``evidence``, the exponentially
    weighted sum of the stacked residual in the test's coordinates, ``named``, the class the decision holds plus one (0: none, so a zero initial state names nothing), and ``age``,
    the samples the alarm has been raised, counted up to the test's ``settle``.
    """
    blocks = [(f"xi{g}", gen.n_state, 1) for g, gen in enumerate(generators)]
    blocks += [("counters", len(evaluators), 1), ("ready", len(generators), 1), ("nonfinite", 1, 1)]
    # each statistic's block, grouped by prefix in the order the table first names it (window, then sequential)
    stats = [STATISTICS.get(e.kind) for e in evaluators]
    for prefix in dict.fromkeys(s.block for s in STATISTICS.values() if s.block is not None):
        for j, (e, s) in enumerate(zip(evaluators, stats, strict=True)):
            rows = s.block_rows(e) if s is not None and s.block == prefix else None
            if rows is not None:
                blocks.append((f"{prefix}{j}", rows, 1))
    blocks += [(f"acc{g}", gen.n_state, 1) for g, gen in enumerate(generators) if getattr(gen, "warmup", 0)]
    scalars = {"nonfinite"}
    if decision is not None and getattr(decision, "isolation", None) is not None:
        blocks += [("evidence", int(np.asarray(decision.isolation.basis).shape[0]), 1), ("named", 1, 1), ("age", 1, 1)]
        scalars |= {"named", "age"}
    return StateLayout(tuple(blocks), scalars=frozenset(scalars))

