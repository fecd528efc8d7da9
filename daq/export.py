"""The raw CAN frames of a recording, written through python-can's log writers.

For other tools (``canplayer``, Vector CANalyzer/CANoe, ...): ``portal-daq export
REC.mcap --to candump|asc|blf`` reads ``/can/raw`` of the service's MCAP files (the
batches of :mod:`daq.can_batch`, or the JSON frames of older recordings; the files of
one run chained in its order) and writes every frame, bad ones included, with its
receive time, through :class:`can.CanutilsLogWriter`, :class:`can.ASCWriter` or
:class:`can.BLFWriter`. What python-can writes back reads with ``can.LogReader`` (and
``portal-daq replay --config``) into the same frames. The log is written beside its
path and takes its place once complete (:mod:`daq.output_file`): an export that fails
leaves an earlier file of that name as it was, and one that names a file it reads is
refused.

ASC and BLF store each frame's time as an offset from the log's start, which python-can
takes from the first frame: after a clock stepped back (NTP; the recording keeps such
frames in the order received), ASC wrote the frames before the first one with their
Unix time as the offset (read back 56 years late) and BLF at the start itself (their
times lost). The log starts at the earliest frame instead (a first pass over the
recording), so every frame keeps its time. ASC's ``date`` and ``Begin Triggerblock``
lines give that start (python-can wrote the time of the export in ``date``, and the
milliseconds without their leading zeros: ``.45`` for 45 ms).
"""

import logging
import math
from collections import Counter
from collections.abc import Iterable, Iterator
from datetime import datetime
from pathlib import Path
from typing import Any

import can

from daq.errors import RecordingError
from daq.frames import BusEvent, RawFrame
from daq.output_file import named, refuse_an_input, replacing_path
from daq.recording_run import expand, run_files
from daq.replay import count_loss, lost_frames, run_items

logger = logging.getLogger(__name__)

#: Format name -> (python-can writer, file suffix).
FORMATS: dict[str, tuple[type[can.io.generic.FileIOMessageWriter], str]] = {  # type: ignore[type-arg]
    "candump": (can.CanutilsLogWriter, ".log"),
    "asc": (can.ASCWriter, ".asc"),
    "blf": (can.BLFWriter, ".blf"),
}


class AscWriter(can.ASCWriter):
    """python-can's ASC writer with the log's start given (``start_s``, Unix s, to the
    millisecond), not taken from the first frame nor, in ``date``, from the clock."""

    def __init__(self, file: Any, start_s: float) -> None:
        self._start = datetime.fromtimestamp(start_s)
        super().__init__(file)
        self.started = self.last_timestamp = start_s

    def _format_header_datetime(self, dt: datetime) -> str:
        start = self._start  # python-can passes the clock's time for the ``date`` line
        return start.strftime(f"%a %b %d %H:%M:%S.{start.microsecond // 1000:03d} %Y")

    def log_event(self, message: str, timestamp: float | None = None) -> None:
        if not self.header_written:  # python-can would start the log at ``timestamp``
            self.file.write(f"Begin Triggerblock {self._format_header_datetime(self._start)}\n")
            self.header_written = True
            super().log_event("Start of measurement")
        super().log_event(message, timestamp)


def message(frame: RawFrame, channel: str) -> can.Message:
    """The python-can message of a recorded frame."""
    return can.Message(
        timestamp=frame.t_s,
        arbitration_id=frame.arbitration_id,
        is_extended_id=frame.is_extended_id,
        is_remote_frame=frame.is_remote_frame,
        is_error_frame=frame.is_error_frame,
        is_fd=frame.is_fd,
        dlc=frame.dlc,
        data=frame.data,
        channel=channel,
        check=False,
    )


def write_frames(
    frames: Iterable[RawFrame],
    out: Path,
    fmt: str,
    channel: str = "can0",
    start_s: float | None = None,
) -> int:
    """Write ``frames`` to ``out`` in ``fmt`` (a key of :data:`FORMATS`), in its place
    once all are written; the count. ``start_s``: the log's start for ASC and BLF (at
    most the earliest frame's time; by default the first frame's, as python-can)."""
    count = 0
    try:
        with replacing_path(out) as target, _writer(fmt, target, start_s) as writer:
            for frame in frames:
                writer.on_message_received(message(frame, channel))
                count += 1
    except OSError as exc:
        raise RecordingError(out, f"cannot write it: {exc.strerror or exc}") from exc
    return count


def _writer(fmt: str, target: Path, start_s: float | None) -> can.io.generic.MessageWriter:
    if start_s is not None:
        start_s = math.floor(start_s * 1000) / 1000  # ASC's date and BLF's header: to the ms
        if fmt == "asc":
            return AscWriter(target, start_s)
    writer = FORMATS[fmt][0](target)
    if isinstance(writer, can.BLFWriter) and start_s is not None:
        writer.start_timestamp = start_s
    return writer


def export(paths: Iterable[Path], out: Path, fmt: str) -> int:
    """The raw frames of the recording at ``paths`` (MCAP files or a directory of one
    run) into ``out``; returns the number of frames written. The frames the recording
    says were lost before it (``/daq/bus`` loss events: a CAN log has no place for
    them, and a replay of the log no longer counted them) are said in a warning line."""
    files = run_files(expand(list(paths)))
    refuse_an_input(out, files)
    lost: Counter[str] = Counter()
    start_s = None
    if fmt in ("asc", "blf"):  # the earliest frame, before the first after a step back
        times = (item.t_s for item in run_items(files, warn=False) if isinstance(item, RawFrame))
        start_s = min(times, default=None)
    count = write_frames(_frames(run_items(files), lost), out, fmt, start_s=start_s)
    if lost.total():
        logger.warning(
            "%s",
            lost_frames(lost, f"not in {out.name}, a CAN log: only {files[0].name} counts them"),
        )
    return count


def _frames(items: Iterable[RawFrame | BusEvent], lost: Counter[str]) -> Iterator[RawFrame]:
    """The frames of ``items``; their loss events' counts added up in ``lost``."""
    for item in items:
        if isinstance(item, RawFrame):
            yield item
        else:
            count_loss(lost, item)


def default_out(path: Path, fmt: str) -> Path:
    """``REC.mcap`` -> ``REC.log`` / ``.asc`` / ``.blf`` beside it (a directory: inside)."""
    suffix = FORMATS[fmt][1]
    path = named(path)
    return path / f"{path.name}{suffix}" if path.is_dir() else path.with_suffix(suffix)
