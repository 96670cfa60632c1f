"""A Monte Carlo campaign: per-run seeds, chunks of runs simulated and diagnosed, and where the chunks run.

Run ``i`` of scenario ``s`` (the scenario's position in ``problem.scenarios``)
gets the seed :func:`run_seed` ``(seed0, s, i)``, whatever the design, the
chunk it falls in or the process that runs it: every design of a comparison
sees the same runs (common random numbers), and a run is the same run on one
core, on many and on a Dask cluster. The runs of a scenario are simulated and
diagnosed in chunks of bounded size (:func:`simulate_and_diagnose`, a
:class:`~fdisyn.evaluation.runs.ChunkRuns`); each chunk is reduced where it ran to a few numbers per
run (:func:`fdisyn.evaluation.metrics.summarise_runs`) and the parent merges
them in run order, so memory does not grow with the samples of the campaign
and the metrics are identical to the last bit however the runs were spread.

Chunks run here (``workers=1``), over local processes (each given a
:class:`CampaignSpec` that rebuilds the problem and loads the compiled
diagnosers once per process) or on a ``dask.distributed.Client``. A chunk that
raises is run again once; a second failure names the scenario, the run, its
seed and the error (:class:`~fdisyn.runtime.errors.MonteCarloError`).
"""

from __future__ import annotations

import importlib
import logging
import multiprocessing
import os
import pickle
import re
import signal
import threading
from collections import deque
from collections.abc import Callable, Generator, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from fdisyn.codegen.library import local_cores
from fdisyn.evaluation.built import Built, load_built
from fdisyn.evaluation.metrics import MetricsPlan, RunSummaries, extra_values, operating_values, summarise_runs
from fdisyn.evaluation.runs import ChunkRuns, DesignRuns
from fdisyn.simulation.problem import Batch, Problem, Scenario
from fdisyn.runtime.errors import ArgumentError, FdisynError, MonteCarloError
from fdisyn.runtime.names import shown

__all__ = [
    "run_seed",
    "OPERATING_DELAY_SHARE",
    "operating_delay",
    "simulate_and_diagnose",
    "Campaign",
    "CampaignSpec",
    "ChunkTask",
    "ChunkPlan",
    "ChunkSummary",
    "RunFailure",
    "chunk_runs",
    "local_cores",
    "first_run",
    "extra_hooks",
    "load_source",
    "problem_source",
    "remote_chunk",
    "run_tasks",
    "dask_client",
    "scheduler_address",
]

CHUNK_SAMPLES = 500_000
"""Samples (runs × samples per run) simulated in one chunk at most: a chunk keeps every signal of its runs, so
this bounds the memory of a campaign whatever its number of runs (about 8 bytes × signals per sample)."""

CHUNK_RUNS = 25
"""Runs in one chunk at most (short runs): enough chunks per scenario to spread over the workers."""


OPERATING_DELAY_SHARE = 0.1
"""Without :attr:`Problem.operating_delay`, the operating characteristic's delay is this share of the shortest fault."""


def operating_delay(problem: Problem) -> float | None:
    """The delay ``D`` (s) of ``problem``'s operating characteristic: its :attr:`Problem.operating_delay`, else
    :data:`OPERATING_DELAY_SHARE` of the shortest time a fault of its scenarios is active (``None``: no fault).

    Parameters
    ----------
    problem : Problem
        The problem.

    Returns
    -------
    float or None
        ``D`` in seconds.
    """
    if problem.operating_delay is not None:
        return float(problem.operating_delay)
    spans = [(sc.end if sc.end is not None else sc.duration) - float(sc.onset or 0.0)
             for sc in problem.scenarios.values() if sc.fault is not None]
    return OPERATING_DELAY_SHARE * min(spans) if spans else None


def run_seed(seed0: int, scenario_index: int, run: int) -> int:
    """The seed of run ``run`` of the scenario at position ``scenario_index`` in a campaign started from ``seed0``:
    the first word of ``SeedSequence([seed0, scenario_index, run])``, halved into ``[0, 2⁶³)``."""
    return int(np.random.SeedSequence([seed0, scenario_index, run]).generate_state(2, np.uint64)[0] >> np.uint64(1))


