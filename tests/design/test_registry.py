"""The method registry: the README's method table and ``fdisyn methods NAME`` equal it, its schemas are enforced,
and one module that registers a method is all a new method needs."""

from __future__ import annotations

import re
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from fdisyn.app.cli import main
from fdisyn.app.examples import EXAMPLES
from fdisyn.simulation.plant_file import load_spec, problem_from_document
from fdisyn.codegen.step import step_function
from fdisyn.models.linear import LinearPlant
from fdisyn.models.nonlinear import NonlinearPlant
from fdisyn.runtime.errors import ArgumentError, GainFileError, SpecError
from fdisyn.synthesis import kinds, registry
from fdisyn.synthesis.registry import REQUIRED, Method

README = Path(__file__).parents[2] / "README.md"
DATA = EXAMPLES


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def method_rows() -> list[list[str]]:
    """The README's method table, as the registry has it."""
    return [[f"`{m.name}`", m.plant_kind, _cell(m.summary), _cell(m.reference)] for m in registry.all_methods()]


def _table(text: str, header: str) -> list[list[str]]:
    lines = text.splitlines()
    start = next(i for i, ln in enumerate(lines) if ln.startswith(f"| {header} |"))
    rows = []
    for ln in lines[start + 2 :]:
        if not ln.startswith("|"):
            break
        rows.append([c.strip() for c in re.split(r"(?<!\\)\|", ln.strip())[1:-1]])
    return rows


def test_the_readme_method_table_is_the_registry() -> None:
    text = README.read_text(encoding="utf-8")
    section = text[text.index("\n## Choosing a method and a detector\n") :]
    section = section[: section.index("\n## ", 5)]
    assert _table(section, "method") == method_rows()


@pytest.mark.parametrize("name", registry.method_names())
def test_the_option_table_of_each_method_is_the_registry(name, capsys) -> None:
    """``fdisyn methods NAME`` (the option tables the README used to hold) prints every option of the method with
    its default, its domain and its doc, in the registry's order."""
    assert main(["methods", name]) == 0
    out = " ".join(capsys.readouterr().out.split())  # the table wraps its cells
    m = registry.get_method(name)
    assert out.startswith(f"{name} ({m.plant_kind} plant): {' '.join(m.summary.split())}")
    assert f"reference: {' '.join(m.reference.split())}" in out
    at = 0
    for o in m.options:
        default = "required" if o.default is REQUIRED else repr(o.default)
        doc = o.doc + (f" (a plant file: {o.plant_file})" if o.plant_file else "")
        row = " ".join(f"{o.name} {default} {o.expected} {doc}".split())
        found = out.find(row, at)
        assert found > at, (name, o.name, row)
        at = found
def test_builtin_methods_register_themselves() -> None:
    names = registry.method_names()
    for name in ("kalman_uio", "kalman_uio_paper", "uio_pole_placement", "sampled_data_observer", "lmi", "nafdf"):
        assert name in names
    kinds = {m.name: m.plant_kind for m in registry.all_methods()}
    assert kinds["lmi"] == kinds["sampled_data_observer"] == "continuous" and kinds["nafdf"] == "nonlinear"
    # the bank options are defined once and shared
    shared = [registry.get_method(n).option("P_f") for n in ("kalman_uio", "lmi", "uio_pole_placement")]
    assert shared[0] is shared[1] is shared[2]
    # what the Monte Carlo needs of a diagnoser kind is the kind's, which each method names
    from fdisyn.synthesis.kinds import get_kind
    from fdisyn.synthesis.nafdf.design import nafdf_extra_metrics

    assert registry.get_method("nafdf").diagnoser_kind == "nafdf" and registry.get_method("lmi").diagnoser_kind == "linear"
    assert get_kind("nafdf").extra_metrics is nafdf_extra_metrics and get_kind("linear").extra_metrics is None


def test_unknown_method_and_option() -> None:
    with pytest.raises(ArgumentError, match=r"no design method 'magic'; methods: \[.*'kalman_uio'"):
        registry.get_method("magic")
    plant = _discrete()
    with pytest.raises(ArgumentError, match=r"unknown option\(s\) \['foo'\]; allowed: \['P_f'"):
        registry.design(plant, "kalman_uio", foo=1)
    with pytest.raises(ArgumentError, match="option eta is read only by method 'lmi', not by 'kalman_uio'"):
        registry.design(plant, "kalman_uio", eta="inf")
    with pytest.raises(GainFileError, match="no step builder for diagnoser kind 'magic'"):
        kinds.get_kind("magic")


