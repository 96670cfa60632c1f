"""Hostile input through the command line, in-process (``fdisyn.app.cli.main``).

Every case ends with status 2 and exactly one line on stderr, ``fdisyn <command>: error: …``,
naming what is wrong and what was expected: no traceback, no value silently replaced. Two
seeded fuzzers then throw wrong types, NaN, huge, negative and malformed values at
``--option KEY=VALUE`` and at the values of the example plant files: status 0 or 2, never
another exception.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from fdisyn.app.cli import main
from fdisyn.app.examples import EXAMPLES
from fdisyn.runtime.errors import (
    ArgumentError,
    CertificateError,
    ExistenceError,
    FileError,
    InternalError,
    ShapeError,
    SolverError,
    SpecError,
)

DATA = EXAMPLES
MOTOR = (DATA / "dc_motor.toml").read_text(encoding="utf-8")
SAMPLED = (DATA / "sampled_data.toml").read_text(encoding="utf-8")
SHIP = (DATA / "ship.toml").read_text(encoding="utf-8")


def _status_and_lines(capsys: pytest.CaptureFixture[str], argv: list[str]) -> tuple[int, list[str]]:
    """Run the command; its status and its stderr lines, progress lines (``[problem] …``) left out."""
    status = main(argv)
    err = capsys.readouterr().err
    return status, [ln for ln in err.splitlines() if not ln.startswith("[")]


def _fails_with(capsys: pytest.CaptureFixture[str], argv: list[str], *expected: str) -> str:
    status, lines = _status_and_lines(capsys, argv)
    assert status == 2, (argv, lines)
    assert len(lines) == 1, lines
    line = lines[0]
    assert line.startswith(f"fdisyn {argv[0]}: error: "), line
    assert "Traceback" not in line
    for part in expected:
        assert part in line, (part, line)
    return line


def _file(tmp_path: Path, text: str, old: str, new: str, name: str = "plant.toml") -> str:
    assert old in text, old
    p = tmp_path / name
    p.write_text(text.replace(old, new, 1), encoding="utf-8")
    return str(p)


# --------------------------------------------------------------------------- plant-file values


PLANT_CASES: list[tuple[str, str, str, str, list[str], tuple[str, ...]]] = [
    # (id, file text, old, new, command after SPEC, expected parts of the error line)
    ("P_f zero", MOTOR, "arl0 = 3600.0 ", "P_f = 0 ", ["design"], ("[design].P_f = 0: expected", "(0, 1)")),
    ("P_f one", MOTOR, "arl0 = 3600.0 ", "P_f = 1.0 ", ["design"], ("[design].P_f = 1.0", "(0, 1)")),
    ("P_f nan", MOTOR, "arl0 = 3600.0 ", "P_f = nan ", ["design"], ("[design].P_f = nan",)),
    ("persistence 1.5", MOTOR, "arl0 = 3600.0 ", "arl0 = 3600.0\npersistence = 1.5 ", ["design"], ("[design].persistence = 1.5: expected a whole number",)),
    ("persistence 0", MOTOR, "arl0 = 3600.0 ", "arl0 = 3600.0\npersistence = 0 ", ["design"], ("[design].persistence = 0",)),
    ("period zero", MOTOR, 'inputs = [{ kind = "step"', 'inputs = [{ kind = "sine", period = 0.0', ["simulate"], ("[simulation].inputs[0].period must be a positive",)),
    ("signal kind", MOTOR, 'kind = "step"', 'kind = "ramp"', ["simulate"], ("[simulation].inputs[0].kind must be one of",)),
    ("scenario fault_free", MOTOR, 'name = "speed_sensor_offset"', 'name = "fault_free"', ["simulate"], ("'fault_free' is the built-in fault-free scenario",)),
    ("scenario twice", MOTOR, "[[scenarios]]", '[[scenarios]]\nname = "speed_sensor_offset"\nduration = 1.0\n\n[[scenarios]]', ["simulate"], ("[[scenarios]][1].name 'speed_sensor_offset' is already the name of [[scenarios]][0]",)),
    ("onset after the end", MOTOR, "onset = 5.0", "onset = 50.0", ["simulate"], ("[[scenarios]][0].onset = 50 s must lie in [0, duration = 10 s)",)),
    ("fault without onset", MOTOR, "onset = 5.0", "", ["simulate"], ("fault 'w_meas' needs an onset",)),
    ("sensor fault kind", MOTOR, 'kind = "offset"', 'kind = "bias"', ["simulate"], ("sensor_faults[0].kind must be one of",)),
    ("poles missing", MOTOR, 'method = "kalman_uio" ', 'method = "uio_pole_placement" ', ["design"], ("[design]: missing key 'poles'",)),
    ("poles a string", MOTOR, 'method = "kalman_uio" ', 'method = "uio_pole_placement"\npoles = "fast" ', ["design"], ("[design].poles must be a list of 3 real numbers",)),
    ("poles strings", MOTOR, 'method = "kalman_uio" ', 'method = "uio_pole_placement"\npoles = ["a", "b", "c"] ', ["design"], ("[design].poles must be a list of 3 real numbers",)),
    ("poles outside", MOTOR, 'method = "kalman_uio" ', 'method = "uio_pole_placement"\npoles = [0.5, 0.6, 1.5] ', ["design"], ("strictly inside the unit circle",)),
    ("poles for another method", MOTOR, "arl0 = 3600.0 ", "arl0 = 3600.0\npoles = [0.5, 0.6, 0.7] ", ["design"], ("[design].poles is read only by method 'uio_pole_placement'",)),
    ("duration below one sample", MOTOR, "duration = 10.0\n#", "duration = 0.0004\n#", ["simulate"], ("[simulation].duration = 0.0004 s is shorter than one sample: expected at least Ts = 0.001 s",)),
    ("duration huge", MOTOR, "duration = 10.0\n#", "duration = 1e12\n#", ["simulate"], ("is 1e+15 samples at Ts = 0.001 s: expected at most 1e+06 samples per run",)),
    ("Ts huge", MOTOR, "Ts = 0.001 ", "Ts = 1e12 ", ["design"], ("[model]: Ts = 1e+12 s is too long to sample this model", "expected Ts < 7.285 s")),
    ("Ts negative", MOTOR, "Ts = 0.001 ", "Ts = -0.001 ", ["design"], ("[model].Ts must be a positive sample time",)),
    ("x0 nan", MOTOR, "x0 = [0.4, 0.0, 0.0]", "x0 = [nan, 0.0, 0.0]", ["simulate"], ("[simulation].x0 must hold finite numbers",)),
    ("bank unknown output", MOTOR, '["w_meas", "theta_meas"]]', '["w_meas", "rpm"]]', ["design"], ("[design].bank[1][1]: no output 'rpm'",)),
    ("bank empty", MOTOR, 'bank = [["i_meas", "theta_meas"], ["w_meas", "theta_meas"]]', "bank = []", ["design"], ("[design].bank is empty; expected groups of outputs",)),
    ("bank repeats", MOTOR, '["w_meas", "theta_meas"]]', '["w_meas", "w_meas"]]', ["design"], ("[design].bank[1] names output 'w_meas' twice",)),
    # a group whose sensors the load reaches only through ~1e-9 of a sample (C E ~ Ts²): named, with the remedy
    ("weak C E", MOTOR.replace("duration = 10.0", "duration = 0.1").replace("onset = 5.0", "onset = 0.05"), "Ts = 0.001 ", "Ts = 0.000001 ", ["design"],
     ("[design].bank[0]: UIO for the outputs ['i_meas', 'theta_meas']", "C E is nearly zero", "remedy:")),
    ("Bd a scalar", SAMPLED, "Bd = [[0.1], [1.0]]", "Bd = 0", ["design"], ("[model].Bd must be a matrix (a list of rows), got 0",)),
    ("Bd zero", SAMPLED, "Bd = [[0.1], [1.0]]", "Bd = [[0.0], [0.0]]", ["design"], ("[design]: the disturbance direction E (Bd of Qiu, Wen & Jiang 2010, eq. (1)) is zero",)),
    ("h huge", SAMPLED, "h = 1.0", "h = 1e5", ["design"], ("[model]: h = 100000 s is too long to sample this model", "expected h < 354.9 s")),
    ("eta unknown", SAMPLED, 'method = "sampled_data_observer"', 'method = "lmi"\neta = "1"', ["design"], ("[design].eta = '1': expected one of ['inf', '2', '-']",)),
    ("persistence beyond a count", MOTOR, "arl0 = 3600.0 ", "arl0 = 3600.0\npersistence = 1000000000000 ", ["design"], ("[design].persistence = 1000000000000: expected a whole number ≥ 1 of consecutive exceedances, at most 1000000000",)),
    # numbers are numbers: NumPy would read "-100.0" and true as floats, and overflow on a huge integer
    ("A a string entry", MOTOR, "[[-100.0, -5.0, 0.0]", '[["-100.0", -5.0, 0.0]', ["design"], ("[model].A must be a matrix of numbers (a list of rows), got [['-100.0'",)),
    ("A a boolean entry", MOTOR, "[[-100.0, -5.0, 0.0]", "[[true, -5.0, 0.0]", ["design"], ("[model].A must be a matrix of numbers (a list of rows), got [[True",)),
    ("A a huge integer", MOTOR, "[[-100.0, -5.0, 0.0]", "[[-1" + "0" * 400 + ", -5.0, 0.0]", ["design"], ("[model].A must hold finite numbers",)),
    ("x0 a boolean", MOTOR, "x0 = [0.4, 0.0, 0.0]", "x0 = [true, 0.0, 0.0]", ["simulate"], ("[simulation].x0 must be a list of 3 numbers",)),
    ("state_scale a string", MOTOR, "state_scale = [1.0, 10.0, 1.0]", 'state_scale = ["1.0", 10.0, 1.0]', ["design"], ("[model].state_scale: state scaling must be 3 positive finite numbers",)),
    ("a matrix nested too deeply", MOTOR, "A = [[-100.0, -5.0, 0.0]", "A = " + "[" * 3000 + "1.0" + "]" * 3000 + "\nA0 = [[-100.0, -5.0, 0.0]", ["design"], ("its TOML is nested too deeply to be a plant file",)),
    ("ship Q a string", SHIP, "Q_sample = [[0.0]]", 'Q = [["0.0"]]', ["design"], ("[model].Q must hold numbers only; found '0.0'",)),
    ("ship Q a huge integer", SHIP, "Q_sample = [[0.0]]", "Q = [[" + "9" * 400 + "]]", ["design"], ("[model].Q holds an integer beyond the range of a double",)),
    ("ship nominal a string", SHIP, "nominal = { a = -0.58", 'nominal = { a = "-0.58"', ["design"], ("nominal value of parameter 'a' must be a number; found '-0.58'",)),
    ("ship nominal a huge integer", SHIP, "nominal = { a = -0.58", "nominal = { a = -" + "9" * 400, ["design"], ("nominal value of parameter 'a' must be finite",)),
    ("ship P0 a string", SHIP, "P0 = 100.0", 'P0 = "100"', ["design"], ("[design]: P0 must be a number or an array of numbers; got '100'",)),
    ("ship theta0 a boolean", SHIP, "theta0 = { a = 0.0", "theta0 = { a = false", ["design"], ("[design]: theta0 must be a number or an array of numbers",)),
    ("constants a string", SHIP, 'time = "nonlinear"', 'time = "nonlinear"\nconstants = "g"', ["design"], ("[model].constants must be a table",)),
]


@pytest.mark.parametrize(("text", "old", "new", "command", "expected"), [c[1:] for c in PLANT_CASES], ids=[c[0] for c in PLANT_CASES])
def test_a_bad_plant_file_value_is_one_line(tmp_path, capsys, text, old, new, command, expected) -> None:
    spec = _file(tmp_path, text, old, new)
    extra = {"design": ["--out", str(tmp_path / "d")], "simulate": ["--scenario", "fault_free", "--out", str(tmp_path / "t.csv")]}
    _fails_with(capsys, [command[0], spec, *extra[command[0]]], *expected)


# --------------------------------------------------------------------------- options and arguments


def _design(*extra: str) -> Callable[[Path], list[str]]:
    return lambda tmp: ["design", "wind_turbine", "--out", str(tmp / "d"), *extra]


ARGUMENT_CASES: list[tuple[str, Callable[[Path], list[str]], tuple[str, ...]]] = [
    ("P_f not a number", _design("--option", "P_f=abc"), ("problem 'wind_turbine': option P_f = 'abc': expected a false-alarm probability",)),
    ("P_f a list", _design("--option", "P_f=[1]"), ("option P_f = [1]",)),
    ("P_f NaN", _design("--option", "P_f=NaN"), ("option P_f = nan",)),
    ("persistence a word", _design("--option", "persistence=x"), ("option persistence = 'x': expected a whole number ≥ 1",)),
    ("persistence 1.5", _design("--option", "persistence=1.5"), ("option persistence = 1.5",)),
    ("parameters unknown", _design("--option", "parameters=foo"), ("no parameter set 'foo'", "'benchmark'")),
    ("parameters a number", _design("--option", "parameters=3"), ("option parameters = 3: expected a string",)),
    ("unknown option", _design("--option", "foo=1"), ("has no option(s) ['foo']; options: {'parameters'",)),
    ("option twice", _design("--option", "P_f=0.1", "--option", "P_f=0.2"), ("--option P_f is given twice",)),
    ("option without =", _design("--option", "P_f"), ("--option expects KEY=VALUE",)),
    ("unknown design", _design("--design", "magic"), ("has no design 'magic'",)),
    ("evaluate --runs 0", lambda tmp: ["evaluate", "wind_turbine", "--runs", "0", "--out", str(tmp / "m.json")], ("argument --runs: expected a whole number of runs ≥ 1, got '0'",)),
    ("evaluate --runs -5", lambda tmp: ["evaluate", "wind_turbine", "--runs", "-5", "--out", str(tmp / "m.json")], ("got '-5'",)),
    ("evaluate --runs 2.5", lambda tmp: ["evaluate", "wind_turbine", "--runs", "2.5", "--out", str(tmp / "m.json")], ("got '2.5'",)),
    ("report --runs 0", lambda tmp: ["report", "wind_turbine", "--runs", "0", "--reports", str(tmp)], ("argument --runs: expected a whole number of runs ≥ 1",)),
    ("evaluate --runs 1_0", lambda tmp: ["evaluate", "wind_turbine", "--runs", "1_0", "--out", str(tmp / "m.json")], ("argument --runs: expected a whole number of runs ≥ 1 written in the digits 0–9 alone, got '1_0'",)),
    ("evaluate --runs Arabic-Indic 1", lambda tmp: ["evaluate", "wind_turbine", "--runs", "\u0661", "--out", str(tmp / "m.json")], ("argument --runs: expected a whole number of runs ≥ 1 written in the digits 0–9 alone, got '\u0661'",)),
    ("evaluate --runs +5", lambda tmp: ["evaluate", "wind_turbine", "--runs", "+5", "--out", str(tmp / "m.json")], ("digits 0–9 alone, got '+5'",)),
    ("evaluate --runs blank", lambda tmp: ["evaluate", "wind_turbine", "--runs", " 5", "--out", str(tmp / "m.json")], ("digits 0–9 alone, got ' 5'",)),
    ("evaluate --runs 5000 digits", lambda tmp: ["evaluate", "wind_turbine", "--runs", "9" * 5000, "--out", str(tmp / "m.json")], ("argument --runs: expected a whole number of runs ≥ 1, got a number of 5000 digits",)),
    ("evaluate --workers fullwidth 2", lambda tmp: ["evaluate", "wind_turbine", "--workers", "\uff12", "--out", str(tmp / "m.json")], ("argument --workers: expected a whole number of worker processes ≥ 1 written in the digits 0–9 alone, got '\uff12'",)),
    ("evaluate --seed Devanagari 3", lambda tmp: ["evaluate", "wind_turbine", "--seed", "\u0969", "--out", str(tmp / "m.json")], ("argument --seed: expected a whole number ≥ 0 (NumPy seeds are non-negative) written in the digits 0–9 alone",)),
    ("simulate --seed 1_0", lambda tmp: ["simulate", "wind_turbine", "--scenario", "fault_free", "--seed", "1_0", "--out", str(tmp / "t.csv")], ("argument --seed:", "got '1_0'")),
    ("report --runs fullwidth", lambda tmp: ["report", "wind_turbine", "--runs", "\uff15", "--reports", str(tmp)], ("argument --runs:", "digits 0–9 alone")),
    ("bench --mc-runs 1_0", lambda tmp: ["bench", "--monte-carlo", "--mc-runs", "1_0", "--out", str(tmp / "b.md")], ("argument --mc-runs:", "got '1_0'")),
    ("bench --rss-runs Arabic-Indic", lambda tmp: ["bench", "--monte-carlo", "--rss-runs", "100,\u0661\u0660", "--out", str(tmp / "b.md")], ("argument --rss-runs:", "digits 0–9 alone")),
    ("simulate --seed -1", lambda tmp: ["simulate", "wind_turbine", "--scenario", "fault_free", "--seed", "-1", "--out", str(tmp / "t.csv")], ("argument --seed: expected a whole number ≥ 0",)),
    ("unknown scenario", lambda tmp: ["simulate", "wind_turbine", "--scenario", "storm", "--out", str(tmp / "t.csv")], ("has no scenario 'storm'",)),
    ("missing --out", lambda tmp: ["design", "wind_turbine"], ("the following arguments are required: --out",)),
    ("SPEC a directory", lambda tmp: ["design", str(tmp), "--out", str(tmp / "d")], ("is not a file: SPEC must be a TOML plant file or a built-in problem name",)),
    ("SPEC dotted", lambda tmp: ["design", "os.path", "--out", str(tmp / "d")], ("no built-in problem 'os.path'",)),
    ("SPEC empty", lambda tmp: ["design", "", "--out", str(tmp / "d")], ("no built-in problem ''",)),
    ("SPEC missing file", lambda tmp: ["design", str(tmp / "none.toml"), "--out", str(tmp / "d")], ("no plant file at",)),
]


_FORMS = "expected tcp://HOST:PORT (HOST:PORT alone is tcp), or tls://HOST:PORT with Dask's TLS configuration"


def _dask(address: str, *extra: str) -> Callable[[Path], list[str]]:
    return lambda tmp: ["evaluate", "sampled_data_example", "--runs", "2", "--out", str(tmp / "m.json"), "--workdir", str(tmp / "b"),
                        "--scheduler", "dask", "--address", address, *extra]


ADDRESS_CASES: list[tuple[str, Callable[[Path], list[str]], tuple[str, ...]]] = [
    ("tls without certificates", _dask("tls://127.0.0.1:9"), (
        "argument --address: 'tls://127.0.0.1:9': a TLS scheduler needs the client's certificate and its authority in "
        "Dask's configuration (DASK_DISTRIBUTED__COMM__TLS__CA_FILE, DASK_DISTRIBUTED__COMM__TLS__CLIENT__CERT and "
        "__CLIENT__KEY in the environment, or distributed.comm.tls in a Dask config file) and none is set; or use a "
        "tcp://HOST:PORT scheduler",)),
    ("ucx", _dask("ucx://127.0.0.1:9"), ("'ucx://127.0.0.1:9': the UCX transport is not supported", _FORMS)),
    ("inproc", _dask("inproc://192.168.0.1/1/2"), ("an inproc:// scheduler lives inside one Python process", _FORMS)),
    ("websocket", _dask("ws://127.0.0.1:9"), ("the websocket transport is not supported", _FORMS)),
    ("other scheme", _dask("http://127.0.0.1:9"), ("scheme 'http' is not one fdisyn joins", _FORMS)),
    ("empty", _dask(""), ("argument --address: '': " + _FORMS,)),
    ("garbage", _dask("garbage"), ("argument --address: 'garbage': " + _FORMS,)),
    ("no port", _dask("tcp://127.0.0.1"), ("'tcp://127.0.0.1': " + _FORMS,)),
    ("a path after the port", _dask("tcp://127.0.0.1:8786/x"), (_FORMS,)),
    ("a fullwidth port", _dask("tcp://127.0.0.1:\uff18\uff17"), (_FORMS,)),
    ("port out of range", _dask("tcp://127.0.0.1:99999"), ("'tcp://127.0.0.1:99999': port 99999 is out of range; expected a port 1–65535",)),
    ("port 0", _dask("tcp://127.0.0.1:0"), ("port 0 is out of range",)),
    ("port of 30 digits", _dask("tcp://127.0.0.1:" + "9" * 30), ("port of 30 digits is out of range",)),
    ("a line break", _dask("tcp://127.0.0.1:8786\n"), ("'tcp://127.0.0.1:8786\\n': " + _FORMS,)),
    ("workers with an address", _dask("tcp://127.0.0.1:9", "--workers", "2"), (
        "--workers 2 with --address tcp://127.0.0.1:9: the scheduler's cluster has its own workers",)),
    ("an address without dask", lambda tmp: ["evaluate", "sampled_data_example", "--out", str(tmp / "m.json"), "--address", "127.0.0.1:9"],
     ("--address tcp://127.0.0.1:9 needs --scheduler dask",)),
]


@pytest.mark.parametrize(("argv", "expected"), [c[1:] for c in ADDRESS_CASES], ids=[c[0] for c in ADDRESS_CASES])
def test_every_scheduler_address_form_is_refused_in_one_line_before_any_connection(tmp_path, capsys, monkeypatch, argv, expected) -> None:
    """No case reaches the network: the address is checked before a client exists (a client made would fail the
    test), and nothing is designed or built."""
    pytest.importorskip("dask.distributed")
    import distributed

    def no_client(*args, **kwargs):  # noqa: ANN002, ANN003, ANN202
        raise AssertionError("a Dask client was made")

    monkeypatch.setattr(distributed, "Client", no_client)
    for name in [k for k in os.environ if k.startswith("DASK_DISTRIBUTED__COMM__TLS") or k.startswith("DASK_DISTRIBUTED__CLIENT")]:
        monkeypatch.delenv(name)
    _fails_with(capsys, argv(tmp_path), *expected)
    assert not (tmp_path / "b").exists()


def test_a_tls_address_is_taken_with_dasks_tls_configuration(tmp_path) -> None:
    """tls:// works when Dask's configuration gives the client its certificate; a configuration whose files do
    not load is one line naming the error. Nothing connects: the address is checked alone."""
    import shutil
    import subprocess

    dask = pytest.importorskip("dask")
    pytest.importorskip("dask.distributed")
    from fdisyn.evaluation.campaign import scheduler_address

    if shutil.which("openssl") is None:
        pytest.skip("openssl makes the test certificate")
    cert, key = tmp_path / "c.pem", tmp_path / "k.pem"
    subprocess.run(["openssl", "req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes",
                    "-keyout", str(key), "-out", str(cert), "-days", "1", "-subj", "/CN=localhost"], check=True, capture_output=True)
    tls = {"distributed.comm.tls.ca-file": str(cert), "distributed.comm.tls.client.cert": str(cert),
           "distributed.comm.tls.client.key": str(key)}
    with dask.config.set(tls):
        assert scheduler_address("tls://127.0.0.1:8786") == "tls://127.0.0.1:8786"
    with dask.config.set({**tls, "distributed.comm.tls.ca-file": str(tmp_path / "none.pem")}):
        with pytest.raises(ArgumentError, match=r"^Dask's TLS configuration cannot be used: FileNotFoundError"):
            scheduler_address("tls://127.0.0.1:8786")
    assert scheduler_address("127.0.0.1:8786") == "tcp://127.0.0.1:8786"
    assert scheduler_address("TCP://[::1]:8786") == "tcp://[::1]:8786"
    assert scheduler_address("tcp://scheduler.example.org:8786") == "tcp://scheduler.example.org:8786"


def test_option_values_read_only_ascii_digits_as_numbers() -> None:
    """``--option`` values are JSON, whose numbers are ASCII digits: other scripts' digits, ``_`` and a sign ``+``
    stay the strings written (the option's check then refuses them by their type)."""
    from fdisyn.app.cli import _options

    odd = ["\u0661", "1\u0661", "\uff12", "1_0", "+5", "1e\u0661", "1.\u0665", "0x10"]
    got = _options([f"k{i}={v}" for i, v in enumerate(odd)])
    assert got == {f"k{i}": v for i, v in enumerate(odd)}
    assert _options(["a=10", "b=-0", "c=[1, 2]"]) == {"a": 10, "b": 0, "c": [1, 2]}


@pytest.mark.parametrize(("argv", "expected"), [c[1:] for c in ARGUMENT_CASES], ids=[c[0] for c in ARGUMENT_CASES])
def test_a_bad_option_or_argument_is_one_line(tmp_path, capsys, argv, expected) -> None:
    _fails_with(capsys, argv(tmp_path), *expected)


def test_no_command_is_one_line_and_help_is_not_an_error(capsys) -> None:
    status, lines = _status_and_lines(capsys, [])
    assert status == 2 and lines == ["fdisyn: error: the following arguments are required: command (see fdisyn --help)"]
    status, lines = _status_and_lines(capsys, ["desing", "wind_turbine"])
    assert status == 2 and len(lines) == 1 and lines[0].startswith("fdisyn: error: argument command: invalid choice: 'desing'")
    assert main(["design", "--help"]) == 0 and "--option KEY=VALUE" in capsys.readouterr().out


def test_a_binary_or_non_utf8_spec_is_one_line(tmp_path, capsys) -> None:
    binary = tmp_path / "plant.toml"
    binary.write_bytes(b"\x7fELF\x02\x01\x01\x00\xff\xfe")
    _fails_with(capsys, ["design", str(binary), "--out", str(tmp_path / "d")], "is not a text file (byte 8 is not UTF-8): a TOML plant file is expected")
    latin1 = tmp_path / "latin1"
    latin1.write_bytes(MOTOR.replace("Ω", "O").encode("utf-8").replace(b"DC motor", "Moteur \xe0 courant continu".encode("latin-1")))
    _fails_with(capsys, ["simulate", str(latin1), "--scenario", "fault_free", "--out", str(tmp_path / "t.csv")], "is not a text file")
    garbage = tmp_path / "garbage.toml"
    garbage.write_text("name = \n[[[", encoding="utf-8")
    _fails_with(capsys, ["design", str(garbage), "--out", str(tmp_path / "d")], "is not valid TOML")


def test_a_spec_that_leads_to_a_device_or_a_fifo_is_one_line(tmp_path, capsys) -> None:
    """``x.toml`` linked to /dev/zero was read until memory ran out; a FIFO blocked for ever."""
    zero = tmp_path / "zero.toml"
    zero.symlink_to("/dev/zero")
    _fails_with(capsys, ["design", str(zero), "--out", str(tmp_path / "d")], "zero.toml is not a regular file (a device, a FIFO or a directory); expected a TOML plant file")
    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)
    _fails_with(capsys, ["simulate", str(fifo), "--scenario", "fault_free", "--out", str(tmp_path / "t.csv")], "fifo.toml is not a regular file")


