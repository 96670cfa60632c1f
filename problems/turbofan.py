"""Turbofan sensor FDI with generalised UIO banks (Long & Wang, Aeroengine 43(5), 2017).

Long & Wang, "A promoted design approach for unknown input observer",
Aeroengine 43(5), 2017, pp. 7–13; section, equation and figure numbers below
are theirs. A 12-state linear model of a two-spool turbofan at sea-level
static (H = 0 km, Ma = 0), states ``T4, P4, T48, P48, T17, P17, T25, P25,
T7, P7, N2, N1``; inputs ``T_BV`` (HPC bleed valve angle), ``V_BV``
(variable bleed valve area), ``V_SV`` (variable stator vane angle), ``W_f``
(fuel flow); outputs ``T3, P25, P3, P13, T42, N2, N1, T5, T25`` with a
feedthrough ``D``. ``rank C = 8 < 9``: the outputs are linearly dependent,
so a UIO bank must be built on groups of independent outputs (section 2).

**Transcription.** The paper prints ``A`` in 3×3 blocks of 4×4, ``B`` as
three 4×4 blocks, ``C`` as three 9×4 blocks and ``D``; the extracted text
splits digits across columns and loses rows. Every legible number is kept;
every guessed entry is in :data:`TRANSCRIPTION` (position, printed text, value
chosen, why). Numbers split by the extraction are joined; where joining gives
more than the paper's four significant digits, the repeated digit at the split
is dropped. Three placements in ``C`` are reconstructions, chosen as the
fewest moved lines that reproduce the paper's structural facts (``rank C = 8``;
the last eight and the first eight outputs, each completed by the virtual
outputs ``T17, T48, T7, T4``, give full-rank 12×12 matrices), the tie broken
by the sensors of the spool speeds reading the states of those names.

**Stand-in truth.** The paper's data come from a nonlinear engine model that
is not available. :func:`simulate_truth` is the design model with three
documented mismatches — the unknown input the UIOs must ignore: a fuel-metering
actuator lag, and quadratic torque terms on both spools (the curvature of the
compressor and turbine maps in spool speed). See :data:`TRUTH`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg
from fdisyn.models.linear import LinearPlant

__all__ = [
    "STATES",
    "INPUTS",
    "OUTPUTS",
    "A",
    "B",
    "C",
    "D",
    "TRANSCRIPTION",
    "PAPER_GROUPS",
    "PAPER_VIRTUAL",
    "TS",
    "TRUTH",
    "design_model",
    "simulate_truth",
]

STATES = ("T4", "P4", "T48", "P48", "T17", "P17", "T25", "P25", "T7", "P7", "N2", "N1")
INPUTS = ("T_BV", "V_BV", "V_SV", "W_f")
OUTPUTS = ("T3", "P25", "P3", "P13", "T42", "N2", "N1", "T5", "T25")

# fmt: off
A = np.array([
    # T4        P4          T48      P48       T17       P17      T25       P25       T7       P7      N2        N1
    [-2.060,    -1.629,     0,       0,        0.03948,  0,       19.81,    -20.95,   0,       0,      0,        0.5640],
    [-0.1483,   -1.793,     0,       0,        0.004503, 0,       -6.907,   8.619,    0,       0,      0,        -0.05254],
    [0.0002146, 0.0001451,  -8.359,  -0.2320,  0.5197,   0.2146,  0.05018,  -0.04557, 0.4826,  0,      -0.01829, 0.001434],
    [0.001615,  0.001029,   -9.60,   -2.563,   0.1007,   1.956,   -0.08216, 0.1620,   0.7306,  0,      -0.04499, 0.009433],
    [11.67,     13.39,      21.60,   0,        -75.10,   -25.44,  17.56,    -16.01,   0,       0,      2.009,    0.7235],
    [2.167,     43.79,      9.782,   0,        -7.999,   -80.76,  -28.38,   41.20,    0,       0,      0.9096,   0.3733],
    [0.01503,   0,          0,       0,        0,        0,       -22.43,   8.441,    0,       0,      1.253,    -0.2544],
    [0.008857,  0,          0,       0,        0,        0,       -8.766,   -3.887,   0,       0,      0.823,    -0.1499],
    [0,         0,          0,       0,        0,        0,       0,        0,        -35.12,  -1.086, 0.6808,   0],
    [0,         0,          0,       0,        0,        0,       0,        0,        -17.21,  -4.314, 0.4066,   0],
    [0.7357,    -0.5766,    -12.17,  0,        3.095,    2.376,   0.8145,   -2.597,   -11.83,  0,      -1.798,   0.03973],
    [5.028,     3.660,      0,       0,        -10.90,   0,       -55.31,   73.81,    0,       0,      0,        -2.482],
])
"""Long & Wang 2017, section 2: ``A = [[A11, A12, A13], [A21, A22, A23], [A31, A32, A33]]``."""

B = np.array([
    # T_BV    V_BV     V_SV      W_f
    [0,       -538.6,  37.20,    3022],
    [0,       439.7,   -7.876,   1688],
    [0,       9.296,   0.09515,  4.479],
    [0,       -5.254,  -5.254,   25.94],
    [0,       2600,    40.59,    869.2],
    [0,       -7061,   -15.28,   1916],
    [-11377,  -2.156,  -20.07,   0],
    [-6902,   -1.270,  -11.83,   0],
    [418.4,   0,       0,        0],
    [280.6,   0,       0,        0],
    [31.59,   438.3,   3.497,    10.22],
    [0,       202.4,   -136.3,   125.8],
])
"""Long & Wang 2017, section 2: ``B = [B1; B2; B3]`` (printed ``[B1 B2 B3]ᵀ``: the blocks stacked)."""

C = np.array([
    # T4        P4         T48     P48    T17      P17     T25      P25      T7  P7      N2        N1
    [0,         0,         0,      0,     0,       0,      1,       0,       0,  0,      0,        0.02969],   # T3
    [0.05723,   0,         0,      0,     0,       0,      1.831,   -1.955,  0,  0,      0,        0],         # P25
    [0,         0,         0,      0,     0,       0,      0,       0,       0,  0,      0,        0.04786],   # P3
    [0.9473,    0,         0,      0,     0.3789,  0,      -0.5295, 0.7093,  0,  0.9904, 0.002922, 0],         # P13
    [-0.04513,  0.5522,    0,      0,     0,       0,      0,       0,       0,  0,      0,        0.000665],  # T42
    [0,         0,         0,      0,     0,       0,      0,       0,       0,  0,      1,        0],         # N2
    [0.0005893, 0.0003696, 1.365,  0,     -0.3104, 0.7474, -0.0722, 0.1054,  0,  0,      0,        1],         # N1
    [0,         0,         -1.037, 1.704, 0,       0,      0,       0,       0,  0,      -0.00791, -0.00056],  # T5
    [0,         0,         0,      0,     0,       0,      1,       0,       0,  0,      0,        0],         # T25
])
"""Long & Wang 2017, section 2: ``C = [C1 C2 C3]``, rows placed as :data:`TRANSCRIPTION` states."""

D = np.array([
    [0,      -8.252,  0.1998,   0],
    [0,      0,       0,        0],
    [0,      -1385.9, 3.292,    0],
    [1.767,  0,       0,        0],
    [0,      -120.0,  -0.4913,  22.22],
    [0,      0,       0,        0],
    [0,      0,       0,        0],
    [0,      -8.825,  -0.08256, 8.752],
    [0,      0,       0,        0],
])
"""Long & Wang 2017, section 2: the feedthrough ``D``."""
# fmt: on

TRANSCRIPTION: tuple[tuple[str, str, str, str], ...] = (
    ("A[T4, T4]", "-2.06 ó", "-2.060", "the last digit is unreadable; taken as 0"),
    ("A[T4, T48]", "(missing)", "0", "the first row of A11 prints three values for four entries; the lost one is taken as 0, like the T48 and P48 entries of the P4 row"),
    ("A[T4, T17]", "0.03948 3", "0.03948", "four significant digits; the trailing 3 does not repeat the digit before the split"),
    ("A[T48, P17]", "0.21 146", "0.2146", "repeated digit at the split dropped"),
    ("A[T48, T48]", "-8.359 9", "-8.359", "repeated digit at the split dropped"),
    ("A[T48, N1]", "0.0014 134", "0.001434", "repeated digit at the split dropped (as in A[P48, N1])"),
    ("A[P48, P17]", "1.95 56", "1.956", "repeated digit at the split dropped"),
    ("A[P48, N1]", "0.0094 133", "0.009433", "repeated digit at the split dropped"),
    ("A[P4, N1]", "-0.052 254", "-0.05254", "repeated digit at the split dropped"),
    ("A[T17, P17]", "-25.44 4", "-25.44", "repeated digit at the split dropped"),
    ("A[P17, P17]", "-80.76 6", "-80.76", "repeated digit at the split dropped"),
    ("A[P17, T25]", "-28.3 88", "-28.38", "repeated digit at the split dropped"),
    ("A[P25, T25]", "-8.76 66", "-8.766", "repeated digit at the split dropped"),
    ("A[N2, P4]", "-0.576 66", "-0.5766", "repeated digit at the split dropped"),
    ("B[T4, W_f]", "3022 2", "3022", "repeated digit at the split dropped"),
    ("B[P4, W_f]", "168 88", "1688", "repeated digit at the split dropped"),
    ("C[N1, P25]", "0 105 4 / 0.100 U", "0.1054", "the row is rendered twice; the first rendering keeps the fourth digit"),
    ("C[T42, P4]", "5522", "0.5522", "the leading '0.' is lost; the magnitude of the other C1 entries"),
    ("C[P13, P7]", "0.9904 0 0.00 2922 0", "0.9904 in the P7 column", "the garbled P13 row of C3 prints five tokens for four columns; in the T7 column, P7 would be measured by no sensor and neither completed group could have rank 12"),
    ("C rows of C1", "lines 1, 3, 4 and 9 at T3, P3, P13, T25", "at P25, P13, T42 and T5", "the extraction misplaces the zero lines of this block; the nonzero lines keep their printed order. As printed, P48 is read only by T25 (so the first eight outputs cannot complete to rank 12) and T42 is proportional to N2. T5 then reads T48 and P48, the LPT inlet"),
    ("C rows N2, N1 of C3", "[0 0 0 1] at N2, [0 0 1 0] at N1", "swapped", "the N2 and N1 sensors read the states of those names (the paper's state order ends N2, N1)"),
    ("C[T25, T25]", "(the C2 block prints 8 lines for 9 rows)", "1", "the lost line is the T25 sensor reading the T25 state; with it T3 = T25 + 0.6204 P3 exactly, the dependency that makes rank C = 8 and that both of the paper's groups break"),
)
"""Every guessed entry: (position, printed text, value chosen, why)."""

PAPER_GROUPS: tuple[tuple[str, ...], ...] = (OUTPUTS[1:], OUTPUTS[:8])
"""Long & Wang 2017, section 2: group 1 the last eight outputs, group 2 the first eight."""
PAPER_VIRTUAL: tuple[str, ...] = ("T17", "T48", "T7", "T4")
"""The virtual outputs of both groups (Long & Wang 2017, section 2)."""

TS = 0.02
"""Sample time (s) of the diagnoser: 50 Hz, a usual engine-control rate; the fastest mode (τ = 11 ms) is
sampled exactly (ZOH), so no accuracy is lost."""


@dataclass(frozen=True)
class Truth:
    """The stand-in for the paper's nonlinear engine model (what the UIOs see as the unknown input)."""

    fuel_lag: float = 0.08
    """Fuel-metering actuator time constant (s): the engine burns the lagged ``W_f``."""
    spool_curvature: tuple[float, float] = (0.12, 0.12)
    """``κ₂, κ₁``: the spool rows gain ``κ_i · N_i² / N_i,ref``, a torque-map curvature; ``N_i,ref`` the
    speed change of the throttle step (so at that step the mismatch is ``κ_i`` of the spool's own term)."""
    throttle_step: float = 0.1
    """The fuel-flow step (units of ``W_f``); the paper's throttle step, scaled to a 10 % transient."""
    noise_fraction: float = 0.005
    """Sensor noise standard deviation as a fraction of each output's steady-state change at the step."""
    sub_steps: int = 10
    """Integration steps per sample (the linear part exact, the quadratic terms held over Ts/10)."""


