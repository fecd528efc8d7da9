"""Zenoh configurations as both programs build them, with errors a person reads.

The service (``daq``) and the simulator bridge (``sim_bridge``, which imports
nothing of the service) each read a Zenoh JSON5 file and put command-line options
or config keys into it. Zenoh's errors come with the Rust source line they were
raised at, the parser's wrapping and, for a TOML file, the whole file; here each
becomes one line naming the file, option or key that gave it (:func:`one_line`).
"""

import json
import re
from pathlib import Path

import zenoh

from dbc.errors import ConfigError

#: The endpoint keys of a Zenoh config.
ENDPOINT_KEYS = ("connect/endpoints", "listen/endpoints")
#: Protocols whose address is ``HOST:PORT``.
PORT_PROTOCOLS = ("tcp", "udp", "tls", "quic", "ws")


def read_config_file(path: Path, option: str) -> zenoh.Config:
    """The :class:`zenoh.Config` in ``path`` (given by ``option``, e.g. ``--config``);
    a file missing, a directory or one Zenoh refuses is a ConfigError naming it, as is
    an endpoint no session could ever use (:func:`endpoint_problem`)."""
    reason = not_a_file(path)
    if reason is not None:
        raise ConfigError(path, "", f"{reason}; give {option} a Zenoh JSON5 file")
    try:
        config = zenoh.Config.from_file(str(path))
    except zenoh.ZError as exc:
        raise ConfigError(path, "", f"not a valid Zenoh config: {one_line(str(exc))}") from exc
    for key in ENDPOINT_KEYS:
        value = json.loads(config.get_json(key) or "null")
        lists = value.values() if isinstance(value, dict) else [value]  # per mode, or one
        for endpoints in lists:
            _check_endpoints(endpoints, key, source=str(path), name=key)
    return config


def not_a_file(path: Path) -> str | None:
    """Why ``path`` is no file to read a config from; None when it is one."""
    if path.is_file():
        return None
    if path.is_dir():
        return "it is a directory"
    return "not a regular file" if path.exists() else "no such file"


def put(config: zenoh.Config, key: str, value: object, *, source: str, name: str = "") -> None:
    """Set ``key`` (e.g. ``connect/endpoints``) of ``config`` to ``value``; a value Zenoh
    refuses, or an endpoint no session could ever use, is a ConfigError naming
    ``source`` (a file or an option) and ``name``."""
    if key in ENDPOINT_KEYS:
        _check_endpoints(value, key, source=source, name=name)
    try:
        config.insert_json5(key, json.dumps(value))
    except zenoh.ZError as exc:
        raise ConfigError(source, name, one_line(str(exc))) from exc


def _check_endpoints(value: object, key: str, *, source: str, name: str) -> None:
    for endpoint in value if isinstance(value, list) else []:
        problem = endpoint_problem(str(endpoint), listen=key.startswith("listen"))
        if problem is not None:
            raise ConfigError(source, name, problem)


def endpoint_problem(endpoint: str, *, listen: bool) -> str | None:
    """Why a session can never use ``endpoint``; None when it may. Zenoh takes a TCP
    endpoint without a port or with port 99999 into its config: a peer then retried it
    for ever ("not reached"), a listener said "invalid socket address".

    >>> endpoint_problem("tcp/192.168.10.1:7447", listen=False) is None
    True
    >>> endpoint_problem("tcp/[::1]:7447?iface=lo", listen=False) is None
    True
    >>> endpoint_problem("tcp/192.168.10.1", listen=False)
    "'tcp/192.168.10.1' names no port (tcp/HOST:PORT, e.g. tcp/192.168.10.1:7447)"
    >>> endpoint_problem("tcp/127.0.0.1:0", listen=False)
    "'tcp/127.0.0.1:0': port 0 is for listening (any free port), one cannot connect to it"
    >>> endpoint_problem("udp/127.0.0.1:70000", listen=True)
    "'udp/127.0.0.1:70000': port 70000 is beyond 65535"
    """
    protocol, slash, rest = endpoint.partition("/")
    if not slash or protocol not in PORT_PROTOCOLS:
        return None
    address = re.split(r"[?#]", rest, maxsplit=1)[0]
    host, colon, port = address.rpartition(":")
    form = f"({protocol}/HOST:PORT, e.g. {protocol}/192.168.10.1:7447)"
    if not colon or not port.isdigit():
        return f"{endpoint!r} names no port {form}"
    if not host.strip("[]"):
        return f"{endpoint!r} names no host {form}"
    if int(port) > 65535:
        return f"{endpoint!r}: port {int(port)} is beyond 65535"
    if int(port) == 0 and not listen:
        return f"{endpoint!r}: port 0 is for listening (any free port), one cannot connect to it"
    return None


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

    Endpoints as Zenoh names them, without its Rust wrapping:

    >>> one_line("Unable to connect to any of [Single(tcp/127.0.0.1:9)]! at /o.rs:447.")
    'Unable to connect to any of [tcp/127.0.0.1:9]!'
    """
    lines = [line.strip() for line in message.strip().splitlines()]
    text = " ".join(line for line in lines if line and line != "|")
    text = re.sub(r'input: Some\("(?:[^"\\]|\\.)*"\), ', "", text)
    text = re.sub(r"\s+at \S+\.rs:\d+\.?", "", text)
    text = re.sub(r"\bSingle\(([^()]*)\)", r"\1", text)
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
