"""The ctypes boundary: a library runs only the gain file it was built from, and only checked arrays reach it."""

from __future__ import annotations

import ctypes
import hashlib
import json
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest
from fdisyn.app.cli import main
from fdisyn.codegen.library import codegen
from fdisyn.runtime.compiled import BUILD_MARK, CompiledDiagnoser, file_sha256, library_suffix, manifest_path
from fdisyn.runtime.errors import ArgumentError, BuildError, ShapeError
from fdisyn.runtime.gainfile import (
    Decision,
    Evaluator,
    GainFile,
    Generator,
    StepSpec,
    gain_file_sha256,
    read_gain_file,
    write_gain_file,
)
from fdisyn.runtime.layout import linear_state_layout
from fdisyn.runtime.monitor import Monitor
from fdisyn.runtime.reference import LinearReference
from fdisyn.runtime.trace import Trace, write_trace

SO = library_suffix()
"""The shared library's suffix here: ``.so``, ``.dylib`` or ``.dll``."""


def _trace_csv(gf: GainFile, U: np.ndarray, Y: np.ndarray, path) -> str:  # noqa: ANN001 - a path
    t = np.arange(len(Y)) * gf.Ts
    return str(write_trace(Trace(t=t, inputs=gf.inputs, outputs=gf.outputs, U=U, Y=Y), path))


def _cli(*args: str) -> subprocess.CompletedProcess:
    """``fdisyn`` in a fresh process: a crash in C shows as a negative return code, not a dead test run."""
    return subprocess.run([sys.executable, "-m", "fdisyn.app.cli", *args], capture_output=True, text=True, timeout=120)


# ------------------------------------------------------------------ the library's file name and build command
def test_the_library_is_named_and_built_for_the_platform(wt_built):
    from fdisyn.codegen.library import shared_library_flags

    assert [library_suffix(p) for p in ("linux", "darwin", "win32", "cygwin", "freebsd14")] == [".so", ".dylib", ".dll", ".dll", ".so"]
    assert shared_library_flags("linux") == ("-fPIC", "-shared") and shared_library_flags("darwin") == ("-fPIC", "-dynamiclib")
    assert shared_library_flags("win32") == ("-shared",)
    lib = wt_built.artifacts.library
    assert lib.name == f"lib{wt_built.gain_file.name}{SO}" and lib.is_file()
    assert json.loads(manifest_path(lib).read_text())["library"] == lib.name
    assert manifest_path(lib).name == f"lib{wt_built.gain_file.name}.manifest.json"


# ------------------------------------------------------------------ the library is bound to its gain file
def test_the_library_carries_the_hash_of_its_gain_file(wt_built):
    gf_disk = read_gain_file(wt_built.directory / "gains.json")
    want = gain_file_sha256(gf_disk)
    assert want == gain_file_sha256(wt_built.gain_file)  # the design's object and the file read back hash alike
    lib = ctypes.CDLL(str(wt_built.artifacts.library))
    fn = getattr(lib, f"{gf_disk.name}_gain_file_sha256")
    fn.restype = ctypes.c_char_p
    assert fn().decode() == want
    man = json.loads(manifest_path(wt_built.artifacts.library).read_text())
    assert man["gain_file_sha256"] == want and man["format"] == "fdisyn.build/2"
    assert man["gain_file_bytes_sha256"] == hashlib.sha256((wt_built.directory / "gains.json").read_bytes()).hexdigest()
    assert wt_built.artifacts.library.read_bytes().count(BUILD_MARK + want.encode()) == 1  # found before dlopen
    header = (wt_built.artifacts.c_dir / f"{gf_disk.name}.h").read_text()
    assert f"const char *{gf_disk.name}_gain_file_sha256(void);" in header