# --------------------------------------------------------------------------- output paths


def test_an_output_that_cannot_be_written_is_one_line(tmp_path, capsys) -> None:
    spec = str(DATA / "dc_motor.toml")
    a_file = tmp_path / "a_file.txt"
    a_file.write_text("x")
    _fails_with(capsys, ["design", spec, "--out", str(a_file)], f"--out {a_file} is a file: expected a directory")
    _fails_with(capsys, ["design", spec, "--out", str(a_file / "sub")], f"--out {a_file / 'sub'}:", "is a file, so the directory cannot be created; expected a directory path")
    _fails_with(capsys, ["simulate", spec, "--scenario", "fault_free", "--out", str(tmp_path)], "is a directory: expected a file name")
    _fails_with(capsys, ["simulate", spec, "--scenario", "fault_free", "--out", str(a_file / "t.csv")], f"the directory of --out {a_file} is a file")
    # /dev/full accepts the open and fails every write with ENOSPC: a full disk
    _fails_with(capsys, ["simulate", spec, "--scenario", "fault_free", "--out", "/dev/full"], "--out /dev/full: No space left on device; expected a writable file")
    _fails_with(capsys, ["evaluate", spec, "--runs", "1", "--out", str(tmp_path / "m.json"), "--workdir", str(a_file)], f"--workdir {a_file} is a file")
    _fails_with(capsys, ["report", spec, "--reports", str(a_file), "--workdir", str(tmp_path / "b")], f"--reports {a_file} is a file")
    _fails_with(capsys, ["codegen", str(a_file)], f"DIR {a_file} is a file: expected the directory holding gains.json")
    _fails_with(capsys, ["codegen", str(tmp_path / "empty")], "no gain file at")


