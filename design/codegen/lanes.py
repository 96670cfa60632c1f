"""A CasADi SX function evaluated for :data:`LANES` independent arguments at once, in C.

CasADi's own C evaluates one argument per call, one scalar operation after
another. A Monte Carlo runs thousands of independent runs of the same
function, so :func:`lane_function` writes the function's algorithm (its
instruction list, in CasADi's order, on its work variables) once with every
work variable a GCC/Clang vector of :data:`LANES` doubles: lane ``l`` is run
``l``. Every operation is the elementwise IEEE operation the scalar code does
(``+ − × ÷``, comparisons and CasADi's 0/1 booleans, ``if_else_zero`` and
``fabs`` as bit masks), and every other operation (``sqrt``, ``fmin``,
``sin`` …) calls the same libm function per lane, so each lane is bit for bit
CasADi's scalar result for its argument, but for the sign of the zero that
``fmin``/``fmax`` return for +0 and −0, which C leaves open and GCC decides
by the order it passes their operands in (no contraction into FMA: the
campaign compiles with ``-std=c99``, whose ``-ffp-contract=off`` covers
vectors). The function is written for the widest vectors the building CPU runs
(AVX-512 or AVX2, :func:`build_widths`) and for the baseline, and the widest this
CPU runs is chosen at each call (``__builtin_cpu_supports``); a CPU without the
wide version runs the baseline, with the same results.

Arguments and results are lane-minor arrays: nonzero ``j`` of lane ``l`` at
``j * LANES + l``; a null argument reads zeros and a null result is not
written, as in CasADi's calling convention.
"""

from __future__ import annotations

import re

import casadi as ca

__all__ = ["LANES", "LANE_PRELUDE", "build_widths", "lane_function", "scalar_lanes"]

LANES = 8
"""Runs per vector: eight doubles fill an AVX-512 register (two AVX2, four SSE2)."""

MAX_INSTRUCTIONS = 15_000
"""Larger functions keep CasADi's scalar code: three vector versions of the turbofan's 37 722-instruction bank took
10 minutes of GCC."""

WIDTHS = (("avx512", 8, "avx512f"), ("avx2", 4, "avx2"), ("base", 2, None))
"""The versions a function can be written in: AVX-512 (one vector of eight lanes), AVX2 (two halves of four)
and the baseline (four quarters of two: SSE2 on x86-64, NEON on ARM). A vector wider than the target's
registers would be split by GCC into scalar comparisons, so each version uses its target's own width."""


def build_widths(flags: str | None = None) -> tuple[tuple[str, int, str | None], ...]:
    """The versions a library built on this CPU is written in: the widest of :data:`WIDTHS` its ``/proc/cpuinfo``
    flags name, and the baseline; all three where the flags cannot be read (another OS) or ``FDISYN_LANE_WIDTHS=all``.

    Writing each function once for this CPU rather than three times cuts the compile of a campaign's library by
    about two thirds (measured: the wind turbine's, 6.1 s of gcc for three versions, 2.2 s for the baseline
    alone); the baseline stays, so a library found by another CPU (a shared folder) still runs.

    Parameters
    ----------
    flags : str, optional
        The CPU's flags (default: read from ``/proc/cpuinfo``), for tests.

    Returns
    -------
    tuple
        The chosen entries of :data:`WIDTHS`, widest first.
    """
    import os

    if os.environ.get("FDISYN_LANE_WIDTHS") == "all":
        return WIDTHS
    if flags is None:
        try:
            with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as fh:
                flags = next((ln.split(":", 1)[1] for ln in fh if ln.startswith("flags")), None)
        except OSError:
            flags = None
        if flags is None:
            return WIDTHS
    have = set(flags.split())
    wide = next((w for w in WIDTHS if w[2] is not None and w[2] in have), None)
    return (WIDTHS[-1],) if wide is None else (wide, WIDTHS[-1])


