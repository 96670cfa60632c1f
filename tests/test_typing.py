"""The type hints are checked, not decorative: mypy over the three packages."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).parents[1]


def test_mypy_passes(tmp_path):
    # mypy needs the package laid out as installed: design/ is fdisyn/ (its files and subpackages),
    # runtime/ and problems/ are fdisyn/runtime and fdisyn/problems; link them into a scratch tree
    pkg = tmp_path / "fdisyn"
    pkg.mkdir()
    for entry in (ROOT / "design").iterdir():
        if entry.name != "__pycache__":
            (pkg / entry.name).symlink_to(entry, target_is_directory=entry.is_dir())
    for part in ("runtime", "problems"):
        (pkg / part).symlink_to(ROOT / part, target_is_directory=True)
    proc = subprocess.run(
        [sys.executable, "-m", "mypy", "--namespace-packages", "--explicit-package-bases", "--ignore-missing-imports",
         "--cache-dir", str(tmp_path / ".cache"), "-p", "fdisyn"],
        cwd=tmp_path, capture_output=True, text=True, check=False,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
