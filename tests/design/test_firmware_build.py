"""The generated C drops into a firmware build.

For a small design of every diagnoser kind (the linear kind with each of its statistics, χ², WSSR, CUSUM and GLR,
the Beard filter, the NAFDF, and ARCHITECTURE.md's worked example ``limit_check``), the sources are generated as
``fdisyn codegen`` writes them and a firmware-style program — its own ``main``, a static state buffer, the trace as
constant tables, the step called once per sample, ``r`` and ``J`` printed — is built with ``-std=c99 -O2 -Wall
-Wextra -Werror -pedantic`` against the files ``DIR/c/SOURCES`` lists (double precision) or every ``.c`` file of
``DIR/c`` (single precision), every file is checked with the same flags under C11, and the program's output is
compared with the step evaluated in Python by CasADi and with the kind's NumPy reference: to round-off in double
precision, and within :data:`SINGLE` in single precision, where a decision may differ only from a sample where a
statistic lies within float round-off of its threshold.

Two diagnosers link into one program; the CMake target ``fdisyn::<name>`` builds the same program through
``add_subdirectory`` (when ``cmake`` is installed).
"""

from __future__ import annotations

import shutil
import subprocess
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import fdisyn
import numpy as np
import pytest
from fdisyn.codegen.library import TOOLS, compiler, generate_sources
from fdisyn.codegen.step import step_function
from fdisyn.runtime.gainfile import GainFile
from fdisyn.runtime.reference import RunResult
from fdisyn.synthesis import kinds

from tests.design.test_architecture_kind import limit_check, simulate  # noqa: F401 - limit_check is a fixture
from tests.design.test_kind_contract import (
    C_VS_CASADI,
    REFERENCE,
    Design,
    beard_design,
    casadi_run,
    gap,
    hostile,
    linear_design,
    plant_file_design,
)
from tests.helpers import random_plant

WARNINGS = ("-O2", "-Wall", "-Wextra", "-Werror", "-pedantic")
"""The firmware's flags besides the standard."""

SINGLE = {"linear_chi2": 2e-3, "linear_wssr": 2e-3, "linear_cusum": 2e-3, "linear_glr": 2e-3, "beard_fdf": 1e-4, "nafdf": 1e-3, "limit_check": 1e-6}
"""Largest ``max |single − double| / max(1, |double|)`` over ``r`` and ``J`` of the single-precision build against the
CasADi step in double, per case, over the samples before the first decision that differs (after it, the two runs
are different runs): float's ε is 6e-8, amplified by the step's recursions and quadratic forms. Measured values are
in runtime/REFERENCE.md."""

NEAR = 1e-3
"""A decision of the single-precision build may differ from the double one only from a sample where a statistic is
within this relative distance of its threshold (float's round-off there, amplified as in :data:`SINGLE`)."""


def _linear(detector: str, **options: object) -> Callable[[], Design]:
    def make() -> Design:
        d = linear_design()
        plant = random_plant(11, n=3, p=3, q=1, radius=0.8)
        gf = fdisyn.design(plant, method="kalman_uio", P_f=1e-3, detector=detector, name=f"firmware_{detector}", **options)
        return Design(gf, d.U, d.Y)

    return make


CASES: dict[str, Callable[[], Design]] = {
    "linear_chi2": linear_design,
    "linear_wssr": _linear("wssr", window=10, persistence=2),
    "linear_cusum": _linear("cusum", persistence=1),
    "linear_glr": _linear("glr", window=20, persistence=1),
    "beard_fdf": beard_design,
    "nafdf": plant_file_design("ship.toml", "a_half", 1500),
}
"""A small design of each kind and statistic, with its trace (NaN and ±inf in a few samples)."""

KINDS = {"linear_chi2": "linear", "linear_wssr": "linear", "linear_cusum": "linear", "linear_glr": "linear", "beard_fdf": "beard_fdf", "nafdf": "nafdf"}
"""The kind of each case's design; ``limit_check``, ARCHITECTURE.md's worked example, is registered by its test."""


