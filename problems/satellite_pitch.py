"""Satellite pitch axis with a solar array: actuator FDI with Beard's detection filter (He, Zhang & Wu, c. 1999).

He, Zhang & Wu, "the robust decision" for the Beard fault detection filter, Journal of Astronautics, c. 1999:
a satellite's pitch axis, body and solar array, whose two actuators (the pitch reaction wheel and the array
drive) a Beard filter detects and isolates by the direction of its residual. The paper's numbers were lost;
every number below is a stand-in chosen here, with its reason.

Design model (linearised, rigid), states ``x = [θ, φ, θ̇, φ̇]`` (pitch angle, array angle, both inertial; their
rates), inputs ``u = [T_y, T_p]`` (pitch wheel torque on the body, array drive torque between body and array):

    Js θ̈ = k (φ − θ) + b (φ̇ − θ̇) + T_y − T_p
    Jp φ̈ = k (θ − φ) + b (θ̇ − φ̇) + T_p,          y = x (C = I, D = 0)

with ``Js = 5 kg·m²``, ``Jp = 1 kg·m²``, coupling spring ``k = 0.15 N·m/rad``, damper ``b = 0.05 N·m·s/rad``
(the coupled mode: 0.42 rad/s, damping ratio 0.07). The component-fault directions are the columns of ``B``
(``pitch_wheel``, ``array_drive``). Sampled at ``Ts = 0.1 s`` (10 Hz: 75 samples per period of the coupled mode,
12 per period of the truth's flexible mode; the attitude controller runs at the same rate).

Truth (:func:`simulate`), what the design model leaves out:

* parameter error: ``Js, Jp, k, b`` each drawn per run uniformly within ±3 % (mass properties and a hinge's
  stiffness and damping known to a few per cent); ``‖A_true − A_model‖₂`` of the rigid part then lies in
  ``[0, 0.0141]`` (the corners of the box: :func:`model_error_range`), bounded by :data:`SIGMA` = 0.015;
* a second flexible mode of the array, a modal coordinate ``q`` coupled to the body,
  ``Js θ̈ + δ q̈ = …``, ``q̈ + 2 ζ_f ω_f q̇ + ω_f² q + δ θ̈ = 0``, ``ω_f = 2.5 rad/s`` (six times the coupled mode),
  ``ζ_f = 0.005`` (a lightly damped structure), ``δ = 0.5 kg^½·m`` (``δ²/Js`` = 5 % modal participation);
* small-angle nonlinearity: the spring torque ``k sin(φ − θ)`` and a drive friction
  ``τ_c tanh((φ̇ − θ̇)/ω_s)`` with ``τ_c = 5e-5 N·m``, ``ω_s = 1e-3 rad/s`` (near rest it doubles the damper);
* actuator limits: wheel torque ±0.02 N·m, drive torque ±0.01 N·m (ten and five times the largest steady
  command, so only a large transient reaches them); applied torque = ``(1 − κ)·sat(u)``;
* a constant disturbance torque ``T_d = 1e-3 N·m`` on the pitch axis (solar pressure and gravity gradient,
  the upper end of 1e-4…1e-3 N·m: the pitch wheel carries it as a steady torque);
* measurement noise, Gaussian per sample: 2e-5 rad on θ (star tracker), 5e-5 rad on φ (drive encoder),
  1e-5 rad/s on θ̇ (gyro), 5e-5 rad/s on φ̇ (drive tachometer).

Operating point and controller. The body holds an inertial pitch attitude ``θ_ref = 0`` (an inertially pointing
satellite), so the sun is fixed in the body frame over a run (it moves by 2e-7 rad/s) and sun tracking is a
hold of the array at the sun angle ``φ_ref = φ_c = 0.02 rad``. The rigid model's spring is neutral at
``φ = θ``, so the drive carries the steady torque ``k φ_c = 3e-3 N·m``. A drive law that winds the array
relative to the body at orbital rate (2π/5400 rad/s) was rejected: in this model it winds the coupling spring
(0.7 rad and 0.1 N·m over 600 s), and the parameter error of ``k`` and the ``sin`` nonlinearity then grow to
more than the faults. The attitude controller is discrete, at ``Ts``, on the measured outputs:
``T_y = −K_pθ θ − K_dθ θ̇`` (``K_pθ = 1.25``, ``K_dθ = 3.5``: ``Js ω²`` and ``2 ζ Js ω`` for ω = 0.5 rad/s,
ζ = 0.7) and ``T_p = k φ_c − K_pφ (φ − φ_c) − K_dφ φ̇`` (``K_pφ = 0.25``, ``K_dφ = 0.7``, with the spring
preload as feedforward). Started at rest, ``x = 0`` with the array at its spring's neutral, the drive
moves it to ``φ_c`` and the wheel takes up ``T_d``; the rates settle below the noise within 60 s. Scenarios
start at each run's own closed-loop equilibrium (:func:`steady_state`: a satellite already in normal mode), so
the diagnoser sees no start-up transient; ``Truth(start_at_rest=True)`` starts at rest.

Faults (component faults with the directions of ``B``): a torque loss of relative size κ of the pitch wheel
or the array drive, applied ``(1 − κ)·sat(u)``; the logged input is the commanded ``u``, so the fault enters
along its column of ``B`` with ``μ = −κ·sat(u)``. Onset at 300 s of a 600 s run (five times the settling
time; 300 s of faulty data). Why the pitch-wheel fault is the hard one: the wheel's steady torque is the
unmodelled disturbance ``−T_d``, which enters along the pitch-wheel direction itself, so a fault-free run
already carries a residual bias of a wheel "fault" ``T_d`` and a loss κ raises it to ``T_d/(1 − κ)`` (the
controller re-balances the torque). The default κ = 0.3 raises it by 43 %.

Truth integration: RK4 at ``Ts/5`` with the inputs held over the sample (ZOH), vectorised over runs
(runs × states). With no parameter error, flexible mode, nonlinearity, saturation or noise it reproduces the
exactly sampled design model to round-off (``‖A h‖ ≈ 0.01``: the RK4 step error ``‖A h‖⁵/120`` is below 1e-12).
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import casadi as ca
import numpy as np
import scipy.special
from fdisyn.simulation.sample_models import NAMES_IN, NAMES_OUT, SampleModel, clip_sx
from fdisyn.models.linear import LinearPlant
from fdisyn.simulation.problem import Batch, Problem, Scenario
from fdisyn.runtime.errors import ArgumentError
from fdisyn.runtime.gainfile import GainFile
from fdisyn.synthesis.registry import design as design_with

__all__ = [
    "PROBLEM",
    "NOMINAL",
    "TRUTH",
    "TS",
    "SIGMA",
    "DURATION",
    "ONSET",
    "KAPPA",
    "Rigid",
    "Truth",
    "rigid_matrices",
    "design_model",
    "model_error_range",
    "run_parameters",
    "fault_scenario",
    "fault_size_scenarios",
    "steady_state",
    "energy",
    "truth_derivative",
    "rk4_step",
    "simulate",
    "filter_residuals",
    "fault_free_levels",
    "explicit_levels",
]

TS = 0.1
"""Sample time (s) of the measurements, the controller and the diagnoser."""
DURATION = 600.0
"""Length of a run (s)."""
ONSET = 300.0
"""Fault onset (s): five times the 60 s the closed loop takes to settle from rest."""
KAPPA = 0.3
"""Default relative torque loss of the faulty actuator."""
STATES = ("theta", "phi", "theta_dot", "phi_dot")
OUTPUTS = ("theta_m", "phi_m", "theta_dot_m", "phi_dot_m")
INPUTS = ("T_y", "T_p")
FAULTS = ("pitch_wheel", "array_drive")


@dataclass(frozen=True)
class Rigid:
    """The rigid model's parameters: inertias (kg·m²), coupling spring (N·m/rad) and damper (N·m·s/rad)."""

    Js: float = 5.0
    Jp: float = 1.0
    k: float = 0.15
    b: float = 0.05


