"""The ``fdisyn`` command line.

::

    fdisyn design SPEC --out DIR [--design NAME] [--option KEY=VALUE ...]
    fdisyn codegen DIR
    fdisyn replay DIR IN.csv OUT.csv
    fdisyn simulate SPEC --scenario NAME --seed N --out TRACE.csv [--option KEY=VALUE ...]
    fdisyn evaluate SPEC --design NAME --runs N --out METRICS.json [--option KEY=VALUE ...] [MONTE CARLO]
    fdisyn report SPEC [--runs N] [MONTE CARLO]
    fdisyn reproduce [SPEC ...] [--runs N] [MONTE CARLO]
    fdisyn bench [SPEC ...] [--sdp] [--out reports/bench.md] [--monte-carlo [--mc-runs N] [--rss-runs N,…]]
    fdisyn list
    fdisyn methods [NAME] [--option PATTERN] [--plant-kind KIND]
    fdisyn example [NAME [--out PATH] [--force]] [--reference]
    fdisyn --version

``MONTE CARLO`` is ``[--workers N] [--scheduler local|dask] [--address
tcp://HOST:PORT]``: the runs spread over N local processes (default: every
core; more than the cores is run as that many, said in one line), or over a
Dask cluster (the scheduler at ``--address``, else a local one of N
processes). ``fdisyn --quiet <command>`` (or ``--quiet`` anywhere after the
command) shows no progress bar (there is none either when stderr is not a
terminal) and no note. Every whole-number
argument (``--runs``, ``--seed``, ``--workers``, ``--mc-runs``,
``--rss-runs``) is the digits 0–9 alone: no sign, ``_``, blank or other
script's digits.

``SPEC`` is a built-in problem name (``fdisyn list``) or the path of a TOML
plant file (``fdisyn example --reference``); ``fdisyn <command> --help`` describes every
argument and shows examples. Errors a user can act on end the command with
status 2 and one line on stderr, ``fdisyn <command>: error: …``, naming what
is wrong and what was expected: every :class:`FdisynError` (see
:mod:`fdisyn.runtime.errors`), every usage error (argparse's own messages
included, without the usage block), and an ``OSError`` met while reading or
writing a path the user named (a file given as a directory, no permission, a
full disk), and a design package missing from a runtime-only installation
(the line names it and the extra, ``fdisyn[design]``, that installs it:
``replay``, ``example`` and ``--version`` need NumPy alone). Anything else
is a bug: an :class:`InternalError` or any other exception ends with status
3 and one line, ``fdisyn <command>: internal error: … — please report;
FDISYN_DEBUG=1 shows the traceback`` (with
``FDISYN_DEBUG=1`` in the environment the traceback is printed before it).
Ctrl-C ends every command with status 130 and one line, ``fdisyn <command>:
interrupted``, after the Monte Carlo's worker processes are ended; SIGTERM
likewise with status 143 and ``fdisyn <command>: terminated``. A reader that
closes the command's standard output early (``| head``) ends it with status
141 (128 + SIGPIPE) and nothing on stderr.
"""

from __future__ import annotations

import argparse
import errno
import fnmatch
import json
import math
import os
import re
import select
import signal
import sys
import textwrap
import threading
import traceback
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any, NoReturn

from fdisyn import __version__
from fdisyn.app import DESIGN_EXTRA, WORKDIR, missing_design_package
from fdisyn.runtime.errors import ArgumentError, FdisynError, FileError, InternalError
from fdisyn.runtime.names import shown

__all__ = ["main"]

_DISK_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS, errno.EIO}
"""Write failures that carry no file name (a full disk, a quota, a read-only or
failing file system): they can only concern the files being written."""


def _options(pairs: Sequence[str] | None) -> dict[str, Any]:
    """``--option KEY=VALUE`` pairs; each value is JSON (``1e-3``, ``[1, 2]``,
    ``"x"``) or, when it is not valid JSON, the plain string (``parameters=paper``).

    Only the syntax is checked here; the problem validates each value against
    the option's type and domain (:meth:`~fdisyn.simulation.problem.Problem.check_options`).
    An object or a list is data, read strictly (:func:`~fdisyn.runtime.jsondata.parse_json_data`):
    a key repeated in one of its objects (JSON would keep the last) is refused naming the option.
    """
    from fdisyn.runtime.jsondata import parse_json_data

    out: dict[str, Any] = {}
    for pair in pairs or []:
        k, eq, v = pair.partition("=")
        k = k.strip()
        if not eq or not k:
            raise ArgumentError(f"--option expects KEY=VALUE, got {pair!r}")
        if k in out:
            raise ArgumentError(f"--option {k} is given twice; give each option once")
        try:
            out[k] = json.loads(v)
        except (json.JSONDecodeError, RecursionError):  # RecursionError: JSON nested too deep to be an option value
            out[k] = v
            continue
        if isinstance(out[k], (dict, list)):
            out[k] = parse_json_data(v, f"--option {k}", "an option value", error=ArgumentError)
    return out


_DIGITS = re.compile(r"[0-9]+")
"""A whole number on the command line: ASCII digits alone (no sign, blank, ``_``, or other script's digits, which
``int()`` would read)."""


def _whole(text: str, least: int, what: str) -> int:
    """A whole-number argument: ``text`` in the digits 0–9 alone, at least ``least``, else argparse's one-line error."""
    if _DIGITS.fullmatch(text) is None:
        raise argparse.ArgumentTypeError(f"expected {what} written in the digits 0–9 alone, got {shown(text)}")
    try:
        value = int(text)
    except ValueError:  # more digits than Python converts (sys.get_int_max_str_digits)
        raise argparse.ArgumentTypeError(f"expected {what}, got a number of {len(text)} digits") from None
    if value < least:
        raise argparse.ArgumentTypeError(f"expected {what}, got {shown(text)}")
    return value


