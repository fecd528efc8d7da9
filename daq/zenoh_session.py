"""Building the Zenoh session's configuration from ``[zenoh]``; opening it (in __main__).

Order, later winning: Zenoh's defaults, the JSON5 ``config_file``, then the
explicit keys ``mode``, ``connect``, ``listen``, ``multicast_scouting``.
"""

import json
import re

import zenoh

from daq.errors import ZenohError
from daq.service_config import ZenohSettings
from dbc.errors import ConfigError


def zenoh_config(settings: ZenohSettings, source: str = "") -> zenoh.Config:
    """The :class:`zenoh.Config` for ``settings``; a bad JSON5 file is a ConfigError."""
    config = zenoh.Config()
    if settings.config_file is not None:
        try:
            config = zenoh.Config.from_file(str(settings.config_file))
        except zenoh.ZError as exc:
            raise ConfigError(
                settings.config_file, "", f"not a valid Zenoh config: {one_line(str(exc))}"
            ) from exc
    overrides: dict[str, object] = {}
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
            raise ConfigError(source, f"zenoh.{key.split('/')[0]}", str(exc)) from exc
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
    (`` at /root/.cargo/.../tcp.rs:61.``).

    >>> one_line("bad --> 1:8\\n  |\\n  = expected array at /x/lib.rs:1486.")
    'bad --> 1:8 = expected array'
    """
    lines = [line.strip() for line in message.strip().splitlines()]
    text = " ".join(line for line in lines if line and line != "|")
    return re.sub(r"\s+at \S+\.rs:\d+\.?", "", text)
