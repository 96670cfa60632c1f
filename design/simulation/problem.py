"""What a reference problem provides to the pipeline.

A problem module (``fdisyn.problems.<name>``) exposes ``PROBLEM``, a
:class:`Problem`: its designs (each returns a certified
:class:`~fdisyn.runtime.gainfile.GainFile`), its scenarios, a simulator that is
vectorised over seeds, and the paper's reported results. The CLI looks
problems up by name (:func:`get_problem`), so problems depend on the design
code and never the other way round.
"""

from __future__ import annotations

import importlib
import math
import pkgutil
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from fdisyn.runtime.errors import ArgumentError, SpecError
from fdisyn.runtime.gainfile import GainFile
from fdisyn.runtime.names import shown
from fdisyn.runtime.values import real_number
from fdisyn.runtime.trace import Trace
from fdisyn.synthesis.registry import check_option

__all__ = ["Scenario", "Batch", "Problem", "get_problem", "problem_names", "scaled_scenario"]


@dataclass(frozen=True)
class Scenario:
    """A simulated situation: its length and the fault it contains.

    ``fault`` is the name of the gain file's fault class the diagnoser should
    isolate (``None`` for a fault-free run); the fault is active on
    ``onset ≤ t < end`` (``end = None``: until the end of the run).
    ``params`` carries the problem-specific description (fault kind, size).

    Attributes
    ----------
    name : str
        The scenario's name (the key of :attr:`Problem.scenarios`).
    description : str
        One line for the report.
    duration : float
        The run's length in seconds.
    fault : str or None
        The fault class the diagnoser should isolate; ``None``: fault-free.
    onset, end : float or None
        The fault is active on ``onset ≤ t < end`` (``end = None``: until the end of the run).
    params : Mapping of str to object
        The problem-specific description of the fault (kind, size, …).

    Raises
    ------
    ArgumentError
        ``duration``, ``onset`` or ``end`` is not a finite number.
    """

    name: str
    description: str
    duration: float
    fault: str | None = None
    onset: float | None = None
    end: float | None = None
    params: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        # times are numbers as they are given: "1_0" or True would be read as 10 or 1 by float() downstream
        for key in ("duration", "onset", "end"):
            value = getattr(self, key)
            if value is None and key != "duration":
                continue
            x = real_number(value)
            if x is None or not math.isfinite(x):
                raise ArgumentError(f"scenario {self.name!r}: {key} must be a finite number of seconds; got {shown(value)}")

    def active(self, t: np.ndarray) -> np.ndarray:
        """Boolean mask of the samples where the fault is active.

        Parameters
        ----------
        t : numpy.ndarray
            The sample times in seconds.

        Returns
        -------
        numpy.ndarray
            ``True`` where ``onset ≤ t < end`` (within 1e-9 s); all ``False`` for a fault-free scenario.

        Examples
        --------
        >>> Scenario("step", "a step", 3.0, fault="y0", onset=1.0, end=2.0).active(np.arange(4.0)).tolist()
        [False, True, False, False]
        """
        if self.fault is None or self.onset is None:
            return np.zeros(t.shape, dtype=bool)
        end = np.inf if self.end is None else self.end
        return (t >= self.onset - 1e-9) & (t < end - 1e-9)


