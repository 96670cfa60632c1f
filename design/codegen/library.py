"""Generate, compile and check the C step function of a diagnoser.

``fdisyn codegen DIR`` reads ``DIR/gains.json`` and writes

* ``DIR/c/``: the library a firmware or application compiles, nothing
  else: ``<prefix>.c`` / ``<prefix>.h`` (the malloc-free C API; ``<prefix>.c``
  is the one source, listed in ``SOURCES``), ``<prefix>_casadi.c`` /
  ``<prefix>_casadi.h`` (CasADi's code for the step, which ``<prefix>.c``
  includes; compiled on its own it is empty, so a build that takes every
  ``.c`` file of the folder links too), and a ``CMakeLists.txt`` whose static
  library target ``fdisyn::<prefix>`` an ``add_subdirectory`` adds;
* ``DIR/c/tools/``: the programs with a ``main``, ``replay.c`` and ``bench.c``;
* ``DIR/lib<prefix>.so`` (``.dylib`` on macOS, ``.dll`` on Windows:
  :func:`fdisyn.runtime.compiled.library_suffix`): the shared library (loaded by ctypes);
* ``DIR/replay``: the pure-C replay program.

Everything is compiled with ``-std=c99 -O2 -Wall -Wextra -Werror -pedantic``
(never ``-ffast-math``, which may remove the non-finite checks); the library
is also warning-free under ``-std=c11``. ``<prefix>`` is the gain file's
``name``. With ``precision="single"`` the step computes in ``float``
(CasADi's ``casadi_real`` option, ``<tgmath.h>`` for its math functions):
``<prefix>_init_f`` / ``<prefix>_step_f`` take floats, and the double API
converts at the boundary.

A gain file is data, never code. Before anything is generated, the name that
prefixes the C API is checked again (it cannot be escaped: it forms
identifiers and file names) and so are the size limits; every other string
written into C goes through :func:`c_string_literal` (string literals) or
:func:`c_comment_text` (comments), so whatever a name holds it cannot end its
literal or comment. The templates are filled in one pass, so a value that
looks like a placeholder stays text. The library carries the gain file's
content hash after a build mark (``<prefix>_gain_file_sha256()``,
:data:`fdisyn.runtime.compiled.BUILD_MARK`) and ``codegen`` writes a build
manifest next to it (:func:`fdisyn.runtime.compiled.write_manifest`): the
loader refuses a library built from another gain file, or one that changed
since it was built, before ``dlopen`` ever sees it. ``replay`` carries the
sha256 of the bytes of the ``gains.json`` that ``codegen`` read and refuses to
run beside another one, with the line ``fdisyn replay`` prints
(:data:`fdisyn.runtime.compiled.STALE_BUILD`).
"""

from __future__ import annotations

import hashlib
import math
import os
import re
import shlex
import shutil
import subprocess
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import casadi as ca
import fdisyn.runtime
import numpy as np
from fdisyn.codegen.step import step_function
from fdisyn.runtime.compiled import BUILD_MARK, STALE_BUILD, library_path, manifest_path, write_manifest
from fdisyn.runtime.errors import ArgumentError, BuildError, GainFileError
from fdisyn.runtime.gainfile import GainFile, gain_file_sha256, read_gain_file
from fdisyn.runtime.jsondata import read_regular_file
from fdisyn.runtime.schema import FORMAT, LIMITS
from fdisyn.runtime.validate import check_limits
from fdisyn.runtime.names import check_diagnoser_name

__all__ = [
    "CFLAGS",
    "LIBRARY_SOURCES",
    "PRECISIONS",
    "TOOLS",
    "check_precision",
    "float_literals",
    "STACK_LIMIT_BYTES",
    "CodegenResult",
    "c_comment_text",
    "c_string_literal",
    "fill_template",
    "generate_sources",
    "compile_sources",
    "codegen",
    "compiler",
    "shared_library_flags",
    "step_stack_bytes",
    "local_cores",
]

C_TEMPLATES = Path(fdisyn.runtime.__file__).parent / "c"
"""The C templates shipped with the runtime package."""

