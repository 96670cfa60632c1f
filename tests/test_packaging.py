"""The wheel carries every subpackage: ``pyproject.toml`` lists packages by hand (the folders are mapped
onto ``fdisyn``), so a new subpackage that is not listed would be missing from a non-editable install.
It carries the example plant files and the two references (``examples/PLANT_FILES.md``,
``runtime/REFERENCE.md``) too, the ``py.typed`` marker and the licence, and it installs the runtime alone (NumPy) unless the extra
``design`` is asked for."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_every_package_folder_is_listed_in_pyproject() -> None:
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(cfg["packages"])
    found = set()
    for package, folder in cfg["package-dir"].items():
        base = ROOT / folder
        for init in base.rglob("__init__.py"):
            rel = init.parent.relative_to(base)
            found.add(".".join([package, *rel.parts]))
    assert found == listed, f"missing from pyproject: {sorted(found - listed)}; listed but absent: {sorted(listed - found)}"


def test_the_base_installation_is_the_runtime_and_the_design_packages_are_an_extra() -> None:
    from fdisyn.app import DESIGN_EXTRA, DESIGN_PACKAGES

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert project["dependencies"] == ["numpy>=1.26"]
    extras = project["optional-dependencies"]
    assert tuple(re.match(r"[A-Za-z0-9_.-]+", r).group(0) for r in extras[DESIGN_EXTRA]) == DESIGN_PACKAGES
    assert f"fdisyn[{DESIGN_EXTRA}]" in extras["dev"]


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The wheel ``pip wheel`` builds from a copy of the sources (setuptools writes its ``build/`` there)."""
    src = tmp_path_factory.mktemp("src")
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy2(ROOT / name, src / name)
    for folder in ("design", "runtime", "problems"):
        shutil.copytree(ROOT / folder, src / folder, ignore=shutil.ignore_patterns("__pycache__"))
    out = tmp_path_factory.mktemp("wheel")
    proc = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "--wheel-dir", str(out), str(src)],
        capture_output=True, text=True, timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    (whl,) = out.glob("fdisyn-*.whl")
    return whl


@pytest.mark.slow
def test_the_wheel_carries_the_examples_and_installs_the_runtime_alone(wheel: Path, tmp_path: Path) -> None:
    from fdisyn.app import DESIGN_PACKAGES
    from fdisyn.app.examples import EXAMPLES, PLANT_FILES, example_names

    with zipfile.ZipFile(wheel) as zf:
        for name in example_names():
            assert zf.read(f"fdisyn/examples/{name}.toml") == (EXAMPLES / f"{name}.toml").read_bytes(), name
        # the references: the plant files' beside the examples, the formats' with the runtime
        assert zf.read("fdisyn/examples/PLANT_FILES.md") == PLANT_FILES.read_bytes()
        for script in sorted((EXAMPLES / "workflows").glob("*.py")):  # the workflow scripts the README names
            assert zf.read(f"fdisyn/examples/workflows/{script.name}") == script.read_bytes(), script.name
        assert zf.read("fdisyn/runtime/REFERENCE.md") == (ROOT / "runtime" / "REFERENCE.md").read_bytes()
        (meta,) = [n for n in zf.namelist() if n.endswith(".dist-info/METADATA")]
        requires = [ln.split(":", 1)[1].strip() for ln in zf.read(meta).decode().splitlines() if ln.startswith("Requires-Dist:")]
        site = tmp_path / "site"
        zf.extractall(site)
    assert [r for r in requires if "extra ==" not in r] == ["numpy>=1.26"]
    assert {r.split(">=")[0] for r in requires if 'extra == "design"' in r} == set(DESIGN_PACKAGES)
    # the installed package, without its design packages, writes an example where it is run
    work = tmp_path / "work"
    work.mkdir()
    code = "import sys\n" + "".join(f"sys.modules[{n!r}] = None\n" for n in DESIGN_PACKAGES) + (
        "import fdisyn\nfrom fdisyn.app.cli import main\nprint(fdisyn.__file__)\nsys.exit(main(['example', 'ship']) or main(['example', '--reference']))\n"
    )
    env = {**os.environ, "PYTHONPATH": str(site)}
    proc = subprocess.run([sys.executable, "-c", code], cwd=work, env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert Path(proc.stdout.splitlines()[0]).is_relative_to(site)  # the wheel's files, not the source tree
    assert (work / "ship.toml").read_bytes() == (EXAMPLES / "ship.toml").read_bytes()
    assert proc.stdout.endswith(PLANT_FILES.read_text(encoding="utf-8"))  # the reference, runtime-only too


@pytest.mark.slow
def test_the_wheel_carries_the_typing_marker_and_the_licence(wheel: Path) -> None:
    """``py.typed`` (PEP 561) at the package root, the MIT licence in the metadata and as a file."""
    with zipfile.ZipFile(wheel) as zf:
        names = zf.namelist()
        assert "fdisyn/py.typed" in names
        (meta,) = [n for n in names if n.endswith(".dist-info/METADATA")]
        fields = [ln for ln in zf.read(meta).decode().splitlines() if ln.startswith(("License-Expression:", "License-File:"))]
        (licence,) = [n for n in names if n.endswith(".dist-info/licenses/LICENSE")]
        assert zf.read(licence) == (ROOT / "LICENSE").read_bytes()
    assert "License-Expression: MIT" in fields and "License-File: LICENSE" in fields
    text = (ROOT / "LICENSE").read_text(encoding="utf-8")
    assert text.startswith("MIT License") and "Copyright (c) 2026 the fdisyn authors" in text


def test_the_source_tree_has_the_typing_marker_and_the_licence() -> None:
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert (ROOT / cfg["tool"]["setuptools"]["package-dir"]["fdisyn"] / "py.typed").is_file()
    assert "py.typed" in cfg["tool"]["setuptools"]["package-data"]["fdisyn"]
    assert cfg["project"]["license"] == "MIT" and cfg["project"]["license-files"] == ["LICENSE"]
    assert (ROOT / "LICENSE").is_file()
