"""The reader's bus states: down keeps the socket, away reopens it, both reset the counters."""

from __future__ import annotations

import errno
import logging
import queue
import threading
import time
import uuid
from collections import deque
from collections.abc import Callable, Iterable
from typing import Any

import can
import pytest

from daq.bus_reader import BusReader, FrameSource, PythonCanSource, bus_error
from daq.frames import BusEvent, RawFrame
from daq.runner import bus_factory, kernel_filters
from daq.service_config import BusSettings
from dbc.decoding import ReceiveFilter

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
    return names(inbox.get(timeout=WAIT_S) for _ in range(count))


def names(items: Iterable[RawFrame | BusEvent]) -> list[Any]:
    """A frame by its ID, a loss by its counts, a state change by (state, reset)."""
    named: list[Any] = []
    for item in items:
        if not isinstance(item, BusEvent):
            named.append(item.arbitration_id)
        elif item.kernel_dropped or item.rx_dropped:
            named.append(("lost", item.kernel_dropped, item.rx_dropped))
        else:
            named.append((item.state, item.reset_counters))
    return named


def opener(*buses: ScriptedBus | OSError) -> Callable[[], FrameSource]:
    """A bus factory giving ``buses`` in turn (an exception is raised, as at open)."""
    waiting = deque(buses)

    def open_bus() -> FrameSource:
        bus = waiting.popleft()
        if isinstance(bus, BaseException):
            raise bus
        return PythonCanSource(bus)

    return open_bus


def test_down_keeps_the_socket_away_reopens_and_both_reset_counters() -> None:
    enetdown = can.CanOperationError("Network is down", errno.ENETDOWN)
    enodev = can.CanOperationError("No such device", errno.ENODEV)
    first = ScriptedBus([message(1), enetdown, None, message(2), enodev])
    second = ScriptedBus([message(3)])
    open_bus = opener(first, OSError(errno.ENODEV, "No such device"), second)

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


def test_polled_without_a_thread_the_same_states_in_place_and_frames_in_batches() -> None:
    """The event loop's way (``threaded=False``): each poll is one wake-up, every frame
    waiting after the first comes with it, the bus events keep their place."""
    enetdown = can.CanOperationError("Network is down", errno.ENETDOWN)
    enodev = can.CanOperationError("No such device", errno.ENODEV)
    first = ScriptedBus([message(1), message(2), message(3), enetdown, None, message(4), enodev])
    second = ScriptedBus([message(5)])
    open_bus = opener(first, OSError(errno.ENODEV, "No such device"), second)

    with BusReader(open_bus, None, channel="can0", threaded=False) as reader:
        assert not reader.alive  # no thread of its own
        polls = [names(reader.poll(0.01)) for _ in range(40)]
    assert [batch for batch in polls if batch] == [
        [("up", False)],  # opened
        [1, 2, 3, ("down", False)],  # one wake-up: the frames waiting, then ENETDOWN
        [("up", True), 4, ("absent", False)],  # frames again; then ENODEV
        [("up", True)],  # reopened after the backoff (the first retry failed)
        [5],
    ]
    assert first.closed and second.closed
    assert reader.reopens == 1 and reader.received == 5


def test_down_then_link_probe_up_without_frames() -> None:
    enetdown = can.CanOperationError("Network is down", errno.ENETDOWN)
    link = {"up": False}
    inbox: queue.Queue[RawFrame | BusEvent] = queue.Queue()
    reader = BusReader(
        lambda: PythonCanSource(ScriptedBus([enetdown])),
        inbox,
        channel="can0",
        link_up=lambda: link["up"],
    )
    with reader:
        assert drain(inbox, 2) == [("up", False), ("down", False)]
        assert "ip link set can0 up" in reader.reason
        link["up"] = True
        assert drain(inbox, 1) == [("up", True)]


def test_an_event_finding_the_queue_full_waits_and_is_never_replaced() -> None:
    """Down, then up again, while the consumer is stuck: both events reach it, in order,
    on receive timeouts alone (no frame comes after them)."""
    enetdown = can.CanOperationError("Network is down", errno.ENETDOWN)
    link = {"up": False}
    inbox: queue.Queue[RawFrame | BusEvent] = queue.Queue(maxsize=2)
    script = [message(1), message(2), enetdown]
    reader = BusReader(
        lambda: PythonCanSource(ScriptedBus(script)),
        inbox,
        channel="can0",
        link_up=lambda: link["up"],
    )
    with reader:
        deadline = time.monotonic() + WAIT_S
        while reader.state != "down" and time.monotonic() < deadline:
            time.sleep(0.01)
        link["up"] = True
        while reader.state != "up" and time.monotonic() < deadline:
            time.sleep(0.01)
        assert drain(inbox, 2) == [("up", False), 1]  # the queue was full after these
        items = drain(inbox, 3)
    assert reader.dropped == 1
    assert items == [("lost", 0, 1), ("down", False), ("up", True)]