def _runs(text: str) -> int:
    """``--runs``: Monte Carlo runs per scenario, a whole number ≥ 1 (0 is not "the default")."""
    return _whole(text, 1, "a whole number of runs ≥ 1")


def _run_list(text: str) -> list[int]:
    """``--rss-runs``: comma-separated run counts, each ≥ 1."""
    return [_runs(x.strip()) for x in text.split(",")]


def _workers(text: str) -> int:
    """``--workers``: processes running the Monte Carlo, a whole number ≥ 1."""
    return _whole(text, 1, "a whole number of worker processes ≥ 1")


def _address(text: str) -> str:
    """``--address``: a Dask scheduler's address (:func:`~fdisyn.evaluation.campaign.scheduler_address`), checked
    before anything runs or connects."""
    from fdisyn.evaluation.campaign import scheduler_address

    try:
        return scheduler_address(text)
    except FdisynError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _seed(text: str) -> int:
    """``--seed``: a whole number ≥ 0 (NumPy's generators take non-negative seeds only)."""
    return _whole(text, 0, "a whole number ≥ 0 (NumPy seeds are non-negative)")


def _under(name: str | bytes | int | None, root: Path) -> bool:
    if not isinstance(name, (str, bytes)):
        return False
    p = Path(os.fsdecode(name)).absolute()
    return p == root or root in p.parents


@contextmanager
def _user_paths(expected: str, *paths: tuple[str, str | Path]) -> Iterator[None]:
    """Report an ``OSError`` about a path the user named (or a full disk while writing) as one line.

    ``paths`` are ``(option, path)`` pairs, e.g. ``("--out", "motor")``;
    the line names the option and path concerned and what was ``expected``.
    An ``OSError`` about any other file is not the user's input and propagates
    unchanged: :func:`main` reports it as a bug (status 3).
    """
    roots = [(opt, str(path), Path(path).absolute()) for opt, path in paths]
    try:
        yield
    except FdisynError:
        raise
    except OSError as exc:
        hit = [(o, p) for o, p, r in roots if _under(exc.filename, r) or _under(exc.filename2, r)]
        if not hit and not (exc.filename is None and exc.errno in _DISK_ERRNOS):
            raise
        label = " / ".join(f"{o} {p}" for o, p in (hit or [(o, p) for o, p, _ in roots]))
        detail = f" ({exc.filename})" if exc.filename is not None and str(exc.filename) != hit[0][1] else ""
        raise FileError(f"{label}: {exc.strerror or exc}{detail}; expected {expected}") from exc


def _output_dir(path: str, option: str) -> Path:
    """``path`` as a directory fdisyn can write in or create, checked before any work.

    Nothing is created here (a command that fails later leaves no empty
    folder behind): the nearest existing ancestor must be a directory that is
    writable; the writers create what is missing.
    """
    d = Path(path)
    if d.exists() and not d.is_dir():
        raise FileError(f"{option} {path} is a file: expected a directory")
    probe = d.absolute()
    while not probe.exists():
        probe = probe.parent
    if not probe.is_dir():
        raise FileError(f"{option} {path}: {probe} is a file, so the directory cannot be created; expected a directory path")
    if not os.access(probe, os.W_OK | os.X_OK):
        what = "write in it" if probe == d.absolute() else f"create it in {probe}"
        raise FileError(f"{option} {path}: no permission to {what}; expected a writable directory")
    return d


def _output_file(path: str, option: str) -> Path:
    """``path`` as a file that can be written: not a directory, in a writable directory."""
    f = Path(path)
    if f.is_dir():
        raise FileError(f"{option} {path} is a directory: expected a file name")
    if f.exists():  # an existing file (or device) only needs to be writable itself
        if not os.access(f, os.W_OK):
            raise FileError(f"{option} {path}: no permission to write it; expected a writable file")
    else:
        _output_dir(str(f.parent), f"the directory of {option}")
    return f


def _problem(spec: str):  # noqa: ANN202 - Problem
    from fdisyn.simulation.plant_file import load_spec

    return load_spec(spec)


def _cmd_design(a: argparse.Namespace) -> None:
    from fdisyn.runtime.gainfile import write_gain_file
    from fdisyn.synthesis.kinds import get_kind

    opts = _options(a.option)
    out = _output_dir(a.out, "--out")
    prob = _problem(a.spec)
    gf = prob.design(a.design, **opts)
    with _user_paths("a writable directory with room for gains.json", ("--out", out)):
        path = write_gain_file(gf, out / "gains.json")
    print(f"wrote {path} ({gf.name}: {get_kind(gf.kind).describe(gf)}, certificate passed)")
    from fdisyn.reporting.budget import budget_line
    from fdisyn.numerics.account import account_lines

    print(budget_line(gf))

    print("\n".join(account_lines(gf.account, get_kind(gf.kind).account_note)))


def _cmd_codegen(a: argparse.Namespace) -> None:
    from fdisyn.codegen.library import codegen

    if Path(a.dir).exists() and not Path(a.dir).is_dir():
        raise FileError(f"DIR {a.dir} is a file: expected the directory holding gains.json (fdisyn design --out DIR)")
    with _user_paths("a writable directory holding gains.json", ("DIR", a.dir)):
        res = codegen(a.dir, precision=a.precision)
    single = " (single precision)" if a.precision == "single" else ""
    print(f"wrote {res.c_dir}/, {res.library}, {res.replay}{single}")


def _cmd_replay(a: argparse.Namespace) -> None:
    """Stream IN.csv through DIR's compiled diagnoser into OUT.csv, as ``DIR/replay`` does.

    Bad data is an ``FdisynError`` (status 2, one line, from ``main``); a file
    the system refuses to read or write ends with status 1 and one line, the
    statuses and messages of the C program.
    """
    from fdisyn.runtime.monitor import Monitor
    from fdisyn.runtime.trace import replay_csv

    mon = Monitor.from_directory(a.dir, backend="compiled")
    st = mon.gf.step
    try:
        samples, skipped = replay_csv(mon.run, a.input, a.output, inputs=mon.gf.inputs, outputs=mon.gf.outputs, nj=st.nj, nr=st.nr)
    except FdisynError:
        raise
    except OSError as exc:
        print(f"fdisyn replay: error: {exc.strerror or exc}", file=sys.stderr)
        raise SystemExit(1) from None
    print(f"replay: {samples} samples, {skipped} with non-finite values skipped", file=sys.stderr)