NOMINAL = Rigid()


def rigid_matrices(Js: Any, Jp: Any, k: Any, b: Any) -> tuple[np.ndarray, np.ndarray]:
    """``A`` (4 × 4) and ``B`` (4 × 2) of the rigid model (module docstring); arrays of parameters give stacks."""
    Js, Jp, k, b = (np.asarray(v, dtype=float) for v in (Js, Jp, k, b))
    shape = np.broadcast(Js, Jp, k, b).shape
    a = np.zeros((*shape, 4, 4))
    bb = np.zeros((*shape, 4, 2))
    a[..., 0, 2] = a[..., 1, 3] = 1.0
    a[..., 2, :] = np.stack(np.broadcast_arrays(-k / Js, k / Js, -b / Js, b / Js), axis=-1)
    a[..., 3, :] = np.stack(np.broadcast_arrays(k / Jp, -k / Jp, b / Jp, -b / Jp), axis=-1)
    bb[..., 2, 0], bb[..., 2, 1], bb[..., 3, 1] = 1.0 / Js, -1.0 / Js, 1.0 / Jp
    return a, bb


@dataclass(frozen=True)
class Truth:
    """What the simulation adds to the design model (module docstring); each part can be switched off."""

    parameter_error: float = 0.03
    """Relative half-width of the uniform per-run error of ``Js, Jp, k, b``."""
    flex_frequency: float = 2.5
    """ω_f (rad/s) of the array's second flexible mode."""
    flex_damping: float = 0.005
    """ζ_f of that mode."""
    flex_coupling: float = 0.5
    """δ (kg^½·m), its coupling to the body; 0: no flexible mode."""
    nonlinear: bool = True
    """``k sin(φ − θ)`` and the drive friction (else the linear spring and no friction)."""
    friction_torque: float = 5e-5
    """τ_c (N·m) of the drive friction ``τ_c tanh((φ̇ − θ̇)/ω_s)``."""
    friction_rate: float = 1e-3
    """ω_s (rad/s) of the drive friction."""
    wheel_limit: float | None = 0.02
    """Wheel torque saturation (N·m); ``None``: none."""
    drive_limit: float | None = 0.01
    """Drive torque saturation (N·m); ``None``: none."""
    disturbance: float = 1e-3
    """Constant disturbance torque on the pitch axis (N·m)."""
    noise: tuple[float, float, float, float] = (2e-5, 5e-5, 1e-5, 5e-5)
    """Measurement-noise standard deviations of θ, φ, θ̇, φ̇ per sample (rad, rad/s)."""
    cant: float = 0.02
    """Sun angle φ_c (rad) the drive holds the array at."""
    substeps: int = 5
    """RK4 steps per sample."""
    start_at_rest: bool = False
    """Start at rest (``x = 0``, the array at its spring's neutral) instead of at the run's own steady state."""

    @property
    def ideal(self) -> Truth:
        """The truth reduced to the design model: no parameter error, flexible mode, nonlinearity, limits or noise.

        The disturbance stays (zero it with ``replace``): it is a torque along the first column of ``B``."""
        return replace(self, parameter_error=0.0, flex_coupling=0.0, nonlinear=False, wheel_limit=None, drive_limit=None,
                       noise=(0.0, 0.0, 0.0, 0.0))


TRUTH = Truth()

GAINS = {"Kp_theta": 1.25, "Kd_theta": 3.5, "Kp_phi": 0.25, "Kd_phi": 0.7}
"""The attitude controller's PD gains (module docstring)."""

R_NOISE = np.diag(np.square(TRUTH.noise))


def design_model() -> LinearPlant:
    """The continuous rigid model with its fault directions ``Fx = B`` and the truth's measurement noise ``R``.

    ``Q = 0``: the truth has no random process noise (its model errors are deterministic, bounded by
    :data:`SIGMA` and estimated through the fault-free levels).
    """
    a, b = rigid_matrices(NOMINAL.Js, NOMINAL.Jp, NOMINAL.k, NOMINAL.b)
    return LinearPlant.create(
        A=a,
        B=b,
        C=np.eye(4),
        Fx=b,
        R=R_NOISE,
        states=STATES,
        inputs=INPUTS,
        outputs=OUTPUTS,
        component_faults=FAULTS,
        units={"theta": "rad", "phi": "rad", "theta_dot": "rad/s", "phi_dot": "rad/s", "T_y": "N·m", "T_p": "N·m",
               "theta_m": "rad", "phi_m": "rad", "theta_dot_m": "rad/s", "phi_dot_m": "rad/s"},
    )


def model_error_range(fraction: float = TRUTH.parameter_error) -> tuple[float, float]:
    """Smallest and largest ``‖A_true − A_model‖₂`` of the rigid part over the parameter box ``±fraction``.

    ``A_true`` is affine in each of ``1/Js``, ``1/Jp``, ``k``, ``b`` with the others fixed, and the norm is convex,
    so along each parameter the largest value is at an end of its interval: over the box it is at one of the
    16 corners. The smallest is 0 (the nominal point).
    """
    a0, _ = rigid_matrices(NOMINAL.Js, NOMINAL.Jp, NOMINAL.k, NOMINAL.b)
    worst = 0.0
    for s in itertools.product((-1.0, 1.0), repeat=4):
        p = [v * (1.0 + fraction * si) for v, si in zip((NOMINAL.Js, NOMINAL.Jp, NOMINAL.k, NOMINAL.b), s, strict=True)]
        a, _ = rigid_matrices(*p)
        worst = max(worst, float(np.linalg.norm(a - a0, 2)))
    return 0.0, worst


SIGMA = 0.015
"""Bound on ``‖δA‖₂`` (continuous units, 1/s² and 1/s) the designs assume: above the 0.0141 the ±3 % box reaches."""

DECAY_RATE = 0.5
"""Every eigenvalue of the filter inside ``|z| ≤ e^{−0.5·Ts}`` (0.951): a time constant of at most 2 s, five times
faster than the 0.42 rad/s coupled mode's period of 15 s, and slow enough not to pass the gyro noise unfiltered."""


