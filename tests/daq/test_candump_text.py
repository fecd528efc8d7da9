"""candump's readable output (``candump -ta can0 > trace.log``) replayed as its ``-L``
log is: python-can read only ``-L`` lines, so such a trace stopped at its first line."""

import io
import logging
import re
from datetime import datetime
from pathlib import Path

import pytest

from daq.candump_text import dash_l_line
from daq.replay import can_log_frames, replay
from daq.replay_command import replay_main
from tests.daq.test_foreign_logs import sim_log
from tests.helpers import EXAMPLE_CONFIG

_DASH_L = re.compile(r"\((?P<t>[^)]+)\) (?P<iface>\S+) (?P<id>\w+)#(?P<data>\w*)")


def readable(log: Path, time_format: str = "a", extra: bool = False) -> str:
    """The frames of the ``-L`` ``log`` as candump prints them with ``-t{time_format}``,
    ``-a`` (and ``-x`` where ``extra``)."""
    lines = []
    for line in log.read_text().splitlines():
        match = _DASH_L.match(line)
        assert match is not None, line
        data = bytes.fromhex(match["data"])
        t_s = float(match["t"])
        time = (
            datetime.fromtimestamp(t_s).strftime("%Y-%m-%d %H:%M:%S.%f")
            if time_format == "A"
            else match["t"]
        )
        ascii_column = "".join(chr(b) if 0x20 <= b < 0x7F else "." for b in data)
        octets = " ".join(f"{b:02X}" for b in data)
        direction = "RX - -  " if extra else ""
        lines.append(
            f" ({time})  {match['iface']}  {direction}{match['id']:>3}   [{len(data)}]  "
            f"{octets}   '{ascii_column}'"
        )
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize(("time_format", "extra"), [("a", False), ("a", True), ("A", False)])
def test_a_readable_candump_trace_replays_as_its_dash_l_log(
    tmp_path: Path, time_format: str, extra: bool
) -> None:
    log = sim_log(tmp_path, seconds=0.3)
    trace = tmp_path / "trace.log"
    trace.write_text(readable(log, time_format, extra))
    expected, got = io.StringIO(), io.StringIO()
    assert replay(log, expected, EXAMPLE_CONFIG) == replay(trace, got, EXAMPLE_CONFIG) == 6 * 30
    assert got.getvalue() == expected.getvalue()


def test_a_readable_trace_whose_clock_steps_back_replays_as_its_dash_l_log(
    tmp_path: Path,
) -> None:
    # NTP stepping the logger's clock back 3 s mid-trace (or -tA's local time when
    # daylight saving ends): dated times going back are no -td steps; it was refused.
    log = sim_log(tmp_path, seconds=0.3)
    lines = log.read_text().splitlines()
    middle = len(lines) // 2
    for i in range(middle, len(lines)):
        stamp, rest = lines[i].split(")", 1)
        lines[i] = f"({float(stamp[1:]) - 3.0:.6f}){rest}"
    log.write_text("\n".join(lines) + "\n")
    trace = tmp_path / "trace.log"
    trace.write_text(readable(log))
    expected, got = io.StringIO(), io.StringIO()
    assert replay(log, expected, EXAMPLE_CONFIG) == replay(trace, got, EXAMPLE_CONFIG) == 6 * 30
    assert got.getvalue() == expected.getvalue()


def test_the_ascii_column_a_data_byte_0x23_prints_as_hash_is_no_dash_l_line() -> None:
    line = " (1750000000.000000)  can0  100   [2]  23 41   '#A'"
    assert dash_l_line(line) == "(1750000000.000000) can0 100#2341\n"


@pytest.mark.parametrize(
    ("line", "expected"),
    [
        ("(1.5)  can0  7FF   [0]  remote request", "(1.5) can0 7FF#R0\n"),
        ("(1.5)  can0  123  [12]  " + "00 " * 12, "(1.5) can0 123##0" + "00" * 12 + "\n"),
        ("(1.5) can0 100#0102", "(1.5) can0 100#0102"),  # -L passes
        # a CAN FD frame of 8 bytes (two digits: [08]) is one, with -x's BRS / ESI flags;
        # it was read as a classic frame, estimates from frames the service refuses
        ("(1.5)  can0  100  [08]  " + "01 " * 8, "(1.5) can0 100##0" + "01" * 8 + "\n"),
        ("(1.5)  can0  RX B -  100  [08]  " + "01 " * 8, "(1.5) can0 100##1" + "01" * 8 + "\n"),
        ("(1.5)  can0  TX B E  100  [02]  01 02", "(1.5) can0 100##30102\n"),
        # -8: a classic frame's raw DLC in braces (9 to F: 8 bytes); stopped the replay
        ("(1.5)  can0  100   {F}  " + "01 " * 8, "(1.5) can0 100#" + "01" * 8 + "\n"),
        ("(1.5)  can0  100   {2}  01 02", "(1.5) can0 100#0102\n"),
        # -c's colours around the interface: its name was 'ESC[1;31mcan0ESC[0m'
        ("(1.5)  \x1b[1;31mcan0\x1b[0m  100   [2]  01 02", "(1.5) can0 100#0102\n"),
    ],
)
def test_remote_fd_and_dash_l_lines(line: str, expected: str) -> None:
    assert dash_l_line(line) == expected


def test_a_dated_time_to_the_nanosecond_is_read_to_the_nanosecond() -> None:
    # candump -tA -N: 9 digits after the second ('unconverted data remains: 000', exit 1)
    line = " (2026-12-02 17:27:42.001854321)  can0  100   [2]  01 02"
    second = datetime(2026, 12, 2, 17, 27, 42).timestamp()
    assert dash_l_line(line) == f"({second:.0f}.001854321) can0 100#0102\n"


