"""``portal-daq report FILE.mcap... | DIR [--out DIR] [--config FILE]``: arguments, exit codes.

``portal-daq report --campaign FILES... | DIRS... [--cluster ADDRESS] [--workers N]``:
the campaign report over many recordings (each run of the service one recording;
:mod:`daq.report.campaign`), computed on local processes or a Dask cluster
(:mod:`daq.report.campaign_run`), written by :mod:`daq.report.campaign_output`.

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

from daq.errors import EmptyRecordingError, RecordingError
from daq.output_file import named
from daq.subcommand import Subcommand, add_channel_option
from dbc.errors import ConfigError, DbcError, PortalDaqError

PROG = "portal-daq"
logger = logging.getLogger(__name__)


@dataclass(frozen=True, slots=True)
class ReportOptions:
    #: A recording file, or the files or directory of one run (rotated files).
    recording: Path | Sequence[Path]
    #: Output directory; None: ``<stem>_report`` next to the (first) recording given.
    out_dir: Path | None = None
    #: Machine configuration; None: the one embedded in the recording.
    config_path: Path | None = None
    #: A campaign report over every run found in ``recording`` (files, directories).
    campaign: bool = False
    #: Campaign: a Dask scheduler address; None: local processes.
    cluster: str | None = None
    #: Campaign: local processes (None: one per CPU; 1: this process).
    workers: int | None = None
    #: CAN logs: only this channel's frames (as python-can names it); None: all.
    channel: str | None = None

    @property
    def directory(self) -> Path:
        if self.out_dir is not None:
            return self.out_dir
        first = named(self.recording if isinstance(self.recording, Path) else self.recording[0])
        suffix = "campaign" if self.campaign else "report"
        return first.with_name(f"{first.stem}_{suffix}")


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
        help="a service recording (.mcap); rotated: the files or the directory of the run; "
        "or CAN logs (candump .log, .asc, .blf, ...: need --config)",
    )
    parser.add_argument(
        "--out", type=Path, help="output directory (default: <recording stem>_report beside it)"
    )
    parser.add_argument(
        "--config", type=Path, help="machine config (default: the one embedded in the file)"
    )
    add_channel_option(parser, "report")
    campaign = parser.add_argument_group(
        "campaign", "one table and summary page over many recordings (runs of the service)"
    )
    campaign.add_argument(
        "--campaign",
        action="store_true",
        help="every run among the files and directories given (and their subdirectories): "
        "campaign.csv + campaign.html (default --out: <first stem>_campaign)",
    )
    campaign.add_argument(
        "--cluster",
        metavar="ADDRESS",
        help="compute on a Dask distributed cluster, e.g. tcp://10.0.0.5:8786 "
        "(pip install 'portal-daq[cluster]'; paths as the workers see them)",
    )
    campaign.add_argument(
        "--workers", type=int, metavar="N", help="local processes (default: one per CPU)"
    )
    options = parser.parse_args(args)
    # ``is not None``: ``--workers 0`` is given too (it was ignored without --campaign).
    if not options.campaign and (options.cluster or options.workers is not None):
        parser.error("--cluster and --workers go with --campaign")
    if options.cluster and options.workers is not None:
        parser.error("--workers counts local processes: not with --cluster")
    if options.campaign and options.channel:
        parser.error("--channel picks a CAN log's bus: not with --campaign (service recordings)")
    return ReportOptions(
        tuple(options.recording),
        options.out,
        options.config,
        campaign=options.campaign,
        cluster=options.cluster,
        workers=options.workers,
        channel=options.channel,
    )


def report(options: ReportOptions) -> list[Path]:
    """Read the recording, write the report; the files written (the page last)."""
    from daq.report.content import analyse  # numpy and matplotlib only when drawing
    from daq.report.loading import load_recording
    from daq.report.output import write_report

    recording = load_recording(options.recording, options.config_path, options.channel)
    counts = recording.counts
    if counts.estimates == 0:
        # The frames are there but none is a leg's (another machine's config, say): the
        # page is written, and this says why its pictures are empty.
        unused = ", ".join(f"{kind} {n}" for kind, n in sorted(counts.bad.items()))
        logger.warning(
            "%s: no leg estimate in it (%d frames%s): the pictures are empty; is the "
            "machine config (--config, or the one embedded) this machine's?",
            recording.name,
            counts.frames,
            f"; not used: {unused}" if unused else "",
        )
    return write_report(analyse(recording), options.directory)


def campaign_report(options: ReportOptions) -> list[Path]:
    """Find the runs, compute their rows (locally or on the cluster), write the table and
    the page; the files written (the page last)."""
    from daq.recording_run import runs
    from daq.report.campaign_output import write_campaign
    from daq.report.campaign_run import campaign

    given = [options.recording] if isinstance(options.recording, Path) else options.recording
    found = runs(given, recursive=True)
    rows = campaign(found, options.config_path, cluster=options.cluster, workers=options.workers)
    reported = len({row.recording for row in rows})
    if not rows:
        raise EmptyRecordingError(given[0], f"none of its {len(found)} recordings holds data")
    return write_campaign(rows, options.directory, reported, len(found) - reported)


def report_main(args: Sequence[str]) -> int:
    """The ``report`` subcommand of ``portal-daq``; returns the exit status."""
    options = parse_report_args(args)
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        if options.directory.exists() and not options.directory.is_dir():
            # Found before the recording is read (mkdir said "File exists" at the end).
            raise RecordingError(
                options.directory, "it is a file; --out names the directory the report goes into"
            )
        written = campaign_report(options) if options.campaign else report(options)
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
