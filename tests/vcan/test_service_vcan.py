"""The service as a process on a real SocketCAN vcan0: estimates on Zenoh, link down/up, crash.

Run through ``tests/vcan/with-vcan`` (User-Mode Linux). No timing is asserted;
every wait is for an event (READY=1 on the notify socket, a Zenoh sample, a
recorded frame) with a generous timeout.
"""

from __future__ import annotations

import itertools
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import can
import pytest
from mcap.reader import NonSeekingReader

from daq import can_batch
from daq.mcap_reading import RecordingStream
from daq.pipeline import Pipeline
from daq.replay import replay
from daq.report.content import analyse
from daq.report.loading import load_recording
from daq.report.page import header_rows
from daq.service_config import ServiceConfig, load_service_config
from dbc.encoding import FrameEncoder
from tests.daq.service_support import (
    Collector,
    assert_estimates_match,
    free_port,
    leg_messages,
    leg_signals,
    pressure_series,
    subscriber_session,
    write_service_config,
)
from tests.helpers import LEGS, ROOT, recorded_raw_frames

pytestmark = pytest.mark.vcan

CHANNEL = "vcan0"
START_S = 120.0  # the guest is slow: python imports alone take seconds
WAIT_S = 60.0
FRAMES_PER_LEG = 20


@contextmanager
def service_process(config_path: Path, tmp_path: Path) -> Iterator[subprocess.Popen[str]]:
    """The service on vcan0, returned once it said READY=1; SIGTERM (or kill) at the end."""
    address = str(tmp_path / "notify.sock")
    # The service's log goes to a file: a pipe nobody reads until the end would block
    # the service once its buffer is full.
    log = tmp_path / "service.log"
    with (
        socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as notify,
        log.open("w") as log_file,
    ):
        notify.bind(address)
        notify.settimeout(START_S)
        process = subprocess.Popen(
            [sys.executable, "-m", "daq", "--config", str(config_path)],
            cwd=ROOT,
            # A hung service dumps every thread's stack into its log on SIGABRT.
            env=dict(os.environ, NOTIFY_SOCKET=address, PYTHONFAULTHANDLER="1"),
            stderr=log_file,
            text=True,
        )
        try:
            while notify.recv(4096) != b"READY=1":
                pass
            yield process
        finally:
            if process.poll() is None:
                process.send_signal(signal.SIGTERM)
                try:
                    process.wait(timeout=WAIT_S)
                except subprocess.TimeoutExpired:
                    process.send_signal(signal.SIGABRT)
                    process.wait(timeout=WAIT_S)
            process.communicate()


@contextmanager
def vcan() -> Iterator[can.BusABC]:
    bus = can.Bus(interface="socketcan", channel=CHANNEL)
    try:
        yield bus
    finally:
        bus.shutdown()


def link(state: str) -> None:
    subprocess.run(["ip", "link", "set", CHANNEL, state], check=True)


def make_config(tmp_path: Path, **kwargs: object) -> ServiceConfig:
    path = write_service_config(
        tmp_path, interface="socketcan", channel=CHANNEL, port=free_port(), **kwargs
    )
    return load_service_config(path)


def encoder_for(config: ServiceConfig) -> FrameEncoder:
    return FrameEncoder(config.database, config.machine.protection)


def port_of(config: ServiceConfig) -> int:
    return int(config.zenoh.listen[0].rsplit(":", 1)[1])


def connected(collector: Collector, prefix: str) -> None:
    """Wait until ``collector`` heard the service's status (it is connected)."""
    collector.wait_for(f"{prefix}/status", timeout=WAIT_S)


@contextmanager
def watched_service(
    config: ServiceConfig, tmp_path: Path
) -> Iterator[tuple[subprocess.Popen[str], Collector]]:
    """The service on vcan0, and a collector on its keys that has heard its status."""
    prefix = config.zenoh.key_prefix
    with (
        service_process(Path(config.source), tmp_path) as process,
        subscriber_session(port_of(config)) as session,
    ):
        collector = Collector(session, f"{prefix}/**")
        connected(collector, prefix)
        yield process, collector


