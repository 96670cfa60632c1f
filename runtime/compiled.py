"""Load a compiled diagnoser (``lib<prefix>.so``; ``.dylib`` on macOS, ``.dll`` on Windows) with ctypes.

A library runs only the gain file it was built from, and only once it is
known to be the file ``fdisyn codegen`` wrote:

1. ``fdisyn codegen`` writes a build manifest next to the library
   (``lib<prefix>.manifest.json``: the library's sha256 and the gain file's,
   see :func:`write_manifest`);
2. before ``dlopen``, the loader compares the manifest's gain-file hash with
   the gain file it is given (a library built from another gain file — e.g.
   after ``fdisyn design`` rewrote ``gains.json`` without ``fdisyn codegen``
   — is refused) and the library file's sha256 with the manifest's (a
   truncated, corrupted or replaced file never reaches the dynamic loader);
3. after loading, the hash compiled into the library
   (``<prefix>_gain_file_sha256()``) and its sizes (``<prefix>_dims``) must
   match the gain file too (the dynamic loader returns a library already
   loaded from the same path, even after the file was rebuilt: such a
   process is told to start anew).

Every array crosses into C only after the checks of
:mod:`fdisyn.runtime.reference` (:func:`sample_vector`, :func:`sample_block`,
:func:`step_state`): the compiled backend accepts and refuses exactly what
the NumPy reference does, with the same messages, and C never reads or
writes past an array.
"""

from __future__ import annotations

import ctypes
import hashlib
import json
import sys
from pathlib import Path

import numpy as np
from fdisyn.runtime.errors import BuildError
from fdisyn.runtime.gainfile import GainFile, gain_file_sha256, read_regular_file
from fdisyn.runtime.reference import RunResult, StepOutput, sample_block, sample_vector, step_state

__all__ = ["CompiledDiagnoser", "MANIFEST_FORMAT", "library_path", "library_suffix", "manifest_path", "write_manifest", "file_sha256"]

MANIFEST_FORMAT = "fdisyn.build/1"
_MANIFEST_BYTES = 1 << 16  # a manifest holds two hashes and a file name: ~250 bytes

_D = ctypes.POINTER(ctypes.c_double)
_I = ctypes.POINTER(ctypes.c_int)


def library_suffix(platform: str | None = None) -> str:
    """The file suffix of a shared library on ``platform`` (``sys.platform`` by default): ``.dylib`` on
    macOS, ``.dll`` on Windows (and Cygwin), ``.so`` elsewhere."""
    platform = sys.platform if platform is None else platform
    if platform == "darwin":
        return ".dylib"
    if platform in ("win32", "cygwin"):
        return ".dll"
    return ".so"


def library_path(directory: str | Path, gf: GainFile) -> Path:
    """Where ``fdisyn codegen`` puts the shared library of ``gf`` in ``directory``: ``lib<name>`` and
    :func:`library_suffix`."""
    return Path(directory) / f"lib{gf.name}{library_suffix()}"


def manifest_path(library: str | Path) -> Path:
    """The build manifest of ``library``: ``lib<prefix>.manifest.json`` beside it."""
    return Path(library).with_suffix(".manifest.json")


