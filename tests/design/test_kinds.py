"""The diagnoser-kind table (fdisyn.synthesis.kinds): every kind registered by its own module, complete and working
on a gain file designed by one of its methods; the methods name their kind and share it."""

from __future__ import annotations

import sys
import textwrap
from collections.abc import Mapping
from dataclasses import fields, replace
from types import SimpleNamespace

import numpy as np
import pytest
from fdisyn.app.examples import EXAMPLES
from fdisyn.codegen.step import step_function
from fdisyn.runtime.errors import ArgumentError, GainFileError
from fdisyn.runtime.gainfile import GainFile
from fdisyn.simulation.plant_file import load_spec
from fdisyn.synthesis import kinds, registry
from fdisyn.synthesis.kinds import STEP_INPUTS, STEP_OUTPUTS, DiagnoserKind, ExtraMetrics, get_kind, warmup_text

EXAMPLE_OF = {"linear": "dc_motor", "beard_fdf": "beard_textbook", "nafdf": "ship"}
"""A shipped plant file whose default design is of each kind."""


@pytest.fixture(scope="module")
def designed() -> dict[str, GainFile]:
    return {kind: load_spec(EXAMPLES / f"{name}.toml").design() for kind, name in EXAMPLE_OF.items()}


def test_the_builtin_kinds_are_registered_by_their_own_modules() -> None:
    assert kinds.kind_names() == sorted(EXAMPLE_OF)
    homes = {k.name: type(k).__module__ for k in kinds.all_kinds()}
    assert set(homes.values()) == {"fdisyn.synthesis.kinds"}
    where = {k.name: sys.modules[k.step_builder.__module__].__name__ for k in kinds.all_kinds()}
    assert where["nafdf"].startswith("fdisyn.synthesis.nafdf.") and where["beard_fdf"].startswith("fdisyn.synthesis.beard_fdf.")


@pytest.mark.parametrize("kind", sorted(EXAMPLE_OF))
def test_every_kind_is_complete_and_its_step_works(kind: str, designed: dict[str, GainFile]) -> None:
    k = get_kind(kind)
    assert isinstance(k, DiagnoserKind) and k.name == kind and k.summary
    for f in fields(DiagnoserKind):  # no field left out
        assert hasattr(k, f.name)
    gf = designed[kind]
    assert gf.kind == kind
    fn = k.step_builder(gf)
    assert tuple(fn.name_in()) == STEP_INPUTS and tuple(fn.name_out()) == STEP_OUTPUTS
    out = fn(gf.step.init_state, np.zeros(gf.step.nu), np.zeros(gf.step.ny))
    assert [np.array(o).size for o in out] == [gf.step.nstate, gf.step.nr, gf.step.nj, 1, 1, 1]
    assert tuple(step_function(gf).name_out()) == STEP_OUTPUTS
    blocks = k.certified(gf)
    assert blocks and all(isinstance(b, Mapping) and all(c["passed"] for c in b["checks"]) for b in blocks)
    assert isinstance(k.describe(gf), str) and k.describe(gf)
    assert k.rate_unit in ("per sample", "per statistic and sample")
    assert isinstance(kinds.recovery_samples(gf), int) and kinds.recovery_samples(gf) >= 0
    budget = kinds.false_alarm_budget(gf)
    assert budget is None or budget > 0
    assert k.extra_metrics is None or isinstance(k.extra_metrics, ExtraMetrics)
    assert k.budget_text is None or k.budget_text.startswith('<p class="small">')
    window = kinds.lorden_window(gf)
    assert window is None or window >= 1


def test_what_each_kind_says(designed: dict[str, GainFile]) -> None:
    lin, nafdf, beard = designed["linear"], designed["nafdf"], designed["beard_fdf"]
    warm = sorted({g.warmup for g in lin.generators})
    span = str(warm[0]) if len(warm) == 1 else f"{warm[0]}–{warm[-1]}"
    assert get_kind("linear").describe(lin) == f"{len(lin.generators)} generators, a warm-up of {span} samples before the statistics run"
    before = SimpleNamespace(kind="linear", generators=[replace(g, warmup=0) for g in lin.generators])  # a file written before warm-ups
    assert get_kind("linear").describe(before) == f"{len(lin.generators)} generators"  # type: ignore[arg-type]
    assert get_kind("nafdf").describe(nafdf) == f"a nafdf step with {nafdf.step.nstate} states"
    beard_warm = beard.extensions["beard_fdf"]["warmup"]
    assert beard_warm >= 1
    assert get_kind("beard_fdf").describe(beard) == (
        f"a beard_fdf step with {beard.step.nstate} states, a warm-up of {beard_warm} samples before its window fills")
    assert warmup_text(nafdf) is None and warmup_text(lin) == span and warmup_text(beard) == str(beard_warm)
    assert get_kind("linear").certified(lin) == list(lin.certificate["generators"])
    assert get_kind("nafdf").certified(nafdf) == [nafdf.certificate["nafdf"]]
    assert get_kind("linear").rate_unit == "per statistic and sample" and get_kind("nafdf").rate_unit == "per sample"
    assert "Ts·(1/P_f + 2·N2)" in get_kind("nafdf").budget_text
    assert get_kind("linear").budget_text is None and get_kind("beard_fdf").budget_text is None


def test_an_unknown_kind_in_a_gain_file_is_one_line(designed: dict[str, GainFile]) -> None:
    nafdf = designed["nafdf"]
    gf = replace(nafdf, kind="magic", extensions={"magic": nafdf.extensions["nafdf"]})
    for ask in (step_function, kinds.recovery_samples, kinds.false_alarm_budget, kinds.lorden_window):
        with pytest.raises(GainFileError) as err:
            ask(gf)
        msg = str(err.value)
        assert "\n" not in msg and msg == "no step builder for diagnoser kind 'magic'; known kinds: ['beard_fdf', 'linear', 'nafdf']"
    with pytest.raises(GainFileError, match=r"diagnoser kind 42; known kinds"):
        get_kind(42)  # type: ignore[arg-type]


