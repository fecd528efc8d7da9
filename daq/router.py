"""``portal-daq router [--config zenoh-router.json5]``: a site Zenoh router in Python.

The site router is what every machine's service connects to (``[zenoh] connect``)
and what the fleet dashboard and monitor connect to (``--connect``). Eclipse's
``zenohd`` is the production choice (``zenohd -c deploy/zenoh-router.json5``): it
reads the same file. This command opens a Python Zenoh session in router mode
with that file where zenohd is not installed (bench, tests); without ``--config``,
the one shipped in the package (:data:`DEFAULT_CONFIG`), so that it runs from a wheel.

The file's ``mode`` must be ``router`` (or absent). Exit status: 0 after
SIGINT/SIGTERM; 2 for a file that is not a valid Zenoh config (its access control too) or asks for
another mode (one line on stderr); 1 when the session cannot be opened (e.g. the
listen port is taken).
"""

import argparse
import json
import sys
from collections.abc import Sequence
from importlib import resources
from pathlib import Path

import zenoh

from daq.stop_signal import StopSignal
from daq.subcommand import PROG, Subcommand, add_log_level_option, fail, setup_logging
from daq.zenoh_session import open_config_session
from dbc.errors import ConfigError, PortalDaqError
from dbc.zenoh_config import read_config_file

COMMAND = "router"
MODE = "router"
#: The site router's config shipped in the package (``deploy/zenoh-router.json5`` in the
#: repository points to it): listens on ``tcp/0.0.0.0:7447``, 2 s lease, no scouting.
DEFAULT_CONFIG = Path(str(resources.files("daq").joinpath("zenoh-router.json5")))


def router_config(path: Path) -> zenoh.Config:
    """The router's :class:`zenoh.Config` from ``path``; ConfigError when unusable."""
    config = read_config_file(path, "--config")
    mode = json.loads(config.get_json("mode") or "null")
    if mode not in (None, MODE):
        raise ConfigError(path, "mode", f"must be {MODE!r} for a router, got {mode!r}")
    config.insert_json5("mode", json.dumps(MODE))
    return config


def listen_endpoints(config: zenoh.Config) -> list[str]:
    value = json.loads(config.get_json("listen/endpoints") or "[]")
    if isinstance(value, dict):  # per mode, as in Zenoh's defaults
        value = value.get(MODE, [])
    return [str(endpoint) for endpoint in value] if isinstance(value, list) else []


def router_main(args: Sequence[str]) -> int:
    parser = argparse.ArgumentParser(
        prog=f"{PROG} {COMMAND}",
        description="A site Zenoh router (Python session in router mode) for machines and "
        "fleet views to connect to; zenohd with the same file is the production choice.",
    )
    parser.add_argument(
        "--config",
        type=Path,
        default=DEFAULT_CONFIG,
        help=f"Zenoh JSON5 file [the packaged one: {DEFAULT_CONFIG}]",
    )
    add_log_level_option(parser, "WARNING")
    options = parser.parse_args(args)
    setup_logging(options.log_level)
    try:
        config = router_config(options.config)
    except ConfigError as exc:
        return fail(exc, 2)
    endpoints = listen_endpoints(config)
    try:
        with (
            StopSignal() as stop,  # SIGTERM, SIGINT
            open_config_session(
                config, "check listen in the router's config", options.config
            ) as session,
        ):
            sys.stdout.write(f"router {session.info.zid()} listening on {' '.join(endpoints)}\n")
            sys.stdout.flush()
            stop.wait()
    except ConfigError as exc:  # an access control Zenoh refuses
        return fail(exc, 2)
    except PortalDaqError as exc:
        return fail(exc, 1)
    return 0


SUBCOMMAND = Subcommand(
    COMMAND, "a site Zenoh router for machines and fleet views (zenohd in production)", router_main
)
