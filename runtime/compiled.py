"""Load a compiled diagnoser (``lib<prefix>.so``; ``.dylib`` on macOS, ``.dll`` on Windows) with ctypes.

A library runs only the gain file it was built from, and only once it is
known to be the file ``fdisyn codegen`` wrote:

1. ``fdisyn codegen`` writes a build manifest next to the library
   (``lib<prefix>.manifest.json``: the library's sha256, the gain file's
   content hash and the sha256 of the bytes of the ``gains.json`` it read,
   see :func:`write_manifest`), and compiles into the library a build mark:
   the fixed text :data:`BUILD_MARK` followed by the gain file's content hash;
2. before ``dlopen`` (:func:`_check_before_loading`), the loader compares
   the bytes of the ``gains.json`` beside the library with the manifest's
   record (a gain file rewritten after ``fdisyn codegen``, or a build copied
   in from another folder, is refused with :data:`STALE_BUILD`, the line the
   C replay prints too); the manifest's content hash with the gain file it
   is given; the library file's sha256 with the manifest's (a truncated,
   corrupted or replaced file never reaches the dynamic loader); and the
   build mark found in the library file's bytes with the gain file (a
   library built from another gain file, even with a manifest rewritten to
   match it, is refused before any of its code runs). A library this process
   already loaded from the same path for another gain file is refused too:
   the dynamic loader would hand back the old one;
3. after loading, the hash the library reports
   (``<prefix>_gain_file_sha256()``) and its sizes (``<prefix>_dims``) must
   match the gain file too.

These checks catch stale, mixed and accidentally replaced builds. They are
no defence against someone who can write the folder: the hashes are public
and anyone can build a library with the right mark (or replace the gain file
and ``replay`` together).

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
import os
import re
import stat
import sys
from pathlib import Path

import numpy as np
from fdisyn.runtime.errors import BuildError
from fdisyn.runtime.gainfile import GainFile, gain_file_sha256
from fdisyn.runtime.jsondata import parse_json_data, read_regular_file
from fdisyn.runtime.reference import RunResult, StepOutput, sample_block, sample_vector, step_state
from fdisyn.runtime.trace import shown_path

__all__ = [
    "BUILD_MARK",
    "CompiledDiagnoser",
    "MANIFEST_FORMAT",
    "STALE_BUILD",
    "library_path",
    "library_suffix",
    "manifest_path",
    "stale_build_message",
    "write_manifest",
    "file_sha256",
]

MANIFEST_FORMAT = "fdisyn.build/2"
_MANIFEST_BYTES = 1 << 16  # a manifest holds three hashes and a file name: ~300 bytes

BUILD_MARK = b"fdisyn build mark: gain file sha256 "
"""The text the generated library carries just before its gain file's content hash (64 hex digits): the
loader finds the hash in the library file's bytes and compares it before ``dlopen``."""

STALE_BUILD = (
    "%s is not the gain file the compiled diagnoser in %s was built from (sha256 of its bytes %.16s…, built from "
    "%.16s…): it changed after the build, or the build was copied from another folder; run `fdisyn codegen %s`"
)
"""The refusal of a build beside another gain file, one text for both replays: ``fdisyn codegen`` compiles it
into ``replay`` as its ``printf`` format, and Python fills it with ``%`` (:func:`stale_build_message`). Its
arguments: the gain file and its folder (as :func:`~fdisyn.runtime.trace.shown_path` shows them), the sha256 of
the file's bytes, the one the build was made from, the folder again."""

_HEX64 = re.compile(rb"[0-9a-f]{64}")
_LOADED: dict[str, str] = {}
"""The libraries this process loaded: resolved path → the gain-file hash the loaded code reports ("" if none).
The dynamic loader returns the library already loaded from a path, however the file changed since."""

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


def stale_build_message(directory: str | Path, have: str, built: str) -> str:
    """:data:`STALE_BUILD` for the build in ``directory``, whose ``gains.json`` bytes hash to ``have`` but was built
    from a file whose bytes hash to ``built``: the line both replays print."""
    d = Path(directory)
    shown_dir = shown_path(str(d))
    return STALE_BUILD % (shown_path(str(d / "gains.json")), shown_dir, have, built, shown_dir)


def write_manifest(library: str | Path, gain_sha256: str, gain_file_bytes_sha256: str | None = None, *, precision: str = "double") -> Path:
    """Record what ``library`` is.

    Parameters
    ----------
    library : str or Path
        The compiled library.
    gain_sha256 : str
        The content hash of the gain file it was built from (:func:`~fdisyn.runtime.gainfile.gain_file_sha256`).
    gain_file_bytes_sha256 : str, optional
        The sha256 of the bytes of the ``gains.json`` beside it that ``fdisyn codegen`` read; ``None`` for a
        library built from a gain file that is not on disk (the check of the file beside it is then skipped).
    precision : str
        What the step computes in: ``"double"``, or ``"single"`` (``fdisyn codegen --precision single``); a record
        for the reader, not checked by the loader (both builds have the same double API).

    Returns
    -------
    Path
        The manifest written (:func:`manifest_path`).
    """
    lib = Path(library)
    doc = {
        "format": MANIFEST_FORMAT,
        "library": lib.name,
        "library_sha256": file_sha256(lib),
        "gain_file_sha256": gain_sha256,
        "gain_file_bytes_sha256": gain_file_bytes_sha256,
        "precision": precision,
    }
    out = manifest_path(lib)
    if out.is_symlink():  # a planted link would be followed and its target overwritten
        out.unlink()
    out.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    return out


