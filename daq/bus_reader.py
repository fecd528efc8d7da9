"""The reader thread: receives CAN frames and only enqueues them; reopens a lost bus.

The bus is a frame source (:class:`FrameSource`) opened by a factory built in
``daq.runner`` (on SocketCAN the service's own socket, :mod:`daq.socketcan`;
for other interfaces and in tests a python-can bus in a
:class:`PythonCanSource`), so the reader can reopen it. Its thread calls
``source.recv(timeout)`` and puts each frame, as a :class:`~daq.frames.RawFrame`,
into a bounded queue with ``put_nowait``: a full queue drops the frame and
counts it (``dropped``); the reader never blocks on the consumer.

Without a thread (``threaded=False``, the service's event loop) the consumer's
thread calls :meth:`BusReader.poll` instead: one wake-up, the first frame within a
timeout and then every frame already waiting (``recv(0)`` until there is none,
i.e. until ``EAGAIN`` on a socket), with the bus events in their place.

Bus states (:mod:`daq.frames`), each change queued as a :class:`BusEvent` in
order with the frames:

- ``up``: frames can arrive.
- ``down``: the interface was set down (``ENETDOWN``). The socket stays open and
  bound, so the first frame after ``ip link set <if> up`` is received; the state
  returns to ``up`` with that frame, or when the link probe sees the interface up.
- ``absent``: the bus cannot be opened, or the interface went away (``ENODEV``);
  it is reopened with a backoff of 0.1 s doubling to :data:`BACKOFF_MAX_S`.

Every return to ``up`` after ``down`` or ``absent`` carries
``reset_counters=True``: the consumer forgets the rolling counters, so the
first frames after the gap are not flagged.

Lost frames are queued as events too, in order, so that a recording shows where
they went missing: one :class:`BusEvent` (state unchanged) with the frames the
kernel dropped (``kernel_dropped``, its receive buffer was full: the source's
``SO_RXQ_OVFL`` counter went up) and those the full queue dropped
(``rx_dropped``) since the previous event. An event that finds the queue full
waits, in order, until there is room (tried again at every frame and every
receive timeout); frames meanwhile are dropped and counted, and no waiting
event is ever replaced or lost.
"""

import errno
import logging
import queue
import threading
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import Protocol

import can

from daq._worker import Worker
from daq.can_batch import MAX_FRAMES
from daq.errors import BusError
from daq.frames import BUS_ABSENT, BUS_CLOSED, BUS_DOWN, BUS_UP, BusEvent, RawFrame
from daq.frames import from_can_message as _raw
from dbc.bus_hints import bus_hint, error_code

logger = logging.getLogger(__name__)

#: Longest wait between two attempts to reopen the bus.
BACKOFF_MAX_S = 1.0
BACKOFF_MIN_S = 0.1


class FrameSource(Protocol):
    """Where the reader gets frames: an open bus."""

    #: Frames the kernel dropped on this source since it was opened (0 if unknown).
    kernel_dropped: int
    #: The kernel receive buffer it got, bytes; None if not a kernel socket.
    rcvbuf_bytes: int | None

    def recv(self, timeout_s: float) -> RawFrame | None:
        """The next frame, None after ``timeout_s``; raises ``OSError`` or python-can's
        ``CanOperationError`` (with an errno) when the bus fails."""
        ...

    def shutdown(self) -> None: ...


class PythonCanSource:
    """A python-can bus as a :class:`FrameSource` (no kernel drop counter)."""

    kernel_dropped = 0
    rcvbuf_bytes: int | None = None

    def __init__(self, bus: can.BusABC) -> None:
        self.bus = bus

    def recv(self, timeout_s: float) -> RawFrame | None:
        message = self.bus.recv(timeout=timeout_s)
        return None if message is None else _raw(message)

    def shutdown(self) -> None:
        self.bus.shutdown()


BusFactory = Callable[[], FrameSource]
#: True/False: the interface is up/down; None: unknown.
LinkProbe = Callable[[], bool | None]
Inbox = queue.Queue[RawFrame | BusEvent]


def bus_error(channel: str, exc: BaseException) -> BusError:
    """Translate python-can's or the OS's exception into a :class:`BusError` with a hint."""
    reason = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
    return BusError(channel, reason, bus_hint(exc, channel))


