"""Offline replay: a recording through the same decoder and estimator, out to CSV.

Sources:

- the service's MCAP files: the ``/can/raw`` channel (every frame, bad ones
  included; batches of :mod:`daq.can_batch`, or one JSON frame per message in
  recordings made before) and ``/daq/bus`` (gaps that reset the rolling counters), in file
  order, which is the order the live pipeline processed them. The files of one
  run (a directory, or files in any order: :mod:`daq.recording_run`) are chained
  in the order of the run. The machine configuration and DBC come from the first
  file's attachments unless a config file is given. A file cut short by a crash
  replays up to its last complete chunk.
- python-can logs (candump ``.log``, ``.asc``, ``.blf``, ... via
  ``can.LogReader``), chained in the order given: need ``--config``.

The frames go through one fresh :class:`~daq.pipeline.Pipeline`, so the
estimates equal the live ones of the same recording bit for bit, across file
rotations too.
"""

import csv
import gzip
import itertools
import json
import logging
import math
import sqlite3
import struct
import tomllib
import zlib
from array import array
from collections import Counter
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import IO, Any, TextIO, cast

import can
import numpy as np
import numpy.typing as npt
from can.io.blf import BLFParseError
from can.io.generic import BinaryIOMessageReader, MessageReader, TextIOMessageReader
from can.io.player import MESSAGE_READERS
from cantools.database.can import Database

from daq.blf_log import BlfReader
from daq.can_batch import recorded_frames
from daq.candump_text import CandumpReader
from daq.errors import RecordingError
from daq.frames import BUS_UP, BusEvent, RawFrame, from_can_message
from daq.leg_restarts import warn_restarting_legs
from daq.log_kind import FORMATS, looks_like
from daq.mcap_file import (
    BUS_TOPIC,
    CONFIG_ATTACHMENT,
    DBC_ATTACHMENT,
    RAW_TOPIC,
    RECORDING_TOPIC,
    WRITE_ERROR,
)
from daq.mcap_reading import RecordedAttachment, RecordedMessage, RecordingStream
from daq.pipeline import FrameResult, Pipeline
from daq.recording_run import MCAP_SUFFIX, expand, run_files
from daq.report.timeline import Timeline
from daq.silences import leg_silences
from daq.text_log import AscReader, CsvReader, LogLines
from daq.trc_log import TrcReader
from dbc.database import load_database_bytes
from dbc.errors import ConfigError
from dbc.machine import MachineConfig, load_machine_config, parse_machine_config
from estimator.leg import LegEstimate
from estimator.validity import both_chambers_heard

logger = logging.getLogger(__name__)

CSV_COLUMNS = (
    "leg",
    "t",
    "force_N",
    "force_raw_N",
    "pressure_Pa",
    "p_piston_Pa",
    "p_rod_Pa",
    "contact",
    "valid",
    "reasons",
)

Machine = tuple[MachineConfig, Database]

#: What python-can's log parsers raise for a file they cannot read (SQLite's for ``.db``).
_READER_ERRORS = (ValueError, IndexError, KeyError, struct.error, sqlite3.Error, BLFParseError)
#: What reading a compressed log raises where its data is cut or damaged: a gzip stream's
#: (a text log's are :class:`LogLines`'), or zlib's in a BLF's container (tracebacks).
_COMPRESSION_ERRORS = (EOFError, gzip.BadGzipFile, zlib.error)

#: No frame of a log is stamped this late (2100-01-01, Unix s): a time beyond it (inf,
#: 1e300: a corrupted line) is no time; at 1e300, adding a second changes nothing, and
#: the estimator's and the report's windows never ended.
LATEST_S = 4_102_444_800.0

#: What a line of a text log must look like, for an error whose reason python-can words
#: as its code sees it (``not enough values to unpack``).
_LINE_FORMATS = {
    ".log": " (a candump -L line is '(TIME) INTERFACE ID#DATA', candump -ta's "
    "'(TIME)  INTERFACE  ID   [LENGTH]  DATA')",
    ".csv": " (python-can's CSV: timestamp,arbitration_id,extended,remote,error,dlc,data)",
    ".blf": " (no BLF object begins where one should: a damaged file)",
}


