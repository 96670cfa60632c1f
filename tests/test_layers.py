"""The house holds ARCHITECTURE.md's layers: the folder table there, read as data, is asserted on the code.

The table lists the layers lowest first, and for each the layers it imports. Every ``import`` of an fdisyn module
(at module level or inside a function) is read from the
source with :mod:`ast`, so an import that only runs on some path counts too. Then:

- a layer imports only itself and layers below it (no upward import);
- the layers each layer imports are exactly those the table names (the map stays true);
- the modules' import graph has no circle (strongly connected components of one module each).

Importing the root package itself (``from fdisyn import __version__``) is not counted either: every import of an
fdisyn module loads it first. The registries' discovery by name at run time (methods and kinds from ``fdisyn.synthesis``, problems by their
name from ``fdisyn.problems``) is no static import and is not counted: it is how a layer finds plug-ins, and
ARCHITECTURE.md says so.
"""

from __future__ import annotations

import ast
import re
from collections import defaultdict
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SOURCES = {"design": "fdisyn", "runtime": "fdisyn.runtime", "problems": "fdisyn.problems"}


def _table() -> list[tuple[str, set[str]]]:
    """ARCHITECTURE.md's folder table: ``(import name, layers it imports)``, lowest layer first."""
    text = (ROOT / "ARCHITECTURE.md").read_text(encoding="utf-8")
    section = text[text.index("## The folders") :]
    section = section[: section.index("\n## ", 1)]
    rows = []
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 4 or not cells[1].startswith("`fdisyn"):
            continue
        name = cells[1].strip("`")
        imports = set() if cells[3] in ("—", "") else {w.strip() for w in cells[3].split(",")}
        rows.append((name, imports))
    assert rows, "ARCHITECTURE.md lost its folder table"
    return rows


def _module(path: Path) -> str:
    rel = path.relative_to(ROOT)
    parts = list(rel.with_suffix("").parts)
    parts = SOURCES[parts[0]].split(".") + parts[1:]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


EXAMPLES = ROOT / "design" / "examples"
"""The example plant files and workflow scripts: data shipped with the package, not modules of it (a workflow
script imports the package root alone, as a user's script does; tests/design/test_workflows.py runs them)."""


def _modules() -> dict[str, Path]:
    return {_module(p): p for top in SOURCES for p in sorted((ROOT / top).rglob("*.py")) if EXAMPLES not in p.parents}


def _imports(name: str, path: Path, known: set[str]) -> set[str]:
    """The fdisyn modules ``name`` imports, resolved to the deepest known module."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    targets: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[: len(anchor) - (node.level - 1)]
                base = ".".join(anchor + ([base] if base else []))
            targets.update(f"{base}.{a.name}" for a in node.names)
            targets.add(base)
        elif isinstance(node, ast.Import):
            targets.update(a.name for a in node.names)
    out = set()
    for t in targets:
        while t and t not in known:
            t = t.rpartition(".")[0]
        if t and t != name and t != "fdisyn":  # importing any fdisyn module loads the root package first anyway
            out.add(t)
    return out


def _layer(module: str, layers: list[str]) -> str:
    """The deepest layer whose import name is ``module`` or a package above it."""
    return max((l for l in layers if module == l or module.startswith(l + ".")), key=len)


@pytest.fixture(scope="module")
def graph() -> dict[str, set[str]]:
    mods = _modules()
    return {m: _imports(m, p, set(mods)) for m, p in mods.items()}


def test_every_module_belongs_to_a_layer_of_the_table(graph: dict[str, set[str]]) -> None:
    layers = [n for n, _ in _table()]
    # a subpackage without a row of its own (e.g. fdisyn.synthesis.nafdf) is in its parent's layer;
    # a module directly under fdisyn is in the root's layer only if it is the root itself
    stray = [m for m in graph if _layer(m, layers) == "fdisyn" and m != "fdisyn"]
    assert not stray, f"modules outside every layer of ARCHITECTURE.md's folder table: {stray}"


def test_no_upward_import_and_the_table_is_exact(graph: dict[str, set[str]]) -> None:
    table = _table()
    layers = [n for n, _ in table]
    rank = {n: i for i, n in enumerate(layers)}
    short = {n: (n.rpartition(".")[2] if n != "fdisyn" else "fdisyn") for n in layers}
    by_short = {v: k for k, v in short.items()}
    declared = {n: {by_short.get(w, w) for w in imports} for n, imports in table}
    unknown = {n: sorted(d - set(layers)) for n, d in declared.items() if d - set(layers)}
    assert not unknown, f"ARCHITECTURE.md's table names layers it does not list: {unknown}"
    upward_declared = {n: sorted(short[d] for d in ds if rank[d] >= rank[n]) for n, ds in declared.items()}
    assert not any(upward_declared.values()), f"the table itself declares an upward import: {upward_declared}"

    actual: dict[str, set[str]] = defaultdict(set)
    upward = []
    for m, targets in graph.items():
        lm = _layer(m, layers)
        for t in targets:
            lt = _layer(t, layers)
            if lt == lm:
                continue
            actual[lm].add(lt)
            if rank[lt] > rank[lm]:
                upward.append(f"{m} → {t}")
    assert not upward, "upward imports (a lower layer importing a higher one): " + "; ".join(sorted(upward))
    differ = {
        short[n]: {"table": sorted(short[d] for d in declared[n]), "code": sorted(short[d] for d in actual[n])}
        for n in layers
        if declared[n] != actual[n]
    }
    assert not differ, f"ARCHITECTURE.md's 'imports from fdisyn' column differs from the code: {differ}"


def test_no_import_circle(graph: dict[str, set[str]]) -> None:
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    circles: list[list[str]] = []

    def visit(v: str) -> None:  # Tarjan's strongly connected components
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                circles.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    assert not circles, f"import circles: {circles}"


def test_the_checker_sees_what_it_must(tmp_path: Path) -> None:
    """The reader counts imports inside functions and relative imports, and resolves a name to its module."""
    known = {"fdisyn", "fdisyn.a", "fdisyn.a.b", "fdisyn.c"}
    src = "def f():\n    from fdisyn.a.b import thing\n    from ..c import other\nimport fdisyn.a\n"
    p = tmp_path / "x.py"
    p.write_text(src, encoding="utf-8")
    got = _imports("fdisyn.a.x", p, known)
    assert got == {"fdisyn.a.b", "fdisyn.c", "fdisyn.a"}


def test_the_table_order_is_the_documented_pipeline() -> None:
    """The layers run lowest first as ARCHITECTURE.md's pipeline reads them."""
    layers = [n for n, _ in _table()]
    text = (ROOT / "ARCHITECTURE.md").read_text(encoding="utf-8")
    order = re.search(r"Layers, lowest first: (.+?)\.\n", text)
    assert order is not None, "ARCHITECTURE.md lost its one-line layer order"
    assert [w.strip(" `") for w in order.group(1).split("<")] == layers
