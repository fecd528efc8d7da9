"""Building the Zenoh session's configuration from ``[zenoh]``; opening it (in __main__).

Order, later winning: Zenoh's defaults, then either the JSON5 ``config_file`` or,
without one, :data:`SAFE_DEFAULTS`, then the explicit keys ``mode``, ``connect``,
``listen``, ``multicast_scouting``.

Zenoh's own defaults suit a lab, not a machine: a peer listens on every interface
(``tcp/[::]:0``) and announces itself by UDP multicast, so anyone on the network
finds and reaches it. Without a ``config_file`` the service therefore listens on
loopback only (:data:`DEFAULT_LISTEN`) and neither scouts by multicast nor gossips;
reaching it from the network takes an explicit ``listen`` (and, for a locked-down
surface, the access control of ``deploy/zenoh.json5``).
"""

import json
from typing import Any

import zenoh

from daq.errors import ZenohError
from daq.service_config import ZenohSettings
from dbc.zenoh_config import one_line, put, read_config_file

#: Where the service listens without a ``config_file`` and without ``listen``.
DEFAULT_LISTEN = "tcp/127.0.0.1:7447"
#: A put to a link that stays congested this long (µs) closes the link instead of
#: stalling the publisher thread (below the watchdog's 2 s heartbeat limit).
BLOCK_WAIT_BEFORE_CLOSE_US = 1_000_000
#: Applied when there is no ``config_file`` (the explicit keys still win); a client
#: listens nowhere, so it gets no listener.
SAFE_DEFAULTS: dict[str, object] = {
    "listen/endpoints": [DEFAULT_LISTEN],
    "scouting/multicast/enabled": False,
    "scouting/gossip/enabled": False,
}


def zenoh_config(settings: ZenohSettings, source: str = "") -> zenoh.Config:
    """The :class:`zenoh.Config` for ``settings``; a bad JSON5 file is a ConfigError."""
    overrides: dict[str, object] = {
        "transport/link/tx/queue/congestion_control/block/wait_before_close": (
            BLOCK_WAIT_BEFORE_CLOSE_US
        )
    }
    if settings.config_file is not None:
        config = read_config_file(settings.config_file, "[zenoh] config_file")
    else:
        config = zenoh.Config()
        overrides.update(SAFE_DEFAULTS)
        if settings.mode == "client":
            del overrides["listen/endpoints"]
    if settings.mode is not None:
        overrides["mode"] = settings.mode
    if settings.connect:
        overrides["connect/endpoints"] = list(settings.connect)
    if settings.listen:
        overrides["listen/endpoints"] = list(settings.listen)
    if settings.multicast_scouting is not None:
        overrides["scouting/multicast/enabled"] = settings.multicast_scouting
    for key, value in overrides.items():
        put(config, key, value, source=source, name=f"zenoh.{key.split('/')[0]}")
    return config


def open_session(settings: ZenohSettings, source: str = "") -> zenoh.Session:
    """Open the session; a failure (e.g. the listen port is taken) is a ZenohError."""
    where = "[zenoh] listen/connect"
    if settings.config_file is not None:  # where the endpoints come from when not set here
        where += f" (or listen/connect in {settings.config_file})"
    return open_config_session(
        zenoh_config(settings, source),
        f"check {where}: is the port taken by another process, is the address on this host?",
    )


def open_config_session(config: zenoh.Config, hint: str) -> zenoh.Session:
    """Open a session on ``config``; a Zenoh error becomes a ZenohError with ``hint``."""
    try:
        return zenoh.open(config)
    except zenoh.ZError as exc:
        first = (str(exc).strip().splitlines() or [""])[0]
        raise ZenohError(one_line(first) or "cannot open the session", hint) from exc


def config_value(config: zenoh.Config, key: str) -> Any:
    """The JSON value of ``key`` in ``config``, or None when unset."""
    try:
        return json.loads(config.get_json(key))
    except (zenoh.ZError, ValueError):
        return None


def endpoints(value: Any, mode: str) -> list[str]:
    """Endpoints as the config holds them: a list, or per mode (Zenoh's defaults)."""
    if isinstance(value, dict):
        value = value.get(mode, [])
    return [str(e) for e in value] if isinstance(value, list) else []


def connect_endpoints(settings: ZenohSettings, source: str = "") -> list[str]:
    """The endpoints the session connects to: ``[zenoh] connect`` or the JSON5 file's."""
    config = zenoh_config(settings, source)
    mode = config_value(config, "mode") or "peer"
    return endpoints(config_value(config, "connect/endpoints"), mode)
