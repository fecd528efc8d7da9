"""What a ``portal-daq`` subcommand is, and the plumbing the subcommands share.

A subcommand module defines one ``SUBCOMMAND = Subcommand(name, summary, main)``;
:mod:`daq.cli` lists the module once in ``SUBCOMMAND_MODULES`` and that is all it
takes for ``portal-daq NAME`` to run it and ``portal-daq --help`` to list it. ``main``
gets the arguments after the name and returns the exit status (0 done, 2 bad usage or
configuration, 1 a resource or input that cannot be used), printing the reason as one
line via :func:`fail`.
"""

import argparse
import logging
import os
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass

PROG = "portal-daq"


@dataclass(frozen=True, slots=True)
class Subcommand:
    #: The word after ``portal-daq``.
    name: str
    #: One line for ``portal-daq --help``.
    summary: str
    #: Parses the remaining arguments itself and returns the exit status.
    main: Callable[[Sequence[str]], int]


def setup_logging(level: str) -> None:
    """To stderr; under systemd (journald adds time stamps) without time stamps."""
    under_systemd = "JOURNAL_STREAM" in os.environ or "INVOCATION_ID" in os.environ
    fmt = "%(levelname)s %(name)s: %(message)s"
    logging.basicConfig(
        level=level.upper(), format=fmt if under_systemd else "%(asctime)s " + fmt, force=True
    )


#: What ``--log-level`` takes (any case).
LOG_LEVELS = ("DEBUG", "INFO", "WARNING", "ERROR")


def add_log_level_option(parser: argparse.ArgumentParser, default: str) -> None:
    """``--log-level``, checked by argparse: ``LOUD`` was a ``ValueError`` traceback
    from :func:`logging.basicConfig`."""
    parser.add_argument(
        "--log-level",
        type=str.upper,
        choices=LOG_LEVELS,
        default=default,
        metavar="LEVEL",
        help=f"{', '.join(LOG_LEVELS)} (any case) [{default}]",
    )


def fail(exc: BaseException | str, status: int) -> int:
    """One line on stderr, ``portal-daq: REASON``; returns ``status``."""
    sys.stderr.write(f"{PROG}: {exc}\n")
    return status


def add_channel_option(parser: argparse.ArgumentParser, verb: str) -> None:
    """``--channel``: of CAN logs of several buses, ``verb`` only that channel's frames."""
    parser.add_argument(
        "--channel",
        help=f"CAN logs: {verb} only this channel's frames (candump: can0; ASC/BLF: 0 for "
        "the first)",
    )