def _cmd_simulate(a: argparse.Namespace) -> None:
    from fdisyn.runtime.trace import write_trace

    opts = _options(a.option)
    out = _output_file(a.out, "--out")
    prob = _problem(a.spec)
    tr = prob.run(a.scenario, [a.seed], **opts).trace(0)
    with _user_paths("a writable file with room for the trace", ("--out", out)):
        write_trace(tr, out)
    print(f"wrote {a.out}: {len(tr.t)} samples of scenario {a.scenario!r}, seed {a.seed}")


@contextmanager
def _monte_carlo(a: argparse.Namespace) -> Iterator[dict[str, Any]]:
    """The ``evaluate`` keywords of ``--workers``, ``--scheduler`` and ``--address``; a Dask client is closed after."""
    from fdisyn.evaluation.campaign import dask_client, local_cores

    if a.address is not None and a.scheduler != "dask":
        raise ArgumentError(f"--address {a.address} needs --scheduler dask")
    if a.address is not None and a.workers is not None:
        raise ArgumentError(
            f"--workers {a.workers} with --address {a.address}: the scheduler's cluster has its own workers; "
            "give --workers for local processes or a local Dask cluster only"
        )
    cores = local_cores()
    workers = a.workers
    if workers is not None and workers > cores:
        if not a.quiet:
            print(f"fdisyn {a.command}: note: --workers {workers} is more than the {cores} cores this process may run on; "
                  f"running {cores} worker processes", file=sys.stderr)
        workers = cores
    if a.scheduler != "dask":
        yield {"workers": workers}
        return
    client = dask_client(a.address, workers or cores)()
    try:
        yield {"client": client}
    finally:
        cluster = client.cluster if a.address is None else None
        client.close()
        if cluster is not None:
            cluster.close()


def _workdir(a: argparse.Namespace, problem: str, design: str) -> Path:
    return Path(a.workdir) / problem / design


def _cmd_evaluate(a: argparse.Namespace) -> None:
    from fdisyn.evaluation.built import build
    from fdisyn.evaluation.evaluate import evaluate
    from fdisyn.evaluation.progress import bar

    opts = _options(a.option)
    out = _output_file(a.out, "--out")
    _output_dir(a.workdir, "--workdir")
    prob = _problem(a.spec)
    prob.check_options(opts)  # refuse a bad option before designing and compiling
    design = a.design or prob.default_design
    with _monte_carlo(a) as where:
        with bar(1, f"{prob.name} {design}: design, export, compile", "design") as shown:
            with _user_paths("a writable directory with room for the build", ("--workdir", a.workdir)):
                built = {design: build(prob, design, _workdir(a, prob.name, design), **opts)}
            shown.update(1)
        ev = evaluate(prob, built, runs=a.runs, seed0=a.seed, source=a.spec, **where, **opts)
    doc = ev.to_dict()
    doc["gain_file"] = built[design].gain_file.name
    with _user_paths("a writable file with room for the metrics", ("--out", out)):
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    print(f"wrote {a.out}")


def _cmd_report(a: argparse.Namespace) -> None:
    from fdisyn.app.pipeline import reproduce_problem

    _output_dir(a.reports, "--reports")
    _output_dir(a.workdir, "--workdir")
    prob = _problem(a.spec)
    with _monte_carlo(a) as where, _user_paths(
        "writable directories with room for the report", ("--reports", a.reports), ("--workdir", a.workdir)
    ):
        out = reproduce_problem(
            prob, runs=a.runs, reports=Path(a.reports), workdir=Path(a.workdir), variants=a.variants, source=a.spec, **where
        )
    print(f"wrote {out}")


def _cmd_reproduce(a: argparse.Namespace) -> None:
    from fdisyn.app.pipeline import reproduce_problem
    from fdisyn.simulation.problem import problem_names

    _output_dir(a.reports, "--reports")
    _output_dir(a.workdir, "--workdir")
    specs = a.specs or problem_names()
    problems = [_problem(spec) for spec in specs]  # every SPEC is checked before the long run
    with _monte_carlo(a) as where:
        for spec, prob in zip(specs, problems, strict=True):
            with _user_paths("writable directories with room for the reports", ("--reports", a.reports), ("--workdir", a.workdir)):
                out = reproduce_problem(
                    prob, runs=a.runs, reports=Path(a.reports), workdir=Path(a.workdir), variants=a.variants, source=spec, **where
                )
            print(f"wrote {out}")
    from fdisyn.app.pipeline import phase_table
    from fdisyn.reporting.page import summary_table

    print(summary_table(Path(a.reports), [p.name for p in problems]))
    print("time per problem and phase (s):\n" + phase_table([p.name for p in problems]))
    if not a.specs and a.runs is None and a.variants is None:  # the main job itself: its figures go beside the bench's
        from fdisyn.app.bench import record_main_job

        print(f"wrote {record_main_job(Path(a.reports) / 'bench.md', [p.name for p in problems])}")


def _cmd_bench(a: argparse.Namespace) -> None:
    from fdisyn.app.bench import run_bench, run_monte_carlo_bench
    from fdisyn.simulation.problem import problem_names

    out = _output_file(a.out, "--out")
    _output_dir(a.workdir, "--workdir")
    if a.monte_carlo:
        if a.specs:
            raise ArgumentError("--monte-carlo measures wind_turbine/kalman_uio alone; give no SPEC with it")
        with _user_paths("a writable file and directory with room for the benchmark", ("--out", out), ("--workdir", a.workdir)):
            path = run_monte_carlo_bench(out=out, workdir=Path(a.workdir), runs=a.mc_runs, rss_runs=a.rss_runs)
        print(f"wrote {path}")
        return
    specs = a.specs or problem_names()
    with _user_paths("a writable file and directory with room for the benchmark", ("--out", out), ("--workdir", a.workdir)):
        path = run_bench([_problem(s) for s in specs], out=out, workdir=Path(a.workdir), sdp=a.sdp or not a.specs, monte_carlo=not a.specs,
                         scaling=a.scaling or not a.specs)
    print(f"wrote {path}")


