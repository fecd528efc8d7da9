"""The reader thread: receives CAN frames and only enqueues them; reopens a lost bus.

The bus is opened by a factory built in ``daq.__main__`` (python-can, from the
``[bus]`` table), so the reader can reopen it. Its thread calls
``bus.recv(timeout)`` and puts each frame, as a :class:`~daq.frames.RawFrame`,
into a bounded queue with ``put_nowait``: a full queue drops the frame and
counts it (``dropped``); the reader never blocks on the consumer.

Bus states (:mod:`daq.frames`), each change queued as a :class:`BusEvent` in
order with the frames:

- ``up``: frames can arrive.
- ``down``: the interface was set down (python-can raises ``CanOperationError``
  with ``ENETDOWN``). The socket stays open and bound, so the first frame after
  ``ip link set <if> up`` is received; the state returns to ``up`` with that
  frame, or when the link probe sees the interface up.
- ``absent``: the bus cannot be opened, or the interface went away (``ENODEV``);
  it is reopened with a backoff of 0.1 s doubling to :data:`BACKOFF_MAX_S`.

Every return to ``up`` after ``down`` or ``absent`` carries
``reset_counters=True``: the consumer forgets the rolling counters, so the
first frames after the gap are not flagged.

Each state change is logged once, with a hint. python-can's socketcan backend logs
its own ERROR ("Could not access SocketCAN device ...") on every failed open; while
the bus is already ``absent``, the retries' copies of it are dropped (:class:`_Quiet`),
so a missing interface gives one line per state change, not one a second.
"""

import errno
import logging
import queue
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import can

from daq._worker import Worker
from daq.errors import BusError
from daq.frames import BUS_ABSENT, BUS_CLOSED, BUS_DOWN, BUS_UP, BusEvent, RawFrame
from daq.frames import from_can_message as _raw

logger = logging.getLogger(__name__)

#: Longest wait between two attempts to reopen the bus.
BACKOFF_MAX_S = 1.0
BACKOFF_MIN_S = 0.1

#: python-can's socketcan backend logs each failed open here, at ERROR.
PYTHON_CAN_SOCKETCAN_LOGGER = "can.interfaces.socketcan.socketcan"

BusFactory = Callable[[], can.BusABC]
#: True/False: the interface is up/down; None: unknown.
LinkProbe = Callable[[], bool | None]
Inbox = queue.Queue[RawFrame | BusEvent]

_HINTS = {
    errno.ENETDOWN: "the CAN interface is down; bring it up: ip link set {channel} up",
    errno.ENODEV: "no such CAN interface; check [bus] channel and `ip link show {channel}`",
    errno.ENXIO: "no such CAN interface; check [bus] channel and `ip link show {channel}`",
    errno.EPERM: "not permitted; run the service as a user allowed to open CAN sockets",
    errno.EACCES: "not permitted; run the service as a user allowed to open CAN sockets",
}


def bus_error(channel: str, exc: BaseException) -> BusError:
    """Translate python-can's or the OS's exception into a :class:`BusError` with a hint."""
    code = getattr(exc, "error_code", None) or getattr(exc, "errno", None)
    hint = _HINTS.get(code, "") if isinstance(code, int) else ""
    reason = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
    return BusError(channel, reason, hint.format(channel=channel))


def sysfs_link_probe(channel: str) -> LinkProbe:
    """A probe reading IFF_UP of a Linux network interface from /sys/class/net."""
    flags = Path("/sys/class/net") / channel / "flags"

    def link_up() -> bool | None:
        try:
            return bool(int(flags.read_text(), 16) & 0x1)
        except (OSError, ValueError):
            return None

    return link_up


class _Quiet(logging.Filter):
    """Drops every record of the reader thread (the one that opens the bus)."""

    def __init__(self) -> None:
        super().__init__()
        self.thread = threading.get_ident()

    def filter(self, record: logging.LogRecord) -> bool:
        return record.thread != self.thread


@contextmanager
def _python_can_quiet(quiet: bool) -> Iterator[None]:
    """While ``quiet``, python-can's socketcan log lines of this thread are dropped."""
    if not quiet:
        yield
        return
    target = logging.getLogger(PYTHON_CAN_SOCKETCAN_LOGGER)
    quiet_filter = _Quiet()
    target.addFilter(quiet_filter)
    try:
        yield
    finally:
        target.removeFilter(quiet_filter)


