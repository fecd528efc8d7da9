"""Real-SocketCAN checks on vcan0: python-can's socketcan interface and can-utils.

These need a ``vcan0`` that is up; run them through ``tests/vcan/with-vcan`` (User-Mode
Linux), as ``./dev test`` does. Elsewhere tests/conftest.py skips them.

No fixed sleeps: every wait is a receive with a timeout, or a bounded retry loop.
Timing itself is not asserted (inside UML every syscall is slow).
"""

from __future__ import annotations

import re
import shutil
import subprocess
import time
from collections.abc import Iterator

import can
import pytest

CHANNEL = "vcan0"
RECV_TIMEOUT = 5.0  # seconds; generous, the guest is slow

# (arbitration id, extended?, payload): standard and extended ids, DLC 0..8.
FRAMES: list[tuple[int, bool, bytes]] = [
    (0x000, False, b""),
    (0x7FF, False, b"\x01"),
    (0x1FFFFFFF, True, b"\xde\xad"),
    (0x123, False, b"\x00\xff\x10"),
    (0x00000001, True, b"\x11\x22\x33\x44"),
    (0x456, False, b"\xa5\x5a\xa5\x5a\xa5"),
    (0x18FEF100, True, b"\x00\x01\x02\x03\x04\x05"),
    (0x080, False, b"\xff" * 7),
    (0x0CF00400, True, bytes(range(0xF8, 0x100))),
]


def open_bus() -> can.BusABC:
    return can.Bus(interface="socketcan", channel=CHANNEL)


@pytest.fixture
def bus_pair() -> Iterator[tuple[can.BusABC, can.BusABC]]:
    sender = open_bus()
    try:
        receiver = open_bus()
        try:
            yield sender, receiver
        finally:
            receiver.shutdown()
    finally:
        sender.shutdown()


@pytest.fixture
def bus() -> Iterator[can.BusABC]:
    one = open_bus()
    try:
        yield one
    finally:
        one.shutdown()


def recv_one(bus: can.BusABC) -> can.Message:
    msg = bus.recv(timeout=RECV_TIMEOUT)
    assert msg is not None, f"no frame on {CHANNEL} within {RECV_TIMEOUT} s"
    return msg


def assert_frame(msg: can.Message, arbitration_id: int, extended: bool, data: bytes) -> None:
    assert msg.arbitration_id == arbitration_id, hex(msg.arbitration_id)
    assert msg.is_extended_id is extended
    assert bytes(msg.data) == data
    assert msg.dlc == len(data)
    assert not msg.is_remote_frame
    assert not msg.is_error_frame
    assert not msg.is_fd
    assert msg.channel == CHANNEL


@pytest.mark.vcan
def test_python_can_round_trip(bus_pair: tuple[can.BusABC, can.BusABC]) -> None:
    sender, receiver = bus_pair
    for arbitration_id, extended, data in FRAMES:
        sender.send(can.Message(arbitration_id=arbitration_id, is_extended_id=extended, data=data))

    received = [recv_one(receiver) for _ in FRAMES]

    for msg, (arbitration_id, extended, data) in zip(received, FRAMES, strict=True):
        assert_frame(msg, arbitration_id, extended, data)
    timestamps = [msg.timestamp for msg in received]
    assert all(ts > 0 for ts in timestamps), timestamps
    assert timestamps == sorted(timestamps), timestamps
    # Nothing more arrived, and the sender does not hear its own frames.
    assert receiver.recv(timeout=0.2) is None
    assert sender.recv(timeout=0.0) is None


@pytest.mark.vcan
@pytest.mark.parametrize(
    ("frame", "arbitration_id", "extended", "data"),
    [
        ("123#DEADBEEF", 0x123, False, b"\xde\xad\xbe\xef"),
        ("1ABCDEF0#0011223344556677", 0x1ABCDEF0, True, bytes.fromhex("0011223344556677")),
        ("7FF#", 0x7FF, False, b""),
    ],
)
def test_cansend_to_python_can(
    bus: can.BusABC, frame: str, arbitration_id: int, extended: bool, data: bytes
) -> None:
    cansend = shutil.which("cansend")
    assert cansend is not None, "cansend (Debian package can-utils) is not installed"

    subprocess.run([cansend, CHANNEL, frame], check=True, timeout=30)

    assert_frame(recv_one(bus), arbitration_id, extended, data)


CANDUMP_LINE = re.compile(
    r"^\((?P<ts>\d+\.\d+)\) (?P<iface>\S+) (?P<id>[0-9A-F]{3}|[0-9A-F]{8})#(?P<data>[0-9A-F]*)$"
)


@pytest.mark.vcan
@pytest.mark.parametrize(
    ("arbitration_id", "extended", "data"),
    [
        (0x321, False, b"\xca\xfe\x00\x01"),
        (0x10FF00AA, True, b"\x01\x23\x45\x67\x89\xab\xcd\xef"),
    ],
)
def test_python_can_to_candump(
    bus: can.BusABC, arbitration_id: int, extended: bool, data: bytes
) -> None:
    candump = shutil.which("candump")
    assert candump is not None, "candump (Debian package can-utils) is not installed"
    msg = can.Message(arbitration_id=arbitration_id, is_extended_id=extended, data=data)

    # candump has no "ready" signal: send the same frame until it has caught one
    # and exited (-n 1), within a deadline.
    proc = subprocess.Popen(
        [candump, "-L", "-n", "1", CHANNEL],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 30.0
        while True:
            bus.send(msg)
            try:
                proc.wait(timeout=0.05)
                break
            except subprocess.TimeoutExpired:
                assert time.monotonic() < deadline, "candump saw no frame within 30 s"
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()

    assert proc.returncode == 0, err
    lines = out.splitlines()
    assert len(lines) == 1, out
    match = CANDUMP_LINE.match(lines[0])
    assert match is not None, lines[0]
    assert match["iface"] == CHANNEL
    assert float(match["ts"]) > 0
    assert int(match["id"], 16) == arbitration_id
    assert (len(match["id"]) == 8) is extended
    assert bytes.fromhex(match["data"]) == data