def _cmd_list(a: argparse.Namespace) -> None:
    from fdisyn.simulation.problem import get_problem, problem_names

    for name in problem_names():
        p = get_problem(name)
        print(f"{name}: {p.title}")
        print(f"  designs:   {', '.join(p.designs)} (default {p.default_design})")
        print(f"  scenarios: {', '.join(p.scenarios)}")
        if p.options:
            print(f"  options:   {', '.join(f'{k}={v!r}' for k, v in p.options.items())}")


def _cmd_example(a: argparse.Namespace) -> None:
    from fdisyn.app.examples import example_names, example_title, plant_file_reference, write_example

    if a.reference:
        if a.name is not None or a.out is not None or a.force:
            raise ArgumentError("--reference takes no NAME, --out or --force; expected fdisyn example --reference alone")
        sys.stdout.write(plant_file_reference())
        return
    if a.name is None:
        if a.out is not None or a.force:
            raise ArgumentError("--out and --force need the NAME of an example; fdisyn example lists them")
        for name in example_names():
            print(f"{name}: {example_title(name)}")
        return
    out = _output_file(f"{a.name}.toml" if a.out is None else a.out, "--out")
    with _user_paths("a writable file name", ("--out", out)):
        path = write_example(a.name, out, force=a.force)
    print(f"wrote {path}: the example plant file {a.name!r}; fdisyn design {path} --out DIR designs it")


def _frequencies(text: str) -> list[float]:
    """``--frequencies F,…``: numbers in rad/s."""
    out = []
    for part in text.split(","):
        try:
            out.append(float(part))
        except ValueError:
            raise ArgumentError(f"--frequencies {shown(text)}: {shown(part.strip())} is not a number; expected rad/s values such as 0,0.5") from None
    return out


def _cmd_analyse(a: argparse.Namespace) -> None:
    from fdisyn.synthesis.nullspace import analyse_gaps
    from fdisyn.synthesis.structure import analyse_structure

    opts = _options(a.option)
    prob = _problem(a.spec)
    if prob.model is None:
        raise ArgumentError(f"{a.spec}: the structure analysis needs a linear plant; {prob.name!r} is nonlinear (linearise it at its operating point)")
    freqs = _frequencies(a.frequencies) if a.frequencies is not None else None
    if freqs is not None and not a.strong:
        raise ArgumentError("--frequencies sets the strong structure's frequencies: add --strong, or omit --frequencies")
    plant = prob.model(**prob.check_options(opts))
    res = analyse_gaps(analyse_structure(plant, kind="strong" if a.strong else "weak", frequencies=freqs), plant, pole=a.pole)
    if a.json:
        print(json.dumps({"problem": prob.name, **res.to_dict()}, indent=1))
        return
    at = f" at {', '.join(f'{w:g}' for w in res.frequencies)} rad/s" if res.kind == "strong" else ""
    print(f"{prob.name}: {len(res.faults)} faults, {res.kind} structure{at}: {len(res.rows)} achievable specification(s) "
          f"(1: the residual sees the fault; 0: decoupled from it); gap: min_j ‖R_fj‖∞ / ‖R_w‖∞ of the least-order filter "
          f"with its poles at {res.pole:g}")
    header = [*res.faults, "least order", "gap", "decouples"]
    rows = [[*(str(v) for v in row), str(lo), "∞" if math.isinf(g) else f"{g:.4g}", ", ".join(dec) or "—"]
            for row, lo, g, dec in zip(res.rows, res.least_orders, res.gaps or (), res.decoupled, strict=True)]
    widths = [max(len(str(c)) for c in col) for col in zip(header, *rows, strict=True)]
    for row in [header, ["-" * w for w in widths], *rows]:
        print("  ".join(c.rjust(w) if i < len(res.faults) + 2 else c for i, (c, w) in enumerate(zip(row, widths, strict=True))).rstrip())


def _cmd_methods(a: argparse.Namespace) -> None:
    from fdisyn.synthesis.registry import PLANT_KINDS, REQUIRED, all_methods, get_method

    methods = [get_method(a.name)] if a.name is not None else all_methods()
    if a.plant_kind is not None:
        if a.plant_kind not in PLANT_KINDS:
            raise ArgumentError(f"--plant-kind {shown(a.plant_kind)}: expected one of {', '.join(PLANT_KINDS)}")
        methods = [m for m in methods if m.plant_kind == a.plant_kind]
        if not methods:
            raise ArgumentError(
                f"method {a.name!r} designs for {get_method(a.name).plant_kind} plants, not {a.plant_kind}; "
                f"expected fdisyn methods {a.name} alone, or fdisyn methods --plant-kind {a.plant_kind}"
            )

    def default(o: Any) -> str:
        return "required" if o.default is REQUIRED else repr(o.default)

    if a.name is None and a.option is None:  # the listing: one line per method (NAME or --option: the option tables)
        for m in methods:
            print(f"{m.name} ({m.plant_kind} plant): {m.summary}")
        return
    pattern = "*" if a.option is None else a.option.lower()

    def matches(name: str) -> bool:
        return fnmatch.fnmatchcase(name.lower(), pattern) or pattern in name.lower()

    chosen = [(m, [o for o in m.options if matches(o.name)]) for m in methods]
    if not any(opts for _, opts in chosen):
        names = sorted({o.name for m in methods for o in m.options})
        raise ArgumentError(f"--option {shown(a.option)} matches no option; expected a name or a pattern such as 'P_*' matching one of {', '.join(names)}")
    width = max(len("option"), *(len(o.name) for _, opts in chosen for o in opts))
    dwidth = max(len("default"), *(len(default(o)) for _, opts in chosen for o in opts))
    indent = " " * (4 + width + 2 + dwidth + 2)
    first = True
    for m, opts in chosen:
        if not opts:
            continue
        if not first:
            print()
        first = False
        print(f"{m.name} ({m.plant_kind} plant): {m.summary}")
        print(f"  plant: {PLANT_KINDS[m.plant_kind]}")
        print(f"  reference: {m.reference}")
        print(f"    {'option':<{width}}  {'default':<{dwidth}}  expected / meaning")
        for o in opts:
            head = f"    {o.name:<{width}}  {default(o):<{dwidth}}  "
            doc = o.doc + (f" (a plant file: {o.plant_file})" if o.plant_file else "")
            for text, first_indent in ((o.expected, head), (doc, indent)):  # words stay whole: formulas keep their hyphens
                print(textwrap.fill(text, 119, initial_indent=first_indent, subsequent_indent=indent, break_on_hyphens=False, break_long_words=False))


