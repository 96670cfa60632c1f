"""Generated C: compiled with the flags the README documents, loaded and compared numerically."""

from __future__ import annotations

import dataclasses
import re
import subprocess

import numpy as np
import pytest
from fdisyn.app.pipeline import EXPORT_TOL, check_export
from fdisyn.codegen.library import CFLAGS, compiler
from fdisyn.runtime.compiled import CompiledDiagnoser
from fdisyn.runtime.errors import BuildError, GainFileError
from fdisyn.runtime.gainfile import read_gain_file
from fdisyn.runtime.reference import LinearReference
from fdisyn.runtime.trace import Trace, read_trace, write_replay_csv, write_trace


def _with_bad_samples(U, Y):
    U, Y = U.copy(), Y.copy()
    Y[100, 0], Y[200, 2], Y[300, :] = np.nan, np.inf, -np.inf
    U[400, 0] = np.nan
    return U, Y


def test_flags_are_the_contract(wt_built, tmp_path):
    """What the flags do, observed through the compiler rather than compared with their spelling:
    C99 without GNU extensions, optimised, no fast-math (which may remove the non-finite checks),
    and every warning of -Wall, -Wextra and -pedantic an error. The build used them."""
    cc = compiler()

    def builds(source: str, *flags: str) -> bool:
        c = tmp_path / "probe.c"
        c.write_text(source, encoding="utf-8")
        return subprocess.run([*cc, *flags, "-c", str(c), "-o", str(tmp_path / "probe.o")], capture_output=True, check=False).returncode == 0

    modes = "#if __STDC_VERSION__ != 199901L || !defined(__STRICT_ANSI__) || !__OPTIMIZE__ || defined(__FAST_MATH__)\n#error\n#endif\nint f(void) { return 0; }\n"
    assert builds(modes, *CFLAGS) and not builds(modes, *CFLAGS, "-ffast-math")
    for warning in (
        "int f(void) { int unused; return 0; }\n",  # -Wall
        "int f(int unused) { return 0; }\n",  # -Wextra
        "int f(void) { return ({ 0; }); }\n",  # -pedantic: a GNU statement expression
    ):
        assert builds(warning) and not builds(warning, *CFLAGS), warning
    log = (wt_built.directory / "c" / "build.log").read_text(encoding="utf-8")
    assert f" {' '.join(CFLAGS)} " in log.splitlines()[0] and "-ffast-math" not in log


def test_c_agrees_with_both_python_references_on_1e4_samples(wt_built, wt_trace):
    _, U, Y = wt_trace
    U, Y = _with_bad_samples(U, Y)
    chk = check_export(wt_built, U, Y)
    assert chk.samples == 10_000 and chk.nonfinite_samples == 4
    for ref, v in chk.references.items():
        # relative to the rounding scale of each output: a few ulps are expected, 1e-12 is ~1e4 of them
        assert max(v["r"], v["J"], v["state"]) <= EXPORT_TOL, (ref, v)
        assert v["decisions_equal"], ref
    res = wt_built.diagnoser.run(U, Y)
    # and plainly normwise relative to the reference (the figure a user would compute first): residuals are ~0.1
    # differences of ~150-sized terms, so summation order alone leaves ~1e-13
    ref = LinearReference(wt_built.gain_file).run(U, Y)
    for name in ("r", "J", "state"):
        a, b = getattr(res, name), getattr(ref, name)
        assert np.linalg.norm(a - b) <= EXPORT_TOL * np.linalg.norm(b), name
    assert res.alarm[-3000:].mean() > 0.9  # the stuck sensor (from 100 s) is detected in this window
    assert np.all(np.isfinite(res.r)) and np.all(np.isfinite(res.J))


def test_the_export_check_sees_a_gain_off_by_1e_10(wt_built, wt_trace):
    """The rounding-scale measure still has teeth: a reference whose Dy differs by 1e-10 relative
    (not round-off: ~1e6 ulps) fails the check, while the untouched one stays within ~10 ulps."""
    _, U, Y = wt_trace
    gf = wt_built.gain_file
    gens = list(gf.generators)
    gens[0] = dataclasses.replace(gens[0], Dy=gens[0].Dy * (1.0 + 1e-10))
    off = dataclasses.replace(wt_built, gain_file=dataclasses.replace(gf, generators=tuple(gens)))
    bad = check_export(off, U[:2000], Y[:2000]).references["numpy"]
    assert bad["r"] > 10 * EXPORT_TOL
    good = check_export(wt_built, U[:2000], Y[:2000]).references["numpy"]
    assert good["r"] < 1e-3 * EXPORT_TOL


