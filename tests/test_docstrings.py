"""The public API's docstrings are numpydoc and say what every parameter is.

In the style of python-control's ``control/tests/docstrings_test.py``: walk the public names (the
``__all__`` of the modules below), and for every public function, class and public method fail naming it
when it has no docstring, when a parameter (other than ``self``, ``cls``, ``*args`` and ``**kwargs``) is
missing from its ``Parameters`` section, or when that section documents a parameter that does not exist.
A dataclass documents its fields in an ``Attributes`` section (or ``Parameters``). numpydoc is not a
dependency of fdisyn, so the sections are read with a small parser (:func:`sections`).
"""

from __future__ import annotations

import dataclasses
import doctest
import importlib
import inspect
import re
from collections.abc import Iterator

import pytest

# (module, names): the module's ``__all__`` when names is None
PUBLIC = [
    ("fdisyn", None),
    ("fdisyn.app.api", None),
    ("fdisyn.runtime.gainfile", None),
    ("fdisyn.runtime.monitor", None),
    ("fdisyn.runtime.compiled", ["CompiledDiagnoser"]),
    ("fdisyn.runtime.trace", None),
    ("fdisyn.runtime.errors", None),  # every exception type
    ("fdisyn.evaluation.metrics", None),
    ("fdisyn.numerics.certificate", ["Check", "Certificate"]),
    ("fdisyn.simulation.problem", ["Problem", "Scenario", "Batch"]),
]

SECTION = re.compile(r"^(\w[\w ]*)\n-{3,}[ \t]*$", re.M)


def sections(doc: str) -> dict[str, str]:
    """The numpydoc sections of a docstring (``inspect.getdoc``'s text): title → body."""
    heads = list(SECTION.finditer(doc))
    return {h.group(1): doc[h.end() : heads[i + 1].start() if i + 1 < len(heads) else len(doc)] for i, h in enumerate(heads)}


def documented(body: str) -> list[str]:
    """The names a ``Parameters`` or ``Attributes`` section documents: its unindented ``name : type`` lines."""
    names = []
    for line in body.splitlines():
        if line and not line[0].isspace():
            for n in line.split(":")[0].split(","):
                names.append(n.strip().lstrip("*"))
    return [n for n in names if n]


def _docstring(obj: object) -> str | None:
    doc = obj.__doc__
    if inspect.isclass(obj) and dataclasses.is_dataclass(obj) and doc and doc.startswith(obj.__name__ + "("):
        return None  # the signature dataclasses write when a class has no docstring
    return inspect.getdoc(obj) if doc else None


def _names(module: str, names: list[str] | None) -> Iterator[tuple[str, object]]:
    mod = importlib.import_module(module)
    for name in names if names is not None else (mod.__all__ if hasattr(mod, "__all__") else vars(mod)):
        obj = getattr(mod, name)
        if module == "fdisyn.runtime.errors" and not (inspect.isclass(obj) and issubclass(obj, Exception)):
            continue
        if inspect.isfunction(obj) or inspect.isclass(obj):
            yield f"{obj.__module__}.{obj.__qualname__}", obj


def public_objects() -> dict[str, tuple[object, str]]:
    """Every public function, class and public method or property of the classes: qualified name → (object, what)."""
    out: dict[str, tuple[object, str]] = {}
    for module, names in PUBLIC:
        for qual, obj in _names(module, names):
            out[qual] = (obj, "class" if inspect.isclass(obj) else "function")
            if inspect.isclass(obj) and not issubclass(obj, BaseException):
                for k, v in vars(obj).items():
                    if k.startswith("_"):
                        continue
                    if isinstance(v, property) and v.fget is not None:
                        out[f"{qual}.{k}"] = (v.fget, "property")
                    elif isinstance(v, (classmethod, staticmethod)):
                        out[f"{qual}.{k}"] = (v.__func__, "function")
                    elif inspect.isfunction(v):
                        out[f"{qual}.{k}"] = (v, "function")
    return out


def _parameters(obj: object) -> tuple[list[str], bool]:
    """The parameters a docstring must document, and whether the callable takes ``**kwargs``."""
    try:
        sig = inspect.signature(obj)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return [], False
    params, var_kw = [], False
    for i, (n, p) in enumerate(sig.parameters.items()):
        if p.kind is p.VAR_KEYWORD:
            var_kw = True
        elif p.kind is p.VAR_POSITIONAL or (i == 0 and n in ("self", "cls")) or n.startswith("_"):
            continue
        else:
            params.append(n)
    return params, var_kw


