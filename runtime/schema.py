"""The gain file's format: its version, the statistic kinds it knows and its size and magnitude limits.

These constants are what :mod:`fdisyn.runtime.gainfile` reads and writes against, what
:mod:`fdisyn.runtime.validate` checks and what the design side sizes its designs by.
"""

from __future__ import annotations

from collections.abc import Mapping

from fdisyn.runtime.statistics import STATISTICS

__all__ = [
    "FORMAT",
    "FORMAT_FAMILY",
    "MATRIX_KEYS",
    "EVALUATOR_KINDS",
    "SEQUENTIAL_KINDS",
    "LIMITS",
    "SCALAR_STEP_LIMITS",
    "ACCOUNT_FORMAT",
    "ACCOUNT_EFFECTS",
    "MAX_MAGNITUDE",
    "UNIT_MAX",
    "SIGNAL_LABEL_MAX",
]

FORMAT = "fdisyn.gains/1"
"""The gain file format this fdisyn reads and writes."""
FORMAT_FAMILY = "fdisyn.gains/"
"""The prefix every version of the format shares (a file of another version is named as such)."""
MATRIX_KEYS = ("Ar", "Bu", "By", "Cr", "Du", "Dy", "Xu", "Xy")
"""A generator's matrices, in the order the file and the step list them (:class:`~fdisyn.runtime.gainfile.Generator`)."""
EVALUATOR_KINDS = tuple(STATISTICS)
"""The statistics a linear diagnoser evaluates (:class:`~fdisyn.runtime.gainfile.Evaluator`; one entry each of
:data:`~fdisyn.runtime.statistics.STATISTICS`)."""
SEQUENTIAL_KINDS = tuple(k for k, s in STATISTICS.items() if s.sequential)
"""Statistics that accumulate evidence over time (:class:`~fdisyn.runtime.gainfile.Evaluator`): their alarm holds until the evidence is gone."""

LIMITS: Mapping[str, int] = {
    # every kind
    "inputs": 256,
    "outputs": 256,
    "faults": 256,
    "step_outputs": 1024,
    "file_bytes": 64 * 1024 * 1024,
    # linear kind
    "generators": 64,
    "generator_states": 1024,
    "nstate": 32_768,
    "residuals": 1024,
    "plant_states": 2048,
    "unknown_inputs": 256,
    "coefficients": 1_000_000,
    "warmup_coefficients": 5_000_000,
    "isolation_coefficients": 1_000_000,
    "persistence": 10**9,
}
"""Size limits of a gain file, checked by the reader before anything costly.

A linear diagnoser's step is written as loops over constant tables once it is
large (:func:`fdisyn.synthesis.linear_step.linear_step_function`): its C then
grows with the step's operations, its coefficients are ``static const`` data,
and gcc's time with both. Measured on 2 cores: a bank of ten 100-state
generators on 20 sensors (166 480 coefficients, 2 059 state entries) gives
82 KB of code beside 12 MB of tables and compiles in 5 s; the turbofan's GLR
(86 615 coefficients, 11 533 state entries) in 7 s with its design. The
limits are those of what the step must hold and the machine must run:
``coefficients`` — the nonzero entries of every generator's ``Ar Bu By Cr Du
Dy Xu Xy`` and every evaluator's ``W`` — ≤ 10⁶ (8 MB of tables, ~10⁶
multiply-adds per sample); ``warmup_coefficients`` — the warm-ups' gains and
corrections (:func:`fdisyn.runtime.warmup.warmup_coefficients`), dense, read
one sample's worth at a time — ≤ 5·10⁶ (40 MB); ``nstate`` ≤ 32 768 keeps the
step's copy of the state on the stack at 256 KiB (the whole frame is bounded
by :data:`fdisyn.codegen.library.STACK_LIMIT_BYTES`); ``generator_states`` ≤
1 024 bounds the stability check (an eigenvalue problem per generator); the
signal, fault, generator and residual counts (``step_outputs``: residual and
statistic names of any kind) bound the name tables and the replay program's
stack arrays; ``file_bytes`` bounds what the reader parses at all.
``persistence`` ≤ 10⁹ consecutive exceedances: the step counts them in a
double, and beyond 2⁵³ a count no longer grows, so a larger one could never
alarm (10⁹, like the NAFDF's sample counters, is 11 days of samples at 1 kHz).
Other kinds add their own limits to their payload; a kind whose step is
straight-line code keeps :data:`SCALAR_STEP_LIMITS`."""

SCALAR_STEP_LIMITS: Mapping[str, int] = {
    "nstate": 2048,
    "plant_states": 512,
    "coefficients": 10_000,
    "warmup_coefficients": 50_000,
}
"""Size limits of a diagnoser whose step is one multiply-add per coefficient in straight-line code (the Beard
filter's): gcc -O2's memory grows by ~45 kB per coefficient (measured on a 2-core machine shared with other
jobs: 4 974 coefficients took 11 s and 0.20 GB, 9 774 took 14–16 s and 0.44 GB), and the state's copy on the
stack stays at 16 KiB."""

ACCOUNT_FORMAT = 1
"""Format of a gain file's optional ``account`` block (what the design can see; see :func:`~fdisyn.runtime.validate.validate_account`)."""
ACCOUNT_EFFECTS = ("zero", "transient", "persistent")
"""A fault's effect on a residual in the ``account`` block: none, its onset only (zero steady-state gain), or lasting."""

MAX_MAGNITUDE = 1e150
"""Largest magnitude of a number in a gain file's matrices and numeric fields (every kind's payload too).

The reader's consistency checks multiply the file's numbers: ``(I − Ar) Xu − Bu``, ``‖Ar‖·‖Xu‖``,
``A − L C`` and its equilibrium solve, ``UᵀU`` of an axis basis. A product of two entries is at most
10³⁰⁰; a sum of them over an inner dimension the :data:`LIMITS` allow (at most 2048) at most ~2·10³⁰³,
and the Frobenius norm of a matrix of at most 2048 × 2048 such sums ~4·10³⁰⁶: below the largest double
(1.8·10³⁰⁸), so no check can overflow to ``inf`` and pass (``gap ≤ tol·inf``). Designed files hold
numbers far below it (the committed designs: at most ~10¹⁰)."""

UNIT_MAX = 32
"""Longest unit of a signal (``"rad/s"``, ``"N·m"``), in characters: a plant's ``units`` and a gain file's
``signals.units``."""
SIGNAL_LABEL_MAX = 80
"""Longest readable name of a signal (``"rotor speed"``, without its unit), in characters: a plant's ``labels`` and a
gain file's ``signals.labels`` (one line of a table or a legend)."""
