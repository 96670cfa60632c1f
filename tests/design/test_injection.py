"""Gain files are data: compiling and loading one never executes anything it carries.

A fault name that closes its C string literal, or a ``problem`` that closes
its C comment, could define an ``__attribute__((constructor))`` function that
runs when the library is loaded. Such names are refused where they enter (the
gain-file reader), and the C generator escapes every string it writes anyway:
a :class:`GainFile` forced to hold them (bypassing validation) still yields C
in which they are inert text that reads back byte for byte. A control run
with the escaping switched off shows that the payload is live, so the test
would see an injection.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from fdisyn.app.cli import main
from fdisyn.codegen import library as cg
from fdisyn.runtime.errors import BuildError, GainFileError
from fdisyn.runtime.gainfile import gain_file_sha256, read_gain_file, write_gain_file

from tests.runtime.test_reference import toy

# open(path, O_WRONLY | O_CREAT, 0644) on Linux: a constructor that leaves a marker file when it runs
_PWN = 'extern int open(const char *, int, ...); __attribute__((constructor)) static void pwn{k}(void) {{ open("{marker}", 65, 420); }}'


def hostile_literal(marker) -> str:  # noqa: ANN001 - a path
    """A name that closes ``<prefix>_fault_names[] = {"…"`` and defines a constructor."""
    return 'x", 0}; ' + _PWN.format(k=1, marker=marker) + ' const char *fdisyn_y[] = {"'


def hostile_comment(marker) -> str:  # noqa: ANN001 - a path
    """A ``problem`` that closes the header's ``/* … */`` comment and defines a constructor."""
    return "*/ " + _PWN.format(k=2, marker=marker) + " /*"


ODD = ("back\\slash", "tri??/graph", "new\nline\ttab", "ünï€7", '@PREFIX@ "q"', "\x01" + "7", "\x7f*/")
"""Names that need escaping: a backslash, a trigraph, control characters, non-ASCII followed by a
digit (a hex escape would swallow it), a template placeholder, a comment end."""

_READ_BACK = r"""
import ctypes, json, sys
lib = ctypes.CDLL(sys.argv[1])
prefix, counts = sys.argv[2], json.loads(sys.argv[3])
out = {}
for table, n in counts.items():
    arr = (ctypes.c_char_p * (n + 1)).in_dll(lib, prefix + "_" + table)
    out[table] = [arr[i].hex() for i in range(n)] + [arr[n]]
sha = getattr(lib, prefix + "_gain_file_sha256")
sha.restype = ctypes.c_char_p
out["sha256"] = sha().decode()
print(json.dumps(out))
"""


def _forced(tmp_path):
    """The toy gain file with hostile and odd strings forced in around the validation."""
    marker = tmp_path / "MARKER"
    gf = toy()
    object.__setattr__(gf, "faults", (hostile_literal(marker), ODD[0] + ODD[1], ODD[2] + ODD[3]))
    object.__setattr__(gf, "inputs", (ODD[4],))
    object.__setattr__(gf, "outputs", (ODD[5], ODD[6]))
    object.__setattr__(gf, "problem", hostile_comment(marker))
    object.__setattr__(gf, "design", "??/\n" + hostile_comment(marker))
    return gf, marker


def _build_and_load(gf, tmp_path, script=_READ_BACK):  # noqa: ANN001, ANN202 - a GainFile, a path, a script
    """Generate, compile, then load the library (running ``script``) and start the replay program, in fresh processes."""
    cg.generate_sources(gf, tmp_path / "c")
    lib, replay = cg.compile_sources(gf, tmp_path / "c", tmp_path)
    counts = {"input_names": len(gf.inputs), "output_names": len(gf.outputs), "fault_names": len(gf.faults)}
    proc = subprocess.run([sys.executable, "-c", script, str(lib), gf.name, json.dumps(counts)], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    usage = subprocess.run([str(replay)], capture_output=True, text=True, timeout=60)  # no arguments: prints its usage
    assert usage.returncode == 2 and "usage" in usage.stderr
    return json.loads(proc.stdout or "null")


def test_forced_hostile_strings_are_inert_and_read_back_byte_for_byte(tmp_path):
    gf, marker = _forced(tmp_path)
    back = _build_and_load(gf, tmp_path)
    assert not marker.exists(), "a constructor carried by the gain file ran"
    for table, names in (("input_names", gf.inputs), ("output_names", gf.outputs), ("fault_names", gf.faults)):
        assert back[table] == [n.encode("utf-8").hex() for n in names] + [None], table
    assert back["sha256"] == gain_file_sha256(gf)
    header = (tmp_path / "c" / "toy.h").read_text()
    comment = header[: header.index("*/") + 2]
    assert comment.count("pwn2(void)") == 2 and "%2A%2F extern int open" in comment  # both payloads are text inside it


def test_the_payload_is_live_without_escaping(tmp_path, monkeypatch):
    """Control: with plain quoting, the same strings define constructors that run on loading."""
    monkeypatch.setattr(cg, "c_string_literal", lambda text: f'"{text}"')
    monkeypatch.setattr(cg, "c_comment_text", lambda text: text)
    gf, marker = _forced(tmp_path)
    object.__setattr__(gf, "faults", (hostile_literal(marker), "y1", "both"))  # only names that compile unescaped
    object.__setattr__(gf, "inputs", ("u",))
    object.__setattr__(gf, "outputs", ("y0", "y1"))
    object.__setattr__(gf, "design", "toy")
    _build_and_load(gf, tmp_path, script="import ctypes, sys; ctypes.CDLL(sys.argv[1])")
    assert marker.exists()
    marker.unlink()
    subprocess.run([str(tmp_path / "replay")], capture_output=True, timeout=60)  # the header's comment reaches the replay program too
    assert marker.exists()


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("faults", "literal", r"faults\[0\] 'x\", 0\}; extern int open.* is not a fault name"),
        ("problem", "comment", r"problem '\*/ extern int open.* is not a label"),
        ("design", "comment", r"design '\*/ extern int open.* is not a label"),
        ("inputs", "literal", r"inputs\[0\] .* is not a signal name"),
        ("outputs", "literal", r"outputs\[0\] .* is not a signal name"),
        ("name", "toy\"; int x; //", "cannot prefix the generated C API"),
    ],
)
def test_the_reader_refuses_hostile_strings(wt_built, tmp_path, field, value, message):
    doc = read_gain_file(wt_built.directory / "gains.json").to_dict()
    marker = tmp_path / "MARKER"
    text = {"literal": hostile_literal(marker), "comment": hostile_comment(marker)}.get(value, value)
    if isinstance(doc[field], list):
        doc[field][0] = text
    else:
        doc[field] = text
    p = tmp_path / "gains.json"
    p.write_text(json.dumps(doc))
    with pytest.raises(GainFileError, match=message):
        read_gain_file(p)