def results(
    pipeline: Pipeline, items: Iterable[RawFrame | BusEvent], lost: Counter[str] | None = None
) -> Iterator[FrameResult]:
    """What each frame gives, in order; bus gaps reset the counters. The frames lost
    before the recording or log (by the kernel, by the service's queue: the bus events'
    ``kernel_dropped``, ``rx_dropped``) are added up in ``lost``."""
    for item in items:
        if isinstance(item, BusEvent):
            if item.reset_counters:
                pipeline.reset_counters()
            if lost is not None:
                count_loss(lost, item)
            continue
        yield pipeline.process(item)


def estimates(
    pipeline: Pipeline, items: Iterable[RawFrame | BusEvent], lost: Counter[str] | None = None
) -> Iterator[LegEstimate]:
    """Every leg estimate the frames give, in order; bus gaps reset the counters."""
    for result in results(pipeline, items, lost):
        yield from result.estimates


def write_csv(rows: Iterable[LegEstimate], out: IO[str]) -> int:
    """One CSV row per estimate (floats in full precision, ``reasons`` joined by ``|``).
    The header is written once the first row is made (or ``rows`` ended without one): a
    replay that fails before (a log not there, unreadable) leaves ``out`` untouched."""
    writer = csv.writer(out, lineterminator="\n")
    rows = iter(rows)
    first = next(rows, None)  # what reading the recording raises comes here, before the header
    writer.writerow(CSV_COLUMNS)
    count = 0
    for e in itertools.chain(() if first is None else (first,), rows):
        writer.writerow(
            (
                e.leg,
                repr(e.t_s),
                repr(e.force_N),
                repr(e.force_raw_N),
                repr(e.pressure_Pa),
                repr(e.p_piston_Pa),
                repr(e.p_rod_Pa),
                int(e.contact),
                int(e.valid),
                "|".join(e.reasons),
            )
        )
        count += 1
    return count


def replay(
    paths: Path | Sequence[Path],
    out: IO[str],
    config_path: Path | None = None,
    channel: str | None = None,
) -> int:
    """Replay a recording into CSV on ``out``; returns the row count.

    ``paths``: MCAP files or directories of one run, or python-can logs (of which only
    the frames of ``channel`` are replayed when it is given).
    """
    machine = load_machine_config(config_path) if config_path is not None else None
    files = expand([paths] if isinstance(paths, Path) else paths)
    of_one_kind(files)
    lost: Counter[str] = Counter()
    if all(path.suffix.lower() == MCAP_SUFFIX for path in files):
        no_channel_of_recordings(channel)  # was ignored: every frame of the one bus
        source = run_source(run_files(files), machine)
        if source is None:  # only truth, say, or nothing: as for an empty log, say so
            logger.warning("%s: no CAN frame in it: the CSV has its header only", files[0])
            return write_csv((), out)
        pipeline, items = source
    elif machine is None:
        raise ConfigError(files[0], "", "replaying a CAN log needs --config (the machine config)")
    else:
        pipeline = Pipeline.from_config(*machine)
        items = chained_log_frames(files, channel)
    heard = _Heard()
    rows = write_csv(heard.estimates(estimates(pipeline, heard.frames(items), lost)), out)
    if lost.total():
        logger.warning("%s", lost_frames(lost, "not in the file"))
    if pipeline.bad:
        logger.warning(
            "%d frames, %d of them not used (%s)",
            pipeline.frames,
            pipeline.bad.total(),
            ", ".join(f"{kind} {n}" for kind, n in sorted(pipeline.bad.items())),
        )
    if pipeline.frames_lost:  # the live status's frames_lost: said nowhere in a replay
        logger.warning(
            "%d frames lost on the bus before they were logged or recorded, as the rolling "
            "counters of the frames after them tell (frames_lost)",
            pipeline.frames_lost,
        )
    if pipeline.frames == 0:  # an empty log (a logger stopped at once): say so
        logger.warning("%s: no CAN frame in it: the CSV has its header only", files[0])
        return rows
    stale_s = {name: leg.stale_after_s for name, leg in pipeline.estimator.legs.items()}
    silent = leg_silences(heard.times(), stale_s, *heard.span_s, stale_s)
    for leg in pipeline.estimator.restarting_legs():  # its cycle time is wrong: said below
        silent.pop(leg, None)
    if silent:
        logger.warning(
            "legs silent (no estimate for longer than their stale time): %s",
            ", ".join(f"{leg} {n}x, {seconds:.2f} s" for leg, (n, seconds) in silent.items()),
        )
    warn_restarting_legs(pipeline)
    return rows


