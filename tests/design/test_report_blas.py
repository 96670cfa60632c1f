"""``fdisyn reproduce`` and ``fdisyn report`` run their linear algebra on one OpenBLAS kernel and one thread on every
x86-64 CPU, so that the designs they publish do not depend on the machine. Checked by asking the OpenBLAS that
NumPy loaded which kernel and how many threads it runs (``scipy_openblas_get_corename64_``)."""

from __future__ import annotations

import platform
import subprocess
import sys

import pytest
from fdisyn.app.cli import REPORT_BLAS, pin_report_blas

PROBE = r"""
import ctypes, os, sys
{pin}
import numpy
names = []
for path in sorted({{l.split()[-1] for l in open("/proc/self/maps") if "openblas" in l.lower() and l.split()[-1].startswith("/")}}):
    lib = ctypes.CDLL(path)
    for sym in ("scipy_openblas_get_corename64_", "scipy_openblas_get_corename", "openblas_get_corename64_", "openblas_get_corename"):
        if hasattr(lib, sym):
            core, threads = getattr(lib, sym), getattr(lib, sym.replace("corename", "num_threads"))
            core.restype = ctypes.c_char_p
            names.append(f"{{core().decode()}}/{{threads()}}")
            break
print(" ".join(names))
"""

pytestmark = pytest.mark.skipif(
    platform.machine().lower() not in ("x86_64", "amd64") or not sys.platform.startswith("linux"),
    reason="the kernel is pinned on x86-64 only, and probed through /proc/self/maps",
)


def _probe(pin: str, env: dict[str, str] | None = None) -> str:
    done = subprocess.run([sys.executable, "-c", PROBE.format(pin=pin)], capture_output=True, text=True, env=env, check=True)
    return done.stdout.strip()


def test_the_report_commands_pin_the_kernel_and_one_thread() -> None:
    pinned = _probe("from fdisyn.app.cli import pin_report_blas; assert pin_report_blas()")
    assert pinned and set(pinned.split()) == {f"{REPORT_BLAS['OPENBLAS_CORETYPE']}/1"}, pinned


def test_the_pin_replaces_the_users_own_kernel() -> None:
    import os

    env = {**os.environ, "OPENBLAS_CORETYPE": "SandyBridge", "OPENBLAS_NUM_THREADS": "2"}
    assert {name.lower() for name in _probe("", env).split()} == {"sandybridge/2"}  # the user's choice, unpinned
    pinned = _probe("from fdisyn.app.cli import pin_report_blas; assert pin_report_blas()", env)
    assert set(pinned.split()) == {f"{REPORT_BLAS['OPENBLAS_CORETYPE']}/1"}, pinned


def test_once_numpy_is_loaded_the_kernel_is_left_as_it_is() -> None:
    import numpy  # noqa: F401  (loaded by this process already: OpenBLAS has read its environment)

    assert pin_report_blas() is False