def _regular_file(path: Path, what: str, again: str) -> int:
    """A read-only descriptor of ``path``, which must be a regular file (a FIFO opens without waiting for a writer)."""
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise BuildError(f"{path} is not a regular file (a device, a FIFO or a directory); expected {what}; {again}")
    return fd


def _file_facts(path: Path, what: str, again: str, *, marks: bool = False) -> tuple[str, list[str]]:
    """The sha256 of a regular file's bytes and, with ``marks``, what follows each :data:`BUILD_MARK` in them
    (64 hex digits, or what stands there instead), read in one pass of 1 MiB chunks."""
    h = hashlib.sha256()
    found: list[str] = []
    mark, span = BUILD_MARK, len(BUILD_MARK) + 64
    tail = b""
    with os.fdopen(_regular_file(path, what, again), "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
            if not marks:
                continue
            buf = tail + chunk
            at = buf.find(mark)
            while at >= 0 and at + span <= len(buf):  # a whole mark and hash: never seen whole in an earlier tail
                found.append(buf[at + len(mark) : at + span].decode("ascii", "replace"))
                at = buf.find(mark, at + 1)
            tail = buf[-(span - 1) :] if at < 0 else buf[at:]  # an unfinished mark waits for the next chunk
    if marks and tail.find(mark) >= 0:
        found.append(tail[tail.find(mark) + len(mark) :].decode("ascii", "replace"))  # cut short by the end of the file
    return h.hexdigest(), found


def _check_before_loading(path: Path, gain_sha: str, *, gain_file: Path | None = None, marked: bool = False) -> None:
    """The checks of step 2 (module docstring): nothing unchecked reaches ``dlopen``.

    Parameters
    ----------
    path : Path
        The library.
    gain_sha : str
        What the manifest's ``gain_file_sha256`` must be: the content hash of the gain file to run.
    gain_file : Path, optional
        The gain file beside the library (``DIR/gains.json``): when it exists and the manifest records the
        sha256 of the bytes it was built from, its bytes must hash alike (else :data:`STALE_BUILD`).
    marked : bool
        The library is a diagnoser's: its bytes must carry :data:`BUILD_MARK` followed by ``gain_sha``.

    Raises
    ------
    BuildError
        Whichever check fails first, in one line with the remedy.
    """
    again = f"run `fdisyn codegen {path.parent}`"
    man = manifest_path(path)
    # regular files only: a library or manifest that leads to /dev/zero or a FIFO would be read forever
    if not path.is_file():
        raise BuildError(f"{path} is not a regular file (a device, a FIFO or a directory); {again}")
    try:
        text = read_regular_file(man, _MANIFEST_BYTES, "a build manifest", error=BuildError).decode("utf-8")
        doc = parse_json_data(text, str(man), "a build manifest", error=BuildError)
    except BuildError as exc:
        raise BuildError(f"{exc}; {again}") from None
    except FileNotFoundError:
        raise BuildError(f"{path} has no build manifest {man.name}: it was not built by `fdisyn codegen` or its build did not finish; {again}") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise BuildError(f"cannot read the build manifest {man} ({exc}); {again}") from None
    keys = ("library_sha256", "gain_file_sha256")
    if not isinstance(doc, dict) or doc.get("format") != MANIFEST_FORMAT or not all(isinstance(doc.get(k), str) for k in keys):
        raise BuildError(f"{man} is not a build manifest of format {MANIFEST_FORMAT!r}; {again}")
    built_bytes = doc.get("gain_file_bytes_sha256")
    if gain_file is not None and isinstance(built_bytes, str):
        try:
            have_bytes, _ = _file_facts(gain_file, "the gain file the library was built from", again)
        except FileNotFoundError:
            pass  # no gain file beside it: the library runs a GainFile given in memory, checked by its content hash
        except OSError as exc:
            raise BuildError(f"cannot read {gain_file}: {exc.strerror or exc}") from None
        else:
            if have_bytes != built_bytes:
                raise BuildError(stale_build_message(path.parent, have_bytes, built_bytes))
    built_from = doc["gain_file_sha256"]
    if built_from != gain_sha:
        raise BuildError(
            f"{path} was built from another gain file (sha256 {built_from[:16]}…; this gain file has {gain_sha[:16]}…); {again}"
        )
    try:
        have, marks = _file_facts(path, "a library", again, marks=marked)
    except OSError as exc:
        raise BuildError(f"cannot read {path}: {exc.strerror or exc}") from None
    if have != doc["library_sha256"]:
        raise BuildError(
            f"{path} is not the library `fdisyn codegen` built (sha256 {have[:16]}…, built {doc['library_sha256'][:16]}…): "
            f"it was truncated, corrupted or replaced; {again}"
        )
    if marked and not marks:
        raise BuildError(
            f"{path} carries no fdisyn build mark: it is not a library `fdisyn codegen` built (the file was replaced, "
            f"or built by an older fdisyn) and was not loaded; {again}"
        )
    other = next((m for m in marks if m != gain_sha), None)
    if other is not None:
        shown = other[:16] if _HEX64.fullmatch(other.encode("ascii", "replace")) else "(no hash)"
        raise BuildError(
            f"{path} holds the diagnoser of another gain file (its build mark: sha256 {shown}…; this gain file has "
            f"{gain_sha[:16]}…): the library file was replaced or built from another gain file, and was not loaded; {again}"
        )


def _ptr(a: np.ndarray, kind: type) -> object:
    return a.ctypes.data_as(kind)


class CompiledDiagnoser:
    """The C step of one diagnoser, callable per sample or over a whole trace.

    The library must have been built from ``gf`` (``fdisyn codegen`` writes its build mark and manifest);
    a library built from another gain file, or changed since, is refused before it is loaded.

    Parameters
    ----------
    library : str or Path
        The compiled library (``lib<name>.so`` beside ``gains.json``).
    gf : GainFile
        The gain file it was built from.

    Attributes
    ----------
    gf : GainFile
        The diagnoser.

    Raises
    ------
    BuildError
        No library at ``library``, one not built from ``gf`` (or changed since), or one this process
        loaded before from another gain file; the message says to run ``fdisyn codegen``.
    """

    def __init__(self, library: str | Path, gf: GainFile) -> None:
        path = Path(library)
        if not path.exists():
            raise BuildError(f"no compiled diagnoser at {path}; run `fdisyn codegen` on its directory first")
        gain_sha = gain_file_sha256(gf)
        _check_before_loading(path, gain_sha, gain_file=path.parent / "gains.json", marked=True)
        key = str(path.resolve())
        earlier = _LOADED.get(key)
        if earlier is not None and earlier != gain_sha:
            # the file passed every check, but the dynamic loader would hand back the library it loaded before
            was = f"built from another gain file (sha256 {earlier[:16]}…)" if earlier else "another library"
            raise BuildError(
                f"this process already loaded {path} when it was {was}, and a process loads a path only once: the "
                f"file was rebuilt since (this gain file has sha256 {gain_sha[:16]}…); start a new process"
            )
        try:
            self._lib = ctypes.CDLL(key)
        except OSError as exc:
            raise BuildError(f"cannot load {path}: {exc}") from exc
        _LOADED.setdefault(key, "")
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
        if not _LOADED[key]:
            _LOADED[key] = compiled_sha
        if compiled_sha != gain_sha:
            # the file passed the checks, so the loaded code is not that file: a library loaded from that path
            # outside this loader (the dynamic loader hands it back), or a file changed while it was loaded
            raise BuildError(
                f"the library loaded from {path} reports the gain file sha256 {compiled_sha[:16]}…, though its file carries "
                f"{gain_sha[:16]}…: this process had loaded another library from that path, or the file changed while it "
                f"was loaded; start a new process (and if it persists, run `fdisyn codegen {path.parent}`)"
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
        """The step's initial state (``<prefix>_init``): a new array of ``nstate`` entries."""
        s = np.zeros(self.gf.step.nstate)
        self._init(_ptr(s, _D))
        return s

    def step(self, state: np.ndarray, u: np.ndarray, y: np.ndarray) -> StepOutput:
        """One sample; ``state`` is updated in place.

        Parameters
        ----------
        state : numpy.ndarray
            The step's state: float64, contiguous, writeable, ``nstate`` long.
        u : numpy.ndarray
            The ``nu`` inputs of the sample.
        y : numpy.ndarray
            The ``ny`` outputs of the sample.

        Returns
        -------
        StepOutput
            Residuals, statistics, alarm, isolated fault and status of the sample.

        Raises
        ------
        ArgumentError
            ``u`` or ``y`` does not hold real numbers.
        ShapeError
            ``u`` or ``y`` has the wrong length, or ``state`` is not a writeable, contiguous float64 array
            of ``nstate`` entries (it is never converted: a copy would leave the caller's state unchanged).
        """
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
        """All samples of a trace in one C call.

        Parameters
        ----------
        U : numpy.ndarray
            The inputs, ``N × nu``.
        Y : numpy.ndarray
            The outputs, ``N × ny``.
        state : numpy.ndarray, optional
            The state to start from (copied; default: :meth:`init_state`).

        Returns
        -------
        RunResult
            Every sample's residuals, statistics, alarms and isolated faults, and the final state.

        Raises
        ------
        ArgumentError
            An array that does not hold real numbers.
        ShapeError
            An array of the wrong shape.
        """
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
