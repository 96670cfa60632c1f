"""What a diagnoser kind means: one :class:`DiagnoserKind` per kind, and the step contract every kind's step honours.

A gain file's ``kind`` (``"linear"``, ``"nafdf"``, ``"beard_fdf"``, ...) names what its payload means downstream:
its CasADi step, the Monte Carlo's recovery window and extra figures, its false-alarm budget and Lorden bound,
the certificate blocks and the prose its page shows, and how the command line describes it. Each kind lives in its
own module of :mod:`fdisyn.synthesis`, which calls :func:`register_kind` when it is imported; the kinds are found
like the methods (every module of :data:`PLUGIN_PACKAGES` is imported the first time one is looked up), so adding a
kind needs no other edit. A :class:`~fdisyn.synthesis.registry.Method` names the kind its designs produce.

Contract (shared by every diagnoser kind, and by the generated C)::

    step(state[nstate], u[nu], y[ny]) -> (state_next[nstate], r[nr], J[nj],
                                          alarm[1], isolated[1], status[1])

all dense double vectors; ``alarm`` ∈ {0, 1}; ``isolated`` ∈ {−1, 0..nf−1};
``status`` 1 when the sample held a non-finite value (see
:mod:`fdisyn.runtime.reference` for the linear semantics). A kind names its independent NumPy reference run
(:attr:`DiagnoserKind.reference`, :func:`reference_run`), against which its CasADi step and generated C are checked;
tests/design/test_kind_contract.py holds every registered kind to this contract.

Importing this module is light (no CasADi, no cvxpy).
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from fdisyn.runtime.errors import ArgumentError, GainFileError
from fdisyn.runtime.gainfile import GainFile
from fdisyn.runtime.reference import RunResult

__all__ = [
    "STEP_INPUTS",
    "STEP_OUTPUTS",
    "PLUGIN_PACKAGES",
    "ExtraMetrics",
    "DiagnoserKind",
    "payload_certificate",
    "step_states",
    "register_kind",
    "get_kind",
    "all_kinds",
    "kind_names",
    "discover",
    "discovered",
    "find_kind",
    "recovery_samples",
    "false_alarm_budget",
    "lorden_bound",
    "lorden_window",
    "onset_lorden_bound",
    "reference_run",
]

STEP_INPUTS = ("state", "u", "y")
STEP_OUTPUTS = ("state_next", "r", "J", "alarm", "isolated", "status")

PLUGIN_PACKAGES: list[str] = ["fdisyn.synthesis"]
"""Packages whose modules are imported to discover the kinds and the methods (each module registers its own)."""


@dataclass(frozen=True, eq=False)
class ExtraMetrics:
    """Monte Carlo figures of one scenario beyond detection, computed run by run and then reduced.

    ``per_run(scenario, gain_file, run)`` summarises one run (``run``: ``alarm``,
    ``isolated``: ``N``; ``J``: ``N × nj``) by a few numbers (anything picklable);
    ``reduce(scenario, gain_file, values)`` turns the runs' values, in run order,
    into ``{name: figure}``. The Monte Carlo keeps only the values, never the
    runs. Called on stacked runs (``runs × N`` arrays) it gives the same figures
    at once.
    """

    per_run: Callable[[Any, GainFile, Mapping[str, np.ndarray]], Any]
    reduce: Callable[[Any, GainFile, list[Any]], Mapping[str, Any]]

    def __call__(self, scenario: Any, gf: GainFile, runs: Mapping[str, np.ndarray]) -> Mapping[str, Any]:
        n = len(runs["alarm"])
        values = [self.per_run(scenario, gf, {k: np.asarray(v)[i] for k, v in runs.items()}) for i in range(n)]
        return self.reduce(scenario, gf, values)


def _no_recovery(gf: GainFile) -> int:
    return 0


def payload_certificate(gf: GainFile) -> list[Mapping[str, Any]]:
    """The certificate block of a kind whose certificate is one block named after it: ``[gf.certificate[gf.kind]]``
    (the default :attr:`DiagnoserKind.certified`)."""
    return [gf.certificate[gf.kind]]


def step_states(gf: GainFile) -> str:
    """``"a KIND step with N states"`` (the default :attr:`DiagnoserKind.describe`)."""
    return f"a {gf.kind} step with {gf.step.nstate} states"


@dataclass(frozen=True, eq=False)
class DiagnoserKind:
    """What the gain files of one diagnoser kind mean downstream of their design.

    Parameters
    ----------
    name : str
        The gain files' ``kind`` (an identifier).
    summary : str
        One line: what a diagnoser of this kind is.
    step_builder : callable
        ``GainFile -> casadi.Function`` with the step contract (:data:`STEP_INPUTS`, :data:`STEP_OUTPUTS`).
    certified : callable, optional
        ``GainFile -> list of Mapping``: the certificate blocks its page shows, each with its ``checks`` (default:
        :func:`payload_certificate`).
    describe : callable, optional
        ``GainFile -> str``: one phrase for the command line (``"3 generators"``; default: :func:`step_states`).
    rate_unit : str
        How a false-alarm rate ``P_f`` of this kind is worded (``"per sample"``).
    recovery_samples : callable
        ``GainFile -> int``: samples after a fault's end during which alarms are not false alarms.
    extra_metrics : ExtraMetrics or None
        Monte Carlo figures of one scenario beyond detection (None: none).
    false_alarm_budget : callable or None
        ``GainFile -> seconds or None``: the designed mean time between false alarms (None: the kind has none,
        or a gain file whose thresholds were given).
    lorden_bound : callable or None
        ``(GainFile, μ, Σ) -> (I, ln(ARL)/I) or None``: the information per sample of a fault that shifts the
        residual's mean by ``μ`` (``Σ``: the residual's covariance without the fault) and the Lorden bound on
        its delay (samples).
    lorden_information : callable or None
        ``(GainFile, M, Σ) -> [(ARL_j, I_j), …]``: per statistic ``j``, its false-alarm budget in samples and the
        information per sample ``I_j`` (an array, one per row of ``M``) of each mean shift in the rows of ``M``
        (``m × nr``) — the measure :attr:`lorden_bound` takes, per statistic; the onset-aware bound
        (:func:`onset_lorden_bound`) sums it lag by lag. None: the kind has no onset-aware bound.
    lorden_window : callable or None
        ``GainFile -> int``: samples after a fault's onset over which its mean shift is measured (None: while
        it is active) — for a diagnoser that adapts its model to the fault, the samples before it can.
    budget_text : str or None
        The page's prose (HTML) on how the kind's false-alarm budget is set (None: the page's general text).
    detectors_text : str or None
        The page's phrase (HTML) naming the detectors its comparison at one false-alarm budget sets side by side (None:
        the detectors the variants name, "statistics of the same generators").
    account_view : callable or None
        ``GainFile -> BankView``: the diagnoser as a bank of linear generators, on which the account of what it can
        see is computed (:mod:`fdisyn.numerics.account`); None: the kind has no account.
    account_note : str or None
        Why the kind has no account (printed by ``fdisyn design``, shown on its page).
    warmups : callable or None
        ``GainFile -> tuple of int``: the warm-up of each of its generators, in samples (:mod:`fdisyn.runtime.warmup`);
        None: the kind has none.
    reference : callable or None
        ``(GainFile, U, Y) -> RunResult``: the kind's independent NumPy run over a trace (``U``: ``T × nu``,
        ``Y``: ``T × ny``) from the gain file's initial state, written from the specification without CasADi, against
        which its CasADi step and generated C are checked (:func:`reference_run`); None: the kind has none, and its C
        is checked against its CasADi step only.
    threshold_scaled : callable or None
        ``(GainFile, scale, name) -> GainFile``: a copy named ``name`` whose alarm thresholds are ``scale`` times
        the diagnoser's, for a kind whose decisions at other thresholds do not follow from one run's statistics (an
        alarm that restarts the diagnoser's learning): its operating characteristic is measured on such copies run
        beside it (:func:`fdisyn.evaluation.built.threshold_copies`). None: the kind has none (a linear diagnoser's
        is read from its own statistics).
    """

    name: str
    summary: str
    step_builder: Callable[[GainFile], Any]
    """``GainFile -> casadi.Function`` (annotated ``Any``: CasADi is not imported here)."""
    certified: Callable[[GainFile], list[Mapping[str, Any]]] = payload_certificate
    describe: Callable[[GainFile], str] = step_states
    rate_unit: str = "per sample"
    recovery_samples: Callable[[GainFile], int] = _no_recovery
    extra_metrics: ExtraMetrics | None = None
    false_alarm_budget: Callable[[GainFile], float | None] | None = None
    lorden_bound: Callable[[GainFile, np.ndarray, np.ndarray], tuple[float, float] | None] | None = None
    lorden_window: Callable[[GainFile], int] | None = None
    lorden_information: Callable[[GainFile, np.ndarray, np.ndarray], list[tuple[float, np.ndarray]]] | None = None
    budget_text: str | None = None
    detectors_text: str | None = None
    account_view: Callable[[GainFile], Any] | None = None
    """``GainFile -> fdisyn.numerics.account.BankView`` (annotated ``Any``: SciPy is not imported here)."""
    account_note: str | None = None
    reference: Callable[[GainFile, np.ndarray, np.ndarray], RunResult] | None = None
    warmups: Callable[[GainFile], tuple[int, ...]] | None = None
    threshold_scaled: Callable[[GainFile, float, str], GainFile] | None = None


_KINDS: dict[str, DiagnoserKind] = {}
_SCANNED: set[str] = set()
_DISCOVERING = 0


def register_kind(kind: DiagnoserKind) -> DiagnoserKind:
    """Make ``kind`` known by its name (its module calls this when it is imported).

    Parameters
    ----------
    kind : DiagnoserKind
        The kind to register.

    Returns
    -------
    DiagnoserKind
        ``kind`` itself.

    Raises
    ------
    ArgumentError
        Its name is no identifier, or another kind of that name is registered.
    """
    if not isinstance(kind.name, str) or not kind.name.isidentifier():
        raise ArgumentError(f"a diagnoser kind's name is an identifier (gain files name it); got {kind.name!r}")
    other = _KINDS.get(kind.name)
    if other is not None and other is not kind:
        raise ArgumentError(f"diagnoser kind {kind.name!r} is registered twice; one kind, one DiagnoserKind: rename one")
    _KINDS[kind.name] = kind
    return kind


def discover() -> None:
    """Import every module of :data:`PLUGIN_PACKAGES` not yet scanned (each registers its kinds and methods)."""
    global _DISCOVERING
    _DISCOVERING += 1
    try:
        for pkg_name in list(PLUGIN_PACKAGES):
            if pkg_name in _SCANNED:
                continue
            _SCANNED.add(pkg_name)
            pkg = importlib.import_module(pkg_name)
            for mod in pkgutil.walk_packages(pkg.__path__, f"{pkg_name}."):
                if not mod.name.rsplit(".", 1)[-1].startswith("_"):
                    importlib.import_module(mod.name)
    finally:
        _DISCOVERING -= 1


def discovered() -> bool:
    """Whether every module of :data:`PLUGIN_PACKAGES` has been imported (and none is being imported by
    :func:`discover`): the kind table is then complete."""
    return _DISCOVERING == 0 and all(p in _SCANNED for p in PLUGIN_PACKAGES)


def kind_names() -> list[str]:
    """The names of the registered kinds, sorted."""
    discover()
    return sorted(_KINDS)


def all_kinds() -> list[DiagnoserKind]:
    """Every registered kind, by name."""
    return [_KINDS[k] for k in kind_names()]


def find_kind(name: str) -> DiagnoserKind | None:
    """The kind ``name``, or None when no module registers it."""
    if not isinstance(name, str):
        return None
    if name not in _KINDS:
        discover()
    return _KINDS.get(name)


def get_kind(name: str) -> DiagnoserKind:
    """The diagnoser kind ``name`` (a gain file's ``kind``).

    Parameters
    ----------
    name : str
        The kind's name.

    Returns
    -------
    DiagnoserKind

    Raises
    ------
    GainFileError
        No kind of that name is registered (the message lists the known ones).
    """
    kind = find_kind(name)
    if kind is None:
        raise GainFileError(f"no step builder for diagnoser kind {name!r}; known kinds: {kind_names()}")
    return kind


def recovery_samples(gf: GainFile) -> int:
    """Samples after a fault during which the gain file's statistics still carry it (:attr:`DiagnoserKind.recovery_samples`)."""
    return int(get_kind(gf.kind).recovery_samples(gf))


def warmup_text(gf: GainFile) -> str | None:
    """The gain file's warm-up as the pages and the command line show it: ``"4"``, ``"2–5"`` when its generators'
    differ, ``"0"`` (it starts at its first sample's equilibrium); None: its kind has none.

    Parameters
    ----------
    gf : GainFile
        Any gain file.

    Returns
    -------
    str or None
        The span of its generators' warm-ups in samples (:attr:`DiagnoserKind.warmups`).
    """
    of = get_kind(gf.kind).warmups
    lengths = sorted(set(of(gf))) if of is not None else []
    if not lengths:
        return None
    return str(lengths[0]) if len(lengths) == 1 else f"{lengths[0]}–{lengths[-1]}"


def false_alarm_budget(gf: GainFile) -> float | None:
    """The gain file's designed mean time between false alarms in seconds (None: its kind has none)."""
    budget = get_kind(gf.kind).false_alarm_budget
    seconds = None if budget is None else budget(gf)
    return None if seconds is None else float(seconds)


def lorden_bound(gf: GainFile, shift: np.ndarray, covariance: np.ndarray) -> tuple[float, float] | None:
    """``(I, bound)`` of a residual mean shift for the gain file's kind (:attr:`DiagnoserKind.lorden_bound`; None: none)."""
    bound = get_kind(gf.kind).lorden_bound
    return None if bound is None else bound(gf, shift, covariance)


def onset_lorden_bound(
    gf: GainFile, lag_shifts: np.ndarray, shift: np.ndarray, covariance: np.ndarray, lag_noise: np.ndarray | None = None
) -> float | None:
    """The onset-aware Lorden bound of a fault whose mean residual shift builds up after its onset, in samples.

    With ``I_j(ℓ)`` the information per sample the shift ``ℓ`` samples after the onset brings to statistic ``j``
    (the kind's :attr:`DiagnoserKind.lorden_information`, the measure of its :attr:`DiagnoserKind.lorden_bound`),
    the bound is the smallest over the statistics of the smallest ``n`` with ``Σ_{ℓ<n} I_j(ℓ) ≥ ln(ARL_j)``
    (:func:`fdisyn.detectors.sequential.onset_lorden_delay`; Lai, IEEE Transactions on Information Theory 44(7),
    1998), the rows of ``lag_shifts`` giving the lags they cover and ``shift`` every later one. For a step (every
    row equal to ``shift``) it is the kind's ``ln(ARL_j)/I_j``.

    Parameters
    ----------
    gf : GainFile
        A gain file of a registered kind.
    lag_shifts : numpy.ndarray
        ``L × nr``: the mean residual shift at lags ``0, …, L−1`` after the onset.
    shift : numpy.ndarray
        ``nr``: the mean shift from lag ``L`` on.
    covariance : numpy.ndarray
        ``nr × nr``: the residual's covariance without the fault.
    lag_noise : numpy.ndarray, optional
        ``nr × nr``: the covariance of each row's estimation error (a Monte Carlo's: the residual's covariance over
        its runs). The information of a measured shift is biased up by its noise's, ``½ tr(W · lag_noise)`` for a
        measure ``½ μᵀ W μ``, which over many lags of a small shift outweighs the shift's own; it is subtracted
        (computed by the kind's measure on the noise's principal axes), each lag's information then an unbiased
        estimate. None: the rows are exact.

    Returns
    -------
    float or None
        The bound in samples; None when the kind has no per-lag information or no statistic sees the fault.

    Raises
    ------
    ArgumentError
        ``lag_shifts`` and ``shift`` disagree on the residual's size, or hold a non-finite value.
    """
    from fdisyn.detectors.sequential import onset_lorden_delay

    information = get_kind(gf.kind).lorden_information
    if information is None:
        return None
    lags = np.asarray(lag_shifts, dtype=float)
    tail = np.asarray(shift, dtype=float).reshape(-1)
    if lags.ndim != 2 or lags.shape[1] != tail.size:
        raise ArgumentError(f"the per-lag shifts are {lags.shape}, not L × {tail.size} (one row per lag, one column per residual)")
    if not (np.all(np.isfinite(lags)) and np.all(np.isfinite(tail))):
        return None
    rows = [lags, tail[None, :]]
    axes = np.zeros((0, tail.size))
    if lag_noise is not None:
        lam, vec = np.linalg.eigh(0.5 * (np.asarray(lag_noise, dtype=float) + np.asarray(lag_noise, dtype=float).T))
        keep = lam > 0
        axes = (vec[:, keep] * np.sqrt(lam[keep])).T  # Σ_k a_k a_kᵀ = lag_noise: Σ_k I(a_k) is the noise's information
        rows.append(axes)
    best = np.inf
    for arl, info in information(gf, np.vstack(rows), np.asarray(covariance, dtype=float)):
        info = np.asarray(info, dtype=float)
        if not np.all(np.isfinite(info)):
            continue
        n = lags.shape[0]
        per_lag = info[:n] - float(np.sum(info[n + 1 :]))
        best = min(best, onset_lorden_delay(arl, per_lag, max(float(info[n]), 0.0)))
    return float(best) if np.isfinite(best) else None


def lorden_window(gf: GainFile) -> int | None:
    """:attr:`DiagnoserKind.lorden_window` of the gain file's kind (None: the fault's whole active time)."""
    window = get_kind(gf.kind).lorden_window
    return None if window is None else int(window(gf))


def reference_run(gf: GainFile, U: np.ndarray, Y: np.ndarray) -> RunResult | None:
    """The gain file's run over a trace by its kind's independent NumPy reference (:attr:`DiagnoserKind.reference`).

    Parameters
    ----------
    gf : GainFile
        A gain file of a registered kind.
    U : numpy.ndarray
        Inputs, ``T × nu``.
    Y : numpy.ndarray
        Outputs, ``T × ny`` (non-finite values allowed: their samples have status 1).

    Returns
    -------
    RunResult or None
        ``r``, ``J``, ``alarm``, ``isolated`` and ``status`` per sample and the state after the last one, from
        ``gf.step.init_state``; None when the kind has no reference.

    Raises
    ------
    GainFileError
        Its kind is registered by no module.
    """
    run = get_kind(gf.kind).reference
    return None if run is None else run(gf, U, Y)
