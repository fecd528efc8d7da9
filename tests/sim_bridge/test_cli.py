"""python -m sim_bridge: plays on a virtual bus, writes truth, fails in one line, obeys SIGTERM."""

import csv
import errno
import os
import re
import signal
import socket
import subprocess
import sys
import uuid
from importlib import metadata
from pathlib import Path

import can
import pytest
from mcap.reader import make_reader

from dbc.decoding import FrameDecoder
from sim_bridge.__main__ import cli
from sim_bridge._args import BridgeOptions, parse_args
from sim_bridge.faults import FaultWindow
from tests.helpers import EXAMPLE_CONFIG, EXAMPLE_SERVICE_CONFIG, ROOT
from tests.sim_bridge.synthetic import CONFIG, DATABASE, make_result, write_export


@pytest.fixture()
def export(tmp_path: Path) -> list[str]:
    data, mapping = write_export(tmp_path, make_result(duration_s=0.5))
    return ["--input", str(data), "--mapping", str(mapping)]


def virtual(channel: str) -> list[str]:
    return ["--config", str(EXAMPLE_CONFIG), "--interface", "virtual", "--channel", channel]


def drain(bus: can.BusABC) -> list[can.Message]:
    messages = []
    while (message := bus.recv(timeout=0)) is not None:
        messages.append(message)
    return messages


