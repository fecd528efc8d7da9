"""The Zenoh edge of a viewer: advanced subscribers whose callbacks only enqueue.

:class:`LiveFeed` declares a :func:`zenoh.ext.declare_advanced_subscriber` on
``<prefix>/ground``, ``/status`` and ``/metrics`` on the session passed in. With
history, it gets the latest value of each key from the service's publisher cache
when it joins, and again when the service (re)starts after it (late publisher
detection). Its miss listener counts the samples it missed (:attr:`LiveFeed.missed`:
lost on the way, or dropped by a congested link), from the service's sequence
numbers and heartbeats. Callbacks run on Zenoh's threads and only put
``(key, payload, received_s)`` into a bounded queue (full: dropped and counted).
The viewer's one consumer thread drains it into a :class:`~daq.live.state.LiveState`
with :meth:`LiveFeed.drain`.

The prefix may hold a wildcard (``portal/*``: every machine, the fleet views).
With ``liveliness=True`` the feed also follows the services' liveliness tokens
(``<prefix>/alive``, the ones present at start included): an item with
``alive`` True when a token appears, False when it goes (the service stopped,
or its session's lease expired). A liveliness change is never dropped: when the
queue is full it is kept aside, the latest one per token, and :meth:`LiveFeed.wait`
hands it out once the queue is empty (a fleet view behind a burst of data must still
see a machine go).
"""

import logging
import queue
import threading
import time
from collections.abc import Callable
from typing import Any, NamedTuple

import zenoh
import zenoh.ext

from daq.live.state import ALIVE, SUFFIXES, LiveState

logger = logging.getLogger(__name__)

#: The latest sample of each key when joining (and when the service starts later).
HISTORY = zenoh.ext.HistoryConfig(detect_late_publishers=True, max_samples=1)
#: Check sequence numbers against the publisher's heartbeats (a lost last sample too).
RECOVERY = zenoh.ext.RecoveryConfig(periodic_queries=None, heartbeat=True)


class Item(NamedTuple):
    key: str
    payload: bytes
    #: ``clock()`` (monotonic seconds) when the callback ran.
    received_s: float
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
        #: Liveliness changes that found the queue full: the latest one by token key.
        self._tokens_aside: dict[str, Item] = {}
        self._tokens_lock = threading.Lock()
        self._entities: list[Any] = []
        self._started = False
        self._closed = False
        #: Payloads lost because the queue was full (the consumer is too slow).
        self.dropped = 0
        #: Samples the service published that never arrived here (miss listener).
        self.missed = 0

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
            subscriber = zenoh.ext.declare_advanced_subscriber(
                self.session,
                f"{self.prefix}/{suffix}",
                self._on_sample,
                history=HISTORY,
                recovery=RECOVERY,
            )
            self._entities.append(subscriber.sample_miss_listener(self._on_miss))
            self._entities.append(subscriber)
        if self.liveliness:
            self._entities.append(
                self.session.liveliness().declare_subscriber(
                    f"{self.prefix}/{ALIVE}", self._on_token, history=True
                )
            )

    def close(self) -> None:
        """Undeclare the subscribers (the session stays open: its owner closes it). Idempotent."""
        if self._closed:
            return
        self._closed = True
        for entity in self._entities:
            try:
                entity.undeclare()
            except zenoh.ZError as exc:  # e.g. the session was closed first
                logger.debug("undeclaring %s: %s", entity, exc)
        self._entities.clear()

    def linked(self) -> bool:
        """Whether the session has a link to any peer or router: without one, "waiting
        for <prefix>/status" is no service to hear (an endpoint unreached, a service
        not running), not a service that has said nothing yet."""
        info = self.session.info
        try:
            return bool(info.routers_zid() or info.peers_zid())
        except zenoh.ZError as exc:  # the session closing: not known, not "no link"
            logger.debug("session info: %s", exc)
            return True

    def drain(self, state: LiveState) -> int:
        """Apply every queued payload to ``state`` (and :meth:`linked` to its
        ``linked``); returns how many were applied."""
        state.linked = self.linked()
        applied = 0
        while True:
            try:
                item = self._queue.get_nowait()
            except queue.Empty:
                return applied
            applied += apply_item(state, item)

    def wait(self, timeout_s: float) -> Item | None:
        """The next queued payload (a liveliness change kept aside once the queue is
        empty), or None after ``timeout_s``."""
        try:
            return self._queue.get_nowait()
        except queue.Empty:
            pass
        with self._tokens_lock:
            if self._tokens_aside:
                return self._tokens_aside.pop(next(iter(self._tokens_aside)))
        try:
            return self._queue.get(timeout=timeout_s)
        except queue.Empty:
            return None

    def _on_sample(self, sample: zenoh.Sample) -> None:
        self._enqueue(Item(str(sample.key_expr), sample.payload.to_bytes(), self._clock()))

    def _on_token(self, sample: zenoh.Sample) -> None:
        item = Item(str(sample.key_expr), b"", self._clock(), sample.kind == zenoh.SampleKind.PUT)
        with self._tokens_lock:
            # Once one change of a token waits aside, the later ones go after it there
            # (the latest wins), never ahead of it through the queue.
            if item.key not in self._tokens_aside:
                try:
                    self._queue.put_nowait(item)
                    return
                except queue.Full:
                    pass
            self._tokens_aside[item.key] = item

    def _enqueue(self, item: Item) -> None:
        try:
            self._queue.put_nowait(item)
        except queue.Full:
            self.dropped += 1

    def _on_miss(self, miss: zenoh.ext.Miss) -> None:
        self.missed += miss.nb


def apply_item(state: LiveState, item: Item) -> int:
    """Apply one item to ``state``: 1 when it was usable, else 0 (and counted there)."""
    return int(state.apply(item.key, item.payload, item.received_s))
