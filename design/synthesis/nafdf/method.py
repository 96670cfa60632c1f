"""The NAFDF as a design method of the registry (Zhou, Xi & Zhang, Shanghai Jiao Tong University, c. 1991).

Its options are the keywords of :func:`fdisyn.synthesis.nafdf.design.nafdf`,
with one name for the false-alarm probability everywhere: ``P_f`` (the
keyword ``false_alarm_probability`` of :func:`~fdisyn.synthesis.nafdf.design.nafdf`
names the stored setting). Settings per parameter are a list (in the plant's
parameter order) or a table by parameter name. The domains the options state
are checked in full, with the plant's sizes, by the design itself
(:mod:`fdisyn.synthesis.nafdf.settings`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from typing import Any

import numpy as np
from fdisyn.models.nonlinear import NonlinearPlant
from fdisyn.runtime.errors import ArgumentError
from fdisyn.runtime.gainfile import GainFile
from fdisyn.runtime.names import shown
from fdisyn.synthesis.nafdf.design import nafdf
from fdisyn.synthesis.nafdf.payload import nafdf_gain_file
from fdisyn.synthesis.nafdf.settings import MAX_CLASSIFIER_WINDOW, MAX_COUNT, MAX_WINDOW, MIN_SHIFT_RANGE
from fdisyn.synthesis.registry import ARL0, DEFAULT_ARL0, DETECTOR, P_F, WINDOW, Method, Option, at, is_count, is_real, register

__all__ = ["NAFDF_OPTIONS", "NAFDF"]


def _per_parameter(key: str) -> Any:
    def refine(value: Any, where: str, plant: NonlinearPlant | None) -> Any:
        """A per-parameter setting given as a table by name: the list in the plant's parameter order."""
        if not isinstance(value, Mapping) or plant is None:
            return value
        parameters = plant.parameters
        unknown = sorted(set(value) - set(parameters))
        missing = [q for q in parameters if q not in value]
        if unknown or missing:
            raise ArgumentError(f"{at(where, key)}: expected one entry per parameter {list(parameters)}; missing {missing}, unknown {unknown}")
        return [value[q] for q in parameters]

    return refine


def _u0(value: Any, where: str, plant: NonlinearPlant | None) -> Any:
    """The nominal input: one finite number per input."""
    label, m = at(where, "u0"), "m" if plant is None else plant.m
    if not isinstance(value, (list, tuple, np.ndarray)) or not all(isinstance(x, (int, float, np.floating)) and not isinstance(x, bool) for x in value):
        raise ArgumentError(f"{label} must be a list of {m} finite numbers (one per input), got {shown(value)}")
    if plant is not None and len(value) != plant.m:
        raise ArgumentError(f"{label} must have {plant.m} entries (one per input), got {len(value)}")
    if not np.all(np.isfinite(np.asarray(value, dtype=float))):
        raise ArgumentError(f"{label} must hold finite numbers, got {shown(value)}")
    return [float(x) for x in value]


def _per(name: str, doc: str, kind: str) -> Option:
    return Option(name, None, doc, kind, refine=_per_parameter(name))


