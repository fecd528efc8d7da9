"""``portal-daq report FILE.mcap... | DIR [--out DIR] [--config FILE]``: arguments, exit codes.

Exit status: 0 when the report was written; 2 for a bad configuration or DBC; 1 when
the recording cannot be read or the report cannot be written. The reason is one
line on stderr, like the other ``portal-daq`` commands. matplotlib is imported only
when a report is drawn, so the service does not load it.
"""

import argparse
import logging
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from daq.subcommand import Subcommand
from dbc.errors import ConfigError, DbcError, PortalDaqError

PROG = "portal-daq"


@dataclass(frozen=True, slots=True)
class ReportOptions:
    #: A recording file, or the files or directory of one run (rotated files).
    recording: Path | Sequence[Path]
    #: Output directory; None: ``<stem>_report`` next to the (first) recording given.
    out_dir: Path | None = None
    #: Machine configuration; None: the one embedded in the recording.
    config_path: Path | None = None

    @property
    def directory(self) -> Path:
        if self.out_dir is not None:
            return self.out_dir
        first = self.recording if isinstance(self.recording, Path) else self.recording[0]
        return first.with_name(f"{first.stem}_report")


def parse_report_args(args: Sequence[str]) -> ReportOptions:
    parser = argparse.ArgumentParser(
        prog=f"{PROG} report",
        description="Pictures and one HTML page of a service recording: contact pressure "
        "and force per foot over time, per-cycle peak and near-constant pressures, and, "
        "when it holds simulation truth, calculated vs. true force (paper, Figures 5-8).",
    )
    parser.add_argument(
        "recording",
        type=Path,
        nargs="+",
        help="a service recording (.mcap); rotated: the files or the directory of the run",
    )
    parser.add_argument(
        "--out", type=Path, help="output directory (default: <recording stem>_report beside it)"
    )
    parser.add_argument(
        "--config", type=Path, help="machine config (default: the one embedded in the file)"
    )
    options = parser.parse_args(args)
    return ReportOptions(tuple(options.recording), options.out, options.config)


def report(options: ReportOptions) -> list[Path]:
    """Read the recording, write the report; the files written (the page last)."""
    from daq.report.content import analyse  # numpy and matplotlib only when drawing
    from daq.report.loading import load_recording
    from daq.report.output import write_report

    recording = load_recording(options.recording, options.config_path)
    return write_report(analyse(recording), options.directory)


def report_main(args: Sequence[str]) -> int:
    """The ``report`` subcommand of ``portal-daq``; returns the exit status."""
    options = parse_report_args(args)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        written = report(options)
    except (ConfigError, DbcError) as exc:
        return _fail(str(exc), 2)
    except PortalDaqError as exc:
        return _fail(str(exc), 1)
    except OSError as exc:
        return _fail(f"{exc.filename or options.directory}: {exc.strerror or exc}", 1)
    sys.stdout.write(f"{written[-1]}\n")
    return 0


def _fail(message: str, status: int) -> int:
    sys.stderr.write(f"{PROG}: {message}\n")
    return status


SUBCOMMAND = Subcommand(
    "report", "pictures and an HTML page of a recording (with simulation truth)", report_main
)