def _c_number(x: float) -> str:
    if np.isnan(x):
        return "NAN"
    if np.isinf(x):
        return "INFINITY" if x > 0 else "-INFINITY"
    return repr(float(x))


def firmware_main(gf: GainFile, U: np.ndarray, Y: np.ndarray) -> str:
    """A firmware-style ``main.c``: its own ``main``, a static state buffer, the trace as constant tables, one step
    call per sample (the float API in a single-precision build), every sample's status, alarm, isolated, ``r`` and
    ``J`` printed."""
    p, P = gf.name, gf.name.upper()
    u = ", ".join(_c_number(x) for x in U.ravel()) or "0.0"
    y = ", ".join(_c_number(x) for x in Y.ravel())
    return f"""#include <math.h>
#include <stdio.h>
#include "{p}.h"

#define SAMPLES {Y.shape[0]}
#define SZ(n) ((n) > 0 ? (n) : 1)
static const double trace_u[] = {{{u}}};
static const double trace_y[] = {{{y}}};
#if {P}_SINGLE_PRECISION
typedef float real;
#else
typedef double real;
#endif
static real state[{P}_NSTATE];

int main(void) {{
    real u[SZ({P}_NU)], y[SZ({P}_NY)], r[SZ({P}_NR)], J[SZ({P}_NJ)];
    int alarm, isolated, rc, i;
    long k;
#if {P}_SINGLE_PRECISION
    {p}_init_f(state);
#else
    {p}_init(state);
#endif
    for (k = 0; k < SAMPLES; ++k) {{
        for (i = 0; i < {P}_NU; ++i) u[i] = (real)trace_u[k * {P}_NU + i];
        for (i = 0; i < {P}_NY; ++i) y[i] = (real)trace_y[k * {P}_NY + i];
#if {P}_SINGLE_PRECISION
        rc = {p}_step_f(state, u, y, r, J, &alarm, &isolated);
#else
        rc = {p}_step(state, u, y, r, J, &alarm, &isolated);
#endif
        printf("%d %d %d", rc, alarm, isolated);
        for (i = 0; i < {P}_NR; ++i) printf(" %.17g", (double)r[i]);
        for (i = 0; i < {P}_NJ; ++i) printf(" %.17g", (double)J[i]);
        putchar('\\n');
    }}
    return 0;
}}
"""


def build_firmware(gf: GainFile, c_dir: Path, main: Path, std: str, *, every_c_file: bool = False, syntax_only: bool = False) -> Path:
    """``main`` compiled with the sources ``c_dir/SOURCES`` lists (or every ``.c`` file of ``c_dir``), ``-std=std`` and
    :data:`WARNINGS`; the program's path. A warning fails it. ``syntax_only``: each source checked with the same flags
    (``-fsyntax-only``: every warning of the front end, where the language standard matters) and nothing built."""
    listed = [c_dir / line for line in (c_dir / "SOURCES").read_text(encoding="utf-8").split()]
    sources = sorted(c_dir.glob("*.c")) if every_c_file else listed
    exe = main.parent / f"firmware_{std}_{c_dir.parent.name}"
    flags = [*compiler(), f"-std={std}", *WARNINGS, f"-I{c_dir}"]
    commands = [[*flags, "-fsyntax-only", str(src)] for src in (main, *sources)] if syntax_only else [
        [*flags, str(main), *map(str, sources), "-o", str(exe), "-lm"]]
    for argv in commands:
        done = subprocess.run(argv, capture_output=True, text=True, timeout=300, check=False)
        assert done.returncode == 0 and not done.stderr, done.stderr
    return exe


def run_firmware(exe: Path, gf: GainFile) -> RunResult:
    """The program's output as a :class:`RunResult` (``state`` left empty)."""
    out = subprocess.run([str(exe)], capture_output=True, text=True, timeout=60, check=True).stdout
    rows = np.array([[float(v) for v in line.split()] for line in out.splitlines()])
    nr = gf.step.nr
    return RunResult(
        r=rows[:, 3 : 3 + nr], J=rows[:, 3 + nr :], alarm=rows[:, 1].astype(int), isolated=rows[:, 2].astype(int),
        status=rows[:, 0].astype(int), state=np.zeros(0),
    )  # fmt: skip


