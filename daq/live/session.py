"""The Zenoh session of a viewer: the service's ``[zenoh]`` settings, turned round.

A viewer runs next to the service with the service's config file. It must not
listen where the service listens (the port is taken), so by default it

- takes the mode and everything else from ``[zenoh]`` (and its JSON5 file),
- connects to the service's ``connect`` endpoints (a router, say) and to the
  service's ``listen`` endpoints (a wildcard address ``0.0.0.0`` / ``[::]``
  reached through loopback; port 0 skipped: nobody can know it),
- listens on ``tcp/127.0.0.1:0`` only (a peer needs a listener; loopback works
  without IPv6), nothing in client mode,
- and leaves the service's access control out. Its rules guard the *service's*
  ingress (no foreign put under ``portal/**``); in the viewer's session the same rule
  refused every sample the service published, and the viewer got only what its
  advanced subscribers queried from the service's cache: about one ``/ground`` a
  second (the heartbeat's recovery, the other nine counted as missed) instead of ten,
  so the monitor of ``deploy/demo.sh`` said "STALE ground" now and then.

``--connect``, ``--listen`` and ``--mode`` replace these. A peer keeps retrying
an endpoint that is not up yet (every second at most), so a viewer may start
before the service.
"""

import re
from collections.abc import Sequence
from typing import Any

import zenoh

from daq.service_config import ZenohSettings
from daq.zenoh_session import config_value, endpoints, open_config_session, zenoh_config
from dbc.zenoh_config import put

#: The viewer's own listener when none is given.
VIEWER_LISTEN = "tcp/127.0.0.1:0"
#: Reconnect quickly to a service that (re)starts after the viewer.
CONNECT_RETRY = {"period_init_ms": 250, "period_max_ms": 1000, "period_increase_factor": 2}
_WILDCARD = re.compile(r"^(?P<proto>[a-z]+)/(?P<host>0\.0\.0\.0|\[::\]):(?P<rest>.*)$")
_PORT = re.compile(r":(?P<port>\d+)(?:[#?].*)?$")


def reachable(endpoint: str) -> str | None:
    """Where a local viewer reaches a listener ``endpoint``; None for an ephemeral port.

    >>> reachable("tcp/0.0.0.0:7447"), reachable("tcp/[::]:7447"), reachable("tcp/[::]:0")
    ('tcp/127.0.0.1:7447', 'tcp/[::1]:7447', None)
    """
    port = _PORT.search(endpoint)
    if port is not None and port.group("port") == "0":
        return None
    match = _WILDCARD.match(endpoint)
    if match is None:
        return endpoint
    host = "127.0.0.1" if match.group("host") == "0.0.0.0" else "[::1]"
    return f"{match.group('proto')}/{host}:{match.group('rest')}"


def viewer_connect(service_connect: Sequence[str], service_listen: Sequence[str]) -> list[str]:
    """The endpoints a viewer connects to by default (duplicates dropped, order kept)."""
    targets = [*service_connect, *(reachable(e) for e in service_listen)]
    return list(dict.fromkeys(t for t in targets if t))


def viewer_zenoh_config(
    settings: ZenohSettings,
    *,
    mode: str | None = None,
    connect: Sequence[str] = (),
    listen: Sequence[str] = (),
    source: str = "",
) -> zenoh.Config:
    """The viewer's :class:`zenoh.Config` (see the module docstring)."""
    config = zenoh_config(settings, source)
    service_mode = config_value(config, "mode") or "peer"
    service_listen = endpoints(config_value(config, "listen/endpoints"), service_mode)
    service_connect = endpoints(config_value(config, "connect/endpoints"), service_mode)
    mode = mode or service_mode
    overrides: dict[str, Any] = {
        "access_control/enabled": False,
        "mode": mode,
        "connect/endpoints": list(connect) or viewer_connect(service_connect, service_listen),
        "listen/endpoints": list(listen) or ([] if mode == "client" else [VIEWER_LISTEN]),
    }
    if config_value(config, "connect/retry") is None:
        overrides["connect/retry"] = CONNECT_RETRY
    # An endpoint refused is named by the option that gave it, else by the config's key.
    options = {
        "connect/endpoints": "--connect" if connect else "",
        "listen/endpoints": "--listen" if listen else "",
    }
    for key, value in overrides.items():
        if options.get(key):
            put(config, key, value, source=options[key])
        else:
            put(config, key, value, source=source, name=f"zenoh.{key.split('/')[0]}")
    return config


def open_viewer_session(config: zenoh.Config) -> zenoh.Session:
    """Open the session; a failure (e.g. ``--listen`` on a taken port) is a ZenohError."""
    return open_config_session(
        config, "check --connect/--listen/--mode and [zenoh]: is the service's address right?"
    )