# --------------------------------------------------------------------------- the C compiler


@pytest.fixture(scope="module")
def motor_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("motor")
    assert main(["design", str(DATA / "dc_motor.toml"), "--out", str(d)]) == 0
    return d


@pytest.mark.parametrize(
    ("cc", "expected"),
    [
        ("gcc;rm -rf /", "'gcc;rm' is not a plain command or flag"),
        ("gcc $(id)", "'$(id)' is not a plain command or flag"),
        ("gcc '-O2", "is not a command: No closing quotation"),
        ("", "CC is set but empty"),
        ("no-such-cc -O2", "no C compiler 'no-such-cc' on PATH (from CC='no-such-cc -O2')"),
    ],
)
def test_a_bad_cc_is_refused_before_running_anything(motor_dir, capsys, monkeypatch, cc, expected) -> None:
    monkeypatch.setenv("CC", cc)
    _fails_with(capsys, ["codegen", str(motor_dir)], expected)


def test_a_cc_with_flags_is_a_compiler_and_its_failure_names_the_log(motor_dir, capsys, monkeypatch) -> None:
    missing = motor_dir / "no_such_header.h"
    monkeypatch.setenv("CC", f"gcc -include {missing}")
    line = _fails_with(capsys, ["codegen", str(motor_dir)], "compiling", "failed (exit status 1)", f"the compiler's output is in {motor_dir / 'c' / 'build.log'}")
    assert "no C compiler" not in line and "no_such_header.h" in line
    log = (motor_dir / "c" / "build.log").read_text(encoding="utf-8")
    assert log.startswith(f"$ gcc -include {missing} -std=c99") and "no_such_header.h" in log and log.endswith("exit status 1\n")
    # 'gcc -m32' is a compiler with a flag, not "no C compiler": it builds, or fails naming the log
    monkeypatch.setenv("CC", "gcc -m32")
    status, lines = _status_and_lines(capsys, ["codegen", str(motor_dir)])
    assert status == 0 or (status == 2 and len(lines) == 1 and "build.log" in lines[0] and "no C compiler" not in lines[0])


