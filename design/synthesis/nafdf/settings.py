"""NAFDF settings, their validation and the layout of the step's state vector.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from fdisyn.detectors.sequential import MAX_ARL_SAMPLES
from fdisyn.models.nonlinear import NonlinearPlant
from fdisyn.numerics.linalg import as_covariance, as_vector, frozen_array, real_array
from fdisyn.runtime.errors import ArgumentError, ShapeError
from fdisyn.runtime.schema import MAX_MAGNITUDE
from fdisyn.runtime.layout import StateLayout
from fdisyn.runtime.names import shown
from fdisyn.runtime.values import real_number

__all__ = ['DEFAULT_MIN_SHIFT', 'MIN_SHIFT_RANGE', 'largest_min_shift', 'MAX_CLASSIFIER_WINDOW', 'MAX_COUNT', 'MAX_DIMENSION', 'MAX_STATE', 'MAX_STEP_INSTRUCTIONS', 'MAX_STEP_WORK', 'MAX_WINDOW', 'NafdfSettings', 'THRESHOLD_SCALE_RANGE']

# Resource limits (module docstring).
MAX_DIMENSION = 30
"""Most states, inputs, outputs or parameters: the step unrolls LDLᵀ factorisations of n×n, p×p and l×l
matrices (~k³/3 operations each) and the diagonal of the l×l inverse (another ~l³/3), so ~30 already
fills :data:`MAX_STEP_INSTRUCTIONS`."""
MAX_WINDOW = 1000
"""Largest WSSR window ``N``: the window costs ~16 operations per sample (shift, sum, threshold lookup)."""
MAX_CLASSIFIER_WINDOW = 1000
"""Largest ``N2``: the classifier and convergence windows cost ~35 operations per sample and parameter."""
MIN_SHIFT_RANGE = (1e-6, 1e6)
"""The CUSUM's designed shift ``min_shift`` (standard deviations of a normalised innovation): its drift
``½ min_shift²`` and increments ``min_shift·w`` (``w`` capped at 1e150) stay within a double; below a millionth, the
CUSUM would accumulate for longer than any run length the thresholds are computed for. The budget bounds it further
(:func:`largest_min_shift`: below 74.1 for every budget the thresholds are computed for)."""
DEFAULT_MIN_SHIFT = 1.0
"""The CUSUM's designed shift when ``min_shift`` is not given (one standard deviation); what every design records."""
MAX_COUNT = 10**9
"""Largest ``N1`` and ``T1``: sample counters held in doubles (exact to 2⁵³)."""
MAX_STATE = 4096
"""Most entries of the diagnoser state (32 KiB; the generated step keeps a copy on the stack)."""
MAX_STEP_INSTRUCTIONS = 40_000
"""Most operations of the step (≈ 1 MB of C that gcc -O2 compiles in about a minute)."""
MAX_STEP_WORK = 8192
"""Most doubles of CasADi work memory (64 KiB): locals of the generated step, in registers or on its stack."""

# Names a payload may hold (the design's own and the signals'): identifiers of bounded length.
_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_MAX_NAME = 64
# Variance floor of the classifier: keeps d_i finite when θ̂_i is constant to the last bit.
_VAR_FLOOR = 1e-280
# d_i reported when its formula overflows (only for |θ̂| beyond ~1e140).
_D_OVERFLOW = 1e300
# Largest normalised square kept in the WSSR window, so that the window sum cannot overflow.
_Q_CAP = 1e300
# Largest normalised innovation the CUSUM and GLR take in (their sums stay finite: M · 1e150 < DBL_MAX).
_W_CAP = 1e150
# Relative shift making a PSD covariance test tolerant of round-off (Joseph form: error ~ n·eps·‖P‖).
_PSD_SHIFT = 1e-12


# --------------------------------------------------------------------------- settings