class _Heard:
    """The times of a replay's first and last frame, and each leg's estimates' times
    (those made with both chambers heard: a leg whose rod transducer fell silent has
    estimates, every one ``rod_stale``, and was not named), taken as they go by (for
    :func:`~daq.silences.leg_silences`), on the time line that joins the clock's steps
    back, as the report's header takes them
    (:class:`~daq.report.timeline.Timeline`): on frame times, a leg silent for 5 s across
    a step back of an hour was named nowhere, and frames stamped 0 (a logger's glitch)
    made every leg silent for 56 years."""

    def __init__(self) -> None:
        self.span_s = (math.nan, math.nan)
        self._line = Timeline()
        self._times: dict[str, array[float]] = {}

    def frames(self, items: Iterable[RawFrame | BusEvent]) -> Iterator[RawFrame | BusEvent]:
        first_s, line = math.nan, self._line
        for item in items:
            if isinstance(item, RawFrame):
                t_s = line.advance(item.t_s)
                if first_s != first_s:  # NaN: the first
                    first_s = t_s
                self.span_s = (first_s, t_s)
            yield item

    def estimates(self, rows: Iterable[LegEstimate]) -> Iterator[LegEstimate]:
        times, line = self._times, self._line
        for row in rows:
            leg_times = times.get(row.leg)
            if leg_times is None:
                leg_times = times[row.leg] = array("d")
            if both_chambers_heard(row.reasons):
                leg_times.append(line.at(row.t_s))
            yield row

    def times(self) -> dict[str, npt.NDArray[np.float64]]:
        return {leg: np.frombuffer(t_s, dtype=np.float64) for leg, t_s in self._times.items()}


def recording_results(
    files: Sequence[Path],
    machine: Machine,
    pipeline: Pipeline | None = None,
    channel: str | None = None,
    lost: Counter[str] | None = None,
) -> Iterator[FrameResult]:
    """What one fresh pipeline (or ``pipeline``, whose counters the caller reads after)
    makes of every frame of ``files``: CAN logs chained in the order given (of
    ``channel`` only, when given; the frames their logger lost added up in ``lost``,
    as :func:`results` does), or the MCAP files of one run in its order."""
    if is_can_log(files[0]):
        frames = chained_log_frames(files, channel)
        return results(pipeline or Pipeline.from_config(*machine), frames, lost)
    no_channel_of_recordings(channel)
    return run_results(files, machine, pipeline)


def no_channel_of_recordings(channel: str | None) -> None:
    """Raises :class:`~dbc.errors.ConfigError` when a channel is asked of service
    recordings (MCAP): they hold the one bus the service read."""
    if channel is not None:
        raise ConfigError("--channel", "", "picks a CAN log's bus; a service recording has one")


def of_one_kind(files: Sequence[Path]) -> None:
    """Raises :class:`~daq.errors.RecordingError` when ``files`` mix service recordings
    (``.mcap``) with CAN logs: the two are never one run, and each kind was read as the
    other (``REC.mcap: cannot read it as a CAN log``, after the log's rows)."""
    recordings = [path for path in files if path.suffix.lower() == MCAP_SUFFIX]
    if recordings and len(recordings) < len(files):
        log = next(path for path in files if path.suffix.lower() != MCAP_SUFFIX)
        raise RecordingError(
            log,
            f"a CAN log given with service recordings ({recordings[0]}): they are not one "
            "run; give one kind at a time",
        )


def is_can_log(path: Path) -> bool:
    """``path``'s suffix is one of python-can's log readers (also gzipped: ``.log.gz``)."""
    return _log_suffix(path)[0] in MESSAGE_READERS


def _log_suffix(path: Path) -> tuple[str, bool]:
    """The suffix of ``path``'s log format (``.log``, also of ``.log.gz``; '' if none)
    and whether it is gzipped."""
    suffixes = [suffix.lower() for suffix in path.suffixes[-2:]]
    gzipped = suffixes[-1:] == [".gz"]
    if gzipped:
        suffixes.pop()
    return (suffixes[-1] if suffixes else ""), gzipped


