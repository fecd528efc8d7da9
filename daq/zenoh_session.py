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
import re
from typing import Any

import zenoh

from daq.errors import ZenohError
from daq.service_config import ZenohSettings
from dbc.errors import ConfigError

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
        try:
            config = zenoh.Config.from_file(str(settings.config_file))
        except zenoh.ZError as exc:
            raise ConfigError(
                settings.config_file, "", f"not a valid Zenoh config: {one_line(str(exc))}"
            ) from exc
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
        try:
            config.insert_json5(key, json.dumps(value))
        except zenoh.ZError as exc:
            raise ConfigError(source, f"zenoh.{key.split('/')[0]}", one_line(str(exc))) from exc
    return config


def open_session(settings: ZenohSettings, source: str = "") -> zenoh.Session:
    """Open the session; a failure (e.g. the listen port is taken) is a ZenohError."""
    return open_config_session(
        zenoh_config(settings, source),
        "check [zenoh] listen/connect: is the port taken by another process, "
        "is the address on this host?",
    )


def open_config_session(config: zenoh.Config, hint: str) -> zenoh.Session:
    """Open a session on ``config``; a Zenoh error becomes a ZenohError with ``hint``."""
    try:
        return zenoh.open(config)
    except zenoh.ZError as exc:
        first = (str(exc).strip().splitlines() or [""])[0]
        raise ZenohError(one_line(first) or "cannot open the session", hint) from exc


def one_line(message: str) -> str:
    """A Zenoh error on one line, without the noise of its source location for an operator
    (`` at /root/.cargo/.../tcp.rs:61.``) nor the whole file it could not parse (a TOML
    error's ``input: Some("...")``: a service config given as the Zenoh file printed
    all of its 10 KB).

    >>> one_line("bad --> 1:8\\n  |\\n  = expected array at /x/lib.rs:1486.")
    'bad --> 1:8 = expected array'
    >>> one_line('Error { message: "unclosed table", input: Some("[m\\\\n\\\\"x\\\\""), span: 8 }')
    'Error { message: "unclosed table", span: 8 }'

    A bad value put into a config is its message alone, a file's with where in the file
    (both were wrapped in ``Message { msg: ..., location: ... }``):

    >>> one_line('Json5Err(Message { msg: "Endpoints must be ...: x at /e.rs:615.", '
    ...          'location: Some(Location { line: 1, column: 2 }) }) at /c.rs:86.')
    'Endpoints must be ...: x'
    >>> one_line('JSON error: Message { msg: "unknown field `modee`, expected one of `id`", '
    ...          'location: Some(Location { line: 3, column: 5 }) }')
    'unknown field `modee`, expected one of `id` (line 3, column 5)'

    A TOML file's (Zenoh reads ``.toml`` as TOML: the service's config given as Zenoh's):

    >>> one_line('TOML deserization error: Error { message: "unknown field `bus`", '
    ...          'input: Some("[bus]\\n"), keys: [], span: Some(1..4) }')
    'TOML: unknown field `bus`'
    """
    lines = [line.strip() for line in message.strip().splitlines()]
    text = " ".join(line for line in lines if line and line != "|")
    text = re.sub(r'input: Some\("(?:[^"\\]|\\.)*"\), ', "", text)
    text = re.sub(r"\s+at \S+\.rs:\d+\.?", "", text)
    found = re.fullmatch(
        r'(Json5Err\(|JSON error: )Message \{ msg: "((?:[^"\\]|\\.)*)"'
        r"(?:, location: Some\(Location \{ line: (\d+), column: (\d+) \}\))?.*",
        text,
    )
    toml = re.fullmatch(r'TOML \w+ error: Error \{ message: "((?:[^"\\]|\\.)*)".*', text)
    if toml is not None:
        return f"TOML: {toml[1]}"
    if found is None:
        return text
    # A value inserted (Json5Err) is located in the JSON made of it: no help to anyone.
    inserted = found[1] == "Json5Err(" or found[3] is None
    return found[2] + ("" if inserted else f" (line {found[3]}, column {found[4]})")


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
