"""The example plant files shipped in the package (``fdisyn/examples/*.toml``) and ``fdisyn example``.

They are the plant files the plant-file reference (``PLANT_FILES.md`` beside them) shows and the tests design:
``dc_motor`` (the reference's linear plant),
``sampled_data`` (Qiu, Wen & Jiang 2010, Control Theory & Applications 27(8), section 4), ``ship`` (Zhou,
Xi & Zhang c. 1991, Shanghai Jiao Tong University, eq. (3.1)) and ``beard_textbook`` (a Beard filter).
``fdisyn example NAME`` copies one into the current directory to be read and changed; ``fdisyn example
--reference`` prints the reference. Nothing here
needs more than the standard library, so the command works in a runtime-only installation too.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

from fdisyn.runtime.errors import ArgumentError, FileError

__all__ = ["EXAMPLES", "PLANT_FILES", "example_names", "example_path", "example_title", "plant_file_reference", "write_example"]

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
"""The folder of the example plant files: ``fdisyn/examples`` (``design/examples`` in the source tree)."""

PLANT_FILES = EXAMPLES / "PLANT_FILES.md"
"""The plant-file reference, shipped beside the examples: every key of a plant file, the methods' keys and limits,
what ``fdisyn design`` prints and how the Monte Carlo runs (``fdisyn example --reference`` prints it)."""


def example_names() -> list[str]:
    """The examples' names: their file names without ``.toml``, sorted."""
    return sorted(p.stem for p in EXAMPLES.glob("*.toml"))


def example_path(name: str) -> Path:
    """The plant file of example ``name``; an unknown name is refused with the list of known ones."""
    names = example_names()
    if name not in names:
        raise ArgumentError(f"no example plant file {name!r}; the examples are {', '.join(names)} (fdisyn example lists them)")
    return EXAMPLES / f"{name}.toml"


def example_title(name: str) -> str:
    """The example's ``title`` (its ``name`` when it has none)."""
    doc = tomllib.loads(example_path(name).read_text(encoding="utf-8"))
    return str(doc.get("title") or doc.get("name") or name)


def plant_file_reference() -> str:
    """The plant-file reference, :data:`PLANT_FILES`, as text.

    Returns
    -------
    str
        The document (Markdown, UTF-8).

    Raises
    ------
    FileError
        The installation lacks the document (a package built without its data files).
    """
    try:
        return PLANT_FILES.read_text(encoding="utf-8")
    except OSError as exc:
        raise FileError(
            f"cannot read the plant-file reference {PLANT_FILES}: {exc.strerror or exc}; expected it installed with "
            "fdisyn's examples: reinstall fdisyn (python3 -m pip install .)"
        ) from None


def write_example(name: str, out: str | Path | None = None, *, force: bool = False) -> Path:
    """Copy example ``name`` to ``out`` (default ``<name>.toml`` in the current directory); return the path.

    An existing ``out`` is replaced only with ``force``; a directory never is.
    """
    src = example_path(name)
    dst = Path(f"{name}.toml" if out is None else out)
    if dst.is_dir():
        raise FileError(f"{dst} is a directory: expected the name of the plant file to write")
    if dst.exists() or dst.is_symlink():
        if not force:
            raise FileError(f"{dst} exists: expected a new file name, or --force to replace it")
        if dst.is_symlink():  # replace the link itself, never the file it leads to
            dst.unlink()
    dst.parent.mkdir(parents=True, exist_ok=True)
    dst.write_bytes(src.read_bytes())
    return dst