def problems(qual: str, obj: object, what: str = "function") -> list[str]:
    """What is wrong with the docstring of ``obj`` (empty when nothing is); ``what``: function, class or property."""
    doc = _docstring(obj)
    if doc is None:
        return [f"{qual} has no docstring"]
    if what == "property" or (inspect.isclass(obj) and issubclass(obj, BaseException)):
        return []  # a property is documented by its docstring; an exception type takes its message only
    secs = sections(doc)
    params, var_kw = _parameters(obj)
    listed = documented(secs.get("Parameters", ""))
    fields = [f.name for f in dataclasses.fields(obj)] if inspect.isclass(obj) and dataclasses.is_dataclass(obj) else []
    if inspect.isclass(obj):
        listed += documented(secs.get("Attributes", ""))
        init = vars(obj).get("__init__")
        if inspect.isfunction(init) and init.__doc__:  # numpydoc: the constructor's parameters in either docstring
            listed += documented(sections(inspect.getdoc(init) or "").get("Parameters", ""))
    out = [f"{qual}: parameter {p!r} is not documented in its Parameters section" for p in params if p not in listed and p not in fields]
    out += [f"{qual}: field {f!r} is not documented in its Attributes section" for f in fields if f not in listed]
    if not var_kw and not inspect.isclass(obj):
        out += [f"{qual}: documents parameter {p!r}, which it does not take" for p in listed if p not in params]
    return out


OBJECTS = public_objects()


def test_the_public_api_list_is_not_empty() -> None:
    """The walk finds the names the README documents (a renamed module would otherwise pass vacuously)."""
    for qual in (
        "fdisyn.app.api.design",
        "fdisyn.app.api.load",
        "fdisyn.runtime.monitor.Monitor",
        "fdisyn.runtime.compiled.CompiledDiagnoser",
        "fdisyn.runtime.gainfile.GainFile.to_dict",
        "fdisyn.runtime.gainfile.read_gain_file",
        "fdisyn.runtime.trace.replay_csv",
        "fdisyn.runtime.errors.GainFileError",
        "fdisyn.evaluation.metrics.ScenarioMetrics",
        "fdisyn.models.linear.LinearPlant",
    ):
        assert qual in OBJECTS, qual


@pytest.mark.parametrize("qual", sorted(OBJECTS))
def test_public_docstring(qual: str) -> None:
    assert problems(qual, *OBJECTS[qual]) == []


def test_the_examples_run() -> None:
    """Every ``Examples`` section of the public API runs as written (those marked ``+SKIP`` need a built diagnoser)."""
    import numpy as np

    import fdisyn

    finder, runner = doctest.DocTestFinder(recurse=False), doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    ran = 0
    for qual, (obj, _) in sorted(OBJECTS.items()):
        module = importlib.import_module(obj.__module__)
        for test in finder.find(obj, qual, module=module, globs={**vars(module), "np": np, "fdisyn": fdisyn}):
            ran += len(test.examples)
            runner.run(test)
    assert runner.failures == 0, f"{runner.failures} example(s) failed (the output above shows which)"
    assert ran > 0


def test_the_checker_names_an_undocumented_and_an_unknown_parameter() -> None:
    def f(a: int, b: int, *args: int, **kwargs: int) -> None:
        """Summary.

        Parameters
        ----------
        a : int
            The first.
        """

    def g(a: int) -> None:
        """Summary.

        Parameters
        ----------
        a, c : int
            Two names, one of them wrong.
        """

    def h(a: int) -> None:
        pass

    assert problems("f", f) == ["f: parameter 'b' is not documented in its Parameters section"]
    assert problems("g", g) == ["g: documents parameter 'c', which it does not take"]
    assert problems("h", h) == ["h has no docstring"]

    @dataclasses.dataclass
    class D:
        x: int
        y: int = 0

    assert problems("D", D, "class") == ["D has no docstring"]
    D.__doc__ = "A pair.\n\nAttributes\n----------\nx : int\n    The first.\n"
    assert problems("D", D, "class") == ["D: field 'y' is not documented in its Attributes section"]
