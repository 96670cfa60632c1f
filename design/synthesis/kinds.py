"""What a diagnoser kind means: the step contract every kind's step honours.

Contract (shared by every diagnoser kind, and by the generated C)::

    step(state[nstate], u[nu], y[ny]) -> (state_next[nstate], r[nr], J[nj],
                                          alarm[1], isolated[1], status[1])

all dense double vectors; ``alarm`` ∈ {0, 1}; ``isolated`` ∈ {−1, 0..nf−1};
``status`` 1 when the sample held a non-finite value (see
:mod:`fdisyn.runtime.reference` for the linear semantics).
"""

from __future__ import annotations

__all__ = ["STEP_INPUTS", "STEP_OUTPUTS"]

STEP_INPUTS = ("state", "u", "y")
STEP_OUTPUTS = ("state_next", "r", "J", "alarm", "isolated", "status")