def simulate_and_diagnose(
    problem: Problem, built: Mapping[str, Built], scenario: str | Scenario, seeds: Sequence[int], *, keep_batch: bool = False,
    **options: Any,
) -> ChunkRuns:
    """Simulate ``scenario`` once per seed (:meth:`Problem.run`) and run every built diagnoser's C step over each run."""
    batch = problem.run(scenario, seeds, **options)
    designs = {}
    for name, b in built.items():
        res = [b.diagnoser.run(batch.U[i], batch.Y[i]) for i in range(len(batch.seeds))]
        designs[name] = DesignRuns(
            r=np.stack([x.r for x in res]),
            J=np.stack([x.J for x in res]),
            alarm=np.stack([x.alarm for x in res]).astype(bool),
            isolated=np.stack([x.isolated for x in res]).astype(np.int32),
            status=np.stack([x.status for x in res]).astype(np.int8),
        )
    return ChunkRuns(seeds=batch.seeds, t=batch.t, designs=designs, batch=batch if keep_batch else None)


def chunk_runs(samples_per_run: int) -> int:
    """Runs per chunk for runs of ``samples_per_run`` samples (:data:`CHUNK_SAMPLES`, :data:`CHUNK_RUNS`); it
    depends on the runs' length only, never on the workers."""
    return max(1, min(CHUNK_RUNS, CHUNK_SAMPLES // max(samples_per_run, 1)))


# --------------------------------------------------------------------------- one chunk


@dataclass(frozen=True)
class ChunkTask:
    """Runs ``start … start + len(seeds) − 1`` of scenario ``scenario`` (its position ``scenario_index``)."""

    scenario: str
    scenario_index: int
    start: int
    seeds: tuple[int, ...]
    keep_batch: bool = False


@dataclass(frozen=True)
class ChunkPlan:
    """The chunks of a campaign in run order, each :class:`ChunkTask` made (its seeds drawn) only when it is
    reached: the plan itself holds a few numbers whatever ``runs`` is, so a campaign's memory does not grow with its
    runs and its first chunk starts at once.

    Iterating gives, scenario after scenario, the chunks of runs ``0 … runs − 1``; run ``i`` of the scenario at
    position ``s`` gets :func:`run_seed` ``(seed0, s, i)``, the first chunk of each scenario keeps its batch (run 0:
    the figures' example). ``len()`` is the number of chunks.
    """

    seed0: int
    runs: int
    """Runs per scenario."""
    scenarios: tuple[tuple[str, int, int], ...]
    """``(name, position in problem.scenarios, runs per chunk)`` of each scenario, in the order they are run."""

    def __len__(self) -> int:
        return sum(-(-self.runs // size) for _, _, size in self.scenarios)

    def __iter__(self) -> Iterator[ChunkTask]:
        for name, s, size in self.scenarios:
            for start in range(0, self.runs, size):
                seeds = tuple(run_seed(self.seed0, s, i) for i in range(start, min(self.runs, start + size)))
                yield ChunkTask(scenario=name, scenario_index=s, start=start, seeds=seeds, keep_batch=start == 0)


@dataclass(frozen=True, eq=False)
class ChunkSummary:
    """What a chunk sends back: each design's per-run summaries, and run 0's simulation when it was asked for."""

    task: ChunkTask
    t: np.ndarray
    summaries: Mapping[str, RunSummaries]
    batch: Batch | None = None


@dataclass(eq=False)
class Campaign:
    """A problem, its options and its built diagnosers, ready to run chunks."""

    problem: Problem
    built: Mapping[str, Built]
    options: Mapping[str, Any]
    extra: Mapping[str, Any] = field(default_factory=dict)
    compiled: bool = True
    """Simulate and diagnose in one generated C call where the problem has a sample model
    (:func:`fdisyn.evaluation.compiled_campaign.compiled_campaign`); ``False``: the Python simulator."""
    copies: tuple[str, ...] = ()
    """The designs of ``built`` that are copies of another with scaled thresholds (:attr:`CampaignSpec.copies`):
    in the fused library they call their own step once per run instead of a vector form, whose C would cost more
    to compile than they take to run."""
    _fused: dict[str, Any] = field(default_factory=dict, repr=False)

    def fused(self, sc: Scenario) -> Any:
        """The scenario's :class:`~fdisyn.evaluation.compiled_campaign.CompiledCampaign`, or ``None`` (the Python
        path: ``compiled=False``, no design, or no sample model)."""
        if not (self.compiled and self.built and self.problem.sample_model is not None):
            return None
        if sc.name not in self._fused:
            from fdisyn.evaluation.compiled_campaign import compiled_campaign  # CasADi and the C compiler: only here

            self._fused[sc.name] = compiled_campaign(self.problem, self.built, sc, scalar=self.copies, **self.options)
        return self._fused[sc.name]

    def chunk(self, sc: Scenario, task: ChunkTask) -> ChunkRuns:
        """The chunk's runs simulated and diagnosed: compiled when the problem allows, else on the Python path."""
        fused = self.fused(sc)
        if fused is not None:
            return fused.run(task.seeds, keep_batch=task.keep_batch)
        return simulate_and_diagnose(self.problem, self.built, sc, task.seeds, keep_batch=task.keep_batch, **self.options)

    def plan(self, sc: Scenario, name: str, t: np.ndarray) -> MetricsPlan:
        """Design ``name``'s :class:`~fdisyn.evaluation.metrics.MetricsPlan` in ``sc`` at times ``t``, with its extra
        figures and the problem's :func:`operating_delay`."""
        return MetricsPlan.of(sc, self.built[name].gain_file, t, self.extra.get(name), operating_delay(self.problem))

    def run(self, task: ChunkTask) -> ChunkSummary:
        """The chunk's per-run summaries: on the compiled path accumulated in its C loop, no sample kept but those
        the extra figures and the operating characteristic read (their designs' arrays) and the batch when asked
        for; else from the chunk's arrays."""
        sc = self.problem.scenario(task.scenario)
        fused = self.fused(sc)
        if fused is not None:
            t = np.arange(fused.spec.samples) * fused.spec.Ts
            plans = {name: self.plan(sc, name, t) for name in self.built}
            kept = [name for name, plan in plans.items() if plan.extra is not None or plan.operating is not None]
            chunk, out = fused.summarise(task.seeds, plans, keep_batch=task.keep_batch, arrays=kept)
            for name in kept:
                runs = chunk.designs[name]
                out[name] = replace(out[name], extra=extra_values(plans[name], runs, sc, self.built[name].gain_file),
                                    operating=operating_values(plans[name], runs))
        else:
            chunk = self.chunk(sc, task)
            out = {}
            for name, b in self.built.items():
                plan = self.plan(sc, name, chunk.t)
                out[name] = summarise_runs(plan, chunk.designs[name], sc, b.gain_file)
        return ChunkSummary(task=task, t=chunk.t, summaries=out, batch=None if chunk.batch is None else first_run(chunk.batch))

    def run_or_locate(self, task: ChunkTask) -> ChunkSummary:
        """:meth:`run`; when the chunk raises, the first of its runs that raises alone is named (:class:`RunFailure`)."""
        try:
            return self.run(task)
        except Exception as exc:
            for k, seed in enumerate(task.seeds):
                try:
                    self.run(ChunkTask(task.scenario, task.scenario_index, task.start + k, (seed,)))
                except Exception as one:
                    raise RunFailure(task.scenario, task.start + k, seed, _describe(one)) from one
            last = task.start + len(task.seeds) - 1
            raise RunFailure(task.scenario, task.start, task.seeds[0], f"runs {task.start}–{last} together: {_describe(exc)}") from exc


def _describe(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


class RunFailure(Exception):
    """A run of a chunk raised (picklable: it crosses from a worker process or a Dask worker)."""

    def __init__(self, scenario: str, run: int, seed: int, error: str) -> None:
        super().__init__(scenario, run, seed, error)
        self.scenario, self.run, self.seed, self.error = scenario, run, seed, error

    def __str__(self) -> str:
        return f"scenario {self.scenario!r}, run {self.run} (seed {self.seed}): {self.error}"


def first_run(batch: Batch) -> Batch:
    """Run 0 of ``batch`` alone (the example run of the figures)."""
    return Batch(
        scenario=batch.scenario,
        seeds=batch.seeds[:1],
        t=batch.t,
        inputs=batch.inputs,
        outputs=batch.outputs,
        U=batch.U[:1],
        Y=batch.Y[:1],
        extra={k: v[:1] for k, v in batch.extra.items()},
    )


# --------------------------------------------------------------------------- rebuilding a campaign in a worker


@dataclass(frozen=True)
class CampaignSpec:
    """Everything a worker process needs to rebuild a campaign: picklable, no library handle.

    ``source``: a built-in problem's name, a plant file's path, or
    ``module:attribute`` naming a :class:`Problem`; ``options``: the problem's
    options; ``built``: each design's built directory (``gains.json`` and the
    compiled library; a remote worker must see the same path).
    """

    source: str
    options: tuple[tuple[str, Any], ...]
    built: tuple[tuple[str, str, str], ...]
    """``(design, directory, sha256 of its gains.json)``: a directory built again is loaded again."""
    scenarios: tuple[Scenario, ...] = ()
    """The scenarios run, as the parent has them (a problem's scenarios may be replaced, e.g. scaled faults)."""
    compiled: bool = True
    """:attr:`Campaign.compiled`."""
    copies: tuple[str, ...] = ()
    """The designs of ``built`` that are copies of another with scaled thresholds: run for their alarms only (no
    extra figures)."""

    def key(self) -> bytes:
        return pickle.dumps((self.source, self.options, self.built, self.scenarios, self.compiled, self.copies))


_CAMPAIGNS: dict[bytes, Campaign] = {}
"""The campaigns this process rebuilt, by :meth:`CampaignSpec.key` (a worker loads each library once)."""


def load_source(source: str) -> Problem:
    """The problem ``source`` names (see :class:`CampaignSpec`)."""
    from fdisyn.simulation.plant_file import load_spec

    if ":" in source and not Path(source).exists():
        module, _, attr = source.partition(":")
        prob = getattr(importlib.import_module(module), attr, None)
        if not isinstance(prob, Problem):
            raise ArgumentError(f"{source!r} does not name a Problem (module:attribute)")
        return prob
    return load_spec(source)


def problem_source(problem: Problem) -> str | None:
    """The source that rebuilds ``problem`` in another process: its name when it is the built-in problem of that
    name, else ``None`` (a plant file's problem needs its path)."""
    from fdisyn.simulation.problem import get_problem

    try:
        return problem.name if get_problem(problem.name) is problem else None
    except FdisynError:
        return None


def _campaign(spec: CampaignSpec) -> Campaign:
    key = spec.key()
    if key not in _CAMPAIGNS:
        problem = load_source(spec.source)
        if spec.scenarios:
            problem = replace(problem, scenarios={sc.name: sc for sc in spec.scenarios})
        built = {name: load_built(d) for name, d, _ in spec.built}
        own = {name: b for name, b in built.items() if name not in spec.copies}
        _CAMPAIGNS[key] = Campaign(problem, built, dict(spec.options), extra_hooks(problem, own), compiled=spec.compiled,
                                   copies=spec.copies)
    return _CAMPAIGNS[key]


def remote_chunk(spec: CampaignSpec, task: ChunkTask) -> ChunkSummary:
    """Run ``task`` in a worker (the campaign rebuilt from ``spec`` once per process)."""
    return _campaign(spec).run_or_locate(task)


def extra_hooks(problem: Problem, built: Mapping[str, Built]) -> dict[str, Any]:
    """Each design's extra figures (:class:`~fdisyn.synthesis.kinds.ExtraMetrics`): the problem's, else its
    diagnoser kind's; designs without any are left out."""
    from fdisyn.synthesis.kinds import ExtraMetrics, get_kind

    out = {}
    for name, b in built.items():
        hook = problem.extra_metrics or get_kind(b.gain_file.kind).extra_metrics
        if hook is None:
            continue
        if not isinstance(hook, ExtraMetrics):
            raise ArgumentError(
                f"problem {problem.name!r}: extra_metrics must be an ExtraMetrics (per-run values and their reduction); "
                f"got {type(hook).__name__}"
            )
        out[name] = hook
    return out


# --------------------------------------------------------------------------- where chunks run


class _Serial:
    """Chunks run here, one after the other."""

    slots = 1

    def __init__(self, campaign: Campaign) -> None:
        self.campaign = campaign

    def submit(self, task: ChunkTask) -> Future[ChunkSummary]:
        fut: Future[ChunkSummary] = Future()
        try:
            fut.set_result(self.campaign.run_or_locate(task))
        except RunFailure as exc:
            fut.set_exception(exc)
        return fut

    def reset(self) -> bool:
        return False

    def abort(self, pending: Iterable[Any]) -> None:
        pass


_POOLS: dict[int, ProcessPoolExecutor] = {}
"""The process pools of this process, by size: kept between campaigns, so each worker loads a campaign once."""


def _context() -> Any:
    """Worker processes start from a fork server that has imported fdisyn (no fork of a threaded parent), else
    spawned. The fork server is started with Ctrl-C ignored (a disposition kept across ``exec`` and restored in
    every process it forks), so that SIGINT, which a terminal sends to the whole process group, reaches the parent
    alone: it stops the workers itself (:func:`run_tasks`), and no worker prints a traceback."""
    if "forkserver" in multiprocessing.get_all_start_methods():
        from multiprocessing import forkserver

        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(["fdisyn.evaluation.campaign", "fdisyn.evaluation.evaluate"])
        with _sigint_ignored():
            forkserver.ensure_running()
        return ctx
    return multiprocessing.get_context("spawn")  # pragma: no cover - not POSIX


@contextmanager
def _sigint_ignored() -> Iterator[None]:
    """SIGINT ignored meanwhile by this process and whatever it starts (only the main thread may change it;
    elsewhere nothing changes). It is blocked in this thread, and in the threads started meanwhile, so that a Ctrl-C
    that came meanwhile is kept pending and raised after (a thread that was already running may still take and
    drop it)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        old = signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            yield
        finally:
            signal.signal(signal.SIGINT, old)
    finally:
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


def _ignore_sigint() -> None:
    """A worker process's initializer: Ctrl-C is the parent's to handle (it stops the workers)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


class _Processes:
    """Chunks run over local worker processes."""

    def __init__(self, spec: CampaignSpec, workers: int) -> None:
        self.spec, self.slots = spec, 2 * workers
        self.workers = workers
        self.pool = self._pool()

    def _pool(self) -> ProcessPoolExecutor:
        pool = _POOLS.get(self.workers)
        if pool is None:
            pool = _POOLS[self.workers] = ProcessPoolExecutor(self.workers, mp_context=_context(), initializer=_ignore_sigint)
        return pool

    def submit(self, task: ChunkTask) -> Future[ChunkSummary]:
        return self.pool.submit(remote_chunk, self.spec, task)

    def reset(self) -> bool:
        """After a worker process died: a new pool (the lost chunks are submitted again)."""
        _POOLS.pop(self.workers, None)
        self.pool.shutdown(wait=False, cancel_futures=True)
        self.pool = self._pool()
        return True

    def abort(self, pending: Iterable[Any]) -> None:
        """The campaign stopped early (Ctrl-C, an error): the chunks in flight dropped and the worker processes
        ended and waited for (none is left behind); the next campaign starts a new pool."""
        _POOLS.pop(self.workers, None)
        processes = list((getattr(self.pool, "_processes", None) or {}).values())
        self.pool.shutdown(wait=False, cancel_futures=True)
        for proc in processes:
            proc.terminate()
        for proc in processes:
            proc.join(5)
            if proc.is_alive():  # pragma: no cover - a worker stuck in a system call
                proc.kill()
                proc.join(5)


class _Dask:
    """Chunks run on a Dask cluster."""

    def __init__(self, spec: CampaignSpec, client: Any) -> None:
        self.spec, self.client = spec, client
        self.slots = 2 * max(1, sum(client.nthreads().values()))

    def submit(self, task: ChunkTask) -> Any:
        return self.client.submit(remote_chunk, self.spec, task, pure=False)

    def reset(self) -> bool:
        return False

    def abort(self, pending: Iterable[Any]) -> None:
        """The campaign stopped early: its chunks still queued or running on the cluster cancelled."""
        futures = list(pending)
        if futures:
            try:
                self.client.cancel(futures)
            except Exception:  # noqa: BLE001 - the cluster already gone: nothing left to cancel
                pass


def run_tasks(
    tasks: Sequence[ChunkTask] | ChunkPlan,
    *,
    campaign: Campaign,
    spec: CampaignSpec | None,
    workers: int,
    client: Any = None,
) -> Generator[ChunkSummary, None, None]:
    """The chunks' summaries in task order, run here (``workers == 1`` or no ``spec``), over
    ``min(workers, len(tasks))`` local processes, or on ``client``.

    ``tasks`` is read one task at a time as chunks are submitted (a :class:`ChunkPlan` draws each chunk's seeds
    then), and at most two chunks per worker are in flight, so memory does not grow with the number of chunks. A
    chunk that fails is run once more, and a second failure is a :class:`MonteCarloError` naming its run. When the
    caller stops early (Ctrl-C, an exception, the generator closed) the chunks in flight are dropped and the worker
    processes ended.

    Parameters
    ----------
    tasks : sequence of ChunkTask or ChunkPlan
        The chunks in run order; ``len(tasks)`` is used, no list of them is made.
    campaign : Campaign
        Runs the chunks in this process.
    spec : CampaignSpec or None
        Rebuilds the campaign in a worker; ``None``: every chunk runs here.
    workers : int
        Local worker processes at most (``1``: here).
    client : dask.distributed.Client, optional
        Run the chunks on this cluster instead.

    Returns
    -------
    iterator of ChunkSummary
        One per task, in task order.

    Raises
    ------
    MonteCarloError
        A chunk failed twice.
    ArgumentError
        ``client`` without ``spec``.
    """
    runner: Any
    if client is not None:
        if spec is None:
            raise ArgumentError(_NO_SOURCE)
        runner = _Dask(spec, client)
    elif workers > 1 and spec is not None and len(tasks) > 1:
        runner = _Processes(spec, min(workers, len(tasks)))
    else:
        runner = _Serial(campaign)
    pending: deque[tuple[ChunkTask, Any, bool]] = deque()
    queue = iter(tasks)

    def fill() -> None:
        while len(pending) < runner.slots:
            task = next(queue, None)
            if task is None:
                return
            pending.append((task, runner.submit(task), False))

    finished = False
    try:
        fill()
        while pending:
            task, fut, retried = pending[0]
            try:
                result = fut.result()
            except Exception as exc:
                pending.popleft()
                if retried:
                    if isinstance(exc, BrokenProcessPool):
                        runner.reset()  # the next campaign finds a working pool
                    raise _failure(exc, task) from None
                if isinstance(exc, BrokenProcessPool) and runner.reset():  # a worker died: every chunk in flight again
                    pending = deque((t, runner.submit(t), r) for t, _, r in pending)
                pending.appendleft((task, runner.submit(task), True))
                continue
            pending.popleft()
            yield result
            fill()
        finished = True
    finally:
        if not finished:
            runner.abort(fut for _, fut, _ in pending)


_NO_SOURCE = (
    "this problem cannot be rebuilt in another process: give evaluate source= (its plant file, or module:attribute), "
    "or workers=1"
)


def _failure(exc: BaseException, task: ChunkTask) -> MonteCarloError:
    last = task.start + len(task.seeds) - 1
    if isinstance(exc, RunFailure):
        what = str(exc)
    else:
        what = f"scenario {task.scenario!r}, runs {task.start}–{last}: {_describe(exc)}"
    return MonteCarloError(f"a Monte Carlo run failed twice: {what}")


_SCHEDULER_FORMS = "tcp://HOST:PORT (HOST:PORT alone is tcp), or tls://HOST:PORT with Dask's TLS configuration"
"""The scheduler addresses ``--address`` takes."""

_TLS_NEEDS = (
    "a TLS scheduler needs the client's certificate and its authority in Dask's configuration "
    "(DASK_DISTRIBUTED__COMM__TLS__CA_FILE, DASK_DISTRIBUTED__COMM__TLS__CLIENT__CERT and __CLIENT__KEY in the environment, "
    "or distributed.comm.tls in a Dask config file)"
)

_OTHER_SCHEMES = {
    "ucx": "the UCX transport is not supported (it needs distributed-ucxx and a UCX network)",
    "inproc": "an inproc:// scheduler lives inside one Python process, which a command cannot join",
    "ws": "the websocket transport is not supported",
    "wss": "the websocket transport is not supported",
}

_HOST_PORT = re.compile(r"(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9](?:[A-Za-z0-9.-]*[A-Za-z0-9])?):([0-9]+)")


def scheduler_address(address: str) -> str:
    """``address`` checked as the address of a Dask scheduler this process can join, before anything connects.

    Parameters
    ----------
    address : str
        ``tcp://HOST:PORT``, ``HOST:PORT`` (tcp) or ``tls://HOST:PORT``; ``HOST`` a name, an IPv4 address or an IPv6
        address in brackets, ``PORT`` 1–65535 in ASCII digits.

    Returns
    -------
    str
        The address with its scheme (``tcp://`` added to ``HOST:PORT``).

    Raises
    ------
    ArgumentError
        Another scheme (``ucx://``, ``inproc://``, …), no host or port, a port out of range, or ``tls://`` without
        the client's certificates in Dask's configuration; the line names the address, what is wrong and the forms
        taken.
    MonteCarloError
        ``tls://`` and Dask is not installed.
    """
    text = shown(address)
    if not isinstance(address, str):
        raise ArgumentError(f"{text}: expected a scheduler address, {_SCHEDULER_FORMS}")
    scheme, sep, rest = address.partition("://")
    if not sep:
        scheme, rest = "tcp", address
    scheme = scheme.lower()
    if scheme not in ("tcp", "tls"):
        why = _OTHER_SCHEMES.get(scheme, f"scheme {shown(scheme)} is not one fdisyn joins")
        raise ArgumentError(f"{text}: {why}; expected {_SCHEDULER_FORMS}")
    m = _HOST_PORT.fullmatch(rest)
    if m is None:
        raise ArgumentError(f"{text}: expected {_SCHEDULER_FORMS}; HOST is a name, an IPv4 address or [an IPv6 address]")
    digits = m.group(2)
    if len(digits) > 5 or not 1 <= int(digits) <= 65535:
        port = digits if len(digits) <= 12 else f"of {len(digits)} digits"
        raise ArgumentError(f"{text}: port {port} is out of range; expected a port 1–65535 in {_SCHEDULER_FORMS}")
    if scheme == "tls" and not _tls_configured():
        raise ArgumentError(f"{text}: {_TLS_NEEDS} and none is set; or use a tcp://HOST:PORT scheduler")
    return f"{scheme}://{rest}"


def _tls_configured() -> bool:
    """Dask's configuration gives a client its TLS context (certificate and authority files that load), or names a
    security loader."""
    try:
        import dask
        from distributed.security import Security
    except ImportError:
        raise MonteCarloError(_NO_DASK) from None
    if dask.config.get("distributed.client.security-loader", None):
        return True
    try:
        return Security().get_connection_args("client").get("ssl_context") is not None
    except (OSError, ValueError) as exc:  # ssl.SSLError is an OSError: a file missing, not PEM, a key that does not fit
        raise ArgumentError(f"Dask's TLS configuration cannot be used: {_describe(exc)}; {_TLS_NEEDS}") from None


_NO_DASK = "--scheduler dask needs Dask: pip install 'fdisyn[dask]'"


def dask_client(address: str | None, workers: int) -> Callable[[], Any]:
    """A factory of the Dask client of ``fdisyn … --scheduler dask``: the scheduler at ``address``
    (:func:`scheduler_address`, checked here before the factory is made), else a local cluster of ``workers``
    processes of one thread. Dask missing or the scheduler unreachable: a :class:`MonteCarloError` in one line."""
    if address is not None:
        try:
            address = scheduler_address(address)
        except ArgumentError as exc:
            raise ArgumentError(f"--address {exc}") from None

    def connect() -> Any:
        try:
            from dask.distributed import Client, LocalCluster
        except ImportError:
            raise MonteCarloError(_NO_DASK) from None
        if address is None:
            with _sigint_ignored():  # the cluster's processes ignore Ctrl-C: the command closes the cluster itself
                # no log on the terminal: a failing chunk is reported by the campaign itself, and stopping the
                # command cancels chunks and cuts heartbeats, which Dask would log as warnings and errors
                return Client(LocalCluster(n_workers=workers, threads_per_worker=1, dashboard_address=None,
                                           silence_logs=logging.CRITICAL))
        try:
            return Client(address, timeout=10)
        except (OSError, TimeoutError, ValueError) as exc:
            raise MonteCarloError(f"--address {address}: cannot reach a Dask scheduler there ({_describe(exc)}); "
                                  f"expected a running Dask scheduler at {_SCHEDULER_FORMS}") from None

    return connect
