"""``portal-daq recover CUT.mcap [-o OUT.mcap]``: complete a recording cut short by a crash.

Argument parsing and exit codes only; the work is in :mod:`daq.recover`. Exit status:
0 when the file was whole, 3 when data after the cut was lost (everything before it is
kept), 1 when a file cannot be read or written; the reason is one line on stderr.
"""

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from daq.recover import recover_file
from daq.subcommand import PROG, Subcommand, fail, setup_logging
from dbc.errors import PortalDaqError

#: Exit status when the recovered file lacks what came after the cut (as mcap's CLI).
LOSSY_STATUS = 3


def recover_main(args: Sequence[str]) -> int:
    parser = argparse.ArgumentParser(
        prog=f"{PROG} recover",
        description="Rewrite a recording cut short by a crash into a complete MCAP file "
        "(summary, indexes, attachments); exit 3 when data after the cut was lost.",
    )
    parser.add_argument("recording", type=Path, help="the cut MCAP file")
    parser.add_argument("-o", "--out", type=Path, help="output file (default: in place)")
    options = parser.parse_args(args)
    setup_logging("WARNING")
    out = options.out
    if out is not None and out.resolve() == options.recording.resolve():
        out = None
    try:
        result = recover_file(options.recording, out)
    except PortalDaqError as exc:
        return fail(exc, 1)
    cut = f"; stopped at the cut ({result.stopped_by})" if result.stopped_by else ""
    if result.damaged_chunks:
        cut += f"; {result.damaged_chunks} damaged chunks skipped"
    sys.stderr.write(
        f"{PROG}: recovered {result.messages} messages, {result.attachments} attachments{cut}\n"
    )
    return LOSSY_STATUS if result.stopped_by or result.damaged_chunks else 0


SUBCOMMAND = Subcommand(
    "recover", "complete an MCAP recording cut short by a crash (indexes, summary)", recover_main
)