@pytest.mark.parametrize("poll_period_ms", [0, 50], ids=["each_wake_up", "coalesced"])
def test_service_on_vcan0_publishes_estimates_matching_eq_4(
    tmp_path: Path, poll_period_ms: int
) -> None:
    """Also with wake-ups coalesced: the frames wait in the socket's receive buffer."""
    config = make_config(tmp_path, extra=f"\n[service]\npoll_period_ms = {poll_period_ms}\n")
    assert config.service.poll_period_ms == poll_period_ms
    prefix = config.zenoh.key_prefix
    with watched_service(config, tmp_path) as (_, collector):
        with vcan() as bus:
            for message in leg_messages(encoder_for(config), FRAMES_PER_LEG, 0.0):
                bus.send(message, timeout=5.0)
        keys = {leg: f"{prefix}/leg/{leg}/ground" for leg in LEGS}
        collector.wait_until(
            lambda: all(len(collector.of(k)) >= FRAMES_PER_LEG for k in keys.values()), WAIT_S
        )
        for seed, (leg, key) in enumerate(keys.items()):
            sent = pressure_series(FRAMES_PER_LEG, seed)
            assert_estimates_match(config.machine, leg, sent, collector.of(key))
        # kernel time stamps, not the sender's (0.0): frame times are now-ish
        assert collector.of(keys["SB1_F1"])[0]["t"] > 1e9


def test_link_down_and_up_service_survives_and_misses_nothing(tmp_path: Path) -> None:
    config = make_config(tmp_path)
    prefix = config.zenoh.key_prefix
    encoder = encoder_for(config)
    key = f"{prefix}/leg/SB1_F1/ground"

    def frame(i: int, counter: int | None = None) -> can.Message:
        encoded = encoder.encode(
            "LEG_SB1_F1", leg_signals("SB1_F1", 9e6 + 1e4 * i, 1e6), counter=counter
        )
        return can.Message(
            arbitration_id=encoded.arbitration_id, data=encoded.data, is_extended_id=False
        )

    with watched_service(config, tmp_path) as (_, collector):
        try:
            with vcan() as bus:
                for i in range(5):
                    bus.send(frame(i), timeout=5.0)
            collector.wait_until(lambda: len(collector.of(key)) == 5, WAIT_S)
            link("down")
            down = collector.wait_for(
                f"{prefix}/status", lambda s: s["bus"]["state"] == "down", WAIT_S
            )
            assert "ip link set vcan0 up" in down["bus"]["reason"]
            link("up")
            # a new sender (a socket that saw the link down holds an ENETDOWN error),
            with vcan() as bus:
                # at once, and with a counter jump: the frames after the gap must be
                # received, and not flagged 'counter' (the counters were reset)
                for i in range(5, 25):
                    bus.send(frame(i, counter=(i + 7) % 16), timeout=5.0)
        finally:
            link("up")
        collector.wait_until(lambda: len(collector.of(key)) == 25, WAIT_S)
        after = collector.of(key)[5:]
        assert [m["valid"] for m in after] == [True] * 20, [m["reasons"] for m in after]
        assert [m["p_piston_Pa"] for m in after] == [9e6 + 1e4 * i for i in range(5, 25)]
        status = collector.wait_for(f"{prefix}/status", lambda s: s["bus"]["state"] == "up", WAIT_S)
        assert status["frames"]["received"] == 25 and status["bad"] == {}


