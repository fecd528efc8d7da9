"""The bridge's frame log (``--frames-log``): written as it sends, read by ``portal-daq
replay``, which then gives the estimates the live service gave, bit for bit.

The live side is the service in-process on a python-can ``virtual`` bus with its real
recorder (real MCAP); the log is python-can's own writers and readers.
"""

from __future__ import annotations

import csv
import io
import subprocess
import sys
import time
import uuid
from pathlib import Path

import can
import pytest

from daq.errors import RecordingError
from daq.replay import replay
from daq.service_config import load_service_config
from sim_bridge.__main__ import cli
from sim_bridge.emitter import Emitter
from tests.daq.service_support import WAIT_S, free_port, write_service_config
from tests.daq.test_service_live import live_estimates, live_service
from tests.helpers import EXAMPLE_CONFIG, LEGS
from tests.sim_bridge.synthetic import make_playout, make_result

KEYS = ("t", "force_N", "force_raw_N", "pressure_Pa", "p_piston_Pa", "p_rod_Pa")


def test_the_frames_log_replays_to_the_live_estimates_bit_for_bit(tmp_path: Path) -> None:
    config = load_service_config(
        write_service_config(
            tmp_path, channel=f"log-{uuid.uuid4().hex}", port=free_port(), recording=tmp_path
        )
    )
    log = tmp_path / "cycle.log"
    playout = make_playout(make_result(duration_s=2.0))
    with live_service(config) as service:
        with (
            can.Bus(
                interface="virtual", channel=config.bus.channel, preserve_timestamps=True
            ) as bus,
            can.Logger(log) as frames_log,
        ):
            stats = Emitter(
                bus, playout, end_sim_ns=playout.timeline.cycle_ns, frames_log=frames_log
            ).run()
        sent = sum(stats.sent.values())
        deadline = time.monotonic() + WAIT_S
        while service.pipeline.frames < sent and time.monotonic() < deadline:
            time.sleep(0.01)
        assert service.pipeline.frames == sent
        recorder = service.recorder
        assert recorder is not None
    live = live_estimates(recorder.paths[:1])
    assert len(live) == 6 * stats.sent["LEG_SB1_F1"] == 6 * 200

    out = io.StringIO()
    assert replay(log, out, Path(config.source)) == len(live)
    rows = sorted(
        csv.DictReader(io.StringIO(out.getvalue())), key=lambda row: (float(row["t"]), row["leg"])
    )
    for row, estimate in zip(rows, live, strict=True):
        assert row["leg"] == estimate["leg"]
        assert [float(row[k]) for k in KEYS] == [estimate[k] for k in KEYS]  # bit for bit
        assert (row["contact"], row["valid"]) == (
            str(int(estimate["contact"])),
            str(int(estimate["valid"])),
        )


@pytest.mark.parametrize("suffix", [".log", ".blf", ".asc"])
def test_portal_sim_frames_log_then_portal_daq_replay(tmp_path: Path, suffix: str) -> None:
    """The README's quickest way in, from a directory outside the repository (the
    simulator's default machine config is the packaged example)."""
    log = tmp_path / f"cycle{suffix}"
    args = ["--interface", "virtual", "--channel", f"log-{uuid.uuid4()}", "--as-fast-as-possible"]
    sim = subprocess.run(
        [sys.executable, "-m", "sim_bridge", *args, "--rtol", "1e-3", "--duration", "0.5",
         "--frames-log", str(log), "-q"],
        capture_output=True, text=True, timeout=120, cwd=tmp_path,
    )  # fmt: skip
    assert sim.returncode == 0, sim.stderr
    replayed = subprocess.run(
        [sys.executable, "-m", "daq", "replay", str(log), "--config", str(EXAMPLE_CONFIG)],
        capture_output=True, text=True, timeout=120, cwd=tmp_path,
    )  # fmt: skip
    assert replayed.returncode == 0, replayed.stderr
    rows = list(csv.DictReader(io.StringIO(replayed.stdout)))
    assert len(rows) == 6 * 50  # 0.5 s of six 10 ms leg messages
    assert [row["leg"] for row in rows[:6]] == list(LEGS)
    assert all(row["valid"] == "1" for row in rows), {row["reasons"] for row in rows}
    first_sb1 = float(rows[0]["force_N"])
    assert 15_000 < first_sb1 < 25_000  # the model's SB1_F1 at t = 0 (~19 kN)


