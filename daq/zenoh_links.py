"""Which of the configured Zenoh ``connect`` endpoints the session is connected to.

Zenoh retries a ``connect`` endpoint it cannot reach quietly, in the background; the
session's own admin space (``@/<zid>/session/transport/unicast/*/link/*``, always
served locally) lists every open link with its ``dst`` locator. An endpoint is
reached when a link goes to its address: literally, or (for a host name) to one of
the addresses the name resolves to. The status topic shows the result next to the
connected routers and peers (``session.info``), and ``healthy`` is false while a
configured endpoint is not reached.
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
    """``proto/address`` of every open unicast link of ``session``."""
    key = f"@/{session.info.zid()}/session/transport/unicast/*/link/*"
    destinations = set()
    for reply in session.get(key, timeout=QUERY_TIMEOUT_S):
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


def unreached(endpoints: Sequence[str], destinations: Iterable[str]) -> list[str]:
    """The endpoints no link goes to (a name that does not resolve is not reached).

    >>> unreached(["tcp/127.0.0.1:7447", "tcp/10.0.0.9:7447"], {"tcp/127.0.0.1:7447"})
    ['tcp/10.0.0.9:7447']
    """
    targets = set(destinations)
    return [e for e in endpoints if not targets.intersection(_candidates(_address(e)))]


def zenoh_status(session: zenoh.Session, connect: Sequence[str]) -> JsonObject:
    """``status.zenoh``: the connect endpoints not reached, routers and peers connected."""
    info = session.info
    try:
        missing = unreached(connect, link_destinations(session)) if connect else []
    except zenoh.ZError as exc:
        logger.debug("admin space query failed: %s", exc)
        missing = list(connect)
    return {
        "connect": list(connect),
        "unreached": missing,
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
