"""Generate, compile and check the C step function of a diagnoser.

``fdisyn codegen DIR`` reads ``DIR/gains.json`` and writes

* ``DIR/c/``: ``<prefix>_casadi.c`` (CasADi's code for the step),
  ``<prefix>.c`` / ``<prefix>.h`` (the malloc-free C API), ``replay.c``,
  ``bench.c`` and a ``CMakeLists.txt`` for users who build it themselves;
* ``DIR/lib<prefix>.so``: the shared library (loaded by ctypes);
* ``DIR/replay``: the pure-C replay program.

Everything is compiled with ``-std=c99 -O2 -Wall -Wextra -Werror -pedantic``
(never ``-ffast-math``, which may remove the non-finite checks). ``<prefix>``
is the gain file's ``name``.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import casadi as ca
import fdisyn.runtime
import numpy as np
from fdisyn.design.step import step_function
from fdisyn.runtime.errors import BuildError
from fdisyn.runtime.gainfile import FORMAT, GainFile, read_gain_file

__all__ = ["CFLAGS", "CodegenResult", "generate_sources", "compile_sources", "codegen", "compiler"]

C_TEMPLATES = Path(fdisyn.runtime.__file__).parent / "c"
"""The C templates shipped with the runtime package."""

CFLAGS = ("-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-pedantic")


@dataclass(frozen=True)
class CodegenResult:
    """Paths of everything ``codegen`` produced."""

    directory: Path
    c_dir: Path
    header: Path
    library: Path
    replay: Path


_CC_WORD = re.compile(r"^[A-Za-z0-9_./+=:,@%-]+$")
"""One word of ``$CC``: a command or a flag. Quotes, spaces inside words, ``$``,
``;``, ``|``, ``&``, ``<``, ``>``, backquotes, globs and the like are refused:
``CC`` comes from the environment, and although it is never given to a shell,
a value that only makes sense to one is not a compiler."""


def compiler() -> str:
    """The C compiler command: ``$CC`` if set (a command and its flags, e.g.
    ``gcc -m32``), else ``gcc``.

    ``$CC`` is split like a shell would (``shlex``) but never run by one: each
    word must match :data:`_CC_WORD`, and the first must be an executable on
    ``PATH`` (or a path to one). Returns the command as written; :func:`_run`
    splits it again into the argument vector.
    """
    cc = os.environ.get("CC", "gcc")
    try:
        words = shlex.split(cc)
    except ValueError as exc:
        raise BuildError(f"CC={cc!r} is not a command: {exc}; expected a compiler and its flags, e.g. CC='gcc -m32'") from None
    if not words:
        raise BuildError("CC is set but empty; expected a C99 compiler, e.g. CC=gcc, or unset it")
    bad = [w for w in words if not _CC_WORD.match(w)]
    if bad:
        raise BuildError(
            f"CC={cc!r}: {bad[0]!r} is not a plain command or flag (letters, digits and _ . / + = : , @ % - only); "
            "expected a compiler and its flags, e.g. CC='gcc -m32'"
        )
    if shutil.which(words[0]) is None:
        where = f" (from CC={cc!r})" if len(words) > 1 else ""
        raise BuildError(f"no C compiler {words[0]!r} on PATH{where}; install gcc or set CC to a C99 compiler")
    return cc


def _c_double(x: float) -> str:
    if np.isinf(x):
        return "INFINITY" if x > 0 else "-INFINITY"
    s = repr(float(x))
    return s if any(ch in s for ch in ".eEn") else s + ".0"


def _c_strings(names: tuple[str, ...]) -> str:
    return ", ".join([f'"{n}"' for n in names] + ["0"])


def _c_doubles(values: np.ndarray) -> str:
    v = np.asarray(values, dtype=float).reshape(-1)
    return ", ".join(_c_double(x) for x in v) if v.size else "0.0"


def _render(template: str, gf: GainFile) -> str:
    text = (C_TEMPLATES / template).read_text(encoding="utf-8")
    st = gf.step
    subs = {
        "@prefix@": gf.name,
        "@PREFIX@": gf.name.upper(),
        "@FORMAT@": FORMAT,
        "@problem@": gf.problem,
        "@design@": gf.design,
        "@NU@": str(st.nu),
        "@NY@": str(st.ny),
        "@NR@": str(st.nr),
        "@NJ@": str(st.nj),
        "@NSTATE@": str(st.nstate),
        "@NFAULTS@": str(len(gf.faults)),
        "@TS@": _c_double(gf.Ts),
        "@INIT_STATE@": _c_doubles(st.init_state),
        "@INPUT_NAMES@": _c_strings(gf.inputs),
        "@OUTPUT_NAMES@": _c_strings(gf.outputs),
        "@FAULT_NAMES@": _c_strings(gf.faults),
        "@THRESHOLDS@": _c_doubles(gf.thresholds),
    }
    for k, v in subs.items():
        text = text.replace(k, v)
    return text


def generate_sources(gf: GainFile, c_dir: str | Path, *, step: ca.Function | None = None) -> Path:
    """Write the C sources of ``gf``'s step into ``c_dir``; return the header path."""
    c_dir = Path(c_dir)
    c_dir.mkdir(parents=True, exist_ok=True)
    fn = step if step is not None else step_function(gf)
    ins: list[Any] = list(fn.sx_in() if fn.is_a("SXFunction") else fn.mx_in())
    named = ca.Function(f"{gf.name}_casadi_step", ins, fn.call(ins), list(fn.name_in()), list(fn.name_out()))
    # the generated header carries the <f>_SZ_* work-size macros the wrapper uses
    cg = ca.CodeGenerator(f"{gf.name}_casadi.c", {"with_header": True, "with_export": False, "verbose": False})
    cg.add(named)
    cg.generate(str(c_dir) + os.sep)
    for template, out in (
        ("diagnoser.h.in", f"{gf.name}.h"),
        ("diagnoser.c.in", f"{gf.name}.c"),
        ("replay.c.in", "replay.c"),
        ("bench.c.in", "bench.c"),
        ("CMakeLists.txt.in", "CMakeLists.txt"),
    ):
        (c_dir / out).write_text(_render(template, gf), encoding="utf-8")
    return c_dir / f"{gf.name}.h"


