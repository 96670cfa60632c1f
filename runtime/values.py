"""Real numbers as fdisyn reads them from files and callers: one rule everywhere.

A real number is an ``int`` or a ``float`` (NumPy's integer and floating
scalars included) and never a ``bool``: ``float()`` would also read the string
``"1.5"`` and ``True``, so a value of a plant file, a gain file or a setting
that is not a number is refused where it enters, never converted. An integer
beyond the double range reads as ±inf (where ``float()`` raises
``OverflowError``), so it fails a finite test like ``inf`` itself. Callers
word their own messages ("must be a number", "must be finite") from the two
outcomes.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["real_number"]


def real_number(value: object) -> float | None:
    """``value`` as a float if it is a real number (see the module docstring), else ``None``.

    The float may be ±inf or NaN; test it with ``math.isfinite`` where a finite number is required.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        return None
    try:
        return float(value)
    except OverflowError:  # an integer beyond the double range
        return math.inf if int(value) > 0 else -math.inf
