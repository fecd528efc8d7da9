"""Publishing on Zenoh from a thread of its own, with a latest-value cache for late joiners.

The session is passed in (opened in ``daq.__main__``). :meth:`ZenohPublisher.submit`
never blocks: it queues (key, payload) into a bounded queue, or drops and counts.
The publisher thread serialises to JSON (NaN as ``null``; a payload may come
encoded already), puts with encoding ``application/json`` and keeps the latest
payload of every key. With ``threaded=False`` (the service's event loop) ``submit``
puts at once, in the caller's thread.

Late joiners: a queryable on ``<prefix>/**`` answers every ``get`` from that
cache, so ``session.get("<prefix>/**")`` returns the latest value of every key
at once. (zenoh.ext's AdvancedPublisher caches too, but only AdvancedSubscribers
can fetch that history; a queryable serves any Zenoh client, e.g. ``z_get``.)
A liveliness token ``<prefix>/alive`` lives as long as the publisher.
"""

import logging
import queue
import threading
import time
from typing import Any

import zenoh

from daq._worker import Worker
from daq.payloads import JsonObject, json_bytes

logger = logging.getLogger(__name__)

#: On close, queued messages are still published for at most this long.
DRAIN_S = 0.3
JSON = zenoh.Encoding.APPLICATION_JSON


class ZenohPublisher(Worker):
    """Publishes JSON payloads under ``prefix``; answers queries from the latest values.

    The constructor declares nothing; :meth:`start` declares the queryable and
    the liveliness token and starts the thread. :meth:`close` undeclares them
    (the session stays open: its owner closes it).
    """

    thread_name = "zenoh-publisher"

    def __init__(
        self,
        session: zenoh.Session,
        prefix: str,
        *,
        queue_size: int = 10_000,
        threaded: bool = True,
    ) -> None:
        super().__init__()
        self.threaded = threaded
        self.session = session
        self.prefix = prefix
        self._queue: queue.Queue[tuple[str, JsonObject | bytes]] = queue.Queue(maxsize=queue_size)
        self._publishers: dict[str, zenoh.Publisher] = {}
        self._latest: dict[str, tuple[zenoh.KeyExpr, bytes]] = {}
        self._latest_lock = threading.Lock()
        self._queryable: Any = None
        self._token: zenoh.LivelinessToken | None = None
        self._closed = False
        #: Messages published, dropped (queue full) and failed (Zenoh error).
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
        self._queryable = self.session.declare_queryable(
            self.key("**"), self._answer, complete=True
        )
        self._token = self.session.liveliness().declare_token(self.key("alive"))

    def submit(self, suffix: str, payload: JsonObject | bytes) -> None:
        """Queue ``payload`` (or its JSON, already encoded) for ``<prefix>/<suffix>``; never
        blocks (full: dropped, counted). Without a thread of its own: put at once."""
        if not self.threaded:
            self._put(suffix, payload)
            return
        try:
            self._queue.put_nowait((suffix, payload))
        except queue.Full:
            self.dropped += 1

    def _after_stop(self) -> None:
        """Undeclare everything (once); the thread published what was queued (:data:`DRAIN_S`)."""
        if self._closed:
            return
        self._closed = True
        for entity in (*self._publishers.values(), self._queryable, self._token):
            if entity is None:
                continue
            try:
                entity.undeclare()
            except zenoh.ZError as exc:  # e.g. the session was closed first
                logger.debug("undeclaring %s: %s", entity, exc)
        self._publishers.clear()

    def _answer(self, query: zenoh.Query) -> None:
        """Queryable callback (Zenoh's thread): reply from the cache, nothing else."""
        with self._latest_lock:
            matching = [
                (key_expr, payload)
                for key_expr, payload in self._latest.values()
                if key_expr.intersects(query.key_expr)
            ]
        for key_expr, payload in matching:
            try:
                query.reply(key_expr, payload, encoding=JSON)
            except zenoh.ZError as exc:
                logger.debug("reply on %s failed: %s", key_expr, exc)

    def _run(self) -> None:
        deadline: float | None = None
        while True:
            self.heartbeat = time.monotonic()
            if self._stop.is_set():
                deadline = deadline or time.monotonic() + DRAIN_S
                if time.monotonic() > deadline:
                    break
            try:
                suffix, payload = self._queue.get(timeout=0.1 if deadline is None else 0)
            except queue.Empty:
                if deadline is not None:
                    break
                continue
            self._put(suffix, payload)

    def _put(self, suffix: str, payload: JsonObject | bytes) -> None:
        key = self.key(suffix)
        data = payload if isinstance(payload, bytes) else json_bytes(payload)
        try:
            publisher = self._publishers.get(key)
            if publisher is None:
                publisher = self._publishers[key] = self.session.declare_publisher(
                    key, encoding=JSON
                )
            publisher.put(data)
        except zenoh.ZError as exc:
            self.errors += 1
            logger.warning("publishing on %s failed: %s", key, exc)
            return
        self.published += 1
        with self._latest_lock:
            self._latest[key] = (zenoh.KeyExpr(key), data)
