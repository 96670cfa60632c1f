"""The public Python API: ``fdisyn.design``, ``export``, ``load``, ``methods``, ``problem``, ``simulate``,
``evaluate``, ``fault_size_sweep``, ``report``.

::

    plant = fdisyn.LinearPlant.from_control(sys, n_unknown=1, Q=Q, R=R)
    gf = fdisyn.design(plant, method="kalman_uio", P_f=1e-4)   # a certified GainFile
    fdisyn.export(gf, "motor")                                  # what `fdisyn codegen` builds
    mon = fdisyn.load("motor")                                  # a Monitor over the compiled step
    fdisyn.methods()                                            # the registered method names
    prob = fdisyn.problem(plant, name="motor", designs={...}, simulation={...}, scenarios=[...])
    fdisyn.simulate(prob, "fault_free", seed=1)                 # a Trace
    fdisyn.evaluate(prob, runs=100)                             # the compiled Monte Carlo's metrics
    fdisyn.report(prob)                                         # reports/motor/index.html

Each function is what a command of the command line does, from Python:
``design`` is ``fdisyn design`` on a plant object (through the method
registry, :mod:`fdisyn.synthesis.registry`), ``export`` writes ``gains.json``
and runs ``fdisyn codegen`` on it, ``load`` is
:meth:`fdisyn.runtime.monitor.Monitor.from_directory`; ``problem`` is a plant
file made of Python objects (the same reader validates it), and ``simulate``,
``evaluate`` and ``report`` are ``fdisyn simulate``, ``evaluate`` and
``report`` on it. The design side is imported when a function other than
``load`` is first called, so ``load`` needs only the runtime.
"""

from __future__ import annotations

import os
from pathlib import Path
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, Literal

from fdisyn.runtime.errors import ArgumentError, FileError
from fdisyn.runtime.gainfile import GainFile, write_gain_file
from fdisyn.runtime.monitor import Monitor

if TYPE_CHECKING:
    from fdisyn.app.pipeline import FaultSizeSweep
    from fdisyn.evaluation.evaluate import Evaluation
    from fdisyn.runtime.trace import Trace
    from fdisyn.simulation.problem import Problem

__all__ = ["design", "export", "load", "methods", "problem", "simulate", "evaluate", "fault_size_sweep", "report"]


def design(plant: Any, method: str, *, name: str | None = None, **options: Any) -> GainFile:
    """Design a diagnoser for ``plant`` with a registered ``method``; a certified :class:`GainFile`.

    Parameters
    ----------
    plant : LinearPlant, SampledDataPlant or NonlinearPlant
        The plant to diagnose (the method says which kinds of plant it takes).
    method : str
        A registered design method (:func:`methods`; ``fdisyn methods NAME`` describes one).
    name : str, optional
        The diagnoser's name, the prefix of its C API (a C identifier); default: the method's.
    **options
        The method's options (``fdisyn methods NAME`` lists them, with their defaults), e.g. ``P_f``.

    Returns
    -------
    GainFile
        The diagnoser, its certificate passed.

    Raises
    ------
    ArgumentError
        An unknown method or option, or a value outside its domain.
    ExistenceError
        A plant the method cannot design for (the message names the condition that fails).
    CertificateError
        A design that fails its verification.

    Examples
    --------
    >>> gf = fdisyn.design(plant, method="kalman_uio", P_f=1e-4)  # doctest: +SKIP
    >>> gf.faults  # doctest: +SKIP
    ('y0', 'y1', 'y2')
    """
    from fdisyn.synthesis.registry import design as registry_design

    return registry_design(plant, method, name=name, **options)


def methods() -> list[str]:
    """The names of the registered design methods.

    Returns
    -------
    list of str
        The names :func:`design` takes as ``method``.
    """
    from fdisyn.synthesis.registry import method_names

    return list(method_names())


