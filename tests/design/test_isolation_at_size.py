"""Isolation against the size at which a fault is detected (:func:`fdisyn.evaluation.metrics.isolation_at_size`):
the rule the fault-size sweep's table applies, on hand-made Monte Carlo figures whose answer is known."""

from __future__ import annotations

from fdisyn.app.pipeline import SWEEP_DETECTION_GRID, SWEEP_FACTORS
from fdisyn.evaluation.metrics import ISOLATION_MARGIN, isolation_at_size

from tests.helpers import scenario_metrics


def sweep(detected: dict[float, float], named: dict[float, float], another: float = 0.0) -> dict:
    """Figures per size: the share of runs that detect and the share that name the true fault."""
    return {
        f: scenario_metrics("s", "f", missed_detection_rate=1.0 - detected[f], isolation_accuracy=named[f], false_isolation_rate=another)
        for f in detected
    }


def test_every_size_the_goal_asks_about_is_measured() -> None:
    """The margin times each detection size is a sweep size (or the scenario itself, 1), so the first size the
    goal asks about is measured, whatever the detected size turns out to be."""
    sizes = {*SWEEP_FACTORS, 1.0}
    assert set(SWEEP_DETECTION_GRID) <= sizes
    assert all(any(abs(ISOLATION_MARGIN * f - g) < 1e-12 for g in sizes) for f in SWEEP_DETECTION_GRID)


def test_detected_from_the_first_size_that_stays_detected() -> None:
    sizes = (0.25, 0.375, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0)
    det = dict(zip(sizes, (0.2, 0.5, 0.96, 0.9, 1.0, 1.0, 1.0, 1.0), strict=True))  # 0.5 detects, 0.75 does not
    out = isolation_at_size(sweep(det, dict.fromkeys(sizes, 1.0)), SWEEP_DETECTION_GRID)
    assert out is not None and out.detected_from == 1.0  # 0.5 is followed by a size below the goal (0.75 is off-grid, 1.0 on)
    det[0.75] = 0.99
    out = isolation_at_size(sweep(det, dict.fromkeys(sizes, 1.0)), SWEEP_DETECTION_GRID)
    assert out is not None and out.detected_from == 0.5 and out.met and out.at == 0.75 and out.isolated_from == 0.25


def test_the_worst_isolation_from_the_margin_on_decides() -> None:
    sizes = (0.25, 0.375, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0)
    det = dict(zip(sizes, (0.1, 0.5, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0), strict=True))
    named = dict(zip(sizes, (0.0, 0.0, 0.3, 0.97, 0.99, 0.9, 1.0, 1.0), strict=True))  # 1.5 × falls short
    out = isolation_at_size(sweep(det, named, another=0.1), SWEEP_DETECTION_GRID)
    assert out is not None and out.detected_from == 0.5
    assert out.isolation == 0.9 and out.at == 1.5 and out.another == 0.1 and not out.met
    assert out.isolated_from == 2.0  # from 2 × on every size names it in 95 % of the runs


def test_never_detected_and_not_isolating() -> None:
    sizes = (0.25, 0.5, 1.0, 2.0, 3.0)
    out = isolation_at_size(sweep(dict.fromkeys(sizes, 0.5), dict.fromkeys(sizes, 0.0)), SWEEP_DETECTION_GRID)
    assert out is not None and out.detected_from is None and out.isolation is None and not out.met
    plain = {f: scenario_metrics("s", "f", missed_detection_rate=0.0) for f in sizes}  # a detector that does not isolate
    assert isolation_at_size(plain, SWEEP_DETECTION_GRID) is None
