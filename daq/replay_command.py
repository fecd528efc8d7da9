"""``portal-daq replay RECORDING... [--config FILE] [--out FILE]``: estimates as CSV.

Argument parsing and exit codes only; the work is in :mod:`daq.replay`. Exit status:
0 done, 2 for a bad configuration or DBC, 1 when the recording or the output cannot
be used; the reason is one line on stderr.
"""

import argparse
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import IO

from daq.errors import RecordingError
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
    parser.add_argument("--config", type=Path, help="machine config (MCAP: default embedded)")
    parser.add_argument("--out", type=Path, help="CSV file (default: stdout)")
    add_channel_option(parser, "replay")
    options = parser.parse_args(args)
    setup_logging("WARNING")
    try:
        if options.out is None:
            replay(options.recording, sys.stdout, options.config, options.channel)
        else:
            write_then_replace(
                options.out,
                lambda out: replay(options.recording, out, options.config, options.channel),
            )
    except (ConfigError, DbcError) as exc:
        return fail(exc, 2)
    except BrokenPipeError:
        raise  # the reader went away (``| head``): daq.cli exits quietly
    except (PortalDaqError, OSError) as exc:
        return fail(exc, 1)
    return 0


def write_then_replace(path: Path, write: Callable[[IO[str]], object]) -> None:
    """``write`` into a file beside ``path`` (``.NAME.part``) that replaces ``path`` once
    it is done: a replay that fails (a bad config, a log that is not there or stops
    being readable) leaves a file of that name as it was, not emptied or half written.

    What is there and no regular file (``/dev/null``, ``/dev/stdout``, a named pipe) is
    written to as it is: replacing it would put a regular file in its place. A symbolic
    link stays one: the file it names is replaced.
    """
    if path.is_dir():
        raise RecordingError(path, "cannot write it: it is a directory")
    direct = path.exists() and not path.is_file()
    real = path.resolve() if path.is_symlink() else path
    target = path if direct else real.with_name(f".{real.name}.part")
    try:
        try:
            with open(target, "w", newline="") as out:
                write(out)
            if not direct:
                os.replace(target, real)
        except OSError as exc:
            raise RecordingError(path, f"cannot write it: {exc.strerror or exc}") from exc
    except BaseException:
        if not direct:
            target.unlink(missing_ok=True)
        raise


SUBCOMMAND = Subcommand(
    "replay", "estimates of a recording (MCAP, candump .log, .asc, .blf) as CSV", replay_main
)