class _Parser(argparse.ArgumentParser):
    """argparse with the command line's error format: one line, status 2.

    argparse prints the usage block and then ``prog: error: message``; here
    only the last line is printed (``--help`` still shows the usage), so that
    a usage error looks like every other error of the command.
    """

    def error(self, message: str) -> NoReturn:
        print(f"{self.prog}: error: {message} (see {self.prog} --help)", file=sys.stderr)
        raise SystemExit(2)


_SPEC = "a built-in problem (fdisyn list shows them) or the path of a TOML plant file"


def _examples(*lines: str) -> str:
    return "Examples:\n" + "\n".join(f"  {ln}" for ln in lines)


def _parser() -> argparse.ArgumentParser:
    ap = _Parser(
        prog="fdisyn",
        description="Design FDI diagnosers as optimisation problems, export them as C, judge them.",
        epilog=_examples(
            "fdisyn list",
            "fdisyn example dc_motor",
            "fdisyn design dc_motor.toml --out motor",
            "fdisyn codegen motor",
            "fdisyn design wind_turbine --help",
        ),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ap.add_argument("--version", action="version", version=f"fdisyn {__version__}", help="print the version of fdisyn and exit")
    quiet_help = "no progress bars (there are none either when stderr is not a terminal)"
    ap.add_argument("--quiet", action="store_true", help=quiet_help)
    sub = ap.add_subparsers(dest="command", required=True, metavar="command", help="the command to run; fdisyn <command> --help describes it")

    def command(name: str, summary: str, description: str, *examples: str) -> argparse.ArgumentParser:
        p = sub.add_parser(
            name,
            help=summary,
            description=textwrap.fill(description, 79),  # the formatter keeps the epilog's lines, so wrap here
            epilog=_examples(*examples),
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        # --quiet after the command too; SUPPRESS: absent there, it leaves the value given before the command
        p.add_argument("--quiet", action="store_true", default=argparse.SUPPRESS, help=quiet_help)
        return p

    def opt(p: argparse.ArgumentParser) -> None:
        p.add_argument(
            "--option",
            action="append",
            metavar="KEY=VALUE",
            help="a problem option, its value as JSON (P_f=1e-4, persistence=3) or a plain word (parameters=paper); "
            "repeatable; fdisyn list shows each problem's options",
        )

    def work(p: argparse.ArgumentParser) -> None:
        p.add_argument("--workdir", default=str(WORKDIR), help=f"where designs are built and compiled (default: {WORKDIR})")

    def monte_carlo(p: argparse.ArgumentParser) -> None:
        p.add_argument(
            "--workers", type=_workers, default=None, metavar="N",
            help="local processes running the Monte Carlo, ≥ 1 (default: every core; 1: this process only); for a Dask "
            "scheduler without an address, the processes of a local Dask cluster; at most the cores this process may "
            "run on (more is run as that many, said in one line on stderr) and never more than the campaign's chunks",
        )
        p.add_argument(
            "--scheduler", choices=("local", "dask"), default="local",
            help="where the runs go: local processes (default) or a Dask cluster (pip install 'fdisyn[dask]')",
        )
        p.add_argument(
            "--address", type=_address, default=None, metavar="tcp://HOST:PORT",
            help="the Dask scheduler to join (with --scheduler dask): tcp://HOST:PORT (HOST:PORT alone is tcp), or "
            "tls://HOST:PORT with the client's certificate in Dask's configuration (DASK_DISTRIBUTED__COMM__TLS__CA_FILE, "
            "…__CLIENT__CERT, …__CLIENT__KEY); other transports (ucx, inproc, ws) are refused",
        )

    p = command(
        "design",
        "design a diagnoser and write DIR/gains.json",
        "Design a diagnoser of SPEC, verify it against its certificate and write the gain file DIR/gains.json.",
        "fdisyn design wind_turbine --out wt",
        "fdisyn design wind_turbine --design uio_pole_placement --out wt_poles",
        "fdisyn design dc_motor.toml --out motor --option P_f=1e-4",
    )
    p.add_argument("spec", metavar="SPEC", help=_SPEC)
    p.add_argument("--out", required=True, metavar="DIR", help="the directory to write gains.json in (created if missing)")
    p.add_argument("--design", default=None, metavar="NAME", help="which of the problem's designs (default: the problem's default)")
    opt(p)
    p.set_defaults(fn=_cmd_design)

    p = command(
        "codegen",
        "generate and compile the C step of DIR/gains.json",
        "Generate the C step of DIR/gains.json (DIR/c/), compile the shared library DIR/lib<name>.so (.dylib on macOS, "
        ".dll on Windows) with its build manifest and the replay program DIR/replay; the C compiler is $CC (default gcc).",
        "fdisyn codegen motor",
        "CC='gcc -m32' fdisyn codegen motor",
        "fdisyn codegen motor --precision single",
    )
    p.add_argument("dir", metavar="DIR", help="the directory holding gains.json (fdisyn design --out DIR)")
    p.add_argument(
        "--precision", choices=("double", "single"), default="double",
        help="what the step computes in: double (default) or single (float, for a target without a double-precision FPU)",
    )
    p.set_defaults(fn=_cmd_codegen)

    p = command(
        "replay",
        "run DIR's compiled diagnoser over a trace CSV",
        "Stream IN.csv through the compiled diagnoser of DIR into OUT.csv (t, alarm, isolated, J0…, r0…), "
        "byte for byte what DIR/replay writes; the runtime reference's \"Replay CSV grammar\" (runtime/REFERENCE.md) is the input format.",
        "fdisyn replay motor trace.csv alarms.csv",
    )
    p.add_argument("dir", metavar="DIR", help="the directory fdisyn codegen built (gains.json and lib<name>.so)")
    p.add_argument("input", metavar="IN.csv", help="the trace: a header row with t and every input and output of the diagnoser")
    p.add_argument("output", metavar="OUT.csv", help="where to write the decisions, statistics and residuals (replaced when complete)")
    p.set_defaults(fn=_cmd_replay)

    p = command(
        "simulate",
        "simulate one run of a scenario to a trace CSV",
        "Simulate one run of a scenario of SPEC and write its trace (t, inputs, outputs, the truth, fault_active) as CSV.",
        "fdisyn simulate dc_motor.toml --scenario speed_sensor_offset --seed 1 --out trace.csv",
        "fdisyn simulate wind_turbine --scenario fault_free --out trace.csv --option parameters=paper",
    )
    p.add_argument("spec", metavar="SPEC", help=_SPEC)
    p.add_argument("--scenario", required=True, metavar="NAME", help="the scenario to run (fault_free, or one fdisyn list shows)")
    p.add_argument("--seed", type=_seed, default=0, help="seed of the run, a whole number ≥ 0 (default 0)")
    p.add_argument("--out", required=True, metavar="TRACE.csv", help="the CSV file to write")
    opt(p)
    p.set_defaults(fn=_cmd_simulate)

    p = command(
        "evaluate",
        "Monte Carlo metrics of one design over every scenario",
        "Design, export and compile one design of SPEC, run it over --runs simulated runs of every scenario and write "
        "the metrics (false-alarm rate, missed detections, detection delay, isolation accuracy) as JSON.",
        "fdisyn evaluate wind_turbine --design kalman_uio --runs 20 --out metrics.json",
        "fdisyn evaluate dc_motor.toml --runs 5 --seed 100 --out motor.json --workdir /tmp/fdisyn",
        "fdisyn evaluate wind_turbine --runs 10000 --workers 2 --out metrics.json",
        "fdisyn evaluate wind_turbine --runs 10000 --scheduler dask --address tcp://10.0.0.5:8786 --out metrics.json",
    )
    p.add_argument("spec", metavar="SPEC", help=_SPEC)
    p.add_argument("--design", default=None, metavar="NAME", help="which of the problem's designs (default: the problem's default)")
    p.add_argument("--runs", type=_runs, default=100, help="Monte Carlo runs per scenario, ≥ 1 (default 100)")
    p.add_argument(
        "--seed", type=_seed, default=0,
        help="the campaign's seed, ≥ 0 (default 0): run i of the s-th scenario is seeded by SeedSequence([seed, s, i])",
    )
    p.add_argument("--out", required=True, metavar="METRICS.json", help="the JSON file to write")
    opt(p)
    work(p)
    monte_carlo(p)
    p.set_defaults(fn=_cmd_evaluate)

    for name, fn, many in (("report", _cmd_report, False), ("reproduce", _cmd_reproduce, True)):
        p = command(
            name,
            "design, verify, export, compile, simulate, evaluate and report" + (" every problem" if many else ""),
            ("Run the whole pipeline for each SPEC (default: every built-in problem) and write " if many else "Run the whole pipeline for SPEC and write ")
            + "REPORTS/<problem>/index.html: the designs and their certificates, the agreement of the generated C with "
            "the Python references, Monte Carlo metrics and figures.",
            *(("fdisyn reproduce", "fdisyn reproduce wind_turbine dc_motor.toml --runs 5 --reports /tmp/reports")
              if many else ("fdisyn report sampled_data_example --runs 10", "fdisyn report ship.toml --reports /tmp/reports"))
        )
        if many:
            p.add_argument("specs", nargs="*", metavar="SPEC", help=_SPEC + "; none: every built-in problem")
        else:
            p.add_argument("spec", metavar="SPEC", help=_SPEC)
        p.add_argument("--runs", type=_runs, default=None, help="Monte Carlo runs per scenario, ≥ 1 (default: the problem's)")
        p.add_argument("--reports", default="reports", help="report folder (default: reports)")
        p.add_argument(
            "--variants",
            type=lambda s: [v.strip() for v in s.split(",") if v.strip()],
            default=None,
            metavar="LABEL,…",
            help="only these report variants, by label ('default' is the main one; default: all)",
        )
        work(p)
        monte_carlo(p)
        p.set_defaults(fn=fn)

    p = command(
        "bench",
        "time the compiled step against the NumPy reference",
        "Time the compiled step of each SPEC's designs (per sample, per block) against the NumPy reference and write "
        "the table as Markdown; the full bench (no SPEC) or --sdp adds the SDP solve times of the LMI toolkit, and --scaling the "
        "steps of random plants of 10 to 200 states.",
        "fdisyn bench",
        "fdisyn bench ship_propulsion --out /tmp/bench.md",
        "fdisyn bench wind_turbine --sdp",
        "fdisyn bench turbofan --scaling --out /tmp/bench.md",
        "fdisyn bench --monte-carlo --out reports/bench_monte_carlo.md",
    )
    p.add_argument("specs", nargs="*", metavar="SPEC", help=_SPEC + "; none: every built-in problem")
    p.add_argument(
        "--sdp", action="store_true", help="also time the SDPs of the LMI toolkit, n = 2 to 32 (about ten minutes; always done without SPEC)"
    )
    p.add_argument(
        "--scaling", action="store_true",
        help="also design, compile and time a bank of 10 UIOs on random plants of 10, 50, 100 and 200 states (a few "
        "minutes; always done without SPEC)",
    )
    p.add_argument("--out", default="reports/bench.md", help="the Markdown file to write (default: reports/bench.md)")
    p.add_argument(
        "--monte-carlo", action="store_true",
        help="only the Monte Carlo throughput section: plant steps per second of the wind turbine's kalman_uio bank on "
        "one core and on every core, and the peak memory of campaigns of so many runs (see below)",
    )
    p.add_argument("--mc-runs", type=_runs, default=100, metavar="N", help="runs per scenario of the throughput figures (default 100)")
    p.add_argument(
        "--rss-runs", type=_run_list, default=[100, 10_000], metavar="N,…",
        help="runs of the campaigns whose peak memory is measured (default 100,10000)",
    )
    work(p)
    p.set_defaults(fn=_cmd_bench)

    p = command("list", "list the built-in problems", "List the built-in problems with their designs, scenarios and options.", "fdisyn list")
    p.set_defaults(fn=_cmd_list)

    p = command(
        "methods",
        "list the design methods (one line each); with NAME, its reference and options",
        "List every registered design method, one line each: its name, the plant it designs for and its summary. A "
        "plant file names one in [design].method; Python passes it to fdisyn.design(plant, method=...). With NAME, "
        "that method's reference and option table: each option's name, default, the "
        "values it accepts and its meaning; --option PATTERN keeps the options whose name matches PATTERN (a shell "
        "pattern such as 'P_*', or a part of the name, in any case), --plant-kind KIND the methods for one plant "
        "kind (linear, continuous, nonlinear).",
        "fdisyn methods",
        "fdisyn methods kalman_uio",
        "fdisyn methods nafdf --option window",
        "fdisyn methods --option arl0",
        "fdisyn methods --plant-kind continuous",
    )
    p.add_argument("name", nargs="?", default=None, metavar="NAME", help="the method whose option table to print (fdisyn methods lists them)")
    p.add_argument("--option", default=None, metavar="PATTERN", help="only the options whose name matches PATTERN ('P_*', 'window'), as a table")
    p.add_argument("--plant-kind", default=None, metavar="KIND", help="only the methods for this plant kind: linear, continuous or nonlinear")
    p.set_defaults(fn=_cmd_methods)

    p = command(
        "analyse",
        "which faults the plant's sensors can detect and isolate",
        "Print the achievable fault signatures of SPEC's linear plant: every row of a structure matrix a scalar residual "
        "decoupled from the known and unknown inputs can have (1: it sees the fault; 0: it is decoupled from it), over "
        "the plant's faults (one per sensor, then the component faults), with the least order of a filter achieving "
        "each row, its fault-to-noise gap (Varga's: the smallest H∞ norm over the faults it sees over the H∞ norm "
        "from the plant's noise, for the least-order filter of the largest gap with its poles at --pole) and the faults "
        "it decouples. --strong asks that every fault a row sees has a nonzero response at "
        "--frequencies (rad/s; default 0: constant faults). A continuous plant file is analysed on its exact sampling.",
        "fdisyn analyse wind_turbine",
        "fdisyn analyse dc_motor.toml --strong",
        "fdisyn analyse turbofan --strong --frequencies 0,1 --json",
    )
    p.add_argument("spec", metavar="SPEC", help=_SPEC)
    p.add_argument("--strong", action="store_true", help="the strong structure: nonzero responses at --frequencies (default: the weak one)")
    p.add_argument("--frequencies", default=None, metavar="F,…", help="the strong structure's frequencies in rad/s, comma separated (default 0)")
    p.add_argument("--json", action="store_true", help="print the analysis as JSON (faults, rows with their least orders, gaps, basis sizes and decoupled faults)")
    p.add_argument("--pole", type=float, default=None, metavar="P", help="the filters' poles for the gaps (default 0.5; the plant files are analysed discrete)")
    opt(p)
    p.set_defaults(fn=_cmd_analyse)

    p = command(
        "example",
        "write an example plant file (none: list them)",
        "Write the example plant file NAME (a TOML file to read, change and design) to --out (default NAME.toml in the "
        "current directory); without NAME, list the examples. An existing file is replaced only with --force. "
        "--reference prints the plant-file reference (every key of a plant file, what fdisyn design prints, how the "
        "Monte Carlo runs; installed as PLANT_FILES.md beside the examples).",
        "fdisyn example",
        "fdisyn example dc_motor",
        "fdisyn example ship --out my_ship.toml",
        "fdisyn example --reference > PLANT_FILES.md",
    )
    p.add_argument("name", nargs="?", default=None, metavar="NAME", help="the example to write (fdisyn example lists them)")
    p.add_argument("--out", default=None, metavar="PATH", help="the file to write (default: NAME.toml)")
    p.add_argument("--force", action="store_true", help="replace PATH if it exists")
    p.add_argument("--reference", action="store_true", help="print the plant-file reference (PLANT_FILES.md) instead")
    p.set_defaults(fn=_cmd_example)
    return ap


def _one_line(text: object) -> str:
    """``text`` on one line (a compiler's or solver's message may span several)."""
    return " ".join(str(text).split())


def _stdout_gone() -> bool:
    """Standard output is a pipe whose reader has closed it; if so, it is pointed at the null device, so that the
    interpreter's last flush at exit finds no closed pipe (and prints nothing).

    Returns
    -------
    bool
        Whether standard output has lost its reader (a ``BrokenPipeError`` from elsewhere, such as a worker's
        pipe, leaves it as it is: that one is a bug).
    """
    try:
        fd = sys.stdout.fileno()
        poll = select.poll()
        poll.register(fd, select.POLLOUT)
        gone = any(events & (select.POLLERR | select.POLLHUP) for _, events in poll.poll(0))
    except (AttributeError, OSError, ValueError):  # no descriptor (a test's capture) or no poll (Windows)
        return False
    if gone:
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, fd)
        os.close(null)
    return gone


def _debug() -> bool:
    """``FDISYN_DEBUG`` is set (and not ``0``): an internal error shows its traceback."""
    return os.environ.get("FDISYN_DEBUG", "") not in ("", "0")


REPORT_BLAS = {"OPENBLAS_CORETYPE": "Nehalem", "OPENBLAS_NUM_THREADS": "1"}
"""The BLAS that ``fdisyn reproduce`` and ``fdisyn report`` run on (x86-64): OpenBLAS's Nehalem kernels, which every
x86-64 CPU of the last fifteen years runs, on one thread. OpenBLAS otherwise picks a kernel per CPU (Haswell, Zen,
SkylakeX, …) whose sums round differently: the designs' last digits, and the gain files published in the reports,
would then depend on the machine. The kernel matters little to the main job's time (its matrices are small; the
Monte Carlo runs in compiled C)."""


def pin_report_blas() -> bool:
    """Pin OpenBLAS to :data:`REPORT_BLAS` for this process and its workers, so that the reports come out the same on
    every x86-64 CPU.

    Only before NumPy and SciPy are first imported (OpenBLAS reads its environment when it is loaded): a command run
    by the ``fdisyn`` program; a call of :func:`main` in a process that already imported them keeps their kernel.
    It replaces the user's own ``OPENBLAS_CORETYPE`` for these commands. On other architectures nothing is changed.

    Returns
    -------
    bool
        Whether the kernel was pinned.
    """
    import platform

    if platform.machine().lower() not in ("x86_64", "amd64") or any(m in sys.modules for m in ("numpy", "scipy")):
        return False
    os.environ.update(REPORT_BLAS)
    return True


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command; return its exit status: 0, 2 after a one-line error on stderr, 3 after a bug, 130 after
    Ctrl-C (one line, ``fdisyn <command>: interrupted``), 143 after SIGTERM (``fdisyn <command>: terminated``).

    An :class:`FdisynError` is the user's to act on (status 2); an
    :class:`InternalError` or any other exception is a bug (status 3, one
    line asking for a report; the traceback too when ``FDISYN_DEBUG=1``).
    Warnings raised while the command runs (NumPy, SciPy, CasADi) are held
    back: after an error the error line says what went wrong and they are
    dropped; after success each distinct one is printed as one line
    ``fdisyn <command>: warning: …``.
    """
    try:
        args = _parser().parse_args(argv)
    except SystemExit as exc:  # a usage error (already printed as one line) or --help
        return exc.code if isinstance(exc.code, int) else 2
    if args.command in ("reproduce", "report"):
        pin_report_blas()
    from fdisyn.evaluation.progress import set_quiet

    set_quiet(args.quiet)
    with warnings.catch_warnings(record=True) as caught, _terminate_as_exception():
        warnings.simplefilter("default")
        try:
            args.fn(args)
        except FdisynError as exc:
            if not isinstance(exc, InternalError):
                print(f"fdisyn {args.command}: error: {_one_line(exc)}", file=sys.stderr)
                return 2
            return _internal_error(args.command, exc, str(exc))
        except KeyboardInterrupt:  # Ctrl-C: the workers are ended where they were started, the outputs left as they were
            print(f"fdisyn {args.command}: interrupted", file=sys.stderr)
            return 130
        except _Terminated:  # SIGTERM (kill, timeout, a batch system): the same, with the signal's status
            print(f"fdisyn {args.command}: terminated", file=sys.stderr)
            return 128 + signal.SIGTERM
        except ModuleNotFoundError as exc:
            package = missing_design_package(exc)
            if package is None:
                return _internal_error(args.command, exc, f"{type(exc).__name__}: {exc}")
            print(
                f"fdisyn {args.command}: error: this command needs {package}, which is not installed (a runtime-only "
                f"installation); expected fdisyn's design packages: python3 -m pip install 'fdisyn[{DESIGN_EXTRA}]'",
                file=sys.stderr,
            )
            return 2
        except BrokenPipeError as exc:
            if _stdout_gone():  # the reader went away (fdisyn example --reference | head): as a shell's commands do
                return 128 + getattr(signal, "SIGPIPE", 13)
            return _internal_error(args.command, exc, f"{type(exc).__name__}: {exc}")
        except Exception as exc:  # a bug: one line, never a bare traceback
            return _internal_error(args.command, exc, f"{type(exc).__name__}: {exc}")
    for text in dict.fromkeys(f"{w.category.__name__}: {_one_line(w.message)}" for w in caught):
        print(f"fdisyn {args.command}: warning: {text}", file=sys.stderr)
    return 0


class _Terminated(BaseException):
    """SIGTERM arrived: raised where the command was, so that it stops as after Ctrl-C (its worker processes ended,
    one line); a ``BaseException``, so that no ``except Exception`` takes it for an error."""


def _raise_terminated(signum: int, frame: object) -> None:
    raise _Terminated


@contextmanager
def _terminate_as_exception() -> Iterator[None]:
    """SIGTERM raises :class:`_Terminated` meanwhile (in the main thread only; the previous handler restored after):
    without it the process would die at once and leave its worker processes running."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _internal_error(command: str, exc: BaseException, what: str) -> int:
    if _debug():
        traceback.print_exception(exc, file=sys.stderr)
    print(f"fdisyn {command}: internal error: {_one_line(what)} — please report; FDISYN_DEBUG=1 shows the traceback", file=sys.stderr)
    return 3


if __name__ == "__main__":
    raise SystemExit(main())