CFLAGS = ("-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-pedantic")

PRECISIONS = ("double", "single")
"""What the generated step may compute in: IEEE double (the default), or single (``float``) for targets without a
double-precision FPU."""

TOOLS = "tools"
"""The folder of ``DIR/c`` that holds the programs with a ``main`` (``replay.c``, ``bench.c``): ``DIR/c`` itself
holds only the library, so a build may compile every ``.c`` file there."""

LIBRARY_SOURCES = "SOURCES"
"""The file of ``DIR/c`` that lists the sources a build compiles, one a line, relative to ``DIR/c``."""


def shared_library_flags(platform: str | None = None) -> tuple[str, ...]:
    """The compiler flags that make a shared library on ``platform`` (``sys.platform`` by default):
    ``-dynamiclib`` on macOS, ``-shared`` elsewhere; position-independent code (``-fPIC``) except on
    Windows, where all code is (MinGW warns about the flag, and ``-Werror`` would fail the build)."""
    platform = sys.platform if platform is None else platform
    if platform == "darwin":
        return ("-fPIC", "-dynamiclib")
    if platform in ("win32", "cygwin"):
        return ("-shared",)
    return ("-fPIC", "-shared")


STACK_LIMIT_BYTES = 512 * 1024
"""Largest stack frame ``<prefix>_step`` may need (its work arrays and the copy
of the state): a main thread's stack is 8 MiB on Linux and macOS and 1 MiB on
Windows, a task's on an embedded target often tens of KiB, so the size is
bounded here and written into the header as ``<PREFIX>_STACK_BYTES`` (the
reference problems' steps need 0.3–90 KiB; a bank of ten 100-state generators
on 20 sensors about 90 KiB)."""


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


