"""Load a compiled diagnoser (``lib<prefix>.so``) with ctypes.

The library must match its gain file: the loader compares the sizes the
library reports (``<prefix>_dims``) with the gain file's ``step`` section and
refuses a mismatch, so a stale library is never run against a new design.
"""

from __future__ import annotations

import ctypes
from pathlib import Path

import numpy as np
from fdisyn.runtime.errors import BuildError, ShapeError
from fdisyn.runtime.gainfile import GainFile
from fdisyn.runtime.reference import RunResult, StepOutput

__all__ = ["CompiledDiagnoser", "library_path"]

_D = ctypes.POINTER(ctypes.c_double)
_I = ctypes.POINTER(ctypes.c_int)


def library_path(directory: str | Path, gf: GainFile) -> Path:
    """Where ``fdisyn codegen`` puts the shared library of ``gf`` in ``directory``."""
    return Path(directory) / f"lib{gf.name}.so"


def _ptr(a: np.ndarray, kind: type) -> object:
    return a.ctypes.data_as(kind)


class CompiledDiagnoser:
    """The C step of one diagnoser, callable per sample or over a whole trace."""

    def __init__(self, library: str | Path, gf: GainFile) -> None:
        path = Path(library)
        if not path.exists():
            raise BuildError(f"no compiled diagnoser at {path}; run `fdisyn codegen` on its directory first")
        try:
            self._lib = ctypes.CDLL(str(path.resolve()))
        except OSError as exc:
            raise BuildError(f"cannot load {path}: {exc}") from exc
        p = gf.name
        try:
            self._init = getattr(self._lib, f"{p}_init")
            self._step = getattr(self._lib, f"{p}_step")
            self._run = getattr(self._lib, f"{p}_run")
            dims_fn = getattr(self._lib, f"{p}_dims")
        except AttributeError as exc:
            raise BuildError(f"{path} is not the library of diagnoser {p!r}: {exc}") from exc
        self._init.argtypes = [_D]
        self._init.restype = None
        self._step.argtypes = [_D, _D, _D, _D, _D, _I, _I]
        self._step.restype = ctypes.c_int
        self._run.argtypes = [_D, ctypes.c_long, _D, _D, _D, _D, _I, _I, _I]
        self._run.restype = ctypes.c_long
        dims = (ctypes.c_int * 6)()
        dims_fn.argtypes = [ctypes.POINTER(ctypes.c_int * 6)]
        dims_fn(ctypes.byref(dims))
        st = gf.step
        want = (st.nu, st.ny, st.nr, st.nj, st.nstate, len(gf.faults))
        if tuple(dims) != want:
            raise BuildError(
                f"{path} was built for sizes (nu, ny, nr, nj, nstate, nfaults) = {tuple(dims)}, "
                f"but the gain file says {want}; regenerate it with `fdisyn codegen`"
            )
        self.gf = gf
        self.path = path
        # scratch buffers for the per-sample call (u may be empty: keep one slot)
        self._u = np.zeros(max(st.nu, 1))
        self._y = np.zeros(st.ny)
        self._r = np.zeros(max(st.nr, 1))
        self._j = np.zeros(max(st.nj, 1))
        self._alarm = ctypes.c_int(0)
        self._iso = ctypes.c_int(-1)

    def init_state(self) -> np.ndarray:
        s = np.zeros(self.gf.step.nstate)
        self._init(_ptr(s, _D))
        return s

    def step(self, state: np.ndarray, u: np.ndarray, y: np.ndarray) -> StepOutput:
        """One sample; ``state`` (float64, contiguous) is updated in place."""
        st = self.gf.step
        if state.dtype != np.float64 or not state.flags.c_contiguous or state.shape != (st.nstate,):
            raise ShapeError(f"state must be a contiguous float64 vector of length {st.nstate}")
        self._u[: st.nu] = np.asarray(u, dtype=float).reshape(st.nu)
        self._y[:] = np.asarray(y, dtype=float).reshape(st.ny)
        rc = self._step(
            _ptr(state, _D),
            _ptr(self._u, _D),
            _ptr(self._y, _D),
            _ptr(self._r, _D),
            _ptr(self._j, _D),
            ctypes.byref(self._alarm),
            ctypes.byref(self._iso),
        )
        if rc < 0:
            raise BuildError(f"the compiled step of {self.gf.name!r} reported an internal error ({rc})")
        return StepOutput(
            r=self._r[: st.nr].copy(),
            J=self._j[: st.nj].copy(),
            alarm=int(self._alarm.value),
            isolated=int(self._iso.value),
            status=int(rc),
        )

    def run(self, U: np.ndarray, Y: np.ndarray, state: np.ndarray | None = None) -> RunResult:
        """All samples of a trace in one C call (``U``: N × nu, ``Y``: N × ny)."""
        st = self.gf.step
        Y = np.ascontiguousarray(Y, dtype=np.float64)
        n = Y.shape[0]
        if Y.shape != (n, st.ny):
            raise ShapeError(f"Y must be N × {st.ny}; got {Y.shape}")
        U = np.ascontiguousarray(np.asarray(U, dtype=np.float64).reshape(n, st.nu))
        s = self.init_state() if state is None else np.array(state, dtype=np.float64)
        r = np.zeros((n, st.nr))
        jj = np.zeros((n, st.nj))
        alarm = np.zeros(n, dtype=np.intc)
        iso = np.zeros(n, dtype=np.intc)
        u_buf = U if st.nu else np.zeros((n, 1))
        status = np.zeros(n, dtype=np.intc)
        rc = self._run(
            _ptr(s, _D), n, _ptr(u_buf, _D), _ptr(Y, _D), _ptr(r, _D), _ptr(jj, _D), _ptr(alarm, _I), _ptr(iso, _I), _ptr(status, _I)
        )
        if rc < 0:
            raise BuildError(f"the compiled step of {self.gf.name!r} reported an internal error")
        return RunResult(r=r, J=jj, alarm=alarm.astype(int), isolated=iso.astype(int), status=status.astype(int), state=s)