def export(gf: GainFile, directory: str | Path, *, precision: Literal["double", "single"] = "double") -> Path:
    """Write ``gf`` to ``directory`` as ``fdisyn codegen`` builds it; return the directory.

    ``DIR/gains.json``, the C sources in ``DIR/c/``, the shared library
    ``DIR/lib<name>.so`` with its build manifest and the replay program
    ``DIR/replay``. The generated step is checked against the gain file before
    it is written (see :mod:`fdisyn.codegen.library`).

    Parameters
    ----------
    gf : GainFile
        The diagnoser (from :func:`design` or ``read_gain_file``).
    directory : str or Path
        The folder to build in: an existing folder, or one that can be created.
    precision : {"double", "single"}
        The step's arithmetic: ``"single"`` computes in ``float`` for a target without a double-precision FPU,
        behind the same C API (``fdisyn codegen --precision single``; its agreement with the double build is
        stated in the runtime reference).

    Returns
    -------
    Path
        ``directory``.

    Raises
    ------
    ArgumentError
        ``gf`` is not a gain file, ``directory`` is not a path, or ``precision`` is neither of the two.
    FileError
        ``directory`` cannot be written: an existing file, a place that cannot hold a folder (``/proc``), a
        folder without write permission, or ``gains.json`` in it a folder (the message names the path).
    BuildError
        The C compiler failed.
    """
    from fdisyn.codegen.library import codegen

    if not isinstance(gf, GainFile):
        raise ArgumentError(f"gf must be a GainFile (from fdisyn.design or read_gain_file); got {type(gf).__name__}")
    if not isinstance(directory, (str, Path)):
        raise ArgumentError(f"directory must be a path (str or pathlib.Path); got {type(directory).__name__}")
    d = Path(directory)
    _writable_folder(d)
    try:
        write_gain_file(gf, d / "gains.json")
    except OSError as exc:
        raise FileError(f"cannot write {d / 'gains.json'}: {exc.strerror or exc}; expected a folder fdisyn can write in") from exc
    codegen(d, precision=precision)
    return d


def _writable_folder(d: Path) -> None:
    """Refuse an export folder that cannot be written, naming the path, what is wrong and what to give instead."""
    remedy = "give fdisyn.export a folder you can write in (it is created if missing)"
    if d.exists() and not d.is_dir():
        raise FileError(f"export folder {d} is a file; {remedy}")
    try:
        d.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise FileError(f"cannot create the export folder {d}: {exc.strerror or exc}; {remedy}") from exc
    if (d / "gains.json").is_dir():
        raise FileError(f"{d / 'gains.json'} is a folder, where the diagnoser's gain file goes; remove it or {remedy}")
    if not os.access(d, os.W_OK | os.X_OK):
        raise FileError(f"export folder {d} is not writable; {remedy}")


def load(directory: str | Path, *, backend: Literal["compiled", "reference", "auto"] = "compiled") -> Monitor:
    """The :class:`Monitor` of the diagnoser that :func:`export` (or ``fdisyn codegen``) built in ``directory``.

    It runs the compiled library (``backend="compiled"``), loaded only if it
    was built from that very ``gains.json``; ``"reference"`` runs the NumPy
    reference of a linear gain file instead, ``"auto"`` the library when there
    is one. ``mon.update(u, y)`` returns a :class:`~fdisyn.runtime.monitor.Verdict`
    (``.alarm``, ``.fault``, ``.isolated``, ``.J``, ``.r``, ``.time``).

    Parameters
    ----------
    directory : str or Path
        A folder written by :func:`export` or ``fdisyn codegen``.
    backend : {"compiled", "reference", "auto"}
        What runs the step: the C library, the NumPy reference, or the library when there is one.

    Returns
    -------
    Monitor
        The diagnoser at its initial state.

    Raises
    ------
    ArgumentError
        ``backend`` is none of the three.
    GainFileError
        ``DIR/gains.json`` is missing or not a valid gain file.
    BuildError
        The library is missing (``"compiled"``) or was not built from that ``gains.json``.

    Examples
    --------
    >>> mon = fdisyn.load("motor")  # doctest: +SKIP
    >>> mon.update([0.0], [0.0, 0.0]).alarm  # doctest: +SKIP
    False
    """
    if backend not in ("compiled", "reference", "auto"):
        raise ArgumentError(f"backend must be 'compiled', 'reference' or 'auto'; got {backend!r}")
    return Monitor.from_directory(directory, backend=backend)