TRUTH = Truth()


def _sampled(a: np.ndarray, b: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    n, m = b.shape
    big = np.zeros((n + m, n + m))
    big[:n, :n], big[:n, n:] = a, b
    ed = scipy.linalg.expm(big * h)
    return ed[:n, :n], ed[:n, n:]


def steady_state_step(truth: Truth = TRUTH) -> tuple[np.ndarray, np.ndarray]:
    """The design model's steady state after the fuel step: states and outputs."""
    u = np.zeros(len(INPUTS))
    u[3] = truth.throttle_step
    x = -np.linalg.solve(A, B @ u)
    return x, C @ x + D @ u


def sensor_noise(truth: Truth = TRUTH) -> np.ndarray:
    """Standard deviation of each sensor's white noise."""
    _, y = steady_state_step(truth)
    return truth.noise_fraction * np.abs(y)


def design_model(E: np.ndarray | None = None, truth: Truth = TRUTH) -> LinearPlant:
    """The continuous design model with sensor noise ``R`` and unknown-input matrix ``E``; states are named
    ``x_T4`` … (the outputs ``P25, N2, N1, T25`` share the paper's state names)."""
    return LinearPlant.create(
        A=A, B=B, C=C, D=D, E=E, R=np.diag(sensor_noise(truth) ** 2),
        states=tuple(f"x_{s}" for s in STATES), inputs=INPUTS, outputs=OUTPUTS,
        unknown_inputs=None if E is None else tuple(f"d{i + 1}" for i in range(np.asarray(E).shape[1])),
    )


def simulate_truth(
    U: np.ndarray, seeds: Sequence[int], *, truth: Truth = TRUTH, faults: Sequence[Mapping[str, Any]] = (), t: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Runs of the stand-in engine: (``Y`` runs × N × 9, ``X`` runs × N × 12).

    ``U`` (``N × 4``) is held over each sample. Sensor faults (each
    ``{"sensor", "kind", "onset", "size"}``, kinds ``bias`` (offset ``size``),
    ``drift`` (``size`` per second), ``stuck`` (the reading frozen at onset),
    ``open_circuit`` (the reading falls to ``−size``: the sensor's zero, in
    deviation units)) corrupt the readings after the noise is added.
    """
    u = np.asarray(U, dtype=float)
    nsamp = u.shape[0]
    tt = np.arange(nsamp) * TS if t is None else t
    h = TS / truth.sub_steps
    n = len(STATES)
    # [x; w] with w the lagged fuel flow (ẇ = (u_Wf − w)/τ) and two held inputs q₂, q₁: the spool terms on the N2, N1 rows
    aa = np.zeros((n + 1, n + 1))
    aa[:n, :n] = A
    aa[:n, n] = B[:, 3]
    aa[n, n] = -1.0 / truth.fuel_lag
    bb = np.zeros((n + 1, 4))
    bb[:n, :3] = B[:, :3]
    bb[n, 3] = 1.0 / truth.fuel_lag
    phi, gam = _sampled(aa, np.hstack([bb, np.eye(n + 1)[:, [10, 11]]]), h)
    xs, _ = steady_state_step(truth)
    nref = np.abs(xs[[10, 11]])
    kap = np.asarray(truth.spool_curvature)
    spool_gain = np.array([A[10, 10], A[11, 11]])
    runs = len(seeds)
    x = np.zeros((runs, n + 1))
    X = np.empty((runs, nsamp, n))
    for k in range(nsamp):
        X[:, k] = x[:, :n]
        for _ in range(truth.sub_steps):
            q = -kap * spool_gain * x[:, [10, 11]] ** 2 / nref  # (runs, 2): the torque-map curvature
            x = x @ phi.T + u[k] @ gam[:, :4].T + q @ gam[:, 4:].T
    Y = X @ C.T + u @ D.T
    sd = sensor_noise(truth)
    for i, s in enumerate(seeds):
        Y[i] += np.random.default_rng(int(s)).standard_normal((nsamp, len(OUTPUTS))) * sd
    for f in faults:
        j = OUTPUTS.index(f["sensor"])
        on = tt >= f["onset"] - 1e-9
        if f["kind"] == "bias":
            Y[:, on, j] += f["size"]
        elif f["kind"] == "drift":
            Y[:, on, j] += f["size"] * (tt[on] - f["onset"])
        elif f["kind"] == "stuck":
            k0 = int(np.argmax(on))
            Y[:, on, j] = Y[:, [k0], j]
        elif f["kind"] == "open_circuit":
            Y[:, on, j] = -f["size"]
        else:
            raise ValueError(f"unknown sensor fault kind {f['kind']!r}")
    return Y, X
