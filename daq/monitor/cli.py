"""``portal-daq monitor --config FILE [--plain] [--duration S] [--connect EP] ...``.

``portal-daq monitor --fleet --connect ROUTER [--plain]``: every machine on a router
(one row each; :mod:`daq.monitor.fleet_view`).

Exit status: 0 after SIGINT/SIGTERM, ``q``, or ``--duration``; 2 for a bad
config (one line on stderr); 1 when the Zenoh session cannot be opened.
"""

import argparse
import sys
from collections.abc import Sequence

import zenoh

from daq.live.command import (
    FleetViewer,
    Viewer,
    add_viewer_arguments,
    fail,
    load_fleet,
    load_viewer,
    setup_logging,
)
from daq.live.feed import LiveFeed
from daq.live.session import open_viewer_session
from daq.monitor.app import FleetView, MachineView, View, run_curses, run_plain
from daq.stop_signal import StopSignal
from daq.subcommand import Subcommand
from dbc.errors import ConfigError, DbcError, PortalDaqError

COMMAND = "monitor"


def monitor_main(args: Sequence[str]) -> int:
    parser = argparse.ArgumentParser(
        prog=f"portal-daq {COMMAND}",
        description="Live terminal view of the service from Zenoh: per leg force, contact "
        "pressure against the limit, contact and validity; the service's status.",
    )
    add_viewer_arguments(parser)
    parser.add_argument(
        "--plain", action="store_true", help="one plain text line per second (no curses)"
    )
    options = parser.parse_args(args)
    setup_logging(options.log_level)
    try:
        viewer = load_fleet(options) if options.fleet else load_viewer(options)
    except (ConfigError, DbcError) as exc:
        return fail(COMMAND, exc, 2)
    if not options.plain and not sys.stdout.isatty():
        return fail(COMMAND, "standard output is not a terminal: use --plain", 2)
    try:
        with StopSignal() as stop, open_viewer_session(viewer.zenoh) as session:
            feed, view = feed_and_view(viewer, session)
            with feed:
                if options.plain:
                    run_plain(view, stop, sys.stdout, duration_s=options.duration)
                else:
                    run_curses(view, stop, duration_s=options.duration)
    except PortalDaqError as exc:
        return fail(COMMAND, exc, 1)
    return 0


def feed_and_view(viewer: Viewer | FleetViewer, session: zenoh.Session) -> tuple[LiveFeed, View]:
    """The feed (not started) and the view it feeds: one service, or every machine."""
    if isinstance(viewer, FleetViewer):
        feed = LiveFeed(session, viewer.settings.prefix, liveliness=True)
        return feed, FleetView(viewer.settings, feed)
    feed = LiveFeed(session, viewer.config.prefix)
    return feed, MachineView(viewer.config, feed)


SUBCOMMAND = Subcommand(COMMAND, "live terminal view of the service, from Zenoh", monitor_main)