def test_interface_away_and_back_is_reopened(tmp_path: Path) -> None:
    config = make_config(tmp_path)
    prefix = config.zenoh.key_prefix
    key = f"{prefix}/leg/SB1_F1/ground"
    encoder = encoder_for(config)
    with watched_service(config, tmp_path) as (_, collector):
        try:
            subprocess.run(["ip", "link", "del", CHANNEL], check=True)
            away = collector.wait_for(
                f"{prefix}/status", lambda s: s["bus"]["state"] == "absent", WAIT_S
            )
            assert "No such device" in away["bus"]["reason"]
        finally:
            subprocess.run(["ip", "link", "add", "dev", CHANNEL, "type", "vcan"], check=False)
            link("up")
        collector.wait_for(
            f"{prefix}/status",
            lambda s: s["bus"]["state"] == "up" and s["bus"]["reopens"] >= 1,
            WAIT_S,
        )
        # The sender repeats, each frame a valid next counter value, until one arrives:
        # frames sent before the service's socket is reopened are lost by design.
        deadline = time.monotonic() + WAIT_S
        with vcan() as bus:
            for i in itertools.count():
                encoded = encoder.encode("LEG_SB1_F1", leg_signals("SB1_F1", 9e6, 1e6))
                bus.send(
                    can.Message(
                        arbitration_id=encoded.arbitration_id,
                        data=encoded.data,
                        is_extended_id=False,
                    ),
                    timeout=5.0,
                )
                if collector.of(key) or time.monotonic() > deadline:
                    break
                time.sleep(0.05 if i < 20 else 0.5)
        # The estimate that ended the send loop counts: it arrived before this wait.
        estimate = collector.first(key, timeout=WAIT_S)
        assert estimate["valid"] is True
        assert estimate["p_piston_Pa"] == 9e6


def fd_capable_vcan0() -> None:
    """vcan0 with the CAN FD MTU (72), so that FD frames can be sent at all."""
    link("down")
    subprocess.run(["ip", "link", "set", CHANNEL, "mtu", "72"], check=True)
    link("up")


def test_fd_frame_on_a_leg_id_is_counted_and_recorded_raw(tmp_path: Path) -> None:
    fd_capable_vcan0()
    config = make_config(tmp_path, recording=tmp_path / "rec")
    prefix = config.zenoh.key_prefix
    with watched_service(config, tmp_path) as (_, collector):
        # LEG_SB1_F1 (0x100) is a classic 8-byte message: 12 bytes of FD are not it.
        subprocess.run(["cansend", CHANNEL, "100##1" + "11" * 12], check=True)
        status = collector.wait_for(
            f"{prefix}/status", lambda s: s["bad"].get("fd_frame") == 1, WAIT_S
        )
    assert status["frames"]["received"] == 1 and status["bad"] == {"fd_frame": 1}
    assert not collector.of(f"{prefix}/leg/SB1_F1/ground")
    (path,) = (tmp_path / "rec").iterdir()
    (frame,) = recorded_raw_frames(path)  # the frame as received, FD flag in the batch
    assert (frame.arbitration_id, frame.is_fd, frame.data) == (0x100, True, bytes([0x11] * 12))
    assert Pipeline.from_config(config.machine, config.database).process(frame).error_kind == (
        "fd_frame"
    )


#: ~600 frames/s (cangen's gap in ms) for ~4.5 s, a stall of 2 s in the middle.
STALL_GAP_MS = 1.6
STALL_FRAMES = 2700
STALL_S = 2.0


