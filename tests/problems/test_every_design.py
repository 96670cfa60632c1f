"""Every built-in design of every report variant, as the main job designs it, under the BLAS kernel in use.

Marked ``kernels``: not part of the default run (it designs all 44 gain files, about 100 s on two cores);
``.ci/run`` runs it under the machine's own OpenBLAS kernel and again under ``OPENBLAS_CORETYPE=Haswell``, so
a design that exists on one CPU and fails on another (an NLP or an SDP whose iterates depend on the kernel) stops
CI. Each design must pass its certificate and give the committed report's gain file (``reports/<problem>/gains``):
the numbers a diagnoser runs on equal within 1e-6 of each array's largest entry — kernels change a closed form's
last digits (1e-16), an SDP's or a pole placement's iterates by about 1e-10 and a training SVD by 1e-9, measured
under the Zen, Haswell, SandyBridge and Nehalem kernels — plus 1e-12 absolute for arrays that are round-off
themselves (a residual's cancelled feedthrough of 1e-16). The satellite's optimised Beard filter, a nonconvex
NLP, is compared too: a converged KKT point is preferred to a point where IPOPT broke off, so every kernel returns
the same filter (3e-11 apart under the four kernels).
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fdisyn.app.pipeline import variant_specs
from fdisyn.reporting.page import published_gain_name
from fdisyn.simulation.problem import get_problem, problem_names

pytestmark = pytest.mark.kernels

REPORTS = Path(__file__).resolve().parents[2] / "reports"
NOT_THE_DIAGNOSER = ("certificate", "provenance", "account", "design")
"""Keys whose numbers describe the design (checks, diagnostics, timings) rather than the diagnoser it runs."""

CASES = [
    pytest.param(name, label, options, design, id=f"{name}-{label}-{design}")
    for name in problem_names()
    for label, options, _, designs, _ in variant_specs(get_problem(name), get_problem(name).monte_carlo_runs)
    for design in designs
]


def _arrays(doc: Any, path: str = "") -> dict[str, list[float]]:
    """The numbers of a gain file's document, grouped per array (its path without the trailing indices)."""
    out: dict[str, list[float]] = {}

    def walk(x: Any, p: str) -> None:
        if isinstance(x, dict):
            for k, v in x.items():
                if k not in NOT_THE_DIAGNOSER:
                    walk(v, f"{p}/{k}")
        elif isinstance(x, list):
            for i, v in enumerate(x):
                walk(v, f"{p}[{i}]")
        elif isinstance(x, (int, float)) and not isinstance(x, bool):
            out.setdefault(re.sub(r"(\[\d+\])+$", "", p), []).append(float(x))

    walk(doc, path)
    return out


@pytest.mark.parametrize(("problem", "label", "options", "design"), CASES)
def test_every_builtin_design_designs_and_matches_the_committed_report(problem: str, label: str, options: dict, design: str) -> None:
    gf = get_problem(problem).design(design, **options)
    assert gf.certificate.get("passed") is True, f"{problem}/{label}/{design}: certificate failed"
    # a variant whose gain file's name an earlier variant published has its label in the file's name
    gains = REPORTS / problem / "gains"
    own = gains / published_gain_name(gf.name, label, {f"{gf.name}.json"})
    committed = own if own.exists() else gains / f"{gf.name}.json"
    assert committed.exists(), f"{committed} is not committed: run `fdisyn reproduce {problem}`"
    ours = _arrays(json.loads(json.dumps(gf.to_dict())))
    theirs = _arrays(json.loads(committed.read_text(encoding="utf-8")))
    assert ours.keys() == theirs.keys(), f"{gf.name}: arrays differ: {sorted(ours.keys() ^ theirs.keys())}"
    worse = []
    for key, ref in theirs.items():
        a, b = np.asarray(ref), np.asarray(ours[key])
        if a.shape != b.shape:
            worse.append(f"{key}: {a.size} numbers, now {b.size}")
            continue
        finite = np.isfinite(a)
        if not np.array_equal(finite, np.isfinite(b)) or not np.array_equal(a[~finite], b[~finite]):
            worse.append(f"{key}: non-finite entries differ")
            continue
        scale = float(np.max(np.abs(a[finite]), initial=0.0))
        err = float(np.max(np.abs(a[finite] - b[finite]), initial=0.0))
        if err > 1e-6 * scale + 1e-12:
            worse.append(f"{key}: {err:.3g} of {scale:.3g}")
    assert not worse, f"{gf.name} differs from the committed report: " + "; ".join(worse[:8])