@dataclass(frozen=True, eq=False)
class Batch:
    """Simulated runs of one scenario, stacked over seeds.

    ``U`` is ``runs × N × nu``, ``Y`` is ``runs × N × ny``; ``extra`` holds
    per-run signals worth keeping (true unknown inputs, true states), each
    ``runs × N``. Run ``i`` is the :class:`~fdisyn.runtime.trace.Trace`
    :meth:`trace` ``(i)``; the runs stay stacked here because the Monte Carlo
    evaluation and the metrics work on all of them at once.

    Attributes
    ----------
    scenario : Scenario
        What was simulated.
    seeds : tuple of int
        One seed per run.
    t : numpy.ndarray
        The ``N`` sample times.
    inputs, outputs : tuple of str
        The signal names of ``U`` and ``Y``.
    U : numpy.ndarray
        The inputs, ``runs × N × nu``.
    Y : numpy.ndarray
        The outputs, ``runs × N × ny``.
    extra : Mapping of str to numpy.ndarray
        Per-run signals worth keeping (true unknown inputs, true states), each ``runs × N``.
    """

    scenario: Scenario
    seeds: tuple[int, ...]
    t: np.ndarray
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    U: np.ndarray
    Y: np.ndarray
    extra: Mapping[str, np.ndarray] = field(default_factory=dict)

    @property
    def active(self) -> np.ndarray:
        """The samples where the scenario's fault is active (:meth:`Scenario.active`)."""
        return self.scenario.active(self.t)

    def trace(self, run: int = 0) -> Trace:
        """Run ``run`` as the trace ``fdisyn simulate`` writes: inputs, outputs, the extra
        signals and ``fault_active`` (1 where the scenario's fault is active).

        Parameters
        ----------
        run : int
            The run's index in the batch.

        Returns
        -------
        Trace
            The run.
        """
        extra = {k: np.asarray(v)[run] for k, v in self.extra.items()}
        extra["fault_active"] = self.active.astype(float)
        return Trace(t=self.t, inputs=self.inputs, outputs=self.outputs, U=self.U[run], Y=self.Y[run], extra=extra)


DesignFn = Callable[..., GainFile]
SimulateFn = Callable[..., Batch]