def _prelude(widths: tuple[tuple[str, int, str | None], ...] = WIDTHS) -> str:
    out = [
        f"#define FDISYN_LANES {LANES}",
        "/* read, not folded: GCC expands a vector fabs(x) < INFINITY element by element */",
        "static volatile const double fdisyn_infinity __attribute__((unused)) = INFINITY;",
        "#if defined(__GNUC__) && defined(__x86_64__)",
        "#define FDISYN_X86 1",
        "#endif",
        *(f"#define FDISYN_LANE_{tag.upper()} 1" for tag, _, target in widths if target is not None),
    ]
    for _, w, _ in WIDTHS:
        ones = ", ".join(["0x3FF0000000000000LL"] * w)
        absb = ", ".join(["0x7FFFFFFFFFFFFFFFLL"] * w)
        zero = ", ".join(["0.0"] * w)
        out += [
            f"typedef double fdisyn_v{w} __attribute__((vector_size({8 * w})));",
            f"typedef long long fdisyn_m{w} __attribute__((vector_size({8 * w})));",
            f"static const fdisyn_m{w} fdisyn_one_bits{w} __attribute__((unused)) = {{{ones}}};",
            f"static const fdisyn_m{w} fdisyn_abs_bits{w} __attribute__((unused)) = {{{absb}}};",
            f"static const fdisyn_v{w} fdisyn_zero{w} __attribute__((unused)) = {{{zero}}};",
        ]
    return "\n".join(out) + "\n"


LANE_PRELUDE = _prelude()
"""Types and constants every lane function reads (once per C file), for functions written in every version."""


def lane_prelude(widths: tuple[tuple[str, int, str | None], ...]) -> str:
    """:data:`LANE_PRELUDE` for functions written in ``widths`` (it names the wide versions the file holds)."""
    return _prelude(widths)

_BINARY = {ca.OP_ADD: "+", ca.OP_SUB: "-", ca.OP_MUL: "*", ca.OP_DIV: "/"}
_COMPARE = {ca.OP_LT: "<", ca.OP_LE: "<="}
_LIBM_UNARY = {
    ca.OP_SQRT: "sqrt", ca.OP_EXP: "exp", ca.OP_LOG: "log", ca.OP_SIN: "sin", ca.OP_COS: "cos", ca.OP_TAN: "tan",
    ca.OP_ASIN: "asin", ca.OP_ACOS: "acos", ca.OP_ATAN: "atan", ca.OP_SINH: "sinh", ca.OP_COSH: "cosh",
    ca.OP_TANH: "tanh", ca.OP_ASINH: "asinh", ca.OP_ACOSH: "acosh", ca.OP_ATANH: "atanh", ca.OP_ERF: "erf",
    ca.OP_FLOOR: "floor", ca.OP_CEIL: "ceil", ca.OP_LOG1P: "log1p", ca.OP_EXPM1: "expm1",
}
_LIBM_BINARY = {
    ca.OP_POW: "pow", ca.OP_CONSTPOW: "pow", ca.OP_FMIN: "fmin", ca.OP_FMAX: "fmax", ca.OP_FMOD: "fmod",
    ca.OP_ATAN2: "atan2", ca.OP_HYPOT: "hypot", ca.OP_COPYSIGN: "copysign",
}


def _constant(v: float) -> str:
    if v != v:
        return "NAN"
    if v in (float("inf"), float("-inf")):  # read, not folded: GCC scalarises a vector fabs(x) < INFINITY
        return "fdisyn_infinity" if v > 0 else "-fdisyn_infinity"
    return float(v).hex()