# --------------------------------------------------------------------------- seeded fuzzers

HOSTILE_JSON = [
    "0", "-1", "1", "2", "0.5", "1.5", "1e-300", "1e308", "-1e308", "NaN", "Infinity", "-Infinity", "true", "null",
    "[]", "[1]", "[0.1, 0.2]", "{}", '{"a": 1}', '""', '"paper"', "paper", "benchmark", "x" * 500, "[" * 5000,
    "1e999", "9" * 400, "0x10", "१", "é✓", " ", "\t1", "1,2", "=", "==", "P_f=1",
]


def test_fuzz_option_values(tmp_path, capsys) -> None:
    """60 seeded ``--option`` pairs (keys known and unknown, values of every JSON type and none)
    on the cheapest commands that read them: status 0 or 2 with one line, never an exception."""
    rng = np.random.default_rng(20240611)
    keys = ["P_f", "persistence", "parameters", "window", "foo", "", " P_f", "P_f "]
    for k in range(60):
        pairs = []
        for _ in range(int(rng.integers(1, 3))):
            key = keys[int(rng.integers(len(keys)))]
            value = HOSTILE_JSON[int(rng.integers(len(HOSTILE_JSON)))]
            pairs += ["--option", f"{key}={value}"]
        argv = (
            ["simulate", "sampled_data_example", "--scenario", "fault_free", "--out", str(tmp_path / f"t{k}.csv"), *pairs]
            if k % 2
            else ["design", "wind_turbine", "--out", str(tmp_path / f"d{k}"), *pairs]
        )
        status, lines = _status_and_lines(capsys, argv)
        assert status in (0, 2), argv
        if status == 2:
            assert len(lines) == 1 and lines[0].startswith(f"fdisyn {argv[0]}: error: "), (argv, lines)


