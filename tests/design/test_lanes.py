"""The vector form of a CasADi function (fdisyn.codegen.lanes) against CasADi's own scalar C, bit for bit."""

from __future__ import annotations

import ctypes
import os
import subprocess
from pathlib import Path

import casadi as ca
import numpy as np
from fdisyn.codegen.lanes import LANE_PRELUDE, LANES, lane_function, scalar_lanes
from fdisyn.codegen.library import CFLAGS, compiler, shared_library_flags


def _every_operation() -> ca.Function:
    x = ca.SX.sym("x", 3)
    y = ca.SX.sym("y", 2)
    a, b, c = x[0], x[1], x[2]
    outs = [
        a + b, a - b, a * b, a / b, -a, a * a, 2 * a, 1 / a, ca.fabs(a), ca.sqrt(ca.fabs(b)),
        a < b, a <= b, a == b, a != b, ca.logic_not(a), ca.logic_and(a, b), ca.logic_or(a, c),
        ca.if_else(ca.fabs(a) < ca.inf, 3.5 * b, 0), ca.if_else(a > y[0], b, c, False), ca.fmin(a, b), ca.fmax(b, c),
        ca.exp(ca.fmin(a, 50)), ca.log(ca.fabs(a)), ca.sin(a), ca.cos(b), ca.tanh(c), ca.atan2(a, b), ca.erf(a),
        ca.floor(a), ca.ceil(b), ca.fmod(a, y[1]), ca.power(ca.fabs(a), 1.7), ca.power(ca.fabs(b), y[0]),
        ca.asin(ca.fmin(ca.fmax(a, -1), 1)), ca.atan(a), ca.sinh(ca.fmin(b, 20)), ca.constpow(a, 3),
        a * np.inf, a - np.inf, a + np.nan, ca.fabs(a) < np.inf,
    ]
    return ca.Function("f", [x, y], [ca.vertcat(*outs[:20]), ca.vertcat(*outs[20:])])


def test_every_operation_is_casadis_scalar_result_at_every_width(tmp_path: Path) -> None:
    """Random operands with NaN, ±∞, ±0 and repeats (for ==): every lane of every width equals CasADi's C for
    that lane's arguments to the last bit, NaN for NaN. One exception, which C leaves open (C11 F.10.9.2): the
    sign of the zero ``fmin``/``fmax`` return for +0 and −0, which depends on the order GCC passes their
    operands in (it may swap them: the functions are commutative up to that sign); those two outputs are
    compared as values."""
    fn = _every_operation()
    text = lane_function(fn, "lane_f")
    assert text is not None
    cg = ca.CodeGenerator("f_scalar.c", {"with_header": True})
    cg.add(fn)
    cg.generate(str(tmp_path) + os.sep)
    src = tmp_path / "lanes.c"
    src.write_text(
        '#include <math.h>\n#include <string.h>\n#include "f_scalar.h"\n#define CAMPAIGN_SZ(x) ((x) > 0 ? (x) : 1)\n'
        + LANE_PRELUDE + text + scalar_lanes(fn, "scalar_f", "f")
        + "int run_lanes(const double *x, const double *y, double *o1, double *o2, int level, int scalar) {\n"
        "    const double *arg[2] = {x, y};\n    double *res[2] = {o1, o2};\n"
        "    return scalar ? scalar_f(arg, res, level) : lane_f(arg, res, level);\n}\n"
        "int natural(void) {\n#ifdef FDISYN_X86\n"
        '    return __builtin_cpu_supports("avx512f") ? 3 : __builtin_cpu_supports("avx2") ? 2 : 1;\n'
        "#else\n    return 1;\n#endif\n}\n"
    )
    lib = tmp_path / "liblanes.so"
    subprocess.run([*compiler(), *CFLAGS, *shared_library_flags(), "-Wno-unused-function", "-Wno-unused-parameter", f"-I{tmp_path}", str(src),
                    str(tmp_path / "f_scalar.c"), "-o", str(lib), "-lm"], check=True, capture_output=True)
    dll = ctypes.CDLL(str(lib))
    dll.natural.restype = ctypes.c_int
    dll.run_lanes.restype = ctypes.c_int
    dll.run_lanes.argtypes = [ctypes.c_void_p] * 4 + [ctypes.c_int, ctypes.c_int]
    rng = np.random.default_rng(20261123)
    special = np.array([np.nan, np.inf, -np.inf, 0.0, -0.0, 1.0, -1.0, 1e-310])
    levels = list(range(1, dll.natural() + 1))  # the widths this CPU runs
    for trial in range(300):
        x = rng.normal(scale=3.0, size=(3, LANES))
        y = rng.normal(scale=3.0, size=(2, LANES))
        mask = rng.random(x.shape) < 0.2
        x[mask] = rng.choice(special, int(mask.sum()))
        x[1, :2] = x[0, :2]  # equal operands
        outs = []
        for level in levels + [0]:
            for scalar in (0, 1):
                o1, o2 = np.zeros((20, LANES)), np.zeros((fn.nnz_out(1), LANES))
                xa, ya = np.ascontiguousarray(x), np.ascontiguousarray(y)
                rc = dll.run_lanes(xa.ctypes.data, ya.ctypes.data, o1.ctypes.data, o2.ctypes.data, level, scalar)
                assert rc == 0
                outs.append((level, scalar, o1.view(np.int64).copy(), o2.view(np.int64).copy()))
        ref = outs[1]  # CasADi's scalar C per lane
        signed = [(0, 19), (1, 0)]  # fmin(a, b) and fmax(b, c)
        for level, scalar, o1, o2 in outs:
            for (got, want), block in zip(((o1, ref[2]), (o2, ref[3])), (0, 1), strict=True):
                rows = [r for b, r in signed if b == block]
                keep = np.setdiff1d(np.arange(got.shape[0]), rows)
                assert np.array_equal(got[keep], want[keep]), (trial, level, scalar, block)
                assert np.array_equal(got[rows].view(float), want[rows].view(float), equal_nan=True), (trial, level, scalar)


def test_a_library_is_written_for_the_building_cpus_widest_vectors_and_the_baseline(monkeypatch) -> None:  # noqa: ANN001
    """The versions follow the CPU's flags (the widest it runs, then the baseline that every x86-64 runs), all three
    where the flags are unknown or asked for; a function written without a wide version dispatches to the baseline
    (the test above checks that every version gives the same bits)."""
    from fdisyn.codegen.lanes import WIDTHS, build_widths

    monkeypatch.delenv("FDISYN_LANE_WIDTHS", raising=False)
    assert [t for t, _, _ in build_widths("fpu sse2 avx avx2 avx512f avx512bw")] == ["avx512", "base"]
    assert [t for t, _, _ in build_widths("fpu sse2 avx avx2 fma")] == ["avx2", "base"]
    assert [t for t, _, _ in build_widths("fpu sse2")] == ["base"]
    monkeypatch.setenv("FDISYN_LANE_WIDTHS", "all")
    assert build_widths("fpu sse2") == WIDTHS
    text = lane_function(_every_operation(), "lane_f", (WIDTHS[-1],))
    assert text is not None and "__builtin_cpu_supports" not in text and "target(" not in text
    text = lane_function(_every_operation(), "lane_f", (WIDTHS[0], WIDTHS[-1]))
    assert text is not None and 'target("avx512f")' in text and 'target("avx2")' not in text