@dataclass(frozen=True, eq=False)
class NafdfSettings:
    """Every design choice of the NAFDF, validated (see the module docstring for their meaning)."""

    x0: np.ndarray
    """Initial state estimate of both filters (the paper's ``x̂(0)``, section 3)."""
    P0: np.ndarray
    """Initial (and reset) state covariance of both filters (the paper's ``P(0)``)."""
    theta0: np.ndarray
    """Initial (and reset) NF parameter estimate (the paper's ``θ̂(0)``)."""
    R0: np.ndarray
    """Initial (and reset) NF information matrix (the paper's ``R(0)``, eq. (2.5))."""
    window: int
    """WSSR window ``N`` (2.4), or the GLR's onset window ``M`` (detector ``"glr"``)."""
    threshold_rule: Literal["chi2", "beta0"]
    false_alarm_probability: float
    """``P_f`` of the WSSR test per sample under H0 (rule ``"chi2"``); for CUSUM and GLR the detector's
    false-alarm rate ``1/ARL₀`` (samples)."""
    beta0: float | None
    """The paper's fixed WSSR threshold (rule ``"beta0"``)."""
    forgetting_initial: float
    forgetting_rate: float
    forgetting_final: float
    theta_lower: np.ndarray
    theta_upper: np.ndarray
    nominal_samples: int
    """``N1`` of (2.6)."""
    classifier_window: int
    """``N2`` of (2.7); also the window of the convergence tests."""
    W1: float
    W2: float
    T1: int
    isolable_jump: np.ndarray
    """Smallest jump of each ``θ_i`` the classifier must isolate: the NF counts as converged only when
    its own standard deviation ``σ_i`` satisfies ``W1 σ_i² ≤ isolable_jump_i²`` (the information law of
    :mod:`fdisyn.synthesis.nafdf.design`, block 4)."""
    convergence_level: float
    """Significance of the two tests of the convergence check: the drift of ``θ̂`` and the NF innovations."""
    detector: Literal["wssr", "cusum", "glr"] = "wssr"
    """The fast detection's statistic on the EKF innovations (module :mod:`fdisyn.synthesis.nafdf.design`)."""
    min_shift: float = DEFAULT_MIN_SHIFT
    """The CUSUM's designed change: a mean shift of this many standard deviations in one normalised innovation
    (the default for the other detectors, which do not read it)."""
    arl0: float | None = None
    """The diagnoser's mean time between false alarms (seconds), when the thresholds were set from it."""
    u0: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """Nominal input: with ``x0`` and ``θ0`` the point where the model must be finite and where the
    certificate compares the AD Jacobians with central differences (not used by the step)."""
    threshold_scale: float = 1.0
    """Every threshold of the fast detection times this factor (the thresholds the budget gives at 1): a point of
    the operating characteristic, measured on such a copy of the diagnoser. Stored in a gain file only when it is
    not 1."""

    def to_dict(self) -> dict[str, object]:
        out: dict[str, object] = {}
        for k, v in self.__dict__.items():
            if k == "threshold_scale" and v == 1.0:
                continue
            if isinstance(v, np.ndarray):
                out[k] = [None if not math.isfinite(z) else float(z) for z in v.reshape(-1)] if v.ndim == 1 else v.tolist()
            else:
                out[k] = v
        return out


def _float_array(value: object, name: str) -> np.ndarray:
    try:
        return real_array(value, name)  # numbers only: "100" or true are refused, not converted
    except (ShapeError, ArgumentError):
        raise ArgumentError(f"{name} must be a number or an array of numbers; got {shown(value)}") from None


def _vec(value: object, name: str, size: int) -> np.ndarray:
    return as_vector(_float_array(value, name), name, size, fill=True)


def _finite_vec(value: object, name: str, size: int) -> np.ndarray:
    arr = _vec(value, name, size)
    if not np.all(np.isfinite(arr)):
        raise ArgumentError(f"{name} must be finite; got {shown(arr.tolist())}")
    return arr


def _spd(value: object, name: str, size: int) -> np.ndarray:
    return as_covariance(_float_array(value, name), name, size, definite=True)