def run_parameters(seeds: Sequence[int], truth: Truth = TRUTH, uniforms: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """The true ``Js, Jp, k, b`` of each run: the first four draws of its seed's generator, uniform on
    ``[−1, 1]`` (``uniforms``, runs × 4: given ones instead)."""
    if uniforms is None:
        draws = np.array([np.random.default_rng(int(s)).uniform(-1.0, 1.0, 4) for s in seeds]).reshape(-1, 4)
    else:
        draws = np.asarray(uniforms, dtype=float).reshape(-1, 4)
    return scaled_parameters(draws, truth)


def scaled_parameters(draws: Any, truth: Truth = TRUTH) -> dict[str, Any]:
    """``Js, Jp, k, b`` from their draws in ``[−1, 1]`` (runs × 4; a CasADi row for the compiled start)."""
    scale = 1.0 + truth.parameter_error * draws
    nominal = (NOMINAL.Js, NOMINAL.Jp, NOMINAL.k, NOMINAL.b)
    return {name: nominal[i] * scale[:, i] for i, name in enumerate(("Js", "Jp", "k", "b"))}


# --------------------------------------------------------------------------- scenarios

def fault_scenario(actuator: str | None, kappa: float = KAPPA, *, name: str | None = None) -> Scenario:
    """A torque loss κ of ``actuator`` (``pitch_wheel`` or ``array_drive``) from :data:`ONSET`; ``None``: fault-free."""
    if actuator is None:
        return Scenario(name or "fault_free", f"No fault, {DURATION:g} s: false alarms and wrong isolations.", DURATION)
    if actuator not in FAULTS:
        raise ArgumentError(f"actuator must be one of {list(FAULTS)}; got {actuator!r}")
    if not 0.0 < kappa <= 1.0:
        raise ArgumentError(f"kappa must be a torque loss in (0, 1]; got {kappa!r}")
    what = "pitch-wheel" if actuator == "pitch_wheel" else "array-drive"
    return Scenario(
        name or f"{actuator}_loss",
        f"{what} torque loss κ = {kappa:g} (applied torque (1 − κ)·T) from t = {ONSET:g} s.",
        DURATION,
        fault=actuator,
        onset=ONSET,
        params={"actuator": actuator, "kappa": float(kappa)},
    )


def fault_size_scenarios(kappas: Sequence[float]) -> dict[str, Scenario]:
    """Both faults at each torque loss in ``kappas`` (names ``<fault>_loss_k<κ>``): the fault-size sweep."""
    out: dict[str, Scenario] = {}
    for kappa in kappas:
        for actuator in FAULTS:
            sc = fault_scenario(actuator, float(kappa), name=f"{actuator}_loss_k{float(kappa):g}")
            out[sc.name] = sc
    return out


SCENARIOS: dict[str, Scenario] = {
    s.name: s for s in (fault_scenario(None), fault_scenario("pitch_wheel"), fault_scenario("array_drive"))
}


# --------------------------------------------------------------------------- the truth

NUMPY: dict[str, Any] = {"sin": np.sin, "cos": np.cos, "tanh": np.tanh, "ones_like": np.ones_like, "stack": np.column_stack}
"""The elementary functions of the truth's equations on runs × states arrays."""
CASADI: dict[str, Any] = {"sin": ca.sin, "cos": ca.cos, "tanh": ca.tanh, "ones_like": lambda r: ca.SX.ones(r.shape), "stack": lambda cols: ca.horzcat(*cols)}
"""The same on one run's CasADi row (the compiled simulation, :func:`sample_model`)."""


def truth_derivative(x: Any, tau: Any, p: Mapping[str, Any], truth: Truth, ops: Mapping[str, Any] = NUMPY) -> Any:
    """Time derivative of the truth's state ``[θ, φ, θ̇, φ̇, q, q̇]`` (runs × 6) under applied torques ``tau`` (runs × 2)."""
    rel, rel_rate = x[:, 1] - x[:, 0], x[:, 3] - x[:, 2]
    if truth.nonlinear:
        spring = p["k"] * ops["sin"](rel)
        friction = truth.friction_torque * ops["tanh"](rel_rate / truth.friction_rate)
    else:
        spring, friction = p["k"] * rel, 0.0
    internal = spring + p["b"] * rel_rate + friction  # on the body; its reaction on the array
    body = internal + tau[:, 0] - tau[:, 1] + truth.disturbance
    array = -internal + tau[:, 1]
    d, w, z = truth.flex_coupling, truth.flex_frequency, truth.flex_damping
    modal = -2.0 * z * w * x[:, 5] - w * w * x[:, 4]
    # [Js δ; δ 1] [θ̈; q̈] = [body; modal]
    det = p["Js"] - d * d
    theta_acc = (body - d * modal) / det
    q_acc = (p["Js"] * modal - d * body) / det
    return ops["stack"]([x[:, 2], x[:, 3], theta_acc, array / p["Jp"], x[:, 5], q_acc])


def rk4_step(x: Any, tau: Any, p: Mapping[str, Any], truth: Truth, h: float, ops: Mapping[str, Any] = NUMPY) -> Any:
    """One classical Runge–Kutta step of length ``h`` with the torques ``tau`` held."""
    k1 = truth_derivative(x, tau, p, truth, ops)
    k2 = truth_derivative(x + 0.5 * h * k1, tau, p, truth, ops)
    k3 = truth_derivative(x + 0.5 * h * k2, tau, p, truth, ops)
    k4 = truth_derivative(x + h * k3, tau, p, truth, ops)
    return x + (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


def energy(x: np.ndarray, p: Mapping[str, np.ndarray], truth: Truth) -> np.ndarray:
    """Mechanical energy of the truth's state (runs × 6): kinetic, spring and modal (conserved without torques and damping)."""
    d = truth.flex_coupling
    kinetic = 0.5 * (p["Js"] * x[:, 2] ** 2 + 2.0 * d * x[:, 2] * x[:, 5] + x[:, 5] ** 2 + p["Jp"] * x[:, 3] ** 2)
    rel = x[:, 1] - x[:, 0]
    spring = p["k"] * (1.0 - np.cos(rel)) if truth.nonlinear else 0.5 * p["k"] * rel**2
    return kinetic + spring + 0.5 * truth.flex_frequency**2 * x[:, 4] ** 2


def _limit(u: np.ndarray, limit: float | None) -> np.ndarray:
    return u if limit is None else np.clip(u, -limit, limit)


def steady_state(p: Mapping[str, np.ndarray], truth: Truth = TRUTH) -> np.ndarray:
    """The closed loop's noise-free equilibrium of each run (runs × 6) for its true parameters.

    The wheel balances the disturbance through the pitch error, ``K_pθ θ = T_d``; the drive holds the array
    where ``k sin(φ − θ) = k φ_c − K_pφ (φ − φ_c)`` (Newton's method; the linear spring when the truth is linear).
    Limits are not reached there (module docstring).
    """
    k = np.asarray(p["k"], dtype=float)
    theta = np.full(k.shape, truth.disturbance / GAINS["Kp_theta"])
    phi = hold_angle(k, theta, np.full(k.shape, truth.cant), truth)
    x = np.zeros((k.size, 6))
    x[:, 0], x[:, 1] = theta, phi
    return x


def hold_angle(k: Any, theta: Any, phi: Any, truth: Truth = TRUTH, ops: Mapping[str, Any] = NUMPY) -> Any:
    """The array angle where ``k sin(φ − θ) = k φ_c − K_pφ (φ − φ_c)``, by 20 Newton steps from ``phi``
    (:func:`steady_state`; the linear spring when the truth is linear)."""
    g = GAINS
    spring, slope = (ops["sin"], ops["cos"]) if truth.nonlinear else (lambda r: r, ops["ones_like"])
    for _ in range(20):
        res = k * spring(phi - theta) - NOMINAL.k * truth.cant + g["Kp_phi"] * (phi - truth.cant)
        phi = phi - res / (k * slope(phi - theta) + g["Kp_phi"])
    return phi


def simulate(
    scenario: Scenario,
    seeds: Sequence[int],
    *,
    truth: Truth = TRUTH,
    draws: np.ndarray | None = None,
    start_draws: np.ndarray | None = None,
    **_options: object,
) -> Batch:
    """Closed-loop truth runs of ``scenario``, one per seed, vectorised over seeds.

    Per seed: the parameters (:func:`run_parameters`), then the measurement noise, from the seed's generator
    (``start_draws``, runs × 4, and ``draws``, runs × N × 4: given standard normals instead, the parameters'
    uniforms being ``erf(z/√2)``, as the compiled simulation draws them).
    At sample ``k`` the controller reads ``y(k)`` and commands ``u(k)`` (logged), held over the sample; the
    faulty actuator applies ``(1 − κ)·sat(u)`` from the onset. ``extra`` holds the true states (also the flexible
    coordinate ``q``, ``q_dot``), the applied torques ``T_y_applied``, ``T_p_applied`` and the true parameters.
    """
    seeds = tuple(int(s) for s in seeds)
    runs, n = len(seeds), int(round(scenario.duration / TS))
    t = np.arange(n) * TS
    p = run_parameters(seeds, truth, None if start_draws is None else scipy.special.erf(np.asarray(start_draws) / np.sqrt(2.0)))
    sd = np.asarray(truth.noise, dtype=float)
    noise = np.zeros((runs, n, 4))
    for i, s in enumerate(seeds):
        if draws is not None:
            noise[i] = draws[i] * sd
            continue
        rng = np.random.default_rng(s)
        rng.uniform(size=4)  # the parameter draws
        noise[i] = rng.standard_normal((n, 4)) * sd
    loss = np.zeros((n, 2))
    if scenario.fault is not None:
        loss[scenario.active(t), FAULTS.index(scenario.params["actuator"])] = scenario.params["kappa"]
    g = GAINS
    kff = NOMINAL.k * truth.cant
    x = np.zeros((runs, 6)) if truth.start_at_rest else steady_state(p, truth)
    X = np.zeros((runs, n, 6))
    U = np.zeros((runs, n, 2))
    applied = np.zeros((runs, n, 2))
    h = TS / truth.substeps
    for j in range(n):
        X[:, j] = x
        y = x[:, :4] + noise[:, j]
        u = np.column_stack([
            -g["Kp_theta"] * y[:, 0] - g["Kd_theta"] * y[:, 2],
            kff - g["Kp_phi"] * (y[:, 1] - truth.cant) - g["Kd_phi"] * y[:, 3],
        ])
        tau = np.column_stack([_limit(u[:, 0], truth.wheel_limit), _limit(u[:, 1], truth.drive_limit)]) * (1.0 - loss[j])
        U[:, j], applied[:, j] = u, tau
        for _ in range(truth.substeps):
            x = rk4_step(x, tau, p, truth, h)
    extra = {name: X[:, :, i] for i, name in enumerate((*STATES, "q", "q_dot"))}
    extra |= {"T_y_applied": applied[:, :, 0], "T_p_applied": applied[:, :, 1]}
    extra |= {f"true_{name}": np.repeat(v[:, None], n, axis=1) for name, v in p.items()}
    return Batch(scenario=scenario, seeds=seeds, t=t, inputs=INPUTS, outputs=OUTPUTS, U=U, Y=X[:, :, :4] + noise, extra=extra)


def sample_model(*, truth: Truth = TRUTH, **_options: object) -> SampleModel:
    """:func:`simulate` one sample at a time, for the compiled Monte Carlo: each run starts from four draws
    (its parameters, uniform as ``erf(z/√2)``, kept in the state, and the equilibrium they give), then per
    sample the controller on the noisy measurements, the saturated torques (reduced by the fault while it is
    active) and ``substeps`` RK4 steps of the truth."""
    g, kff, h = GAINS, NOMINAL.k * truth.cant, TS / truth.substeps
    names = ("Js", "Jp", "k", "b")
    z0 = ca.SX.sym("z0", 1, 4)
    p0 = scaled_parameters(ca.erf(z0 / np.sqrt(2.0)), truth)
    theta = truth.disturbance / g["Kp_theta"]
    x_start = ca.SX.zeros(1, 6)
    if not truth.start_at_rest:
        x_start[0], x_start[1] = theta, hold_angle(p0["k"], theta, truth.cant, truth, CASADI)
    start = ca.Function("start", [z0.T], [ca.horzcat(x_start, *[p0[q] for q in names]).T], ["z0"], ["x0"])
    x, z, k, loss = ca.SX.sym("x", 10), ca.SX.sym("z", 4), ca.SX.sym("k"), ca.SX.sym("p", 2)
    row = x[:6].T
    p = {q: x[6 + i] for i, q in enumerate(names)}
    y = row[:, :4] + z.T * ca.DM(np.asarray(truth.noise, dtype=float)).T
    u = ca.horzcat(-g["Kp_theta"] * y[:, 0] - g["Kd_theta"] * y[:, 2], kff - g["Kp_phi"] * (y[:, 1] - truth.cant) - g["Kd_phi"] * y[:, 3])

    def limit(v: ca.SX, bound: float | None) -> ca.SX:
        return v if bound is None else clip_sx(v, -bound, bound)

    def outputs(faulty: bool) -> list[ca.SX]:
        tau = ca.horzcat(limit(u[:, 0], truth.wheel_limit), limit(u[:, 1], truth.drive_limit))
        tau = tau * (1.0 - loss.T) if faulty else tau * 1.0
        nxt = row
        for _ in range(truth.substeps):
            nxt = rk4_step(nxt, tau, p, truth, h, CASADI)
        return [ca.vertcat(nxt.T, x[6:]), u.T, y.T, ca.vertcat(row.T, tau.T, x[6:])]

    ins = [x, z, k, loss, ca.SX(0, 1)]
    return SampleModel(
        step=ca.Function("sample", ins, outputs(False), NAMES_IN, NAMES_OUT),
        faulty=ca.Function("sample_faulty", ins, outputs(True), NAMES_IN, NAMES_OUT),
        start=start,
        x0=np.zeros(10),
        parameters=lambda sc: np.array([sc.params["kappa"] if sc.fault == f else 0.0 for f in FAULTS]),
        Ts=TS,
        inputs=INPUTS,
        outputs=OUTPUTS,
        extra=(*STATES, "q", "q_dot", "T_y_applied", "T_p_applied", *(f"true_{q}" for q in names)),
    )


# --------------------------------------------------------------------------- the fault-free levels of a design

LEVEL_SEEDS = tuple(range(100_000, 100_050))
"""The fault-free truth runs the explicit level and ``h`` are estimated on: 50 runs of 600 s (300 000 samples),
seeds apart from those of the evaluation (0, 1, …), so the Monte Carlo tests the levels on other runs."""


def filter_residuals(A: Any, B: Any, C: Any, D: Any, L: Any, U: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """Residuals ``ε(k) = y(k) − C x̂(k) − D u(k)`` of the discrete filter ``x̂⁺ = A x̂ + B u + L ε`` (runs × N × p).

    The filter starts at the equilibrium of its first sample, ``x̂ = (I − G)⁻¹((B − L D) u + L y)``,
    ``G = A − L C`` (as the runtime does), and runs over all runs at once.
    """
    A, B, C, D, L = (np.asarray(m, dtype=float) for m in (A, B, C, D, L))
    G = A - L @ C
    eye = np.eye(A.shape[0])
    Xu, Xy = np.linalg.solve(eye - G, B - L @ D), np.linalg.solve(eye - G, L)
    xh = U[:, 0] @ Xu.T + Y[:, 0] @ Xy.T
    eps = np.zeros(Y.shape)
    for k in range(Y.shape[1]):
        e = Y[:, k] - xh @ C.T - U[:, k] @ D.T
        eps[:, k] = e
        xh = xh @ A.T + U[:, k] @ B.T + e @ L.T
    return eps


def fault_free_levels(A: Any, B: Any, C: Any, D: Any, L: Any, *, seeds: Sequence[int] = LEVEL_SEEDS) -> np.ndarray:
    """The residual records (runs × N × p) of the discrete filter ``(A, B, C, D, L)`` on fault-free truth runs."""
    batch = simulate(SCENARIOS["fault_free"], seeds)
    return filter_residuals(A, B, C, D, L, batch.U, batch.Y)


def explicit_levels(residuals: np.ndarray, window: int, P_f: float) -> tuple[float, float]:
    """``(ε̄, h)``: the ``1 − P_f`` quantiles of the window mean's norm ``‖m‖`` and of the window RMS ``s``.

    Over every sample of every run whose window is full (the runtime's statistics, beard_spec); ``residuals``
    as :func:`fault_free_levels` returns them.
    """
    if residuals.shape[1] < window:
        raise ArgumentError(f"the residual records hold {residuals.shape[1]} samples, fewer than the window {window}")
    zero = np.zeros(residuals.shape[:1] + (1,) + residuals.shape[2:])
    total = np.cumsum(np.concatenate([zero, residuals], axis=1), axis=1)
    squares = np.cumsum(np.concatenate([zero[..., 0], np.sum(residuals**2, axis=-1)], axis=1), axis=1)
    mean = (total[:, window:] - total[:, :-window]) / window
    rms = np.sqrt(np.maximum(squares[:, window:] - squares[:, :-window], 0.0) / window)
    return float(np.quantile(np.linalg.norm(mean, axis=-1), 1.0 - P_f)), float(np.quantile(rms, 1.0 - P_f))


# --------------------------------------------------------------------------- designs

def _beard_design(eigenstructure: str, *, P_f: float = 1e-3, window: int = 50, persistence: int = 1, **_options: object) -> GainFile:
    """The Beard filter (``beard_fdf``) on the sampled rigid model, its levels from fault-free truth runs.

    Designed twice: the first pass gives the gain ``L`` (the levels do not change it), the fault-free truth
    runs through that filter give ``ε̄`` and ``h`` (:func:`explicit_levels`), the second pass certifies the
    gain file with them.
    """
    plant = design_model()
    name = f"satellite_pitch_{eigenstructure}"
    common: dict[str, Any] = {
        "Ts": TS, "decay_rate": DECAY_RATE, "eigenstructure": eigenstructure, "sigma": SIGMA, "window": window,
        "persistence": persistence, "P_f": P_f,
    }
    first = design_with(plant, "beard_fdf", name=name, problem="satellite_pitch", explicit_level=1.0, h=1.0, **common)
    payload = first.extensions["beard_fdf"]
    records = fault_free_levels(*(payload[key] for key in ("A", "B", "C", "D", "L")))
    explicit_level, h = explicit_levels(records, window, P_f)
    record = {"method": "beard_fdf", **common, "explicit_level": explicit_level, "h": h,
              "level_runs": len(LEVEL_SEEDS), "model_error_range": list(model_error_range())}
    return design_with(
        plant, "beard_fdf", name=name, problem="satellite_pitch", record=record, explicit_level=explicit_level, h=h, **common
    )


def optimised(**options: Any) -> GainFile:
    """Eigenstructure chosen to make the cones narrow (``eigenstructure="optimised"``)."""
    return _beard_design("optimised", **options)


def plain(**options: Any) -> GainFile:
    """Eigenstructure as a designer places it by hand (``eigenstructure="plain"``): the comparison."""
    return _beard_design("plain", **options)



# --------------------------------------------------------------------------- the report

SWEEP_KAPPAS = (0.05, 0.1, 0.2, 0.3, 0.5)
"""Torque losses of the fault-size sweep: from below the noise floor to half the torque."""
SWEEP_RUNS = 10
SWEEP_SIGMAS = tuple(float(x) for x in np.geomspace(1e-3, 3.0, 25))


def _window_mean(r: np.ndarray, window: int) -> np.ndarray:
    c = np.cumsum(np.vstack([np.zeros((1, r.shape[1])), r]), axis=0)
    m = np.full_like(r, np.nan)
    m[window - 1 :] = (c[window:] - c[:-window]) / window
    return m


def _report(ctx: Any) -> list[tuple[str, str]]:
    """Cones (plain against optimised), the paper's angle figures, the residual in output space, the fault-size sweep
    and the model-error sweep."""
    from fdisyn.reporting.kit import fmt, shade, subplots, table
    from fdisyn.evaluation.metrics import scenario_metrics
    from fdisyn.numerics.robust_cones import implicit_thresholds, sampled_model_error
    from fdisyn.synthesis.beard_fdf.payload import beard_from_gain_file

    v = ctx.variants[0]
    sections: list[tuple[str, str]] = []
    flts = {d: beard_from_gain_file(b.gain_file) for d, b in v.built.items()}
    infos = {d: b.gain_file.certificate["beard_fdf"]["info"] for d, b in v.built.items()}
    faults = list(FAULTS)
    # 1. the cones
    rows = []
    for d, flt in flts.items():
        info = infos[d]
        for j, f in enumerate(faults):
            sc = f"{f}_loss"
            res = v.evaluation.examples.get(d, {}).get(sc)
            act = v.evaluation.batches[sc].active if sc in v.evaluation.batches else None
            rho = float(np.nanmedian(res.J[act, 1])) if res is not None and act is not None else float("nan")
            x = float(np.degrees(np.arcsin(min(1.0, 1.0 / rho)))) if rho > 0 else 90.0
            y = float(np.degrees(flt.Y_th[j]))
            first = info.get("Y_first_order_deg", [float("nan")] * len(faults))[j]
            rows.append([LABELS[d], LABELS[f], y, first, rho, x, min(90.0, x + y),
                         float(info["cones"]["axis_angles_deg"][0][1]),
                         "never" if info["cones"]["rho_disjoint_max"] is None else float(info["cones"]["rho_disjoint_max"]),
                         "not sampled" if info["bound_tightness"][j] is None else float(info["bound_tightness"][j]),
                         ", ".join(fmt(z[0]) for z in info["eigenvalues_z"])])
    head = ["design", "fault", "Y_th (°)", "first-order Y (°)", "median ρ under the fault", "X_th (°)", "I_th (°)", "angle C f1, C f2 (°)",
            "ρ for disjoint cones", "sampled / Y_th", "eig(A − L C)"]
    sections.append(("Decision cones: plain against optimised eigenstructure",
                     f"<p>σ = {fmt(SIGMA)} (‖δA‖₂ bound, continuous units). Y_th: the guaranteed half-angle, a bound on the "
                     "residual direction over the whole invariant subspace that continues the detection space (Stewart's "
                     "theorem); 'first-order Y': the paper's eigenvector-perturbation bound (Wilkinson), which the "
                     "guaranteed one matches to first order in σ. X_th = asin(1/ρ) at the median ρ of run 0 under the fault (default κ), "
                     "I_th = X_th + Y_th. 'sampled / Y_th': the largest exact angle over 200 sampled model errors of "
                     "norm σ and the first-order worst cases, divided by the bound. The plain filter (every eigenvalue at "
                     "the decay bound) shares its eigenvalue between the detection spaces and the rest: its eigen-directions "
                     "are not defined under model error, so Y_th = 90° and the cones cover everything (detected, never "
                     "isolated). 'ρ for disjoint cones': the largest ρ at which the two cones still overlap "
                     "(never: disjoint at every ρ); 'eig(A − L C)': the filter's discrete eigenvalues.</p>" + table(head, rows, left=2)))
    # 2. the paper's figures: the angle to each axis against the cone half-angle
    fig, axes = subplots(2, len(flts), figsize=(11, 7.2), sharex=True, squeeze=False)
    for col, d in enumerate(flts):
        for row, f in enumerate(faults):
            sc = f"{f}_loss"
            res = v.evaluation.examples[d][sc]
            b = v.evaluation.batches[sc]
            names = list(v.built[d].gain_file.step.statistic_names)
            ax = axes[row][col]
            for jf, g in enumerate(faults):
                ax.plot(b.t, np.degrees(res.J[:, names.index(f"angle_{g}")]), lw=0.8, color=("tab:blue", "tab:orange")[jf],
                        label=f"angle to the {g.replace('_', '-')} direction")
                ax.plot(b.t, np.degrees(res.J[:, names.index(f"cone_{g}")]), lw=0.8, ls="--", color=("tab:blue", "tab:orange")[jf],
                        label=f"cone half-angle I_th of the {g.replace('_', '-')}")
            shade(ax, b.t, b.active)
            ax.set_ylim(0, 92)
            ax.set_title(f"{d}: {LABELS[f]} κ = {fmt(KAPPA)}", fontsize=10)
            ax.set_ylabel("angle (°)", fontsize=10)
            ax.grid(alpha=0.3)
        axes[1][col].set_xlabel("t (s)", fontsize=10)
    handles, texts = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, texts, loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=2, fontsize=9, frameon=False)
    sections.append(("Figures — the residual's angle to each fault direction against its cone", ctx.figure(
        "cone_angles", fig, "Run 0 through the generated C: the angle of the window-mean residual to each fault's output "
        "direction (solid) and the cone half-angle I_th = X_th + Y_th (dashed), over time (cf. He, Zhang & Wu, figs. 1–2). "
        "Before the fault ρ < 1 and the cones are 90°; under the fault its own angle drops into its cone.")))
    # 3. the residual in output space
    d = "optimised" if "optimised" in flts else next(iter(flts))
    flt = flts[d]
    basis, _ = np.linalg.qr(np.hstack(flt.axes))
    fig, ax = subplots(1, 1, figsize=(6.5, 6))
    ax = ax if not isinstance(ax, np.ndarray) else ax.flat[0]
    for jf, f in enumerate(faults):
        sc = f"{f}_loss"
        res, b = v.evaluation.examples[d][sc], v.evaluation.batches[sc]
        m = _window_mean(res.r, flt.window)
        xy = m @ basis
        ax.plot(xy[~b.active, 0], xy[~b.active, 1], ".", ms=1, color="0.6")
        ax.plot(xy[b.active, 0], xy[b.active, 1], ".", ms=1.5, color=("tab:blue", "tab:orange")[jf], label=f"under the {LABELS[f]}")
    lim = float(np.nanmax(np.abs(ax.get_xlim() + ax.get_ylim())))
    for jf in range(len(faults)):
        axis = basis.T @ flt.axes[jf][:, 0]
        ang = np.arctan2(axis[1], axis[0])
        half = float(flt.Y_th[jf]) + float(np.arcsin(1.0 / 3.0))
        for sgn in (1, -1):
            for da in (-half, half):
                ax.plot([0, sgn * lim * np.cos(ang + da)], [0, sgn * lim * np.sin(ang + da)], ls="--", lw=0.8,
                        color=("tab:blue", "tab:orange")[jf])
    ax.set_aspect("equal")
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim, lim)
    ax.legend(fontsize=9, loc="lower left", bbox_to_anchor=(0.0, 1.01), frameon=False, markerscale=6)
    # the power of ten in the axis labels: matplotlib's offset text would sit on the long x label
    power = int(np.floor(np.log10(lim))) if lim > 0 and np.isfinite(lim) else 0
    from matplotlib.ticker import FuncFormatter

    unit = f" (×10{str(power).translate(str.maketrans('-0123456789', '⁻⁰¹²³⁴⁵⁶⁷⁸⁹'))})" if power else ""
    for axis in (ax.xaxis, ax.yaxis):
        axis.set_major_formatter(FuncFormatter(lambda value, _pos: f"{value / 10.0**power:g}"))
    ax.set_xlabel(f"residual along the pitch-wheel direction{unit}\n(orthonormal plane of the two fault directions)", fontsize=10)
    ax.set_ylabel(f"residual across it, in that plane{unit}", fontsize=10)
    ax.grid(alpha=0.3)
    sections.append(("Figures — the residual in output space", ctx.figure(
        "residual_plane", fig, f"Window-mean residual of run 0 ({d} filter) projected on the plane of the two fault directions: "
        "grey before the fault, coloured under it; dashed: the cones at ρ = 3 (X_th = 19.5°) around each fault direction.")))
    # 4. the fault-size sweep through the compiled C
    sweep_rows: list[list[Any]] = []
    for kappa in SWEEP_KAPPAS:
        for f in faults:
            sweep_sc = fault_scenario(f, kappa, name=f"{f}_loss_k{kappa:g}")
            batch = PROBLEM.run(sweep_sc, range(SWEEP_RUNS), **v.options)
            sweep_row: list[Any] = [LABELS[f], float(kappa)]
            for bb in v.built.values():
                outs = [bb.diagnoser.run(batch.U[i], batch.Y[i]) for i in range(SWEEP_RUNS)]
                met = scenario_metrics(
                    scenario=sweep_sc.name, fault=f, fault_index=faults.index(f), active=batch.active,
                    alarm=np.stack([o.alarm for o in outs]), isolated=np.stack([o.isolated for o in outs]),
                    J=np.stack([o.J for o in outs]), thresholds=list(bb.gain_file.thresholds), P_f=[], Ts=TS,
                    recovery=0,
                )
                sweep_row += [met.missed_detection_rate, "no detection" if met.detection_delay_mean_s is None else met.detection_delay_mean_s,
                              met.isolation_accuracy]
            sweep_rows.append(sweep_row)
    sweep_head = ["fault", "κ"] + [f"{dd}: {q}" for dd in v.built for q in ("missed", "delay (s)", "isolated")]
    sections.append(("Monte Carlo over fault sizes", f"<p>{SWEEP_RUNS} runs per torque loss κ through the generated C "
                     "(seeds 0…; the same truth as the scenarios). 'missed': the fraction of runs without an alarm while "
                     "the fault acts; 'delay': the mean time from the onset to the first alarm; 'isolated': the fraction "
                     "of runs whose most frequent isolation while the fault acts names it.</p>" + table(sweep_head, sweep_rows, left=2)))
    # 5. the model-error sweep
    flt = flts.get("optimised", next(iter(flts.values())))
    plant = design_model()
    spaces = [np.linalg.qr(_ax_preimage(flt, j))[0] for j in range(len(faults))]
    y_list = []
    for sg in SWEEP_SIGMAS:
        bd = implicit_thresholds(flt.G, flt.C, spaces, sampled_model_error(plant.A, TS, sg))
        y_list.append(np.degrees(bd.Y))
    ys = np.asarray(y_list)
    theta = float(infos.get("optimised", next(iter(infos.values())))["cones"]["axis_angles_deg"][0][1])
    fig, ax = subplots(1, 1, figsize=(8, 4))
    ax = ax if not isinstance(ax, np.ndarray) else ax.flat[0]
    for jf, f in enumerate(faults):
        ax.loglog(SWEEP_SIGMAS, ys[:, jf], lw=1.0, label=f"Y_th, {LABELS[f]}")
    ax.axhline(theta / 2, color="k", ls=":", lw=0.8, label="half the angle between the fault directions")
    ax.axvline(SIGMA, color="0.5", ls="--", lw=0.8, label=f"design σ = {fmt(SIGMA)}")
    ax.set_xlabel("σ, bound on ‖δA‖₂ (1/s)", fontsize=10)
    ax.set_ylabel("half-angle Y_th (°)", fontsize=10)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=9, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    overlap = next((sg for sg, y in zip(SWEEP_SIGMAS, ys, strict=True) if y.sum() >= theta), None)
    sections.append(("Model-error sweep: where the cones start to overlap", ctx.figure(
        "sigma_sweep", fig, "Implicit threshold Y_th of the optimised filter against the model-error bound σ. The cones "
        "(at ρ → ∞, X_th → 0) overlap once Y_1 + Y_2 reaches the angle between the fault directions "
        + (f"({fmt(theta)}°): first at σ ≈ {fmt(overlap)}" if overlap else f"({fmt(theta)}°); they stay disjoint over the sweep")
        + "; Y_th jumps to 90° where Stewart's condition fails (the eigen-directions need not continue).")))
    return sections


def _ax_preimage(flt: Any, j: int) -> np.ndarray:
    """The detection space of fault ``j`` of a filter on the full-rank C of this plant: ``C⁻¹ S_j``."""
    return np.linalg.solve(flt.C, flt.axes[j])

LABELS: Mapping[str, str] = {
    "T_y": "pitch-wheel torque T_y (N·m)",
    "T_p": "array-drive torque T_p (N·m)",
    "theta_m": "measured pitch angle θ (rad)",
    "phi_m": "measured array angle φ (rad)",
    "theta_dot_m": "measured pitch rate θ̇ (rad/s)",
    "phi_dot_m": "measured array rate φ̇ (rad/s)",
    "eps_theta_m": "residual of the pitch angle θ (rad)",
    "eps_phi_m": "residual of the array angle φ (rad)",
    "eps_theta_dot_m": "residual of the pitch rate θ̇ (rad/s)",
    "eps_phi_dot_m": "residual of the array rate φ̇ (rad/s)",
    "rms": "window RMS of the residual",
    "rho": "ρ: window-mean norm over its fault-free level ε̄ (–)",
    "angle_pitch_wheel": "angle of the window-mean residual to the pitch-wheel direction (rad)",
    "angle_array_drive": "angle of the window-mean residual to the array-drive direction (rad)",
    "cone_pitch_wheel": "decision-cone half-angle I_th of the pitch wheel (rad)",
    "cone_array_drive": "decision-cone half-angle I_th of the array drive (rad)",
    "pitch_wheel": "pitch-wheel torque loss",
    "array_drive": "array-drive torque loss",
    "optimised": "Beard filter, optimised eigenstructure",
    "plain": "Beard filter, every eigenvalue at the decay bound",
}
"""Readable names with units of the signals, residuals, statistics, faults and designs the page shows."""


def _model(**_options: object) -> LinearPlant:
    """The rigid design model (:func:`design_model`)."""
    return design_model()


def _claims(ctx: Any) -> list[Any]:
    """He, Zhang & Wu c. 1999 (its qualitative results; its numbers were lost) against the Monte Carlo."""
    from fdisyn.reporting.kit import Claim, false_alarms_pooled, fmt
    from fdisyn.synthesis.beard_fdf.payload import beard_from_gain_file

    v = ctx.variants[0]
    if "optimised" not in v.built:
        return []
    info = v.built["optimised"].gain_file.certificate["beard_fdf"]["info"]
    m = v.evaluation.metrics["optimised"]
    out = []
    y_th = [float(np.degrees(y)) for y in beard_from_gain_file(v.built["optimised"].gain_file).Y_th]
    theta = float(info["cones"]["axis_angles_deg"][0][1])
    disjoint = sum(y_th) < theta
    out.append(
        Claim(
            "Under the bounded model error the two faults' decision cones are disjoint (He, Zhang & Wu c. 1999)",
            "disjoint",
            f"Y_th = {fmt(y_th[0])}° and {fmt(y_th[1])}°, sum below the {fmt(theta)}° between the fault directions"
            if disjoint
            else f"Y_th = {fmt(y_th[0])}° and {fmt(y_th[1])}° overlap across the {fmt(theta)}° between the fault directions",
            "reproduced" if disjoint else "differs",
            "" if disjoint else "the model-error bound σ is too large for this eigenstructure",
        )
    )
    ff = m.get("fault_free")
    if ff is not None:
        out.append(
            Claim(
                "The robust decision raises no false alarm under model error and disturbance (He, Zhang & Wu c. 1999)",
                "none",
                f"{false_alarms_pooled([ff])}, in {fmt(100 * ff.false_alarm_runs)} % of the runs (levels set for "
                f"P_f = {fmt(ctx.problem.check_options(v.options)['P_f'])})",
                "reproduced" if ff.false_alarm_runs <= 0.05 else "differs",
                "" if ff.false_alarm_runs <= 0.05 else (
                    f"the explicit threshold is the fault-free residual level learned on 50 runs for P_f = "
                    f"{fmt(ctx.problem.check_options(v.options)['P_f'])} per sample, so some runs alarm: the measured "
                    f"{fmt(ff.false_alarm_rate)} per sample is "
                    + ("within" if ff.false_alarm_rate <= ctx.problem.check_options(v.options)["P_f"] else "above")
                    + " that rate; the paper shows a single run"
                ),
            )
        )
    for f in FAULTS:
        mm = m.get(f"{f}_loss")
        if mm is None or mm.missed_detection_rate is None:
            continue
        ok = mm.missed_detection_rate == 0.0 and (mm.isolation_accuracy or 0.0) >= 0.9
        why = ""
        if not ok and f == "pitch_wheel":
            why = (
                "The wheel's steady torque already balances the unmodelled disturbance T_d along the wheel's own "
                f"direction, so a loss κ = {fmt(KAPPA)} raises that residual bias only by 1/(1 − κ) = {fmt(1 / (1 - KAPPA))}: "
                "ρ stays near 1, X_th = asin(1/ρ) near 90°, and the cones cover each other (detected in part, not isolated)."
            )
        elif not ok:
            why = "the fault's window-mean residual does not leave its fault-free level far enough for a narrow cone"
        out.append(
            Claim(
                f"{'An' if LABELS[f][0] in 'aeiou' else 'A'} {LABELS[f]} (κ = {fmt(KAPPA)} from 300 s) turns the residual into its own cone: detected and isolated "
                "(He, Zhang & Wu c. 1999)",
                "detected, isolated",
                f"runs missed {fmt(100 * mm.missed_detection_rate)} %, delay mean {fmt(mm.detection_delay_mean_s)} s, isolated in "
                f"{fmt(100 * (mm.isolation_accuracy or 0.0))} %",
                "reproduced" if ok else "differs",
                why,
            )
        )
    return out


NOTES = (
    "The paper's numbers were lost; the model is a stand-in. Rigid design model: Js = 5 kg·m², Jp = 1 kg·m², "
    "k = 0.15 N·m/rad, b = 0.05 N·m·s/rad; x = [θ, φ, θ̇, φ̇] inertial, u = [T_y, T_p], C = I, D = 0; fault "
    "directions Fx = B (pitch_wheel, array_drive). Continuous, sampled by the design at Ts = 0.1 s (10 Hz: 75 "
    "samples per period of the 0.42 rad/s coupled mode, 12 per period of the truth's flexible mode).",
    "R = diag(2e-5², 5e-5², 1e-5², 5e-5²) per sample, the truth's measurement noise (star tracker, drive encoder, "
    "gyro, drive tachometer); Q = 0: the truth has no random process noise, its model errors are deterministic.",
    "Parameter error: Js, Jp, k, b each uniform within ±3 % per run; ‖A_true − A_model‖₂ of the rigid part then lies in "
    "[0, 0.0141] (the box's corners), and the designs assume σ = 0.015.",
    "Unmodelled in the truth: a second flexible mode of the array coupled to the body (ω_f = 2.5 rad/s, ζ_f = 0.005, "
    "δ = 0.5 kg^½·m, 5 % modal participation); the spring k sin(φ − θ); drive friction 5e-5 N·m · tanh(rate/1e-3 rad/s); "
    "wheel saturation ±0.02 N·m, drive saturation ±0.01 N·m; a constant pitch disturbance 1e-3 N·m (solar pressure and "
    "gravity gradient, the upper end of 1e-4…1e-3 N·m).",
    "Operating point: an inertially pointing body (θ_ref = 0), so the sun is fixed in the body frame over a run and sun "
    "tracking is a hold of the array at the sun angle φ_c = 0.02 rad; the rigid model's spring is neutral at φ = θ, so the "
    "drive carries the steady torque k φ_c = 3e-3 N·m and the wheel the disturbance 1e-3 N·m. A drive rotating the array "
    "relative to the body at orbital rate was rejected: it winds the model's coupling spring (0.7 rad in 600 s), and the "
    "error of k and the sin nonlinearity then outgrow the faults.",
    "Controller, discrete at Ts on the measured outputs: T_y = −1.25 θ − 3.5 θ̇ (PD, 0.5 rad/s, ζ = 0.7 on Js), "
    "T_p = k φ_c − 0.25 (φ − φ_c) − 0.7 φ̇ (PD with the spring preload as feedforward). Runs start at each run's own "
    "closed-loop equilibrium (a satellite already in normal mode); started at rest instead, the rates settle within 60 s.",
    "Truth integration: RK4 at Ts/5 with the torques held over the sample; exact to round-off against the sampled model "
    "when the truth is reduced to it.",
    "Faults: torque loss κ of the pitch wheel or the array drive from t = 300 s of 600 s (five times the settling time), "
    "applied torque (1 − κ)·sat(u) with u the logged command: μ = −κ·sat(u) along the actuator's column of B. Both faults "
    "have the same κ, default 0.3.",
    "Why κ = 0.3: the wheel's steady torque balances the unmodelled disturbance, which enters along the pitch-wheel "
    "direction itself, so a fault-free run already carries a wheel-direction bias of the size of T_d and a loss κ raises "
    "it to T_d/(1 − κ): the ratio to the fault-free level is at most 1/(1 − κ) whatever the noise (1.43 at κ = 0.3, "
    "1.25 at 0.2). The array drive's steady torque is modelled (the spring preload), so its loss stands clear of the "
    "±3 % error of k. fault_size_scenarios(κ…) gives the sweep.",
    "Levels: ε̄ (explicit_level) and h are the 1 − P_f quantiles of the window mean's norm and the window RMS over 50 "
    "fault-free truth runs (seeds 100000–100049) through the design's own filter; window 50 samples (5 s: two periods "
    "of the flexible mode, noise averaged by 7), P_f = 1e-3 per sample.",
)

PROBLEM = Problem(
    name="satellite_pitch",
    title="Satellite pitch axis with a solar array: actuator FDI with Beard's fault detection filter",
    summary=(
        "A Beard fault detection filter on the rigid pitch-axis model of a satellite with a solar array: the residual "
        "of a pitch-wheel or array-drive torque loss stays in its own output direction, and robust decision cones "
        "(an implicit threshold from the model error ‖δA‖ ≤ σ, an explicit one from the fault-free residual level) "
        "isolate it (He, Zhang & Wu, Journal of Astronautics, c. 1999). The truth adds parameter error, a flexible "
        "mode, nonlinearity, actuator limits, a disturbance torque and sensor noise."
    ),
    designs={"optimised": optimised, "plain": plain},
    default_design="optimised",
    scenarios=SCENARIOS,
    simulate=simulate,
    sample_model=sample_model,
    options={"P_f": 1e-3, "window": 50, "persistence": 1},
    reference={
        "setting": [
            "the satellite pitch-axis model with a solar array (body and array, pitch wheel and array drive)",
            "faults occur after the steady state",
            "the faults have equal sizes",
        ],
        "faults": list(FAULTS),
        "numbers": "lost; the model here is a stand-in (notes)",
    },
    monte_carlo_runs=40,
    report=_report,
    claims=_claims,
    labels=LABELS,
    model=_model,
    notes=NOTES,
)
