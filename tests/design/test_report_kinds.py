"""The pages ask the diagnoser-kind table what a kind means and the gain file what it holds: no kind is named in
the report or the application layer."""

from __future__ import annotations

import re
from pathlib import Path
from types import SimpleNamespace

import pytest
from fdisyn.reporting import budget, certificates
from fdisyn.synthesis.kinds import get_kind

DESIGN = Path(__file__).resolve().parents[2] / "design"
NAMED_KIND = re.compile(r"\b(?:gf|gain_file)\.kind\s*(?:==|!=|\bin\b)|\.kind\s+for\b[^}]*\}\s*(?:==|!=)|get_kind\(\s*[\"']")
"""A branch on a gain file's kind, a set of kinds compared with named ones, or a kind looked up by its name."""


@pytest.mark.parametrize(
    "path", sorted([*(DESIGN / "reporting").glob("*.py"), *(DESIGN / "app" / f for f in ("pipeline.py", "cli.py", "bench.py"))]), ids=lambda p: p.name
)
def test_the_report_and_the_app_name_no_diagnoser_kind(path: Path) -> None:
    found = [f"{path.name}:{k}: {line.strip()}" for k, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1) if NAMED_KIND.search(line)]
    assert not found, found


def _metric(fault: str | None) -> SimpleNamespace:
    return SimpleNamespace(
        fault=fault, Ts=0.1, fault_free_samples=1000, false_alarm_episodes=1, arl0_budget_s=60.0, missed_detection_rate=0.0,
        detection_delay_mean_s=None if fault is None else 0.5, delay_bound_ratio=None, lorden_bound_samples=None,
        isolation_accuracy=None if fault is None else 1.0, false_isolation_rate=None if fault is None else 0.0,
        mean_time_between_false_alarms_s=100.0, mean_time_between_false_alarms_interval_s=(50.0, 200.0),
    )


def _variants(kind: str) -> list[SimpleNamespace]:
    gf = SimpleNamespace(kind=kind)
    return [
        SimpleNamespace(label=f"{det} at arl0 = 60 s", options={"detector": det, "arl0": 60.0}, built={"d": SimpleNamespace(gain_file=gf)},
                        evaluation=SimpleNamespace(metrics={"d": {"fault_free": _metric(None), "bias": _metric("f")}}))
        for det in ("wssr", "cusum")
    ]


def test_the_detector_comparison_takes_its_prose_from_the_kind(monkeypatch) -> None:
    """A kind with its own phrase for the compared detectors and its own budget prose has both on its page; a kind
    without either gets the page's general text."""
    own = SimpleNamespace(detectors_text="The kind's own detectors", budget_text='<p class="small">The kind\'s own budget.</p>')
    monkeypatch.setattr(budget, "get_kind", lambda name: own if name == "own" else SimpleNamespace(detectors_text=None, budget_text=None))
    prob = SimpleNamespace(labels={})
    mine = budget.detectors_section(prob, _variants("own"))  # type: ignore[arg-type]
    assert mine.startswith("<p>The kind's own detectors, each designed for the same mean time between false alarms arl0.</p>")
    assert "The kind's own budget." in mine and "Bonferroni" not in mine
    general = budget.detectors_section(prob, _variants("plain"))  # type: ignore[arg-type]
    assert general.startswith("<p>WSSR (Long & Wang, Aeroengine 43(5), 2017, section 2) and CUSUM")
    assert "statistics of the same generators" in general and "Bonferroni" in general


def test_the_nafdf_kind_names_its_compared_detectors() -> None:
    assert get_kind("nafdf").detectors_text.startswith("The NAFDF's fast detection on the EKF innovations")
    assert get_kind("linear").detectors_text is None and get_kind("beard_fdf").detectors_text is None


def test_the_budget_line_words_the_rate_as_the_kind_does(monkeypatch) -> None:
    monkeypatch.setattr(budget, "get_kind", lambda name: SimpleNamespace(rate_unit="per window"))
    monkeypatch.setattr(budget, "false_alarm_budget", lambda gf: 5.0)
    gf = SimpleNamespace(kind="any", evaluators=(SimpleNamespace(P_f=1e-4), SimpleNamespace(P_f=1e-4)), certificate={}, extensions={})
    assert budget.budget_line(gf) == "false-alarm budget: one every 5 s (from P_f = 1·10⁻⁴ per window, 2 statistics)"


def test_the_certificate_shows_the_blocks_the_kind_certifies(monkeypatch) -> None:
    """A diagnoser without linear generators: the kind's blocks, owned by the design."""
    check = {"name": "margin", "reason": "the kind's reason", "value": 0.5, "relation": "<=", "bound": 1.0, "passed": True}
    monkeypatch.setattr(certificates, "get_kind", lambda name: SimpleNamespace(certified=lambda gf: [{"checks": [check]}], account_note=None))
    gf = SimpleNamespace(kind="any", design="the design", generators=(), evaluators=(), certificate={"passed": True}, account=None)
    page = certificates._certificate_html(gf, SimpleNamespace(labels={"the design": "Design D"}))  # type: ignore[arg-type]
    assert "the kind&#x27;s reason" in page and "<th>Design D</th>" in page and "Smallest constant sensor bias" not in page