@pytest.mark.parametrize(
    ("method", "options", "message"),
    [
        ("kalman_uio", {"P_f": 0}, r"method 'kalman_uio': option P_f = 0: expected a false-alarm probability"),
        ("kalman_uio", {"persistence": 1.5}, r"option persistence = 1.5: expected a whole number ≥ 1"),
        ("kalman_uio", {"bank": [["y9"]]}, r"option bank\[0\]\[0\]: no output 'y9'"),
        ("kalman_uio", {"faults": [{"name": "f", "sensors": []}]}, r"faults\[0\] names no sensor"),
        ("uio_pole_placement", {}, r"missing option 'poles'"),
        ("uio_pole_placement", {"poles": [0.5]}, r"option poles must have 2 poles"),
        ("kalman_uio", {"Ts": 0.1}, r"the plant is discrete"),
    ],
)
def test_schema_validation(method: str, options: dict, message: str) -> None:
    with pytest.raises(ArgumentError, match=message):
        registry.design(_discrete(), method, **options)


def test_option_validator() -> None:
    o = registry.SHARED_OPTIONS["P_f"]
    assert o.validate(0.5) == 0.5
    with pytest.raises(ArgumentError, match=r"^option P_f = 'x': expected"):
        o.validate("x")
    assert registry.check_option("persistence", 3, 1, "problem 'p'") == 3
    assert registry.check_option("gain", 2, 1.0, "problem 'p'") == 2.0 and isinstance(registry.check_option("gain", 2, 1.0, "x"), float)
    with pytest.raises(ArgumentError, match="problem 'p': option name = 3: expected a string"):
        registry.check_option("name", 3, "a", "problem 'p'")