def _what_it_looks_like(path: Path, at_all: bool = False) -> str:
    """'; it looks like ...: name it ...' for a log whose content is of another format
    than its name says (:func:`daq.log_kind.looks_like`; ``at_all``: also that it looks
    like no CAN log), else ''."""
    hint = looks_like(path, *_log_suffix(path), at_all=at_all)
    return "" if hint is None else f"; {hint}"


def chained_log_frames(
    paths: Sequence[Path], channel: str | None = None
) -> Iterator[RawFrame | BusEvent]:
    """The frames of CAN logs (and their loggers' losses), one log after the other in
    the order given (the median and contact carry over, as across a logger's file
    rotation); a log that begins before the one before it ended is logged: given out of
    order, two loggers of one bus, or times counted from 0 in each. Raises
    :class:`~daq.errors.RecordingError` at once, before a frame is read, when one of
    them is not there or of no log format (it stopped a replay after the frames of the
    logs before it)."""
    for path in paths:
        _readable(path)
    return _chained_log_frames(paths, channel)


def _chained_log_frames(
    paths: Sequence[Path], channel: str | None
) -> Iterator[RawFrame | BusEvent]:
    previous: tuple[Path, float] | None = None
    for path in paths:
        t_s: float | None = None
        for frame in can_log_frames(path, channel):
            if isinstance(frame, BusEvent):
                yield frame
                continue
            if t_s is None and previous is not None and frame.t_s < previous[1]:
                logger.warning(
                    "%s begins %.3f s before %s ends: logs out of order or overlapping? "
                    "chained in the order given",
                    path,
                    previous[1] - frame.t_s,
                    previous[0],
                )
            t_s = frame.t_s
            yield frame
        if t_s is not None:
            previous = (path, t_s)


def can_log_frames(path: Path, channel: str | None = None) -> Iterator[RawFrame | BusEvent]:
    """The frames of a python-can log (candump .log, .asc, .blf, .csv, ...); with
    ``channel``, those of that channel only (as python-can names it: ``can0`` in a
    candump log, the number from 0 in ASC and BLF), else all, with a warning when they
    come from more than one (a logger on two buses). A frame without a channel (python-can
    gives none to a candump error frame) is kept whatever ``channel`` is. The times of an
    ASC log with ``timestamps relative`` (each the step since the event before) are
    summed from its start (:class:`~daq.text_log.AscReader`). A log cut short is read up
    to its last whole line (:class:`LogLines`) or BLF object (:func:`blf_cut`), with a
    warning. The frames ``candump -d`` says the kernel dropped (its ``DROPCOUNT`` lines)
    come as a :class:`~daq.frames.BusEvent` of that loss before the next frame, as live."""
    _readable(path)
    if path.stat().st_size == 0:  # a logger stopped at once (python-can: a BLF "unpack" error)
        return
    try:
        reader, lines = _log_reader(path)
    except (OSError, NotImplementedError, *_COMPRESSION_ERRORS, *_READER_ERRORS) as exc:
        # NotImplementedError: .mf4 without asammdf
        hint = _what_it_looks_like(path)
        raise RecordingError(path, f"cannot read it as a CAN log: {exc}{hint}") from exc
    count = 0
    channels: set[str] = set()
    cut = None
    dropped = 0
    t_s = math.nan
    with reader:
        try:
            for message in reader:
                if not abs(message.timestamp) < LATEST_S:  # also NaN
                    raise ValueError(
                        f"frame time {message.timestamp!r} is no time (Unix seconds, or a log's "
                        "own from its start)"
                    )
                count += 1
                if isinstance(reader, CandumpReader) and reader.dropped_frames != dropped:
                    yield _loss(message.timestamp, reader.dropped_frames - dropped)
                    dropped = reader.dropped_frames
                name = None if message.channel is None else str(message.channel)
                if name is not None and name not in channels:
                    channels.add(name)
                    if channel is None and len(channels) == 2:
                        logger.warning(
                            "%s: frames of more than one channel (%s%s): replayed as one bus; "
                            "pick one with --channel",
                            path,
                            ", ".join(sorted(channels)),
                            _channel_numbers(path),
                        )
                if channel is None or name in (None, channel):
                    yield from_can_message(message)
                t_s = message.timestamp
        except _COMPRESSION_ERRORS as exc:
            if not _log_suffix(path)[1]:  # a BLF's container
                reason = f"{exc} (a compressed container of the BLF is damaged)"
                raise RecordingError(path, f"unreadable after frame {count}: {reason}") from exc
            cut = str(exc)  # a gzipped binary log cut short or damaged, as a text log's
        except _READER_ERRORS as exc:
            cut = blf_cut(path, reader)
            if cut is None:
                hint = (
                    (count == 0 and _what_it_looks_like(path))
                    or _LINE_FORMATS.get(path.suffix.lower())  # what its line should be
                    or (count == 0 and _what_it_looks_like(path, at_all=True))
                    or ""
                )
                reason = f"{_reason(exc, lines)}{hint}"
                at = f" (line {lines.number})" if lines is not None and lines.number else ""
                raise RecordingError(path, f"unreadable after frame {count}{at}: {reason}") from exc
    if isinstance(reader, CandumpReader) and reader.dropped_frames != dropped:  # at the end
        yield _loss(t_s, reader.dropped_frames - dropped)
    if isinstance(reader, AscReader | TrcReader | BlfReader | CandumpReader):
        _log_controller_events(path, reader.controller_events, channel)
    if count == 0 and (hint := _what_it_looks_like(path, at_all=True)):  # ASC skips every line
        suffix = _log_suffix(path)[0]
        raise RecordingError(path, f"no frame of {FORMATS.get(suffix, suffix)} in it{hint}")
    if isinstance(reader, AscReader | TrcReader) and reader.skipped.first is not None:
        number, text = reader.skipped.first
        logger.warning(
            "%s: %d line%s left out, neither a frame nor an event of %s (the first, line %d: %r)",
            path,
            reader.skipped.count,
            "" if reader.skipped.count == 1 else "s",
            FORMATS[_log_suffix(path)[0]],
            number,
            text,
        )
    cut = cut or (lines.cut if lines is not None else blf_cut(path, reader))
    if cut is not None:
        logger.warning("%s is cut short (%s): read up to frame %d", path, cut, count)
    if channel is not None and channel not in channels:
        raise RecordingError(
            path,
            f"no frame on channel {channel!r}; its channels: {', '.join(sorted(channels))}"
            f"{_channel_numbers(path)}",
        )


