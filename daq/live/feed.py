"""The Zenoh edge of a viewer: subscribers whose callbacks only enqueue.

:class:`LiveFeed` subscribes to ``<prefix>/ground``, ``/status`` and
``/metrics`` on the session passed in, and asks the service's cache once for
their latest values (``get("<prefix>/*")``; late joiner). Callbacks run on
Zenoh's threads and only put ``(key, payload, received_s)`` into a bounded
queue (full: dropped and counted). The viewer's one consumer thread drains it
into a :class:`~daq.live.state.LiveState` with :meth:`LiveFeed.drain`.

The prefix may hold a wildcard (``portal/*``: every machine, the fleet views).
With ``liveliness=True`` the feed also follows the services' liveliness tokens
(``<prefix>/alive``, the ones present at start included): an item with
``alive`` True when a token appears, False when it goes (the service stopped,
or its session's lease expired).
"""

import logging
import queue
import time
from collections.abc import Callable
from typing import Any, NamedTuple

import zenoh

from daq.live.state import ALIVE, SUFFIXES, LiveState

logger = logging.getLogger(__name__)

#: How long the start-up query for the latest values may take.
QUERY_TIMEOUT_S = 2.0


class Item(NamedTuple):
    key: str
    payload: bytes
    #: ``clock()`` (monotonic seconds) when the callback ran.
    received_s: float
    #: From the start-up query: older than anything a subscriber delivers.
    queried: bool
    #: A liveliness change of the token ``key`` (no payload); None for data.
    alive: bool | None = None


class LiveFeed:
    """Subscribes under ``prefix``; the constructor declares nothing (:meth:`start` does)."""

    def __init__(
        self,
        session: zenoh.Session,
        prefix: str,
        *,
        queue_size: int = 2000,
        clock: Callable[[], float] = time.monotonic,
        liveliness: bool = False,
    ) -> None:
        self.session = session
        self.prefix = prefix
        self.liveliness = liveliness
        self._clock = clock
        self._queue: queue.Queue[Item] = queue.Queue(maxsize=queue_size)
        self._subscribers: list[Any] = []
        self._started = False
        self._closed = False
        #: Payloads lost because the queue was full (the consumer is too slow).
        self.dropped = 0

    def __enter__(self) -> "LiveFeed":
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def start(self) -> None:
        if self._started:
            return
        self._started = True
        for suffix in SUFFIXES:
            self._subscribers.append(
                self.session.declare_subscriber(f"{self.prefix}/{suffix}", self._on_sample)
            )
        if self.liveliness:
            self._subscribers.append(
                self.session.liveliness().declare_subscriber(
                    f"{self.prefix}/{ALIVE}", self._on_token, history=True
                )
            )
        self.session.get(f"{self.prefix}/*", self._on_reply, timeout=QUERY_TIMEOUT_S)

    def close(self) -> None:
        """Undeclare the subscribers (the session stays open: its owner closes it). Idempotent."""
        if self._closed:
            return
        self._closed = True
        for subscriber in self._subscribers:
            try:
                subscriber.undeclare()
            except zenoh.ZError as exc:  # e.g. the session was closed first
                logger.debug("undeclaring %s: %s", subscriber, exc)
        self._subscribers.clear()

    def drain(self, state: LiveState) -> int:
        """Apply every queued payload to ``state``; returns how many were applied."""
        applied = 0
        while True:
            try:
                item = self._queue.get_nowait()
            except queue.Empty:
                return applied
            applied += apply_item(state, item)

    def wait(self, timeout_s: float) -> Item | None:
        """The next queued payload, or None after ``timeout_s``."""
        try:
            return self._queue.get(timeout=timeout_s)
        except queue.Empty:
            return None

    def _on_sample(self, sample: zenoh.Sample) -> None:
        self._enqueue(Item(str(sample.key_expr), sample.payload.to_bytes(), self._clock(), False))

    def _on_token(self, sample: zenoh.Sample) -> None:
        alive = sample.kind == zenoh.SampleKind.PUT
        self._enqueue(Item(str(sample.key_expr), b"", self._clock(), False, alive))

    def _on_reply(self, reply: zenoh.Reply) -> None:
        sample = reply.ok
        if sample is not None:
            key = str(sample.key_expr)
            self._enqueue(Item(key, sample.payload.to_bytes(), self._clock(), True))

    def _enqueue(self, item: Item) -> None:
        try:
            self._queue.put_nowait(item)
        except queue.Full:
            self.dropped += 1


def apply_item(state: LiveState, item: Item) -> int:
    """Apply one item; a queried value never replaces one a subscriber delivered."""
    if item.queried and state.holds(item.key):
        return 0
    return int(state.apply(item.key, item.payload, item.received_s))
