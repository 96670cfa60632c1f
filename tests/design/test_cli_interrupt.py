"""Ctrl-C: every command ends with status 130 and one line, ``fdisyn <command>: interrupted``; during the Monte
Carlo the worker processes are ended too, none printing a traceback and none left behind. SIGTERM likewise (143)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from fdisyn.app import cli
from fdisyn.app.examples import EXAMPLES
from fdisyn.evaluation.campaign import local_cores

COMMANDS = ["design", "codegen", "replay", "simulate", "evaluate", "report", "reproduce", "bench", "list", "methods", "example"]


@pytest.mark.parametrize("command", COMMANDS)
def test_ctrl_c_ends_every_command_with_status_130_and_one_line(command: str, monkeypatch, capsys) -> None:
    def interrupted(a) -> None:  # noqa: ANN001 - the parsed arguments
        raise KeyboardInterrupt

    argv = {
        "design": ["design", "dc_motor", "--out", "d"], "codegen": ["codegen", "d"], "replay": ["replay", "d", "i", "o"],
        "simulate": ["simulate", "dc_motor", "--scenario", "fault_free", "--out", "t.csv"],
        "evaluate": ["evaluate", "dc_motor", "--out", "m.json"], "report": ["report", "dc_motor"],
        "reproduce": ["reproduce"], "bench": ["bench"], "list": ["list"], "methods": ["methods"], "example": ["example"],
    }[command]
    monkeypatch.setattr(cli, f"_cmd_{command}", interrupted)
    assert cli.main(argv) == 130
    captured = capsys.readouterr()
    assert captured.err == f"fdisyn {command}: interrupted\n" and captured.out == ""


def _default_sigint() -> None:
    """In the child before it runs the command: SIGINT back at its default disposition."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _descendants(root: int) -> dict[int, int]:
    """``{pid: parent pid}`` of every living process under ``root`` (from /proc; zombies are not living)."""
    parents = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2 :].split()
        if fields[0] != "Z":
            parents[int(entry.name)] = int(fields[1])
    out: dict[int, int] = {}
    frontier = [root]
    while frontier:
        pid = frontier.pop()
        for child, parent in parents.items():
            if parent == pid and child not in out:
                out[child] = parent
                frontier.append(child)
    return out


def _workers(tree: dict[int, int]) -> list[int]:
    """The processes of ``tree`` forked by a multiprocessing fork server (the pool's workers)."""
    out = []
    for pid, parent in tree.items():
        try:
            if b"forkserver" in Path(f"/proc/{parent}/cmdline").read_bytes():
                out.append(pid)
        except OSError:
            continue
    return out


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat[stat.rindex(")") + 2] != "Z"


def _spawned(tree: dict[int, int]) -> list[int]:
    """The processes of ``tree`` started by multiprocessing's spawn (a local Dask cluster's workers)."""
    out = []
    for pid in tree:
        try:
            if b"spawn_main" in Path(f"/proc/{pid}/cmdline").read_bytes():
                out.append(pid)
        except OSError:
            continue
    return out


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads the process tree from /proc (Linux)")
@pytest.mark.skipif(local_cores() < 2, reason="needs two cores for two worker processes")
@pytest.mark.parametrize(("scheduler", "how"), [("local", "ctrl-c"), ("dask", "ctrl-c"), ("local", "sigterm")])
def test_ctrl_c_during_a_monte_carlo_on_workers_is_one_line_and_leaves_no_process(tmp_path: Path, scheduler: str, how: str) -> None:
    """``fdisyn evaluate`` of a long campaign over two worker processes (a pool, or a local Dask cluster), in its own
    process group: SIGINT to the whole group (what a terminal's Ctrl-C does) once the workers run ends it with
    status 130, exactly one line on stderr, and no process of its tree left; SIGTERM to the command alone (kill,
    timeout) likewise with status 143."""
    if scheduler == "dask":
        pytest.importorskip("dask.distributed")
    spec = tmp_path / "dc_motor.toml"
    spec.write_text((EXAMPLES / "dc_motor.toml").read_text(encoding="utf-8"), encoding="utf-8")
    argv = [sys.executable, "-m", "fdisyn.app.cli", "--quiet", "evaluate", str(spec), "--runs", "1000000", "--workers", "2",
            "--scheduler", scheduler, "--out", str(tmp_path / "m.json"), "--workdir", str(tmp_path / "wd")]
    # Ctrl-C at its default, as in a terminal's foreground command: a suite started as a background job of a
    # non-interactive shell inherits SIGINT ignored, and Python then keeps ignoring it
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True, cwd=tmp_path,
                            preexec_fn=_default_sigint)
    seen: dict[int, int] = {}

    def working(tree: dict[int, int]) -> bool:
        if scheduler == "local":  # a worker: a process forked by the fork server
            return bool(_workers(tree))
        # the cluster is up before the design is built: its library means the runs are about to start
        return bool(_spawned(tree)) and any((tmp_path / "wd").rglob("*.so"))

    try:
        deadline = time.monotonic() + 240  # design and compile on a loaded machine: bounded, not timed
        while time.monotonic() < deadline and proc.poll() is None:
            tree = _descendants(proc.pid)
            seen.update(tree)
            if working(tree):
                break
            time.sleep(0.1)
        assert proc.poll() is None, proc.communicate()
        assert working(seen), "no worker process started"
        time.sleep(0.5)  # let the workers start on their chunks (what is tested holds whenever the signal comes)
        seen.update(_descendants(proc.pid))
        if how == "ctrl-c":
            os.killpg(proc.pid, signal.SIGINT)
        else:
            os.kill(proc.pid, signal.SIGTERM)
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:  # pragma: no cover - the test failed: leave nothing running
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    status, line = (130, "interrupted") if how == "ctrl-c" else (143, "terminated")
    assert proc.returncode == status, err.decode()
    assert err.decode() == f"fdisyn evaluate: {line}\n"
    assert out == b"" and not (tmp_path / "m.json").exists()
    deadline = time.monotonic() + 30  # the fork server leaves when the command has gone
    while time.monotonic() < deadline and any(_alive(pid) for pid in seen):
        time.sleep(0.1)
    assert not [pid for pid in seen if _alive(pid)]