HOSTILE_TOML = [
    "nan", "inf", "-inf", "-1", "0", "0.0", "1e308", "-1e308", "1e-308", "9223372036854775807", "1.5", '"x"', '""',
    '"../../x"', '"a\\nb"', "true", "[]", "[[]]", "{}", '[1, "a"]', "[nan]", "[[1e308]]", '{ kind = "sine" }',
    "[[1.0, 2.0], [3.0]]", "@@", "[1e400]",
]
_TOP_VALUE = re.compile(r"^(\w+)(\s*=\s*)(.+?)(\s+#.*)?$", flags=re.M)
_NUMBER = re.compile(r"(?<![\w.])-?\d+(?:\.\d+)?(?:e-?\d+)?(?![\w.])")


def _mutate(text: str, rng: np.random.Generator) -> str:
    """``text`` with one value replaced by a hostile literal: a whole ``key = value``
    or a number inside a matrix or inline table."""
    bad = HOSTILE_TOML[int(rng.integers(len(HOSTILE_TOML)))]
    if rng.random() < 0.5:
        m = list(_TOP_VALUE.finditer(text))[int(rng.integers(len(list(_TOP_VALUE.finditer(text)))))]
        return text[: m.start(3)] + bad + text[m.end(3) :]
    nums = list(_NUMBER.finditer(text))
    m = nums[int(rng.integers(len(nums)))]
    return text[: m.start()] + bad + text[m.end() :]


