"""Which of the configured Zenoh ``connect`` endpoints the session is connected to.

Zenoh retries a ``connect`` endpoint it cannot reach quietly, in the background; the
session's own admin space (``@/<zid>/session/transport/unicast/*/link/*``, always
served locally) lists every open link with its ``dst`` locator. An endpoint is
reached when a link goes to its address: literally, or (for a host name) to one of
the addresses the name resolves to. The status topic shows the result next to the
connected routers and peers (``session.info``), and ``healthy`` is false while a
configured endpoint is not reached.

Those statuses reach nobody through the link that is down: a site router that
restarts takes the fleet's view of the machine with it, and the statuses after the
link is back said nothing of it. :class:`Outages` counts the times a configured
endpoint went unreached and the seconds it stayed so (judged at each status: to a
status period), shown on every status after (``zenoh.outages``,
``zenoh.unreached_s``), and logs a line when the endpoints are reached again.
"""

import json
import logging
import re
import socket
from collections.abc import Iterable, Sequence

import zenoh

from daq.payloads import JsonObject

logger = logging.getLogger(__name__)

#: How long the (local) admin-space query may take.
QUERY_TIMEOUT_S = 0.5
_LOCATOR = re.compile(r"^(?P<proto>[\w-]+)/(?P<address>[^?#]*)")
_HOST_PORT = re.compile(r"^\[?(?P<host>[^\]]*)\]?:(?P<port>\d+)$")


def link_destinations(session: zenoh.Session) -> set[str]:
    """``proto/address`` of every open unicast link of ``session``, as its own admin space
    says: the query goes to no other session (a peer that declared a queryable on
    ``@/<this zid>/session/**`` answered it with a link to an unreached endpoint, which
    the status then called reached; one that never answered held each status for
    :data:`QUERY_TIMEOUT_S`)."""
    key = f"@/{session.info.zid()}/session/transport/unicast/*/link/*"
    destinations = set()
    replies = session.get(
        key, timeout=QUERY_TIMEOUT_S, allowed_destination=zenoh.Locality.SESSION_LOCAL
    )
    for reply in replies:
        sample = reply.ok
        if sample is None:
            continue
        try:
            dst = json.loads(sample.payload.to_bytes()).get("dst")
        except (ValueError, AttributeError):
            continue
        if isinstance(dst, str):
            destinations.add(_address(dst))
    return destinations


def unreached(
    endpoints: Sequence[str], destinations: Iterable[str], *, any_one: bool = False
) -> list[str]:
    """The endpoints no link goes to (a name that does not resolve is not reached); with
    ``any_one`` (a client: it opens a link to one router of its list, the next one when
    that goes), none when one is reached.

    >>> unreached(["tcp/127.0.0.1:7447", "tcp/10.0.0.9:7447"], {"tcp/127.0.0.1:7447"})
    ['tcp/10.0.0.9:7447']
    >>> unreached(["tcp/127.0.0.1:7447", "tcp/10.0.0.9:7447"], {"tcp/127.0.0.1:7447"},
    ...           any_one=True)
    []
    """
    targets = set(destinations)
    missing = [e for e in endpoints if not targets.intersection(_candidates(_address(e)))]
    return [] if any_one and len(missing) < len(endpoints) else missing


class Outages:
    """Times some configured endpoint went unreached, and the seconds it stayed so.

    Fed the unreached endpoints at each status with a monotonic time; pure.

    >>> outages = Outages()
    >>> outages.update([], 0.0), outages.update(["tcp/r:7447"], 1.0)
    (None, None)
    >>> outages.update(["tcp/r:7447"], 2.0), outages.unreached_s(2.5)
    (None, 1.5)
    >>> outages.update([], 8.0), outages.count
    (7.0, 1)
    """

    def __init__(self) -> None:
        #: Times the statuses went from every endpoint reached to some not reached.
        self.count = 0
        self._past_s = 0.0
        self._since_s: float | None = None

    def update(self, unreached: Sequence[str], now_s: float) -> float | None:
        """Take a status's unreached endpoints; the length of an outage that just ended."""
        if unreached and self._since_s is None:
            self.count += 1
            self._since_s = now_s
        elif not unreached and self._since_s is not None:
            lasted_s = now_s - self._since_s
            self._past_s += lasted_s
            self._since_s = None
            return lasted_s
        return None

    def unreached_s(self, now_s: float) -> float:
        """Seconds some endpoint was unreached, the outage going on included."""
        return self._past_s + (0.0 if self._since_s is None else now_s - self._since_s)


def zenoh_status(
    session: zenoh.Session,
    connect: Sequence[str],
    outages: Outages,
    now_s: float,
    *,
    any_one: bool = False,
) -> JsonObject:
    """``status.zenoh``: the connect endpoints not reached (:func:`unreached`, ``any_one``
    for a client), routers and peers connected, and the outages so far (``outages``
    updated with this status, at ``now_s``)."""
    info = session.info
    try:
        missing = unreached(connect, link_destinations(session), any_one=any_one) if connect else []
    except zenoh.ZError as exc:
        logger.debug("admin space query failed: %s", exc)
        missing = list(connect)
    lasted_s = outages.update(missing, now_s)
    if lasted_s is not None:
        logger.warning(
            "zenoh connect %s reached again after %.1f s: what was published meanwhile "
            "went nowhere through it",
            " ".join(connect),
            lasted_s,
        )
    return {
        "connect": list(connect),
        "unreached": missing,
        "outages": outages.count,
        "unreached_s": outages.unreached_s(now_s),
        "routers": sorted(str(zid) for zid in info.routers_zid()),
        "peers": sorted(str(zid) for zid in info.peers_zid()),
    }


def _address(locator: str) -> str:
    """``tcp/host:port`` without Zenoh's ``?metadata`` and ``#config`` parts."""
    match = _LOCATOR.match(locator)
    return f"{match.group('proto')}/{match.group('address')}" if match else locator


def _candidates(address: str) -> set[str]:
    """``address`` and, for a host name, the same with each IP address it resolves to."""
    proto, _, rest = address.partition("/")
    match = _HOST_PORT.match(rest)
    if match is None:
        return {address}
    host, port = match.group("host"), match.group("port")
    try:
        infos = socket.getaddrinfo(host, int(port), proto=socket.IPPROTO_TCP)
    except (OSError, UnicodeError):
        return {address} if _is_ip(host) else set()
    found = {address}
    for family, *_, sockaddr in infos:
        ip = str(sockaddr[0])
        found.add(f"{proto}/[{ip}]:{port}" if family == socket.AF_INET6 else f"{proto}/{ip}:{port}")
    return found


def _is_ip(host: str) -> bool:
    for family in (socket.AF_INET, socket.AF_INET6):
        try:
            socket.inet_pton(family, host)
        except OSError:
            continue
        return True
    return False
