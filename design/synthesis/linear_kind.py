"""The ``linear`` diagnoser kind: a bank of linear residual generators, a statistic per generator and a signature
table (:func:`fdisyn.synthesis.linear_diagnoser.linear_diagnoser`), read back from its gain file alone.

What a linear gain file means downstream of its design: its step (:func:`fdisyn.synthesis.linear_step.linear_step_function`),
the model it was designed on, its recovery window, its false-alarm budget and the Lorden bound of its statistics.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from fdisyn.detectors.sequential import lorden_delay
from fdisyn.detectors.table import DETECTORS
from fdisyn.models.linear import LinearPlant
from fdisyn.numerics.account import BankView, default_bank_of
from fdisyn.runtime.gainfile import GainFile
from fdisyn.runtime.reference import LinearReference, RunResult
from fdisyn.synthesis.kinds import DiagnoserKind, register_kind, warmup_text
from fdisyn.synthesis.linear_step import linear_step_function
from fdisyn.synthesis.residual import long_run_covariance

__all__ = ["LINEAR", "design_plant", "lorden_bound", "budget_seconds", "linear_recovery_samples", "linear_account_view", "linear_reference_run"]


def design_plant(gf: GainFile) -> LinearPlant:
    """The discrete model a linear gain file was designed on (``gf.plant``), with generic state names."""
    pl = gf.plant
    n = pl["A"].shape[0]
    return LinearPlant(
        A=pl["A"], B=pl["B"], C=pl["C"], D=pl["D"], E=pl["E"], Fx=np.zeros((n, 0)), Q=pl["Q"], R=pl["R"], Ts=gf.Ts,
        inputs=gf.inputs, outputs=gf.outputs, states=tuple(f"x{i}" for i in range(n)),
        unknown_inputs=tuple(f"d{i}" for i in range(pl["E"].shape[1])), component_faults=(),
    )


def lorden_bound(gf: GainFile, shift: np.ndarray, covariance: np.ndarray | None = None) -> tuple[float, float] | None:
    """``(I, ln(ARL_j)/I_j)`` for a mean shift ``shift`` of the bank's stacked residual: with ``μ_g`` its part in
    generator ``g``, the largest information per sample ``I_g = ½ μ_gᵀ (Σ_τ R_g(τ))⁺ μ_g``
    (:func:`fdisyn.synthesis.residual.long_run_covariance`, from the design: ``covariance``, the measured one, is
    not used) and the smallest Lorden delay over the statistics, each at its share ``ARL_j = 1/P_f,j`` of the
    budget. ``None`` when no generator sees the shift."""
    offsets = np.cumsum([0] + [g.n_residual for g in gf.generators])
    shifts = [np.asarray(shift, dtype=float)[offsets[g] : offsets[g + 1]] for g in range(len(gf.generators))]
    plant = design_plant(gf)
    best_i, bound = 0.0, math.inf
    for ev in gf.evaluators:
        gen = gf.generators[ev.generator]
        s = long_run_covariance(gen, plant)
        mu = np.asarray(shifts[ev.generator], dtype=float)
        info = 0.5 * float(mu @ np.linalg.pinv(s, rcond=1e-9, hermitian=True) @ mu)
        if info > 0:
            best_i = max(best_i, info)
            bound = min(bound, lorden_delay(1.0 / ev.P_f, info))
    return (best_i, bound) if math.isfinite(bound) else None


def lorden_information(gf: GainFile, shifts: np.ndarray, covariance: np.ndarray | None = None) -> list[tuple[float, np.ndarray]]:
    """Per statistic ``j``, ``(ARL_j, I_j)``: its share ``1/P_f,j`` of the budget and, for each row ``μ`` of
    ``shifts`` (mean shifts of the bank's stacked residual, ``m × nr``), the information per sample
    ``½ μ_gᵀ (Σ_τ R_g(τ))⁺ μ_g`` its generator ``g`` sees — :func:`lorden_bound`'s measure, row by row
    (``covariance`` is not used: the long-run covariance is the design's)."""
    M = np.atleast_2d(np.asarray(shifts, dtype=float))
    offsets = np.cumsum([0] + [g.n_residual for g in gf.generators])
    plant = design_plant(gf)
    weights: dict[int, np.ndarray] = {}
    out = []
    for ev in gf.evaluators:
        g = ev.generator
        if g not in weights:
            weights[g] = np.linalg.pinv(long_run_covariance(gf.generators[g], plant), rcond=1e-9, hermitian=True)
        mu = M[:, offsets[g] : offsets[g + 1]]
        out.append((1.0 / float(ev.P_f), 0.5 * np.einsum("li,ij,lj->l", mu, weights[g], mu)))
    return out


def budget_seconds(gf: GainFile) -> float:
    """A linear diagnoser's false-alarm budget: its ``arl0``, or ``Ts / Σ_j P_f,j`` for a design by ``P_f``."""
    bank = gf.certificate.get("bank", {})
    info = bank.get("info", {}) if isinstance(bank, Mapping) else {}
    if isinstance(info, Mapping) and isinstance(info.get("arl0_s"), (int, float)):
        return float(info["arl0_s"])
    return float(gf.Ts) / sum(float(e.P_f) for e in gf.evaluators)


def linear_recovery_samples(gf: GainFile) -> int:
    """Samples for a fault's transient to decay by 1e-8 in the slowest generator.

    ``ceil(ln 1e-8 / ln ρ)`` with ``ρ`` the largest spectral radius of the
    generators' ``Ar``, plus ``N − 1`` for the longest WSSR or GLR window ``N`` (it
    holds the fault's last samples that long) or ``2h / drift`` for a CUSUM (it
    drains from its cap at its drift); after that the statistics no longer
    carry the fault.
    """
    rho = max((float(np.max(np.abs(np.linalg.eigvals(g.Ar)))) for g in gf.generators if g.n_state), default=0.0)
    held = max((e.window for e in gf.evaluators), default=1) - 1
    # a CUSUM, capped at 2h, drains at its smallest drift per sample once the fault is gone
    held = max([held] + [math.ceil(2.0 * e.threshold / float(np.min(e.drift))) for e in gf.evaluators if e.drift is not None])
    if rho <= 0.0:
        return 1 + held
    return max(1, math.ceil(math.log(1e-8) / math.log(rho))) + held


def linear_account_view(gf: GainFile) -> BankView:
    """A linear diagnoser as the account sees it: its own generators and statistics on its design model, its
    signature table, and how its bank was built when none was given.

    Parameters
    ----------
    gf : GainFile
        A ``linear`` gain file.

    Returns
    -------
    BankView
    """
    return BankView(
        generators=list(gf.generators),
        statistics=list(gf.evaluators),
        statistic_names=list(gf.step.statistic_names),
        laws=[DETECTORS[ev.kind].size_law for ev in gf.evaluators],
        model=gf.plant,
        persistence=int(gf.decision.persistence) if gf.decision is not None else 1,
        signatures=None if gf.decision is None else gf.decision.signatures,
        default_bank=default_bank_of(gf),
    )


def linear_reference_run(gf: GainFile, U: np.ndarray, Y: np.ndarray) -> RunResult:
    """A linear gain file's run over a trace by the runtime's NumPy reference (:class:`fdisyn.runtime.reference.LinearReference`).

    Parameters
    ----------
    gf : GainFile
        A ``linear`` gain file.
    U : numpy.ndarray
        Inputs, ``T × nu``.
    Y : numpy.ndarray
        Outputs, ``T × ny``.

    Returns
    -------
    RunResult
        From the gain file's initial state.
    """
    return LinearReference(gf).run(U, Y)


def _certified(gf: GainFile) -> list[Mapping[str, Any]]:
    return list(gf.certificate["generators"])


def _describe(gf: GainFile) -> str:
    span = warmup_text(gf)
    if span in (None, "0"):
        return f"{len(gf.generators)} generators"
    return f"{len(gf.generators)} generators, a warm-up of {span} samples before the statistics run"


LINEAR = register_kind(
    DiagnoserKind(
        name="linear",
        summary="a bank of linear residual generators, one statistic each (χ², WSSR, CUSUM or GLR) and a signature table",
        step_builder=linear_step_function,
        certified=_certified,
        describe=_describe,
        rate_unit="per statistic and sample",
        recovery_samples=linear_recovery_samples,
        false_alarm_budget=budget_seconds,
        lorden_bound=lorden_bound,
        lorden_information=lorden_information,
        account_view=linear_account_view,
        reference=linear_reference_run,
        warmups=lambda gf: tuple(int(g.warmup) for g in gf.generators),
    )
)
"""The ``linear`` kind, produced by every linear method (:func:`fdisyn.synthesis.linear_diagnoser.linear_method`,
the generalised observer scheme of :mod:`fdisyn.synthesis.uio_gos`)."""
