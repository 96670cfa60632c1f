"""The detectors a linear diagnoser offers, one :class:`Detector` per statistic kind.

Each detector's module (:mod:`fdisyn.detectors.chi2`, :mod:`~fdisyn.detectors.wssr`,
:mod:`~fdisyn.detectors.sequential`) registers its entry with :func:`register` when it is imported
(:mod:`fdisyn.detectors` imports every module of the package); the bank's checks and evaluators
(:mod:`fdisyn.synthesis.linear_diagnoser`), the option ``detector`` (:mod:`fdisyn.synthesis.registry`),
the linear step (:mod:`fdisyn.synthesis.linear_step`) and the methods read :data:`DETECTORS` and name
no detector. The runtime's oracle and gain-file rules for the same kinds are
:data:`fdisyn.runtime.schema.EVALUATOR_KINDS` and its modules.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from fdisyn.numerics.account import SizeLaw
from fdisyn.runtime.statistics import STATISTICS

__all__ = ["Detector", "BankRequest", "DETECTORS", "register", "windowed_kinds", "quoted", "option_texts"]


@dataclass(frozen=True)
class BankRequest:
    """What a detector's :attr:`Detector.evaluators` builds a bank's statistics from.

    Attributes
    ----------
    plant : Any
        The discrete plant the generators were designed on.
    generators : Sequence
        The bank's residual generators.
    sigma_r : Sequence
        Each generator's steady-state residual covariance.
    faults : Sequence
        The fault classes to isolate.
    arl_samples : float
        Each statistic's share of the false-alarm budget, in samples (``1 / P_f`` without ``arl0``).
    window : int or None
        The option ``window`` (``None``: the detector's own choice).
    min_fault : Mapping or None
        The option ``min_fault``.
    autocovariances : Callable
        ``autocovariances(generator, lags)``: its residual's ``R(0) … R(lags)`` on ``plant``.
    sequential : Callable
        ``sequential(detector)``: the bank whitened, one statistic per generator built by the detector's
        :attr:`Detector.hypotheses`; returns ``(evaluators, generators, sigma_r, info)``.
    """

    plant: Any
    generators: Sequence[Any]
    sigma_r: Sequence[Any]
    faults: Sequence[Any]
    arl_samples: float
    window: int | None
    min_fault: Mapping[str, float] | None
    autocovariances: Callable[[Any, int], Any]
    sequential: Callable[["Detector"], tuple[list[Any], list[Any], list[Any], dict[str, Any]]]


@dataclass(frozen=True)
class Detector:
    """One statistic kind of a linear diagnoser: its option text, its rules and how it is built and stepped.

    Attributes
    ----------
    kind : str
        The evaluator's ``kind`` in the gain file (one of :data:`fdisyn.runtime.schema.EVALUATOR_KINDS`).
    doc : str
        Its clause in the option ``detector``'s text (after its quoted kind).
    windowed : bool
        It reads the option ``window`` (otherwise the window must be 1 or not given).
    no_window : str
        The bank's refusal of a window on a detector that has none, ``{window}`` standing for the value shown;
        empty for a windowed detector.
    sequential : bool
        It runs on whitened residuals against its fault hypotheses, accumulates the evidence itself
        (persistence must be 1) and reads ``min_fault``.
    evaluators : Callable
        ``evaluators(request)``: the bank's statistics (:class:`BankRequest`); returns ``(evaluators,
        generators, sigma_r, info)`` — a sequential detector returns the whitened generators and its table.
    hypotheses : Callable or None
        A sequential detector's statistic of one whitened generator: ``hypotheses(gi, sigma, visible,
        steady, infos, arl_samples, window, response, shifts)`` with ``steady[k]`` the steady-state residual of fault
        class ``k``, ``infos[k]`` its information per sample and ``response(k, m)`` its first ``m`` samples;
        ``shifts`` the option ``shifts`` (``None``: not given); ``None`` otherwise.
    statistic : Any
        Its symbolic update in the linear step (:class:`fdisyn.detectors.symbolic.LinearStatistic`).
    size_law : SizeLaw
        The law of its smallest detectable fault in the account of what a design can see
        (:class:`fdisyn.numerics.account.SizeLaw`: its computation and its wording).
    cited : str
        How a report names it, with its source (e.g. ``"CUSUM (Page, Biometrika 41(1/2), 1954)"``).
    window_doc : str
        A windowed detector's clause in the option ``window``'s text: what its window is.
    window_default : str
        A windowed detector's window when the option is not given, in words.
    reads_shifts : bool
        Its hypotheses read the option ``shifts`` (the whitened mean shifts each is tuned to).
    null_law : Callable or None
        ``null_law(ev)``: its statistic's exact law without a fault, ``(density, label)`` with ``density(x)`` the
        probability density the report draws over the fault-free histogram (e.g. χ²(dof)); ``None``: no closed
        form (the report draws the empirical tail against ``P_f``).
    """

    kind: str
    doc: str
    windowed: bool
    no_window: str
    sequential: bool
    evaluators: Callable[[BankRequest], tuple[list[Any], list[Any], list[Any], dict[str, Any]]]
    statistic: Any
    size_law: SizeLaw
    cited: str
    hypotheses: Callable[..., Any] | None = None
    window_doc: str = ""
    window_default: str = ""
    null_law: Callable[[Any], tuple[Callable[[Any], Any], str]] | None = None
    reads_shifts: bool = False


DETECTORS: dict[str, Detector] = {}
"""Every registered detector by kind, in the order of :data:`fdisyn.runtime.schema.EVALUATOR_KINDS` (a kind the
runtime does not know last)."""


def register(detector: Detector) -> Detector:
    """Add ``detector`` to :data:`DETECTORS` (called by the detector's own module).

    Parameters
    ----------
    detector : Detector
        The entry.

    Returns
    -------
    Detector
        The entry, registered.
    """
    DETECTORS[detector.kind] = detector
    order = list(STATISTICS)  # the gain file's order, whatever order the modules are imported in
    ranked = sorted(DETECTORS.items(), key=lambda kv: order.index(kv[0]) if kv[0] in order else len(order))
    DETECTORS.clear()
    DETECTORS.update(ranked)
    return detector


def quoted(kinds: Sequence[str], last: str = "or") -> str:
    """``'a', 'b' or 'c'``: the kinds as the option texts list them.

    Parameters
    ----------
    kinds : Sequence of str
        The kinds.
    last : str
        The word before the last one.

    Returns
    -------
    str
        The list.
    """
    names = [repr(k) for k in kinds]
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} {last} {names[-1]}"


def windowed_kinds() -> tuple[str, ...]:
    """The registered detectors that read the option ``window``.

    Returns
    -------
    tuple of str
        Their kinds, in registration order.
    """
    return tuple(k for k, d in DETECTORS.items() if d.windowed)


def option_texts() -> dict[str, str]:
    """The texts of the linear methods' options that list the detectors, composed from :data:`DETECTORS`.

    Returns
    -------
    dict of str to str
        ``"kinds"``: the kinds as an option's domain (``'a', 'b' or 'c'``); ``"detector"``: each detector's
        clause of the option ``detector``; ``"sequential"``: the sequential kinds (``'a' and 'b'``);
        ``"window"``: what a window is, detector by detector; ``"window_default"``: each windowed detector's
        default window.
    """
    windowed = [d for d in DETECTORS.values() if d.windowed]
    return {
        "kinds": quoted(list(DETECTORS)),
        "detector": "; ".join(f"{k!r}, {d.doc}" for k, d in DETECTORS.items()),
        "sequential": quoted([k for k, d in DETECTORS.items() if d.sequential], "and"),
        "window": ", or ".join(d.window_doc for d in windowed),
        "window_default": ", ".join(f"{d.window_default} for {d.kind!r}" for d in windowed),
    }
