"""The service as a process: exit codes, one-line errors, sd_notify order, SIGTERM, replay CLI."""

from __future__ import annotations

import csv
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import can
import pytest
import zenoh
from mcap.reader import make_reader

from dbc import DEFAULT_DBC_PATH
from dbc.encoding import FrameEncoder
from tests.daq.service_support import (
    WAIT_S,
    free_port,
    leg_messages,
    peer_config,
    write_service_config,
)
from tests.helpers import EXAMPLE_CONFIG, ROOT, example_machine


def run_cli(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "daq", *args],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
        env=env,
    )


def assert_one_line_error(result: subprocess.CompletedProcess[str], status: int, text: str) -> None:
    assert result.returncode == status, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("portal-daq: ") and text in lines[0]
    assert "Traceback" not in result.stderr


def test_bad_config_exits_2_with_one_line(tmp_path: Path) -> None:
    path = write_service_config(tmp_path, port=free_port())
    path.write_text(path.read_text().replace("[bus]\n", "[bus]\nbitrate = 500000\n"))
    assert_one_line_error(run_cli("--config", str(path)), 2, f"{path}: bus.bitrate: unknown key")


def test_a_bad_endpoint_is_one_line_naming_file_and_key(tmp_path: Path) -> None:
    """It was Zenoh's ``Json5Err(Message { msg: "..." at /root/.cargo/...rs:615. ...})``."""
    path = write_service_config(tmp_path, port=free_port())
    path.write_text(path.read_text().replace("listen = [", 'connect = ["nonsense"]\nlisten = ['))
    result = run_cli("run", "--config", str(path), "--log-level", "warning")
    assert_one_line_error(result, 2, f"{path}: zenoh.connect: Endpoints must be of the form ")
    assert result.stderr.rstrip().endswith("[#<config>]: nonsense"), result.stderr


