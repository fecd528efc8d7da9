"""``portal-daq export RECORDING... --to candump|asc|blf [--out FILE]``: raw frames out.

Argument parsing and exit codes only; the work is in :mod:`daq.export`. Exit status:
0 done, 1 when the recording or the output cannot be used; the reason is one line on
stderr.
"""

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from daq.export import FORMATS, default_out, export
from daq.subcommand import PROG, Subcommand, fail, setup_logging
from dbc.errors import PortalDaqError


def export_main(args: Sequence[str]) -> int:
    parser = argparse.ArgumentParser(
        prog=f"{PROG} export",
        description="Write the raw CAN frames of a service recording (MCAP files, or the "
        "directory of one run) as a candump .log, Vector .asc or .blf, through python-can.",
    )
    parser.add_argument("recording", type=Path, nargs="+", help="MCAP files or a directory")
    parser.add_argument("--to", choices=sorted(FORMATS), required=True, help="log format")
    parser.add_argument(
        "--out",
        type=Path,
        help="output file (default: the first file's name with the format's suffix, beside "
        "it; a directory's name, inside the directory)",
    )
    options = parser.parse_args(args)
    setup_logging("WARNING")
    out = options.out or default_out(options.recording[0], options.to)
    try:
        count = export(options.recording, out, options.to)
    except (PortalDaqError, OSError) as exc:
        return fail(exc, 1)
    sys.stdout.write(f"{out}: {count} frames\n")
    return 0


SUBCOMMAND = Subcommand(
    "export", "raw CAN frames of a recording as candump .log, .asc or .blf", export_main
)
