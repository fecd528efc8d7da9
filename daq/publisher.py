"""Publishing on Zenoh from a thread of its own, through zenoh.ext advanced publishers.

The session is passed in (opened in ``daq.__main__``). :meth:`ZenohPublisher.submit`
and :meth:`~ZenohPublisher.submit_batch` never block: they queue (key, payload) pairs,
a batch as one item, into a queue bounded in messages, or drop and count.
The publisher thread serialises to JSON (NaN as ``null``; a payload may come
encoded already) and puts with encoding ``application/json``; any exception while
publishing one message is counted (:attr:`ZenohPublisher.errors`) and the message
skipped. The service's event loop hands its messages over the same way, so a slow link
never stalls acquisition and nothing is lost uncounted.

Every key gets a :func:`zenoh.ext.declare_advanced_publisher` that keeps its latest
sample (:data:`CACHE`), numbers its samples and sends a heartbeat when it published
something new (:data:`MISS_DETECTION`), and declares itself (publisher detection).
An advanced subscriber with history (the live views, :mod:`daq.live.feed`) therefore
gets the latest value of every key when it joins, also when the service starts after
it, and its miss listener tells it how many samples it missed. (A plain ``get``
does not reach that cache: it answers only advanced subscribers' queries.)

Congestion control, in a thread of its own: ``BLOCK``. Zenoh never drops a sample
silently for a slow link; a put to a congested link waits, the bounded queue in front
takes up the slack and beyond it messages are dropped and counted (``dropped.publish``
on the status topic). Zenoh closes a link that stays blocked longer than
``wait_before_close`` (:data:`daq.zenoh_session.BLOCK_WAIT_BEFORE_CLOSE_US`, shorter
than the watchdog's heartbeat limit). Putting in the acquisition thread itself was
measured and left: with ``BLOCK`` a slow subscriber behind a router held it for
seconds, and with ``DROP`` Zenoh drops without a count. A liveliness token
``<prefix>/alive`` lives as long as the publisher, and so do the queryables that answer a
plain ``get`` with what does not change while the service runs (``answers``, e.g.
``<prefix>/units``).
"""

import logging
import queue
import threading
import time
from collections.abc import Callable, Mapping, Sequence

import zenoh
import zenoh.ext

from daq._worker import Worker
from daq.payloads import JsonObject, json_bytes

logger = logging.getLogger(__name__)

Message = tuple[str, JsonObject | bytes]

#: On close, queued messages are still published for at most this long.
DRAIN_S = 0.3
JSON = zenoh.Encoding.APPLICATION_JSON
#: Late joiners get the latest sample of every key.
CACHE = zenoh.ext.CacheConfig(max_samples=1)
#: Sequence numbers on every sample, and a heartbeat after new samples (at most every
#: second) so that a subscriber also notices when the last sample of a burst is lost.
MISS_DETECTION = zenoh.ext.MissDetectionConfig(heartbeat=None, sporadic_heartbeat=1.0)


class MessageQueue:
    """A queue of batches of messages, sized and bounded in messages: a batch is taken
    while fewer than ``maxsize`` messages wait (one hand-off per batch, not per message).

    One thread takes (``get``), any may put. Built on :class:`queue.SimpleQueue`, whose
    put and get are C (``queue.Queue`` runs a Python condition variable on each side:
    at one frame per wake-up, a saturated bus's 9,000 a second, that was most of the
    hand-off's cost). The size is what was put less what was taken, each counted by
    its own side (puts under a lock, as several threads put).
    """

    def __init__(self, maxsize: int) -> None:
        self.maxsize = maxsize
        self._batches: queue.SimpleQueue[Sequence[Message]] = queue.SimpleQueue()
        self._put_lock = threading.Lock()
        self._put_messages = 0
        self._taken_messages = 0

    def qsize(self) -> int:
        """Messages waiting."""
        return self._put_messages - self._taken_messages

    def full(self) -> bool:
        return self.qsize() >= self.maxsize

    def put_nowait(self, batch: Sequence[Message]) -> None:
        """Queue ``batch``; raises :class:`queue.Full` when ``maxsize`` messages wait."""
        with self._put_lock:
            if self.full():
                raise queue.Full
            self._put_messages += len(batch)
        self._batches.put(batch)

    def get(self, timeout: float | None = None) -> Sequence[Message]:
        """The oldest batch; raises :class:`queue.Empty` after ``timeout`` (0: at once)."""
        batch = self._batches.get(timeout=timeout)
        self._taken_messages += len(batch)
        return batch


