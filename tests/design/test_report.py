"""The report's figures leave the user's Matplotlib backend alone and need no display."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
from fdisyn.app.report import ReportContext, subplots, timeline


def test_importing_the_report_and_the_problems_selects_no_backend() -> None:
    """A fresh interpreter with the user's backend set: the report and every problem module (they
    draw the paper's figures) import without pyplot and without touching the backend."""
    script = (
        "import sys, matplotlib\n"
        "import fdisyn.app.report, fdisyn.problems.wind_turbine, fdisyn.problems.ship_propulsion\n"
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

    from fdisyn.app.report import _compared_detectors

    def variants(*detectors: str) -> list[SimpleNamespace]:
        return [SimpleNamespace(options={"detector": None, "arl0": None})] + [SimpleNamespace(options={"detector": d, "arl0": 60.0}) for d in detectors]

    assert _compared_detectors(variants("glr", "chi2", "cusum")) == (
        "Per-sample χ², CUSUM (Page, Biometrika 41(1/2), 1954) and windowed GLR (Willsky & Jones, IEEE Transactions on "
        "Automatic Control 21(1), 1976)"
    )
    assert _compared_detectors(variants("wssr", "cusum")) == "WSSR (Long & Wang, Aeroengine 43(5), 2017, section 2) and CUSUM (Page, Biometrika 41(1/2), 1954)"