def test_bad_machine_value_exits_2_naming_file_and_key(tmp_path: Path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(EXAMPLE_CONFIG.read_text().replace("median_window = 11", "median_window = 4"))
    assert_one_line_error(run_cli("--config", str(path)), 2, f"{path}: estimator.median_window")


def test_bad_dbc_exits_2(tmp_path: Path) -> None:
    (tmp_path / "broken.dbc").write_text("BO_ nonsense {")
    path = tmp_path / "bad.toml"
    path.write_text(
        EXAMPLE_CONFIG.read_text().replace('# dbc = "portal_sensors.dbc"', 'dbc = "broken.dbc"')
    )
    assert_one_line_error(run_cli("--config", str(path)), 2, "broken.dbc: not a valid DBC")


def test_missing_config_exits_2() -> None:
    assert_one_line_error(run_cli("--config", "/nonexistent.toml"), 2, "no such file")


def test_config_not_utf8_exits_2_naming_the_file(tmp_path: Path) -> None:
    path = tmp_path / "latin1.toml"
    text = "# Hydraulik\u00f6l 46 \u00b0C\n" + EXAMPLE_CONFIG.read_text()
    path.write_bytes(text.encode("latin-1", errors="replace"))
    assert_one_line_error(run_cli("--config", str(path)), 2, f"{path}: not UTF-8 (byte 0xf6")


@pytest.mark.parametrize(
    ("name", "content", "reason"),
    [
        ("portal_sensors.dbc", DEFAULT_DBC_PATH.read_bytes(), "not valid TOML: Expected '='"),
        ("zenoh.json5", b'{ mode: "peer" }\n', "not valid TOML: Invalid statement"),
        ("run.mcap", b"\x89MCAP0\r\n", "not UTF-8 (byte 0x89 at offset 0)"),
    ],
)
def test_a_file_of_another_kind_as_config_says_what_to_give(
    tmp_path: Path, name: str, content: bytes, reason: str
) -> None:
    """The DBC, the Zenoh file or a recording given as ``--config`` got the TOML parser's
    complaint alone; a recording was told "save the file as UTF-8"."""
    path = tmp_path / name
    path.write_bytes(content)
    result = run_cli("replay", str(path), "--config", str(path))
    suffix = path.suffix
    assert_one_line_error(result, 2, f"{path}: {reason}")
    assert result.stderr.endswith(
        f"; a {suffix} file is no config: give the TOML file (e.g. portal-daq.toml)\n"
    )
    assert "save the file as UTF-8" not in result.stderr


def test_zenoh_config_not_utf8_exits_2_naming_the_file(tmp_path: Path) -> None:
    zenoh_file = tmp_path / "zenoh.json5"
    zenoh_file.write_bytes('// Hydraulik\u00f6l\n{ mode: "peer" }\n'.encode("latin-1"))
    path = write_service_config(tmp_path, port=free_port())
    path.write_text(path.read_text().replace("[zenoh]\n", '[zenoh]\nconfig_file = "zenoh.json5"\n'))
    result = run_cli("--config", str(path))
    assert result.returncode == 2, result.stderr
    last = result.stderr.strip().splitlines()[-1]  # after the start-up log lines
    assert last.startswith(f"portal-daq: {zenoh_file}: not a valid Zenoh config: ")
    assert "UTF-8" in last and ".rs:" not in last and "Traceback" not in result.stderr


def test_a_misspelt_zenoh_key_is_zenohs_reason_and_where(tmp_path: Path) -> None:
    """It was ``JSON error: Message { msg: "unknown field ...", location: Some(Location {
    line: 2, column: 3 }) }``."""
    zenoh_file = tmp_path / "zenoh.json5"
    zenoh_file.write_text('{\n  modee: "peer" }\n')
    path = write_service_config(tmp_path, port=free_port())
    path.write_text(path.read_text().replace("[zenoh]\n", '[zenoh]\nconfig_file = "zenoh.json5"\n'))
    result = run_cli("run", "--config", str(path), "--log-level", "warning")
    assert_one_line_error(
        result, 2, f"{zenoh_file}: not a valid Zenoh config: unknown field `modee`, expected"
    )
    assert result.stderr.endswith("` (line 2, column 3)\n"), result.stderr
    assert "Message {" not in result.stderr


def test_unreadable_config_exits_2_naming_the_file(tmp_path: Path) -> None:
    # A directory: unreadable as a file even for root (chmod 000 is not, for root).
    assert_one_line_error(run_cli("--config", str(tmp_path)), 2, f"{tmp_path}: cannot read it")


def test_taken_zenoh_port_exits_1_with_a_hint(tmp_path: Path) -> None:
    port = free_port()
    with zenoh.open(peer_config(listen=f"tcp/127.0.0.1:{port}")):
        result = run_cli("--config", str(write_service_config(tmp_path, port=port)))
    assert result.returncode == 1, result.stderr
    last = result.stderr.strip().splitlines()[-1]  # after the start-up log lines
    assert last.startswith("portal-daq: Zenoh: ") and "Address already in use" in last
    assert "port" in last and ".rs:" not in last and "Traceback" not in result.stderr


def test_a_taken_port_of_the_zenoh_file_is_looked_for_there(tmp_path: Path) -> None:
    # The listen endpoint of `portal-daq init`'s config is in its zenoh.json5; the hint
    # sent the user to [zenoh] listen, which is not in the TOML.
    assert run_cli("init", str(tmp_path)).returncode == 0
    config, zenoh_file = tmp_path / "portal-daq.toml", tmp_path / "zenoh.json5"
    endpoint = f"tcp/127.0.0.1:{free_port()}"  # not 7447: this host's other services
    zenoh_file.write_text(zenoh_file.read_text().replace("tcp/127.0.0.1:7447", endpoint))
    text = config.read_text().replace("/var/lib/portal-daq/recordings", str(tmp_path / "rec"))
    config.write_text(text)
    with zenoh.open(peer_config(listen=endpoint)):
        result = run_cli("run", "--config", str(config))
    assert result.returncode == 1, result.stderr
    last = result.stderr.strip().splitlines()[-1]
    assert "Address already in use" in last
    assert f"(or listen/connect in {zenoh_file})" in last


def test_a_client_whose_router_is_down_is_told_to_look_at_the_router(tmp_path: Path) -> None:
    # In client mode Zenoh gives up at start without its router; the hint was the one of
    # a taken listen port ("is the port taken by another process, ...?").
    endpoint = f"tcp/127.0.0.1:{free_port()}"  # nobody listens
    path = write_service_config(tmp_path, port=free_port())
    text = path.read_text()
    zenoh_table = text[text.index("[zenoh]") : text.index("[publish]")]
    path.write_text(
        text.replace(zenoh_table, f'[zenoh]\nmode = "client"\nconnect = ["{endpoint}"]\n\n')
    )
    result = run_cli("run", "--config", str(path))
    assert result.returncode == 1, result.stderr
    last = result.stderr.strip().splitlines()[-1]
    assert last == (
        f"portal-daq: Zenoh: Unable to connect to any of [{endpoint}]! (check [zenoh] "
        "connect: is the router up at that address and reachable from here? A client needs "
        "it at start; a peer starts without it and keeps trying)"
    )


def test_notify_order_and_clean_sigterm(tmp_path: Path) -> None:
    """READY before STATUS/WATCHDOG, STOPPING last; the MCAP file gets its summary."""
    config = write_service_config(
        tmp_path, channel="notify-test", port=free_port(), recording=tmp_path / "rec"
    )
    address = str(tmp_path / "notify.sock")
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as sock:
        sock.bind(address)
        sock.settimeout(WAIT_S)
        env = dict(os.environ, NOTIFY_SOCKET=address, WATCHDOG_USEC="400000")
        process = subprocess.Popen(
            [sys.executable, "-m", "daq", "--config", str(config)],
            cwd=ROOT,
            env=env,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            messages: list[str] = []
            while not (any(m.startswith("STATUS=") for m in messages) and "WATCHDOG=1" in messages):
                messages.append(sock.recv(4096).decode())
            process.send_signal(signal.SIGTERM)
            status = process.wait(timeout=WAIT_S)
            sock.settimeout(0.5)
            try:
                while True:
                    messages.append(sock.recv(4096).decode())
            except TimeoutError:
                pass
        finally:
            if process.poll() is None:
                process.kill()
            stderr = process.communicate()[1]
    assert status == 0, stderr
    assert messages[0] == "READY=1"
    assert messages[-1] == "STOPPING=1" and messages.count("STOPPING=1") == 1
    assert all(m.startswith(("STATUS=bus up", "WATCHDOG=1")) for m in messages[1:-1]), messages
    # How fast it stops is not asserted (a loaded machine takes seconds; speed is bench's):
    # a stop that hangs fails the wait above, a recorder's process killed for taking too
    # long leaves the file without its summary.
    assert_one_finished_recording(tmp_path / "rec")


def assert_one_finished_recording(directory: Path) -> None:
    """``directory`` holds one recording, finished: a cut file has no summary."""
    (path,) = directory.iterdir()
    with open(path, "rb") as file:
        assert make_reader(file).get_summary() is not None


def write_candump_log(path: Path) -> int:
    config, database = example_machine()
    messages = leg_messages(FrameEncoder(database, config.protection), 4, 1_700_000_000.0)
    with can.Logger(str(path)) as logger:
        for message in messages:
            message.channel = "can0"
            logger.on_message_received(message)
    return len(messages)


def test_replay_cli_on_a_candump_log(tmp_path: Path) -> None:
    log = tmp_path / "drive.log"
    count = write_candump_log(log)
    out = tmp_path / "out.csv"
    result = run_cli("replay", str(log), "--config", str(EXAMPLE_CONFIG), "--out", str(out))
    assert result.returncode == 0, result.stderr
    with open(out, newline="") as file:
        rows = list(csv.DictReader(file))
    assert len(rows) == count
    assert {row["leg"] for row in rows} == {
        "SB1_F1",
        "SB1_F2",
        "SB1_F3",
        "SB2_F1",
        "SB2_F2",
        "SB2_F3",
    }
    assert all(row["valid"] == "1" for row in rows)
    assert float(rows[0]["t"]) == pytest.approx(1_700_000_000.0)


def test_replay_of_a_can_log_needs_a_config(tmp_path: Path) -> None:
    log = tmp_path / "drive.log"
    write_candump_log(log)
    assert_one_line_error(run_cli("replay", str(log)), 2, "needs --config")


@pytest.mark.parametrize("command", ["replay", "report", "calibrate"])
def test_a_can_log_that_does_not_exist_is_said_before_the_config(
    tmp_path: Path, command: str
) -> None:
    """A typo in the log's name was "needs --config", as if --config were what is missing."""
    missing = tmp_path / "drvie.log"
    assert_one_line_error(run_cli(command, str(missing)), 1, f"{missing}: no such file")


def test_an_access_control_zenoh_refuses_is_one_line_naming_the_file(tmp_path: Path) -> None:
    # Zenoh checks a policy's subjects when the session opens: it was exit 1, blamed on
    # a taken port ("check [zenoh] listen/connect ...: is the port taken ...?").
    assert run_cli("init", str(tmp_path)).returncode == 0
    config, zenoh_file = tmp_path / "portal-daq.toml", tmp_path / "zenoh.json5"
    text = zenoh_file.read_text().replace("tcp/127.0.0.1:7447", f"tcp/127.0.0.1:{free_port()}")
    assert 'subjects: ["anyone"] }' in text
    zenoh_file.write_text(text.replace('subjects: ["anyone"] }', 'subjects: ["anyon"] }'))
    result = run_cli("run", "--config", str(config))
    assert_one_line_error(
        result,
        2,
        f"{zenoh_file}: access_control: Subject 'anyon' in policy #0 does not exist in "
        "subjects list",
    )
    assert "is the port taken" not in result.stderr


def service_process(config: Path, notify: str | None = None) -> subprocess.Popen[str]:
    """``portal-daq run`` in a session of its own (so that a signal to its process group,
    as a terminal or systemd sends it, reaches the service and its recorder only)."""
    env = {name: value for name, value in os.environ.items() if name != "NOTIFY_SOCKET"}
    return subprocess.Popen(
        [sys.executable, "-m", "daq", "run", "--config", str(config)],
        cwd=ROOT,
        env=env if notify is None else dict(env, NOTIFY_SOCKET=notify),
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )


def test_sighup_stops_the_service_and_finishes_the_file(tmp_path: Path) -> None:
    # A terminal that closes sends SIGHUP to its process group: the service and its
    # recorder's process died of it, the file cut without its summary.
    config = write_service_config(
        tmp_path, channel=f"hup-{os.getpid()}", port=free_port(), recording=tmp_path / "rec"
    )
    address = str(tmp_path / "notify.sock")
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as sock:
        sock.bind(address)
        sock.settimeout(WAIT_S)
        process = service_process(config, address)
        try:
            while sock.recv(4096).decode() != "READY=1":
                pass
            os.killpg(process.pid, signal.SIGHUP)
            status = process.wait(timeout=WAIT_S)
        finally:
            if process.poll() is None:
                process.kill()
            stderr = process.communicate()[1]
    assert status == 0, stderr
    assert "Traceback" not in stderr
    assert_one_finished_recording(tmp_path / "rec")


def children(pid: int) -> list[int]:
    """The child processes of ``pid`` (Linux: /proc/PID/task/*/children)."""
    found: list[int] = []
    for task in Path(f"/proc/{pid}/task").glob("*/children"):
        try:
            found += [int(child) for child in task.read_text().split()]
        except OSError:  # the thread ended meanwhile
            pass
    return found


def spawned_recorder(pid: int) -> bool:
    """The recorder's process of the service ``pid`` has been started (it may still be
    importing: its start takes ~0.5 s)."""
    for child in children(pid):
        try:
            command = Path(f"/proc/{child}/cmdline").read_bytes()
        except OSError:
            continue
        if b"spawn_main" in command:
            return True
    return False


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGHUP])
def test_a_signal_to_the_group_while_the_recorder_starts_is_a_clean_stop(
    tmp_path: Path, signum: signal.Signals
) -> None:
    # Ctrl-C (or a closing terminal, or systemd's stop) signals the whole process group.
    # Landing while the recorder's process was still importing (before it ignored them),
    # it died of a KeyboardInterrupt traceback, and the service exited 1: "the recorder's
    # process did not start".
    config = write_service_config(
        tmp_path, channel=f"start-{os.getpid()}", port=free_port(), recording=tmp_path / "rec"
    )
    process = service_process(config)
    try:
        deadline = time.monotonic() + WAIT_S
        while not spawned_recorder(process.pid):
            assert process.poll() is None and time.monotonic() < deadline
            time.sleep(0.001)
        os.killpg(process.pid, signum)
        status = process.wait(timeout=WAIT_S)
    finally:
        if process.poll() is None:
            process.kill()
        stderr = process.communicate()[1]
    assert status == 0, stderr
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr
    assert_one_finished_recording(tmp_path / "rec")
