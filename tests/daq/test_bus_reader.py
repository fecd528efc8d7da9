"""The reader's bus states: down keeps the socket, away reopens it, both reset the counters."""

from __future__ import annotations

import errno
import logging
import queue
import threading
import time
import uuid
from collections import deque
from typing import Any

import can
import pytest

from daq.bus_reader import BusReader, bus_error
from daq.frames import BusEvent, RawFrame
from daq.runner import bus_factory, kernel_filters
from daq.service_config import BusSettings

WAIT_S = 10.0


class ScriptedBus(can.BusABC):
    """A bus whose recv() plays a script: messages, errors, then silence."""

    def __init__(self, script: list[Any]) -> None:
        super().__init__(channel="scripted")
        self.script = deque(script)
        self.closed = False

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        if not self.script:
            time.sleep(min(timeout or 0.0, 0.01))
            return None, False
        item = self.script.popleft()
        if isinstance(item, BaseException):
            raise item
        return item, False

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        raise NotImplementedError

    def shutdown(self) -> None:
        self.closed = True
        super().shutdown()


def message(arbitration_id: int) -> can.Message:
    return can.Message(arbitration_id=arbitration_id, data=b"", is_extended_id=False)


def drain(inbox: queue.Queue[RawFrame | BusEvent], count: int) -> list[Any]:
    items = []
    for _ in range(count):
        item = inbox.get(timeout=WAIT_S)
        items.append(
            (item.state, item.reset_counters) if isinstance(item, BusEvent) else item.arbitration_id
        )
    return items


def test_down_keeps_the_socket_away_reopens_and_both_reset_counters() -> None:
    enetdown = can.CanOperationError("Network is down", errno.ENETDOWN)
    enodev = can.CanOperationError("No such device", errno.ENODEV)
    first = ScriptedBus([message(1), enetdown, None, message(2), enodev])
    second = ScriptedBus([message(3)])
    buses: deque[Any] = deque([first, OSError(errno.ENODEV, "No such device"), second])

    def open_bus() -> can.BusABC:
        bus = buses.popleft()
        if isinstance(bus, BaseException):
            raise bus
        return bus

    inbox: queue.Queue[RawFrame | BusEvent] = queue.Queue()
    with BusReader(open_bus, inbox, channel="can0") as reader:
        assert drain(inbox, 8) == [
            ("up", False),  # opened
            1,
            ("down", False),  # ENETDOWN: socket kept
            ("up", True),  # a frame came again: counters reset
            2,
            ("absent", False),  # ENODEV: closed, reopened with backoff
            ("up", True),  # reopened
            3,
        ]
    assert first.closed and second.closed
    assert reader.reopens == 1 and reader.received == 3


def test_down_then_link_probe_up_without_frames() -> None:
    enetdown = can.CanOperationError("Network is down", errno.ENETDOWN)
    link = {"up": False}
    inbox: queue.Queue[RawFrame | BusEvent] = queue.Queue()
    reader = BusReader(
        lambda: ScriptedBus([enetdown]), inbox, channel="can0", link_up=lambda: link["up"]
    )
    with reader:
        assert drain(inbox, 2) == [("up", False), ("down", False)]
        assert "ip link set can0 up" in reader.reason
        link["up"] = True
        assert drain(inbox, 1) == [("up", True)]


def test_python_cans_own_error_is_logged_once_per_state_change(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """python-can's socketcan backend logs "Could not access SocketCAN device" at ERROR on
    each failed open; while the bus stays absent, the retries do not repeat it."""
    python_can = logging.getLogger("can.interfaces.socketcan.socketcan")
    attempts: list[int] = []
    enough = threading.Event()
    buses: deque[Any] = deque([OSError(errno.ENODEV, "No such device")] * 4)
    buses.append(ScriptedBus([message(1)]))

    def open_bus() -> can.BusABC:
        attempts.append(1)
        bus = buses.popleft()
        if isinstance(bus, BaseException):
            python_can.error("Could not access SocketCAN device %s (%s)", "can0", bus)
            raise bus
        enough.set()
        return bus

    inbox: queue.Queue[RawFrame | BusEvent] = queue.Queue()
    with caplog.at_level(logging.INFO), BusReader(open_bus, inbox, channel="can0"):
        assert drain(inbox, 3) == [("absent", False), ("up", False), 1]  # first open
        assert enough.wait(WAIT_S)
    assert len(attempts) == 5
    copies = [r for r in caplog.records if r.getMessage().startswith("Could not access")]
    assert len(copies) == 1  # not 4
    ours = [r for r in caplog.records if r.name == "daq.bus_reader"]
    assert [r.levelno for r in ours] == [logging.WARNING, logging.INFO]
    assert "absent" in ours[0].getMessage() and "no such CAN interface" in ours[0].getMessage()
    assert python_can.filters == []  # nothing left behind


def test_bus_errors_carry_a_hint() -> None:
    error = bus_error("can0", can.CanOperationError("Failed", errno.ENETDOWN))
    assert "ip link set can0 up" in str(error) and error.channel == "can0"
    error = bus_error("can9", OSError(errno.ENODEV, "No such device"))
    assert str(error).startswith("CAN bus 'can9': No such device (no such CAN interface")


def test_kernel_filters_pass_exactly_the_dbc_ids() -> None:
    assert kernel_filters([(0x100, False), (0x18FEF100, True)]) == [
        {"can_id": 0x100, "can_mask": 0x7FF, "extended": False},
        {"can_id": 0x18FEF100, "can_mask": 0x1FFFFFFF, "extended": True},
    ]


@pytest.mark.parametrize("filtered", [False, True])
def test_bus_factory_filters_only_when_asked(filtered: bool) -> None:
    channel = f"test-{uuid.uuid4().hex}"
    settings = BusSettings(interface="virtual", channel=channel, kernel_filters=filtered)
    with (
        bus_factory(settings, [(0x100, False)])() as bus,
        can.Bus(interface="virtual", channel=channel) as sender,
    ):
        sender.send(message(0x7AB))
        sender.send(message(0x100))
        received = [bus.recv(timeout=WAIT_S)]
        if not filtered:
            received.append(bus.recv(timeout=WAIT_S))
    ids = [m.arbitration_id for m in received if m is not None]
    assert ids == ([0x100] if filtered else [0x7AB, 0x100])