def _run(cmd: list[str], what: str) -> None:
    """Run one compiler command; ``cmd[0]`` is :func:`compiler`'s command, split here.

    The compiler's output is written to ``build.log`` next to the first C
    source of the command (``DIR/c/build.log``), replaced by every compile, and
    a failure is one line naming the output, the first error and the log; no
    shell is involved.
    """
    argv = [*shlex.split(cmd[0]), *cmd[1:]]
    sources = [Path(a) for a in argv[1:] if a.endswith(".c")]
    log = (sources[0].parent if sources else Path(what).parent) / "build.log"
    try:
        proc = subprocess.run(argv, capture_output=True, text=True, errors="replace", check=False)
    except OSError as exc:
        raise BuildError(f"cannot run the C compiler {argv[0]!r} to build {what}: {exc.strerror or exc}") from exc
    record = f"$ {shlex.join(argv)}\n{proc.stdout}{proc.stderr}exit status {proc.returncode}\n"
    try:
        log.write_text(record, encoding="utf-8")
        saved = f"the compiler's output is in {log}"
    except OSError as exc:
        saved = f"its output could not be saved to {log} ({exc.strerror or exc})"
    if proc.returncode != 0:
        lines = (proc.stderr or proc.stdout).splitlines()
        first = next((ln for ln in lines if "error" in ln.lower()), lines[0] if lines else "no output")
        raise BuildError(
            f"compiling {what} failed (exit status {proc.returncode}): {first.strip()[:200]}; {saved}"
        )


def compile_sources(gf: GainFile, c_dir: str | Path, out_dir: str | Path) -> tuple[Path, Path]:
    """Compile ``lib<prefix>.so`` and the ``replay`` program; return their paths."""
    c_dir, out_dir = Path(c_dir), Path(out_dir)
    cc = compiler()
    lib = out_dir / f"lib{gf.name}.so"
    replay = out_dir / "replay"
    wrapper = str(c_dir / f"{gf.name}.c")
    _run([cc, *CFLAGS, "-fPIC", "-shared", wrapper, "-o", str(lib), "-lm"], str(lib))
    _run([cc, *CFLAGS, str(c_dir / "replay.c"), wrapper, "-o", str(replay), "-lm"], str(replay))
    return lib, replay


def compile_bench(gf: GainFile, c_dir: str | Path, out: str | Path) -> Path:
    """Compile the benchmark driver (``-O2`` like the library)."""
    c_dir = Path(c_dir)
    _run([compiler(), *CFLAGS, str(c_dir / "bench.c"), str(c_dir / f"{gf.name}.c"), "-o", str(out), "-lm"], str(out))
    return Path(out)


def codegen(directory: str | Path) -> CodegenResult:
    """``fdisyn codegen DIR``: generate and compile everything for ``DIR/gains.json``."""
    d = Path(directory)
    gf = read_gain_file(d / "gains.json")
    c_dir = d / "c"
    header = generate_sources(gf, c_dir)
    lib, replay = compile_sources(gf, c_dir, d)
    return CodegenResult(directory=d, c_dir=c_dir, header=header, library=lib, replay=replay)