def test_an_unknown_frames_log_format_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = ["--interface", "virtual", "--channel", f"log-{uuid.uuid4()}", "--as-fast-as-possible"]
    assert cli([*args, "--duration", "0.1", "--frames-log", str(tmp_path / "x.txt")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--frames-log: no log format for '.txt'" in err[0], err


@pytest.mark.parametrize(
    ("suffix", "bad_line"),
    [
        (".log", "(1750000000.030000) vcan0 100#ZZ\n"),
        (".log", "(1750000000.030000) vcan0\n"),
        (".asc", " 0.030000 1  100             Rx   d 8 GG 00 00 00 00 00 00 00\n"),
    ],
)
def test_a_malformed_line_in_a_can_log_is_one_line_naming_file_and_frame(
    tmp_path: Path, suffix: str, bad_line: str, capsys: pytest.CaptureFixture[str]
) -> None:
    from daq.replay_command import replay_main

    log = tmp_path / f"bad{suffix}"
    with can.Logger(log) as writer:
        for k in range(3):
            writer.on_message_received(
                can.Message(
                    timestamp=1_750_000_000.0 + k / 100, arbitration_id=0x100, data=bytes(8)
                )
            )
    lines = log.read_text().splitlines(keepends=True)
    end = next(i for i, line in enumerate(lines) if "End" in line) if suffix == ".asc" else None
    lines.insert(end if end is not None else len(lines), bad_line)
    log.write_text("".join(lines))
    assert replay_main([str(log), "--config", str(EXAMPLE_CONFIG)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{log}: unreadable after frame 3 (line " in err[0], err


def test_a_log_of_two_buses_is_replayed_one_channel_at_a_time(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A logger on two buses may see the legs' IDs on both (another node, another DBC):
    ``--channel`` picks the machine's bus; without it, replay says it mixes them."""
    from dbc.encoding import FrameEncoder
    from dbc.machine import load_machine_config

    config, database = load_machine_config(EXAMPLE_CONFIG)
    encoder = FrameEncoder.from_config(config, database)
    log = tmp_path / "two_buses.log"
    with can.Logger(log) as writer:
        for k in range(5):
            signals = {"SB1_F1_pPiston": 9e6 + k * 1e5, "SB1_F1_pRod": 1e6, "SB1_F1_Status": "ok"}
            frame = encoder.encode("LEG_SB1_F1", signals)
            for channel, data in (("can0", frame.data), ("can1", bytes(range(8)))):
                writer.on_message_received(can.Message(timestamp=1_750_000_000.0 + k / 100,
                    arbitration_id=frame.arbitration_id, is_extended_id=False, data=data,
                    channel=channel))  # fmt: skip
    out = io.StringIO()
    assert replay(log, out, EXAMPLE_CONFIG, channel="can0") == 5
    rows = list(csv.DictReader(io.StringIO(out.getvalue())))
    assert [float(row["p_piston_Pa"]) for row in rows] == [9e6 + k * 1e5 for k in range(5)]
    assert all(row["valid"] == "1" for row in rows)
    (silent,) = caplog.records  # the log holds LEG_SB1_F1's frames alone
    assert silent.getMessage().startswith("legs silent (no estimate for longer than their stale")
    assert "SB1_F1" not in silent.getMessage() and "SB2_F3 1x, 0.04 s" in silent.getMessage()
    caplog.clear()
    assert replay(log, io.StringIO(), EXAMPLE_CONFIG) == 10
    warning, unused, _ = caplog.records
    assert "more than one channel (can0, can1)" in warning.getMessage()
    assert unused.getMessage() == "10 frames, 5 of them not used (crc 5)"  # can1's
    with pytest.raises(
        RecordingError, match=r"no frame on channel 'can2'; its channels: can0, can1"
    ):
        replay(log, io.StringIO(), EXAMPLE_CONFIG, channel="can2")


def test_a_channel_asked_of_a_service_recording_is_refused(tmp_path: Path) -> None:
    """``replay REC.mcap --channel can1`` replayed every frame of the one bus the service
    read (can0, say), exit 0; report and calibrate refused it already."""
    from daq.frames import RawFrame
    from daq.mcap_file import McapFile, RecordBatch
    from dbc.errors import ConfigError
    from tests.helpers import example_machine

    path = tmp_path / "rec.mcap"
    with open(path, "wb") as stream, McapFile(stream, example_machine()[1]) as mcap:
        mcap.start()
        mcap.write_batch(RecordBatch([RawFrame(1.0, 0x100, False, bytes(8))], []))
    with pytest.raises(ConfigError, match="--channel: picks a CAN log's bus; a service"):
        replay(path, io.StringIO(), EXAMPLE_CONFIG, channel="can1")
    assert replay(path, io.StringIO(), EXAMPLE_CONFIG) == 1  # without --channel, its frame


def test_the_frames_the_rolling_counters_say_were_lost_are_said(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """The live status counts them (frames_lost) and the report's header too; a replay said
    nothing of a log whose counters skip (its estimates valid within max_delta_counter)."""
    from dbc.encoding import FrameEncoder
    from dbc.machine import load_machine_config

    config, database = load_machine_config(EXAMPLE_CONFIG)
    encoder = FrameEncoder.from_config(config, database)
    log = tmp_path / "skips.log"
    signals = {"SB1_F1_pPiston": 9e6, "SB1_F1_pRod": 1e6, "SB1_F1_Status": "ok"}
    with can.Logger(log) as writer:
        for k, counter in enumerate((0, 1, 3, 4, 5, 9)):  # 2 lost (valid), 6..8 (counter)
            frame = encoder.encode("LEG_SB1_F1", signals, counter=counter)
            message = can.Message(
                timestamp=1_750_000_000.0 + k / 100,
                arbitration_id=frame.arbitration_id,
                is_extended_id=False,
                data=frame.data,
            )
            writer.on_message_received(message)
    out = io.StringIO()
    assert replay(log, out, EXAMPLE_CONFIG) == 6
    rows = list(csv.DictReader(io.StringIO(out.getvalue())))
    assert [row["reasons"] for row in rows] == ["", "", "", "", "", "counter"]
    messages = [record.getMessage() for record in caplog.records]
    assert "6 frames, 1 of them not used (counter 1)" in messages
    assert (
        "4 frames lost on the bus before they were logged or recorded, as the rolling "
        "counters of the frames after them tell (frames_lost)" in messages
    )
