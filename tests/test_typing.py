"""The type hints are checked, not decorative: mypy over the three packages.

mypy runs in a process of its own, started by ``tests/conftest.py`` as soon as this test is collected
to run (:func:`start_mypy`): on two cores it checks the packages beside the other tests instead of
after them, and the test waits for its verdict."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).parents[1]


def start_mypy(scratch: Path) -> subprocess.Popen:
    """mypy over ``fdisyn`` from the empty folder ``scratch``; its report goes to ``scratch/mypy.log``."""
    # mypy needs the package laid out as installed: design/ is fdisyn/ (its files and subpackages),
    # runtime/ and problems/ are fdisyn/runtime and fdisyn/problems; link them into a scratch tree
    pkg = scratch / "fdisyn"
    pkg.mkdir()
    for entry in (ROOT / "design").iterdir():
        if entry.name != "__pycache__":
            (pkg / entry.name).symlink_to(entry, target_is_directory=entry.is_dir())
    for part in ("runtime", "problems"):
        (pkg / part).symlink_to(ROOT / part, target_is_directory=True)
    with open(scratch / "mypy.log", "w", encoding="utf-8") as log:
        return subprocess.Popen(
            [sys.executable, "-m", "mypy", "--namespace-packages", "--explicit-package-bases", "--ignore-missing-imports",
             "--cache-dir", str(scratch / ".cache"), "-p", "fdisyn"],
            cwd=scratch, stdout=log, stderr=subprocess.STDOUT,
        )


def test_mypy_passes(mypy_run) -> None:
    proc, scratch = mypy_run
    assert proc.wait() == 0, (scratch / "mypy.log").read_text(encoding="utf-8")
