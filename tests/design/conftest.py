"""Test-only helper: compile a CasADi step Function to C with strict flags and run it via ctypes.

Not the project's code-generation pipeline: just enough to compile the
generated C exactly as a deployment would (``-std=c99 -O2 -Wall -Wextra
-Werror -pedantic``, no fast-math), load it and loop it over a record in C.
"""

from __future__ import annotations

import ctypes
import shutil
import subprocess
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

CFLAGS = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-pedantic", "-shared", "-fPIC"]

_WRAPPER = r"""
#include <string.h>
/* CasADi's generated functions take arguments (iw, mem…) they may not use. */
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-parameter"
#include "{source}"
#pragma GCC diagnostic pop

/* Run n steps in C: u, y, states, r, J are sample-major (sample k at offset k*size). */
int fdisyn_test_run(long long n, double *state, const double *u, const double *y, double *states,
                    double *r, double *J, double *alarm, double *isolated, double *status) {{
  casadi_int sz_arg, sz_res, sz_iw, sz_w;
  long long k;
  if ({name}_work(&sz_arg, &sz_res, &sz_iw, &sz_w)) return -1;
  {{
    const casadi_real *arg[sz_arg + 1];
    casadi_real *res[sz_res + 1];
    casadi_int iw[sz_iw + 1];
    casadi_real w[sz_w + 1];
    for (k = 0; k < n; ++k) {{
      arg[0] = state; arg[1] = u + k * {nu}; arg[2] = y + k * {ny};
      res[0] = states + k * {ns}; res[1] = r + k * {nr}; res[2] = J + k * {nj};
      res[3] = alarm + k; res[4] = isolated + k; res[5] = status + k;
      if ({name}(arg, res, iw, w, 0)) return 1;
      memcpy(state, states + k * {ns}, {ns} * sizeof(double));
    }}
  }}
  return 0;
}}
"""


@dataclass
class CStep:
    """A compiled step: ``run`` loops it in C over a record, like ``NafdfDesign.run``."""

    lib: ctypes.CDLL
    sizes: tuple[int, int, int, int, int]
    c_bytes: int

    def run(self, *, state: np.ndarray, u: np.ndarray, y: np.ndarray) -> dict[str, np.ndarray]:
        ns, nu, ny, nr, nj = self.sizes
        T = y.shape[0]
        st = np.ascontiguousarray(state, dtype=float).copy()
        uu = np.ascontiguousarray(np.asarray(u, dtype=float).reshape(T, nu))
        yy = np.ascontiguousarray(np.asarray(y, dtype=float).reshape(T, ny))
        out = {
            "state": np.zeros((T, ns)),
            "r": np.zeros((T, nr)),
            "J": np.zeros((T, nj)),
            "alarm": np.zeros(T),
            "isolated": np.zeros(T),
            "status": np.zeros(T),
        }
        ptr = ctypes.POINTER(ctypes.c_double)

        def p(a: np.ndarray) -> object:
            return a.ctypes.data_as(ptr)

        rc = self.lib.fdisyn_test_run(
            ctypes.c_longlong(T), p(st), p(uu), p(yy), p(out["state"]), p(out["r"]), p(out["J"]),
            p(out["alarm"]), p(out["isolated"]), p(out["status"]),
        )
        if rc != 0:
            raise RuntimeError(f"the compiled step returned {rc}")
        return out


def compile_step(fun: ca.Function, workdir: Path) -> CStep:
    """Generate ``fun`` to C, compile it with the strict flags, load it."""
    gcc = shutil.which("gcc")
    if gcc is None:
        raise RuntimeError("gcc is required to check the generated C")
    name = fun.name()
    src = f"{name}.c"
    cg = ca.CodeGenerator(src, {"with_header": False})
    cg.add(fun)
    cg.generate(str(workdir) + "/")
    sizes = (fun.nnz_in(0), fun.nnz_in(1), fun.nnz_in(2), fun.nnz_out(1), fun.nnz_out(2))
    ns, nu, ny, nr, nj = sizes
    wrapper = workdir / f"{name}_wrapper.c"
    wrapper.write_text(_WRAPPER.format(source=src, name=name, ns=ns, nu=nu, ny=ny, nr=nr, nj=nj))
    lib = workdir / f"lib{name}.so"
    proc = subprocess.run([gcc, *CFLAGS, str(wrapper), "-o", str(lib), "-lm"], capture_output=True, text=True, cwd=workdir)
    if proc.returncode != 0:
        raise RuntimeError(f"gcc failed on the generated C:\n{proc.stderr[:4000]}")
    dll = ctypes.CDLL(str(lib))
    dll.fdisyn_test_run.restype = ctypes.c_int
    return CStep(lib=dll, sizes=sizes, c_bytes=(workdir / src).stat().st_size)


@pytest.fixture(scope="session")
def c_compiler(tmp_path_factory: pytest.TempPathFactory) -> Callable[[ca.Function], CStep]:
    """``c_compiler(step)`` → a :class:`CStep` compiled in a fresh temporary directory."""

    def build(fun: ca.Function) -> CStep:
        return compile_step(fun, tmp_path_factory.mktemp(f"c_{fun.name()}"))

    return build
