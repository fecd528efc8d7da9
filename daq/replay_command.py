"""``portal-daq replay RECORDING... [--config FILE] [--out FILE]``: estimates as CSV.

Argument parsing and exit codes only; the work is in :mod:`daq.replay`. Exit status:
0 done, 2 for a bad configuration or DBC, 1 when the recording or the output cannot
be used; the reason is one line on stderr.
"""

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from daq.errors import RecordingError
from daq.output_file import refuse_an_input, replacing
from daq.recording_run import expand
from daq.replay import replay
from daq.subcommand import PROG, Subcommand, add_channel_option, fail, setup_logging
from dbc.errors import ConfigError, DbcError, PortalDaqError


def replay_main(args: Sequence[str]) -> int:
    parser = argparse.ArgumentParser(
        prog=f"{PROG} replay",
        description="Run a recording (service MCAP, candump .log, .asc, .blf) through the "
        "decoder and estimator; one CSV row per leg estimate. The files of a rotated "
        "MCAP recording (or their directory) are chained in the order of their run.",
    )
    parser.add_argument(
        "recording", type=Path, nargs="+", help="MCAP files or a directory of one run, or CAN logs"
    )
    parser.add_argument(
        "--config",
        type=Path,
        help="service or machine TOML (`portal-daq init`'s); needed for CAN logs; "
        "MCAP: the one embedded in the recording by default",
    )
    parser.add_argument("--out", type=Path, help="CSV file (default: stdout)")
    add_channel_option(parser, "replay")
    options = parser.parse_args(args)
    setup_logging("WARNING")
    try:
        if options.out is None:
            replay(options.recording, sys.stdout, options.config, options.channel)
        else:
            write_csv_to(options.out, options)
    except (ConfigError, DbcError) as exc:
        return fail(exc, 2)
    except BrokenPipeError:
        raise  # the reader went away (``| head``): daq.cli exits quietly
    except (PortalDaqError, OSError) as exc:
        return fail(exc, 1)
    return 0


def write_csv_to(path: Path, options: argparse.Namespace) -> None:
    """The replay's CSV into ``path`` (:func:`~daq.output_file.replacing`: a replay that
    fails leaves what was there as it was; one that would write a file it reads is
    refused)."""
    refuse_an_input(path, expand(options.recording))
    try:
        with replacing(path) as out:
            replay(options.recording, out, options.config, options.channel)
    except OSError as exc:
        raise RecordingError(path, f"cannot write it: {exc.strerror or exc}") from exc


SUBCOMMAND = Subcommand(
    "replay", "estimates of a recording (MCAP, candump .log, .asc, .blf) as CSV", replay_main
)