def _channel_numbers(path: Path) -> str:
    """How python-can numbers the channels of ``path``'s format, where it is not as the
    logging tool does (CANalyzer counts from 1: its channel 1 was taken for ``--channel
    1``, the other bus, replayed without a word but the legs' silence)."""
    if _log_suffix(path)[0] in (".asc", ".blf"):
        return "; numbered from 0: CANalyzer's and CANoe's channel 1 is 0"
    return ""


#: The most of a reader's word on a line an error line quotes (it quotes the line's
#: text: a line of thousands of zero bytes made an error line of 16 KB).
_REASON_CHARS = 300
#: The byte a block the file system left unwritten reads as.
_ZERO = "\0"


def _reason(exc: Exception, lines: LogLines | None) -> str:
    """Why a log's reader stopped, in a line: a line of zero bytes (a block of the
    file the file system left zeroed, a power cut as it was written) said as such."""
    line = lines.last if lines is not None else None
    if line is not None and line.count(_ZERO) > len(line) // 2:
        return (
            f"{line.count(_ZERO)} zero bytes (a block of the file left zeroed: the logger "
            "stopped by a power cut as it wrote it?)"
        )
    reason = str(exc) or type(exc).__name__  # BLFParseError(): nothing
    return reason if len(reason) <= _REASON_CHARS else f"{reason[:_REASON_CHARS]}..."


def _readable(path: Path) -> None:
    """Raises :class:`~daq.errors.RecordingError` unless ``path`` is a file of a CAN log
    format (by its suffix)."""
    if not path.is_file():  # python-can's SQLite reader would create it
        what = "not a file" if path.exists() else "no such file"
        raise RecordingError(path, f"cannot read it as a CAN log: {what}")
    if not is_can_log(path):  # python-can: 'No read support for unknown log format ".txt"'
        known = ", ".join(sorted(MESSAGE_READERS))
        raise RecordingError(
            path,
            f"cannot read it as a CAN log: no log format for its suffix; replay reads {known} "
            "(each also .gz) and service recordings (.mcap)",
        )


