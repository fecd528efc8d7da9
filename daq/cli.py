"""``portal-daq COMMAND ...``: the subcommands, listed once, dispatched by name.

``portal-daq --help`` lists every subcommand of ``SUBCOMMAND_MODULES``; ``portal-daq
NAME ARGS`` hands ``ARGS`` to that subcommand's ``main`` (see :mod:`daq.subcommand`).
The bare ``portal-daq --config FILE`` of earlier releases still runs the service
(``portal-daq run --config FILE``); ``portal-daq --version`` prints the installed version
(it was taken for the bare form: "run: --config is required"). An unknown name exits 2
with argparse's list of the valid ones. When whoever reads standard output goes away
(``portal-daq replay X | head``), the command ends quietly with status 141, as a Unix
tool killed by SIGPIPE; Ctrl-C in a command that does not handle SIGINT itself (replay,
report, calibrate, ...) ends it with one line and status 130.
"""

import argparse
import importlib
import os
import sys
from collections.abc import Sequence

from daq.subcommand import PROG, Subcommand
from dbc import installed_version

#: One line per subcommand module; each defines ``SUBCOMMAND``. Keep them sorted.
SUBCOMMAND_MODULES = (
    "daq.calibrate.command",
    "daq.check_command",
    "daq.dashboard.cli",
    "daq.export_command",
    "daq.init_command",
    "daq.monitor.cli",
    "daq.recover_command",
    "daq.replay_command",
    "daq.report.command",
    "daq.router",
    "daq.run_command",
)

#: What a shell reports for a process killed by SIGPIPE (128 + 13).
BROKEN_PIPE_STATUS = 141
#: What a shell reports for a process ended by SIGINT, Ctrl-C (128 + 2).
INTERRUPTED_STATUS = 130


def subcommands() -> dict[str, Subcommand]:
    """Every subcommand by name, in the order of ``SUBCOMMAND_MODULES``."""
    found: dict[str, Subcommand] = {}
    for module_name in SUBCOMMAND_MODULES:
        command: Subcommand = importlib.import_module(module_name).SUBCOMMAND
        found[command.name] = command
    return found


def build_parser(commands: dict[str, Subcommand]) -> argparse.ArgumentParser:
    """The top-level parser: only the command name; each command parses the rest."""
    width = max(len(name) for name in commands) + 3
    listing = "\n".join(f"  {c.name:<{width}}{c.summary}" for c in commands.values())
    parser = argparse.ArgumentParser(
        prog=PROG,
        description="CAN-bus DAQ and soil-pressure estimation for the portal advancing mechanism.",
        epilog=f"commands:\n{listing}\n\n`{PROG} COMMAND --help` for a command's options; "
        f"`{PROG} --config FILE` (no command) is `{PROG} run --config FILE`.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    names = parser.add_subparsers(
        dest="command", metavar="COMMAND", required=True, help="one of the commands below"
    )
    for command in commands.values():
        names.add_parser(command.name, add_help=False)
    parser.add_argument("--version", action="version", version=f"{PROG} {installed_version()}")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    commands = subcommands()
    if args[:1] and args[0].startswith("-") and args[0] not in ("-h", "--help", "--version"):
        name, rest = "run", args  # the bare service form: portal-daq --config FILE
    else:
        name, rest = build_parser(commands).parse_args(args[:1]).command, args[1:]
    try:
        return commands[name].main(rest)
    except KeyboardInterrupt:
        # Ctrl-C in replay, report, calibrate, ...: what they write beside an output is
        # removed on the way out; the traceback of wherever it landed told nothing.
        sys.stderr.write(f"{PROG}: interrupted\n")
        return INTERRUPTED_STATUS
    except BrokenPipeError:
        # Python would report the flush at exit as an error too: point stdout at nothing.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return BROKEN_PIPE_STATUS