def first_difference(a: RunResult, b: RunResult) -> int:
    """The first sample whose alarm or isolated differs between ``a`` and ``b`` (the length when none does)."""
    differ = np.flatnonzero((a.alarm != b.alarm) | (a.isolated != b.isolated))
    return int(differ[0]) if differ.size else len(a.alarm)


def near_threshold(gf: GainFile, J: np.ndarray, k: int) -> float:
    """The smallest relative distance ``|J − h| / max(1, h)`` of a statistic to its finite threshold over the samples
    ``k − persistence + 1 … k`` (an alarm after persistence rests on them), ``inf`` when no threshold is finite."""
    h = np.asarray(gf.thresholds, dtype=float)
    finite = np.isfinite(h)
    if not finite.any():
        return float("inf")
    payload = next(iter(gf.extensions.values()), {}) if gf.extensions else {}
    p = max(int(gf.decision.persistence if gf.decision is not None else payload.get("persistence") or 1), 1)
    window = J[max(k - p + 1, 0) : k + 1][:, finite]
    return float(np.min(np.abs(window - h[finite]) / np.maximum(1.0, np.abs(h[finite]))))


def agreement(gf: GainFile, single: RunResult, double: RunResult) -> dict[str, float]:
    """The single-precision build against the double step: the worst ``r`` and ``J`` difference before the first
    decision that differs, where that is, and how near a threshold its statistic was."""
    k = first_difference(single, double)
    return {
        "r": gap(single.r[:k], double.r[:k]),
        "J": gap(single.J[:k], double.J[:k]),
        "first_difference": float(k),
        "samples": float(len(double.alarm)),
        "margin": near_threshold(gf, double.J, k) if k < len(double.alarm) else float("inf"),
        "alarms_differ": float(np.sum(single.alarm != double.alarm)),
        "isolated_differ": float(np.sum(single.isolated != double.isolated)),
    }


def check_firmware(gf: GainFile, U: np.ndarray, Y: np.ndarray, work: Path, case: str) -> dict[str, float]:
    """The whole check of this module on one design: both precisions, C99 and C11, against CasADi and the reference."""
    expected, _ = casadi_run(step_function(gf), gf.step.init_state, U, Y)
    ref = kinds.reference_run(gf, U, Y)
    (work / "app").mkdir(parents=True)
    main = work / "app" / "main.c"
    main.write_text(firmware_main(gf, U, Y), encoding="utf-8")
    figures: dict[str, float] = {}
    for precision in ("double", "single"):
        c_dir = work / precision / "c"
        generate_sources(gf, c_dir, precision=precision)
        assert not [f.name for f in c_dir.glob("*.c") if f.name not in (f"{gf.name}.c", f"{gf.name}_casadi.c")]
        assert sorted(f.name for f in (c_dir / TOOLS).iterdir()) == ["bench.c", "replay.c"]
        # built and run under C99 (the double build from SOURCES, the single one from every .c file of DIR/c); every
        # file checked under C11 too, where only the front end's warnings can differ (the build's cost is -O2's)
        got = run_firmware(build_firmware(gf, c_dir, main, "c99", every_c_file=precision == "single"), gf)
        build_firmware(gf, c_dir, main, "c11", every_c_file=True, syntax_only=True)
        np.testing.assert_array_equal(got.status, expected.status, err_msg=f"{case} {precision}: status")
        if precision == "double":
            assert max(gap(got.r, expected.r), gap(got.J, expected.J)) <= C_VS_CASADI, case
            for key in ("alarm", "isolated"):
                np.testing.assert_array_equal(getattr(got, key), getattr(expected, key), err_msg=f"{case}: {key}")
            if ref is not None:
                assert max(gap(got.r, ref.r), gap(got.J, ref.J)) <= REFERENCE + C_VS_CASADI, case
        else:
            figures = agreement(gf, got, expected)
            assert max(figures["r"], figures["J"]) <= SINGLE[case], (case, figures)
            # a decision differs only from a sample where a statistic was within float round-off of its threshold
            assert figures["first_difference"] == figures["samples"] or figures["margin"] <= NEAR, (case, figures)
    return figures