def _body(fn: ca.Function) -> list[str] | None:
    """The instructions as C lines on vectors of ``V`` (mask type ``M``; ``Z``, ``ONE``, ``ABS`` its zero, the bits
    of 1.0 and of the absolute value, ``W`` its width), or ``None`` for an operation without a lane form."""
    true = "(((M)({x}) & ABS) != 0)"  # nonzero, NaN included, on the bits: a vector != is not vectorised everywhere
    boolean = "((V)((M)({m}) & ONE))"  # CasADi's booleans are the doubles 1 and 0
    body: list[str] = []
    for k in range(fn.n_instructions()):
        op = fn.instruction_id(k)
        i = fn.instruction_input(k)
        o = fn.instruction_output(k)
        a = f"w{i[0]}" if i else ""
        b = f"w{i[1]}" if len(i) > 1 else ""
        out = f"w{o[0]}"
        if op == ca.OP_INPUT:
            body.append(f"  if (arg[{i[0]}]) memcpy(&{out}, arg[{i[0]}] + {i[1] * LANES} + off, sizeof {out}); else {out} = Z;")
        elif op == ca.OP_OUTPUT:
            body.append(f"  if (res[{o[0]}]) memcpy(res[{o[0]}] + {o[1] * LANES} + off, &{a}, sizeof {a});")
        elif op == ca.OP_CONST:
            body.append(f"  {out} = Z + {_constant(fn.instruction_constant(k))};")
        elif op == ca.OP_ASSIGN:
            body.append(f"  {out} = {a};")
        elif op in _BINARY:
            body.append(f"  {out} = {a} {_BINARY[op]} {b};")
        elif op in _COMPARE:
            body.append(f"  {out} = {boolean.format(m=f'{a} {_COMPARE[op]} {b}')};")
        elif op == ca.OP_EQ:  # as two ordered comparisons: a vector == is not vectorised everywhere
            body.append(f"  {out} = {boolean.format(m=f'({a} <= {b}) & ({b} <= {a})')};")
        elif op == ca.OP_NE:
            body.append(f"  {out} = {boolean.format(m=f'~(({a} <= {b}) & ({b} <= {a}))')};")
        elif op == ca.OP_NEG:
            body.append(f"  {out} = -{a};")
        elif op == ca.OP_SQ:
            body.append(f"  {out} = {a} * {a};")
        elif op == ca.OP_TWICE:
            body.append(f"  {out} = 2.0 * {a};")
        elif op == ca.OP_INV:
            body.append(f"  {out} = 1.0 / {a};")
        elif op == ca.OP_FABS:
            body.append(f"  {out} = (V)((M){a} & ABS);")
        elif op == ca.OP_NOT:
            body.append(f"  {out} = {boolean.format(m='~' + true.format(x=a))};")
        elif op == ca.OP_AND:
            body.append(f"  {out} = {boolean.format(m=true.format(x=a) + ' & ' + true.format(x=b))};")
        elif op == ca.OP_OR:
            body.append(f"  {out} = {boolean.format(m=true.format(x=a) + ' | ' + true.format(x=b))};")
        elif op == ca.OP_IF_ELSE_ZERO:
            body.append(f"  {out} = (V)((M){b} & {true.format(x=a)});")
        elif op in _LIBM_UNARY:
            body.append(f"  for (l = 0; l < W; ++l) t[l] = {_LIBM_UNARY[op]}({a}[l]);\n  {out} = t;")
        elif op in _LIBM_BINARY:
            body.append(f"  for (l = 0; l < W; ++l) t[l] = {_LIBM_BINARY[op]}({a}[l], {b}[l]);\n  {out} = t;")
        else:
            return None
    return body