def _positive_int(value: object, name: str, maximum: int = MAX_COUNT) -> int:
    """A whole number in ``1..maximum`` (an integral float is accepted: TOML and JSON write ``1e3``)."""
    whole: int | None = None
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        whole = int(value)
    elif isinstance(value, (float, np.floating)) and math.isfinite(value) and float(value).is_integer():
        whole = int(value)
    if whole is None or whole < 1:
        raise ArgumentError(f"{name} must be a positive integer; got {shown(value)}")
    if whole > maximum:
        raise ArgumentError(f"{name} is {whole}; at most {maximum} is allowed (see the limits in fdisyn.synthesis.nafdf.design)")
    return whole


def _number(value: object, name: str) -> float:
    """A real number (NaN and ±inf pass: each setting's range check refuses them with its own words)."""
    v = real_number(value)
    if v is None:
        raise ArgumentError(f"{name} must be a number; got {shown(value)}")
    if math.isinf(v) and isinstance(value, int):  # an integer beyond the double range
        raise ArgumentError(f"{name} must be a finite number; got {shown(value)}")
    return v


def _unit_open(value: float, name: str) -> float:
    v = _number(value, name)
    if not 0.0 < v < 1.0:
        raise ArgumentError(f"{name} must lie strictly between 0 and 1; got {shown(value)}")
    return v


# --------------------------------------------------------------------------- state layout


DETECTORS = ("wssr", "cusum", "glr")
"""The NAFDF's fast-detection statistics on the EKF innovations."""


def _detector_blocks(detector: str, window: int, p: int) -> tuple[tuple[str, int, int], ...]:
    """The detector's state: the WSSR's window of normalised squares and its fill count, the CUSUM's ``2p``
    sums, or the GLR's ``p × M`` onset sums."""
    if detector == "cusum":
        return (("cusum_sums", 2 * p, 1),)
    if detector == "glr":
        return (("glr_sums", p, window),)
    return (("wssr_buffer", window, 1), ("wssr_count", 1, 1))


def _layout(n: int, l: int, window: int, n2: int, detector: str = "wssr", p: int = 1) -> StateLayout:
    one = (1, 1)
    entries = (
            ("ekf_x", n, 1),
            ("ekf_P", n, n),
            ("ekf_theta", l, 1),
            *_detector_blocks(detector, window, p),
            ("nf_x", n, 1),
            ("nf_P", n, n),
            ("nf_theta", l, 1),
            ("nf_R", l, l),
            ("nf_W", n, l),
            ("nf_gain", *one),
            ("nf_forgetting", *one),
            ("nf_age", *one),
            ("nf_settled", *one),
            ("nf_converged", *one),
            ("nf_info", l, 1),
            ("theta_window", l, n2),
            ("nis_window", n2, 1),
            ("ekf_nis_window", n2, 1),
            ("nominal_count", *one),
            ("nominal_mean", l, 1),
            ("nominal_m2", l, 1),
            ("nominal_frozen", *one),
            ("count_w1", l, 1),
            ("count_w2", l, 1),
            ("fault_class", l, 1),
            ("fault_size", l, 1),
            ("isolated", *one),
            ("episode_open", *one),
            ("insufficient_excitation", *one),
            ("diagnosis_left", *one),
            ("samples", *one),
            ("skipped", *one),
            ("alarm_resets", *one),
            ("ekf_reparameterisations", *one),
            ("episodes_dismissed", *one),
            ("ekf_fit_run", *one),
            ("ekf_divergence_resets", *one),
            ("nf_divergence_resets", *one),
    )
    return StateLayout(entries, _SCALAR_BLOCKS, frozenset({"ekf_P", "nf_P", "nf_R", "nf_W", "theta_window", "glr_sums"}))


