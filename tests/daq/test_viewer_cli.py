"""``portal-daq monitor`` and ``portal-daq dashboard`` as processes: exit codes, one-line
errors, clean SIGINT/SIGTERM."""

from __future__ import annotations

import argparse
import signal
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from daq.live.command import add_viewer_arguments, load_fleet
from daq.live.state import NO_LINK
from tests.daq.service_support import WAIT_S, free_port, write_service_config
from tests.helpers import EXAMPLE_CONFIG, ROOT

COMMANDS = ("monitor", "dashboard")


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "daq", *args], capture_output=True, text=True, timeout=60, cwd=ROOT
    )


def assert_one_line(result: subprocess.CompletedProcess[str], status: int, prefix: str) -> str:
    assert result.returncode == status, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(prefix), result.stderr
    assert "Traceback" not in result.stderr
    return lines[0]


@pytest.mark.parametrize("command", COMMANDS)
def test_bad_config_exits_2_with_one_line(command: str, tmp_path: Path) -> None:
    path = write_service_config(tmp_path, port=free_port())
    path.write_text(path.read_text().replace('mode = "peer"', 'mode = "mesh"'))
    line = assert_one_line(run(command, "--config", str(path)), 2, f"portal-daq {command}: ")
    assert f"{path}: zenoh.mode: must be one of" in line


ENDPOINT_FORM = "Endpoints must be of the form <protocol>/<address>[?<metadata>][#<config>]"


@pytest.mark.parametrize("command", COMMANDS)
def test_a_bad_endpoint_is_named_by_the_option_or_key_that_gave_it(
    command: str, tmp_path: Path
) -> None:
    """``--connect nonsense`` was blamed on the config's ``zenoh.connect``, in Zenoh's
    ``Json5Err(Message { msg: ... at /root/.cargo/...rs:615. ...})``."""
    path = write_service_config(tmp_path, port=free_port())
    prefix = f"portal-daq {command}: "
    line = assert_one_line(run(command, "--config", str(path), "--connect", "nonsense"), 2, prefix)
    assert line == f"{prefix}--connect: {ENDPOINT_FORM}: nonsense"
    path.write_text(path.read_text().replace("listen = [", 'connect = ["tcp:x"]\nlisten = ['))
    line = assert_one_line(run(command, "--config", str(path)), 2, prefix)
    assert line == f"{prefix}{path}: zenoh.connect: {ENDPOINT_FORM}: tcp:x"


@pytest.mark.parametrize("command", COMMANDS)
def test_missing_config_exits_2(command: str) -> None:
    line = assert_one_line(
        run(command, "--config", "/nonexistent.toml"), 2, f"portal-daq {command}: "
    )
    assert "no such file" in line


