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
from pathlib import Path
from typing import Any

import zenoh

from daq.errors import ZenohError
from daq.service_config import ZenohSettings
from dbc.errors import ConfigError
from dbc.zenoh_config import one_line, put, read_config_file

#: How Zenoh begins the error of an access control it refuses when a session opens.
ACL_REFUSED = "Access control not enabled due to: "
#: How Zenoh begins the error of a client that reached none of its connect endpoints.
CONNECT_FAILED = "Unable to connect to any of "
#: Where the service listens without a ``config_file`` and without ``listen``.
DEFAULT_LISTEN = "tcp/127.0.0.1:7447"
#: A put to a link that stays congested this long (µs) closes the link instead of
#: stalling the publisher thread (below the watchdog's 2 s heartbeat limit).
BLOCK_WAIT_BEFORE_CLOSE_US = 1_000_000
#: The lease the service's session announces (ms), and its keep-alives per lease: a
#: router (or peer) drops a machine that vanishes without closing its session (power,
#: cable, a frozen process) after the lease the *machine* announces, so its liveliness
#: token goes and the fleet views show it gone within ~2 s. With Zenoh's default of
#: 10 s it took 8-10 s, measured through the site router, whose own 2 s lease only
#: governs how the machines judge the router. As ``zenoh.json5`` sets it.
LEASE_MS = 2000
KEEP_ALIVES = 4
#: Applied when there is no ``config_file`` (the explicit keys still win); a client
#: listens nowhere, so it gets no listener.
SAFE_DEFAULTS: dict[str, object] = {
    "listen/endpoints": [DEFAULT_LISTEN],
    "scouting/multicast/enabled": False,
    "scouting/gossip/enabled": False,
    "transport/link/tx/lease": LEASE_MS,
    "transport/link/tx/keep_alive": KEEP_ALIVES,
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


def session_config(settings: ZenohSettings, source: str = "") -> zenoh.Config:
    """:func:`zenoh_config`, and an access control that leaves the key prefix open
    (:func:`access_control_gap`) a ConfigError naming the file: what the service's session
    is opened with, checked without opening it (``portal-daq check`` too)."""
    config = zenoh_config(settings, source)
    if settings.config_file is not None:
        gap = access_control_gap(config, settings.key_prefix)
        if gap is not None:
            raise ConfigError(settings.config_file, "access_control", gap)
    return config


def open_session(settings: ZenohSettings, source: str = "") -> zenoh.Session:
    """Open the session (:func:`session_config`); a failure (e.g. the listen port is
    taken) is a ZenohError."""
    config = session_config(settings, source)
    where = "[zenoh] {keys}"
    if settings.config_file is not None:  # where the endpoints come from when not set here
        where += f" (or {{keys}} in {settings.config_file})"
    return open_config_session(
        config,
        f"check {where.format(keys='listen/connect')}: is the port taken by another "
        "process, is the address on this host?",
        settings.config_file,
        connect_hint=f"check {where.format(keys='connect')}: is the router up at that "
        "address and reachable from here? A client needs it at start; a peer starts "
        "without it and keeps trying",
    )


def access_control_gap(config: zenoh.Config, key_prefix: str) -> str | None:
    """Why the access control of ``config`` leaves ``key_prefix`` open; None when it does
    not (no access control; everything denied unless allowed; a deny rule that refuses
    puts from other sessions, :func:`_deny_rule_keys`, names a key under the prefix).

    The shipped ``zenoh.json5`` denies puts under ``portal/**``, which covers the
    default prefix ``portal/<machine id>`` but no other: with ``[zenoh] key_prefix =
    "site7/pam"`` a foreign peer's fake ``/sim/truth`` was recorded.

    >>> config = zenoh.Config()
    >>> config.insert_json5("access_control", '{"enabled": true, "default_permission": '
    ...     '"allow", "rules": [{"id": "r", "permission": "deny", "flows": ["ingress"], '
    ...     '"messages": ["put"], "key_exprs": ["portal/**"]}], "subjects": [{"id": "s"}], '
    ...     '"policies": [{"rules": ["r"], "subjects": ["s"]}]}')
    >>> access_control_gap(config, "portal/pam-1") is None
    True
    >>> access_control_gap(config, "site7/pam")[:65]
    'its deny rules name no key under site7/pam (their keys: portal/**'

    The rules see the keys as they go on the wire, under the config's ``namespace``:
    with ``namespace: "site7"`` a foreign peer's put to ``site7/portal/pam-1/sim/truth``
    passed ``portal/**`` and reached the service as ``portal/pam-1/sim/truth``.

    >>> config.insert_json5("namespace", '"site7"')
    >>> access_control_gap(config, "portal/pam-1")[:75]
    'its deny rules name no key under site7/portal/pam-1 (their keys: portal/**)'
    """
    namespace = config_value(config, "namespace")
    if namespace:
        key_prefix = f"{namespace}/{key_prefix}"
    acl = config_value(config, "access_control")
    if not isinstance(acl, dict) or acl.get("enabled") is not True:
        return None
    if acl.get("default_permission") != "allow":
        return None  # Zenoh denies what no rule allows (its default when the key is absent)
    keys, idle = _deny_rule_keys(acl)
    covered = zenoh.KeyExpr(f"{key_prefix}/**")
    if any(zenoh.KeyExpr(key).intersects(covered) for key in keys):
        return None
    idle_note = (
        f"; a deny rule no policy names, or that denies no put arriving (flows: ingress, "
        f"messages: put), keeps nothing out: {', '.join(idle)}"
        if idle
        else ""
    )
    return (
        f"its deny rules name no key under {key_prefix} (their keys: "
        f"{', '.join(keys) or 'none'}{idle_note}), the service's key prefix"
        f"{f' in the namespace {namespace}' if namespace else ''}: puts and deletes from "
        f"other sessions under it (a fake /sim/truth, a fake /status) pass; add "
        f'"{key_prefix}/**" to the key_exprs of the rule that denies them'
    )


def _deny_rule_keys(acl: dict[str, Any]) -> tuple[list[str], list[str]]:
    """The keys of the deny rules that refuse puts from other sessions (a policy names
    the rule, its flows include ingress, Zenoh's default both, its messages put), and of
    the other deny rules, which do not (a foreign put passed each such rule under
    ``portal/**`` while the check took the prefix for covered)."""
    used = {
        str(name)
        for policy in acl.get("policies") or []
        if isinstance(policy, dict)
        for name in policy.get("rules") or []
    }
    keys: list[str] = []
    idle: list[str] = []
    for rule in acl.get("rules") or []:
        if not isinstance(rule, dict) or rule.get("permission") != "deny":
            continue
        refuses_puts = (
            rule.get("id") in used
            and "ingress" in (rule.get("flows") or ["ingress"])
            and "put" in (rule.get("messages") or [])
        )
        (keys if refuses_puts else idle).extend(str(key) for key in rule.get("key_exprs") or [])
    return keys, idle


def open_config_session(
    config: zenoh.Config, hint: str, config_file: Path | None = None, *, connect_hint: str = ""
) -> zenoh.Session:
    """Open a session on ``config``; a Zenoh error becomes a ZenohError with ``hint``
    (``connect_hint``, when given, for a client that reached none of its ``connect``
    endpoints: a router down was told to look for a taken port), an access control Zenoh
    refuses (checked only now: a policy naming a rule or subject that is not there) a
    ConfigError naming ``config_file``, the file it came from (it exited 1 with the hint
    of a taken port)."""
    try:
        return zenoh.open(config)
    except zenoh.ZError as exc:
        first = one_line((str(exc).strip().splitlines() or [""])[0])
        if first.startswith(ACL_REFUSED):
            source = config_file or "the Zenoh config"
            raise ConfigError(source, "access_control", first.removeprefix(ACL_REFUSED)) from exc
        if connect_hint and first.startswith(CONNECT_FAILED):
            hint = connect_hint
        raise ZenohError(first or "cannot open the session", hint) from exc


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


def connect_endpoints(settings: ZenohSettings, source: str = "") -> tuple[str, list[str]]:
    """The session's mode (Zenoh's default: peer) and the endpoints it connects to:
    ``[zenoh] mode`` and ``connect`` or the JSON5 file's."""
    config = zenoh_config(settings, source)
    mode = config_value(config, "mode") or "peer"
    return mode, endpoints(config_value(config, "connect/endpoints"), mode)