@pytest.mark.parametrize(("name", "text", "cases"), [("dc_motor", MOTOR, 24), ("sampled_data", SAMPLED, 12)])
def test_fuzz_plant_file_values(tmp_path, capsys, name, text, cases) -> None:
    """Seeded mutations of an example file (one or two values replaced by wrong types, NaN,
    huge, negative, strings, malformed TOML), designed and simulated through the CLI: status
    0 or 2 with one line, never another exception."""
    rng = np.random.default_rng({"dc_motor": 11, "sampled_data": 12}[name])
    for k in range(cases):
        mutated = _mutate(text, rng)
        if rng.random() < 0.3:
            mutated = _mutate(mutated, rng)
        spec = tmp_path / f"{name}_{k}.toml"
        spec.write_text(mutated, encoding="utf-8")
        for argv in (
            ["design", str(spec), "--out", str(tmp_path / f"d{k}")],
            ["simulate", str(spec), "--scenario", "fault_free", "--out", str(tmp_path / f"t{k}.csv")],
        ):
            status, lines = _status_and_lines(capsys, argv)
            assert status in (0, 2), (argv, mutated)
            if status == 2:
                assert len(lines) == 1 and lines[0].startswith(f"fdisyn {argv[0]}: error: "), (lines, mutated)


# --------------------------------------------------------------------------- the same checks below the CLI


