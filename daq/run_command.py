"""``portal-daq run --config FILE``: the DAQ service (also the bare ``portal-daq --config FILE``).

Argument parsing and exit codes only; the work is in :mod:`daq.runner`. Exit status:
0 after a clean stop (SIGTERM, SIGINT, SIGHUP), 2 for a bad configuration or DBC, 1 when a
resource cannot be had at start (Zenoh endpoint, recording directory); the reason is
one line on stderr.
"""

import argparse
from collections.abc import Sequence
from pathlib import Path

from daq.interpreter import tuned_interpreter
from daq.runner import run_service
from daq.service_config import load_service_config
from daq.stop_signal import StopSignal
from daq.subcommand import PROG, Subcommand, add_log_level_option, fail, setup_logging
from dbc.errors import ConfigError, DbcError, PortalDaqError


def run_main(args: Sequence[str]) -> int:
    parser = argparse.ArgumentParser(
        prog=f"{PROG} run",
        description="Run the DAQ service: CAN frames in, soil-pressure estimates published "
        "on Zenoh and recorded to MCAP, until SIGTERM, SIGINT or SIGHUP.",
    )
    parser.add_argument(
        "--config",
        type=Path,
        required=True,
        help="service + machine TOML (`portal-daq init DIR` writes one to edit: [bus] channel, "
        "[recording] directory, the legs)",
    )
    add_log_level_option(parser, "INFO")
    options = parser.parse_args(args)
    setup_logging(options.log_level)
    try:
        config = load_service_config(options.config)
    except (ConfigError, DbcError) as exc:
        return fail(exc, 2)
    try:
        with tuned_interpreter(), StopSignal() as stop:  # SIGTERM, SIGINT, SIGHUP
            run_service(config, stop)
    except (ConfigError, DbcError) as exc:
        return fail(exc, 2)
    except PortalDaqError as exc:
        return fail(exc, 1)
    return 0


SUBCOMMAND = Subcommand("run", "run the DAQ service (CAN in, Zenoh and MCAP out)", run_main)
