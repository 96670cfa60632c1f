"""Each input-signal kind and sensor-fault kind is described once (fdisyn.simulation.signals): its NumPy evaluation
(the Python simulators) and its CasADi evaluation (the sample models, compiled into the C Monte Carlo) give the same
numbers to the last bit, on seeded random parameters and draws, but where CasADi's simplifier folds the constants of
``c·(k·Ts)`` into ``(c·Ts)·k`` (sine, square): there the CasADi value is the NumPy expression so associated, bit for
bit, and the NumPy value itself within rounding."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from fdisyn.runtime.errors import ArgumentError
from fdisyn.simulation.signals import (
    SENSOR_FAULT_TABLE,
    SIGNAL_TABLE,
    SensorFaultSpec,
    Signal,
    apply_sensor_faults,
    faulty_measurement_sx,
    sensor_fault_map,
    signal_sx,
)

SAMPLES = 400
CASES = 25


FOLDED = {
    "sine": lambda sig, k, ts: sig.offset + sig.amplitude * np.sin((2 * np.pi * ts) * k / sig.period),
    "square": lambda sig, k, ts: sig.offset + sig.amplitude * np.where(np.floor((2.0 * ts) * k / sig.period + 1e-9) % 2 == 0, 1.0, -1.0),
}
"""The kinds whose CasADi expression CasADi reassociates (``t = k·Ts`` is a symbol times a constant), and the NumPy
expression in CasADi's association."""


def _casadi_run(sig: Signal, ts: float, z: np.ndarray) -> np.ndarray:
    """The signal sample by sample through its CasADi expression, the memory carried as a sample model carries it."""
    k, zz, mem = ca.SX.sym("k"), ca.SX.sym("z"), ca.SX.sym("m")
    value, nxt = signal_sx(sig, k * ts, k, ts, zz, mem) if sig.random else (signal_sx(sig, k * ts, k, ts, None, None)[0], None)
    fn = ca.Function("signal", [k, zz, mem], [value, mem if nxt is None else nxt])
    out, memory = np.empty(len(z)), 0.0
    for i in range(len(z)):
        v, memory = fn(float(i), z[i], memory)
        out[i] = float(v)
    return out


def _random_signal(kind: str, rng: np.random.Generator, ts: float) -> Signal:
    return Signal(kind, offset=float(rng.normal(0, 3)), amplitude=float(rng.normal(0, 2)),
                  period=float(ts * rng.uniform(1.0, 80.0)), start=float(ts * rng.uniform(0, SAMPLES)))


@pytest.mark.parametrize("kind", list(SIGNAL_TABLE))
def test_every_signal_kind_is_the_same_number_in_numpy_and_casadi(kind: str) -> None:
    rng = np.random.default_rng(20261128)
    for _ in range(CASES):
        ts = float(rng.choice([1e-3, 0.01, 0.1, 1.0]))
        sig = _random_signal(kind, rng, ts)
        z = rng.standard_normal(SAMPLES)
        t = np.arange(SAMPLES) * ts
        want = sig.sample(t, np.random.default_rng(0), ts, z if sig.random else None)
        got = _casadi_run(sig, ts, z)
        if kind in FOLDED:
            np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * (abs(sig.offset) + abs(sig.amplitude)))
            want = FOLDED[kind](sig, np.arange(SAMPLES, dtype=float), ts)
        assert np.array_equal(got, want), (sig, np.flatnonzero(got != want)[:5])


def test_a_random_signal_draws_one_normal_per_sample_and_the_others_none() -> None:
    assert [k for k, v in SIGNAL_TABLE.items() if v.random] == ["prbs", "gauss_markov"]
    assert {k for k, v in SIGNAL_TABLE.items() if v.periodic} == {"sine", "square", "prbs", "gauss_markov"}
    with pytest.raises(ArgumentError, match="positive period"):
        Signal("square", period=0.0)
    with pytest.raises(ArgumentError, match="not one of"):
        Signal("triangle")
    with pytest.raises(ArgumentError, match="finite"):
        signal_sx(Signal("sine", amplitude=np.inf), ca.SX.sym("t"), ca.SX.sym("k"), 0.1, None, None)


def _casadi_faults(y: np.ndarray, rows: np.ndarray, t: float, onset: float) -> np.ndarray:
    p = y.shape[1]
    ys, par, ts, on = ca.SX.sym("y", 1, p), ca.SX.sym("p", 5, p), ca.SX.sym("t"), ca.SX.sym("on")
    fn = ca.Function("faulty", [ys, par, ts, on], [faulty_measurement_sx(ys, *(par[i, :] for i in range(5)), ts, on)])
    return np.vstack([np.array(fn(row[None, :], rows, t, onset)).reshape(-1) for row in y])


@pytest.mark.parametrize("kind", list(SENSOR_FAULT_TABLE))
def test_every_sensor_fault_kind_is_the_same_number_in_numpy_and_casadi(kind: str) -> None:
    """One fault of the kind on a random output: the NumPy corruption in place and the affine map it composes into."""
    rng = np.random.default_rng(1128)
    outputs = ("a", "b", "c")
    for _ in range(CASES):
        y = rng.normal(0, 10, (6, len(outputs)))
        onset = float(rng.uniform(0, 5))
        t = onset + float(rng.uniform(0, 10))
        fault = SensorFaultSpec(str(rng.choice(outputs)), kind, float(rng.normal(0, 3)))
        want = y.copy()
        apply_sensor_faults(want, outputs, [fault], since_onset=t - onset)
        got = _casadi_faults(y, sensor_fault_map([fault], outputs, lambda f: float(f.value)), t, onset)
        assert np.array_equal(got, want), fault


def test_composed_sensor_faults_agree_within_rounding() -> None:
    """Several faults on one sensor compose in order (a gain after an offset scales it); the composed map reorders
    the products, so the two agree to rounding, not bit for bit."""
    rng = np.random.default_rng(7)
    outputs = ("a", "b")
    for _ in range(CASES):
        y = rng.normal(0, 10, (4, 2))
        faults = [SensorFaultSpec(str(rng.choice(outputs)), str(rng.choice(list(SENSOR_FAULT_TABLE))), float(rng.normal(1, 1)))
                  for _ in range(3)]
        want = y.copy()
        apply_sensor_faults(want, outputs, faults, since_onset=2.5)
        got = _casadi_faults(y, sensor_fault_map(faults, outputs, lambda f: float(f.value)), 3.0, 0.5)
        np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-12)


def test_a_fault_on_no_output_is_refused_in_both() -> None:
    fault = SensorFaultSpec("x", "offset", 1.0)
    with pytest.raises(ArgumentError, match="no such output"):
        apply_sensor_faults(np.zeros((1, 1)), ("a",), [fault])
    with pytest.raises(ArgumentError, match="no such output"):
        sensor_fault_map([fault], ("a",), lambda f: f.value)
    with pytest.raises(ArgumentError, match="not one of"):
        SensorFaultSpec("a", "noise", 1.0)