NAFDF_OPTIONS: tuple[Option, ...] = (
    replace(P_F, doc="false-alarm probability of the WSSR test per sample under H0 (threshold rule 'chi2'); for CUSUM and GLR 1/ARL₀ in samples; "
            "given instead of arl0 (the per-sample choice; default: none, the budget is arl0)"),
    replace(WINDOW, doc="WSSR window N in samples (Zhou, Xi & Zhang c. 1991, eq. (2.4)), or the GLR's onset window (detector 'glr')",
            expected=f"a whole number of samples in 1..{MAX_WINDOW}", accepts=lambda v: is_count(v) and v <= MAX_WINDOW),
    replace(
        DETECTOR,
        default="wssr",
        doc="the fast detection's statistic on the EKF innovations: 'wssr' (eq. (2.4)), 'cusum' (Page's CUSUM per normalised "
        "innovation and sign, tuned to min_shift) or 'glr' (windowed GLR per normalised innovation, Willsky & Jones 1976)",
        expected="'wssr', 'cusum' or 'glr'",
        accepts=lambda v: v in ("wssr", "cusum", "glr"),
    ),
    replace(ARL0, doc="the diagnoser's mean time between false alarms (s): the detector's rate 1/(arl0/Ts − 2·classifier_window) per sample "
            f"(default: {DEFAULT_ARL0:g} s, one hour, unless P_f is given; give one of arl0 and P_f)"),
    Option(
        "min_shift", None, "the CUSUM's designed change: a mean shift of this many standard deviations in one normalised EKF "
        "innovation (detector 'cusum' only; default 1)",
        f"a number of standard deviations in [{MIN_SHIFT_RANGE[0]:g}, {MIN_SHIFT_RANGE[1]:g}] and below 2·Q⁻¹(P_f/2p), where one "
        "sample meets the budget (Q the normal tail, p the outputs: 5.15 at P_f = 0.01 and p = 1; 74.1 at most)",
        lambda v: is_real(v) and MIN_SHIFT_RANGE[0] <= v <= MIN_SHIFT_RANGE[1],
    ),
    Option("threshold_rule", "chi2", "the WSSR threshold: the chi2 quantile for P_f, or the paper's fixed beta0", "'chi2' or 'beta0'", lambda v: v in ("chi2", "beta0")),
    Option("beta0", None, "the paper's fixed WSSR threshold (threshold rule 'beta0')", "a positive finite number"),
    Option("x0", None, "initial state estimate of both filters; default zeros (a plant file: [simulation].x0)", "one finite number per state"),
    Option("P0", 1.0, "initial (and reset) state covariance of both filters", "a positive number, or a positive definite matrix"),
    _per("theta0", "initial (and reset) parameter estimate of the NF; default the nominal θ", "one finite number per parameter (a list or a table by name)"),
    Option("R0", None, "initial (and reset) NF information matrix (eq. (2.5)); default I", "a positive definite matrix"),
    Option("forgetting_initial", 0.95, "initial forgetting factor of the NF (eq. (2.5))", "a number in (0, 1]"),
    Option("forgetting_rate", 0.99, "rate at which the forgetting factor tends to its final value", "a number in (0, 1)"),
    Option("forgetting_final", 0.99, "final forgetting factor λ∞ of the NF", "a number in (0, 1]"),
    _per("theta_lower", "lower bounds of the parameter box (projection of the NF step); default -inf", "one number per parameter"),
    _per("theta_upper", "upper bounds of the parameter box; default +inf", "one number per parameter"),
    Option("nominal_samples", 200, "N1 of eq. (2.6): samples that learn the nominal spread of θ̂", f"a whole number in 1..{MAX_COUNT}"),
    Option("classifier_window", 50, "N2 of eq. (2.7), also the convergence window", f"a whole number in 1..{MAX_CLASSIFIER_WINDOW}"),
    Option("W1", 50.0, "Bayes-distance threshold of a fault class (eq. (2.7))", "a number with 0 ≤ W1 < W2"),
    Option("W2", 350.0, "Bayes-distance threshold of a certain fault class (eq. (2.7))", "a finite number > W1"),
    Option("T1", 50, "samples the classifier waits after the NF converged", f"a whole number in 1..{MAX_COUNT}"),
    _per(
        "isolable_jump",
        "smallest jump of θ_i to isolate: the NF converges only when W1·σ_i² ≤ isolable_jump_i² (σ_i from its own covariance); default 50 % of |θ0_i|",
        "one positive number (or inf) per parameter",
    ),
    Option("convergence_level", 1e-3, "significance of the drift and innovation tests of the NF's convergence check", "a number in (0, 1)"),
    _per(
        "convergence_tolerance",
        "deprecated: read as the largest standard deviation of θ̂_i, i.e. isolable_jump = √W1 · convergence_tolerance",
        "one positive number per parameter",
    ),
    Option("u0", None, "nominal input (where the model must be finite, and the certificate's Jacobian check); default zeros", "one finite number per input", refine=_u0),
)
"""The options of the NAFDF, named as a plant file's ``[design]`` keys and the keywords of ``fdisyn.design``."""


def _design(
    plant: NonlinearPlant,
    *,
    name: str,
    problem: str | None = None,
    record: Mapping[str, object] | None = None,
    where: str = "",
    P_f: float,
    x0: Any,
    **options: Any,
) -> GainFile:
    try:
        dsg = nafdf(
            plant,
            name=problem or name,
            x0=np.zeros(plant.n) if x0 is None else x0,
            false_alarm_probability=P_f,
            **options,
        )
    except (TypeError, ValueError) as exc:
        raise ArgumentError(f"{where}: {exc}") from exc
    return nafdf_gain_file(dsg, problem=problem or name, design_name="nafdf", name=name, options=record)


NAFDF = register(
    Method(
        name="nafdf",
        plant_kind="nonlinear",
        summary="nonlinear adaptive fault detection filter: EKF + WSSR detection, parameter re-estimation and Bayes classification",
        reference="Zhou, Xi & Zhang c. 1991, Shanghai Jiao Tong University, eqs. (2.1)-(2.8), fig. 1",
        options=NAFDF_OPTIONS,
        design=_design,
        diagnoser_kind="nafdf",
    )
)