@dataclass(frozen=True, eq=False)
class Problem:
    """A reference plant with its designs, scenarios and reported results.

    ``designs[name](**options)`` returns a certified gain file;
    ``simulate(scenario, seeds, **options)`` a :class:`Batch`. ``options``
    are problem-specific keyword settings (e.g. a parameter set), accepted
    by both, listed in ``options`` with their defaults.

    Attributes
    ----------
    name : str
        The problem's name (``fdisyn reproduce NAME``).
    title, summary : str
        The report's title and one-paragraph summary.
    designs : Mapping of str to callable
        ``designs[name](**options)``: a certified gain file.
    default_design : str
        The design :meth:`design` makes without a name.
    scenarios : Mapping of str to Scenario
        The simulated situations, by name.
    simulate : callable
        ``simulate(scenario, seeds, **options)``: a :class:`Batch`.
    options : Mapping of str to object
        The problem's keyword settings and their defaults.
    reference : Mapping of str to object
        The source paper's figures the report compares with.
    monte_carlo_runs : int
        Runs per scenario in the report.
    report : callable or None
        Problem-specific report sections: ``report(ctx) -> [(title, html), …]``.
    variants : sequence of Mapping
        Extra report variants: ``{"label", "options", "scenarios", "designs", "runs"}`` (e.g. another parameter
        set); ``scenarios`` and ``designs`` default to all, ``runs`` to :attr:`monte_carlo_runs` (``--runs``
        overrides it).
    notes : sequence of str
        Modelling choices the sources left open, stated in the report.
    extra_metrics : callable or None
        Problem-specific Monte Carlo figures of one scenario (default: those of the gain file's diagnoser kind,
        :attr:`fdisyn.synthesis.kinds.DiagnoserKind.extra_metrics`): an :class:`~fdisyn.synthesis.kinds.ExtraMetrics`,
        a few values per run and their reduction over the runs (the Monte Carlo never holds every run).
    sample_model : callable or None
        The simulator one sample at a time, for the compiled Monte Carlo: ``sample_model(**options)`` returns a
        :class:`~fdisyn.simulation.sample_models.SampleModel` whose runs match :attr:`simulate`'s given the same
        standard-normal draws; ``None``: the runs stay on the Python path.
    claims : callable or None
        The paper's claims against ours, the table each report page opens with: ``claims(ctx)`` with ``ctx`` the
        :class:`fdisyn.reporting.kit.ReportContext`, returning :class:`fdisyn.reporting.kit.Claim` rows.
    labels : Mapping of str to str
        Readable physical names with units of internal names (signals, statistics, faults, designs), e.g.
        ``"omega_g_m1": "generator speed ω_g,m1 (rad/s)"``: what the report shows
        (:func:`fdisyn.reporting.kit.label`).
    model : callable or None
        ``model(**options)``: the design model (a ``LinearPlant`` or ``SampledDataPlant``) for the residuals'
        frequency responses and the plant's poles in the report; ``None`` for nonlinear problems.
    scaled : callable or None
        ``scaled(scenario, k)``: the scenario with its fault ``k`` times as large, for the report's fault-size
        sweep (``None`` from the hook: this scenario's fault has no size). Default: :func:`scaled_scenario`.
    shift_scenario : str or None
        A scenario whose fault is a persistent step (a bias): each report variant with sequential statistics
        runs it again at the fault sizes that shift the whitened residual by 0.25σ … 4σ, for their delay
        against the Lorden bound (``None``: no such sweep).
    operating_delay : float or None
        The delay ``D`` (s) of the report's operating characteristic, the probability of detection within ``D``
        against the mean time between false alarms (``None``: a tenth of the shortest faulty scenario's fault).
    """

    name: str
    title: str
    summary: str
    designs: Mapping[str, DesignFn]
    default_design: str
    scenarios: Mapping[str, Scenario]
    simulate: SimulateFn
    options: Mapping[str, Any] = field(default_factory=dict)
    reference: Mapping[str, Any] = field(default_factory=dict)
    monte_carlo_runs: int = 100
    report: Callable[..., Any] | None = None
    variants: Sequence[Mapping[str, Any]] = ()
    notes: Sequence[str] = ()
    extra_metrics: Callable[..., Mapping[str, Any]] | None = None
    sample_model: Callable[..., Any] | None = None
    claims: Callable[..., Sequence[Any]] | None = None
    labels: Mapping[str, str] = field(default_factory=dict)
    model: Callable[..., Any] | None = None
    scaled: Callable[[Scenario, float], Scenario | None] | None = None
    shift_scenario: str | None = None
    operating_delay: float | None = None

    def design(self, name: str | None = None, **options: Any) -> GainFile:
        """Make one of the problem's designs.

        Parameters
        ----------
        name : str, optional
            A key of :attr:`designs`; default: :attr:`default_design`.
        **options
            The problem's options (:attr:`options`), checked by :meth:`check_options`.

        Returns
        -------
        GainFile
            The certified diagnoser.

        Raises
        ------
        ArgumentError
            An unknown design or option, or an option's value outside its domain.
        """
        key = name or self.default_design
        if key not in self.designs:
            raise ArgumentError(f"problem {self.name!r} has no design {key!r}; designs: {sorted(self.designs)}")
        return self.designs[key](**self.check_options(options))

    def scenario(self, name: str) -> Scenario:
        """The scenario called ``name``.

        Parameters
        ----------
        name : str
            A key of :attr:`scenarios`.

        Returns
        -------
        Scenario
            The scenario.

        Raises
        ------
        ArgumentError
            The problem has no such scenario (the message lists those it has).
        """
        if name not in self.scenarios:
            raise ArgumentError(f"problem {self.name!r} has no scenario {name!r}; scenarios: {sorted(self.scenarios)}")
        return self.scenarios[name]

    def run(self, scenario: str | Scenario, seeds: Sequence[int], **options: Any) -> Batch:
        """Simulate ``scenario`` once per seed; seeds are whole numbers ≥ 0 (NumPy's
        generators refuse negative ones, and a float seed would be truncated).

        Parameters
        ----------
        scenario : str or Scenario
            A scenario of the problem, by name, or any scenario.
        seeds : sequence of int
            One seed per run.
        **options
            The problem's options, checked by :meth:`check_options`.

        Returns
        -------
        Batch
            The runs, stacked over the seeds.

        Raises
        ------
        ArgumentError
            An unknown scenario or option, a value outside its domain, or a seed that is not a whole number ≥ 0.
        """
        sc = self.scenario(scenario) if isinstance(scenario, str) else scenario
        bad = [s for s in seeds if isinstance(s, bool) or not isinstance(s, (int, np.integer)) or s < 0]
        if bad:
            raise ArgumentError(f"seeds must be whole numbers ≥ 0; got {shown(bad)}")
        return self.simulate(sc, tuple(int(s) for s in seeds), **self.check_options(options))

    def check_options(self, options: Mapping[str, Any]) -> dict[str, Any]:
        """The problem's defaults updated by ``options``, each value validated by
        :func:`~fdisyn.synthesis.registry.check_option` (unknown names are refused with the list of known ones).

        Parameters
        ----------
        options : Mapping of str to object
            The options given.

        Returns
        -------
        dict
            Every option of the problem: its default, or the value given.

        Raises
        ------
        ArgumentError
            An unknown option, a value outside its domain, or both ``P_f`` and ``arl0``.
        """
        unknown = sorted(set(options) - set(self.options))
        if unknown:
            raise ArgumentError(f"problem {self.name!r} has no option(s) {unknown}; options: {dict(self.options)}")
        checked = {k: check_option(k, v, self.options[k], f"problem {self.name!r}") for k, v in options.items()}
        if checked.get("P_f") is not None and checked.get("arl0") is not None:
            raise ArgumentError(
                f"problem {self.name!r}: P_f = {shown(checked['P_f'])} and arl0 = {shown(checked['arl0'])} s both set the "
                f"false-alarm budget; give one (arl0 alone replaces the problem's P_f = {shown(self.options.get('P_f'))})"
            )
        return {**self.options, **checked}