def test_plays_an_export_onto_the_bus_with_truth(tmp_path: Path, export: list[str]) -> None:
    channel = f"cli-{uuid.uuid4()}"
    truth_csv, truth_mcap = tmp_path / "truth.csv", tmp_path / "truth.mcap"
    args = [*virtual(channel), *export, "--cycles", "2", "--as-fast-as-possible"]
    args += ["--truth-csv", str(truth_csv), "--truth-mcap", str(truth_mcap)]
    with can.Bus(interface="virtual", channel=channel) as rx:
        assert cli(args) == 0
        messages = drain(rx)
    decoder = FrameDecoder(DATABASE, CONFIG.protection)
    frames = [decoder.decode(m.arbitration_id, bytes(m.data), m.timestamp) for m in messages]
    assert sum(f.message == "LEG_SB1_F1" for f in frames) == 100
    assert all(f.crc_ok and f.counter_ok for f in frames)
    with open(truth_csv, newline="") as stream:
        rows = list(csv.DictReader(stream))
    assert len(rows) == 100 and rows[-1]["cycle"] == "1"
    with open(truth_mcap, "rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None and summary.statistics.message_count == 100


def test_faults_from_the_command_line(export: list[str]) -> None:
    channel = f"cli-{uuid.uuid4()}"
    args = [*virtual(channel), *export, "--as-fast-as-possible", "--seed", "3"]
    args += ["--silent", "SB1_F1@0.1:0.2", "--bad-crc", "1", "--pause", "0.4:0.05"]
    with can.Bus(interface="virtual", channel=channel) as rx:
        assert cli(args) == 0
        messages = drain(rx)
    decoder = FrameDecoder(DATABASE, CONFIG.protection)
    frames = [decoder.decode(m.arbitration_id, bytes(m.data), m.timestamp) for m in messages]
    assert sum(f.message == "LEG_SB1_F1" for f in frames) == 50 - 20 - 5
    assert sum(f.message == "LEG_SB1_F2" for f in frames) == 50 - 5
    assert not any(f.crc_ok for f in frames)


def test_the_model_drives_the_bus(tmp_path: Path) -> None:
    channel = f"cli-{uuid.uuid4()}"
    truth_csv = tmp_path / "truth.csv"
    args = [*virtual(channel), "--rtol", "1e-3", "--duration", "0.5", "--as-fast-as-possible"]
    with can.Bus(interface="virtual", channel=channel) as rx:
        assert cli([*args, "--truth-csv", str(truth_csv)]) == 0
        messages = drain(rx)
    assert sum(m.arbitration_id == 0x100 for m in messages) == 50
    with open(truth_csv, newline="") as stream:
        rows = list(csv.DictReader(stream))
    assert len(rows) == 50 and float(rows[0]["force_true_N_SB1_F1"]) > 0


def test_plot_subcommand_writes_a_png(tmp_path: Path, export: list[str]) -> None:
    out = tmp_path / "cycle.png"
    assert cli(["plot", "--config", str(EXAMPLE_CONFIG), *export, "--out", str(out)]) == 0
    assert out.read_bytes().startswith(b"\x89PNG") and out.stat().st_size > 10_000


@pytest.mark.parametrize(
    ("extra", "expected"),
    [
        (["--config", "nowhere.toml"], "sim_bridge: nowhere.toml: no such file"),
        (["--silent", "SB9_F9@1:1"], "sim_bridge: fault flags: --silent SB9_F9@1:1: no message"),
        (["--interface", "socketcan", "--channel", "nonexistent9"], "cannot open the bus"),
        (["--truth-csv", "/nonexistent-dir/truth.csv"], "/nonexistent-dir/truth.csv: cannot write"),
        (["--sensor-fault", "LEG_SB1_F1@1:1"], "--sensor-fault LEG_SB1_F1@1:1: no leg"),
    ],
)
def test_bad_input_is_one_line_on_stderr_and_status_2(
    export: list[str], extra: list[str], expected: str, capsys: pytest.CaptureFixture[str]
) -> None:
    args = [*virtual(f"cli-{uuid.uuid4()}"), *export, "--as-fast-as-possible", *extra]
    assert cli(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and expected in err[0] and err[0].startswith("sim_bridge: "), err


def closed_port() -> int:
    with socket.socket() as sock:  # bound, never listening: a connect is refused
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


@pytest.mark.parametrize(
    ("extra", "expected"),
    [
        (["--connect", "nonsense"], "sim_bridge: --connect: Endpoints must be of the form "),
        (["--zenoh-config", "nothere.json5"], "sim_bridge: nothere.json5: no such file; give "),
        (["--zenoh-config", str(EXAMPLE_SERVICE_CONFIG)], "config: TOML: unknown field `bus`"),
        (["--mode", "client", "--connect", "tcp/127.0.0.1:PORT"], "Unable to connect to any of"),
    ],
)
def test_a_zenoh_option_refused_is_one_line_naming_it(
    export: list[str], extra: list[str], expected: str, capsys: pytest.CaptureFixture[str]
) -> None:
    # They were Zenoh's own words, with the Rust source line of each error, blamed on
    # --zenoh, and the whole service config (10 KB) given as --zenoh-config.
    extra = [arg.replace("PORT", str(closed_port())) for arg in extra]
    args = [*virtual(f"cli-{uuid.uuid4()}"), *export, "--as-fast-as-possible", "--zenoh", *extra]
    assert cli(args) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert expected in line and ".rs:" not in line and "Single(" not in line, line
    assert len(line) < 500, line


def test_a_kernel_without_socketcan_is_told_so(
    export: list[str], capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    # It was told to `ip link add dev vcan0 type vcan`, which such a kernel cannot do.
    def no_socketcan(**kwargs: object) -> can.BusABC:
        raise OSError(errno.EAFNOSUPPORT, "Address family not supported by protocol")

    monkeypatch.setattr(can, "Bus", no_socketcan)
    args = [*virtual("vcan0"), *export, "--as-fast-as-possible"]
    assert cli(args) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "cannot open the bus: Address family not supported by protocol; this kernel has no " \
        "SocketCAN: load it (sudo modprobe can-raw;" in line, line  # fmt: skip
    assert line.endswith("or set --interface to another python-can interface"), line
    assert "ip link add" not in line


def test_a_bad_mapping_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data, mapping = write_export(tmp_path, make_result(duration_s=0.2))
    mapping.write_text(mapping.read_text().replace('rod = "r_SB2_F2"', 'rod = "nope"'))
    assert cli(["plot", "--input", str(data), "--mapping", str(mapping), "--out", "x.png"]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "mapping.toml: legs.SB2_F2.rod: no column 'nope' in " in line


@pytest.mark.parametrize(
    "argv",
    [
        ["--drop", "2"],
        ["--speed", "0"],
        ["--cycles", "-1"],
        ["--silent", "SB1_F1"],
        ["--pause", "SB1_F1@1:2"],
        ["--input", "x.csv"],
        ["--mode", "client"],
        ["--truth-every", "0"],
        ["--truth-every", "-1"],
        ["--rtol", "1"],
        # The solver would run for minutes (not ended after 5 at 1e-300): a hang.
        ["--rtol", "1e-300"],
        ["--rtol", "1e-11"],
        ["--steps", "3"],
        ["--steps", "0"],
        ["--steps", "2", "--input", "x.csv", "--mapping", "m.toml"],
        ["plot"],
    ],
)
def test_bad_usage_exits_2(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        cli(argv)
    assert info.value.code == 2
    assert "error:" in capsys.readouterr().err


def test_an_rtol_the_solver_would_take_minutes_for_is_refused_naming_it(
    capsys: pytest.CaptureFixture[str],
) -> None:
    with pytest.raises(SystemExit) as info:
        cli(["--rtol", "1e-300"])
    assert info.value.code == 2
    assert "argument --rtol: must be within [1e-10, 1), got '1e-300'" in capsys.readouterr().err


def test_version_is_the_installed_one(capsys: pytest.CaptureFixture[str]) -> None:
    """``portal-sim --version`` was "unrecognized arguments" (exit 2) where ``portal-daq
    --version`` printed the version of the wheel both came in."""
    with pytest.raises(SystemExit) as info:
        cli(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out == f"portal-sim {metadata.version('portal-daq')}\n"


def test_options_parse_as_documented() -> None:
    options, _ = parse_args(
        ["--speed", "10", "--cycles", "0", "--drop", "0.01", "--bad-crc", "0.001",
         "--freeze-counter", "LEG_SB1_F1@10:2", "--silent", "SB2_F3@12:1",
         "--stuck", "SB1_F2@5:3", "--out-of-range", "SB1_F3@20:0.5", "--pause", "30:1",
         "--seed", "7", "--zenoh", "--mode", "client", "--connect", "tcp/10.0.0.1:7447",
         "--steps", "2"]
    )  # fmt: skip
    assert isinstance(options, BridgeOptions)
    default, _ = parse_args([])
    assert options.source.steps == 2 and isinstance(default, BridgeOptions)
    assert default.source.steps == 1
    assert (options.speed, options.cycles, options.interface, options.channel) == (
        10.0, 0, "socketcan", "vcan0",
    )  # fmt: skip
    faults = options.faults
    assert (faults.drop_probability, faults.bad_crc_probability, faults.seed) == (0.01, 0.001, 7)
    assert faults.freeze_counter == (FaultWindow("LEG_SB1_F1", 10.0, 2.0),)
    assert faults.pause == (FaultWindow("", 30.0, 1.0),)
    assert options.zenoh is not None and options.zenoh.connect == ("tcp/10.0.0.1:7447",)


def test_zenoh_truth_from_the_command_line(export: list[str]) -> None:
    args = [*virtual(f"cli-{uuid.uuid4()}"), *export, "--as-fast-as-possible", "--duration", "0.1"]
    args += ["--zenoh", "--no-multicast-scouting", "--listen", "tcp/127.0.0.1:0"]
    assert cli(args) == 0


def test_sigterm_stops_cleanly_and_the_mcap_file_is_valid(
    tmp_path: Path, export: list[str]
) -> None:
    truth_mcap = tmp_path / "truth.mcap"
    args = [*virtual("smoke"), *export, "--cycles", "0", "--truth-mcap", str(truth_mcap), "-v"]
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    with subprocess.Popen(
        [sys.executable, "-m", "sim_bridge", *args],
        cwd=ROOT,
        env=env,
        stderr=subprocess.PIPE,
        text=True,
    ) as process:
        assert process.stderr is not None
        lines = []
        for line in process.stderr:  # wait for the event, not for a time
            lines.append(line)
            if "first instant sent" in line:
                break
        process.send_signal(signal.SIGTERM)
        _, rest = process.communicate(timeout=30)
    assert process.returncode == 0, "".join(lines) + rest
    assert "stopped by SIGTERM" in rest
    with open(truth_mcap, "rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None and [c.topic for c in summary.channels.values()] == ["/sim/truth"]
    written = re.search(r"wrote (\d+) truth samples", rest)
    assert written and summary.statistics.message_count == int(written.group(1)) >= 1
