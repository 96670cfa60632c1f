"""The ``nafdf`` diagnoser kind: the nonlinear adaptive fault-detection filter's gain file read back
(Zhou, Xi & Zhang, Shanghai Jiao Tong University, c. 1991): its step, Monte Carlo figures, budget and Lorden bound."""

from __future__ import annotations

from typing import Any

from fdisyn.runtime.gainfile import GainFile
from fdisyn.synthesis.kinds import DiagnoserKind, register_kind
from fdisyn.synthesis.nafdf.design import nafdf_extra_metrics
from fdisyn.synthesis.nafdf.payload import (
    nafdf_budget_seconds,
    nafdf_from_gain_file,
    nafdf_lorden_bound,
    nafdf_lorden_information,
    nafdf_lorden_window,
    nafdf_scaled,
)

__all__ = ["NAFDF_KIND", "NAFDF_BUDGET_TEXT", "NAFDF_DETECTORS_TEXT", "NAFDF_ACCOUNT_NOTE"]

NAFDF_BUDGET_TEXT = (
    '<p class="small">Time between false alarms: fault-free time over the number of alarm episodes, with Garwood\'s exact '
    "95 % Poisson interval; budget: the design's arl0, or Ts·(1/P_f + 2·N2) for a design by P_f — the detector's run "
    "length plus the 2·N2 samples a false alarm's episode lasts before its dismissal. The WSSR's per-sample P_f ignores "
    "that its exceedances come in clusters, so its budget is met many times over. Lorden bound: ln(ARL)/I (Lorden, Annals "
    "of Mathematical Statistics 42(6), 1971), ARL = 1/P_f the detector's run length in samples, I = ½ μᵀ Σ⁻¹ μ with μ the "
    "mean shift of the EKF innovation over the N2 samples after the onset (before the EKF can be re-parameterised) and Σ "
    "its fault-free covariance. A parameter jump's innovation shift builds up through the plant's dynamics over several "
    "samples, while the bound is for a mean that steps at once: a ratio above 1 measures that build-up as much as the "
    "detector. Isolation is the NAFDF's classifier (eq. (2.7)); false isolation: runs whose most frequent decision names "
    "another parameter.</p>"
)
"""How a NAFDF's false-alarm budget, its Lorden bound and its isolation figures are read (the report's HTML)."""

NAFDF_DETECTORS_TEXT = (
    "The NAFDF's fast detection on the EKF innovations: the WSSR (Zhou, Xi & Zhang c. 1991, eq. (2.4)), and CUSUM "
    "(Page, Biometrika 41(1/2), 1954) and windowed GLR (Willsky & Jones, IEEE Transactions on Automatic Control "
    "21(1), 1976) on the normalised innovations, the rest of the filter unchanged"
)
"""The detectors a NAFDF's page compares at one false-alarm budget (the report's HTML)."""

NAFDF_ACCOUNT_NOTE = (
    "the account is computed for linear diagnosers only: the NAFDF's parameter faults act through a "
    "nonlinear model, so their effect depends on the operating point (the report's Monte Carlo and fault-size "
    "sweep measure it)"
)
"""Why a NAFDF has no account of what it can see (printed by ``fdisyn design``, shown on the report)."""


def _step(gf: GainFile) -> Any:
    return nafdf_from_gain_file(gf).step


# No ``reference``: the NAFDF has no NumPy twin of its step (its EKF, parameter re-estimation and classifier are
# written once, in CasADi; ``NafdfDesign.run`` runs that step), so its generated C is checked against the CasADi step
# only, and its step's parts against independent truths in its tests.
NAFDF_KIND = register_kind(
    DiagnoserKind(
        name="nafdf",
        summary="an EKF on the nonlinear model, a WSSR, CUSUM or GLR on its innovation, parameter re-estimation and Bayes classification",
        step_builder=_step,
        extra_metrics=nafdf_extra_metrics,
        false_alarm_budget=nafdf_budget_seconds,
        lorden_bound=nafdf_lorden_bound,
        lorden_information=nafdf_lorden_information,
        lorden_window=nafdf_lorden_window,
        budget_text=NAFDF_BUDGET_TEXT,
        detectors_text=NAFDF_DETECTORS_TEXT,
        account_note=NAFDF_ACCOUNT_NOTE,
        threshold_scaled=nafdf_scaled,
    )
)
"""The ``nafdf`` kind, produced by the method ``nafdf`` (:mod:`fdisyn.synthesis.nafdf.method`)."""
