"""The pure-C replay runs only beside the gain file it was built from, and refuses as `fdisyn replay` does.

``fdisyn codegen`` compiles the sha256 of the bytes of ``DIR/gains.json`` into ``DIR/replay``; the program
hashes the ``gains.json`` in its own folder (``/proc/self/exe``) before it reads anything else. These tests
run both replays on the same directory and compare their lines, and test the C program's SHA-256 and its
file-name rule against Python's (``hashlib``, :func:`fdisyn.runtime.trace.shown_path`) through a small
driver compiled from the generated ``replay.c``.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from fdisyn.app.cli import main
from fdisyn.runtime.compiled import STALE_BUILD, manifest_path, stale_build_message
from fdisyn.runtime.trace import shown_path

TRACE = b"t,voltage,i_meas,w_meas,theta_meas\n" + b"".join(b"%.3f,6,0.615,107.7,%.4f\n" % (0.001 * k, 0.1077 * k) for k in range(20))


def _c(replay: Path | str, src: Path, out: Path, cwd: Path | None = None) -> tuple[int, str]:
    proc = subprocess.run([str(replay), str(src), str(out)], capture_output=True, timeout=60, cwd=cwd)
    err = proc.stderr.decode("utf-8")
    assert err.count("\n") == 1, err  # one line, never a signal
    return proc.returncode, err.removeprefix("replay: error: ").rstrip("\n")


def _py(directory: Path | str, src: Path, out: Path) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        status = main(["replay", str(directory), str(src), str(out)])
    text = err.getvalue()
    assert text.count("\n") == 1, text
    return status, text.removeprefix("fdisyn replay: error: ").rstrip("\n")


@pytest.fixture
def motor_copy(motor_built, tmp_path: Path) -> Path:
    d = tmp_path / "motor"
    shutil.copytree(motor_built.directory, d)
    (tmp_path / "in.csv").write_bytes(TRACE)
    return d


def _rewrite(gains: Path, *, layout_only: bool = False) -> None:
    """What `fdisyn design … --out DIR` does to DIR/gains.json without `fdisyn codegen` (or a new layout)."""
    doc = json.loads(gains.read_text())
    if not layout_only:
        doc["evaluators"][0]["threshold"] *= 10.0
    gains.write_text(json.dumps(doc, indent=3))


# ------------------------------------------------------------------ one refusal from both replays
@pytest.mark.parametrize("layout_only", [False, True], ids=["new threshold", "same content, new layout"])
def test_a_gain_file_rewritten_after_codegen_is_refused_by_both_replays_with_one_line(motor_copy, layout_only):
    tmp = motor_copy.parent
    built = json.loads(manifest_path(next(motor_copy.glob("lib*.so"))).read_text())["gain_file_bytes_sha256"]
    assert built == hashlib.sha256((motor_copy / "gains.json").read_bytes()).hexdigest()
    _rewrite(motor_copy / "gains.json", layout_only=layout_only)
    have = hashlib.sha256((motor_copy / "gains.json").read_bytes()).hexdigest()
    want = stale_build_message(motor_copy, have, built)
    assert want == (
        f"{motor_copy}/gains.json is not the gain file the compiled diagnoser in {motor_copy} was built from (sha256 of its "
        f"bytes {have[:16]}…, built from {built[:16]}…): it changed after the build, or the build was copied from another "
        f"folder; run `fdisyn codegen {motor_copy}`"
    )
    assert _c(motor_copy / "replay", tmp / "in.csv", tmp / "c.csv") == (2, want)
    assert _py(motor_copy, tmp / "in.csv", tmp / "py.csv") == (2, want)
    assert not (tmp / "c.csv").exists() and not (tmp / "py.csv").exists()
    # the folder as the user spells it: from inside it, through a link to the program, by its absolute path
    here = stale_build_message(".", have, built)
    assert here.startswith("gains.json is not the gain file the compiled diagnoser in . was built from")
    assert _c("./replay", tmp / "in.csv", tmp / "c.csv", cwd=motor_copy) == (2, here)
    (tmp / "link").symlink_to(motor_copy / "replay")
    assert _c(tmp / "link", tmp / "in.csv", tmp / "c.csv") == (2, stale_build_message(motor_copy.resolve(), have, built))
    assert _c(motor_copy.resolve() / "replay", tmp / "in.csv", tmp / "c.csv") == (2, stale_build_message(motor_copy.resolve(), have, built))
    assert not (tmp / "c.csv").exists()


def test_from_inside_the_folder_both_replays_name_it_alike(motor_copy, monkeypatch):
    tmp = motor_copy.parent
    _rewrite(motor_copy / "gains.json")
    monkeypatch.chdir(motor_copy)
    c = _c("./replay", tmp / "in.csv", tmp / "c.csv")
    assert c[0] == 2 and c == _py(".", tmp / "in.csv", tmp / "py.csv")
    assert c[1].startswith("gains.json is not the gain file the compiled diagnoser in . was built from") and c[1].endswith("run `fdisyn codegen .`")


def test_a_replay_copied_from_another_directory_is_refused(motor_copy, wt_built):
    tmp = motor_copy.parent
    shutil.copy2(wt_built.directory / "replay", motor_copy / "replay")  # another design's program
    built = hashlib.sha256((wt_built.directory / "gains.json").read_bytes()).hexdigest()
    have = hashlib.sha256((motor_copy / "gains.json").read_bytes()).hexdigest()
    assert _c(motor_copy / "replay", tmp / "in.csv", tmp / "c.csv") == (2, stale_build_message(motor_copy, have, built))
    assert not (tmp / "c.csv").exists()
    assert _py(motor_copy, tmp / "in.csv", tmp / "py.csv")[0] == 0  # the library beside it is the right one


def test_the_untouched_directory_replays_as_before(motor_copy):
    tmp = motor_copy.parent
    c = _c(motor_copy / "replay", tmp / "in.csv", tmp / "c.csv")
    assert c == _py(motor_copy, tmp / "in.csv", tmp / "py.csv") == (0, "replay: 20 samples, 0 with non-finite values skipped")
    assert (tmp / "c.csv").read_bytes() == (tmp / "py.csv").read_bytes()


@pytest.mark.parametrize("kind", ["missing", "a folder", "a FIFO"])
def test_a_gain_file_missing_beside_the_replay_is_one_clear_line(motor_copy, kind):
    tmp = motor_copy.parent
    gains = motor_copy / "gains.json"
    gains.unlink()
    if kind == "a folder":
        gains.mkdir()
    elif kind == "a FIFO":
        os.mkfifo(gains)  # opened without waiting for a writer
    status, msg = _c(motor_copy / "replay", tmp / "in.csv", tmp / "c.csv")
    assert status == 2 and not (tmp / "c.csv").exists()
    what = f"no gain file at {gains}" if kind == "missing" else f"{gains} is not a regular file (a device, a FIFO or a directory)"
    assert msg == (
        f"{what}; expected the gain file the compiled diagnoser in {motor_copy} was built from (put it back, or run "
        f"`fdisyn codegen {motor_copy}` on the gain file that is to run)"
    )


def test_the_refusal_is_one_text_compiled_into_the_replay(motor_built):
    """The C program's printf format is STALE_BUILD itself, written as a C literal by `fdisyn codegen`."""
    from fdisyn.codegen.library import c_string_literal

    src = (motor_built.artifacts.c_dir / "tools" / "replay.c").read_text()
    assert f"#define STALE_BUILD {c_string_literal(STALE_BUILD)}\n" in src
    assert STALE_BUILD.count("%") == 5 and STALE_BUILD.count("%s") == 3 and STALE_BUILD.count("%.16s") == 2


