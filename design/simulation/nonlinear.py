"""Simulation of a nonlinear plant (Zhou, Xi & Zhang 1991, eq. (2.1)) with Gaussian noise.

``x(k+1) = f(x(k), u(k), θ(k)) + v(k)``, ``y(k) = h(x(k), θ(k)) + e(k)`` of a
:class:`~fdisyn.models.nonlinear.NonlinearPlant`, ``v ~ N(0, Q)``,
``e ~ N(0, R)``; its one-sample form is
:func:`fdisyn.simulation.sample_models.nonlinear_sample_model`, which reads the
same draws. :func:`simulate_nonlinear_runs` gives a scenario's runs as a batch.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import casadi as ca
import numpy as np
from fdisyn.models.nonlinear import NonlinearPlant
from fdisyn.numerics.linalg import as_vector
from fdisyn.runtime.errors import ArgumentError, ShapeError
from fdisyn.simulation.problem import Batch, Scenario
from fdisyn.simulation.signals import Signal

__all__ = ["kept_variables", "noise_factor", "simulate_nonlinear", "simulate_nonlinear_runs"]


def noise_factor(cov: np.ndarray) -> np.ndarray:
    """``F`` with ``F Fᵀ = cov`` (square; a singular ``cov`` is fine: eigen-factor, not Cholesky).

    Parameters
    ----------
    cov : numpy.ndarray
        A covariance matrix.

    Returns
    -------
    numpy.ndarray
        The square factor.
    """
    w, vecs = np.linalg.eigh(cov)
    return vecs * np.sqrt(np.clip(w, 0.0, None))[None, :]


def _gaussian(rng: np.random.Generator, cov: np.ndarray, count: int, z: np.ndarray | None = None) -> np.ndarray:
    """``count`` samples of ``N(0, cov)`` (rows), from ``rng`` or the given standard normals ``z``."""
    return (rng.standard_normal((count, cov.shape[0])) if z is None else z) @ noise_factor(cov).T


def simulate_nonlinear(
    plant: NonlinearPlant,
    *,
    x0: object,
    u: object,
    theta: object | None = None,
    rng: np.random.Generator,
    draws: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Simulate ``T`` samples of ``plant`` with Gaussian noise.

    Parameters
    ----------
    plant : NonlinearPlant
        The plant.
    x0 : array_like
        ``x[0]`` (n entries).
    u : array_like
        The inputs, ``(T, m)`` (``(T,)`` for one input).
    theta : array_like, optional
        The parameters: ``(l,)`` (constant) or ``(T, l)``, where row ``k`` is the parameter of the transition
        ``x(k) → x(k+1)`` (a fault at ``k_f`` first shows in ``y(k_f + 1)``); default the nominal ones.
    rng : numpy.random.Generator
        Draws the noise unless ``draws`` is given.
    draws : numpy.ndarray, optional
        ``T × (n + p)`` standard normals replacing those drawn from ``rng`` (``v``'s, then ``e``'s, per sample): the
        draws of the compiled simulation, to compare the two on the same noise.

    Returns
    -------
    tuple of numpy.ndarray
        ``(x, y)``, shapes ``(T, n)`` and ``(T, p)``: ``x[k]`` and ``y[k] = h(x[k], θ(k)) + e[k]`` are the state and
        measurement at sample ``k``.

    Raises
    ------
    ShapeError
        ``u``, ``theta``, ``x0`` or ``draws`` of the wrong shape.
    """
    uu = np.asarray(u, dtype=float)
    if uu.ndim == 1 and plant.m == 1:
        uu = uu[:, None]
    if uu.ndim != 2 or uu.shape[1] != plant.m:
        raise ShapeError(f"u has shape {uu.shape}; expected (T, {plant.m})")
    T = uu.shape[0]
    th = plant.theta_nominal if theta is None else np.asarray(theta, dtype=float)
    if th.ndim == 1:
        th = np.broadcast_to(th, (T, plant.l))
    if th.shape != (T, plant.l):
        raise ShapeError(f"theta has shape {th.shape}; expected ({plant.l},) or ({T}, {plant.l})")
    x0v = as_vector(x0, "x0", plant.n)
    if draws is not None and np.shape(draws) != (T, plant.n + plant.p):
        raise ShapeError(f"draws have shape {np.shape(draws)}; expected ({T}, {plant.n + plant.p})")
    v = _gaussian(rng, plant.Q, T, None if draws is None else draws[:, : plant.n])
    e = _gaussian(rng, plant.R, T, None if draws is None else draws[:, plant.n :])
    xs = ca.SX.sym("x", plant.n)
    drive = ca.SX.sym("drive", plant.m + plant.l + plant.n)
    step = ca.Function(
        "plant_transition",
        [xs, drive],
        [plant.f(xs, drive[: plant.m], drive[plant.m : plant.m + plant.l]) + drive[plant.m + plant.l :]],
    )
    # x(k+1) for k = 0..T-2, by one accumulated map over the whole horizon (fast, no Python loop)
    drives = np.hstack([uu, th, v]).T
    xnext = np.array(step.mapaccum(max(T - 1, 1))(x0v, drives[:, : max(T - 1, 1)]), dtype=float)
    x = np.vstack([x0v[None, :], xnext.T[: T - 1]])
    thx = ca.SX.sym("thx", plant.l)
    meas = ca.Function("plant_measurement", [xs, thx], [plant.h(xs, thx)]).map(T)
    y = np.array(meas(x.T, th.T), dtype=float).T + e
    return x, y