def test_a_method_of_an_unregistered_kind_is_refused_in_one_line() -> None:
    m = registry.get_method("kalman_uio")
    with pytest.raises(ArgumentError) as err:
        registry.register(replace(m, name="kalman_uio_elsewhere", diagnoser_kind="magic"))
    assert "\n" not in str(err.value)
    assert str(err.value).startswith("method 'kalman_uio_elsewhere' names diagnoser kind 'magic', which no module registers; known kinds: [")
    assert "kalman_uio_elsewhere" not in registry.method_names()


def test_a_method_discovered_before_its_kind_is_checked_once_discovery_is_done(tmp_path, monkeypatch) -> None:  # noqa: ANN001
    """A plug-in package's method is registered while the modules are imported: its kind is checked after them all."""
    pkg = tmp_path / "extra_kinds"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a_method.py").write_text(
        textwrap.dedent(
            """
            from fdisyn.synthesis.registry import Method, get_method, register

            m = get_method("kalman_uio")
            register(Method("late_kind", "linear", "a method of a kind registered after it", "", m.options, m.design, "late"))
            register(Method("no_kind", "linear", "a method of no kind", "", m.options, m.design, "nowhere"))
            """
        )
    )
    (pkg / "b_kind.py").write_text(
        textwrap.dedent(
            """
            from fdisyn.synthesis.kinds import DiagnoserKind, get_kind, register_kind

            lin = get_kind("linear")
            register_kind(DiagnoserKind(name="late", summary="the linear kind under another name", step_builder=lin.step_builder))
            """
        )
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(kinds, "PLUGIN_PACKAGES", [*kinds.PLUGIN_PACKAGES, "extra_kinds"])
    monkeypatch.setattr(kinds, "_KINDS", dict(kinds._KINDS))
    monkeypatch.setattr(registry, "_METHODS", dict(registry._METHODS))
    try:
        with pytest.raises(ArgumentError, match=r"^method 'no_kind' names diagnoser kind 'nowhere', which no module registers"):
            registry.method_names()
        names = registry.method_names()
        assert "late_kind" in names and "no_kind" not in names
        assert get_kind(registry.get_method("late_kind").diagnoser_kind).summary == "the linear kind under another name"
    finally:
        kinds._SCANNED.discard("extra_kinds")
        for mod in ("extra_kinds.a_method", "extra_kinds.b_kind", "extra_kinds"):
            sys.modules.pop(mod, None)


def test_methods_of_one_kind_share_the_kind_object() -> None:
    by_kind: dict[str, list[str]] = {}
    for m in registry.all_methods():
        by_kind.setdefault(m.diagnoser_kind, []).append(m.name)
    assert set(by_kind) == set(kinds.kind_names())
    assert {"kalman_uio", "lmi", "kalman_uio_gos", "sampled_data_observer"} <= set(by_kind["linear"])
    from fdisyn.synthesis.linear_kind import LINEAR

    assert all(get_kind(registry.get_method(n).diagnoser_kind) is LINEAR for n in by_kind["linear"])
    # a method holds design-time fields only: what its gain files mean is asked of the kind
    for gone in ("step_builder", "recovery_samples", "extra_metrics", "false_alarm_budget", "lorden_bound", "lorden_window"):
        assert not hasattr(registry.get_method("lmi"), gone) and not hasattr(registry, gone)


def test_a_kind_name_is_registered_once() -> None:
    lin = get_kind("linear")
    assert kinds.register_kind(lin) is lin  # the same object again: harmless (a module imported twice)
    with pytest.raises(ArgumentError, match=r"^diagnoser kind 'linear' is registered twice"):
        kinds.register_kind(replace(lin, summary="another"))
    with pytest.raises(ArgumentError, match="a diagnoser kind's name is an identifier"):
        kinds.register_kind(replace(lin, name="two words"))
    assert get_kind("linear") is lin


@pytest.mark.parametrize("kind", sorted(EXAMPLE_OF))
def test_a_kind_has_an_account_view_or_says_why_not(kind: str, designed: dict[str, GainFile]) -> None:
    """The account (fdisyn.numerics.account) is computed on the view the kind gives of its gain file; a kind
    without one says why, and ``fdisyn design`` prints that line."""
    from fdisyn.numerics.account import BankView, account_lines
    from fdisyn.synthesis.account import fault_account, with_account

    k, gf = get_kind(kind), designed[kind]
    assert (k.account_view is None) != (k.account_note is None)
    if k.account_view is None:
        assert gf.account is None and fault_account(gf) is None and with_account(gf) is gf
        assert account_lines(None, k.account_note) == [f"what the design can see: not computed — {k.account_note}"]
        return
    view = k.account_view(gf)
    assert isinstance(view, BankView) and len(view.statistics) == len(view.statistic_names) == len(view.laws)
    assert {"A", "C"} <= set(view.model)
    recomputed = fault_account(replace(gf, account=None))
    assert recomputed is not None and [s["kind"] for s in recomputed["statistics"]] == [law.name for law in view.laws]
    assert gf.account is not None and gf.account["kind"] == kind


def test_the_account_does_not_ask_which_kind_it_is() -> None:
    """What differs between kinds comes from their views: the account's code names no diagnoser kind."""
    import inspect

    from fdisyn.numerics import account

    source = inspect.getsource(account)
    for name in kinds.kind_names():
        assert f'"{name}"' not in source and f"'{name}'" not in source, name
