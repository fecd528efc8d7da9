"""``portal-daq init``: the shipped examples, written where the user wants them, loadable
as they are, and never over a file the user already has."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from daq.cli import main
from daq.init_command import example_names
from daq.service_config import load_service_config
from dbc import DEFAULT_DBC_PATH
from tests.helpers import ROOT, assert_links_to


def test_every_example_of_the_repository_ships() -> None:
    assert example_names() == ["default", "e2e", "j1939"]
    # deploy/ links to the packaged files: one copy of each
    assert_links_to(
        ROOT / "deploy" / "portal-daq.example.toml",
        ROOT / "daq" / "examples" / "default" / "portal-daq.toml",
    )


@pytest.mark.parametrize("name", ["default", "e2e", "j1939"])
def test_an_example_is_written_and_loads_from_where_it_was_written(
    name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / "new" / name
    assert main(["init", str(target), "--example", name]) == 0
    config_path = target / "portal-daq.toml"
    config = load_service_config(config_path)
    # the Zenoh file it names is the one written beside it, not the package's
    assert config.zenoh.config_file == target / "zenoh.json5"
    assert config.zenoh.config_file.read_bytes() == (ROOT / "deploy" / "zenoh.json5").read_bytes()
    shipped = ROOT / "deploy" / "examples" / name
    assert sorted(p.name for p in target.iterdir()) == sorted(p.name for p in shipped.iterdir())
    for written in target.iterdir():
        assert written.read_bytes() == (shipped / written.name).read_bytes()
    err = capsys.readouterr().err
    assert f"portal-daq run --config {config_path}" in err


def test_the_default_machine_gets_a_copy_of_the_packaged_dbc(tmp_path: Path) -> None:
    """A user with the wheel alone had no way to see the signal names the config names,
    and the example's commented ``dbc = "portal_sensors.dbc"``, uncommented, was "no such
    file". Left commented, the packaged DBC is read; uncommented, the copy."""
    assert main(["init", str(tmp_path)]) == 0
    copy = tmp_path / "portal_sensors.dbc"
    assert copy.read_bytes() == DEFAULT_DBC_PATH.read_bytes()
    config = tmp_path / "portal-daq.toml"
    assert load_service_config(config).machine.dbc_path == DEFAULT_DBC_PATH
    text = config.read_text()
    assert text.count('# dbc = "portal_sensors.dbc"\n') == 1
    config.write_text(text.replace('# dbc = "portal_sensors.dbc"', 'dbc = "portal_sensors.dbc"'))
    assert load_service_config(config).machine.dbc_path == copy


def test_the_machine_with_its_own_dbc_gets_that_dbc(tmp_path: Path) -> None:
    assert main(["init", str(tmp_path), "--example", "j1939"]) == 0
    config = load_service_config(tmp_path / "portal-daq.toml")
    assert config.machine.dbc_path == tmp_path / "transducers_j1939.dbc"
    assert len(config.machine.legs) == 6


def test_existing_files_are_kept_unless_forced(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["init", str(tmp_path)]) == 0
    mine = tmp_path / "portal-daq.toml"
    mine.write_text("# my machine\n")
    (tmp_path / "zenoh.json5").unlink()
    (tmp_path / "portal_sensors.dbc").unlink()
    capsys.readouterr()
    assert main(["init", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err == f"portal-daq: {mine} exists; --force overwrites it\n"
    # nothing written, not even the file that was missing
    assert mine.read_text() == "# my machine\n"
    assert not (tmp_path / "zenoh.json5").exists()
    assert main(["init", str(tmp_path), "--force"]) == 0
    assert mine.read_bytes() == (ROOT / "deploy" / "portal-daq.example.toml").read_bytes()


def test_an_unwritable_directory_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    a_file = tmp_path / "file"
    a_file.write_text("")
    assert main(["init", str(a_file / "sub")]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"portal-daq: {a_file / 'sub'}: cannot write the example")
    assert err.count("\n") == 1


def test_an_unknown_example_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["init", "--example", "nope"])
    assert exit_info.value.code == 2
    assert "invalid choice: 'nope'" in capsys.readouterr().err


def test_a_file_where_the_directory_goes_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``portal-daq init my.toml`` (a file named instead of a directory) printed Python's
    ``[Errno 17] File exists: 'my.toml'``."""
    mine = tmp_path / "my.toml"
    mine.write_text("# mine\n")
    assert main(["init", str(mine)]) == 2
    assert capsys.readouterr().err == (
        f"portal-daq: {mine}: it is a file; give init a directory to write into\n"
    )
    assert mine.read_text() == "# mine\n"


@pytest.mark.parametrize("command", ["run", "replay"])
def test_the_commands_that_take_a_config_say_where_one_comes_from(
    command: str, capsys: pytest.CaptureFixture[str]
) -> None:
    # `run --help` said "service + machine TOML", replay's "machine config (MCAP: default
    # embedded)": a user with the wheel alone was not told that init writes one, nor
    # that a CAN log needs it.
    with pytest.raises(SystemExit):
        main([command, "--help"])
    assert "portal-daq init" in " ".join(capsys.readouterr().out.split())


@pytest.mark.parametrize("name", ["default", "e2e", "j1939"])
def test_the_examples_name_nothing_a_wheel_lacks(name: str, tmp_path: Path) -> None:
    # Their comments sent the user to deploy/examples/..., deploy/demo.sh and
    # `python -m sim_bridge`: a clone's paths, where init wrote them out of a wheel.
    assert main(["init", str(tmp_path), "--example", name]) == 0
    for written in tmp_path.iterdir():
        if written.suffix == ".dbc":
            continue
        text = written.read_text()
        for clone_only in ("deploy/examples", "deploy/demo.sh", "deploy/portal-daq.example"):
            assert clone_only not in text, (written.name, clone_only)


def test_the_commands_it_suggests_take_a_directory_with_a_space(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``portal-daq init "my machine"`` printed `portal-daq run --config my
    machine/portal-daq.toml`: pasted into a shell, ``--config my`` and a stray argument."""
    target = tmp_path / "my machine"
    assert main(["init", str(target), "--deploy"]) == 0
    commands = re.findall(r"`([^`]*)`", capsys.readouterr().err)
    assert ["run", "--config", str(target / "portal-daq.toml")] == shlex.split(commands[0])[1:]
    assert str(target / "deploy" / "install.sh") in shlex.split(commands[-1])