@pytest.fixture(scope="module")
def designs() -> dict[str, Design]:
    """The cases' designs, each made once per module."""
    return {}


@pytest.mark.parametrize("case", list(CASES))
def test_a_firmware_program_builds_against_the_generated_files(case: str, designs: dict[str, Design], tmp_path: Path) -> None:
    d = designs.setdefault(case, CASES[case]())
    assert d.gain_file.kind == KINDS[case]
    check_firmware(d.gain_file, d.U, d.Y, tmp_path, case)


def test_every_registered_kind_has_a_firmware_case() -> None:
    missing = set(kinds.kind_names()) - set(KINDS.values()) - {"limit_check"}
    assert not missing, f"diagnoser kinds without a case in CASES of tests/design/test_firmware_build.py: {sorted(missing)}"


def test_the_worked_example_kind_builds_into_a_firmware(limit_check: ModuleType, tmp_path: Path) -> None:  # noqa: F811
    plant = random_plant(7, n=3, p=3, q=1, radius=0.8)
    gf = fdisyn.design(plant, method="limit_check", P_f=1e-2, persistence=3)
    T = 300
    sigma = np.array(gf.extensions["limit_check"]["sigma"])
    U, Y = hostile(np.zeros((T, plant.m)), simulate(plant, T, 2, slice(150, 250), 0, 5.0 * sigma[0]), 3)
    check_firmware(gf, U, Y, tmp_path, "limit_check")