def scaled_scenario(scenario: Scenario, k: float) -> Scenario | None:
    """``scenario`` with its fault ``k`` times as large; ``None`` when its size is not known.

    A ``size`` parameter is multiplied by ``k``; ``sensor_faults`` ``(sensor, kind, value)`` entries scale an
    offset's or a drift's value and a gain's deviation from 1 (a stuck sensor's value is no size: ``None``).
    """
    from dataclasses import replace

    if scenario.fault is None:
        return None
    params = dict(scenario.params)
    if str(params.get("kind", "bias")).split("_")[0] not in ("bias", "offset", "drift"):  # stuck, open circuit: no size
        return None
    if isinstance(params.get("size"), (int, float)):
        params["size"] = params["size"] * k
    elif params.get("sensor_faults"):
        faults: list[Any] = []
        for spec in params["sensor_faults"]:
            # (sensor, kind, value) tuples, or specs with those fields (plant files)
            sensor, kind, value = spec if isinstance(spec, (tuple, list)) else (spec.sensor, spec.kind, spec.value)
            if kind == "gain":
                value = 1.0 + k * (value - 1.0)
            elif kind.startswith("offset") or kind.startswith("drift"):
                value = k * value
            else:
                return None
            faults.append((sensor, kind, value) if isinstance(spec, (tuple, list)) else replace(spec, value=value))
        params["sensor_faults"] = faults
    else:
        return None
    return replace(scenario, name=f"{scenario.name}_x{k:g}", description=f"{scenario.description} Fault scaled by {k:g}.", params=params)


def problem_names() -> list[str]:
    """Names of the built-in problems (modules of :mod:`fdisyn.problems`)."""
    pkg = importlib.import_module("fdisyn.problems")
    names = []
    for mod in pkgutil.iter_modules(pkg.__path__):
        if mod.name.startswith("_"):
            continue
        if hasattr(importlib.import_module(f"fdisyn.problems.{mod.name}"), "PROBLEM"):
            names.append(mod.name)
    return sorted(names)


def get_problem(name: str) -> Problem:
    """The built-in problem ``name`` (error lists the valid names).

    Only a plain identifier is looked up: the name becomes a module path, and a
    dotted or empty one would import something else or fail inside importlib.
    """
    if not name.isidentifier():
        raise SpecError(f"no built-in problem {name!r} (and no plant file by that name); problems: {problem_names()}")
    try:
        mod = importlib.import_module(f"fdisyn.problems.{name}")
    except ModuleNotFoundError:
        raise SpecError(f"no built-in problem {name!r}; problems: {problem_names()}") from None
    prob = getattr(mod, "PROBLEM", None)
    if not isinstance(prob, Problem):
        raise SpecError(f"fdisyn.problems.{name} is not a problem module (it has no PROBLEM); problems: {problem_names()}")
    return prob
