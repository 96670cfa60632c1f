"""The type hints are checked, not decorative: mypy over the three packages."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).parents[1]


def test_mypy_passes(tmp_path):
    # mypy needs the packages laid out as fdisyn/<part>: link the three folders into a scratch tree
    pkg = tmp_path / "fdisyn"
    pkg.mkdir()
    for part in ("design", "runtime", "problems"):
        (pkg / part).symlink_to(ROOT / part, target_is_directory=True)
    proc = subprocess.run(
        [sys.executable, "-m", "mypy", "--namespace-packages", "--explicit-package-bases", "--ignore-missing-imports",
         "--cache-dir", str(tmp_path / ".cache"), "-p", "fdisyn"],
        cwd=tmp_path, capture_output=True, text=True, check=False,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