def test_two_diagnosers_link_into_one_program(designs: dict[str, Design], tmp_path: Path) -> None:
    """Each symbol is its diagnoser's: two libraries (of different kinds and precisions) in one program, no clash."""
    pair = [designs.setdefault(c, CASES[c]()) for c in ("linear_chi2", "beard_fdf")]
    sources, includes, calls = [], [], []
    for (d, precision) in zip(pair, ("double", "single"), strict=True):
        gf = d.gain_file
        c_dir = tmp_path / gf.name
        generate_sources(gf, c_dir, precision=precision)
        sources += [str(c_dir / s) for s in (c_dir / "SOURCES").read_text(encoding="utf-8").split()]
        includes += [f"-I{c_dir}"]
        p, P = gf.name, gf.name.upper()
        calls.append(
            f"    {{ static double s[{P}_NSTATE], r[{P}_NR], J[{P}_NJ], u[{P}_NU + 1], y[{P}_NY];\n"
            f"      int a, i, k;\n      for (k = 0; k < {P}_NY; ++k) y[k] = 0.0;\n      for (k = 0; k <= {P}_NU; ++k) u[k] = 0.0;\n"
            f"      {p}_init(s);\n      for (k = 0; k < 3; ++k) if ({p}_step(s, u, y, r, J, &a, &i) != 0) return 1;\n"
            f"      printf(\"{p} %d %d\\n\", a, i); }}"
        )
    main = tmp_path / "main.c"
    main.write_text(
        "#include <stdio.h>\n" + "".join(f'#include "{d.gain_file.name}.h"\n' for d in pair)
        + "int main(void) {\n" + "\n".join(calls) + "\n    return 0;\n}\n",
        encoding="utf-8",
    )  # fmt: skip
    exe = tmp_path / "both"
    argv = [*compiler(), "-std=c99", *WARNINGS, *includes, str(main), *sources, "-o", str(exe), "-lm"]
    done = subprocess.run(argv, capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0 and not done.stderr, done.stderr
    out = subprocess.run([str(exe)], capture_output=True, text=True, timeout=60, check=True).stdout.split()
    assert out[0::3] == [d.gain_file.name for d in pair]


@pytest.mark.skipif(shutil.which("cmake") is None, reason="cmake is not installed")
def test_the_cmake_target_links_into_a_firmware(designs: dict[str, Design], tmp_path: Path) -> None:
    """``add_subdirectory(DIR/c)`` and ``target_link_libraries(app PRIVATE fdisyn::<name>)``, the project's warnings
    errors, C11: the program builds and prints what the one compiled by hand prints."""
    d = designs.setdefault("linear_chi2", CASES["linear_chi2"]())
    gf, U, Y = d.gain_file, d.U[:50], d.Y[:50]
    c_dir = tmp_path / "diagnoser" / "c"
    generate_sources(gf, c_dir)
    app = tmp_path / "app"
    app.mkdir()
    (app / "main.c").write_text(firmware_main(gf, U, Y), encoding="utf-8")
    (app / "CMakeLists.txt").write_text(
        "cmake_minimum_required(VERSION 3.10)\nproject(firmware C)\nset(CMAKE_C_STANDARD 11)\n"
        "add_compile_options(-Wall -Wextra -Werror -pedantic)\n"
        f"add_subdirectory({c_dir.as_posix()} fdisyn_{gf.name})\n"
        f"add_executable(firmware main.c)\ntarget_link_libraries(firmware PRIVATE fdisyn::{gf.name})\n",
        encoding="utf-8",
    )  # fmt: skip
    build = tmp_path / "build"
    for argv in (["cmake", "-S", str(app), "-B", str(build)], ["cmake", "--build", str(build)]):
        done = subprocess.run(argv, capture_output=True, text=True, timeout=300, check=False)
        assert done.returncode == 0, done.stdout + done.stderr
    got = run_firmware(build / "firmware", gf)
    by_hand = run_firmware(build_firmware(gf, c_dir, app / "main.c", "c99"), gf)
    for key in ("r", "J", "alarm", "isolated", "status"):
        np.testing.assert_array_equal(getattr(got, key), getattr(by_hand, key), err_msg=key)


def test_a_single_precision_build_runs_behind_the_double_api(designs: dict[str, Design], tmp_path: Path) -> None:
    """``codegen(DIR, precision="single")``: the library keeps the double API, so the loader runs it, bit for bit as
    the float API in a firmware (both round the signals to float on the way in); its manifest says so; a rebuild at
    the same precision is reused; another precision is refused in one line."""
    import json

    from fdisyn.codegen.library import codegen
    from fdisyn.runtime.compiled import CompiledDiagnoser, manifest_path
    from fdisyn.runtime.errors import ArgumentError
    from fdisyn.runtime.gainfile import read_gain_file, write_gain_file

    d = designs.setdefault("linear_chi2", CASES["linear_chi2"]())
    gf, U, Y = d.gain_file, d.U[:100], d.Y[:100]
    write_gain_file(gf, tmp_path / "gains.json")
    res = codegen(tmp_path, precision="single")
    assert json.loads(manifest_path(res.library).read_text(encoding="utf-8"))["precision"] == "single"
    assert f"#define {gf.name.upper()}_SINGLE_PRECISION 1" in res.header.read_text(encoding="utf-8")
    got = CompiledDiagnoser(res.library, read_gain_file(tmp_path / "gains.json")).run(U, Y)
    (tmp_path / "app").mkdir()
    (tmp_path / "app" / "main.c").write_text(firmware_main(gf, U, Y), encoding="utf-8")
    fw = run_firmware(build_firmware(gf, res.c_dir, tmp_path / "app" / "main.c", "c99"), gf)
    for key in ("r", "J", "alarm", "isolated", "status"):
        np.testing.assert_array_equal(getattr(got, key), getattr(fw, key), err_msg=key)
    stamp = res.library.stat().st_mtime_ns
    assert codegen(tmp_path, reuse=True, precision="single").library == res.library and res.library.stat().st_mtime_ns == stamp
    with pytest.raises(ArgumentError, match="precision must be 'double' or 'single', not 'half'"):
        codegen(tmp_path, precision="half")