# ------------------------------------------------------------------ the C pieces against Python's
_DRIVER = r"""
#define main replay_main
#include "replay.c"
#undef main
/* hash FILE... : the sha256 of each file; path NAME... : each name as messages show it */
int main(int argc, char **argv) {
    char hex[65];
    int i;
    for (i = 2; i < argc; ++i) {
        if (strcmp(argv[1], "hash") == 0) {
            if (hash_file(argv[i], hex) != 0) return 1;
            puts(hex);
        } else
            puts(shown_path(argv[i]));
    }
    return 0;
}
"""


@pytest.fixture(scope="module")
def driver(motor_built, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The generated replay.c's functions behind a small command line."""
    from fdisyn.codegen.library import compiler

    d = tmp_path_factory.mktemp("driver")
    (d / "driver.c").write_text(_DRIVER)
    c_dir = motor_built.artifacts.c_dir
    wrapper = c_dir / f"{motor_built.gain_file.name}.c"
    subprocess.run([*compiler(), "-std=c99", "-O2", f"-I{c_dir / 'tools'}", str(d / "driver.c"), str(wrapper), "-o", str(d / "driver"), "-lm"],
                   check=True, capture_output=True, timeout=300)
    return d / "driver"


def test_the_c_sha256_is_hashlibs(driver, tmp_path):
    rng = np.random.default_rng(20240612)
    # the padding's edges (55/56 bytes fit one block or not, 64, 119/120 two blocks) and the read buffer's (65536)
    lengths = [0, 1, 3, 55, 56, 57, 63, 64, 65, 119, 120, 121, 127, 128, 129, 65535, 65536, 65537, 2 * 65536 + 55]
    lengths += [int(n) for n in rng.integers(0, 400, size=60)]
    files = []
    for k, n in enumerate(lengths):
        p = tmp_path / f"f{k}"
        p.write_bytes(rng.integers(0, 256, size=n, dtype=np.uint8).tobytes() if k % 3 else b"a" * n)
        files.append(p)
    proc = subprocess.run([str(driver), "hash", *map(str, files)], capture_output=True, text=True, check=True, timeout=60)
    assert proc.stdout.split() == [hashlib.sha256(p.read_bytes()).hexdigest() for p in files]


# the bytes file names are made of: blanks and line breaks, the escape, UTF-8 pieces and hidden characters
_NAME_BYTES = [b"a", b"Z", b"0", b".", b"/", b"-", b" ", b"\t", b"\n", b"\r", b"\\", b"'", b'"', b"%", b"\x7f", b"\x01",
               b"\x1b", b"\xff", b"\xc3", b"\xa9", b"\x80", b"\xed\xa0\x80", b"\xf4\x90\x80\x80", b"\xc0\xaf", "é".encode(),
               "\u00a0".encode(), "\u00a1".encode(), "\u00ad".encode(), "\u0085".encode(), "\u2028".encode(), "\u202e".encode(),
               "\u200b".encode(), "\u3000".encode(), "\ufeff".encode(), "\u1680".encode(), "\u205f".encode(), "ｘ".encode(),
               "😀".encode(), "\u2060".encode(), "\ufffb".encode()]


def test_the_c_file_name_rule_is_pythons(driver):
    rng = np.random.default_rng(7)
    names = [b"plain.csv", b"a b.csv", b" a", b"a ", b"a  b", b" ", b"bad\nname.csv", b"a\xffb.csv"]
    names += [b"".join(_NAME_BYTES[i] for i in rng.integers(0, len(_NAME_BYTES), size=int(rng.integers(1, 12)))) for _ in range(400)]
    proc = subprocess.run([str(driver), "path", *names], capture_output=True, check=True, timeout=60)
    shown = proc.stdout.decode("utf-8").split("\n")[:-1]
    assert shown == [shown_path(os.fsdecode(n)) for n in names]
    assert all(s.isprintable() and "\n" not in s and s == " ".join(s.split()) for s in shown)  # one line, unchanged by any reflow
    assert [shown_path(os.fsdecode(n)) for n in names[:8]] == [
        "plain.csv", "a b.csv", "\\x20a", "a\\x20", "a\\x20\\x20b", "\\x20", "bad\\x0aname.csv", "a\\xffb.csv",
    ]
