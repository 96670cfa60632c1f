"""The ``fdisyn`` command line.

::

    fdisyn design SPEC --out DIR [--design NAME] [--option KEY=VALUE ...]
    fdisyn codegen DIR
    fdisyn replay DIR IN.csv OUT.csv
    fdisyn simulate SPEC --scenario NAME --seed N --out TRACE.csv [--option KEY=VALUE ...]
    fdisyn evaluate SPEC --design NAME --runs N --out METRICS.json [--option KEY=VALUE ...]
    fdisyn report SPEC [--runs N]
    fdisyn reproduce [SPEC ...] [--runs N]
    fdisyn bench [SPEC ...] [--out reports/bench.md]
    fdisyn list

``SPEC`` is a built-in problem name (``fdisyn list``) or the path of a TOML
plant file (see the README). Errors a user can act on end the command with
status 2 and one line naming what is wrong.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from fdisyn.runtime.errors import FdisynError, SpecError

__all__ = ["main"]


def _options(pairs: Sequence[str] | None) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for pair in pairs or []:
        if "=" not in pair:
            raise SpecError(f"--option expects KEY=VALUE, got {pair!r}")
        k, v = pair.split("=", 1)
        try:
            out[k.strip()] = json.loads(v)
        except json.JSONDecodeError:
            out[k.strip()] = v
    return out


def _problem(spec: str):  # noqa: ANN202 - Problem
    from fdisyn.design.spec import load_spec

    return load_spec(spec)


def _cmd_design(a: argparse.Namespace) -> None:
    from fdisyn.runtime.gainfile import write_gain_file

    prob = _problem(a.spec)
    gf = prob.design(a.design, **_options(a.option))
    path = write_gain_file(gf, Path(a.out) / "gains.json")
    what = f"{len(gf.generators)} generators" if gf.kind == "linear" else f"a {gf.kind} step with {gf.step.nstate} states"
    print(f"wrote {path} ({gf.name}: {what}, certificate passed)")


def _cmd_codegen(a: argparse.Namespace) -> None:
    from fdisyn.design.codegen import codegen

    res = codegen(a.dir)
    print(f"wrote {res.c_dir}/, {res.library}, {res.replay}")


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
    from fdisyn.runtime.trace import Trace, write_trace

    prob = _problem(a.spec)
    batch = prob.run(a.scenario, [a.seed], **_options(a.option))
    extra = {k: np.asarray(v)[0] for k, v in batch.extra.items()}
    extra["fault_active"] = batch.active.astype(float)
    tr = Trace(t=batch.t, inputs=batch.inputs, outputs=batch.outputs, U=batch.U[0], Y=batch.Y[0], extra=extra)
    write_trace(tr, a.out)
    print(f"wrote {a.out}: {len(tr.t)} samples of scenario {a.scenario!r}, seed {a.seed}")


def _workdir(a: argparse.Namespace, problem: str, design: str) -> Path:
    return Path(a.workdir) / problem / design


def _cmd_evaluate(a: argparse.Namespace) -> None:
    from fdisyn.design.evaluate import build, evaluate, progress_printer

    prob = _problem(a.spec)
    opts = _options(a.option)
    say = progress_printer(f"{prob.name}/{a.design or prob.default_design}")
    design = a.design or prob.default_design
    say("designing, exporting and compiling")
    built = {design: build(prob, design, _workdir(a, prob.name, design), **opts)}
    ev = evaluate(prob, built, runs=a.runs, seed0=a.seed, progress=say, **opts)
    doc = ev.to_dict()
    doc["gain_file"] = built[design].gain_file.name
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    print(f"wrote {a.out}")


def _cmd_report(a: argparse.Namespace) -> None:
    from fdisyn.design.pipeline import reproduce_problem

    out = reproduce_problem(_problem(a.spec), runs=a.runs, reports=Path(a.reports), workdir=Path(a.workdir))
    print(f"wrote {out}")


def _cmd_reproduce(a: argparse.Namespace) -> None:
    from fdisyn.design.pipeline import reproduce_problem
    from fdisyn.design.problem import problem_names

    specs = a.specs or problem_names()
    for spec in specs:
        out = reproduce_problem(_problem(spec), runs=a.runs, reports=Path(a.reports), workdir=Path(a.workdir))
        print(f"wrote {out}")


def _cmd_bench(a: argparse.Namespace) -> None:
    from fdisyn.design.bench import run_bench
    from fdisyn.design.problem import problem_names

    specs = a.specs or problem_names()
    out = run_bench([_problem(s) for s in specs], out=Path(a.out), workdir=Path(a.workdir))
    print(f"wrote {out}")


def _cmd_list(a: argparse.Namespace) -> None:
    from fdisyn.design.problem import get_problem, problem_names

    for name in problem_names():
        p = get_problem(name)
        print(f"{name}: {p.title}")
        print(f"  designs:   {', '.join(p.designs)} (default {p.default_design})")
        print(f"  scenarios: {', '.join(p.scenarios)}")
        if p.options:
            print(f"  options:   {', '.join(f'{k}={v!r}' for k, v in p.options.items())}")


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="fdisyn", description="Design FDI diagnosers as optimisation problems, export them as C, judge them.")
    sub = ap.add_subparsers(dest="command", required=True)

    def opt(p: argparse.ArgumentParser) -> None:
        p.add_argument("--option", action="append", metavar="KEY=VALUE", help="problem option (JSON value), repeatable")

    def work(p: argparse.ArgumentParser) -> None:
        p.add_argument("--workdir", default="build", help="where designs are built and compiled (default: build)")

    p = sub.add_parser("design", help="design a diagnoser and write DIR/gains.json")
    p.add_argument("spec")
    p.add_argument("--out", required=True)
    p.add_argument("--design", default=None)
    opt(p)
    p.set_defaults(fn=_cmd_design)

    p = sub.add_parser("codegen", help="generate and compile the C step of DIR/gains.json")
    p.add_argument("dir")
    p.set_defaults(fn=_cmd_codegen)

    p = sub.add_parser("replay", help="run DIR's compiled diagnoser over a trace CSV")
    p.add_argument("dir")
    p.add_argument("input")
    p.add_argument("output")
    p.set_defaults(fn=_cmd_replay)

    p = sub.add_parser("simulate", help="simulate one run of a scenario to a trace CSV")
    p.add_argument("spec")
    p.add_argument("--scenario", required=True)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", required=True)
    opt(p)
    p.set_defaults(fn=_cmd_simulate)

    p = sub.add_parser("evaluate", help="Monte Carlo metrics of one design over every scenario")
    p.add_argument("spec")
    p.add_argument("--design", default=None)
    p.add_argument("--runs", type=int, default=100)
    p.add_argument("--seed", type=int, default=0, help="seed of the first run (default 0)")
    p.add_argument("--out", required=True)
    opt(p)
    work(p)
    p.set_defaults(fn=_cmd_evaluate)

    for name, fn, many in (("report", _cmd_report, False), ("reproduce", _cmd_reproduce, True)):
        p = sub.add_parser(name, help="design, verify, export, compile, simulate, evaluate and report" + (" every problem" if many else ""))
        if many:
            p.add_argument("specs", nargs="*")
        else:
            p.add_argument("spec")
        p.add_argument("--runs", type=int, default=None, help="Monte Carlo runs per scenario (default: the problem's)")
        p.add_argument("--reports", default="reports", help="report folder (default: reports)")
        work(p)
        p.set_defaults(fn=fn)

    p = sub.add_parser("bench", help="time the compiled step against the NumPy reference")
    p.add_argument("specs", nargs="*")
    p.add_argument("--out", default="reports/bench.md")
    work(p)
    p.set_defaults(fn=_cmd_bench)

    p = sub.add_parser("list", help="list the built-in problems")
    p.set_defaults(fn=_cmd_list)
    return ap


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        args.fn(args)
    except FdisynError as exc:
        print(f"fdisyn {args.command}: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
