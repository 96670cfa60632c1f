"""The detector table: every statistic kind the runtime reads has one design-side entry with its symbolic
update, and no module outside the detectors' own names a detector in code."""

from __future__ import annotations

import ast
import pathlib

import pytest
from fdisyn.detectors.symbolic import LinearStatistic
from fdisyn.detectors.table import DETECTORS, option_texts, quoted, windowed_kinds
from fdisyn.runtime.schema import EVALUATOR_KINDS, SEQUENTIAL_KINDS
from fdisyn.synthesis.linear_diagnoser import check_window, is_sequential
from fdisyn.runtime.errors import ArgumentError
from fdisyn.runtime.statistics import STATISTICS

ROOT = pathlib.Path(__file__).resolve().parents[2]

OWN_MODULES = {
    "design/detectors/chi2.py",
    "design/detectors/wssr.py",
    "design/detectors/sequential.py",
    "runtime/statistics.py",  # the runtime's entry of each kind: its fields, state block and NumPy oracle
}
"""The detectors' own modules: they name their kinds."""

ALLOWED = {
    # path: (the kinds it may name and how often, None: any; why)
    "design/detectors/symbolic.py": ({"chi2": 1}, "its __all__ lists its function chi2 (q = rᵀ W r), the shared vocabulary"),
    "design/synthesis/linear_diagnoser.py": ({"chi2": 2}, "the linear methods' default detector (linear_diagnoser, chosen_detector)"),
    "design/synthesis/uio_gos.py": ({"wssr": 1}, "kalman_uio_gos's default detector (DEFAULT_DETECTOR, the paper's WSSR)"),
    "design/synthesis/nafdf/design.py": (None, "the NAFDF's own fast detection (its settings and payload, not the linear table)"),
    "design/synthesis/nafdf/method.py": (None, "the NAFDF's own fast detection"),
    "design/synthesis/nafdf/payload.py": (None, "the NAFDF's own fast detection"),
    "design/synthesis/nafdf/settings.py": (None, "the NAFDF's own fast detection"),
    "design/synthesis/nafdf/step.py": (None, "the NAFDF's own fast detection"),
    "problems/sampled_data_example.py": (None, "a problem chooses the detectors its study compares"),
    "problems/ship_propulsion.py": (None, "a problem chooses the detectors its study compares (NAFDF fast detection)"),
    "problems/turbofan.py": (None, "a problem chooses the detectors its study compares"),
    "problems/wind_turbine.py": (None, "a problem chooses the detectors its study compares"),
    "problems/wind_turbine_efficiency.py": (None, "a problem chooses the detectors its study compares (NAFDF fast detection)"),
}
"""Modules that may name a detector kind in code, and why."""

NOT_YET: dict[str, str] = {}
"""Modules that still name detectors and should read a table instead (left as they are, with the reason): none."""

KINDS = frozenset(EVALUATOR_KINDS)


def _named_kinds(path: pathlib.Path) -> list[tuple[int, str]]:
    """String constants in code (not docstrings) that are exactly a detector kind."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    docs = set()
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if isinstance(body, list):
            docs.update(
                id(s.value) for s in body if isinstance(s, ast.Expr) and isinstance(s.value, ast.Constant)
            )
    return sorted(
        (n.lineno, n.value)
        for n in ast.walk(tree)
        if isinstance(n, ast.Constant) and isinstance(n.value, str) and n.value in KINDS and id(n) not in docs
    )


def test_every_kind_of_the_gain_file_has_one_design_entry_and_symbolic_update_and_vice_versa():
    assert tuple(DETECTORS) == tuple(STATISTICS) == EVALUATOR_KINDS
    for kind, d in DETECTORS.items():
        runtime = STATISTICS[kind]
        assert d.kind == runtime.kind == kind
        assert isinstance(d.statistic, LinearStatistic)
        assert d.statistic.sequential == d.sequential == runtime.sequential == (kind in SEQUENTIAL_KINDS)
        assert d.statistic.block == runtime.block  # the symbolic step reads the block the oracle writes
        assert (runtime.update is None) == (runtime.block is None)
        assert d.windowed == runtime.window_read
        assert (d.hypotheses is not None) == d.sequential
        assert bool(d.no_window) != d.windowed and bool(d.window_doc) == d.windowed == bool(d.window_default)
        assert d.evaluators is not None and d.doc


def test_the_option_texts_list_every_detector_in_the_order_of_the_gain_file():
    texts = option_texts()
    assert texts["kinds"] == quoted(EVALUATOR_KINDS) == "'chi2', 'wssr', 'cusum' or 'glr'"
    assert all(f"{k!r}, " in texts["detector"] for k in EVALUATOR_KINDS)
    assert texts["sequential"] == quoted(SEQUENTIAL_KINDS, "and")
    assert set(windowed_kinds()) <= KINDS


def test_the_window_and_sequential_rules_come_from_the_table():
    for kind, d in DETECTORS.items():
        assert is_sequential(kind) == d.sequential
        check_window(kind, None, "m")
        check_window(kind, 1, "m")
        if d.windowed:
            check_window(kind, 5, "m")
        else:
            with pytest.raises(ArgumentError, match=f"needs detector = {quoted(windowed_kinds())}"):
                check_window(kind, 5, "m")
    assert not is_sequential("nonsense")
    check_window("nonsense", 5, "m")  # an unknown detector is refused by the option's own domain


def test_no_module_outside_the_detectors_names_a_detector_kind_in_code():
    found = {}
    for top in ("design", "runtime", "problems"):
        for path in sorted((ROOT / top).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            if rel in OWN_MODULES or rel in NOT_YET or rel.startswith("design/examples/"):  # user scripts: they choose one
                continue
            named = _named_kinds(path)
            allowed = ALLOWED[rel][0] if rel in ALLOWED else {}
            counts = {k: sum(1 for _, n in named if n == k) for _, k in named}
            if allowed is not None and any(c > allowed.get(k, 0) for k, c in counts.items()):
                found[rel] = named
    assert not found, f"modules naming a detector kind in code (read fdisyn.detectors.table.DETECTORS instead): {found}"


def test_the_exceptions_are_still_needed():
    """An exception that no longer names a detector is removed from the lists."""
    stale = [rel for rel in (*ALLOWED, *NOT_YET) if (ROOT / rel).exists() and not _named_kinds(ROOT / rel)]
    assert not stale, f"listed as naming a detector but naming none: {stale}"


def test_a_new_detector_is_one_registration_and_the_option_texts_and_rules_follow(monkeypatch):
    """What a new detector's module does (register an entry) is all the bank's checks and the option texts need."""
    from dataclasses import replace

    from fdisyn.detectors.table import register

    monkeypatch.setattr("fdisyn.detectors.table.DETECTORS", dict(DETECTORS))
    import fdisyn.detectors.table as table

    register(replace(DETECTORS["wssr"], kind="toy", doc="a toy statistic", window_doc="the toy's window", window_default="2"))
    assert list(table.DETECTORS)[-1] == "toy" and list(table.DETECTORS)[:4] == list(EVALUATOR_KINDS)
    texts = table.option_texts()
    assert texts["kinds"].endswith("'glr' or 'toy'") and "'toy', a toy statistic" in texts["detector"]
    assert texts["window_default"].endswith("2 for 'toy'") and "'toy'" in quoted(table.windowed_kinds())