# Counters and flags of the state (every other block is a vector or matrix, whatever its size).
_SCALAR_BLOCKS = frozenset(
    {
        "wssr_count",
        "nf_gain",
        "nf_forgetting",
        "nf_age",
        "nf_settled",
        "nf_converged",
        "nominal_count",
        "nominal_frozen",
        "isolated",
        "episode_open",
        "insufficient_excitation",
        "diagnosis_left",
        "samples",
        "skipped",
        "alarm_resets",
        "ekf_reparameterisations",
        "episodes_dismissed",
        "ekf_fit_run",
        "ekf_divergence_resets",
        "nf_divergence_resets",
    }
)


def _check_sizes(plant: NonlinearPlant, window: int, classifier_window: int, detector: str = "wssr") -> None:
    """The limits that need no step: dimensions and state size (module docstring)."""
    for what, count in (("states", plant.n), ("inputs", plant.m), ("outputs", plant.p), ("parameters", plant.l)):
        if count > MAX_DIMENSION:
            raise ArgumentError(f"the plant has {count} {what}; the NAFDF allows at most {MAX_DIMENSION}")
    size = _layout(plant.n, plant.l, window, classifier_window, detector, plant.p).size
    if size > MAX_STATE:
        raise ArgumentError(
            f"the diagnoser state would have {size} entries (window {window}, classifier_window {classifier_window}, "
            f"{plant.n} states, {plant.l} parameters); at most {MAX_STATE} are allowed"
        )


