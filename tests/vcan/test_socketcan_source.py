"""The service's own SocketCAN socket on a real vcan0: FD frames, buffer size, drop counter.

Run through ``tests/vcan/with-vcan`` (User-Mode Linux, as root there). No timing is
asserted; every wait is a receive with a timeout.
"""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Iterator

import can
import pytest

from daq.frames import RawFrame
from daq.socketcan import SocketCanSource
from tests.helpers import ROOT

pytestmark = pytest.mark.vcan

CHANNEL = "vcan0"
RECV_TIMEOUT_S = 5.0


@pytest.fixture(scope="module", autouse=True)
def fd_capable_vcan0() -> None:
    """vcan0 with the CAN FD MTU (72), so that FD frames can be sent at all."""
    subprocess.run(["ip", "link", "set", CHANNEL, "down"], check=True)
    subprocess.run(["ip", "link", "set", CHANNEL, "mtu", "72"], check=True)
    subprocess.run(["ip", "link", "set", CHANNEL, "up"], check=True)


@pytest.fixture
def sender() -> Iterator[can.BusABC]:
    with can.Bus(interface="socketcan", channel=CHANNEL) as bus:
        yield bus


def source(receive_buffer_bytes: int = 4 * 1024 * 1024) -> SocketCanSource:
    return SocketCanSource(CHANNEL, receive_buffer_bytes=receive_buffer_bytes)


def receive_all(socket_source: SocketCanSource, timeout_s: float = 1.0) -> list[RawFrame]:
    frames = []
    while (frame := socket_source.recv(timeout_s)) is not None:
        frames.append(frame)
    return frames


def test_classic_and_fd_frames_from_cansend_with_kernel_time_stamps() -> None:
    with source() as socket_source:
        before = time.time()
        subprocess.run(["cansend", CHANNEL, "123#0102"], check=True)
        subprocess.run(["cansend", CHANNEL, "100##1" + "11" * 12], check=True)
        subprocess.run(["cansend", CHANNEL, "18FEF100#AA"], check=True)
        classic, fd, extended = (socket_source.recv(RECV_TIMEOUT_S) for _ in range(3))
    assert classic is not None
    assert (classic.arbitration_id, classic.data, classic.is_fd) == (0x123, b"\x01\x02", False)
    assert fd is not None and (fd.arbitration_id, fd.is_fd, fd.data) == (0x100, True, b"\x11" * 12)
    assert extended is not None and (extended.arbitration_id, extended.is_extended_id) == (
        0x18FEF100,
        True,
    )
    assert classic is not None and before - 1.0 < classic.t_s < time.time() + 1.0


def rmem_max() -> int:
    with open("/proc/sys/net/core/rmem_max") as file:
        return int(file.read())


def test_the_receive_buffer_is_forced_past_rmem_max_as_root() -> None:
    asked = 4 * rmem_max()  # SO_RCVBUF alone would be clamped to rmem_max
    with source(asked) as socket_source:
        # Linux doubles what it grants for its bookkeeping.
        assert socket_source.rcvbuf_bytes == 2 * asked


UNPRIVILEGED_OPEN = """
import logging, sys
logging.basicConfig(level=logging.WARNING, stream=sys.stdout, format="%(levelname)s %(message)s")
from daq.runner import bus_factory
from daq.service_config import BusSettings
open_bus = bus_factory(BusSettings(channel="vcan0", receive_buffer_bytes=int(sys.argv[1])), [])
for _ in range(2):  # a reopen
    source = open_bus()
    print("GRANTED", source.rcvbuf_bytes)
    source.shutdown()
"""


def test_without_cap_net_admin_the_buffer_is_clamped_and_warned_about_once() -> None:
    limit = rmem_max()
    result = subprocess.run(
        ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups", "--inh-caps=-all",
         "--bounding-set=-all", sys.executable, "-c", UNPRIVILEGED_OPEN, str(4 * limit)],
        cwd=ROOT, capture_output=True, text=True, check=True, timeout=120,
    )  # fmt: skip
    assert result.stdout.count(f"GRANTED {2 * limit}") == 2, result.stdout + result.stderr
    (warning,) = [line for line in result.stdout.splitlines() if line.startswith("WARNING")]
    assert f"clamped to {2 * limit} bytes ({4 * limit} asked for" in warning


def test_the_kernel_drop_counter_accounts_for_every_frame_sent(sender: can.BusABC) -> None:
    sent = 300
    with source(2048) as socket_source:  # room for a handful of frames
        for i in range(sent):
            sender.send(can.Message(arbitration_id=0x7AA, data=i.to_bytes(2, "big")), timeout=5)
        early = receive_all(socket_source)
        # The count travels with the frames queued after the drops: send one more.
        sender.send(can.Message(arbitration_id=0x7AB, data=b""), timeout=5)
        late = receive_all(socket_source)
    assert [frame.arbitration_id for frame in late] == [0x7AB]
    assert 0 < len(early) < sent
    assert socket_source.kernel_dropped == sent - len(early)


def test_the_controllers_error_frames_are_received(sender: can.BusABC) -> None:
    # A socket gets error frames only when it asks (CAN_RAW_ERR_FILTER): the service's
    # did not, so a bus-off or an overflow of the controller's receive buffer showed
    # nowhere (python-can's socket, which it replaced, asked for every class).
    bus_off = can.Message(arbitration_id=0x040, is_error_frame=True, dlc=8, data=bytes(8))
    overflow = can.Message(
        arbitration_id=0x004, is_error_frame=True, dlc=8, data=bytes([0, 0x01, 0, 0, 0, 0, 0, 0])
    )
    with source() as socket_source:
        for message in (bus_off, can.Message(arbitration_id=0x123, data=b"\x01"), overflow):
            sender.send(message)
        frames = [socket_source.recv(RECV_TIMEOUT_S) for _ in range(3)]
    assert [(f.arbitration_id, f.is_error_frame) for f in frames if f is not None] == [
        (0x040, True),
        (0x123, False),
        (0x004, True),
    ]
    assert frames[2] is not None and frames[2].data[1] == 0x01  # its detail: rx overflow
