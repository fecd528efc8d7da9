"""``portal-daq`` as a subcommand CLI: the help lists every subcommand, a wrong name gets
a useful error, ``run --config`` and the bare ``--config`` form both run the service, and
``replay | head`` ends quietly."""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import can
import pytest

from daq.cli import SUBCOMMAND_MODULES, subcommands
from dbc.encoding import FrameEncoder
from tests.daq.service_support import leg_messages
from tests.helpers import EXAMPLE_CONFIG, ROOT, example_machine

#: The subcommands the README documents; others may add more, never fewer.
DOCUMENTED = {"run", "replay", "report", "monitor", "dashboard"}


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "daq", *args], capture_output=True, text=True, timeout=120, cwd=ROOT
    )


def test_help_lists_every_subcommand_with_its_summary() -> None:
    result = run_cli("--help")
    assert result.returncode == 0, result.stderr
    commands = subcommands()
    assert DOCUMENTED <= set(commands)
    assert len(commands) == len(SUBCOMMAND_MODULES)  # one subcommand per module, no clash
    listed = {line.split()[0]: line for line in result.stdout.splitlines() if line.strip()}
    for command in commands.values():
        assert command.summary in listed[command.name], result.stdout


def test_every_subcommand_has_its_own_help() -> None:
    for name in subcommands():
        result = run_cli(name, "--help")
        assert result.returncode == 0, (name, result.stderr)
        assert result.stdout.startswith(f"usage: portal-daq {name}"), result.stdout


def test_version_is_the_installed_one() -> None:
    """``portal-daq --version`` was taken for the bare ``--config`` form: "portal-daq run:
    error: the following arguments are required: --config"."""
    from importlib import metadata

    result = run_cli("--version")
    assert result.returncode == 0, result.stderr
    assert result.stdout == f"portal-daq {metadata.version('portal-daq')}\n"


def test_an_unknown_subcommand_names_the_valid_ones() -> None:
    result = run_cli("bogus")
    assert result.returncode == 2
    assert "invalid choice: 'bogus'" in result.stderr
    assert all(name in result.stderr for name in DOCUMENTED), result.stderr
    assert "--config" not in result.stderr


def test_no_arguments_is_a_usage_error() -> None:
    result = run_cli()
    assert result.returncode == 2 and "usage: portal-daq" in result.stderr


def test_run_and_the_bare_form_both_read_the_config(tmp_path: Path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(EXAMPLE_CONFIG.read_text().replace("median_window = 11", "median_window = 4"))
    for args in (("run", "--config", str(path)), ("--config", str(path))):
        result = run_cli(*args)
        assert result.returncode == 2, result.stderr
        (line,) = result.stderr.strip().splitlines()
        assert line.startswith(f"portal-daq: {path}: estimator.median_window"), line


def replaying_a_long_log(
    tmp_path: Path, sigint: signal.Handlers | None = None
) -> subprocess.Popen[str]:
    """``portal-daq replay`` of a log whose CSV (~1 MB) is far more than a pipe's buffer
    into a pipe, once it has written its header: it then waits on the pipe.

    ``sigint``: the replay's SIGINT disposition as it starts (a test run in the
    background of a script inherits SIGINT ignored, and so would the replay)."""
    config, database = example_machine()
    log = tmp_path / "long.log"
    with can.Logger(str(log)) as logger:
        for message in leg_messages(FrameEncoder(database, config.protection), 2000, 1.7e9):
            message.channel = "can0"
            logger.on_message_received(message)
    process = subprocess.Popen(
        [sys.executable, "-m", "daq", "replay", str(log), "--config", str(EXAMPLE_CONFIG)],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=None if sigint is None else lambda: signal.signal(signal.SIGINT, sigint),
    )
    assert process.stdout is not None
    assert process.stdout.readline().startswith("leg,t,")
    return process


def test_replay_into_a_closed_pipe_ends_quietly(tmp_path: Path) -> None:
    """``portal-daq replay X | head -1``: no "Broken pipe" message, status 141 like ``cat``."""
    process = replaying_a_long_log(tmp_path)
    assert process.stdout is not None and process.stderr is not None
    process.stdout.close()
    with process.stderr:
        stderr = process.stderr.read()
    assert process.wait(timeout=120) == 141, stderr
    assert stderr == ""


def test_ctrl_c_ends_a_command_in_one_line(tmp_path: Path) -> None:
    """Ctrl-C in replay (report, calibrate: any command that does not handle SIGINT
    itself) was a KeyboardInterrupt traceback of some 30 lines; now one line, status 130
    as a shell reports it. The replay is held writing into a full pipe when it comes."""
    process = replaying_a_long_log(tmp_path, sigint=signal.SIG_DFL)
    process.send_signal(signal.SIGINT)
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 130, stderr
    assert stderr == "portal-daq: interrupted\n"


@pytest.mark.parametrize("name", ["run", "monitor", "dashboard", "router"])
def test_a_log_level_that_is_none_is_a_usage_error(
    name: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--log-level LOUD`` was a ValueError traceback from logging.basicConfig; a level
    in lower case is taken (``debug``), so the option is parsed, not passed on."""
    command = subcommands()[name]
    with pytest.raises(SystemExit) as exited:
        command.main(["--log-level", "LOUD"])
    assert exited.value.code == 2
    assert "--log-level: invalid choice: 'LOUD'" in capsys.readouterr().err
    with pytest.raises(SystemExit) as helped:
        command.main(["--log-level", "debug", "--help"])
    assert helped.value.code == 0
