"""Command-line plumbing shared by ``portal-daq monitor`` and ``portal-daq dashboard``.

Both read the service's config file (prefix, legs, pressure limit, ``[zenoh]``),
or with ``--fleet`` show every machine found on a router (:mod:`daq.live.fleet`),
take the same Zenoh overrides, stop cleanly on SIGINT/SIGTERM (exit 0), and
report a bad config in one line with exit status 2 (see :mod:`daq.cli`).
"""

import argparse
import logging
import sys
from dataclasses import dataclass
from pathlib import Path

import zenoh

from daq.live.fleet import DEFAULT_ROOT, FleetSettings
from daq.live.session import viewer_zenoh_config
from daq.live.viewer import ViewerConfig, viewer_config
from daq.service_config import ZenohSettings, key_prefix_problem, load_service_config
from daq.subcommand import add_log_level_option
from dbc.errors import ConfigError

PROG = "portal-daq"


@dataclass(frozen=True)
class Viewer:
    """A viewer's settings and the Zenoh configuration of its session (not open yet)."""

    config: ViewerConfig
    zenoh: zenoh.Config


def add_viewer_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--config",
        type=Path,
        help="the service's TOML file (key prefix, legs, pressure limit, [zenoh]); "
        "required but with --fleet",
    )
    fleet = parser.add_argument_group(
        "fleet", "every machine found on a site router through its liveliness token"
    )
    fleet.add_argument(
        "--fleet",
        action="store_true",
        help="show every machine under --root (connect to the router with --connect)",
    )
    fleet.add_argument(
        "--root",
        type=_root,
        help="machines are <root>/<machine id> [with --config: its key prefix without the "
        f"machine id; else {DEFAULT_ROOT}]",
    )
    parser.add_argument(
        "--duration", type=_positive, metavar="S", help="stop after S seconds (default: run)"
    )
    add_log_level_option(parser, "WARNING")
    group = parser.add_argument_group(
        "Zenoh", "default: the config's [zenoh], connecting to where the service listens"
    )
    group.add_argument("--mode", choices=("peer", "client"), help="Zenoh session mode")
    group.add_argument(
        "--connect",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="connect here instead, e.g. tcp/192.168.10.1:7447 (repeatable)",
    )
    group.add_argument(
        "--listen", action="append", default=[], metavar="ENDPOINT", help="listen here (repeatable)"
    )


@dataclass(frozen=True)
class FleetViewer:
    """A fleet view's settings and the Zenoh configuration of its session (not open yet)."""

    settings: FleetSettings
    zenoh: zenoh.Config


def load_viewer(options: argparse.Namespace) -> Viewer:
    """Read the config; raises ConfigError or DbcError (exit status 2)."""
    if options.config is None:
        raise ConfigError("--config", "", "required (or --fleet)")
    config = load_service_config(options.config)
    settings = viewer_zenoh_config(
        config.zenoh,
        mode=options.mode,
        connect=options.connect,
        listen=options.listen,
        source=config.source,
    )
    return Viewer(viewer_config(config), settings)


def load_fleet(options: argparse.Namespace) -> FleetViewer:
    """The fleet view's settings: from ``--config`` when given (its ``[zenoh]``, pressure
    limit and status period), else defaults with multicast scouting off (``--connect``
    says where the router is). Raises ConfigError or DbcError (exit status 2)."""
    if not options.config and not options.connect:
        raise ConfigError("--fleet", "", "needs --connect ROUTER_ENDPOINT (or --config)")
    zenoh_settings = ZenohSettings(multicast_scouting=False)
    settings = FleetSettings(options.root or DEFAULT_ROOT)
    source = "--fleet"
    if options.config is not None:
        config = load_service_config(options.config)
        viewer = viewer_config(config)
        zenoh_settings, source = config.zenoh, config.source
        settings = FleetSettings(
            options.root or config_root(config.zenoh.key_prefix),
            pressure_limit_Pa=viewer.pressure_limit_Pa,
            status_stale_s=viewer.status_stale_s,
            ground_stale_s=viewer.ground_stale_s,
        )
    session = viewer_zenoh_config(
        zenoh_settings,
        mode=options.mode,
        connect=options.connect,
        listen=options.listen,
        source=source,
    )
    return FleetViewer(settings, session)


def setup_logging(level: str) -> None:
    logging.basicConfig(
        level=level.upper(), format="%(asctime)s %(levelname)s %(name)s: %(message)s", force=True
    )


def fail(command: str, error: BaseException | str, status: int) -> int:
    """One line on stderr, e.g. ``portal-daq monitor: x.toml: zenoh.mode: ...``."""
    sys.stderr.write(f"{PROG} {command}: {error}\n")
    return status


def config_root(key_prefix: str) -> str:
    """The fleet root a service's key prefix is under: the prefix without its last chunk
    (the machine id of ``portal/<machine id>``). With ``[zenoh] key_prefix = "site7/pam"``
    in the config given, the fleet looked under ``portal`` and showed "no machine yet"
    for ever.

    >>> config_root("portal/pam-1"), config_root("site7/hall-2/pam"), config_root("pam")
    ('portal', 'site7/hall-2', 'portal')
    """
    root, slash, _ = key_prefix.rpartition("/")
    return root if slash else DEFAULT_ROOT


def _root(text: str) -> str:
    """A key prefix (the machines' without their ids): a bad one was a Zenoh traceback,
    one with a wildcard showed no machine ever."""
    problem = key_prefix_problem(text)
    if problem is not None:
        raise argparse.ArgumentTypeError(f"{text!r} {problem}")
    return text


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
    return value
