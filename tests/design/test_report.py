"""The report's figures leave the user's Matplotlib backend alone and need no display."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
from fdisyn.reporting.kit import ReportContext, subplots, timeline


def test_importing_the_report_and_the_problems_selects_no_backend() -> None:
    """A fresh interpreter with the user's backend set: the report and every problem module (they
    draw the paper's figures) import without pyplot and without touching the backend."""
    script = (
        "import sys, matplotlib\n"
        "import fdisyn.reporting.page, fdisyn.problems.wind_turbine, fdisyn.problems.ship_propulsion\n"
        "import fdisyn.problems.sampled_data_example, fdisyn.problems.wind_turbine_efficiency\n"
        "print(matplotlib.rcParams._get_backend_or_none(), 'matplotlib.pyplot' in sys.modules)\n"
    )
    env = {**os.environ, "MPLBACKEND": "svg"}
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, check=True)
    assert out.stdout.split() == ["svg", "False"]


def test_a_figure_is_saved_as_png_without_pyplot(tmp_path) -> None:
    fig, (ax, ax2) = subplots(2, 1, figsize=(4, 3), sharex=True, gridspec_kw={"height_ratios": [3, 1]})
    timeline(ax, np.array([0.0, 1.0, 2.0]), np.array([[0.5], [1.5], [0.2]]), ["J"], threshold=1.0)
    ax2.step([0.0, 1.0, 2.0], [-1, 0, 0], where="post")
    ctx = ReportContext(problem=None, variants=[], directory=tmp_path)  # type: ignore[arg-type]
    html = ctx.figure("toy", fig, "a toy figure")
    assert (tmp_path / "toy.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert 'src="toy.png"' in html and ctx.figures == ["toy.png"]


def test_the_detector_comparison_names_the_detectors_it_compares() -> None:
    from types import SimpleNamespace

    from fdisyn.reporting.budget import _compared_detectors

    def variants(*detectors: str) -> list[SimpleNamespace]:
        return [SimpleNamespace(options={"detector": None, "arl0": None})] + [SimpleNamespace(options={"detector": d, "arl0": 60.0}) for d in detectors]

    assert _compared_detectors(variants("glr", "chi2", "cusum")) == (
        "Per-sample χ², CUSUM (Page, Biometrika 41(1/2), 1954) and windowed GLR (Willsky & Jones, IEEE Transactions on "
        "Automatic Control 21(1), 1976)"
    )
    assert _compared_detectors(variants("wssr", "cusum")) == "WSSR (Long & Wang, Aeroengine 43(5), 2017, section 2) and CUSUM (Page, Biometrika 41(1/2), 1954)"


def test_fmt_one_number_format() -> None:
    from fdisyn.reporting.kit import fmt

    assert fmt(None) == "—"
    assert fmt(0.0) == "0" and fmt(0) == "0" and fmt(True) == "yes"
    assert fmt(12) == "12" and fmt(-3) == "−3" and fmt(np.int64(99999)) == "99999"
    assert fmt(0.5) == "0.5" and fmt(1.0) == "1" and fmt(2.0 / 3.0) == "0.6667"
    assert fmt(34480.4) == "34480" and fmt(12.3456) == "12.35" and fmt(0.0012345) == "0.001234"
    assert fmt(123456.0) == "1.235·10⁵" and fmt(3.45e4, 3) == "34500" and fmt(345000, 3) == "3.45·10⁵"
    assert fmt(2.5e-4) == "2.5·10⁻⁴" and fmt(-7.97e-17, 3) == "−7.97·10⁻¹⁷"
    assert fmt(99999.6) == "1·10⁵" and fmt(0.00099996) == "0.001"  # decided after rounding
    assert fmt(float("nan")) == "NaN" and fmt(float("inf")) == "∞" and fmt(-float("inf")) == "−∞"
    assert fmt(3.45e5, 3, interval=(2.4e5, 4.9e5)) == "3.45·10⁵ [2.4·10⁵, 4.9·10⁵]"
    assert fmt(120.0, interval=(80.0, None)) == "120 [80, —]"


def test_a_claim_that_differs_says_why() -> None:
    import pytest
    from fdisyn.reporting.kit import Claim
    from fdisyn.reporting.page import _verdict_section

    with pytest.raises(ValueError, match="say why"):
        Claim(claim="X detects at once (A, B 1(2), 2000, fig. 2)", paper="at once", ours="3 s", verdict="differs")
    with pytest.raises(ValueError, match="reproduced"):
        Claim(claim="X", paper="1", ours="1", verdict="yes")
    claims = [
        Claim(claim="X detects at once", paper="at once", ours="1 s", verdict="reproduced"),
        Claim(claim="Y never detects", paper="never", ours="1 s", verdict="differs", why="Its threshold did not match its residual."),
    ]
    page = _verdict_section(claims)
    assert "1 of 2 claims reproduced" in page and "differs" in page and "Its threshold did not match its residual." in page


def test_labels_map_internal_names() -> None:
    from types import SimpleNamespace

    from fdisyn.reporting.kit import label

    prob = SimpleNamespace(labels={"omega_g_m1": "generator speed ω_g,m1 (rad/s)"})
    assert label(prob, "omega_g_m1") == "generator speed ω_g,m1 (rad/s)"  # type: ignore[arg-type]
    assert label(prob, "other") == "other" and label(None, "x") == "x"  # type: ignore[arg-type]


def test_every_definition_is_in_the_metrics_docstring() -> None:
    import fdisyn.evaluation.metrics as metrics

    for name, text in metrics.DEFINITIONS.items():
        assert f"{name}\n    {text}" in (metrics.__doc__ or "")


@pytest.fixture(scope="module")
def two_reports(tmp_path_factory):
    """The main job on the sampled-data example (main variant, two runs), twice, into two folders."""
    from fdisyn.app.pipeline import reproduce_problem
    from fdisyn.simulation.problem import get_problem

    root = tmp_path_factory.mktemp("reports")
    prob = get_problem("sampled_data_example")
    pages = [reproduce_problem(prob, runs=2, reports=root / k, workdir=root / f"work{k}", variants=["default"]) for k in ("a", "b")]
    return pages


def test_two_writes_are_identical(two_reports) -> None:
    a, b = (p.parent for p in two_reports)
    files = sorted(str(f.relative_to(a)) for f in a.rglob("*") if f.is_file())
    assert files == sorted(str(f.relative_to(b)) for f in b.rglob("*") if f.is_file())
    assert "index.html" in files and "metrics.json" in files and any(f.endswith(".png") for f in files)
    for f in files:
        assert (a / f).read_bytes() == (b / f).read_bytes(), f
    assert (a.parent / "index.html").read_bytes() == (b.parent / "index.html").read_bytes()


def test_the_page_opens_with_the_verdict_and_its_contents_resolve(two_reports) -> None:
    import re

    text = two_reports[0].read_text()
    assert text.index('id="verdict"') < text.index('id="contents"') < text.index('id="detection-at-a-glance"')
    ids = set(re.findall(r'id="([^"]+)"', text))
    targets = re.findall(r'href="#([^"]+)"', text)
    assert targets and all(t in ids for t in targets)
    toc = text[text.index('id="contents"') : text.index("</nav>")]
    assert {"definitions", "certificates", "isolation", "generator-poles"} <= set(re.findall(r'href="#([^"]+)"', toc))
    assert "claims reproduced" in text
    for png in re.findall(r'src="([^"]+)"', text):
        assert (two_reports[0].parent / png).is_file()


def test_the_index_links_every_page(two_reports) -> None:
    import re

    index = two_reports[0].parent.parent / "index.html"
    links = re.findall(r'href="([^"]+)"', index.read_text())
    assert links == ["sampled_data_example/index.html"]
    assert all((index.parent / link).is_file() for link in links)
    assert "3 of 7 claims reproduced" in index.read_text()


def test_the_summary_table_names_every_design(two_reports) -> None:
    from fdisyn.reporting.page import summary_table

    text = summary_table(two_reports[0].parent.parent, ["sampled_data_example"])
    assert text.splitlines()[0].split()[:2] == ["problem", "design"]
    assert all(d in text for d in ("direct", "indirect", "lmi")) and "3/7" in text


def _metric(fault: str | None, isolated: float = 1.0):
    from types import SimpleNamespace

    return SimpleNamespace(fault=fault, fault_free_samples=100, Ts=0.01, false_alarm_episodes=1, false_alarm_rate=0.01,
                           missed_detection_rate=None if fault is None else 0.0,
                           detection_delay_mean_s=None if fault is None else 0.5, isolation_accuracy=None if fault is None else isolated,
                           false_isolation_rate=None if fault is None else 0.0, alarm_held_fraction=None if fault is None else 1.0,
                           isolated_held_fraction=None if fault is None else isolated)


def test_many_scenarios_read_at_a_glance() -> None:
    """Thirty faulty scenarios and two designs: one visible row per scenario in the glance and in the isolation
    figure, the designs side by side under their labels; the per-design numbers folded."""
    import re
    from types import SimpleNamespace

    from fdisyn.reporting.page import _glance_section, _isolation_section

    scenarios = {"fault_free": None, **{f"s{k}": f"sensor{k // 3}" for k in range(30)}}
    metrics = {d: {s: _metric(f, 0.2 if s == "s4" else 1.0) for s, f in scenarios.items()} for d in ("a", "b")}
    variant = SimpleNamespace(evaluation=SimpleNamespace(runs=4, metrics=metrics))
    prob = SimpleNamespace(labels={"a": "design A", "b": "design B", "sensor0": "the first sensor"})
    for section in (_glance_section(prob, variant), _isolation_section(prob, variant)):  # type: ignore[arg-type]
        visible = re.sub(r"<details.*?</details>", "", section, flags=re.S)
        assert visible.count("<tr>") <= 30 + 3
        assert visible.count("design A") == 1 and visible.count("design B") == 1
        assert visible.count("the first sensor") == 1  # named once for its three scenarios
    glance = _glance_section(prob, variant)  # type: ignore[arg-type]
    assert glance.count('<span class="bad">20\u00a0%</span>') == 2  # isolated over 20 % of the fault, both designs
    folded = _isolation_section(prob, variant)  # type: ignore[arg-type]
    assert folded.count("<details>") == 1 and re.search(r"<details>.*design A.*</details>", folded, flags=re.S)


def test_certificate_columns_carry_the_generators_labels() -> None:
    """The certificate names each generator by its label (the internal name where the problem has none), side by
    side for a small bank and one row each for a large one."""
    from types import SimpleNamespace

    from fdisyn.reporting.certificates import CERTIFICATE_COLUMNS, _certificate_table

    def gain_file(n: int) -> SimpleNamespace:
        check = {"name": "spectral radius of F", "reason": "F must be Schur stable", "value": 0.5, "relation": "<=", "bound": 1.0,
                 "passed": True}
        gens = [SimpleNamespace(name=f"uio_{k}") for k in range(n)]
        return SimpleNamespace(kind="linear", generators=gens, certificate={"generators": [{"checks": [check]} for _ in gens]})

    prob = SimpleNamespace(labels={"uio_0": "the observer on ω_r,m1"})
    for n in (2, CERTIFICATE_COLUMNS + 2):
        page = _certificate_table(gain_file(n), prob)  # type: ignore[arg-type]
        assert "the observer on ω_r,m1" in page and ">uio_0<" not in page and ">uio_1<" in page
        assert page.count("<table>") == (1 if n <= CERTIFICATE_COLUMNS else 2)


def test_the_glance_does_not_flatter_a_fault_alarmed_briefly() -> None:
    """A bias detected at once, alarmed for two samples and then silent for the rest of its 1000 samples: the
    glance shows its first alarm, and its alarm held and isolation over 0.2 % of the fault in bold red, never
    green; a fault alarmed and isolated throughout is green. The figures come from the metrics of the alarm
    traces themselves (:func:`fdisyn.evaluation.metrics.scenario_metrics`)."""
    from types import SimpleNamespace

    import numpy as np
    from fdisyn.evaluation.metrics import scenario_metrics
    from fdisyn.reporting.page import _glance_section, glance_verdict

    runs, n, onset = 4, 1200, 200
    active = np.arange(n) >= onset

    def metrics(alarmed: slice) -> object:
        alarm = np.zeros((runs, n), dtype=bool)
        alarm[:, alarmed] = True
        isolated = np.where(alarm, 0, -1)
        return scenario_metrics(scenario="s", fault="f", fault_index=0, active=active, alarm=alarm, isolated=isolated,
                                J=np.zeros((runs, n, 1)), thresholds=[1.0], P_f=[1e-3], Ts=0.004, recovery=0)

    brief, held = metrics(slice(onset + 2, onset + 4)), metrics(slice(onset + 2, n))
    assert brief.missed_detection_rate == 0.0 and brief.detection_delay_mean_s == 0.008
    assert brief.alarm_held_fraction == pytest.approx(0.002, rel=1e-12) and brief.isolated_held_fraction == pytest.approx(0.002, rel=1e-12)
    assert glance_verdict(brief) == ({"missed": False, "held": True, "isolated": True, "false_isolation": False}, False)
    assert glance_verdict(held)[1] is True
    for m, green in ((brief, False), (held, True)):
        ev = SimpleNamespace(runs=runs, metrics={"d": {"fault_free": _metric(None, 1.0), "s": m}})
        glance = _glance_section(SimpleNamespace(labels={}), SimpleNamespace(evaluation=ev))  # type: ignore[arg-type]
        assert ('class="ok"' in glance) is green
        if not green:
            assert glance.count('<span class="bad">0.2\u00a0%</span>') == 2 and ">0.008<" in glance