def test_runs_and_seeds_are_checked_by_the_api_too(tmp_path) -> None:
    """``--runs`` and ``--seed`` are checked by argparse; the functions behind them refuse the
    same values with a named error instead of NumPy's ValueError or a silent default."""
    from fdisyn.app.pipeline import reproduce_problem
    from fdisyn.simulation.plant_file import load_spec
    from fdisyn.evaluation.evaluate import evaluate
    from fdisyn.runtime.errors import ArgumentError

    prob = load_spec(DATA / "dc_motor.toml")
    with pytest.raises(ArgumentError, match=r"seeds must be whole numbers ≥ 0; got \[-1\]"):
        prob.run("fault_free", [-1])
    with pytest.raises(ArgumentError, match="runs must be a whole number ≥ 1; got 0"):
        evaluate(prob, {}, runs=0)
    with pytest.raises(ArgumentError, match="seed0 must be a whole number ≥ 0"):
        evaluate(prob, {}, runs=1, seed0=-3)
    with pytest.raises(ArgumentError, match=r"runs must be a whole number ≥ 1 \(or None for the problem's 50\); got 0"):
        reproduce_problem(prob, runs=0, reports=tmp_path / "r", workdir=tmp_path / "b")


def test_an_oserror_about_another_file_is_not_the_users_and_is_a_bug(tmp_path, capsys, monkeypatch) -> None:
    """Only an OSError about a path the user named (or a full disk) becomes an error of status 2; one
    about any other file is a bug: status 3, one line, and the traceback with FDISYN_DEBUG=1."""
    import fdisyn.runtime.gainfile as gainfile

    def broken(gf: object, path: object) -> None:
        raise FileNotFoundError(2, "No such file or directory", "/usr/share/fdisyn/template.json")

    monkeypatch.setattr(gainfile, "write_gain_file", broken)
    argv = ["design", str(DATA / "dc_motor.toml"), "--out", str(tmp_path / "d")]
    monkeypatch.delenv("FDISYN_DEBUG", raising=False)
    assert main(argv) == 3
    lines = capsys.readouterr().err.splitlines()
    assert lines == [
        "fdisyn design: internal error: FileNotFoundError: [Errno 2] No such file or directory: "
        "'/usr/share/fdisyn/template.json' — please report; FDISYN_DEBUG=1 shows the traceback"
    ]
    monkeypatch.setenv("FDISYN_DEBUG", "1")
    assert main(argv) == 3
    err = capsys.readouterr().err
    assert err.startswith("Traceback (most recent call last):") and "in broken" in err and err.splitlines()[-1] == lines[0]


