"""``fdisyn example``: the example plant files shipped in the package, listed and written out; a refused name,
an existing file (without ``--force``) and a directory each end with status 2 and one line."""

from __future__ import annotations

import tomllib

import pytest
from fdisyn.app.cli import main
from fdisyn.app.examples import EXAMPLES, example_names
from fdisyn.simulation.plant_file import load_spec


def _err(capsys) -> str:  # noqa: ANN001 - pytest's capsys
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    return err


def test_the_examples_are_the_readme_s_plant_files() -> None:
    assert example_names() == ["beard_textbook", "dc_motor", "sampled_data", "ship"]
    for name in example_names():
        doc = tomllib.loads((EXAMPLES / f"{name}.toml").read_text(encoding="utf-8"))
        assert doc["title"], name


def test_without_a_name_the_examples_are_listed(capsys) -> None:
    assert main(["example"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [ln.split(":", 1)[0] for ln in lines] == example_names()
    assert "dc_motor: DC motor: sensor FDI under an unknown load torque" in lines


def test_an_example_is_written_byte_for_byte_and_loads(tmp_path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(["example", "dc_motor"]) == 0
    assert capsys.readouterr().out.startswith("wrote dc_motor.toml")
    assert (tmp_path / "dc_motor.toml").read_bytes() == (EXAMPLES / "dc_motor.toml").read_bytes()
    assert load_spec("dc_motor.toml").name == "dc_motor"
    assert main(["example", "ship", "--out", "plants/my_ship.toml"]) == 0  # a missing folder is created
    assert (tmp_path / "plants" / "my_ship.toml").read_bytes() == (EXAMPLES / "ship.toml").read_bytes()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["example", "nope"], "fdisyn example: error: no example plant file 'nope'; the examples are beard_textbook, dc_motor, sampled_data, ship"),
        (["example", "../dc_motor"], "no example plant file '../dc_motor'"),
        (["example", "dc_motor.toml"], "no example plant file 'dc_motor.toml'"),
        (["example", "--out", "x.toml"], "--out and --force need the NAME of an example"),
    ],
)
def test_a_refused_name_is_one_line(argv, message, tmp_path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    assert message in _err(capsys)
    assert list(tmp_path.iterdir()) == []


def test_an_existing_file_is_replaced_only_with_force(tmp_path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    mine = tmp_path / "dc_motor.toml"
    mine.write_text("# my own changes\n")
    assert main(["example", "dc_motor"]) == 2
    assert _err(capsys) == "fdisyn example: error: dc_motor.toml exists: expected a new file name, or --force to replace it\n"
    assert mine.read_text() == "# my own changes\n"
    (tmp_path / "d").mkdir()
    assert main(["example", "dc_motor", "--out", "d", "--force"]) == 2
    assert "--out d is a directory" in _err(capsys)
    target = tmp_path / "target"
    target.write_text("kept\n")
    (tmp_path / "link.toml").symlink_to(target)
    assert main(["example", "dc_motor", "--out", "link.toml"]) == 2
    assert "link.toml exists" in _err(capsys)
    assert main(["example", "dc_motor", "--force"]) == 0
    assert main(["example", "dc_motor", "--out", "link.toml", "--force"]) == 0  # the link is replaced, not its target
    assert mine.read_bytes() == (EXAMPLES / "dc_motor.toml").read_bytes() and target.read_text() == "kept\n"
    assert not (tmp_path / "link.toml").is_symlink()
