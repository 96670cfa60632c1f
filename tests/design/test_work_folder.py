"""fdisyn's work folder (``--workdir``) defaults to ``.fdisyn/`` in the current directory, for every command
and for :func:`reproduce_problem` alike, and never to setuptools' ``build/``."""

from __future__ import annotations

import inspect
from pathlib import Path

from fdisyn.app import WORKDIR
from fdisyn.app.cli import _parser
from fdisyn.app.pipeline import reproduce_problem

ROOT = Path(__file__).parents[2]


def test_every_command_and_the_api_default_to_one_work_folder() -> None:
    assert WORKDIR == Path(".fdisyn")
    ap = _parser()
    for argv in (
        ["evaluate", "wind_turbine", "--out", "m.json"],
        ["report", "wind_turbine"],
        ["reproduce"],
        ["bench"],
    ):
        assert Path(ap.parse_args(argv).workdir) == WORKDIR, argv
    assert inspect.signature(reproduce_problem).parameters["workdir"].default == WORKDIR


def test_the_work_folder_is_ignored_by_git() -> None:
    assert f"{WORKDIR}/" in (ROOT / ".gitignore").read_text(encoding="utf-8").splitlines()