def _settings(plant: NonlinearPlant, **kw: Any) -> NafdfSettings:
    """Validate the keywords of :func:`~fdisyn.synthesis.nafdf.design.nafdf` (also applied to a gain file's stored settings).

    Sizes first (windows, counters, dimensions, state size), then every
    vector and matrix: shapes, finiteness, definiteness, ranges, the box.
    Raises :class:`ArgumentError` or :class:`ShapeError` naming the setting.
    """
    n, m, l = plant.n, plant.m, plant.l  # noqa: E741 — the paper's letter for dim θ
    window = _positive_int(kw["window"], "window", MAX_WINDOW)
    n2 = _positive_int(kw["classifier_window"], "classifier_window", MAX_CLASSIFIER_WINDOW)
    detector = kw.get("detector", "wssr")
    if detector not in DETECTORS:
        raise ArgumentError(f"detector must be one of {', '.join(map(repr, DETECTORS))}; got {shown(detector)}")
    _check_sizes(plant, window, n2, detector)
    th_nom = np.asarray(plant.theta_nominal)
    rule = kw["threshold_rule"]
    if rule not in ("chi2", "beta0"):
        raise ArgumentError(f"threshold_rule must be 'chi2' or 'beta0'; got {shown(rule)}")
    if rule == "beta0" and detector != "wssr":
        raise ArgumentError(f"threshold_rule 'beta0' is the paper's WSSR threshold; detector {detector!r} takes its threshold from P_f or arl0")
    given_shift = kw.get("min_shift")  # None: not given (the CUSUM's default, DEFAULT_MIN_SHIFT)
    if given_shift is not None and detector != "cusum":  # any value, the default's too: it would be ignored
        raise ArgumentError(
            f"min_shift = {shown(given_shift)} is read only by the detector 'cusum' (its designed shift); the detector "
            f"here is {detector!r}: remove min_shift, or choose detector = 'cusum'"
        )
    min_shift = DEFAULT_MIN_SHIFT if given_shift is None else _number(given_shift, "min_shift")
    if not (math.isfinite(min_shift) and MIN_SHIFT_RANGE[0] <= min_shift <= MIN_SHIFT_RANGE[1]):
        raise ArgumentError(
            f"min_shift must be a number of standard deviations in [{MIN_SHIFT_RANGE[0]:g}, {MIN_SHIFT_RANGE[1]:g}]; "
            f"got {shown(given_shift)}"
        )
    arl0 = None if kw.get("arl0") is None else _number(kw["arl0"], "arl0")
    p_f = kw["false_alarm_probability"]
    # the detector's statistics share its run length: 2p one-sided CUSUMs, p GLRs, one WSSR
    shares = {"cusum": 2 * plant.p, "glr": plant.p}.get(detector, 1)
    if arl0 is not None:
        p_f = _budget_rate(arl0, float(plant.Ts or 1.0), n2, shares)
    elif real_number(p_f) is not None and 0.0 < float(p_f) < 1.0 and not float(p_f) * MAX_ARL_SAMPLES >= shares:
        raise ArgumentError(
            f"false_alarm_probability (P_f) = {shown(p_f)} with detector {detector!r} gives its {shares} statistics a mean run "
            f"length of more than {MAX_ARL_SAMPLES:g} samples each; expected P_f ≥ {shares / MAX_ARL_SAMPLES:g}"
        )
    if detector == "cusum" and real_number(p_f) is not None and 0.0 < float(p_f) < 1.0:
        _check_shift(min_shift, given_shift, float(p_f), 2 * plant.p, "P_f" if arl0 is None else "arl0",
                     kw["false_alarm_probability"] if arl0 is None else kw["arl0"])
    lo = np.full(l, -np.inf) if kw["theta_lower"] is None else _vec(kw["theta_lower"], "theta_lower", l)
    hi = np.full(l, np.inf) if kw["theta_upper"] is None else _vec(kw["theta_upper"], "theta_upper", l)
    if np.any(np.isnan(lo)) or np.any(np.isnan(hi)) or np.any(lo >= hi) or np.any(lo == np.inf) or np.any(hi == -np.inf):
        raise ArgumentError(f"theta_lower must be below theta_upper for every parameter; got {shown(lo.tolist())} and {shown(hi.tolist())}")
    w1, w2 = _number(kw["W1"], "W1"), _number(kw["W2"], "W2")
    if not 0.0 <= w1 < w2 or not math.isfinite(w2):
        raise ArgumentError(f"the classifier thresholds must satisfy 0 <= W1 < W2 < inf; got W1 = {kw['W1']}, W2 = {kw['W2']}")
    jump = _isolable_jump(kw.get("isolable_jump"), kw.get("convergence_tolerance"), th_nom, w1)
    th0 = th_nom.copy() if kw["theta0"] is None else _finite_vec(kw["theta0"], "theta0", l)
    beta0 = None if kw["beta0"] is None else _number(kw["beta0"], "beta0")
    if beta0 is not None and not (math.isfinite(beta0) and beta0 > 0):
        raise ArgumentError(f"beta0 must be a positive finite number; got {shown(kw['beta0'])}")
    settings = NafdfSettings(
        x0=frozen_array(_finite_vec(kw["x0"], "x0", n)),
        P0=frozen_array(_spd(kw["P0"], "P0", n)),
        theta0=frozen_array(th0),
        R0=frozen_array(_spd(np.eye(l) if kw["R0"] is None else kw["R0"], "R0", l)),
        window=window,
        threshold_rule=rule,
        false_alarm_probability=_unit_open(p_f, "false_alarm_probability"),
        beta0=beta0,
        forgetting_initial=_unit_interval(kw["forgetting_initial"], "forgetting_initial"),
        forgetting_rate=_unit_open(kw["forgetting_rate"], "forgetting_rate"),
        forgetting_final=_unit_interval(kw["forgetting_final"], "forgetting_final"),
        theta_lower=frozen_array(lo),
        theta_upper=frozen_array(hi),
        nominal_samples=_positive_int(kw["nominal_samples"], "nominal_samples"),
        classifier_window=n2,
        W1=w1,
        W2=w2,
        T1=_positive_int(kw["T1"], "T1"),
        isolable_jump=frozen_array(jump),
        convergence_level=_unit_open(kw["convergence_level"], "convergence_level"),
        detector=detector,
        min_shift=min_shift,
        arl0=arl0,
        u0=frozen_array(np.zeros(m) if kw["u0"] is None else _finite_vec(kw["u0"], "u0", m)),
        threshold_scale=_threshold_scale(kw.get("threshold_scale", 1.0)),
    )
    for key, value in settings.to_dict().items():  # the gain file holds no number beyond MAX_MAGNITUDE
        big = [z for z in np.ravel(np.asarray(value, dtype=object)) if isinstance(z, float) and math.isfinite(z) and abs(z) > MAX_MAGNITUDE]
        if big:
            raise ArgumentError(
                f"{key} holds {big[0]!r}; a design's numbers must be at most {MAX_MAGNITUDE:g} in magnitude (its gain file "
                "holds no larger ones: they would overflow its consistency checks); rescale the model's units"
            )
    if np.any(settings.theta0 < lo) or np.any(settings.theta0 > hi):
        raise ArgumentError(
            f"theta0 = {shown(settings.theta0.tolist())} lies outside the parameter box "
            f"[{shown(lo.tolist())}, {shown(hi.tolist())}]"
        )
    return settings