C3 = [[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]


def _discrete() -> LinearPlant:
    return LinearPlant.create(A=[[0.5, 0.1], [0.0, 0.7]], C=C3, E=[[1.0], [0.0]], Q=np.eye(2) * 1e-3, R=np.eye(3) * 1e-2, Ts=0.1)


def _continuous() -> LinearPlant:
    return LinearPlant.create(A=[[-1.0, 5.0], [0.0, -2.0]], B=[[0.0], [1.0]], C=np.eye(2), E=[[0.1], [1.0]], R=np.zeros((2, 2)))


def _nonlinear() -> NonlinearPlant:
    return NonlinearPlant.from_expressions(
        states=["x"], inputs=["u"], outputs=["y"], parameters=["a"], nominal={"a": -0.5}, f={"x": "0.5*x + a*u"}, h={"y": "x"},
        Q=[[0.0]], R=[[0.01]],
    )


def test_each_method_checks_the_plant_kind() -> None:
    plants = {"discrete": _discrete(), "continuous": _continuous(), "nonlinear": _nonlinear()}
    accepts = {"linear": {"discrete", "continuous"}, "continuous": {"continuous"}, "nonlinear": {"nonlinear"}}
    for m in registry.all_methods():
        for label, plant in plants.items():
            if label in accepts[m.plant_kind]:
                registry.check_plant(m, plant)
            else:
                with pytest.raises(ArgumentError, match=f"method '{m.name}' designs for"):
                    registry.check_plant(m, plant)


def test_design_through_the_registry_is_certified() -> None:
    gf = registry.design(_discrete(), "kalman_uio", P_f=1e-4)
    assert gf.kind == "linear" and gf.name == "kalman_uio" and gf.certificate["passed"]
    assert gf.provenance["options"] == {"method": "kalman_uio", "P_f": 1e-4}
    assert kinds.recovery_samples(gf) >= 1
    assert step_function(gf).name_out()[-1] == "status"
    # a continuous plant: ZOH-sampled at Ts for a linear method, sampled-data design for a continuous one
    uio = LinearPlant.create(A=[[-1.0, 5.0], [0.0, -2.0]], C=C3, E=[[1.0], [0.0]], Q=np.eye(2) * 1e-3, R=np.eye(3) * 1e-2)
    assert registry.design(uio, "kalman_uio", Ts=0.5).Ts == 0.5
    assert registry.design(_continuous(), "sampled_data_observer", Ts=1.0).design == "sampled_data_observer"


def test_a_method_in_one_module_is_picked_up(tmp_path, monkeypatch, capsys) -> None:
    """A new method is one module of a package the registry scans: the plant file, the CLI and the step assembly see it."""
    pkg = tmp_path / "extra_methods"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "scaled_kalman.py").write_text(
        textwrap.dedent(
            '''
            """A Kalman UIO bank under another name (a method in one module)."""
            from fdisyn.synthesis.linear_diagnoser import linear_method
            from fdisyn.synthesis.registry import Option
            from fdisyn.synthesis.uio import kalman_uio


            def generator(plant, outputs_used, name, *, note):
                d = kalman_uio(plant.select_outputs(outputs_used))
                return d.generator(name, outputs_used, plant.p), d.Sigma_r, d.certificate


            linear_method(
                "extra_uio",
                summary="a UIO bank registered from a module of its own",
                reference="Hu, Sun, Jiang, He & Zhang 2013, Acta Automatica Sinica 39(8), eq. (20)",
                generator=generator,
                options=(Option("note", "x", "a string carried along", "a string", lambda v: isinstance(v, str)),),
            )
            '''
        )
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(kinds, "PLUGIN_PACKAGES", [*kinds.PLUGIN_PACKAGES, "extra_methods"])
    monkeypatch.setattr(registry, "_METHODS", dict(registry._METHODS))
    try:
        assert "extra_uio" in registry.method_names()
        text = (DATA / "dc_motor.toml").read_text(encoding="utf-8").replace('method = "kalman_uio" ', 'method = "extra_uio"\nnote = "y" ')
        spec = tmp_path / "motor.toml"
        spec.write_text(text, encoding="utf-8")
        prob = load_spec(spec)
        assert prob.default_design == "extra_uio"
        gf = prob.design()
        assert gf.design == "extra_uio" and gf.provenance["options"]["note"] == "y"
        assert step_function(gf).n_out() == 6
        assert main(["methods"]) == 0
        assert "extra_uio (linear plant): a UIO bank registered from a module of its own" in capsys.readouterr().out
        with pytest.raises(SpecError, match=r"\[design\].note = 3: expected a string"):
            load_spec(_write(tmp_path, text.replace('note = "y"', "note = 3")))
    finally:
        kinds._SCANNED.discard("extra_methods")
        sys.modules.pop("extra_methods.scaled_kalman", None)
        sys.modules.pop("extra_methods", None)


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "other.toml"
    p.write_text(text, encoding="utf-8")
    return p


def test_register_refuses_a_bad_method() -> None:
    m = registry.get_method("kalman_uio")
    with pytest.raises(ArgumentError, match="plant_kind 'analog'"):
        Method("x", "analog", "", "", (), m.design, "linear")
    with pytest.raises(ArgumentError, match="names an option twice"):
        Method("x", "linear", "", "", (m.options[0], m.options[0]), m.design, "linear")
    with pytest.raises(ArgumentError, match="names diagnoser kind 'magic', which no module registers"):
        registry.register(Method("other_linear", "linear", "", "", (), m.design, "magic"))
    assert "other_linear" not in registry.method_names()


def test_plant_file_design_keys_come_from_the_schema(tmp_path) -> None:
    doc = {"name": "p", "model": {"time": "discrete", "Ts": 0.1, "A": [[0.5]], "C": [[1.0]], "E": [[1.0]]}, "design": {"sigma": 0.1}}
    with pytest.raises(SpecError, match=r"\[design\].sigma is read only by method 'beard_fdf', not by 'kalman_uio'"):
        problem_from_document(doc, tmp_path / "p.toml")
    doc["design"] = {"window": 3}  # the linear bank's WSSR window: with its evaluator only
    with pytest.raises(SpecError, match=r"\[design\].window = 3 needs detector = 'wssr' or 'glr'"):
        problem_from_document(doc, tmp_path / "p.toml")
    doc["design"] = {"method": "lmi"}
    with pytest.raises(SpecError, match="designs for a continuous plant sampled at Ts"):
        problem_from_document(doc, tmp_path / "p.toml")
