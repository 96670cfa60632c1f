"""The statistics of a linear gain file, one :class:`Statistic` per evaluator ``kind`` (χ², WSSR, CUSUM, GLR).

Each entry holds what the runtime knows of its kind: the fields its evaluator has in the file and their
rules, its block of the step state, its release level, and its NumPy update and alarm rule — the
independent oracle (:class:`fdisyn.runtime.reference.LinearReference`) the generated steps are tested
against. The schema (:data:`~fdisyn.runtime.schema.EVALUATOR_KINDS`), the validator, the reader and writer,
the state layout and the reference iterate over :data:`STATISTICS` and name no statistic. The design side's
entry of each kind (its threshold from its law, its symbolic update) is :data:`fdisyn.detectors.table.DETECTORS`.

Each update adds, clamps and compares in the order the symbolic updates
(:mod:`fdisyn.detectors.symbolic`) follow: a window summed newest first, a CUSUM's increment before its
drift, a GLR's ``d·d·w``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from fdisyn.runtime.errors import GainFileError
from fdisyn.runtime.names import shown

__all__ = ["Statistic", "STATISTICS", "count_level", "cusum_flags", "held_level", "MAX_GLR_WINDOW", "MAX_WSSR_WINDOW", "glr_weights"]

MAX_GLR_WINDOW = 1000
"""Largest GLR onset window accepted: the step updates ``window`` sums per hypothesis and sample."""
MAX_WSSR_WINDOW = 100_000
"""Largest WSSR window accepted in a gain file. The window's ``q`` values are part of the state, so
``nstate`` ≤ :data:`~fdisyn.runtime.schema.LIMITS` ``["nstate"]`` bounds the windows of a compiled diagnoser further."""


@dataclass(frozen=True)
class Statistic:
    """One evaluator kind of a linear gain file (:class:`~fdisyn.runtime.gainfile.Evaluator`).

    Attributes
    ----------
    kind : str
        The evaluator's ``kind`` in the file.
    sequential : bool
        It accumulates evidence against fault hypotheses (``directions`` and ``hypotheses`` in the file,
        persistence 1) and its alarm holds until the evidence is gone.
    window_read : bool
        The reader requires ``window`` (otherwise it is 1 when not written).
    window_written : bool
        The writer writes ``window`` (a χ² evaluator's is 1 and left out, so its files stay as they were).
    window_rule : Callable
        ``window_rule(e, w)``: the validator's refusal of ``e.window`` (``w`` the field's path), or ``""``.
    vectors : tuple of str
        The evaluator's vector fields of its kind (``"drift"``, ``"information"``), read and written in order.
    rows_per_hypothesis : Callable
        ``rows_per_hypothesis(e)``: a sequential statistic's rows of ``directions`` per hypothesis.
    check_vectors : Callable or None
        ``check_vectors(e, w, rows, per)``: the validator's refusal of its vector fields (each already
        checked finite and within the magnitude limit), or ``""``.
    block : str or None
        The prefix of its block of the step state (:func:`fdisyn.runtime.layout.linear_state_layout`),
        ``None`` for none.
    block_rows : Callable
        ``block_rows(e)``: the rows of its block, ``None`` when the evaluator cannot have one.
    release : Callable
        ``release(e)``: where its raised alarm ends (:func:`fdisyn.runtime.gainfile.release_level`).
    onset_sums : bool
        Its block holds a GLR's onset sums (:func:`fdisyn.runtime.reference.glr_estimates`).
    prepare : Callable
        ``prepare(e)``: constants the update reads, computed once per diagnoser.
    update : Callable or None
        ``update(e, r, q, block, prepared)``: ``(J, new block)`` from the generator's residual ``r``, its χ²
        value ``q = rᵀ W r`` (``None`` for a sequential statistic) and the block before the sample; ``None``:
        ``J = q`` and no block.
    counter : Callable
        ``counter(e, J, count, threshold, release, block)``: the alarm counter after a valid sample.
    level : Callable or None
        ``level(e, x, persistence)``: the alarm level of traces ``x = J / threshold`` (``runs × samples``): the
        statistic's persistence flag at the threshold ``s · threshold`` is raised exactly where the level is above
        ``s`` (``s > 0``), the same ``J``, from a zero counter, valid samples only. ``None``: ``J`` itself depends on
        the threshold (a CUSUM's sums are clamped at twice it), so a trace at one threshold does not give another's.
    flags_at : Callable or None
        ``flags_at(e, r, scales)``: for a statistic without a ``level``, its flag at every threshold scale, run again
        from the generator's residuals ``r`` (``runs × samples × n_residual``, the samples on which it ran) —
        ``runs × len(scales) × samples``.
    """

    kind: str
    sequential: bool
    window_read: bool
    window_written: bool
    window_rule: Callable[[Any, str], str]
    vectors: tuple[str, ...]
    rows_per_hypothesis: Callable[[Any], int]
    check_vectors: Callable[[Any, str, int, int], str] | None
    block: str | None
    block_rows: Callable[[Any], int | None]
    release: Callable[[Any], float]
    onset_sums: bool
    prepare: Callable[[Any], Any]
    update: Callable[[Any, np.ndarray, float | None, np.ndarray, Any], tuple[float, np.ndarray]] | None
    counter: Callable[[Any, float, float, float, float, np.ndarray | None], float]
    level: Callable[[Any, np.ndarray, int], np.ndarray] | None = None
    flags_at: Callable[[Any, np.ndarray, np.ndarray], np.ndarray] | None = None


def _one(label: str, remedy: str = "") -> Callable[[Any, str], str]:
    def rule(e: Any, w: str) -> str:
        if type(e.window) is int and e.window == 1:
            return ""
        return f"{w}.window must be 1 for {label}, found {shown(e.window)}{remedy}"

    return rule


def _wssr_window(e: Any, w: str) -> str:
    most = MAX_WSSR_WINDOW
    if type(e.window) is int and 1 <= e.window <= most:
        return ""
    return f"{w}.window must be a whole number of samples in 1..{most}, found {shown(e.window)}"


def _glr_window(e: Any, w: str) -> str:
    most = MAX_GLR_WINDOW
    if type(e.window) is int and 1 <= e.window <= most:
        return ""
    return f"{w}.window must be a whole number of onsets in 1..{most} for a 'glr' evaluator, found {shown(e.window)}"


def _check_drift(e: Any, w: str, rows: int, per: int) -> str:
    assert e.drift is not None
    if e.drift.shape != (rows,) or not np.all(e.drift > 0):
        return f"{w}.drift must hold one positive number per direction ({rows}), found {shown(e.drift.tolist())}"
    return ""


def _check_information(e: Any, w: str, rows: int, per: int) -> str:
    assert e.information is not None
    c = e.information.reshape(-1, per) if e.information.shape == (rows,) else None
    if c is None or not np.all(c >= 0) or not np.all(np.diff(c, axis=1) >= -1e-9 * c[:, -1:]) or not np.all(c[:, -1] > 0):
        return f"{w}.information must hold, per hypothesis, {per} nondecreasing cumulative informations ending positive"
    return ""


def glr_weights(information: np.ndarray | None, window: int) -> np.ndarray:
    """``1 / (2 c_i(n))`` for each onset, 0 where ``c_i(n)`` is below ``1e-12`` of hypothesis ``i``'s largest
    (an onset too recent for the fault to have shown: ``d_i(n)`` is then 0 too, and the term is left out).

    Parameters
    ----------
    information : numpy.ndarray or None
        A GLR evaluator's ``information``: ``window`` cumulative informations per hypothesis.
    window : int
        The evaluator's onset window ``M``.

    Returns
    -------
    numpy.ndarray
        One weight per onset, hypothesis-major (the layout of ``information``).

    Raises
    ------
    GainFileError
        ``information`` is ``None`` (not a GLR evaluator).

    Examples
    --------
    >>> glr_weights(np.array([0.0, 1.0, 2.0]), 3).tolist()
    [0.0, 0.5, 0.25]
    """
    if information is None:
        raise GainFileError("a GLR evaluator needs its information")
    c = np.asarray(information, dtype=float).reshape(-1, int(window))
    top = np.max(c, axis=1, keepdims=True)
    with np.errstate(divide="ignore"):
        return np.where(c > 1e-12 * top, 0.5 / np.where(c > 0, c, 1.0), 0.0).reshape(-1)


def _none(e: Any) -> None:
    return None


def _count_above(e: Any, J: float, count: float, threshold: float, release: float, block: np.ndarray | None) -> float:
    """χ², WSSR: consecutive samples above the threshold."""
    return count + 1.0 if J > threshold else 0.0


def _wssr_update(e: Any, r: np.ndarray, q: float | None, old: np.ndarray, prepared: Any) -> tuple[float, np.ndarray]:
    window = np.concatenate([[q], old[:-1]])
    return float(np.add.accumulate(window)[-1]), window  # in order, newest first


def count_level(e: Any, x: np.ndarray, persistence: int) -> np.ndarray:
    """The alarm level of :func:`_count_above` with ``persistence``: the smallest ``x`` of the last ``persistence``
    samples (``−inf`` before there are as many), since ``persistence`` consecutive ``x > s`` raise the flag at ``s``.

    Parameters
    ----------
    e : Evaluator
        The evaluator (unread: the rule is the same for every one).
    x : numpy.ndarray
        ``J / threshold``, ``runs × samples``.
    persistence : int
        The decision's persistence.

    Returns
    -------
    numpy.ndarray
        The level, the shape of ``x``.
    """
    x = np.asarray(x, dtype=float)
    out = x.copy()
    for k in range(1, int(persistence)):
        out[:, k:] = np.minimum(out[:, k:], x[:, :-k])
        out[:, :k] = -np.inf
    return out


def held_level(e: Any, x: np.ndarray, persistence: int) -> np.ndarray:
    """The alarm level of :func:`_glr_counter`: raised by ``x > s``, held while ``x > ρ s`` (``ρ`` the release over
    the threshold), so ``L(k) = max(x(k), min(L(k − 1), x(k)/ρ))`` from ``L(−1) = −inf`` (``ρ = 0``: held while
    ``x > 0``). Its counter is 0 or 1, so a persistence above 1 never raises it (``−inf``).

    Parameters
    ----------
    e : Evaluator
        The evaluator (its release level over its threshold is ``ρ``).
    x : numpy.ndarray
        ``J / threshold``, ``runs × samples``.
    persistence : int
        The decision's persistence.

    Returns
    -------
    numpy.ndarray
        The level, the shape of ``x``.
    """
    x = np.asarray(x, dtype=float)
    out = np.full(x.shape, -np.inf)
    if int(persistence) > 1:
        return out
    rho = float(STATISTICS[e.kind].release(e)) / float(e.threshold)
    held = np.divide(x, rho) if rho > 0 else np.where(x > 0, np.inf, -np.inf)
    last = np.full(x.shape[0], -np.inf)
    for k in range(x.shape[1]):
        last = np.maximum(x[:, k], np.minimum(last, held[:, k]))
        out[:, k] = last
    return out


def _cusum_update(e: Any, r: np.ndarray, q: float | None, old: np.ndarray, prepared: Any) -> tuple[float, np.ndarray]:
    assert e.directions is not None and e.drift is not None
    z = e.directions @ r
    m2 = 2 * e.directions.shape[0]
    sums = old[:m2] + np.concatenate([z, -z]) - np.concatenate([e.drift, e.drift])
    sums = np.minimum(np.maximum(sums, 0.0), 2.0 * e.threshold)
    latch = np.where((sums > e.threshold) | ((old[m2:] > 0.0) & (sums > 0.0)), 1.0, 0.0)
    return float(np.max(sums)), np.concatenate([sums, latch])


def cusum_flags(e: Any, r: np.ndarray, scales: np.ndarray) -> np.ndarray:
    """A CUSUM evaluator's flag at every threshold scale: :func:`_cusum_update`'s sums and latches run again from
    the residuals, its threshold and clamp (twice the threshold) scaled by each ``s``. The flag is not monotone in
    ``s`` (a higher clamp lets a sum climb higher and so stay latched longer), so each scale is run.

    Parameters
    ----------
    e : Evaluator
        The evaluator (``directions``, ``drift``, ``threshold``).
    r : numpy.ndarray
        Its generator's residuals on the samples on which the statistic ran, ``runs × samples × n_residual``.
    scales : numpy.ndarray
        The threshold scales ``s > 0``.

    Returns
    -------
    numpy.ndarray
        ``runs × len(scales) × samples`` bool: the flag (any latched sum) after each sample.
    """
    assert e.directions is not None and e.drift is not None
    r = np.asarray(r, dtype=float)
    z = r @ np.asarray(e.directions, dtype=float).T
    zz = np.concatenate([z, -z], axis=2)  # added, then the drift taken off, in the update's order
    drift = np.concatenate([e.drift, e.drift])[None, None, :]
    R, n, m2 = zz.shape
    s = np.asarray(scales, dtype=float)[None, :, None]
    high, cap = float(e.threshold) * s, 2.0 * float(e.threshold) * s
    sums = np.zeros((R, s.shape[1], m2))
    latch = np.zeros(sums.shape, dtype=bool)
    out = np.zeros((R, s.shape[1], n), dtype=bool)
    for k in range(n):
        sums = np.minimum(np.maximum(sums + zz[:, None, k, :] - drift, 0.0), cap)
        latch = (sums > high) | (latch & (sums > 0.0))
        out[:, :, k] = latch.any(axis=2)
    return out


def _cusum_counter(e: Any, J: float, count: float, threshold: float, release: float, block: np.ndarray | None) -> float:
    """Any latched sum."""
    assert block is not None
    return float(np.any(block[2 * e.directions.shape[0] :] > 0.0))


def _glr_prepare(e: Any) -> np.ndarray:
    return glr_weights(e.information, e.window)


def _glr_update(e: Any, r: np.ndarray, q: float | None, old: np.ndarray, weights: np.ndarray) -> tuple[float, np.ndarray]:
    assert e.directions is not None
    m = e.window
    z = (e.directions @ r).reshape(-1, m)
    prev = old.reshape(-1, m)
    d = np.concatenate([z[:, :1], prev[:, :-1] + z[:, 1:]], axis=1).reshape(-1)
    return float(np.max(d * d * weights)), d


def _glr_counter(e: Any, J: float, count: float, threshold: float, release: float, block: np.ndarray | None) -> float:
    """Raised above the threshold, held down to the release level."""
    return 1.0 if J > threshold or (count > 0.0 and J > release) else 0.0


def _directions_rows(factor: int) -> Callable[[Any], int | None]:
    return lambda e: int(e.directions.shape[0]) * factor if e.directions is not None else None


STATISTICS: dict[str, Statistic] = {
    "chi2": Statistic(
        kind="chi2",
        sequential=False,
        window_read=False,
        window_written=False,
        window_rule=_one("a 'chi2' evaluator (one sample)", "; use kind 'wssr' for a window"),
        vectors=(),
        rows_per_hypothesis=lambda e: 1,
        check_vectors=None,
        block=None,
        block_rows=_none,
        release=lambda e: 0.5 * float(e.threshold),
        onset_sums=False,
        prepare=_none,
        update=None,
        counter=_count_above,
        level=count_level,
    ),
    "wssr": Statistic(
        kind="wssr",
        sequential=False,
        window_read=True,
        window_written=True,
        window_rule=_wssr_window,
        vectors=(),
        rows_per_hypothesis=lambda e: 1,
        check_vectors=None,
        block="window",
        block_rows=lambda e: int(e.window),
        release=lambda e: 0.5 * float(e.threshold),
        onset_sums=False,
        prepare=_none,
        update=_wssr_update,
        counter=_count_above,
        level=count_level,
    ),
    "cusum": Statistic(
        kind="cusum",
        sequential=True,
        window_read=False,
        window_written=True,
        window_rule=_one("a 'cusum' evaluator (it has no window)"),
        vectors=("drift",),
        rows_per_hypothesis=lambda e: 1,
        check_vectors=_check_drift,
        block="sequential",
        block_rows=_directions_rows(4),
        release=lambda e: 0.0,
        onset_sums=False,
        prepare=_none,
        update=_cusum_update,
        counter=_cusum_counter,
        flags_at=cusum_flags,
    ),
    "glr": Statistic(
        kind="glr",
        sequential=True,
        window_read=True,
        window_written=True,
        window_rule=_glr_window,
        vectors=("information",),
        rows_per_hypothesis=lambda e: int(e.window),
        check_vectors=_check_information,
        block="sequential",
        block_rows=_directions_rows(1),
        release=lambda e: 0.5 * float(e.threshold),
        onset_sums=True,
        prepare=_glr_prepare,
        update=_glr_update,
        counter=_glr_counter,
        level=held_level,
    ),
}
"""Every statistic kind a linear gain file holds, in the order the format lists them."""