def file_sha256(path: str | Path) -> str:
    """sha256 (hex) of a file's bytes."""
    h = hashlib.sha256()
    with Path(path).open("rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def write_manifest(library: str | Path, gain_sha256: str) -> Path:
    """Record what ``library`` is: its own sha256 and that of the gain file it was built from."""
    lib = Path(library)
    doc = {
        "format": MANIFEST_FORMAT,
        "library": lib.name,
        "library_sha256": file_sha256(lib),
        "gain_file_sha256": gain_sha256,
    }
    out = manifest_path(lib)
    if out.is_symlink():  # a planted link would be followed and its target overwritten
        out.unlink()
    out.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    return out


def _check_before_loading(path: Path, gain_sha: str) -> None:
    """The manifest checks of steps 1–2 (module docstring): nothing unchecked reaches ``dlopen``."""
    again = f"run `fdisyn codegen {path.parent}`"
    man = manifest_path(path)
    # regular files only: a library or manifest that leads to /dev/zero or a FIFO would be read forever
    if not path.is_file():
        raise BuildError(f"{path} is not a regular file (a device, a FIFO or a directory); {again}")
    try:
        doc = json.loads(read_regular_file(man, _MANIFEST_BYTES, "a build manifest", error=BuildError).decode("utf-8"))
    except BuildError as exc:
        raise BuildError(f"{exc}; {again}") from None
    except FileNotFoundError:
        raise BuildError(f"{path} has no build manifest {man.name}: it was not built by `fdisyn codegen` or its build did not finish; {again}") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise BuildError(f"cannot read the build manifest {man} ({exc}); {again}") from None
    keys = ("library_sha256", "gain_file_sha256")
    if not isinstance(doc, dict) or doc.get("format") != MANIFEST_FORMAT or not all(isinstance(doc.get(k), str) for k in keys):
        raise BuildError(f"{man} is not a build manifest of format {MANIFEST_FORMAT!r}; {again}")
    built_from = doc["gain_file_sha256"]
    if built_from != gain_sha:
        raise BuildError(
            f"{path} was built from another gain file (sha256 {built_from[:16]}…; this gain file has {gain_sha[:16]}…); {again}"
        )
    try:
        have = file_sha256(path)
    except OSError as exc:
        raise BuildError(f"cannot read {path}: {exc}") from None
    if have != doc["library_sha256"]:
        raise BuildError(
            f"{path} is not the library `fdisyn codegen` built (sha256 {have[:16]}…, built {doc['library_sha256'][:16]}…): "
            f"it was truncated, corrupted or replaced; {again}"
        )


def _ptr(a: np.ndarray, kind: type) -> object:
    return a.ctypes.data_as(kind)


class CompiledDiagnoser:
    """The C step of one diagnoser, callable per sample or over a whole trace."""

    def __init__(self, library: str | Path, gf: GainFile) -> None:
        path = Path(library)
        if not path.exists():
            raise BuildError(f"no compiled diagnoser at {path}; run `fdisyn codegen` on its directory first")
        gain_sha = gain_file_sha256(gf)
        _check_before_loading(path, gain_sha)
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
            sha_fn = getattr(self._lib, f"{p}_gain_file_sha256")
        except AttributeError as exc:
            raise BuildError(f"{path} is not the library of diagnoser {p!r}: {exc}") from exc
        sha_fn.argtypes = []
        sha_fn.restype = ctypes.c_char_p
        compiled_sha = (sha_fn() or b"").decode("ascii", "replace")
        if compiled_sha != gain_sha:
            # the file on disk passed the manifest check, so the loaded code is not that file: the dynamic
            # loader hands back a library already loaded from the same path, however the file changed since
            raise BuildError(
                f"this process already runs an older build of {path} (sha256 of its gain file {compiled_sha[:16]}…; this "
                f"gain file has {gain_sha[:16]}…) and a library cannot be loaded twice from one path; start a new process"
            )
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
        # output buffers of the per-sample call (one slot at least: C never gets a zero-size array)
        self._r = np.zeros(max(st.nr, 1))
        self._j = np.zeros(max(st.nj, 1))
        self._alarm = ctypes.c_int(0)
        self._iso = ctypes.c_int(-1)

    def init_state(self) -> np.ndarray:
        s = np.zeros(self.gf.step.nstate)
        self._init(_ptr(s, _D))
        return s

    def step(self, state: np.ndarray, u: np.ndarray, y: np.ndarray) -> StepOutput:
        """One sample; ``state`` (float64, contiguous, writeable, nstate long) is updated in place."""
        st = self.gf.step
        s = step_state(state, st.nstate)
        uu = sample_vector(u, "u", st.nu)
        yy = sample_vector(y, "y", st.ny)
        u_buf = uu if st.nu else np.zeros(1)
        rc = self._step(
            _ptr(s, _D),
            _ptr(u_buf, _D),
            _ptr(yy, _D),
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
        """All samples of a trace in one C call (``U``: N × nu, ``Y``: N × ny; ``state`` copied)."""
        st = self.gf.step
        Yc = sample_block(Y, "Y", st.ny)
        n = Yc.shape[0]
        Uc = sample_block(U, "U", st.nu, rows=n)
        s = self.init_state() if state is None else sample_vector(state, "state", st.nstate)
        r = np.zeros((n, max(st.nr, 1)))
        jj = np.zeros((n, max(st.nj, 1)))
        alarm = np.zeros(max(n, 1), dtype=np.intc)
        iso = np.zeros(max(n, 1), dtype=np.intc)
        status = np.zeros(max(n, 1), dtype=np.intc)
        u_buf = Uc if st.nu and n else np.zeros(1)
        y_buf = Yc if n else np.zeros(1)
        rc = self._run(
            _ptr(s, _D), n, _ptr(u_buf, _D), _ptr(y_buf, _D), _ptr(r, _D), _ptr(jj, _D), _ptr(alarm, _I), _ptr(iso, _I), _ptr(status, _I)
        )
        if rc < 0:
            raise BuildError(f"the compiled step of {self.gf.name!r} reported an internal error")
        return RunResult(
            r=r[:, : st.nr],
            J=jj[:, : st.nj],
            alarm=alarm[:n].astype(int),
            isolated=iso[:n].astype(int),
            status=status[:n].astype(int),
            state=s,
        )