@pytest.mark.parametrize("command", COMMANDS)
def test_bad_machine_value_exits_2(command: str, tmp_path: Path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(
        EXAMPLE_CONFIG.read_text().replace(
            "pressure_limit_Pa = 200000.0", "pressure_limit_Pa = -1.0"
        )
    )
    line = assert_one_line(run(command, "--config", str(path)), 2, f"portal-daq {command}: ")
    assert "estimator.pressure_limit_Pa" in line


def test_monitor_without_a_terminal_asks_for_plain(tmp_path: Path) -> None:
    path = write_service_config(tmp_path, port=free_port())
    line = assert_one_line(run("monitor", "--config", str(path)), 2, "portal-daq monitor: ")
    assert "--plain" in line


def test_dashboard_bad_http_address_exits_2(tmp_path: Path) -> None:
    path = write_service_config(tmp_path, port=free_port())
    result = run("dashboard", "--config", str(path), "--http", "localhost")
    assert "expected HOST:PORT" in assert_one_line(result, 2, "portal-daq dashboard: --http: ")


def test_dashboard_taken_http_port_exits_1(tmp_path: Path) -> None:
    path = write_service_config(tmp_path, port=free_port())
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        result = run("dashboard", "--config", str(path), "--http", f"127.0.0.1:{port}")
    line = assert_one_line(result, 1, "portal-daq dashboard: HTTP: cannot listen on ")
    assert "in use" in line


@pytest.mark.parametrize(
    ("command", "signum"),
    [("monitor", signal.SIGTERM), ("monitor", signal.SIGINT), ("dashboard", signal.SIGTERM)]
    + [("dashboard", signal.SIGINT)],
)
def test_signals_stop_cleanly_with_status_0(command: str, signum: int, tmp_path: Path) -> None:
    path = write_service_config(tmp_path, port=free_port())
    extra = ["--plain"] if command == "monitor" else ["--http", "127.0.0.1:0"]
    process = subprocess.Popen(
        [sys.executable, "-m", "daq", command, "--config", str(path), *extra],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert process.stdout is not None
        first = process.stdout.readline()  # the first line: it is running
        assert first.strip(), process.stderr.read() if process.stderr else ""
        process.send_signal(signum)
        assert process.wait(timeout=WAIT_S) == 0
    finally:
        if process.poll() is None:
            process.kill()
        _, stderr = process.communicate()
    assert stderr == ""
    if command == "dashboard":
        assert first.startswith("dashboard of portal/pam-proto-1 on http://127.0.0.1:")
    else:
        assert "waiting for portal/pam-proto-1/status" in first


def test_a_monitor_with_no_zenoh_link_says_so_while_it_waits(tmp_path: Path) -> None:
    """No service where the config says it listens: the line said only "waiting for
    portal/pam-proto-1/status", as if the service were there and about to talk."""
    path = write_service_config(tmp_path, port=free_port())  # nobody listens there
    result = run("monitor", "--config", str(path), "--plain", "--duration", "1.5")
    assert result.returncode == 0, result.stderr
    (line,) = result.stdout.splitlines()
    prefix = "portal/pam-proto-1"
    assert line.endswith(
        f" waiting for {prefix}/status: {NO_LINK} | waiting for {prefix}/ground: {NO_LINK}"
    )


def test_a_fleet_monitor_with_no_zenoh_link_says_so_while_it_waits() -> None:
    """``--connect`` to where nobody listens: "no machine yet" for ever, as if no service
    were up."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    result = run("monitor", "--fleet", "--connect", endpoint, "--plain", "--duration", "1.5")
    assert result.returncode == 0, result.stderr
    (line,) = result.stdout.splitlines()
    assert line.endswith(
        f" no machine yet: waiting for liveliness tokens portal/*/alive: {NO_LINK}"
    )


@pytest.mark.parametrize(
    ("root", "reason"),
    [
        ("portal/", "has an empty chunk"),  # was a Zenoh traceback (portal//*/ground)
        ("port#al", "has '#'"),  # was a Zenoh traceback
        ("portal/*", "has '*'"),  # showed "no machine yet" for ever
        ("@site", "has the chunk '@site', which starts with '@'"),  # ditto: not in portal/*
    ],
)
def test_a_fleet_root_that_is_no_key_prefix_is_a_usage_error(
    root: str, reason: str, capsys: pytest.CaptureFixture[str]
) -> None:
    parser = argparse.ArgumentParser(prog="portal-daq monitor")
    add_viewer_arguments(parser)
    assert parser.parse_args(["--fleet", "--root", "site7/hall-2"]).root == "site7/hall-2"
    with pytest.raises(SystemExit) as exit_info:
        parser.parse_args(["--fleet", "--root", root])
    assert exit_info.value.code == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last.startswith(f"portal-daq monitor: error: argument --root: {root!r} {reason}")


def test_the_fleet_root_of_a_config_is_its_key_prefix_without_the_machine_id(
    tmp_path: Path,
) -> None:
    """With --config of a service whose key prefix is site7/pam, the fleet looked under
    portal and said "no machine yet" for ever."""
    path = write_service_config(tmp_path, port=free_port())
    path.write_text(path.read_text().replace("[zenoh]\n", '[zenoh]\nkey_prefix = "site7/pam"\n'))
    parser = argparse.ArgumentParser(prog="portal-daq monitor")
    add_viewer_arguments(parser)
    fleet = load_fleet(parser.parse_args(["--fleet", "--config", str(path)]))
    assert fleet.settings.root == "site7" and fleet.settings.prefix == "site7/*"
    given = load_fleet(parser.parse_args(["--fleet", "--config", str(path), "--root", "lab"]))
    assert given.settings.root == "lab"
    alone = parser.parse_args(["--fleet", "--connect", "tcp/127.0.0.1:7447"])
    assert load_fleet(alone).settings.root == "portal"