def test_a_dash_l_line_with_an_odd_number_of_hex_digits_stops_the_replay(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A line damaged in the middle of a log (``1C`` cut to ``1``): python-can read the
    lone digit as a byte (0x01), a frame of other data, counted a CRC fault."""
    log = sim_log(tmp_path, seconds=0.1)
    lines = log.read_text().splitlines()
    lines[7] = lines[7].split()[0] + " " + lines[7].split()[1] + " " + lines[7].split()[2][:-1]
    log.write_text("\n".join(lines) + "\n")
    assert replay_main([str(log), "--config", str(EXAMPLE_CONFIG), "--out", "/dev/null"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith(
        f"portal-daq: {log}: unreadable after frame 7 (line 8): an odd number of hex"
    )


def test_a_dash_l_line_with_a_raw_dlc_over_8_replays_as_its_8_bytes(tmp_path: Path) -> None:
    """An interface with ``cc-len8-dlc`` on: candump -l writes a classic frame of 8
    bytes sent with DLC 9..F as ``100#1122334455667788_9``; python-can stopped at it
    (``invalid literal for int() with base 16: '_9'``, exit 1)."""
    log = sim_log(tmp_path, seconds=0.1)
    expected = io.StringIO()
    rows = replay(log, expected, EXAMPLE_CONFIG)
    lines = log.read_text().splitlines()
    raw_dlc = tmp_path / "raw_dlc.log"
    # python-can writes `(T) vcan0 ID#DATA R`: the raw DLC goes after DATA, before ` R`
    raw_dlc.write_text(
        "\n".join(line.replace(" R", "_9 R") if i % 3 else line for i, line in enumerate(lines))
        + "\n"
    )
    assert raw_dlc.read_text().count("_9 R") == len(lines) - len(lines[::3])
    got = io.StringIO()
    assert replay(raw_dlc, got, EXAMPLE_CONFIG) == rows == 6 * 10
    assert got.getvalue() == expected.getvalue()


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        (
            "  can0  100   [8]  00 00 00 00 00 00 00 00\n",
            "unreadable after frame 0 (line 1): a candump line without a time: candump -L (or -ta) "
            "writes the frame times a replay needs",
        ),
        (
            # frames of no DBC message (a LEG_SB1_F1 of one byte is logged as wrong_dlc)
            " (000.000000)  can0  7F0   [1]  00\n (000.010000)  can0  7F0   [1]  00\n"
            " (000.000250)  can0  7F1   [1]  00\n",
            "unreadable after frame 2 (line 3): frame times go backwards (0.010000 then 0.000250): "
            "candump -td's steps between frames? candump -L (or -ta) writes the frame times",
        ),
        (
            " (1.000000)  can0  100   [8]  00 00 00\n",
            "unreadable after frame 0 (line 1): [8] and its data bytes differ: "
            "'(1.000000)  can0  100",
        ),
    ],
)
def test_a_trace_that_cannot_be_replayed_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, reason: str
) -> None:
    trace = tmp_path / "trace.log"
    trace.write_text(text)
    assert replay_main([str(trace), "--config", str(EXAMPLE_CONFIG)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"portal-daq: {trace}: ") and reason in err[0], err


def test_error_frames_of_every_class_are_counted_as_error_frames(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """python-can's reader took an error frame of a class other than bus error (0x080)
    for a data frame of the class's ID (bus-off 0x040: unknown_id), and stopped at the
    lines ``candump -e`` describes an error frame in (exit 1)."""
    log = sim_log(tmp_path, seconds=0.3)
    lines = log.read_text().splitlines()
    stamp, interface = lines[10].split()[:2]
    errors = ("20000040#0000000000000000", "20000004#0004000000000060", "20000080#00")
    lines[10:10] = [f"{stamp} {interface} {frame}" for frame in errors]
    log.write_text("\n".join(lines) + "\n")
    trace = tmp_path / "trace.log"
    readable_lines = readable(log).splitlines()
    # -e's lines after the second and the first error frame
    readable_lines[12:12] = [
        "\tcontroller-problem{rx-error-warning}",
        "\terror-counter-tx-rx{{0}{96}}",
    ]
    readable_lines[11:11] = ["\tbus-off"]
    trace.write_text("\n".join(readable_lines) + "\n")
    for path in (log, trace):
        caplog.clear()
        with caplog.at_level(logging.WARNING):
            assert replay(path, io.StringIO(), EXAMPLE_CONFIG) == 6 * 30
        assert f"{len(lines)} frames, 3 of them not used (error_frame 3)" in caplog.text
        assert (
            f"{path}: the CAN controller reported bus off 1, controller problems 1, bus error 1: "
            "each counted as an error frame" in caplog.text
        )


def test_an_error_frame_is_of_its_interface(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """python-can gave a candump error frame no channel: a bus-off of can1 was counted in
    a replay of can0."""
    log = tmp_path / "two.log"
    log.write_text(
        "(1750000000.000000) can0 100#461208070000001C\n"
        "(1750000000.001000) can1 20000040#0000000000000000\n"
        "(1750000000.002000) can0 20000004#0004000000000060\n"
    )
    frames = list(can_log_frames(log, "can0"))
    assert [(f.arbitration_id, f.is_error_frame) for f in frames] == [(0x100, False), (0, True)]
    assert "reported controller problems 1: each" in caplog.text and "bus off" not in caplog.text
    caplog.clear()
    assert [f.is_error_frame for f in can_log_frames(log, "can1")] == [True]
    assert "reported bus off 1: each" in caplog.text