def _log_controller_events(
    path: Path, events: Counter[tuple[str, str]], channel: str | None
) -> None:
    """One warning line for the CAN controller's status changes a log holds (of
    ``channel`` only, when given): bus off, error passive, ..., each an error frame."""
    states: Counter[str] = Counter()
    for (where, state), n in events.items():
        if channel in (None, where):
            states[state] += n
    if states:
        logger.warning(
            "%s: the CAN controller reported %s: each counted as an error frame",
            path,
            ", ".join(f"{state} {n}" for state, n in states.most_common()),
        )


def _loss(t_s: float, kernel_dropped: int) -> BusEvent:
    """The event of frames the kernel dropped before candump read them, as the service's
    reader makes one (the bus state is not known: up, as the logger was reading it)."""
    return BusEvent(t_s, BUS_UP, "candump DROPCOUNT", kernel_dropped=kernel_dropped)


def _log_reader(path: Path) -> tuple[MessageReader, LogLines | None]:
    """python-can's reader of ``path`` by its suffix (also gzipped); a text log's lines
    come through :class:`LogLines`."""
    suffix, gzipped = _log_suffix(path)
    reader_type = _OWN_READERS.get(suffix) or MESSAGE_READERS.get(suffix)
    if reader_type is not None and issubclass(reader_type, BinaryIOMessageReader):
        # opened here, so that a reader refusing it (BLF: 'Unexpected file format') is
        # not left holding it open
        binary = gzip.open(path, "rb") if gzipped else open(path, "rb")  # noqa: SIM115
        try:
            return reader_type(binary), None
        except BaseException:
            binary.close()
            raise
    if reader_type is None or not issubclass(reader_type, TextIOMessageReader):
        return can.LogReader(str(path)), None  # SQLite, or python-can's word on the suffix
    # The frames are ASCII; a header, comment or name may be in a Windows code page
    # (a German CANoe writes "date Mo Mär 02 ..." in Windows-1252): replaced, not fatal.
    file = (
        gzip.open(path, "rt", encoding="utf-8-sig", errors="replace")
        if gzipped
        else open(path, encoding="utf-8-sig", errors="replace")  # noqa: SIM115
    )
    lines = LogLines(file)
    try:
        return reader_type(cast(TextIO, lines)), lines
    except BaseException:
        file.close()
        raise


def blf_cut(path: Path, reader: MessageReader) -> str | None:
    """Why a BLF log is cut short, None if it is not: its header's file size (written when
    the logger closes the file) is not the file's. python-can reads it silently up to its
    last whole object."""
    if not isinstance(reader, can.BLFReader) or path.suffix.lower() != ".blf":
        return None
    size = path.stat().st_size
    if reader.file_size == size:
        return None
    return f"its header gives {reader.file_size} bytes, the file has {size}: not closed"


#: Our readers where python-can's read a suffix wrongly.
_OWN_READERS: dict[str, type[MessageReader]] = {
    ".asc": AscReader,
    ".blf": BlfReader,
    ".csv": CsvReader,
    ".trc": TrcReader,
    ".log": CandumpReader,
}


def _open(path: Path) -> IO[bytes]:
    try:
        return open(path, "rb")
    except OSError as exc:
        raise RecordingError(path, f"cannot open it: {exc.strerror or exc}") from exc


def run_results(
    files: Sequence[Path],
    machine: Machine | None,
    pipeline: Pipeline | None = None,
    *,
    warn: bool = True,
) -> Iterator[FrameResult]:
    """What the pipeline (a fresh one unless given) makes of every frame of MCAP
    ``files`` (one run, in order); ``warn`` False: a file cut short or damaged is not
    logged again (a second pass over files already read)."""
    if pipeline is not None:
        yield from results(pipeline, run_items(files, warn=warn))
        return
    source = run_source(files, machine)
    if source is not None:
        yield from results(*source)


def run_source(
    files: Sequence[Path], machine: Machine | None
) -> tuple[Pipeline, Iterator[RawFrame | BusEvent]] | None:
    """A fresh pipeline for MCAP ``files`` (one run, in order) and their frames and bus
    events; None when they hold none. ``machine`` None: the configuration embedded in the
    first file, whose attachments come before its first message."""
    attachments: dict[str, bytes] = {}
    items = run_items(files, attachments)
    first = next(items, None)
    if first is None:
        return None
    pipeline = Pipeline.from_config(*(machine or embedded_machine(attachments, files[0])))
    return pipeline, itertools.chain((first,), items)


