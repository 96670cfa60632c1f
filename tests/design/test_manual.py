"""The README is a manual, and the references hold the rest: the README's outline, length and first two commands;
the formats in the runtime's reference and the plant files in the reference beside the examples, each path they
name present in the source tree; ``fdisyn methods NAME`` and ``fdisyn example --reference`` serving them."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from fdisyn.app.cli import main
from fdisyn.app.examples import PLANT_FILES

ROOT = Path(__file__).parents[2]
README = ROOT / "README.md"
REFERENCE = ROOT / "runtime" / "REFERENCE.md"

OUTLINE = [
    "The two commands", "Install", "Python", "Command line", "Choosing a method and a detector", "Deploying",
    "Reproducing the papers", "Errors", "Layout",
]


def _headings(path: Path, level: str = "## ") -> list[str]:
    text = re.sub(r"```.*?```", "", path.read_text(encoding="utf-8"), flags=re.S)
    return [ln[len(level) :] for ln in text.splitlines() if ln.startswith(level)]


def _err(capsys) -> str:  # noqa: ANN001 - pytest's capsys
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    return err


def test_the_readme_is_a_manual_of_about_250_lines() -> None:
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 300
    assert _headings(README) == OUTLINE
    assert "| method | option |" not in text  # the option tables are fdisyn methods NAME's
    for word in ("arl0", "P_f", "chi2", "wssr", "cusum", "glr", "sensor", "component", "parameter", "FDISYN_DEBUG"):
        assert word in text, word


def test_the_first_two_commands_are_the_main_job_and_the_tests() -> None:
    """.ci/run runs the second; the first is the main job the reports come from."""
    blocks = re.findall(r"```sh\n(.*?)```", README.read_text(encoding="utf-8"), flags=re.S)
    assert blocks[:2] == ["python3 -m pip install '.[design]' && fdisyn reproduce\n", "python3 -m pip install '.[dev]' && python3 -m pytest\n"]
    assert "python3 -m pip install '.[dev]' && python3 -m pytest" in (ROOT / ".ci" / "run").read_text(encoding="utf-8")


def test_the_references_hold_the_moved_sections() -> None:
    assert _headings(REFERENCE) == [
        "Names", "The gain file (`DIR/gains.json`, format `fdisyn.gains/1`)", "The C API (`DIR/c/<name>.h`)",
        "Replay CSV grammar", "Errors",
    ]
    assert _headings(PLANT_FILES) == [
        "Your own plant: the TOML format", "Methods", "What the design can see", "The command line in detail",
        "The reports", "References",
    ]
    assert _headings(PLANT_FILES, "### ") == [
        "Process noise, names and units", "Several designs on one page, and options from the command line",
        "A nonlinear plant (the NAFDF)", "A generalised UIO bank (`kalman_uio_gos`)", "A Beard filter (`beard_fdf`)",
    ]


@pytest.mark.parametrize("doc", [README, REFERENCE, PLANT_FILES], ids=lambda p: p.name)
def test_every_source_path_a_document_names_exists(doc: Path) -> None:
    """Modules move: a path the manual or a reference names in the source tree must still be there."""
    paths = set(re.findall(r"`((?:design|runtime|problems|tests|reports)/[A-Za-z0-9_./-]*)`", doc.read_text(encoding="utf-8")))
    assert paths, doc
    assert sorted(p for p in paths if not (ROOT / p).exists()) == []


@pytest.mark.parametrize("doc", [README, REFERENCE, PLANT_FILES], ids=lambda p: p.name)
def test_every_module_a_document_names_exists(doc: Path) -> None:
    """A dotted name (`fdisyn.runtime.errors`, `fdisyn.design`) is a module, or an attribute of its parent module."""
    import importlib

    missing = []
    for dotted in sorted(set(re.findall(r"`(fdisyn(?:\.[A-Za-z_]+)+)`", doc.read_text(encoding="utf-8")))):
        try:
            importlib.import_module(dotted)
        except ModuleNotFoundError:
            parent, _, attr = dotted.rpartition(".")
            if not hasattr(importlib.import_module(parent), attr):
                missing.append(dotted)
    assert missing == []


def test_the_c_api_reference_declares_what_the_header_declares() -> None:
    header = (ROOT / "runtime" / "c" / "diagnoser.h.in").read_text(encoding="utf-8")
    section = REFERENCE.read_text(encoding="utf-8").split("## The C API", 1)[1].split("\n## ", 1)[0]
    for macro in re.findall(r"#define @PREFIX@_(\w+)", header):
        if macro != "H":  # the include guard
            assert f"<NAME>_{macro}" in section, macro
    for symbol in re.findall(r"@prefix@_(\w+)\s*[\[(]", header):
        assert f"<name>_{symbol}" in section, symbol


def test_example_reference_prints_the_plant_file_reference(capsys) -> None:
    assert main(["example", "--reference"]) == 0
    assert capsys.readouterr().out == PLANT_FILES.read_text(encoding="utf-8")


@pytest.mark.parametrize("argv", [["example", "dc_motor", "--reference"], ["example", "--reference", "--force"]])
def test_example_reference_takes_nothing_else(argv, tmp_path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    assert "fdisyn example: error: --reference takes no NAME, --out or --force" in _err(capsys)
    assert list(tmp_path.iterdir()) == []


def test_methods_name_prints_its_option_table(capsys) -> None:
    assert main(["methods", "nafdf"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("nafdf (nonlinear plant): nonlinear adaptive fault detection filter")
    assert lines[1] == "  plant: a NonlinearPlant"
    assert lines[3].split() == ["option", "default", "expected", "/", "meaning"]
    assert lines[4].split()[:3] == ["P_f", "None", "a"]
    assert not any(ln.startswith("kalman_uio") for ln in lines)


def test_methods_option_filters_by_name_or_pattern(capsys) -> None:
    assert main(["methods", "nafdf", "--option", "WINDOW"]) == 0  # a part of the name, in any case
    rows = [ln.split()[0] for ln in capsys.readouterr().out.splitlines() if ln.startswith("    ") and not ln.startswith("     ")]
    assert rows == ["option", "window", "classifier_window"]
    assert main(["methods", "--option", "P_*"]) == 0  # a shell pattern, over every method
    out = capsys.readouterr().out
    heads = [ln.split(" ", 1)[0] for ln in out.splitlines() if ln and not ln.startswith(" ")]
    assert heads == ["beard_fdf", "kalman_uio", "kalman_uio_gos", "kalman_uio_paper", "lmi", "nafdf", "nullspace", "sampled_data_observer",
                     "uio_pole_placement"]
    rows = {ln.split()[0] for ln in out.splitlines() if ln.startswith("    ") and not ln.startswith("     ")}
    assert rows == {"option", "P_f"}


def test_methods_plant_kind_keeps_one_kind(capsys) -> None:
    assert main(["methods", "--plant-kind", "continuous"]) == 0
    heads = [ln.split(" ", 1)[0] for ln in capsys.readouterr().out.splitlines() if not ln.startswith(" ")]
    assert heads == ["lmi", "sampled_data_observer"]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["methods", "kalman"], "fdisyn methods: error: no design method 'kalman'; methods: ['beard_fdf', 'kalman_uio', 'kalman_uio_gos', "),
        (["methods", "--plant-kind", "discrete"], "fdisyn methods: error: --plant-kind 'discrete': expected one of linear, continuous, nonlinear"),
        (["methods", "nafdf", "--plant-kind", "linear"], "method 'nafdf' designs for nonlinear plants, not linear"),
        (["methods", "lmi", "--option", "poles"], "--option 'poles' matches no option; expected a name or a pattern such as 'P_*' matching one of P_f, Ts,"),
    ],
)
def test_a_refused_method_or_filter_is_one_line(argv, message, capsys) -> None:
    assert main(argv) == 2
    assert message in _err(capsys)


def test_the_readme_c_example_builds_from_the_files_it_names(motor_built, tmp_path) -> None:
    """The README's C lines, in a program of their own, compile with the four files it names and nothing else of
    ``DIR/c/`` (``<name>.c`` the one compiled), and run: the motor at rest, no alarm."""
    import subprocess

    from fdisyn.codegen.library import CFLAGS, compiler

    text = README.read_text(encoding="utf-8").split("\n## Deploying\n", 1)[1].split("\n## ", 1)[0]
    (code,) = re.findall(r"```c\n(.*?)```", text, flags=re.S)
    name = motor_built.gain_file.name
    code = code.replace("<NAME>", name.upper()).replace("<name>", name)
    include, body = code.split("\n", 1)
    assert include.startswith(f'#include "{name}.h"')
    for f in (f"{name}.c", f"{name}.h", f"{name}_casadi.c", f"{name}_casadi.h"):
        (tmp_path / f).write_bytes((motor_built.directory / "c" / f).read_bytes())
    (tmp_path / "main.c").write_text(
        f"#include <stdio.h>\n{include}\nstatic void report(const char *what) {{ printf(\"alarm %s\\n\", what); }}\n"
        f"int main(void) {{\n    double u[1] = {{0.4}}, y[3] = {{0.4, 0.0, 0.0}};\n{body}"
        "    printf(\"%d %d\\n\", alarm, isolated);\n    return 0;\n}\n",
        encoding="utf-8",
    )
    exe = tmp_path / "monitor"
    subprocess.run([*compiler(), *CFLAGS, "main.c", f"{name}.c", "-o", str(exe), "-lm"], cwd=tmp_path, check=True, capture_output=True, timeout=300)
    assert subprocess.run([str(exe)], capture_output=True, text=True, timeout=60, check=True).stdout == "0 -1\n"


def test_a_reader_that_stops_early_ends_the_command_quietly(tmp_path) -> None:
    """``fdisyn example --reference | head``: the reader closes the pipe; the command ends with 141 (128 + SIGPIPE, as
    a shell's own commands do) and nothing on stderr, not status 3."""
    import os
    import subprocess
    import sys

    read, write = os.pipe()
    os.close(read)  # a reader already gone
    try:
        proc = subprocess.run(
            [sys.executable, "-c", "import sys; from fdisyn.app.cli import main; sys.exit(main(['example', '--reference']))"],
            stdout=write, stderr=subprocess.PIPE, text=True, timeout=120, cwd=tmp_path,
        )
    finally:
        os.close(write)
    assert (proc.returncode, proc.stderr) == (141, "")


def test_the_error_table_names_every_error_type() -> None:
    from fdisyn.runtime import errors

    section = REFERENCE.read_text(encoding="utf-8").split("\n## Errors\n", 1)[1]
    types = [n for n, v in vars(errors).items() if isinstance(v, type) and issubclass(v, errors.FdisynError) and v is not errors.FdisynError]
    assert [n for n in types if f"`{n}`" not in section] == []


def test_every_command_line_example_of_the_readme_parses() -> None:
    """Each verb of the README's command table, and its example, is one the parser takes (none is run here)."""
    import shlex

    from fdisyn.app.cli import _parser

    section = README.read_text(encoding="utf-8").split("\n## Command line\n", 1)[1].split("\n## ", 1)[0]
    rows = [ln for ln in section.splitlines() if ln.startswith("| `fdisyn ")]
    verbs = [re.match(r"\| `fdisyn (\w+)", ln).group(1) for ln in rows]
    parser = _parser()
    subparsers = next(a for a in parser._actions if a.dest == "command")  # noqa: SLF001 - argparse keeps them there
    assert sorted(verbs) == sorted(subparsers.choices)
    for ln in rows:
        example = re.findall(r"`([^`]*)`", ln.rsplit("|", 2)[1])[0]
        argv = shlex.split(example)
        assert argv[0] == "fdisyn", example
        parser.parse_args(argv[1:])
