"""A committed report holds only what is the same on every CPU: a certificate's round-off values as the bound that
holds everywhere, the export check as "within the tolerance", and one gain file per variant design (none
overwritten by a later variant of the same name)."""

from __future__ import annotations

import math

import pytest
from fdisyn.app.pipeline import EXPORT_TOL, ExportCheck, variant_specs
from fdisyn.reporting.kit import ROUND_OFF_MARGIN, below_margin
from fdisyn.reporting.page import published_gain_name
from fdisyn.simulation.problem import get_problem


@pytest.mark.parametrize("bound", [1e-12, 1e-9, 3e-7, 1e-4, 1e-3])
def test_round_off_values_show_the_bound_that_holds_on_every_cpu(bound: float) -> None:
    # the same identity's residual on two BLAS kernels: two values three orders or more below the bound
    small = [0.0, 1e-19 * bound, 0.37 * ROUND_OFF_MARGIN * bound, 0.999 * ROUND_OFF_MARGIN * bound]
    texts = {below_margin(v, bound, "<=") for v in small}
    assert len(texts) == 1 and texts.pop().startswith("below ")  # not "<": a cell starting with "<" is HTML
    # the bound shown is a power of ten at or above the margin, within a decade of it
    shown = 10.0 ** math.ceil(math.log10(ROUND_OFF_MARGIN * bound) - 1e-9)
    assert ROUND_OFF_MARGIN * bound <= shown * (1 + 1e-12) and shown < 10 * ROUND_OFF_MARGIN * bound


def test_values_near_their_bound_and_lower_bounds_keep_their_digits() -> None:
    assert below_margin(0.339, 1.0) == "0.339"
    assert below_margin(2e-6, 1e-3) == "2·10⁻⁶"
    assert below_margin(50.0, 1e10) == "50"  # a large bound (a condition number) is no round-off tolerance
    assert below_margin(1e-20, 1e-8, ">=") == "1·10⁻²⁰"  # a lower bound: a small value fails, and says so
    assert below_margin(float("nan"), 1.0) == "NaN"  # never shown as passing
    assert below_margin(-1e-17, 0.0) == "−1·10⁻¹⁷"  # no margin below a zero bound


def _check(scale: float) -> ExportCheck:
    refs = {"numpy": {"r": 2e-17 * scale, "J": 3e-17 * scale, "state": 0.0 if scale == 1 else 8e-17, "decisions_equal": True}}
    return ExportCheck(samples=10_000, nonfinite_samples=6, references=refs)


def test_the_published_export_check_is_the_same_on_every_cpu() -> None:
    a, b = _check(1.0), _check(2.7)
    assert a.to_dict() != b.to_dict()  # the build folder keeps the round-off
    assert a.published() == b.published()
    assert a.published()["references"]["numpy"] == {"decisions_equal": True, "within_tolerance": True}
    over = ExportCheck(samples=1, nonfinite_samples=0, references={"c": {"r": 10 * EXPORT_TOL, "J": 0.0, "state": 0.0, "decisions_equal": True}})
    assert over.published()["references"]["c"]["within_tolerance"] is False and over.published()["passed"] is False


def test_a_later_variant_of_the_same_gain_file_name_gets_its_own_file() -> None:
    taken: set[str] = set()
    assert published_gain_name("wt_kalman_uio", "default", taken) == "wt_kalman_uio.json"
    assert published_gain_name("wt_uio_pole_placement", "default", taken) == "wt_uio_pole_placement.json"
    assert published_gain_name("wt_kalman_uio", "persistence 3", taken) == "wt_kalman_uio-persistence_3.json"
    assert published_gain_name("wt_kalman_uio_chi2", "χ² at arl0 = 60 s", taken) == "wt_kalman_uio_chi2.json"
    assert taken == {"wt_kalman_uio.json", "wt_uio_pole_placement.json", "wt_kalman_uio-persistence_3.json", "wt_kalman_uio_chi2.json"}


def test_the_variants_are_those_the_main_job_runs() -> None:
    problem = get_problem("wind_turbine")
    specs = variant_specs(problem, 7, None)
    assert specs[0] == ("default", {}, None, list(problem.designs), 7)
    assert [s[0] for s in specs[1:]] == [v["label"] for v in problem.variants]
    assert all(s[4] == v.get("runs", 7) for s, v in zip(specs[1:], problem.variants, strict=True))
    assert all(s[4] == 3 for s in variant_specs(problem, 3, 3))  # the user's --runs wins over a variant's own
