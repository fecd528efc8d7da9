"""Other services under this service's key prefix (two machines given one id).

Every key a service publishes starts with its prefix, so two services of one
machine id on a site (or of one ``[zenoh] key_prefix``) publish into the same keys:
a fleet view showed one machine, live and healthy, its values taken in turn from
both, and nothing said so. Their liveliness token ``<prefix>/alive`` cannot tell
them apart (a router keeps the key alive while either token is there). So each
service also declares ``<prefix>/alive/<zid>`` (:data:`OWNER_KEY`, its session's
id) and follows ``<prefix>/alive/*``: a token of another session there is another
service publishing under the prefix. It may also be this service's previous run,
killed and restarted before the router's lease on that session ran out (2 s with
the shipped router config): such a token goes by itself.

Liveliness tokens are no puts: the shipped access control (which refuses foreign
puts under ``portal/**``) lets them through. The callback only updates a set.

Zenoh routes nothing between two peers through a router (Zenoh 1.10, gossip off as
shipped: neither samples nor tokens), so two services of one id, both in peer mode on
one site router, never see each other's token: :meth:`PrefixOwners.tell_behind_router`
says so once, as the check is blind there.
"""

import logging
import threading
from collections.abc import Sequence
from typing import Any

import zenoh

logger = logging.getLogger(__name__)

#: ``<prefix>/alive/<zid>``: one token per service session under the prefix.
OWNER_KEY = "alive/{zid}"


class PrefixOwners:
    """Declares this session's owner token under ``prefix`` and follows the others'.

    The constructor declares nothing (:meth:`start` does); :meth:`close` undeclares.
    """

    def __init__(self, session: zenoh.Session, prefix: str) -> None:
        self.session = session
        self.prefix = prefix
        self._lock = threading.Lock()
        self._zids: set[str] = set()
        self._own = ""
        self._entities: list[Any] = []
        self._closed = False
        self._router_told = False

    def __enter__(self) -> "PrefixOwners":
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def start(self) -> None:
        if self._entities or self._closed:
            return
        self._own = str(self.session.info.zid())
        liveliness = self.session.liveliness()
        self._entities.append(
            liveliness.declare_token(f"{self.prefix}/{OWNER_KEY.format(zid=self._own)}")
        )
        self._entities.append(
            liveliness.declare_subscriber(
                f"{self.prefix}/{OWNER_KEY.format(zid='*')}", self._on_token, history=True
            )
        )

    def others(self) -> list[str]:
        """The ids of the other sessions with a service token under the prefix."""
        with self._lock:
            return sorted(self._zids - {self._own})

    def tell_behind_router(self, mode: str, routers: Sequence[str]) -> None:
        """One warning line, the first time a session in ``mode`` peer has a link to a
        router (``routers``: their ids): another service under the prefix on that router
        goes unseen, and so does this one for a viewer in peer mode connected there."""
        if mode != "peer" or not routers or self._router_told:
            return
        self._router_told = True
        logger.warning(
            "zenoh: this service is a peer linked to a router (%s): Zenoh routes nothing "
            "between two peers through a router, so another service publishing under %s "
            "there goes unseen (zenoh.same_prefix), and so does this service for a viewer "
            "that connects to the router in peer mode; on a site router set mode = "
            '"client" ([zenoh] mode, or mode in its JSON5 file)',
            " ".join(routers),
            self.prefix,
        )

    def close(self) -> None:
        """Undeclare (the session stays open: its owner closes it). Idempotent."""
        if self._closed:
            return
        self._closed = True
        for entity in reversed(self._entities):
            try:
                entity.undeclare()
            except zenoh.ZError as exc:  # e.g. the session was closed first
                logger.debug("undeclaring %s: %s", entity, exc)
        self._entities.clear()

    def _on_token(self, sample: zenoh.Sample) -> None:
        zid = str(sample.key_expr).rpartition("/")[2]
        with self._lock:
            if sample.kind == zenoh.SampleKind.PUT:
                self._zids.add(zid)
            else:
                self._zids.discard(zid)