def kept_variables(plant: NonlinearPlant, extra: Mapping[str, str] | None) -> dict[str, str]:
    """The kept signals of a nonlinear simulation, checked: each name to a state or a parameter of ``plant``.

    Parameters
    ----------
    plant : NonlinearPlant
        The plant.
    extra : mapping of str to str, optional
        Each kept signal's name to the state or parameter it is.

    Returns
    -------
    dict of str to str
        The same map.

    Raises
    ------
    ArgumentError
        A kept signal that is neither a state nor a parameter.
    """
    keep = dict(extra or {})
    unknown = sorted(set(keep.values()) - set(plant.states) - set(plant.parameters))
    if unknown:
        raise ArgumentError(f"kept signals {unknown} are neither states {list(plant.states)} nor parameters {list(plant.parameters)}")
    return keep


def simulate_nonlinear_runs(
    plant: NonlinearPlant,
    scenario: Scenario,
    seeds: Sequence[int],
    *,
    x0: object,
    drive: Callable[[Scenario], tuple[np.ndarray | None, np.ndarray]],
    Ts: float,
    extra: Mapping[str, str] | None = None,
    signals: Sequence[Signal] | None = None,
    draws: np.ndarray | None = None,
) -> Batch:
    """The runs of ``scenario``, one per seed, by :func:`simulate_nonlinear`: the batch a problem's simulator gives.

    The arguments are those of :func:`fdisyn.simulation.sample_models.nonlinear_sample_model`, which simulates the
    same runs one sample at a time.

    Parameters
    ----------
    plant : NonlinearPlant
        The plant.
    scenario : Scenario
        The scenario.
    seeds : sequence of int
        One run per seed, each from its own generator.
    x0 : array_like
        The initial state of every run.
    drive : callable
        ``drive(scenario) → (u, θ)``: the inputs (N × m; ``None`` with ``signals``) and the parameters (N × l; row
        ``k`` drives ``x(k) → x(k+1)``), the same for every run.
    Ts : float
        The sample time (the batch's times are ``k·Ts``).
    extra : mapping of str to str, optional
        The kept signals: each name to a state or a parameter of the plant.
    signals : sequence of Signal, optional
        One per input: the inputs drawn per run (before the run's noise) instead of ``drive``'s.
    draws : numpy.ndarray, optional
        runs × N × nz standard normals replacing the generators' draws, laid out per sample as ``[v (n), e (p), one
        per prbs or gauss_markov signal]``: those of the compiled simulation.

    Returns
    -------
    Batch
        The runs.

    Raises
    ------
    ShapeError
        The drive, ``x0`` or ``draws`` of the wrong shape.
    ArgumentError
        A kept signal that is neither a state nor a parameter, or no inputs (neither ``drive``'s nor ``signals``).
    """
    keep = kept_variables(plant, extra)
    u_given, theta = drive(scenario)
    theta = np.asarray(theta, dtype=float)
    n = len(theta)
    t = np.arange(n) * Ts
    # the draws of a sample: the plant's v and e, then one per random input signal
    slots = np.cumsum([plant.n + plant.p] + [s.random for s in signals or ()])
    if signals is None and u_given is None:
        raise ArgumentError("a nonlinear simulation needs the drive's inputs or one signal per input; got neither")
    U: list[np.ndarray] = []
    Y, X = [], []
    for i, seed in enumerate(seeds):
        rng = np.random.default_rng(int(seed))
        given = None if draws is None else draws[i]
        if u_given is not None and signals is None:
            u = u_given
        else:
            assert signals is not None
            zs = [None if given is None or slots[j + 1] == slots[j] else given[:, slots[j]] for j in range(len(signals))]
            u = np.column_stack([s.sample(t, rng, Ts, z) for s, z in zip(signals, zs, strict=True)]) if plant.m else np.zeros((n, 0))
        x, y = simulate_nonlinear(plant, x0=x0, u=u, theta=theta, rng=rng, draws=None if given is None else given[:, : plant.n + plant.p])
        U.append(u)
        Y.append(y)
        X.append(x)
    kept = {}
    for name, var in keep.items():
        if var in plant.states:
            kept[name] = np.stack([x[:, plant.states.index(var)] for x in X])
        else:
            kept[name] = np.tile(theta[:, plant.parameters.index(var)], (len(seeds), 1))
    return Batch(scenario, tuple(int(s) for s in seeds), t, plant.inputs, plant.outputs, np.stack(U), np.stack(Y), kept)