def _plain(value: Any) -> Any:
    """A section value as a plant file holds it: an input signal object (``Signal``) as its table, recursively."""
    from dataclasses import fields, is_dataclass

    if is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(getattr(value, f.name)) for f in fields(value)}
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def problem(
    plant: Any,
    *,
    name: str = "plant",
    designs: Mapping[str, Any] | None = None,
    simulation: Mapping[str, Any] | None = None,
    scenarios: Sequence[Mapping[str, Any]] = (),
    title: str | None = None,
    Ts: float | None = None,
) -> Problem:
    """A problem built from Python objects: a plant, its designs side by side, its simulation and scenarios.

    It is the problem the plant file ``plant.to_toml(name, Ts=Ts, designs=designs, simulation=simulation,
    scenarios=scenarios)`` describes, read by the same reader (``design/examples/PLANT_FILES.md``): every key is
    validated the same way, and :func:`evaluate`, :func:`report` and :func:`simulate` take it.

    Parameters
    ----------
    plant : LinearPlant or NonlinearPlant
        The plant (a nonlinear one built from expressions).
    name : str
        The problem's name: it prefixes each diagnoser's name and C API (``<name>_<design>``).
    designs : Mapping of str to Mapping, optional
        The designs by name, each its ``method`` and options, e.g. ``{"kalman": {"method": "kalman_uio"},
        "pp": {"method": "uio_pole_placement", "poles": [0.5, 0.6]}}``; default: one ``kalman_uio`` design (the
        NAFDF for a nonlinear plant).
    simulation : Mapping, optional
        ``[simulation]``: ``duration`` (s), ``x0``, ``inputs`` and ``unknown_inputs`` (signal tables such as
        ``{"kind": "sine", "amplitude": 1.0, "period": 10.0}``, or ``Signal`` objects), one per input.
    scenarios : sequence of Mapping
        The faulty scenarios as ``[[scenarios]]`` tables (``name``, ``duration``, ``fault``, ``onset``,
        ``sensor_faults``, ``component_faults`` or, for a nonlinear plant, ``parameter_faults``); a fault-free
        one, ``fault_free``, is always added.
    title : str, optional
        The report's title (default: ``name``).
    Ts : float, optional
        The diagnoser's sample time, required for a continuous linear plant.

    Returns
    -------
    Problem
        The problem: ``problem.design(NAME)``, ``problem.run(SCENARIO, seeds)``.

    Raises
    ------
    SpecError
        A value the plant file would refuse (the message names the key).
    ArgumentError
        A plant that cannot be written as a plant file, or a continuous plant without ``Ts``.

    Examples
    --------
    >>> prob = fdisyn.problem(plant, name="motor", designs={"kalman": {"method": "kalman_uio"}},
    ...                       simulation={"duration": 10.0}, scenarios=[...])  # doctest: +SKIP
    """
    import tomllib

    from fdisyn.simulation.plant_file import problem_from_document

    to_toml = getattr(plant, "to_toml", None)
    if to_toml is None:
        raise ArgumentError(f"plant must be a LinearPlant or a NonlinearPlant; got {type(plant).__name__}")
    sections: dict[str, Any] = {"title": title, "simulation": _plain(simulation) if simulation is not None else None,
                                "scenarios": _plain(list(scenarios)), "designs": _plain(designs) if designs is not None else None}  # fmt: skip
    if Ts is not None:
        sections["Ts"] = Ts
    text = to_toml(name, **sections)
    return problem_from_document(tomllib.loads(text), Path(f"{name}.toml"), origin="built in Python (fdisyn.problem)")