def count_loss(lost: Counter[str], event: BusEvent) -> None:
    """Add the frames ``event`` says were lost before the recording or log to ``lost``,
    by the keys :func:`lost_frames` reads."""
    lost.update(kernel_dropped=event.kernel_dropped, rx_dropped=event.rx_dropped)


def lost_frames(lost: Counter[str], where: str) -> str:
    """The line that counts the frames a recording's ``/daq/bus`` loss events (or a
    candump log's ``DROPCOUNT`` lines) say were lost before they reached the file.

    >>> lost_frames(Counter(kernel_dropped=37, rx_dropped=1), "not in the file")[:68]
    '38 frames lost before they were recorded or logged, not in the file '
    """
    return (
        f"{lost.total()} frames lost before they were recorded or logged, {where} "
        f"({lost['kernel_dropped']} by the kernel: receive buffer full; "
        f"{lost['rx_dropped']} by the service's queue)"
    )


def run_items(
    files: Sequence[Path], attachments: dict[str, bytes] | None = None, *, warn: bool = True
) -> Iterator[RawFrame | BusEvent]:
    """The frames and bus events of MCAP ``files`` (one run, in order); the first file's
    attachments are put into ``attachments`` as they are read (before its messages).
    ``warn``: log a file cut short or a damaged chunk (:class:`RecordingStream`), and each
    gap in the recording (:func:`recording_gap`)."""
    for path in files:
        with _open(path) as stream:
            for record in RecordingStream(stream, str(path), warn=warn):
                if isinstance(record, RecordedAttachment):
                    if attachments is not None:
                        attachments.setdefault(record.name, record.data)
                elif isinstance(record, RecordedMessage):
                    if warn and record.topic == RECORDING_TOPIC:
                        logger.warning("%s", recording_gap(path, json.loads(record.data)))
                    yield from _items(record, path)


def recording_gap(path: Path, gap: dict[str, Any]) -> str:
    """The line that says what a ``/daq/recording`` gap cost (older files: no reason).

    >>> recording_gap(Path("a.mcap"), {"lost_s": 7.09, "dropped": 9950})[:67]
    'a.mcap: 7.1 s not recorded (write error: 9950 frames and items lost'
    """
    return (
        f"{path}: {float(gap.get('lost_s', math.nan)):.1f} s not recorded "
        f"({gap.get('reason', WRITE_ERROR)}: {gap.get('dropped')} frames and items lost, "
        "counted live in dropped.record); "
        "the estimates after it differ from the live ones until the median has refilled"
    )


def _items(record: RecordedMessage, path: Path) -> Iterable[RawFrame | BusEvent]:
    if record.topic == RAW_TOPIC:
        try:
            return list(recorded_frames(record.encoding, record.data))
        except (ValueError, KeyError) as exc:  # BatchFormatError, JSON
            raise RecordingError(path, f"a {RAW_TOPIC} message is unreadable: {exc}") from exc
    if record.topic == RECORDING_TOPIC:
        # Frames are missing here: their rolling counters restart, as after a bus gap live
        # (which saw every frame: the jump was counted as frames lost on the bus).
        return (BusEvent(json.loads(record.data)["t"], BUS_UP, "recording gap", True),)
    if record.topic == BUS_TOPIC:
        event = json.loads(record.data)
        lost = {key: int(event.get(key, 0)) for key in ("kernel_dropped", "rx_dropped")}
        return (
            BusEvent(event["t"], event["state"], event["reason"], event["reset_counters"], **lost),
        )
    return ()


def embedded_machine(attachments: dict[str, bytes], path: Path) -> Machine:
    if CONFIG_ATTACHMENT not in attachments or DBC_ATTACHMENT not in attachments:
        raise ConfigError(path, "", "no configuration in the recording; give --config")
    source = f"{path}:{CONFIG_ATTACHMENT}"
    try:
        data = tomllib.loads(attachments[CONFIG_ATTACHMENT].decode())
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ConfigError(source, "", f"not valid TOML: {exc}") from exc
    database = load_database_bytes(attachments[DBC_ATTACHMENT], f"{path}:{DBC_ATTACHMENT}")
    return parse_machine_config(data, source, database), database
