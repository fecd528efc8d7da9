"""Command line: ``portal-daq --config FILE`` runs the service, ``portal-daq replay`` replays,
``portal-daq recover`` completes a recording cut short by a crash.

Argument parsing and exit codes only; the work is in :mod:`daq.runner` and
:mod:`daq.replay`. Exit status: 0 after a clean stop (SIGTERM, SIGINT), 2 for a
bad configuration or DBC, 1 when a resource cannot be had at start (Zenoh
endpoint, recording directory); the reason is one line on stderr.
"""

import argparse
import logging
import os
import signal
import sys
import threading
from collections.abc import Sequence
from pathlib import Path

from daq.dashboard.cli import dashboard_main
from daq.monitor.cli import monitor_main
from daq.recover import recover_file
from daq.replay import replay
from daq.report import report_main
from daq.runner import run_service
from daq.service_config import load_service_config
from dbc.errors import ConfigError, DbcError, PortalDaqError

PROG = "portal-daq"

#: The reader, consumer, publisher and recorder threads hand frames on within about a
#: millisecond; CPython's default 5 ms GIL switch interval would add up to 5 ms of
#: latency whenever a busy thread holds the GIL (measured: bench/).
GIL_SWITCH_INTERVAL_S = 0.001


def main(argv: Sequence[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if args[:1] == ["replay"]:
        return replay_main(args[1:])
    if args[:1] == ["report"]:
        return report_main(args[1:])
    if args[:1] == ["monitor"]:
        return monitor_main(args[1:])
    if args[:1] == ["dashboard"]:
        return dashboard_main(args[1:])
    if args[:1] == ["recover"]:
        return recover_main(args[1:])
    parser = argparse.ArgumentParser(
        prog=PROG,
        description="CAN-bus DAQ and soil-pressure estimation; `portal-daq replay -h` "
        "for offline replay.",
    )
    parser.add_argument("--config", type=Path, required=True, help="service + machine TOML")
    parser.add_argument("--log-level", default="INFO", help="DEBUG, INFO, WARNING, ERROR")
    options = parser.parse_args(args)
    setup_logging(options.log_level)
    try:
        config = load_service_config(options.config)
    except (ConfigError, DbcError) as exc:
        return fail(exc, 2)
    stop = threading.Event()
    for signum in (signal.SIGTERM, signal.SIGINT):
        signal.signal(signum, lambda *_: stop.set())
    sys.setswitchinterval(GIL_SWITCH_INTERVAL_S)
    try:
        run_service(config, stop)
    except (ConfigError, DbcError) as exc:
        return fail(exc, 2)
    except PortalDaqError as exc:
        return fail(exc, 1)
    return 0


def replay_main(args: Sequence[str]) -> int:
    parser = argparse.ArgumentParser(
        prog=f"{PROG} replay",
        description="Run a recording (service MCAP, candump .log, .asc, .blf) through the "
        "decoder and estimator; one CSV row per leg estimate.",
    )
    parser.add_argument("recording", type=Path)
    parser.add_argument("--config", type=Path, help="machine config (MCAP: default embedded)")
    parser.add_argument("--out", type=Path, help="CSV file (default: stdout)")
    options = parser.parse_args(args)
    setup_logging("WARNING")
    try:
        if options.out is None:
            replay(options.recording, sys.stdout, options.config)
        else:
            with open(options.out, "w", newline="") as out:
                replay(options.recording, out, options.config)
    except (ConfigError, DbcError) as exc:
        return fail(exc, 2)
    except (PortalDaqError, OSError) as exc:
        return fail(exc, 1)
    return 0


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
    if options.out is not None and options.out.resolve() == options.recording.resolve():
        options.out = None
    try:
        result = recover_file(options.recording, options.out)
    except PortalDaqError as exc:
        return fail(exc, 1)
    sys.stderr.write(
        f"{PROG}: recovered {result.messages} messages, {result.attachments} attachments"
        + (f"; stopped at the cut ({result.stopped_by})\n" if result.stopped_by else "\n")
    )
    return 3 if result.stopped_by else 0


def setup_logging(level: str) -> None:
    """To stderr; under systemd (journald adds time stamps) without time stamps."""
    under_systemd = "JOURNAL_STREAM" in os.environ or "INVOCATION_ID" in os.environ
    fmt = "%(levelname)s %(name)s: %(message)s"
    logging.basicConfig(
        level=level.upper(), format=fmt if under_systemd else "%(asctime)s " + fmt, force=True
    )


def fail(exc: BaseException, status: int) -> int:
    sys.stderr.write(f"{PROG}: {exc}\n")
    return status