@pytest.mark.parametrize("receive_buffer_bytes", [None, 16384], ids=["default", "small"])
def test_a_stalled_service_loses_no_frame_or_counts_each_lost_one(
    tmp_path: Path, receive_buffer_bytes: int | None
) -> None:
    config = make_config(
        tmp_path, recording=tmp_path / "rec", receive_buffer_bytes=receive_buffer_bytes
    )
    status_key = f"{config.zenoh.key_prefix}/status"
    with watched_service(config, tmp_path) as (process, collector):
        generator = subprocess.Popen(
            ["cangen", CHANNEL, "-g", str(STALL_GAP_MS), "-n", str(STALL_FRAMES)]
            + ["-I", "7AA", "-L", "8", "-D", "i", "-p", "1000"]
        )
        try:
            collector.wait_for(status_key, lambda s: s["frames"]["received"] > 0, WAIT_S)
            process.send_signal(signal.SIGSTOP)
            time.sleep(STALL_S)  # the stall itself, not a wait for something
            process.send_signal(signal.SIGCONT)
            assert generator.wait(timeout=WAIT_S) == 0
        finally:
            process.send_signal(signal.SIGCONT)
            if generator.poll() is None:
                generator.kill()
                generator.wait()
        final = collector.wait_for(
            status_key,
            lambda s: s["frames"]["received"] + s["dropped"]["kernel"] == STALL_FRAMES,
            WAIT_S,
        )
        after = collector.wait_for(status_key, timeout=WAIT_S)  # a period without loss
        statuses = collector.of(status_key)
    lost = final["dropped"]["kernel"]
    recordings = [load_recording(path) for path in sorted((tmp_path / "rec").iterdir())]
    recorded_lost = sum(recording.counts.kernel_dropped for recording in recordings)
    if receive_buffer_bytes is None:
        assert final["bus"]["rcvbuf_bytes"] >= 2 * 4 * 1024 * 1024  # forced: root in UML
        assert (lost, final["frames"]["received"]) == (0, STALL_FRAMES)
        assert recorded_lost == 0
        return
    assert 0 < lost < STALL_FRAMES
    assert final["frames"]["received"] == STALL_FRAMES - lost  # exact: every frame accounted
    rises = [
        later
        for earlier, later in itertools.pairwise(statuses)
        if later["dropped"]["kernel"] > earlier["dropped"]["kernel"]
    ]
    assert rises and all(status["healthy"] is False for status in rises)
    # The period after the loss has none; its only problem may be the silence after
    # cangen stopped (no frame for the stale time is unhealthy too), which cangen's
    # frames, of an ID the DBC does not have, make "no frame of the DBC for ...".
    silence = ("no frame for", "no frame of the DBC for")
    assert all(p.startswith(silence) for p in after["problems"]), after["problems"]
    assert recorded_lost == lost
    (lossy,) = [recording for recording in recordings if recording.counts.kernel_dropped]
    in_file = lossy.counts.kernel_dropped
    rows = dict(header_rows(analyse(lossy)))
    assert rows["frames lost before processing"].startswith(f"{in_file} ({in_file} by the kernel")


def test_sigkill_leaves_a_recording_readable_up_to_its_last_chunk(tmp_path: Path) -> None:
    config = make_config(tmp_path, recording=tmp_path / "rec", chunk_size=4096)
    messages = leg_messages(encoder_for(config), FRAMES_PER_LEG, 0.0)
    with service_process(Path(config.source), tmp_path) as process:
        with vcan() as bus:
            for message in messages:
                bus.send(message, timeout=5.0)
        (path,) = (tmp_path / "rec").iterdir()
        deadline = time.monotonic() + WAIT_S
        while len(recorded_raw_frames(path)) < len(messages):  # flushed every 0.2 s
            assert time.monotonic() < deadline, "frames not recorded"
            time.sleep(0.1)
        process.kill()
        process.wait(timeout=WAIT_S)
    frames = recorded_raw_frames(path)
    sent = [(m.arbitration_id, bytes(m.data)) for m in messages]
    assert [(f.arbitration_id, f.data) for f in frames[: len(sent)]] == sent
    # mcap's own non-seeking reader, tolerating the missing summary
    count = 0
    with open(path, "rb") as file:
        try:
            for _, channel, message in NonSeekingReader(file).iter_messages(log_time_order=False):
                if channel.topic == "/can/raw":
                    count += len(list(can_batch.decode(message.data)))
        except Exception:  # noqa: BLE001 -- the end is cut off
            pass
    assert count >= len(sent)
    with open(path, "rb") as file:
        stream = RecordingStream(file)
        list(stream)
        assert not stream.complete  # no summary: the process was killed
    # the crashed file replays (configuration embedded in the file)
    with open(tmp_path / "out.csv", "w") as out:
        assert replay(path, out) >= len(sent)