def test_codegen_of_a_hostile_gain_file_stops_with_one_line(wt_built, tmp_path, capsys):
    doc = read_gain_file(wt_built.directory / "gains.json").to_dict()
    doc["faults"][2] = hostile_literal(tmp_path / "MARKER")
    (tmp_path / "gains.json").write_text(json.dumps(doc, indent=2))
    assert main(["codegen", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "faults[2]" in err and "is not a fault name" in err
    assert not (tmp_path / "c").exists()  # nothing was generated


def test_a_forced_name_never_reaches_identifiers(tmp_path):
    gf = toy()
    for bad in ("toy__x", "toy(void); int pwn", "replay"):
        object.__setattr__(gf, "name", bad)
        with pytest.raises(GainFileError, match="name"):
            cg.generate_sources(gf, tmp_path / "c")
        assert not (tmp_path / "c").exists()


def test_a_valid_gain_file_round_trips_its_names_through_the_writer(tmp_path):
    # the escaping is invisible for valid names: the C literals are the names themselves
    gf = toy()
    write_gain_file(gf, tmp_path / "gains.json")
    cg.generate_sources(read_gain_file(tmp_path / "gains.json"), tmp_path / "c")
    src = (tmp_path / "c" / "toy.c").read_text()
    assert 'toy_fault_names[] = {"y0", "y1", "both", 0};' in src
    assert 'toy_input_names[] = {"u", 0};' in src


def test_codegen_never_writes_through_a_link_planted_in_the_folder(tmp_path):
    """A received folder may hold links where codegen writes (``c/tools/replay.c``, ``c/build.log``, the
    manifest, CasADi's file): followed, they would overwrite any file of the user (``~/.bashrc``).
    Each is replaced by a fresh file; the files they point to stay as they were."""
    gf = toy()
    d = tmp_path / "toy"
    write_gain_file(gf, d / "gains.json")
    victims = {}
    for rel in ("c/tools/replay.c", "c/build.log", f"c/{gf.name}_casadi.c", f"c/{gf.name}.h", f"lib{gf.name}.manifest.json"):
        victim = tmp_path / f"victim_{len(victims)}.txt"
        victim.write_text("mine\n")
        (d / rel).parent.mkdir(parents=True, exist_ok=True)
        (d / rel).symlink_to(victim)
        victims[rel] = victim
    assert main(["codegen", str(d)]) == 0
    for rel, victim in victims.items():
        assert victim.read_text() == "mine\n", rel
        assert not (d / rel).is_symlink() and (d / rel).stat().st_size > 0, rel
    # the folder for the C is the tool's own: a link there is refused, not followed
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    d2 = tmp_path / "toy2"
    write_gain_file(gf, d2 / "gains.json")
    (d2 / "c").symlink_to(elsewhere)
    with pytest.raises(BuildError, match=r"c is a symbolic link; expected a folder of its own for the generated C"):
        cg.generate_sources(read_gain_file(d2 / "gains.json"), d2 / "c")
    assert list(elsewhere.iterdir()) == []
    # and so is a link as the folder of the programs, c/tools
    (d2 / "c").unlink()
    (d2 / "c").mkdir()
    (d2 / "c" / "tools").symlink_to(elsewhere)
    with pytest.raises(BuildError, match=r"tools is a symbolic link; expected the folder `fdisyn codegen` writes the replay"):
        cg.generate_sources(read_gain_file(d2 / "gains.json"), d2 / "c")
    assert list(elsewhere.iterdir()) == []