class DroppingSource:
    """A kernel socket as the reader sees it: frames with a rising drop counter, then
    (with ``then``) an error."""

    rcvbuf_bytes = 4096

    def __init__(self, script: list[tuple[int, int]], then: OSError | None = None) -> None:
        self.script = deque(script)
        self.then = then
        self.kernel_dropped = 0

    def recv(self, timeout_s: float) -> RawFrame | None:
        if not self.script:
            if self.then is not None:
                raise self.then
            time.sleep(0.01)
            return None
        frame_id, self.kernel_dropped = self.script.popleft()
        return RawFrame(0.0, frame_id, False, b"")

    def shutdown(self) -> None:
        pass


def test_kernel_drops_are_counted_and_queued_where_they_happened() -> None:
    enodev = OSError(errno.ENODEV, "No such device")
    sources = deque(
        [
            DroppingSource([(1, 0), (2, 3), (3, 3), (4, 5)], then=enodev),
            DroppingSource([(5, 2)]),  # a new socket counts from 0 again
        ]
    )
    inbox: queue.Queue[RawFrame | BusEvent] = queue.Queue()
    with BusReader(sources.popleft, inbox, channel="can0") as reader:
        items = drain(inbox, 11)
    assert items == [
        ("up", False),
        1,
        ("lost", 3, 0),
        2,
        3,
        ("lost", 2, 0),
        4,
        ("absent", False),
        ("up", True),
        ("lost", 2, 0),
        5,
    ]
    assert reader.kernel_dropped == 7 and reader.rcvbuf_bytes == 4096


def test_a_missing_socketcan_interface_is_logged_once_per_state_change(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """The retries of a bus that stays absent log nothing more: one WARNING at the change
    (python-can's socketcan backend logged its own ERROR on every retry; the service's own
    socket logs none)."""
    settings = BusSettings(interface="socketcan", channel="nosuchcan9")
    open_socketcan = bus_factory(settings, [])
    attempts: list[int] = []
    retried = threading.Event()

    def open_bus() -> FrameSource:
        attempts.append(1)
        if len(attempts) >= 4:
            retried.set()
        return open_socketcan()

    inbox: queue.Queue[RawFrame | BusEvent] = queue.Queue()
    with caplog.at_level(logging.DEBUG), BusReader(open_bus, inbox, channel="nosuchcan9"):
        assert drain(inbox, 1) == [("absent", False)]
        assert retried.wait(WAIT_S)
    lines = [r for r in caplog.records if r.levelno >= logging.WARNING]
    assert len(lines) == 1 and lines[0].name == "daq.bus_reader", lines
    assert "nosuchcan9: absent" in lines[0].getMessage()
    assert not [r for r in caplog.records if r.name.startswith("can.")]


def test_bus_errors_carry_a_hint() -> None:
    error = bus_error("can0", can.CanOperationError("Failed", errno.ENETDOWN))
    assert "ip link set can0 up" in str(error) and error.channel == "can0"
    error = bus_error("can9", OSError(errno.ENODEV, "No such device"))
    assert str(error).startswith("CAN bus 'can9': No such device (no such CAN interface")
    # A kernel without CAN: the service retried for ever saying only this.
    error = bus_error("can0", OSError(errno.EAFNOSUPPORT, "Address family not supported"))
    assert "no SocketCAN: load it (sudo modprobe can-raw;" in str(error)


def test_kernel_filters_pass_exactly_the_dbc_ids() -> None:
    filters = [ReceiveFilter(0x100, 0x7FF, False), ReceiveFilter(0xFF2000, 0x3FFFF00, True)]
    assert kernel_filters(filters) == [
        {"can_id": 0x100, "can_mask": 0x7FF, "extended": False},
        {"can_id": 0xFF2000, "can_mask": 0x3FFFF00, "extended": True},
    ]


@pytest.mark.parametrize("filtered", [False, True])
def test_bus_factory_filters_only_when_asked(filtered: bool) -> None:
    channel = f"test-{uuid.uuid4().hex}"
    settings = BusSettings(interface="virtual", channel=channel, kernel_filters=filtered)
    source = bus_factory(settings, [ReceiveFilter(0x100, 0x7FF, False)])()
    try:
        with can.Bus(interface="virtual", channel=channel) as sender:
            sender.send(message(0x7AB))
            sender.send(message(0x100))
            received = [source.recv(WAIT_S)]
            if not filtered:
                received.append(source.recv(WAIT_S))
    finally:
        source.shutdown()
    ids = [frame.arbitration_id for frame in received if frame is not None]
    assert ids == ([0x100] if filtered else [0x7AB, 0x100])