class ZenohPublisher(Worker):
    """Publishes JSON payloads under ``prefix`` through advanced publishers.

    The constructor declares nothing; :meth:`start` declares the liveliness token and
    starts the thread, which declares a publisher per key on first use. :meth:`close`
    undeclares them (the session stays open: its owner closes it).
    """

    thread_name = "zenoh-publisher"

    def __init__(
        self,
        session: zenoh.Session,
        prefix: str,
        *,
        queue_size: int = 10_000,
        answers: Mapping[str, JsonObject] | None = None,
    ) -> None:
        super().__init__()
        self.session = session
        self.prefix = prefix
        self._queue = MessageQueue(maxsize=queue_size)
        self._publishers: dict[str, zenoh.ext.AdvancedPublisher] = {}
        self._token: zenoh.LivelinessToken | None = None
        #: What a ``get`` of ``<prefix>/<suffix>`` is answered, by suffix (encoded once).
        self._answers = {suffix: json_bytes(payload) for suffix, payload in (answers or {}).items()}
        self._queryables: list[zenoh.Queryable[None]] = []
        self._closed = False
        #: Messages published, dropped (queue full) and failed (an error while publishing).
        self.published = 0
        self.dropped = 0
        self.errors = 0
        #: time.monotonic() of the thread's last loop turn (for the watchdog).
        self.heartbeat = 0.0

    @property
    def depth(self) -> int:
        return self._queue.qsize()

    def key(self, suffix: str) -> str:
        return f"{self.prefix}/{suffix}"

    def _before_start(self) -> None:
        self._token = self.session.liveliness().declare_token(self.key("alive"))
        for suffix, data in self._answers.items():
            key = self.key(suffix)
            self._queryables.append(self.session.declare_queryable(key, _answer(key, data)))

    def submit(self, suffix: str, payload: JsonObject | bytes) -> None:
        """Queue ``payload`` (or its JSON, already encoded) for ``<prefix>/<suffix>``; never
        blocks (full: dropped, counted)."""
        self.submit_batch(((suffix, payload),))

    def submit_batch(self, messages: Sequence[Message]) -> None:
        """Queue (suffix, payload) pairs as one item, published in their order; never
        blocks (full: all dropped, counted)."""
        if not messages:
            return
        try:
            self._queue.put_nowait(messages)
        except queue.Full:
            self.dropped += len(messages)

    def _after_stop(self) -> None:
        """Undeclare everything (once); the thread published what was queued (:data:`DRAIN_S`)."""
        if self._closed:
            return
        self._closed = True
        for entity in (*self._publishers.values(), *self._queryables, self._token):
            if entity is None:
                continue
            try:
                entity.undeclare()  # type: ignore[no-untyped-call]
            except zenoh.ZError as exc:  # e.g. the session was closed first
                logger.debug("undeclaring %s: %s", entity, exc)
        self._publishers.clear()
        self._queryables.clear()

    def _run(self) -> None:
        deadline: float | None = None
        while True:
            self.heartbeat = time.monotonic()
            if self._stop.is_set():
                deadline = deadline or time.monotonic() + DRAIN_S
                if time.monotonic() > deadline:
                    break
            try:
                messages = self._queue.get(timeout=0.1 if deadline is None else 0)
            except queue.Empty:
                if deadline is not None:
                    break
                continue
            for suffix, payload in messages:
                self._put(suffix, payload)

    def _put(self, suffix: str, payload: JsonObject | bytes) -> None:
        key = self.key(suffix)
        try:
            data = payload if isinstance(payload, bytes) else json_bytes(payload)
            publisher = self._publishers.get(key)
            if publisher is None:
                publisher = self._publishers[key] = zenoh.ext.declare_advanced_publisher(
                    self.session,
                    key,
                    encoding=JSON,
                    congestion_control=zenoh.CongestionControl.BLOCK,
                    cache=CACHE,
                    sample_miss_detection=MISS_DETECTION,
                    publisher_detection=True,
                )
            publisher.put(data)
        except Exception as exc:  # noqa: BLE001 -- one message must not stop publishing
            self.errors += 1
            if self.errors == 1 or isinstance(exc, zenoh.ZError):
                logger.warning("publishing on %s failed: %s", key, exc)
            return
        self.published += 1


def _answer(key: str, data: bytes) -> Callable[[zenoh.Query], None]:
    """A queryable's callback (in Zenoh's thread) that replies ``data`` on ``key``."""

    def reply(query: zenoh.Query) -> None:
        try:
            query.reply(key, data, encoding=JSON)
        except zenoh.ZError as exc:  # e.g. the session closing meanwhile
            logger.warning("answering a get of %s failed: %s", key, exc)

    return reply