def test_per_sample_calls_equal_the_batch_call(wt_built, wt_trace):
    _, U, Y = wt_trace
    cd = wt_built.diagnoser
    batch = cd.run(U[:500], Y[:500])
    s = cd.init_state()
    for k in range(500):
        o = cd.step(s, U[k], Y[k])
        assert np.array_equal(o.r, batch.r[k]) and o.isolated == batch.isolated[k]
    assert np.array_equal(s, batch.state)


def test_instances_run_side_by_side(wt_built, wt_trace):
    # no hidden global state: interleaving two streams gives the results of running them apart
    _, U, Y = wt_trace
    cd = wt_built.diagnoser
    a, b = cd.init_state(), cd.init_state()
    alone = cd.run(U[:300], Y[:300] + 1.0)
    for k in range(300):
        cd.step(b, U[k], Y[k])
        cd.step(a, U[k], Y[k] + 1.0)
    assert np.array_equal(a, alone.state)


def test_header_has_the_contract_api(wt_built):
    gf = wt_built.gain_file
    h = (wt_built.artifacts.c_dir / f"{gf.name}.h").read_text()
    P = gf.name.upper()
    for macro, value in (("NU", 1), ("NY", 4), ("NR", 8), ("NJ", 4), ("NSTATE", gf.step.nstate)):
        assert re.search(rf"#define {P}_{macro} {value}\b", h), macro
    assert f"void {gf.name}_init(double *state);" in h
    assert re.search(rf"int {gf.name}_step\(double \*state, const double \*u, const double \*y,\s+double \*r, double \*J, int \*alarm, int \*isolated\);", h)


def test_library_has_no_allocation_and_no_writable_globals(wt_built):
    src = "".join(p.read_text() for p in wt_built.artifacts.c_dir.glob(f"{wt_built.gain_file.name}*.c"))
    assert not re.search(r"\b(malloc|calloc|realloc|free)\s*\(", src)
    table = subprocess.run(["objdump", "-t", str(wt_built.artifacts.library)], capture_output=True, text=True, check=True).stdout
    # writable storage lives in .data/.bss; const tables of pointers sit in .data.rel.ro (read-only after relocation)
    ours = [ln for ln in table.splitlines() if wt_built.gain_file.name in ln and re.search(r"\s\.(data|bss)\s", ln)]
    assert ours == []