class BusReader(Worker):
    """Receives from the bus in a thread of its own and enqueues into ``inbox``.

    ``close`` stops the thread and shuts the bus down.
    """

    thread_name = "can-reader"

    def __init__(
        self,
        open_bus: BusFactory,
        inbox: Inbox,
        *,
        channel: str,
        link_up: LinkProbe | None = None,
        recv_timeout_s: float = 0.1,
        now: Callable[[], float] = time.time,
    ) -> None:
        super().__init__()
        self._open_bus = open_bus
        self._inbox = inbox
        self.channel = channel
        self._link_up = link_up
        self._recv_timeout_s = recv_timeout_s
        self._now = now
        self._bus: can.BusABC | None = None
        self._pending: BusEvent | None = None
        #: The bus was opened at least once (the service reports READY then).
        self.opened = threading.Event()
        self.state = BUS_CLOSED
        self.reason = "not started"
        #: Frames received from the bus, and those dropped because the queue was full.
        self.received = 0
        self.dropped = 0
        #: Times the bus was reopened after it went away.
        self.reopens = 0
        #: time.monotonic() of the thread's last loop turn (for the watchdog).
        self.heartbeat = time.monotonic()

    def _after_stop(self) -> None:
        self._shutdown_bus()
        self.state, self.reason = BUS_CLOSED, "closed"

    # --- reader thread -----------------------------------------------------

    def _run(self) -> None:
        backoff_s = BACKOFF_MIN_S
        while not self._stop.is_set():
            self.heartbeat = time.monotonic()
            if self._bus is None:
                if self._try_open():
                    backoff_s = BACKOFF_MIN_S
                else:
                    self._stop.wait(backoff_s)
                    backoff_s = min(2 * backoff_s, BACKOFF_MAX_S)
                continue
            try:
                message = self._bus.recv(timeout=self._recv_timeout_s)
            except can.CanOperationError as exc:
                self._lost(exc)
                continue
            if message is None:
                if self.state == BUS_DOWN and self._link_up is not None and self._link_up():
                    self._set_state(BUS_UP, "interface up again", reset=True)
                continue
            self.received += 1
            if self.state != BUS_UP:
                self._set_state(BUS_UP, "frames again", reset=True)
            self._offer(_raw(message))

    def _try_open(self) -> bool:
        try:
            # Already absent: our warning said so; python-can's copy would repeat it.
            with _python_can_quiet(self.state == BUS_ABSENT):
                self._bus = self._open_bus()
        except (can.CanError, OSError) as exc:
            error = bus_error(self.channel, exc)
            self._set_state(BUS_ABSENT, str(error), log=logging.WARNING)
            return False
        first = not self.opened.is_set()
        self.opened.set()
        if not first:
            self.reopens += 1
        self._set_state(BUS_UP, "opened" if first else "reopened", reset=not first)
        return True

    def _lost(self, exc: can.CanOperationError) -> None:
        error = bus_error(self.channel, exc)
        if exc.error_code == errno.ENETDOWN:
            # The socket stays bound: frames after the link returns are received.
            self._set_state(BUS_DOWN, str(error), log=logging.WARNING)
            return
        self._set_state(BUS_ABSENT, str(error), log=logging.WARNING)
        self._shutdown_bus()

    def _set_state(
        self, state: str, reason: str, *, reset: bool = False, log: int = logging.INFO
    ) -> None:
        if state == self.state and reason == self.reason:
            return
        changed = state != self.state
        self.state, self.reason = state, reason
        if changed:
            logger.log(log, "CAN bus %s: %s (%s)", self.channel, state, reason)
            # An event still waiting for room keeps its reset request.
            reset = reset or (self._pending is not None and self._pending.reset_counters)
            self._pending = BusEvent(self._now(), state, reason, reset)
            self._offer(None)

    def _offer(self, frame: RawFrame | None) -> None:
        """Enqueue without blocking; a pending bus event goes first, and is never lost."""
        try:
            if self._pending is not None:
                self._inbox.put_nowait(self._pending)
                self._pending = None
            if frame is not None:
                self._inbox.put_nowait(frame)
        except queue.Full:
            if frame is not None:
                self.dropped += 1

    def _shutdown_bus(self) -> None:
        bus, self._bus = self._bus, None
        if bus is not None:
            try:
                bus.shutdown()
            except (can.CanError, OSError) as exc:
                logger.debug("shutting the bus down: %s", exc)