def _as_problem(spec: Any) -> Problem:
    """A :class:`Problem` as given, a built-in problem's name, a plant file's path, or a plant (with the default design)."""
    from fdisyn.simulation.plant_file import load_spec
    from fdisyn.simulation.problem import Problem

    if isinstance(spec, Problem):
        return spec
    if isinstance(spec, (str, Path)):
        return load_spec(spec)
    if hasattr(spec, "to_toml"):
        return problem(spec)
    raise ArgumentError(f"expected a Problem (fdisyn.problem), a plant file, a built-in problem's name or a plant; got {type(spec).__name__}")


def simulate(spec: Any, scenario: str | Mapping[str, Any] = "fault_free", *, seed: int = 0, **options: Any) -> Trace:
    """One simulated run of a scenario as a trace: time, inputs, outputs, and where the fault acts.

    Parameters
    ----------
    spec : Problem, LinearPlant, NonlinearPlant, str or Path
        A problem (:func:`problem`), a plant (its simulation at rest, inputs at zero, with noise: build a
        :func:`problem` to give inputs and faults), a plant file or a built-in problem's name.
    scenario : str or Mapping
        A scenario of the problem by name (default ``"fault_free"``), or, with a plant, one ``[[scenarios]]``
        table.
    seed : int
        The run's seed, a whole number ≥ 0: the same seed gives the same run.
    **options
        The problem's options (``--option``).

    Returns
    -------
    Trace
        ``.t``, ``.U``, ``.Y``, ``.inputs``, ``.outputs``, ``.active`` (the samples where the fault acts); what
        ``Monitor.run(trace.U, trace.Y)`` and the plots take, and what ``write_trace`` writes as CSV.

    Raises
    ------
    ArgumentError
        An unknown scenario, a bad seed or option.
    """
    if isinstance(scenario, Mapping):
        if not hasattr(spec, "to_toml"):
            raise ArgumentError("a scenario given as a table needs a plant as spec; a problem's scenarios are given by name")
        prob = problem(spec, scenarios=[scenario])
        scenario = str(scenario.get("name"))
    else:
        prob = _as_problem(spec)
    return prob.run(scenario, [seed], **options).trace(0)


def evaluate(spec: Any, designs: Sequence[str] | None = None, *, runs: int = 100, seed: int = 0,
             workdir: str | Path | None = None, **options: Any) -> Evaluation:  # fmt: skip
    """The compiled Monte Carlo of a problem's designs: the metrics ``fdisyn evaluate`` writes.

    Each design is designed, exported, compiled and checked, then every scenario is run ``runs`` times through
    the generated C (fused with the plant's simulation where the problem has a sample model).

    Parameters
    ----------
    spec : Problem, LinearPlant, NonlinearPlant, str or Path
        A problem (:func:`problem`; a plant gets its default design and a fault-free scenario), a plant file or a
        built-in problem's name.
    designs : sequence of str, optional
        The designs to run (default: every design of the problem).
    runs : int
        Runs per scenario, ≥ 1.
    seed : int
        The first seed (run ``i`` of scenario ``s`` is seeded by ``[seed, s, i]``).
    workdir : str or Path, optional
        Where the designs are built (default ``.fdisyn/``, as the command line).
    **options
        The problem's options.

    Returns
    -------
    Evaluation
        ``.metrics[design][scenario]`` (false alarms, detection, delays, isolation), ``.to_dict()`` the JSON.

    Raises
    ------
    ArgumentError
        An unknown design or option, or ``runs`` not a whole number ≥ 1.
    """
    from fdisyn.evaluation.evaluate import evaluate as run_campaign

    prob, built, source = _built(spec, designs, workdir, options)
    return run_campaign(prob, built, runs=runs, seed0=seed, source=source, workers=None if source else 1, **options)