def largest_min_shift(rate: float, statistics: int) -> float:
    """The supremum of the CUSUM shifts whose threshold is positive at a false-alarm ``rate`` per sample.

    Page's CUSUM with increment ``δw − δ²/2`` and threshold ``h = 0`` alarms whenever ``w > δ/2``: its run length
    is ``1/Q(δ/2)`` samples (``Q`` the standard normal tail; :func:`~fdisyn.detectors.sequential.cusum_arl` at
    ``h = 0``). When that already meets each statistic's share ``statistics/rate``, no positive threshold is
    needed and the design has none (the certificate wants ``h > 0``): ``δ < 2 Q⁻¹(rate/statistics)``.

    Parameters
    ----------
    rate : float
        The detector's false-alarm rate per sample (``P_f``, or the one ``arl0`` gives), in (0, 1).
    statistics : int
        The one-sided CUSUMs sharing it (two per output).

    Returns
    -------
    float
        ``2 Q⁻¹(rate/statistics)`` (0 when the share is at least one half).
    """
    from scipy.stats import norm

    return max(0.0, 2.0 * float(norm.isf(rate / statistics)))


def _check_shift(min_shift: float, given: object, rate: float, statistics: int, key: str, budget: object) -> None:
    """Refuse a CUSUM shift at or beyond :func:`largest_min_shift`, naming it and the budget as they were given."""
    most = largest_min_shift(rate, statistics)
    if min_shift < most:
        return
    head = (
        f"min_shift = {'1 (its default)' if given is None else shown(given)} with {key} = {shown(budget)}{' s' if key == 'arl0' else ''}: the CUSUM's threshold "
        f"would be 0 (one normalised innovation beyond min_shift/2 already meets the budget of its {statistics} one-sided statistics)"
    )
    if most <= MIN_SHIFT_RANGE[0]:
        remedy = "a smaller P_f" if key == "P_f" else "a larger arl0"
        raise ArgumentError(f"{head}; no min_shift ≥ {MIN_SHIFT_RANGE[0]:g} works at so high a false-alarm rate: give {remedy}")
    step = 10.0 ** (math.floor(math.log10(most)) - 3)  # the bound shown rounded down to 4 digits: it works as written
    raise ArgumentError(f"{head}; expected min_shift < {math.floor(most / step) * step:.4g} for this budget")


THRESHOLD_SCALE_RANGE = (1e-3, 1e3)
"""The factors the fast detection's thresholds may be scaled by (:attr:`NafdfSettings.threshold_scale`): three
decades either way, far beyond any operating characteristic's, and no threshold leaves a double's range."""


def _threshold_scale(value: object) -> float:
    """A threshold scale checked: a finite number in :data:`THRESHOLD_SCALE_RANGE`."""
    v = real_number(value)
    lo, hi = THRESHOLD_SCALE_RANGE
    if v is None or not (math.isfinite(v) and lo <= v <= hi):
        raise ArgumentError(f"threshold_scale must be a number in [{lo:g}, {hi:g}] (1: the budget's thresholds); got {shown(value)}")
    return float(v)


