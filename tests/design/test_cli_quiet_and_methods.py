"""``--quiet`` before or after the command, and ``fdisyn methods``: one line per method, the option tables by name."""

from __future__ import annotations

import argparse

import pytest
from fdisyn.app.cli import _parser, main
from fdisyn.synthesis.registry import all_methods


def _subparsers(ap: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    (sub,) = [a for a in ap._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(sub.choices)


def test_every_command_takes_quiet_after_it() -> None:
    commands = _subparsers(_parser())
    assert len(commands) >= 10
    for name, p in commands.items():
        (quiet,) = [a for a in p._actions if "--quiet" in a.option_strings]
        assert quiet.default is argparse.SUPPRESS, name


@pytest.mark.parametrize(
    ("argv", "quiet"),
    [
        (["report", "x.toml", "--quiet"], True),
        (["--quiet", "report", "x.toml"], True),
        (["report", "--quiet", "x.toml"], True),
        (["--quiet", "report", "x.toml", "--quiet"], True),
        (["report", "x.toml"], False),
        (["design", "x.toml", "--out", "d", "--quiet"], True),
        (["replay", "d", "in.csv", "out.csv", "--quiet"], True),
    ],
)
def test_quiet_is_read_in_either_place(argv, quiet) -> None:
    assert _parser().parse_args(argv).quiet is quiet


@pytest.mark.parametrize("argv", [["list", "--quiet"], ["--quiet", "list"], ["methods", "lmi", "--quiet"]])
def test_a_command_run_with_quiet_anywhere_is_quiet(argv, monkeypatch, capsys) -> None:
    import fdisyn.evaluation.progress as progress

    seen = []
    monkeypatch.setattr(progress, "set_quiet", seen.append)
    assert main(argv) == 0
    assert seen == [True]
    capsys.readouterr()
    assert main(argv[1:] if argv[0] == "--quiet" else [a for a in argv if a != "--quiet"]) == 0
    assert seen == [True, False]


def test_methods_alone_is_one_line_per_method(capsys) -> None:
    assert main(["methods"]) == 0
    lines = capsys.readouterr().out.splitlines()
    methods = all_methods()
    assert lines == [f"{m.name} ({m.plant_kind} plant): {m.summary}" for m in methods]
    assert len(lines) == len(methods) < 20


def test_methods_plant_kind_alone_is_the_short_list_of_that_kind(capsys) -> None:
    assert main(["methods", "--plant-kind", "nonlinear"]) == 0
    assert capsys.readouterr().out.splitlines() == [f"{m.name} ({m.plant_kind} plant): {m.summary}" for m in all_methods() if m.plant_kind == "nonlinear"]


def test_methods_name_keeps_the_full_option_table(capsys) -> None:
    assert main(["methods", "kalman_uio"]) == 0
    out = capsys.readouterr().out
    (method,) = [m for m in all_methods() if m.name == "kalman_uio"]
    assert "  reference: " in out and out.splitlines()[3].split()[:2] == ["option", "default"]
    rows = {ln.split()[0] for ln in out.splitlines() if ln.startswith("    ") and not ln.startswith("     ")} - {"option"}
    assert rows == {o.name for o in method.options}
    assert main(["methods", "--option", "arl0", "--plant-kind", "continuous"]) == 0
    heads = [ln.split(" ", 1)[0] for ln in capsys.readouterr().out.splitlines() if ln and not ln.startswith(" ")]
    assert heads == [m.name for m in all_methods() if m.plant_kind == "continuous"]