def compiler() -> list[str]:
    """The C compiler command: ``$CC`` if set (a command and its flags, e.g.
    ``gcc -m32``), else ``gcc``.

    ``$CC`` is split like a shell would (``shlex``) but never run by one: each
    word must match :data:`_CC_WORD`, and the first must be an executable on
    ``PATH`` (or a path to one). Returns the argument vector (command, then flags).
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
    return words


def _c_double(x: float) -> str:
    if np.isnan(x):
        raise GainFileError("a number written into the C is NaN; the gain file's validation should have refused it")
    if np.isinf(x):
        return "INFINITY" if x > 0 else "-INFINITY"
    s = repr(float(x))
    return s if any(ch in s for ch in ".eEn") else s + ".0"


def c_string_literal(text: str) -> str:
    """``text`` as a C string literal whose bytes are exactly its UTF-8 bytes, whatever it holds.

    Printable ASCII is kept except ``"`` and ``\\`` (they end or escape the
    literal) and ``?`` (``??/`` is a trigraph for ``\\`` under ``-std=c99``);
    every other byte — control characters, non-ASCII — is written as a
    three-digit octal escape ``\\ooo``, which, unlike ``\\x``, never
    swallows a following digit. (A NUL byte would end the C string early;
    the name grammar refuses it long before.)
    """
    out = ['"']
    for b in text.encode("utf-8", "surrogatepass"):
        ch = chr(b)
        out.append(ch if 0x20 <= b < 0x7F and ch not in '"\\?' else f"\\{b:03o}")
    out.append('"')
    return "".join(out)


_COMMENT_SAFE = frozenset("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789 _.+|,:;=()[]{}#-")


def c_comment_text(text: str) -> str:
    """``text`` made inert inside a ``/* … */`` comment.

    Letters, digits, blanks and ``_.+|,:;=()[]{}#-`` are kept; every other
    byte of the UTF-8 text — notably ``*`` and ``/`` (which could close the
    comment), ``?`` (trigraphs), ``\\`` and line breaks — is written as
    ``%XX``, so the comment can neither end nor spill onto a code line.
    """
    return "".join(chr(b) if chr(b) in _COMMENT_SAFE else f"%{b:02X}" for b in text.encode("utf-8", "surrogatepass"))


def _c_strings(names: tuple[str, ...]) -> str:
    return ", ".join([c_string_literal(n) for n in names] + ["0"])


def _c_doubles(values: np.ndarray) -> str:
    v = np.asarray(values, dtype=float).reshape(-1)
    return ", ".join(_c_double(x) for x in v) if v.size else "0.0"


_PLACEHOLDER = re.compile(r"@([A-Za-z0-9_]+)@")


def _render(template: str, gf: GainFile, extra: Mapping[str, str] | None = None) -> str:
    """Fill ``template`` in one pass: a value is never searched for placeholders again."""
    text = (C_TEMPLATES / template).read_text(encoding="utf-8")
    st = gf.step
    subs = {
        "prefix": gf.name,
        "PREFIX": gf.name.upper(),
        "FORMAT": FORMAT,  # fdisyn's own constant, not data from the file
        "problem": c_comment_text(gf.problem),
        "design": c_comment_text(gf.design),
        "NU": str(st.nu),
        "NY": str(st.ny),
        "NR": str(st.nr),
        "NJ": str(st.nj),
        "NSTATE": str(st.nstate),
        "NFAULTS": str(len(gf.faults)),
        "TS": _c_double(gf.Ts),
        "INIT_STATE": _c_doubles(st.init_state),
        "INPUT_NAMES": _c_strings(gf.inputs),
        "OUTPUT_NAMES": _c_strings(gf.outputs),
        "FAULT_NAMES": _c_strings(gf.faults),
        "THRESHOLDS": _c_doubles(gf.thresholds),
        **(extra or {}),
    }

    return fill_template(text, subs, template)


def fill_template(text: str, subs: Mapping[str, str], template: str) -> str:
    """``text`` with each ``@NAME@`` replaced by ``subs[NAME]`` in one pass (``template`` names it in errors)."""

    def fill(m: re.Match[str]) -> str:
        if m.group(1) not in subs:
            raise BuildError(f"C template {template} has an unknown placeholder {m.group(0)}")
        return subs[m.group(1)]

    return _PLACEHOLDER.sub(fill, text)


def step_stack_bytes(fn: ca.Function, nstate: int) -> int:
    """Bytes of automatic storage ``<prefix>_step`` declares around CasADi's call, and CasADi's code inside it.

    CasADi's work vectors (``w``: ``sz_w`` doubles, ``iw``: ``sz_iw`` integers, ``arg``/``res``: pointers;
    each at least one entry) and the next state (``nstate`` doubles), 8 bytes each on a 64-bit target. An SX
    function's C keeps its work in local scalars, ``sz_w`` of them at most. An MX function's object counts
    work its generated C does not declare (each vector's own slot), so for it the sizes are read from the C
    CasADi generates, plus one local scalar per instruction at most.
    """
    sizes = {"w": fn.sz_w(), "iw": fn.sz_iw(), "arg": fn.sz_arg(), "res": fn.sz_res()}
    locals_ = 0
    if not fn.is_a("SXFunction"):
        cg = ca.CodeGenerator("stack.c", {"with_header": False, "with_export": False, "verbose": False})
        cg.add(fn)
        found = {k: int(v) for k, v in re.findall(r"if \(sz_(arg|res|iw|w)\) \*sz_\1 = (\d+);", cg.dump())}
        sizes = {k: max(found.get(k, 0), 0) if set(found) == set(sizes) else v for k, v in sizes.items()}
        locals_ = fn.n_instructions()
    slots = sum(max(int(v), 1) for v in sizes.values()) + locals_ + nstate + 3
    return 8 * int(slots)


def casadi_step(gf: GainFile, step: ca.Function | None = None) -> ca.Function:
    """``gf``'s step (default :func:`step_function`) named ``<name>_casadi_step``: the function CasADi's C of the
    diagnoser is generated from (and the compiled Monte Carlo's vector version)."""
    fn = step if step is not None else step_function(gf)
    ins: list[Any] = list(fn.sx_in() if fn.is_a("SXFunction") else fn.mx_in())
    return ca.Function(f"{gf.name}_casadi_step", ins, fn.call(ins), list(fn.name_in()), list(fn.name_out()))


def check_precision(precision: object) -> str:
    """``precision`` if it is one of :data:`PRECISIONS`.

    Parameters
    ----------
    precision : object
        What the step is to compute in, as given.

    Returns
    -------
    str
        ``"double"`` or ``"single"``.

    Raises
    ------
    ArgumentError
        Anything else, in one line naming the two.
    """
    if precision not in PRECISIONS:
        raise ArgumentError(f"precision must be 'double' or 'single', not {precision!r}; expected --precision double (the default) or single")
    return str(precision)


_FLOAT_LITERAL = re.compile(r"(?<![\w.])(?:\d+\.\d*(?:[eE][+-]?\d+)?|\.\d+(?:[eE][+-]?\d+)?|\d+[eE][+-]?\d+)(?![\w.])")
"""A decimal floating literal of CasADi's C (``2.``, ``1.0000000000000001e+300``), not part of a name or a version."""

_FLT_MIN, _FLT_MAX = float(np.finfo(np.float32).tiny), float(np.finfo(np.float32).max)


def float_literals(text: str) -> str:
    """``text`` (CasADi's C of a step) with every floating literal written as the ``float`` nearest its double value,
    with the suffix ``F``, so that no operation is promoted to double (CasADi writes ``2.*x`` for a doubling).

    The guards a step takes from the double range keep their sense in float's: a nonzero constant below the
    smallest normal float (``DBL_MIN``, ``1e-280``: floors against a division by zero or a logarithm of zero) becomes
    ``FLT_MIN``, one beyond the largest float (``DBL_MAX``, ``1e300``: caps and overflow checks) ``FLT_MAX``, rather
    than 0 and infinity.

    Parameters
    ----------
    text : str
        C generated by CasADi.

    Returns
    -------
    str
        The same C with its floating literals as ``float`` constants.
    """

    def one(m: re.Match[str]) -> str:
        v = float(m.group(0))
        mag = abs(v)
        if mag == 0.0 or math.isinf(mag):
            f = v
        elif mag < _FLT_MIN:
            f = math.copysign(_FLT_MIN, v)
        elif mag > _FLT_MAX:
            f = math.copysign(_FLT_MAX, v)
        else:
            f = float(np.float32(v))
        s = repr(float(np.float32(f)))
        return (s if any(ch in s for ch in ".e") else s + ".") + "F"

    return _FLOAT_LITERAL.sub(one, text)


def _casadi_unit(text: str, gf: GainFile, precision: str) -> str:
    """CasADi's generated C of the step, guarded so that only ``<prefix>.c``, which includes it, compiles it: on its
    own it is an empty unit (one typedef, as ISO C requires a declaration), so a build that compiles every ``.c``
    file of ``DIR/c`` defines each symbol once. In single precision ``<tgmath.h>`` makes CasADi's ``sqrt``, ``exp``,
    ``fmax``… of a ``float`` the ``float`` functions (``sqrtf``…), so no double arithmetic is left in the step."""
    p, P = gf.name, gf.name.upper()
    head = [
        f"/* {p}_casadi.c: CasADi's code for the step of the fdisyn diagnoser \"{p}\" ({precision} precision).",
        f" * It is compiled as part of {p}.c, which includes it; compiled on its own (a build that",
        " * takes every .c file of this folder) it is empty, so no symbol is defined twice. */",
        f"#ifndef {P}_CASADI_IN_WRAPPER",
        f"typedef int {p}_casadi_compiled_in_wrapper; /* ISO C: a unit declares something */",
        "#else",
    ]
    if precision == "single":
        head.append("#include <tgmath.h> /* math functions of the argument's type: sqrt of a float is sqrtf */")
        text = float_literals(text)
    return "\n".join(head) + "\n" + text.rstrip("\n") + f"\n#endif /* {P}_CASADI_IN_WRAPPER */\n"


def generate_sources(
    gf: GainFile, c_dir: str | Path, *, step: ca.Function | None = None, gain_file_bytes_sha256: str | None = None,
    precision: str = "double",
) -> Path:
    """Write the C sources of ``gf``'s step into ``c_dir``; return the header path.

    Refuses, before writing anything, a ``name`` that cannot prefix the C API
    (a :class:`GainFile` built around the reader must not reach identifiers),
    a file beyond the size limits and a step whose stack frame would exceed
    :data:`STACK_LIMIT_BYTES`.

    Parameters
    ----------
    gf : GainFile
        The diagnoser.
    c_dir : str or Path
        Where the sources go (``DIR/c``).
    step : casadi.Function, optional
        The step to generate (default :func:`step_function` of ``gf``).
    gain_file_bytes_sha256 : str, optional
        The sha256 of the bytes of the ``gains.json`` ``gf`` was read from: ``replay.c`` refuses to run beside
        any other. ``None`` (a gain file that is not on disk): the replay program refuses to run at all.
    precision : {"double", "single"}
        What the step computes in (:data:`PRECISIONS`); single adds ``<name>_init_f`` and ``<name>_step_f``.

    Returns
    -------
    Path
        The header ``c_dir/<name>.h``; the programs with a ``main`` are in ``c_dir/tools`` (:data:`TOOLS`).

    Raises
    ------
    GainFileError, BuildError
        A name or size the C cannot take, a stack frame too large, a folder that is a link.
    """
    check_diagnoser_name(gf.name, "name", error=GainFileError)
    check_precision(precision)
    check_limits(gf)
    fn = step if step is not None else step_function(gf)
    st = gf.step
    stack = step_stack_bytes(fn, st.nstate)
    if precision == "single":  # the double API's float copies of the signals (the state's fits in the 8-byte slots)
        stack += 4 * (st.nu + st.ny + st.nr + st.nj + 4)
    if stack > STACK_LIMIT_BYTES:
        raise BuildError(
            f"the step of {gf.name!r} would need {stack} bytes of stack (CasADi work arrays and the state); "
            f"at most {STACK_LIMIT_BYTES} are allowed"
        )
    c_dir = Path(c_dir)
    if c_dir.is_symlink():
        raise BuildError(f"{c_dir} is a symbolic link; expected a folder of its own for the generated C (remove the link)")
    tools = c_dir / TOOLS
    if tools.is_symlink():
        raise BuildError(f"{tools} is a symbolic link; expected the folder `fdisyn codegen` writes the replay and bench programs in (remove the link)")
    c_dir.mkdir(parents=True, exist_ok=True)
    tools.mkdir(exist_ok=True)
    # replay.c and bench.c in DIR/c itself are an earlier layout's: removed, so every .c file there is the library's
    for generated in (f"{gf.name}_casadi.c", f"{gf.name}_casadi.h", f"{gf.name}.h", f"{gf.name}.c", "replay.c", "bench.c", "CMakeLists.txt", LIBRARY_SOURCES):
        fresh_path(c_dir / generated)
    for generated in ("replay.c", "bench.c"):
        fresh_path(tools / generated)
    named = casadi_step(gf, fn)
    # the generated header carries the <f>_SZ_* work-size macros the wrapper uses
    real = "float" if precision == "single" else "double"
    cg = ca.CodeGenerator(f"{gf.name}_casadi.c", {"with_header": True, "with_export": False, "verbose": False, "casadi_real": real})
    cg.add(named)
    cg.generate(str(c_dir) + os.sep)
    unit = c_dir / f"{gf.name}_casadi.c"
    unit.write_text(_casadi_unit(unit.read_text(encoding="utf-8"), gf, precision), encoding="utf-8")
    api = ("api_single" if precision == "single" else "api_double")
    extra = {
        "GAIN_FILE_SHA256": c_string_literal(gain_file_sha256(gf)),
        "BUILD_MARK": c_string_literal(BUILD_MARK.decode("ascii")),
        "GAIN_FILE_BYTES_SHA256": c_string_literal(gain_file_bytes_sha256 or ""),
        "STALE_BUILD": c_string_literal(STALE_BUILD),
        "STACK_BYTES": str(stack),
        "REAL": real,
        "SINGLE": "1" if precision == "single" else "0",
        "PRECISION_NOTE": "Single precision: the step computes in float." if precision == "single" else "Double precision.",
    }
    if precision == "single":  # the initial state as floats: no conversion left for the compiler to warn of
        extra["INIT_STATE"] = float_literals(_c_doubles(st.init_state))
    extra["API"] = _render(f"{api}.c.in", gf, extra)
    extra["API_DECL"] = _render("api_single.h.in", gf, extra) if precision == "single" else ""
    for template, out in (
        ("diagnoser.h.in", f"{gf.name}.h"),
        ("diagnoser.c.in", f"{gf.name}.c"),
        ("replay.c.in", f"{TOOLS}/replay.c"),
        ("bench.c.in", f"{TOOLS}/bench.c"),
        ("CMakeLists.txt.in", "CMakeLists.txt"),
    ):
        (c_dir / out).write_text(_render(template, gf, extra), encoding="utf-8")
    (c_dir / LIBRARY_SOURCES).write_text(f"{gf.name}.c\n", encoding="utf-8")
    return c_dir / f"{gf.name}.h"


def fresh_path(path: Path) -> Path:
    """``path`` cleared for a new file: an entry already there, unless a folder, is removed first.

    The folder may have been received from someone else: writing to a name
    that is a symbolic link (``c/replay.c`` → ``~/.bashrc``) would follow it
    and overwrite the file it points to. Removed first, a link is never
    followed and its target stays as it was; a folder in the way is refused.
    """
    if path.is_symlink() or path.exists():
        if path.is_dir() and not path.is_symlink():
            raise BuildError(f"{path} is a folder; expected the name of a file `fdisyn codegen` writes")
        path.unlink()
    return path


def _run(argv: list[str], what: str) -> None:
    """Run one compiler command (``argv``: :func:`compiler`'s words, then the arguments).

    The compiler's output is written to ``build.log`` next to the first C
    source of the command (``DIR/c/build.log``), replaced by every compile, and
    a failure is one line naming the output, the first error and the log; no
    shell is involved.
    """
    _finish(_start(argv, what), argv, what)


def local_cores() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def _start(argv: list[str], what: str) -> subprocess.Popen[str]:
    """Start one compiler command (:func:`_run`) without waiting for it."""
    try:
        return subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, errors="replace")
    except OSError as exc:
        raise BuildError(f"cannot run the C compiler {argv[0]!r} to build {what}: {exc.strerror or exc}") from exc


def _finish(proc: subprocess.Popen[str], argv: list[str], what: str, log: Path | None = None) -> None:
    """Wait for a compiler command :func:`_start` started; log and judge it as :func:`_run` does (the log in
    ``log``, default ``build.log`` beside the first source)."""
    try:
        stdout, stderr = proc.communicate()
    except BaseException:  # interrupted: no compiler is left running
        proc.kill()
        proc.wait()
        raise
    sources = [Path(a) for a in argv[1:] if a.endswith(".c")]
    log = log if log is not None else (sources[0].parent if sources else Path(what).parent) / "build.log"
    record = f"$ {shlex.join(argv)}\n{stdout}{stderr}exit status {proc.returncode}\n"
    try:
        fresh_path(log).write_text(record, encoding="utf-8")
        saved = f"the compiler's output is in {log}"
    except OSError as exc:
        saved = f"its output could not be saved to {log} ({exc.strerror or exc})"
    if proc.returncode != 0:
        lines = (stderr or stdout).splitlines()
        first = next((ln for ln in lines if "error" in ln.lower()), lines[0] if lines else "no output")
        raise BuildError(
            f"compiling {what} failed (exit status {proc.returncode}): {first.strip()[:200]}; {saved}"
        )


def compile_sources(
    gf: GainFile, c_dir: str | Path, out_dir: str | Path, *, gain_file_bytes_sha256: str | None = None, precision: str = "double"
) -> tuple[Path, Path]:
    """Compile the shared library (:func:`~fdisyn.runtime.compiled.library_path`) and the ``replay`` program;
    return their paths.

    Paths are made absolute, so a folder named like an option (``-o…``)
    never reaches the compiler as one. The library's build manifest (its
    sha256, the gain file's content hash and ``gain_file_bytes_sha256``, the hash of the bytes of the
    ``gains.json`` it was read from, as given to :func:`generate_sources`) is written next to it. The two compiles are
    independent, so they run side by side (a core each where there are two)
    and are judged and logged in turn, the library first: a failure of the
    library is the one reported (the other compile is waited for, not killed,
    so no half-written program is left), and ``build.log`` holds the same
    output as when they ran one after the other. ``precision`` (what :func:`generate_sources` generated) is
    recorded in the manifest.
    """
    check_diagnoser_name(gf.name, "name", error=GainFileError)
    c_dir, out_dir = Path(c_dir).absolute(), Path(out_dir).absolute()
    cc = compiler()
    lib = library_path(out_dir, gf)
    replay = out_dir / "replay"
    wrapper = str(c_dir / f"{gf.name}.c")
    lib_argv = [*cc, *CFLAGS, *shared_library_flags(), wrapper, "-o", str(lib), "-lm"]
    replay_argv = [*cc, *CFLAGS, str(c_dir / TOOLS / "replay.c"), wrapper, "-o", str(replay), "-lm"]
    started = [_start(lib_argv, str(lib))]
    try:
        started.append(_start(replay_argv, str(replay)))
        _finish(started[0], lib_argv, str(lib))
        write_manifest(lib, gain_file_sha256(gf), gain_file_bytes_sha256, precision=check_precision(precision))
    except Exception:  # the first failure is reported; the other compile is waited for, not killed
        for proc in started:
            proc.communicate()
        raise
    except BaseException:  # interrupted: no compiler is left running
        for proc in started:
            proc.kill()
            proc.wait()
        raise
    _finish(started[1], replay_argv, str(replay), log=c_dir / "build.log")
    return lib, replay


def compile_bench(gf: GainFile, c_dir: str | Path, out: str | Path) -> Path:
    """Compile the benchmark driver ``c_dir/tools/bench.c`` (``-O2`` like the library); its output in ``c_dir/build.log``."""
    check_diagnoser_name(gf.name, "name", error=GainFileError)
    c_dir, out = Path(c_dir).absolute(), Path(out).absolute()
    argv = [*compiler(), *CFLAGS, str(c_dir / TOOLS / "bench.c"), str(c_dir / f"{gf.name}.c"), "-o", str(out), "-lm"]
    _finish(_start(argv, str(out)), argv, str(out), log=c_dir / "build.log")
    return out


BUILD_KEY = "build.key"
"""The file in ``DIR/c`` that records the compiler command a build used (:func:`codegen` with ``reuse``)."""


def _build_key() -> str:
    return shlex.join([*compiler(), *CFLAGS, *shared_library_flags()]) + "\n"


def _unchanged_build(gf: GainFile, d: Path, bytes_sha: str, precision: str = "double") -> bool:
    """Whether ``d`` holds a build of ``gf`` (read from ``d/gains.json`` with bytes ``bytes_sha``) that this fdisyn,
    compiler and flags would make again (:func:`codegen`'s ``reuse``)."""
    import tempfile

    from fdisyn.runtime.compiled import _check_before_loading

    c_dir, lib = d / "c", library_path(d, gf)
    try:
        if (c_dir / BUILD_KEY).read_text(encoding="utf-8") != _build_key() or not (d / "replay").is_file():
            return False
        _check_before_loading(lib, gain_file_sha256(gf), gain_file=d / "gains.json", marked=True)
        with tempfile.TemporaryDirectory(dir=d, prefix=".c-staging-") as staging:
            generate_sources(gf, staging, gain_file_bytes_sha256=bytes_sha, precision=precision)
            made = [f for f in Path(staging).rglob("*") if f.is_file()]
            return all((c_dir / f.relative_to(staging)).read_bytes() == f.read_bytes() for f in made)
    except (OSError, BuildError):
        return False


def _gain_file_bytes(path: Path) -> bytes | None:
    """The bytes of the gain file at ``path``, or None when they cannot be read (:func:`read_gain_file` says why)."""
    try:
        return read_regular_file(path, LIMITS["file_bytes"], "a gain file")
    except (OSError, GainFileError):
        return None


def codegen(directory: str | Path, *, reuse: bool = False, sources_only: bool = False, precision: str = "double") -> CodegenResult:
    """``fdisyn codegen DIR``: generate and compile everything for ``DIR/gains.json``.

    The file's bytes are read before and after it is parsed: the sha256 compiled into ``replay`` and
    recorded in the manifest is that of the bytes the diagnoser was generated from (a file rewritten
    meanwhile is refused).

    Parameters
    ----------
    directory : str or Path
        ``DIR``.
    reuse : bool
        Keep what an earlier build of this same ``gains.json`` left when it is still what this build would make:
        the sources generated now equal ``DIR/c``'s byte for byte, the compiler command is the same
        (``DIR/c/build.key``) and the library passes the loader's checks (its manifest, the gain file's bytes
        and content hash, its build mark). As a build system keys its work by its inputs (acados regenerates a
        solver only when its description changed); the sources are generated anyway, the compile (the costly
        part) is skipped.
    sources_only : bool
        Generate the sources only (``DIR/c``), for a diagnoser whose C only a larger build compiles (a
        threshold copy in the compiled Monte Carlo's library); the returned library and ``replay`` are where a later
        ``codegen`` puts them.
    precision : {"double", "single"}
        What the step computes in (default double). ``"single"``: ``casadi_real`` is ``float``, for targets
        without a double-precision FPU; the library keeps the double API (so the Monitor and both replays run it)
        and adds ``<name>_init_f``/``<name>_step_f``. Its agreement with the double build is stated in
        ``runtime/REFERENCE.md``.

    Returns
    -------
    CodegenResult
        Where everything is.
    """
    check_precision(precision)
    d = Path(directory)
    p = d / "gains.json"
    before = _gain_file_bytes(p)
    gf = read_gain_file(p)
    after = _gain_file_bytes(p)
    if before is None or before != after:
        raise BuildError(f"{p} changed while `fdisyn codegen` read it; expected a gain file that stays as it is: run `fdisyn codegen {d}` again")
    bytes_sha = hashlib.sha256(after).hexdigest()
    c_dir = d / "c"
    try:
        if reuse and _unchanged_build(gf, d, bytes_sha, precision):
            return CodegenResult(directory=d, c_dir=c_dir, header=c_dir / f"{gf.name}.h", library=library_path(d, gf), replay=d / "replay")
        header = generate_sources(gf, c_dir, gain_file_bytes_sha256=bytes_sha, precision=precision)
        if sources_only:  # an earlier build's library and program are not these sources': removed, never loaded
            lib = library_path(d, gf)
            for stale in (lib, manifest_path(lib), d / "replay", c_dir / BUILD_KEY):
                stale.unlink(missing_ok=True)
            return CodegenResult(directory=d, c_dir=c_dir, header=header, library=lib, replay=d / "replay")
        lib, replay = compile_sources(gf, c_dir, d, gain_file_bytes_sha256=bytes_sha, precision=precision)
        fresh_path(c_dir / BUILD_KEY).write_text(_build_key(), encoding="utf-8")
    except BuildError:
        raise
    except OSError as exc:  # a path in DIR that cannot be written (DIR/c a file, no permission, a full disk)
        where = exc.filename if exc.filename is not None else d
        raise BuildError(
            f"cannot write {where} while building {d}: {exc.strerror or exc}; expected a folder fdisyn can write in "
            f"(remove what is in the way, or build in another folder)"
        ) from exc
    return CodegenResult(directory=d, c_dir=c_dir, header=header, library=lib, replay=replay)