def _budget_rate(arl0: float, ts: float, n2: int, shares: int = 1) -> float:
    """The detector's false-alarm rate per sample for a diagnoser budget of ``arl0`` seconds: ``1/(arl0/Ts − 2 N2)``.

    A false alarm opens an episode that the dismissal closes no sooner than ``2 N2`` samples later (``N2`` until
    the test may start, ``N2`` passing windows), and the detector cannot alarm again inside it: the time between
    false alarms is the detector's run length plus the episode. Its ``shares`` statistics each run ``shares``
    times as long: at most :data:`~fdisyn.detectors.sequential.MAX_ARL_SAMPLES` samples.
    """
    if not (math.isfinite(arl0) and arl0 > 0):
        raise ArgumentError(f"arl0 must be a positive finite number of seconds; got {shown(arl0)}")
    run = arl0 / ts - 2 * n2
    if not run * shares <= MAX_ARL_SAMPLES:  # inf when arl0/Ts overflows: the value is shown as given
        raise ArgumentError(
            f"arl0 = {shown(arl0)} s gives each of the detector's {shares} statistics a mean run length of more than "
            f"{MAX_ARL_SAMPLES:g} samples; expected arl0 ≤ {(MAX_ARL_SAMPLES / shares + 2 * n2) * ts:.6g} s "
            "(the thresholds are computed up to that run length)"
        )
    if run < 2.0:
        raise ArgumentError(
            f"arl0 = {arl0:g} s leaves no time between false alarms: an episode lasts at least 2·classifier_window = {2 * n2} "
            f"samples ({2 * n2 * ts:g} s); expected arl0 > {(2 * n2 + 2) * ts:g} s"
        )
    return 1.0 / run


DEFAULT_JUMP_FRACTION = 0.5
"""The default ``isolable_jump``: this fraction of ``|θ0_i|`` (of 1 for a zero nominal), the paper's fault
(Zhou, Xi & Zhang 1991, section 3: ``a → a0/2``)."""


def _isolable_jump(jump: object, tolerance: object, th_nom: np.ndarray, w1: float) -> np.ndarray:
    """``isolable_jump`` as given, from the deprecated ``convergence_tolerance``, or the default.

    ``convergence_tolerance`` (before payload version 3: the largest range of ``θ̂_i`` over ``N2``
    samples) is read as the largest standard deviation of ``θ̂_i``: ``isolable_jump_i = √W1 · tol_i``.
    """
    l = th_nom.size  # noqa: E741 — the paper's letter for dim θ
    if jump is not None and tolerance is not None:
        raise ArgumentError("give isolable_jump or the deprecated convergence_tolerance, not both")
    if tolerance is not None:
        tol = _vec(tolerance, "convergence_tolerance", l)
        if np.any(~np.isfinite(tol)) or np.any(tol <= 0):
            raise ArgumentError(f"convergence_tolerance must be positive and finite; got {shown(tol.tolist())}")
        if w1 <= 0:  # W1 = 0: no bound, whatever the tolerance
            return np.full(l, np.inf)
        with np.errstate(over="ignore"):  # a tolerance near the double range: no bound either
            return math.sqrt(w1) * tol
    if jump is None:
        return np.where(th_nom != 0.0, DEFAULT_JUMP_FRACTION * np.abs(th_nom), DEFAULT_JUMP_FRACTION)
    out = _vec(jump, "isolable_jump", l)
    if np.any(np.isnan(out)) or np.any(out <= 0):
        raise ArgumentError(f"isolable_jump must be positive (inf: no information bound); got {shown(out.tolist())}")
    return out


def _unit_interval(value: float, name: str) -> float:
    v = _number(value, name)
    if not 0.0 < v <= 1.0:
        raise ArgumentError(f"{name} must lie in (0, 1]; got {shown(value)}")
    return v

