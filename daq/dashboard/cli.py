"""``portal-daq dashboard --config FILE [--http HOST:PORT] [--allow-host NAME] [--duration S] ...``.

``portal-daq dashboard --fleet --connect ROUTER [--mode client] [--root portal]``
serves the fleet page instead (:mod:`daq.dashboard.fleet`).

Exit status: 0 after SIGINT/SIGTERM or ``--duration``; 2 for a bad config or
``--http`` (one line on stderr); 1 when the Zenoh session or the HTTP address
cannot be had.
"""

import argparse
import sys
from collections.abc import Sequence

from daq.dashboard.fleet import FleetDashboard
from daq.dashboard.server import Dashboard, HubServer
from daq.live.command import (
    FleetViewer,
    add_viewer_arguments,
    fail,
    load_fleet,
    load_viewer,
    setup_logging,
)
from daq.live.session import open_viewer_session
from daq.stop_signal import StopSignal
from daq.subcommand import Subcommand
from dbc.errors import ConfigError, DbcError, PortalDaqError

COMMAND = "dashboard"
DEFAULT_HTTP = "127.0.0.1:8080"


def dashboard_main(args: Sequence[str]) -> int:
    parser = argparse.ArgumentParser(
        prog=f"portal-daq {COMMAND}",
        description="Live web dashboard of the service from Zenoh: the six contact pressures "
        "over the last 60 s against the limit, bus status, contact and validity per leg.",
    )
    add_viewer_arguments(parser)
    parser.add_argument(
        "--http",
        default=DEFAULT_HTTP,
        metavar="HOST:PORT",
        help=f"where to serve the page (port 0: any free one) [{DEFAULT_HTTP}]",
    )
    parser.add_argument(
        "--allow-host",
        action="append",
        default=[],
        metavar="NAME",
        help="a host name or address the browser may use in the URL, besides localhost, "
        "127.0.0.1, ::1 and the --http address (repeatable); others are refused (403) "
        "against DNS rebinding",
    )
    options = parser.parse_args(args)
    setup_logging(options.log_level)
    try:
        viewer = load_fleet(options) if options.fleet else load_viewer(options)
        address = http_address(options.http)
    except (ConfigError, DbcError) as exc:
        return fail(COMMAND, exc, 2)
    try:
        with StopSignal() as stop, open_viewer_session(viewer.zenoh) as session:
            dashboard: HubServer
            if isinstance(viewer, FleetViewer):
                dashboard = FleetDashboard(
                    session, viewer.settings, address, allowed_hosts=options.allow_host
                )
                what = f"fleet {viewer.settings.prefix}"
            else:
                dashboard = Dashboard(
                    session, viewer.config, address, allowed_hosts=options.allow_host
                )
                what = viewer.config.prefix
            with dashboard:
                sys.stdout.write(f"dashboard of {what} on {dashboard.url}\n")
                sys.stdout.flush()
                stop.wait(options.duration)
    except PortalDaqError as exc:
        return fail(COMMAND, exc, 1)
    return 0


def http_address(text: str) -> tuple[str, int]:
    """``HOST:PORT`` (``[::1]:8080`` for IPv6) to ``(host, port)``; ConfigError when not.

    >>> http_address("127.0.0.1:8080"), http_address("[::1]:0")
    (('127.0.0.1', 8080), ('::1', 0))
    """
    host, _, port = text.rpartition(":")
    host = host[1:-1] if host.startswith("[") and host.endswith("]") else host
    if not host or not port.isdigit() or int(port) > 65535:
        raise ConfigError("--http", "", f"expected HOST:PORT, e.g. {DEFAULT_HTTP}, got {text!r}")
    return host, int(port)


SUBCOMMAND = Subcommand(
    COMMAND, "live web dashboard of the service, from Zenoh, over HTTP", dashboard_main
)