def lane_function(fn: ca.Function, name: str, widths: tuple[tuple[str, int, str | None], ...] = WIDTHS) -> str | None:
    """C of ``static int name(const double *const *arg, double *const *res, int level)`` (returns 0): ``fn`` on
    :data:`LANES` arguments at once (see the module); ``level`` 0 picks the widest vectors this CPU runs,
    3, 2, 1 force AVX-512, AVX2, the baseline (a version not among ``widths``, the versions written, runs the
    baseline). ``None`` when ``fn`` is not an SX function, is larger than
    :data:`MAX_INSTRUCTIONS` or has an operation without a lane form: the caller keeps CasADi's scalar C."""
    if not fn.is_a("SXFunction") or fn.n_instructions() > MAX_INSTRUCTIONS:
        return None
    body = _body(fn)
    if body is None:
        return None
    nw = max(fn.sz_w(), 1)
    text = "\n".join(body)
    versions = []
    for tag, w, target in widths:
        decl = "".join("  V " + ", ".join(f"w{j}" for j in range(s, min(s + 12, nw))) + ";\n" for s in range(0, nw, 12))
        code = (
            f"static void {name}_{tag}(const double *const *arg, double *const *res, int off) {{\n"
            f"{decl}  V t;\n  int l;\n  (void)t, (void)l;\n{text}\n}}\n"
        )
        for macro, value in (("V", f"fdisyn_v{w}"), ("M", f"fdisyn_m{w}"), ("Z", f"fdisyn_zero{w}"),
                             ("ONE", f"fdisyn_one_bits{w}"), ("ABS", f"fdisyn_abs_bits{w}"), ("W", str(w))):
            code = re.sub(rf"\b{macro}\b", value, code)
        if target is not None:
            code = f"#ifdef FDISYN_X86\n__attribute__((target(\"{target}\")))\n{code}#endif\n"
        versions.append(code)
    x86 = [(3 - n, tag, w, target) for n, (tag, w, target) in enumerate(WIDTHS) if target is not None and (tag, w, target) in widths]
    base_tag, base_w = WIDTHS[-1][0], WIDTHS[-1][1]
    dispatch = "".join(
        f"    if (level == {lv} || (level == 0 && __builtin_cpu_supports(\"{target}\"))) {{\n"
        f"        for (off = 0; off < FDISYN_LANES; off += {w}) {name}_{tag}(arg, res, off);\n"
        f"        return 0;\n    }}\n"
        for lv, tag, w, target in x86
    )
    return (
        "".join(versions)
        + f"static int {name}(const double *const *arg, double *const *res, int level) {{\n    int off;\n    (void)level;\n"
        + f"#ifdef FDISYN_X86\n{dispatch}#endif\n"
        + f"    for (off = 0; off < FDISYN_LANES; off += {base_w}) {name}_{base_tag}(arg, res, off);\n    return 0;\n}}\n"
    )


def scalar_lanes(fn: ca.Function, name: str, symbol: str) -> str:
    """C of the same interface as :func:`lane_function`'s, calling CasADi's generated scalar ``symbol`` (the C of
    ``fn``, with its ``symbol_SZ_*`` macros) once per lane: for the functions without a lane form."""
    ins = [fn.nnz_in(q) for q in range(fn.n_in())]
    outs = [fn.nnz_out(q) for q in range(fn.n_out())]
    lines = [
        f"static int {name}(const double *const *arg, double *const *res, int level) {{",
        f"    const casadi_real *a[CAMPAIGN_SZ({symbol}_SZ_ARG)];",
        f"    casadi_real *o[CAMPAIGN_SZ({symbol}_SZ_RES)];",
        f"    casadi_int iw[CAMPAIGN_SZ({symbol}_SZ_IW)];",
        f"    casadi_real w[CAMPAIGN_SZ({symbol}_SZ_W)];",
        *(f"    double in{q}[{max(n, 1)}];" for q, n in enumerate(ins)),
        *(f"    double out{q}[{max(n, 1)}];" for q, n in enumerate(outs)),
        "    long l, j;",
        "    (void)level, (void)j;",
        "    for (l = 0; l < FDISYN_LANES; ++l) {",
    ]
    for q, n in enumerate(ins):
        lines.append(f"        if (arg[{q}]) {{ for (j = 0; j < {n}; ++j) in{q}[j] = arg[{q}][j * FDISYN_LANES + l]; a[{q}] = in{q}; }}"
                     f" else a[{q}] = 0;")
    for q in range(len(outs)):
        lines.append(f"        o[{q}] = res[{q}] ? out{q} : 0;")
    lines.append(f"        if ({symbol}(a, o, iw, w, 0) != 0) return -1;")
    for q, n in enumerate(outs):
        lines.append(f"        if (res[{q}]) for (j = 0; j < {n}; ++j) res[{q}][j * FDISYN_LANES + l] = out{q}[j];")
    lines += ["    }", "    return 0;", "}", ""]
    return "\n".join(lines)