def test_a_rewritten_gain_file_is_refused_until_codegen(built_copy, wt_trace, capsys):
    """`fdisyn design` rewrote gains.json (here: one threshold) without `fdisyn codegen`: the old library
    must not run the old gains under the new file's name."""
    p = built_copy / "gains.json"
    doc = json.loads(p.read_text())
    doc["evaluators"][0]["threshold"] *= 10.0
    p.write_text(json.dumps(doc, indent=1))
    with pytest.raises(BuildError, match=rf"^{built_copy}/gains.json is not the gain file the compiled diagnoser in {built_copy} was built from \(sha256 of its bytes [0-9a-f]{{16}}…, built from [0-9a-f]{{16}}…\): .*; run `fdisyn codegen {built_copy}`$"):
        Monitor.from_directory(built_copy)
    _, U, Y = wt_trace
    trace = _trace_csv(read_gain_file(p), U[:200], Y[:200], built_copy / "in.csv")
    assert main(["replay", str(built_copy), trace, str(built_copy / "out.csv")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is not the gain file the compiled diagnoser in" in err and "run `fdisyn codegen" in err
    assert Monitor.from_directory(built_copy, backend="reference").backend == "reference"  # the reference needs no library
    assert main(["codegen", str(built_copy)]) == 0
    mon = Monitor.from_directory(built_copy)
    assert mon.backend == "compiled" and mon.impl.gf.evaluators[0].threshold == doc["evaluators"][0]["threshold"]


def test_layout_and_key_order_matter_beside_the_build_but_not_to_the_content_hash(built_copy, tmp_path):
    """The pure-C replay can only compare the bytes of the gains.json beside it, so both replays do: a
    re-laid-out file is refused until `fdisyn codegen`. A GainFile read elsewhere runs by its content hash."""
    p = built_copy / "gains.json"
    doc = json.loads(p.read_text())
    (tmp_path / "elsewhere.json").write_text(json.dumps(dict(reversed(list(doc.items()))), indent=7))
    lib = built_copy / f"libwind_turbine_kalman_uio{SO}"
    assert CompiledDiagnoser(lib, read_gain_file(tmp_path / "elsewhere.json")).gf.name == "wind_turbine_kalman_uio"
    shutil.copy(tmp_path / "elsewhere.json", p)
    with pytest.raises(BuildError, match="gains.json is not the gain file the compiled diagnoser in"):
        Monitor.from_directory(built_copy)
    assert main(["codegen", str(built_copy)]) == 0
    assert Monitor.from_directory(built_copy).backend == "compiled"


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        ("truncate", "is not the library `fdisyn codegen` built .*truncated, corrupted or replaced; run `fdisyn codegen"),
        ("flip", "is not the library `fdisyn codegen` built"),
        ("no manifest", "has no build manifest libwind_turbine_kalman_uio.manifest.json"),
        ("bad manifest", r"manifest.json is not valid JSON \(line 1, column 2\).*; run `fdisyn codegen"),
        # a repeated key would let the last value win: "library_sha256" written twice, the second forged
        ("manifest repeats a key", r"key 'library_sha256' appears more than once at the top level; a build manifest holds each key once"),
        # links to a device: hashing or reading them would never end
        ("library a device", rf"libwind_turbine_kalman_uio{SO} is not a regular file \(a device, a FIFO or a directory\); run `fdisyn codegen"),
        ("manifest a device", r"manifest.json is not a regular file .*expected a build manifest; run `fdisyn codegen"),
    ],
)
def test_a_damaged_library_never_reaches_dlopen(built_copy, wt_trace, damage, message):
    lib = built_copy / f"libwind_turbine_kalman_uio{SO}"
    data = lib.read_bytes()
    if damage == "truncate":
        lib.write_bytes(data[: len(data) // 2])
    elif damage == "flip":
        lib.write_bytes(data[:4096] + bytes([data[4096] ^ 0xFF]) + data[4097:])
    elif damage == "no manifest":
        manifest_path(lib).unlink()
    elif damage == "library a device":
        lib.unlink()
        lib.symlink_to("/dev/zero")
    elif damage == "manifest a device":
        manifest_path(lib).unlink()
        manifest_path(lib).symlink_to("/dev/zero")
    elif damage == "manifest repeats a key":
        text = manifest_path(lib).read_text()
        doc = json.loads(text)
        manifest_path(lib).write_text(text.rstrip().rstrip("}") + f', "library_sha256": "{doc["library_sha256"]}"}}')
    else:
        manifest_path(lib).write_text("{")
    _, U, Y = wt_trace
    trace = _trace_csv(read_gain_file(built_copy / "gains.json"), U[:100], Y[:100], built_copy / "in.csv")
    proc = _cli("replay", str(built_copy), trace, str(built_copy / "out.csv"))
    assert proc.returncode == 2, proc.stderr  # not a signal (bus error, segfault): one line, status 2
    assert proc.stderr.count("\n") == 1, proc.stderr
    assert re.search(message, proc.stderr), proc.stderr


# ------------------------------------------------------------------ arrays at the boundary
def _backends(wt_built):  # noqa: ANN001, ANN202
    return [wt_built.diagnoser, LinearReference(wt_built.gain_file)]


def _message(fn) -> str:  # noqa: ANN001 - a callable that must raise
    with pytest.raises((ArgumentError, ShapeError)) as err:
        fn()
    return str(err.value)


N_STATE = 38  # the wind-turbine bank: 4 generators of 3 states, 4 counters, 4 ready counts, 1 count, 4 warm-up sums of 3,
# the isolation test's evidence (3 coordinates), the named class and the alarm's age


def _state(kind: str) -> object:
    return {
        "short": np.zeros(N_STATE - 1),
        "long": np.zeros(N_STATE + 1),
        "float32": np.zeros(N_STATE, dtype=np.float32),
        "strided": np.zeros(2 * N_STATE)[::2],
        "read-only": np.zeros(N_STATE),
        "list": [0.0] * N_STATE,
        "2-D": np.zeros((1, N_STATE)),
    }[kind]


U_OK, Y_OK = [1e4], [1.6, 1.6, 152.0, 152.0]


@pytest.mark.parametrize(
    ("u", "y", "message"),
    [
        (None, Y_OK, r"^u is None; expected real numbers of shape \(1,\)$"),
        ([1e4 + 1j], Y_OK, r"^u holds complex numbers \(dtype complex128\); expected real numbers of shape \(1,\)$"),
        (["1e4"], Y_OK, r"^u holds strings"),
        ([object()], Y_OK, r"^u holds Python objects"),
        ([True], Y_OK, r"^u holds booleans"),
        ([1e4, 0.0], Y_OK, r"^u has shape \(2,\); expected \(1,\)$"),
        ([[1e4]], Y_OK, r"^u has shape \(1, 1\); expected \(1,\)$"),
        (1e4, Y_OK, r"^u has shape \(\); expected \(1,\)$"),
        (U_OK, Y_OK[:3], r"^y has shape \(3,\); expected \(4,\)$"),
        (U_OK, [Y_OK], r"^y has shape \(1, 4\); expected \(4,\)$"),
        (U_OK, np.array(Y_OK) + 0j, r"^y holds complex numbers"),
        (U_OK, [[1.0], [1.0, 2.0], 1.0, 1.0], r"^y is not an array of numbers"),
    ],
)
def test_bad_samples_get_the_same_error_from_both_backends(wt_built, u, y, message):
    msgs = [_message(lambda impl=impl: impl.step(impl.init_state(), u, y)) for impl in _backends(wt_built)]
    assert msgs[0] == msgs[1]
    assert re.search(message, msgs[0]), msgs[0]


@pytest.mark.parametrize("kind", ["short", "long", "float32", "strided", "read-only", "list", "2-D"])
def test_a_bad_state_never_reaches_c(wt_built, monkeypatch, kind):
    cd = wt_built.diagnoser

    def never(*_args: object) -> int:
        raise AssertionError("the C step was called")

    monkeypatch.setattr(cd, "_step", never)
    state = _state(kind)
    if kind == "read-only":
        state.setflags(write=False)  # type: ignore[union-attr]
    msgs = [_message(lambda impl=impl: impl.step(state, U_OK, Y_OK)) for impl in (cd, LinearReference(wt_built.gain_file))]
    assert msgs[0] == msgs[1]
    assert msgs[0].startswith("state must be a writeable, contiguous float64 array of shape (38,) (the step updates it in place); found ")


@pytest.mark.parametrize(
    ("what", "message"),
    [
        ("U transposed", r"^U has shape \(1, 50\); expected \(50, 1\) \(one row per sample\)$"),
        ("U flat", r"^U has shape \(50,\); expected \(50, 1\)"),
        ("U short", r"^U has shape \(49, 1\); expected \(50, 1\)"),
        ("U None", r"^U is None"),
        ("U complex", r"^U holds complex numbers"),
        ("Y transposed", r"^Y has shape \(4, 50\); expected \(N, 4\)"),
        ("Y flat", r"^Y has shape \(200,\); expected \(N, 4\)"),
        ("state short", r"^state has shape \(37,\); expected \(38,\)$"),
        ("state complex", r"^state holds complex numbers"),
    ],
)
def test_bad_blocks_get_the_same_error_from_both_backends(wt_built, wt_trace, monkeypatch, what, message):
    _, U, Y = wt_trace
    U, Y = U[:50], Y[:50]
    args = {
        "U transposed": (U.T, Y, None),
        "U flat": (U.ravel(), Y, None),
        "U short": (U[:49], Y, None),
        "U None": (None, Y, None),
        "U complex": (U + 0j, Y, None),
        "Y transposed": (U, Y.T, None),
        "Y flat": (U, Y.ravel(), None),
        "state short": (U, Y, np.zeros(N_STATE - 1)),
        "state complex": (U, Y, np.zeros(N_STATE, dtype=complex)),
    }[what]

    def never(*_args: object) -> int:
        raise AssertionError("the C run was called")

    monkeypatch.setattr(wt_built.diagnoser, "_run", never)
    msgs = [_message(lambda impl=impl: impl.run(*args)) for impl in _backends(wt_built)]
    assert msgs[0] == msgs[1]
    assert re.search(message, msgs[0]), msgs[0]


def test_the_monitor_checks_through_its_backend(wt_built):
    mon = Monitor(wt_built.gain_file, library=wt_built.artifacts.library)
    with pytest.raises(ArgumentError, match="^y holds complex numbers"):
        mon.update(U_OK, np.array(Y_OK, dtype=complex))
    with pytest.raises(ShapeError, match=r"^U has shape \(1, 3\); expected \(3, 1\)"):
        mon.run(np.ones((1, 3)), np.ones((3, 4)))
    assert mon.samples == 0  # nothing ran


def test_integer_arrays_are_converted_exactly_and_empty_runs_are_empty(wt_built):
    U = np.full((20, 1), 10_000, dtype=np.int64)
    Y = np.tile(np.array([2, 2, 150, 150], dtype=np.int32), (20, 1))
    for impl in _backends(wt_built):
        a, b = impl.run(U, Y), impl.run(U.astype(float), Y.astype(float))
        assert np.array_equal(a.J, b.J) and np.array_equal(a.state, b.state)
        empty = impl.run(np.zeros((0, 1)), np.zeros((0, 4)))
        assert empty.J.shape == (0, 4) and empty.r.shape == (0, 8) and empty.alarm.shape == (0,)


def _no_input_toy() -> GainFile:
    """One generator on two outputs and no inputs (nu = 0): r = y − 0.5·ξ, J = rᵀ r."""
    ar = np.array([[0.5]])
    by = np.array([[0.25, 0.25]])
    gen = Generator.from_canonical(name="g0", outputs_used=(0, 1), Ar=ar, Bu=np.zeros((1, 0)), By=by, Cr=np.array([[-0.5], [-0.5]]), Du=np.zeros((2, 0)), Dy=np.eye(2))
    ev = Evaluator(kind="chi2", generator=0, P_f=0.01, dof=2, threshold=9.21, Sigma_r=np.eye(2), W=np.eye(2))
    lay = linear_state_layout([gen], [ev])
    return GainFile(
        kind="linear", name="free", problem="free", design="toy", Ts=1.0, inputs=(), outputs=("a", "b"), faults=("a",),
        step=StepSpec(nu=0, ny=2, nr=2, nj=1, nstate=lay.size, init_state=np.zeros(lay.size), residual_names=("g0.a", "g0.b"), statistic_names=("J_g0",)),
        plant={"A": np.eye(1) * 0.5, "B": np.zeros((1, 0)), "C": np.ones((2, 1)), "D": np.zeros((2, 0)), "E": np.zeros((1, 0)), "Q": np.eye(1), "R": np.eye(2)},
        generators=(gen,), evaluators=(ev,), decision=Decision(kind="signature_table", signatures=np.array([[1]])), certificate={"passed": True},
    )


def test_a_diagnoser_without_inputs_takes_n_by_0_blocks(tmp_path):
    gf = _no_input_toy()
    write_gain_file(gf, tmp_path / "gains.json")
    cd = CompiledDiagnoser(codegen(tmp_path).library, gf)
    Y = np.random.default_rng(0).standard_normal((30, 2)) * 3.0
    runs = [impl.run(np.zeros((30, 0)), Y) for impl in (cd, LinearReference(gf))]
    # the same operations in the same order on both sides; only summation order may differ by an ulp
    np.testing.assert_allclose(runs[0].J, runs[1].J, rtol=1e-14, atol=0.0)
    assert np.array_equal(runs[0].alarm, runs[1].alarm) and runs[0].alarm.any()
    for impl in (cd, LinearReference(gf)):
        assert impl.step(impl.init_state(), [], [1.0, 2.0]).status == 0
        with pytest.raises(ArgumentError, match=r"^U is None; expected real numbers of shape \(30, 0\)$"):
            impl.run(None, Y)
        with pytest.raises(ShapeError, match=r"^u has shape \(1,\); expected \(0,\)$"):
            impl.step(impl.init_state(), [0.0], [1.0, 2.0])


def test_design_without_codegen_leaves_a_library_that_is_refused(built_copy, tmp_path, wt_trace, capsys):
    """The sequence users run: design, codegen (``built_copy`` is what they leave), design again with
    another P_f — and replay."""
    d = built_copy
    assert main(["design", "wind_turbine", "--out", str(d), "--option", "P_f=0.01"]) == 0
    _, U, Y = wt_trace
    trace = _trace_csv(read_gain_file(d / "gains.json"), U[:100], Y[:100], tmp_path / "in.csv")
    capsys.readouterr()
    assert main(["replay", str(d), trace, str(tmp_path / "out.csv")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{d}/gains.json is not the gain file the compiled diagnoser in {d} was built from" in err
    assert err.rstrip().endswith(f"run `fdisyn codegen {d}`") and not (tmp_path / "out.csv").exists()


def test_a_rebuilt_library_is_not_confused_with_the_one_already_loaded(built_copy):
    """dlopen returns the library already loaded from a path, even after `fdisyn codegen` rebuilt the file:
    the hash compiled into the loaded code tells, and the message says what to do."""
    gf = read_gain_file(built_copy / "gains.json")
    CompiledDiagnoser(built_copy / f"libwind_turbine_kalman_uio{SO}", gf)  # loaded in this process
    doc = json.loads((built_copy / "gains.json").read_text())
    doc["decision"]["persistence"] = 3
    (built_copy / "gains.json").write_text(json.dumps(doc))
    assert main(["codegen", str(built_copy)]) == 0
    with pytest.raises(BuildError, match=rf"this process already loaded .*libwind_turbine_kalman_uio{SO} when it was built from another gain file \(sha256 [0-9a-f]{{16}}…\), .*rebuilt since .*; start a new process$"):
        Monitor.from_directory(built_copy)
    proc = subprocess.run(  # a new process loads the new build
        [sys.executable, "-c", f"from fdisyn.runtime.monitor import Monitor; print(Monitor.from_directory({str(built_copy)!r}).impl.gf.decision.persistence)"],
        capture_output=True, text=True, timeout=120,
    )
    assert proc.returncode == 0 and proc.stdout.strip() == "3", proc.stderr


# ------------------------------------------------------------------ a replaced library never reaches dlopen
def _replace_library(directory, new_library) -> None:  # noqa: ANN001 - paths
    """Put ``new_library`` in place of the wind-turbine library and rewrite the manifest to match its bytes:
    the manifest's hashes are public, so this is what a careless (or any) writer can do."""
    lib = directory / f"libwind_turbine_kalman_uio{SO}"
    shutil.copy(new_library, lib)
    man = json.loads(manifest_path(lib).read_text())
    man["library_sha256"] = file_sha256(lib)
    manifest_path(lib).write_text(json.dumps(man))


def _tiny_library(tmp_path, name: str, code: str):  # noqa: ANN001, ANN202 - a path
    """A small shared library whose constructor creates ``<name>.ran``, plus ``code``."""
    from fdisyn.codegen.library import compiler, shared_library_flags

    src = tmp_path / f"{name}.c"
    ran = tmp_path / f"{name}.ran"
    src.write_text(
        "#include <stdio.h>\n"
        f'__attribute__((constructor)) static void ran(void) {{ FILE *f = fopen("{ran}", "w"); if (f) fclose(f); }}\n{code}\n'
    )
    out = tmp_path / f"lib{name}{SO}"
    subprocess.run([*compiler(), *shared_library_flags(), str(src), "-o", str(out)], check=True, capture_output=True, timeout=120)
    return out, ran


def _never_loaded(monkeypatch) -> None:  # noqa: ANN001 - pytest's monkeypatch
    def refuse(*_args: object, **_kw: object) -> None:
        raise AssertionError("the library reached dlopen")

    monkeypatch.setattr(ctypes, "CDLL", refuse)


def test_a_library_built_from_another_gain_file_is_refused_before_dlopen(built_copy, motor_built, monkeypatch):
    """Another design's library under this one's name, with a manifest rewritten to its hash."""
    _replace_library(built_copy, motor_built.artifacts.library)
    _never_loaded(monkeypatch)
    gf = read_gain_file(built_copy / "gains.json")
    other = gain_file_sha256(motor_built.gain_file)
    with pytest.raises(BuildError, match=(
        rf"^{built_copy}/libwind_turbine_kalman_uio{SO} holds the diagnoser of another gain file \(its build mark: sha256 {other[:16]}…; "
        rf"this gain file has {gain_file_sha256(gf)[:16]}…\): the library file was replaced or built from another gain file, and "
        rf"was not loaded; run `fdisyn codegen {built_copy}`$"
    )):
        Monitor.from_directory(built_copy)


@pytest.mark.parametrize("mark", ["none", "another gain file", "cut short"])
def test_a_replaced_library_never_runs_its_constructor(built_copy, tmp_path, mark):
    want = gain_file_sha256(read_gain_file(built_copy / "gains.json"))
    text = {"none": "no mark", "another gain file": BUILD_MARK.decode() + "0" * 64, "cut short": BUILD_MARK.decode() + want[:10]}[mark]
    fake, ran = _tiny_library(tmp_path, "fake", f'const char *fake_text(void) {{ return "{text}"; }}')
    _replace_library(built_copy, fake)
    message = "carries no fdisyn build mark" if mark == "none" else "holds the diagnoser of another gain file"
    with pytest.raises(BuildError, match=message):
        Monitor.from_directory(built_copy)
    proc = _cli("replay", str(built_copy), str(tmp_path / "in.csv"), str(tmp_path / "out.csv"))  # and in a fresh process
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and message in proc.stderr, proc.stderr
    assert not ran.exists(), "the replaced library's code ran"


def test_a_library_forged_with_the_right_mark_is_loaded_the_limit_of_the_check(built_copy, tmp_path):
    """Anyone who can write the folder can forge the mark: its code then runs (the README says so). The checks
    after loading still refuse it, worded for what they see."""
    want = gain_file_sha256(read_gain_file(built_copy / "gains.json"))
    fake, ran = _tiny_library(tmp_path, "forged", f'const char *fake_text(void) {{ return "{BUILD_MARK.decode()}{want}"; }}')
    _replace_library(built_copy, fake)
    with pytest.raises(BuildError, match="is not the library of diagnoser 'wind_turbine_kalman_uio'"):
        Monitor.from_directory(built_copy)
    assert ran.exists()
    p = "wind_turbine_kalman_uio"
    code = (
        f'const char *{p}_gain_file_sha256(void) {{ return "{"f" * 64}"; }}\n'  # reports another gain file once loaded
        f'const char *keep_mark(void) {{ return "{BUILD_MARK.decode()}{want}"; }}\n'
        f"void {p}_init(double *s) {{ (void)s; }}\nint {p}_step(void) {{ return 0; }}\nlong {p}_run(void) {{ return 0; }}\n"
        f"void {p}_dims(int *d) {{ (void)d; }}\n"
    )
    fake2, _ = _tiny_library(tmp_path, "forged2", code)
    d2 = tmp_path / "second"
    shutil.copytree(built_copy, d2)
    _replace_library(d2, fake2)
    with pytest.raises(BuildError, match=(
        rf"^the library loaded from {d2}/libwind_turbine_kalman_uio{SO} reports the gain file sha256 f{{16}}…, though its file "
        rf"carries {want[:16]}…: this process had loaded another library from that path, or the file changed while it was "
        rf"loaded; start a new process"
    )):
        Monitor.from_directory(d2)