def _built(spec: Any, designs: Sequence[str] | None, workdir: str | Path | None, options: Mapping[str, Any]) -> tuple[Problem, dict[str, Any], str | None]:
    """The problem, its ``designs`` designed, exported and compiled under ``workdir``, and the source its Monte
    Carlo workers rebuild it from: a plant file or a built-in problem runs on every core, a problem made in this
    process runs here (``None``)."""
    from fdisyn.app import WORKDIR
    from fdisyn.evaluation.built import build
    from fdisyn.reporting.page import variant_tag

    prob = _as_problem(spec)
    names = list(prob.designs) if designs is None else list(designs)
    if isinstance(designs, str) or not names:
        raise ArgumentError(f"designs must be a list of the problem's design names {sorted(prob.designs)}; got {designs!r}")
    for d in names:
        if d not in prob.designs:
            raise ArgumentError(f"problem {prob.name!r} has no design {d!r}; designs: {sorted(prob.designs)}")
    prob.check_options(options)  # a bad option is refused before anything is designed or compiled
    # the folders the report builds in (its main variant's): a report after an evaluation compiles nothing again
    root = Path(WORKDIR if workdir is None else workdir) / prob.name / variant_tag("default")
    built = {d: build(prob, d, root / d, **options) for d in names}
    return prob, built, str(spec) if isinstance(spec, (str, Path)) else None


def fault_size_sweep(spec: Any, designs: Sequence[str] | None = None, *, runs: int = 20, workdir: str | Path | None = None,
                     **options: Any) -> FaultSizeSweep | None:  # fmt: skip
    """Detection against the fault's size: every faulty scenario run again with its fault scaled, as on the page.

    Each scenario's fault is scaled by the page's factors (``Problem.scaled``; by default the sensor faults'
    values, the component faults' steps or the parameter jumps) and run ``runs`` times per size through the
    compiled step.

    Parameters
    ----------
    spec : Problem, LinearPlant, NonlinearPlant, str or Path
        A problem (:func:`problem`), a plant file or a built-in problem's name.
    designs : sequence of str, optional
        The designs (default: every design of the problem).
    runs : int
        Runs per scenario and size, ≥ 1.
    workdir : str or Path, optional
        Where the designs are built (default ``.fdisyn/``).
    **options
        The problem's options.

    Returns
    -------
    FaultSizeSweep or None
        ``.scenarios[base][factor]`` names the scaled copy of ``base`` in ``.evaluation``: what
        :func:`fdisyn.plot_detection` draws. ``None`` when no scenario's fault has a size.

    Raises
    ------
    ArgumentError
        An unknown design or option, or ``runs`` not a whole number ≥ 1.
    """
    from fdisyn.app.pipeline import fault_size_sweep as sweep

    prob, built, source = _built(spec, designs, workdir, options)
    return sweep(prob, built, runs=runs, source=source, workers=None if source else 1, **options)


def report(spec: Any, *, runs: int | None = None, reports: str | Path = "reports", workdir: str | Path | None = None) -> Path:
    """Design, verify, export, evaluate and write a problem's report page, every design side by side.

    What ``fdisyn report`` does: the page ``REPORTS/<name>/index.html`` with the certificates, what each design
    can see, the false alarms and detection of the compiled Monte Carlo, delays, isolation and the figures.

    Parameters
    ----------
    spec : Problem, LinearPlant, NonlinearPlant, str or Path
        A problem (:func:`problem`), a plant, a plant file or a built-in problem's name.
    runs : int, optional
        Monte Carlo runs per scenario (default: the problem's, 50 for a plant file).
    reports : str or Path
        The folder of the pages (default ``reports``).
    workdir : str or Path, optional
        Where the designs are built (default ``.fdisyn/``).

    Returns
    -------
    Path
        The page written.

    Raises
    ------
    ArgumentError
        ``runs`` not a whole number ≥ 1.
    """
    from fdisyn.app import WORKDIR
    from fdisyn.app.pipeline import reproduce_problem

    prob = _as_problem(spec)
    source = str(spec) if isinstance(spec, (str, Path)) else None
    return reproduce_problem(prob, runs=runs, reports=Path(reports), workdir=Path(WORKDIR if workdir is None else workdir),
                             source=source, workers=None if source else 1)  # fmt: skip