def sysfs_link_probe(channel: str) -> LinkProbe:
    """A probe reading IFF_UP of a Linux network interface from /sys/class/net."""
    flags = Path("/sys/class/net") / channel / "flags"

    def link_up() -> bool | None:
        try:
            return bool(int(flags.read_text(), 16) & 0x1)
        except (OSError, ValueError):
            return None

    return link_up


class _Collected:
    """What :meth:`BusReader.poll` returns, taking the place of the queue (never full)."""

    def __init__(self) -> None:
        self.items: list[RawFrame | BusEvent] = []

    def put_nowait(self, item: RawFrame | BusEvent) -> None:
        self.items.append(item)

    def take(self) -> list[RawFrame | BusEvent]:
        items, self.items = self.items, []
        return items


class BusReader(Worker):
    """Receives from the bus in a thread of its own and enqueues into ``inbox``; or,
    with ``threaded=False`` (and no inbox), when :meth:`poll` ed.

    ``close`` stops the thread (if any) and shuts the bus down.
    """

    thread_name = "can-reader"

    def __init__(
        self,
        open_bus: BusFactory,
        inbox: Inbox | None,
        *,
        channel: str,
        threaded: bool = True,
        link_up: LinkProbe | None = None,
        recv_timeout_s: float = 0.1,
        now: Callable[[], float] = time.time,
    ) -> None:
        super().__init__()
        self.threaded = threaded
        self._open_bus = open_bus
        self._collected = _Collected()
        self._inbox: Inbox | _Collected = self._collected if inbox is None else inbox
        self.channel = channel
        self._link_up = link_up
        self._recv_timeout_s = recv_timeout_s
        self._now = now
        self._bus: FrameSource | None = None
        #: Events waiting for room in the queue, oldest first.
        self._pending: deque[BusEvent] = deque()
        #: Losses not yet queued as an event: by the kernel, by the full queue.
        self._unreported_kernel = 0
        self._unreported_rx = 0
        #: The open source's kernel drop counter as last seen.
        self._source_dropped = 0
        #: Reopening the bus: the next attempt not before this (monotonic), and the wait.
        self._retry_at = 0.0
        self._backoff_s = BACKOFF_MIN_S
        #: The bus was opened at least once (the service reports READY then).
        self.opened = threading.Event()
        self.state = BUS_CLOSED
        self.reason = "not started"
        #: Frames received from the bus, and those dropped because the queue was full.
        self.received = 0
        self.dropped = 0
        #: Frames the kernel dropped (receive buffer full), over every socket opened.
        self.kernel_dropped = 0
        #: The kernel receive buffer of the open socket, bytes (None: not a kernel socket).
        self.rcvbuf_bytes: int | None = None
        #: Times the bus was reopened after it went away.
        self.reopens = 0
        #: time.monotonic() of the thread's last loop turn (for the watchdog).
        self.heartbeat = time.monotonic()

    def _after_stop(self) -> None:
        self._shutdown_bus()
        self.state, self.reason = BUS_CLOSED, "closed"

    # --- reader thread -----------------------------------------------------

    def _run(self) -> None:
        while not self._stop.is_set():
            self._turn(self._recv_timeout_s)

    def poll(self, timeout_s: float) -> list[RawFrame | BusEvent]:
        """One wake-up without a thread: the frames received within ``timeout_s`` and every
        one waiting after the first (at most :data:`MAX_FRAMES`), bus events in their
        place. Opens and reopens the bus (waiting at most ``timeout_s`` for a retry)."""
        if self._turn(timeout_s) and self._bus is not None:
            # The first frame went the whole way (state, events); the rest are taken as
            # they are until none waits (EAGAIN): the bus is up, nothing to report.
            bus, out = self._bus, self._collected.items
            received = 1
            try:
                while received < MAX_FRAMES:
                    frame = bus.recv(0.0)
                    if frame is None:
                        break
                    out.append(frame)
                    received += 1
            except (can.CanOperationError, OSError) as exc:
                self._lost(exc)
            self.received += received - 1
            self._count_kernel_drops(bus.kernel_dropped)
        return self._collected.take()

    def _turn(self, timeout_s: float) -> bool:
        """One receive (or open attempt); True when a frame came."""
        self.heartbeat = now = time.monotonic()
        if self._bus is None:
            if now < self._retry_at:
                self._stop.wait(min(timeout_s, self._retry_at - now))
            elif self._try_open():
                self._backoff_s = BACKOFF_MIN_S
            else:
                self._retry_at = now + self._backoff_s
                self._backoff_s = min(2 * self._backoff_s, BACKOFF_MAX_S)
            return False
        try:
            frame = self._bus.recv(timeout_s)
        except (can.CanOperationError, OSError) as exc:
            self._lost(exc)
            return False
        if frame is None:
            if self.state == BUS_DOWN and self._link_up is not None and self._link_up():
                self._set_state(BUS_UP, "interface up again", reset=True)
            self._deliver_pending()
            return False
        self.received += 1
        self._count_kernel_drops(self._bus.kernel_dropped)
        if self.state != BUS_UP:
            self._set_state(BUS_UP, "frames again", reset=True)
        self._offer(frame)
        return True

    def _try_open(self) -> bool:
        try:
            self._bus = self._open_bus()
        except (can.CanError, OSError) as exc:
            error = bus_error(self.channel, exc)
            self._set_state(BUS_ABSENT, str(error), log=logging.WARNING)
            return False
        self._source_dropped = 0
        self.rcvbuf_bytes = self._bus.rcvbuf_bytes
        first = not self.opened.is_set()
        self.opened.set()
        if not first:
            self.reopens += 1
        self._set_state(BUS_UP, "opened" if first else "reopened", reset=not first)
        return True

    def _lost(self, exc: BaseException) -> None:
        error = bus_error(self.channel, exc)
        if error_code(exc) == errno.ENETDOWN:
            # The socket stays bound: frames after the link returns are received.
            self._set_state(BUS_DOWN, str(error), log=logging.WARNING)
            return
        self._set_state(BUS_ABSENT, str(error), log=logging.WARNING)
        self._shutdown_bus()

    def _count_kernel_drops(self, source_dropped: int) -> None:
        increase = source_dropped - self._source_dropped
        if increase > 0:
            self._source_dropped = source_dropped
            self.kernel_dropped += increase
            self._unreported_kernel += increase

    def _set_state(
        self, state: str, reason: str, *, reset: bool = False, log: int = logging.INFO
    ) -> None:
        if state == self.state and reason == self.reason:
            return
        changed = state != self.state
        if changed:
            self._note_loss()  # frames lost so far went missing before this change
        self.state, self.reason = state, reason
        if changed:
            logger.log(log, "CAN bus %s: %s (%s)", self.channel, state, reason)
            self._pending.append(BusEvent(self._now(), state, reason, reset))
            self._deliver_pending()

    def _note_loss(self) -> None:
        """Queue the losses not yet reported as one event, behind the pending ones."""
        kernel, rx = self._unreported_kernel, self._unreported_rx
        if kernel or rx:
            self._unreported_kernel = self._unreported_rx = 0
            reason = f"{kernel + rx} frames lost: {kernel} by the kernel, {rx} by the queue"
            self._pending.append(
                BusEvent(self._now(), self.state, reason, kernel_dropped=kernel, rx_dropped=rx)
            )

    def _deliver_pending(self) -> bool:
        """Queue waiting events, oldest first, then the unreported losses; True when none
        is left waiting (a loss is noted only once what waits before it is queued, so
        a full queue keeps at most one loss event waiting)."""
        if not self._put_pending():
            return False
        self._note_loss()
        return self._put_pending()

    def _put_pending(self) -> bool:
        pending = self._pending
        try:
            while pending:
                self._inbox.put_nowait(pending[0])
                pending.popleft()
        except queue.Full:
            return False
        return True

    def _offer(self, frame: RawFrame) -> None:
        """Enqueue without blocking, behind the waiting events; a full queue drops it."""
        try:
            waiting = self._pending or self._unreported_kernel or self._unreported_rx
            if waiting and not self._deliver_pending():
                raise queue.Full
            self._inbox.put_nowait(frame)
        except queue.Full:
            self.dropped += 1
            self._unreported_rx += 1

    def _shutdown_bus(self) -> None:
        bus, self._bus = self._bus, None
        if bus is not None:
            try:
                bus.shutdown()
            except (can.CanError, OSError) as exc:
                logger.debug("shutting the bus down: %s", exc)
