"""Command-line plumbing shared by ``portal-daq monitor`` and ``portal-daq dashboard``.

Both read the service's config file (prefix, legs, pressure limit, ``[zenoh]``),
take the same Zenoh overrides, stop cleanly on SIGINT/SIGTERM (exit 0), and
report a bad config in one line with exit status 2 (see :mod:`daq.cli`).
"""

import argparse
import logging
import sys
from dataclasses import dataclass
from pathlib import Path

import zenoh

from daq.live.session import viewer_zenoh_config
from daq.live.viewer import ViewerConfig, viewer_config
from daq.service_config import load_service_config

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
        required=True,
        help="the service's TOML file (key prefix, legs, pressure limit, [zenoh])",
    )
    parser.add_argument(
        "--duration", type=_positive, metavar="S", help="stop after S seconds (default: run)"
    )
    parser.add_argument("--log-level", default="WARNING", help="DEBUG, INFO, WARNING, ERROR")
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


def load_viewer(options: argparse.Namespace) -> Viewer:
    """Read the config; raises ConfigError or DbcError (exit status 2)."""
    config = load_service_config(options.config)
    settings = viewer_zenoh_config(
        config.zenoh,
        mode=options.mode,
        connect=options.connect,
        listen=options.listen,
        source=config.source,
    )
    return Viewer(viewer_config(config), settings)


def setup_logging(level: str) -> None:
    logging.basicConfig(
        level=level.upper(), format="%(asctime)s %(levelname)s %(name)s: %(message)s", force=True
    )


def fail(command: str, error: BaseException | str, status: int) -> int:
    """One line on stderr, e.g. ``portal-daq monitor: x.toml: zenoh.mode: ...``."""
    sys.stderr.write(f"{PROG} {command}: {error}\n")
    return status


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
    return value