@pytest.mark.parametrize(
    ("error", "status", "line"),
    [
        (ArgumentError("option P_f = 2: expected a probability"), 2, "error: option P_f = 2: expected a probability"),
        (ShapeError("A has shape (2, 3)"), 2, "error: A has shape (2, 3)"),
        (FileError("no gain file at x/gains.json"), 2, "error: no gain file at x/gains.json"),
        (SpecError("plant.toml [model].A: …"), 2, "error: plant.toml [model].A: …"),
        (ExistenceError("rank(C E) = 0 but rank(E) = 1"), 2, "error: rank(C E) = 0 but rank(E) = 1"),
        (SolverError("Clarabel: infeasible"), 2, "error: Clarabel: infeasible"),
        (CertificateError("certificate failed:\n  residual 1e-3 > 1e-9"), 2, "error: certificate failed: residual 1e-3 > 1e-9"),
        (InternalError("layout mismatch"), 3, "internal error: layout mismatch — please report; FDISYN_DEBUG=1 shows the traceback"),
        (ValueError("operands could not be broadcast"), 3, "internal error: ValueError: operands could not be broadcast — please report"),
        (KeyError("x"), 3, "internal error: KeyError: 'x' — please report"),
    ],
    ids=lambda v: type(v).__name__ if isinstance(v, Exception) else None,
)
def test_every_error_class_is_one_line_with_its_status(tmp_path, capsys, monkeypatch, error, status, line) -> None:
    """The taxonomy through the command line: every FdisynError is the user's (status 2), an
    InternalError or any other exception a bug (status 3); one line each, no traceback."""
    import fdisyn.app.cli as cli

    def fail(spec: str) -> None:
        raise error

    monkeypatch.delenv("FDISYN_DEBUG", raising=False)
    monkeypatch.setattr(cli, "_problem", fail)
    status_, lines = _status_and_lines(capsys, ["simulate", "wind_turbine", "--scenario", "fault_free", "--out", str(tmp_path / "t.csv")])
    assert status_ == status and len(lines) == 1 and lines[0].startswith(f"fdisyn simulate: {line}"), lines


def test_warnings_of_a_successful_command_are_one_line_each(tmp_path, capsys) -> None:
    """A value that is valid but absurd (an input of 1e308 V) may overflow in the simulation: the
    command succeeds, and NumPy's warnings come out as one line each, no source lines."""
    spec = _file(tmp_path, MOTOR, "amplitude = 5.6", "amplitude = 1e308")
    status, lines = _status_and_lines(capsys, ["simulate", spec, "--scenario", "fault_free", "--out", str(tmp_path / "t.csv")])
    assert status == 0 and lines and all(ln.startswith("fdisyn simulate: warning: RuntimeWarning: ") for ln in lines), lines