def test_replay_program_and_python_replay_write_identical_bytes(wt_built, wt_trace, tmp_path):
    t, U, Y = wt_trace
    U, Y = _with_bad_samples(U[:2000], Y[:2000])
    gf = wt_built.gain_file
    trace_in = write_trace(Trace(t=t[:2000], inputs=gf.inputs, outputs=gf.outputs, U=U, Y=Y, extra={"note": np.zeros(2000)}), tmp_path / "in.csv")
    proc = subprocess.run([str(wt_built.artifacts.replay), str(trace_in), str(tmp_path / "c.csv")], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert "2000 samples, 4 with non-finite values skipped" in proc.stderr
    tr = read_trace(trace_in, inputs=gf.inputs, outputs=gf.outputs)
    write_replay_csv(tmp_path / "py.csv", tr.t, wt_built.diagnoser.run(tr.U, tr.Y))
    assert (tmp_path / "c.csv").read_bytes() == (tmp_path / "py.csv").read_bytes()
    head = (tmp_path / "c.csv").read_text().splitlines()[0]
    assert head == "t,alarm,isolated,J0,J1,J2,J3," + ",".join(f"r{i}" for i in range(8))


def test_replay_program_names_a_missing_column(wt_built, tmp_path):
    p = tmp_path / "in.csv"
    p.write_text("t,tau_g,omega_r_m1,omega_r_m2,omega_g_m1\n0,1,1,1,1\n")
    proc = subprocess.run([str(wt_built.artifacts.replay), str(p), str(tmp_path / "o.csv")], capture_output=True, text=True)
    assert proc.returncode == 2
    assert "no column 'omega_g_m2' (output 3)" in proc.stderr


def test_replay_program_parses_like_python(wt_built, tmp_path):
    # odd fields: blanks, quotes, exponents, nan, empty — both sides must read the same numbers
    p = tmp_path / "in.csv"
    rows = ['t,tau_g,omega_r_m1,omega_r_m2,omega_g_m1,omega_g_m2', '0, 1e4 ,"1.6",1.6,152,1.52e2', '0.01,1e4,nan,1.6,,152', '0.02,1e4,1.6,1.6,152,152']
    p.write_text("\n".join(rows) + "\n")
    subprocess.run([str(wt_built.artifacts.replay), str(p), str(tmp_path / "c.csv")], check=True, capture_output=True)
    gf = wt_built.gain_file
    tr = read_trace(p, inputs=gf.inputs, outputs=gf.outputs)
    write_replay_csv(tmp_path / "py.csv", tr.t, wt_built.diagnoser.run(tr.U, tr.Y))
    assert (tmp_path / "c.csv").read_bytes() == (tmp_path / "py.csv").read_bytes()


def test_a_library_built_for_another_gain_file_is_refused(wt_built, tmp_path):
    gf = read_gain_file(wt_built.directory / "gains.json")
    doc = gf.to_dict()
    doc["generators"] = doc["generators"][:3]
    doc["evaluators"] = doc["evaluators"][:3]
    doc["decision"]["signatures"] = [[1, 1, 0], [0, 0, 1], [1, 0, 1], [0, 1, 0]]
    doc["faults"] = doc["faults"][:4]
    doc["step"]["nr"], doc["step"]["nj"] = 6, 3
    doc["step"]["statistic_names"] = doc["step"]["statistic_names"][:3]
    doc["step"]["residual_names"] = doc["step"]["residual_names"][:6]
    doc["decision"].pop("isolation")  # the flag-pattern decision of a file written without the isolation test
    doc["step"]["nstate"] = 3 * 3 + 3 + 3 + 1 + 3 * 3  # states, counters, ready counts, count, warm-up sums
    doc["step"]["init_state"] = [0.0] * 25
    from fdisyn.runtime.gainfile import gain_file_from_dict

    other = gain_file_from_dict(doc)
    with pytest.raises(BuildError, match=r"was built from another gain file \(sha256 [0-9a-f]{16}…; this gain file has [0-9a-f]{16}…\); run `fdisyn codegen "):
        CompiledDiagnoser(wt_built.artifacts.library, other)


def test_absurd_but_finite_values_never_produce_nan(wt_built, wt_trace):
    # 1e300 readings overflow the generators: such samples are skipped and counted, never NaN
    _, U, Y = wt_trace
    U, Y = U[:600].copy(), Y[:600].copy()
    rng = np.random.default_rng(0)
    rows = rng.choice(600, size=60, replace=False)
    Y[rows, rng.integers(0, 4, size=60)] = rng.choice([1e300, -1e300, 1e308, np.nan, np.inf], size=60)
    U[rows[:10], 0] = 1e300
    results = [impl.run(U, Y) for impl in (wt_built.diagnoser, LinearReference(wt_built.gain_file))]
    for res in results:
        assert np.all(np.isfinite(res.r)) and np.all(np.isfinite(res.J)) and np.all(np.isfinite(res.state))
        assert res.status[rows[10:]].all()  # bad outputs: skipped at once
    c, ref = results
    assert np.array_equal(c.status, ref.status)
    assert np.array_equal(c.alarm, ref.alarm) and np.array_equal(c.isolated, ref.isolated)
    np.testing.assert_allclose(c.state, ref.state, rtol=1e-12)


def test_one_absurd_input_does_not_leave_the_bank_stuck(wt_built, wt_trace):
    # u = 1e300 is accepted (its residual is finite) but fills the states with ~1e295; the next sample
    # overflows, the generators restart at the following one and the statistics are normal again
    _, U, Y = wt_trace
    U, Y = U[:400].copy(), Y[:400]
    U[200, 0] = 1e300
    for impl in (wt_built.diagnoser, LinearReference(wt_built.gain_file)):
        res = impl.run(U, Y)
        assert res.status[201] == 1 and res.status[203:].sum() == 0
        assert res.J[210:].max() < 60  # back to χ²(1) values (the 1 − 1e-14 quantile is ~60)


def test_the_generator_refuses_sizes_beyond_the_limits_before_writing(wt_built, tmp_path, monkeypatch):
    from fdisyn.codegen import library as codegen
    from fdisyn.codegen.step import step_function
    from fdisyn.runtime import schema

    gf = wt_built.gain_file
    # counted here from the matrices: exact zeros depend on the BLAS kernel (148 on SkylakeX, 140 on Haswell)
    coeffs = sum(int(np.count_nonzero(getattr(g, k))) for g in gf.generators for k in ("Ar", "Bu", "By", "Cr", "Du", "Dy", "Xu", "Xy"))
    coeffs += sum(int(np.count_nonzero(e.W)) for e in gf.evaluators)
    assert coeffs > 100
    monkeypatch.setitem(schema.LIMITS, "coefficients", 100)
    with pytest.raises(GainFileError, match=f"hold {coeffs} nonzero coefficients; at most 100"):
        codegen.generate_sources(gf, tmp_path / "c")
    monkeypatch.setitem(schema.LIMITS, "coefficients", 10_000)
    # the wrapper's automatic storage: CasADi's w, iw, arg, res, the next state and a, iso, status (8 bytes each);
    # w follows the exact zeros too (78 doubles on SkylakeX)
    fn = step_function(gf)
    stack = 8 * (max(fn.sz_w(), 1) + max(fn.sz_iw(), 1) + max(fn.sz_arg(), 1) + max(fn.sz_res(), 1) + gf.step.nstate + 3)
    assert stack > 512
    monkeypatch.setattr(codegen, "STACK_LIMIT_BYTES", 512)
    with pytest.raises(BuildError, match=rf"would need {stack} bytes of stack .*; at most 512 are allowed"):
        codegen.generate_sources(gf, tmp_path / "c")
    assert not (tmp_path / "c").exists()
    header = (wt_built.artifacts.c_dir / "wind_turbine_kalman_uio.h").read_text()
    assert f"#define WIND_TURBINE_KALMAN_UIO_STACK_BYTES {stack}" in header


def test_a_rebuild_of_the_same_gain_file_reuses_the_build_and_only_that(wt_built, tmp_path, monkeypatch):
    """``codegen(DIR, reuse=True)`` keeps the library and the replay program when the sources it generates now are
    the ones in ``DIR/c`` and the compiler command and the library are the same; it compiles again when the
    compiler command changed, the library was altered, or the gain file is another."""
    import shutil

    from fdisyn.codegen.library import BUILD_KEY, codegen
    from fdisyn.runtime.compiled import library_path

    d = tmp_path / "wt"
    d.mkdir()
    shutil.copyfile(wt_built.directory / "gains.json", d / "gains.json")
    first = codegen(d)
    lib = library_path(d, wt_built.gain_file)

    def stamp() -> tuple[int, int]:
        return lib.stat().st_mtime_ns, (d / "replay").stat().st_mtime_ns

    before = stamp()
    assert codegen(d, reuse=True).library == first.library and stamp() == before
    assert not any(p.name.startswith(".c-staging") for p in d.iterdir())  # the comparison's sources are gone
    (d / "c" / BUILD_KEY).write_text("gcc -O0\n", encoding="utf-8")  # another compiler command
    codegen(d, reuse=True)
    assert stamp() != before
    rebuilt = stamp()
    lib.write_bytes(lib.read_bytes() + b"\0")  # an altered library
    codegen(d, reuse=True)
    assert stamp() != rebuilt
    CompiledDiagnoser(lib, wt_built.gain_file)  # and what is left loads
    doc = (d / "gains.json").read_text(encoding="utf-8")
    (d / "gains.json").write_text(doc.replace('"persistence": 1', '"persistence": 2', 1), encoding="utf-8")
    again = stamp()
    codegen(d, reuse=True)
    assert stamp() != again  # (loaded in a new process only: a process loads a library path once)
