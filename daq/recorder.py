"""Recording to rotating MCAP files, in a thread of its own fed through a bounded queue.

The consumer hands each :class:`~daq.mcap_file.RecordBatch` (the frames it processed
in one go, their estimates already encoded) and each bus event to
:meth:`Recorder.submit`, which never blocks: when the queue is full the item is
dropped and counted (a batch as its frames). The recorder thread writes a batch per
call through :class:`~daq.mcap_file.McapFile`, writes the chunk in progress out every
``flush_period_s`` and starts a new file when one reaches ``max_bytes`` or spans
``max_duration_s`` of frame time. Files are named
``<machine>_<UTC start, YYYYmmddTHHMMSS.mmmZ>.mcap``. The files of one recorder (one
run of the service) carry the same run id, drawn at :meth:`Recorder.start`, and their
index in the run (:mod:`daq.recording_run`), so that replay chains them. Simulation truth samples
(:class:`~daq.sim_truth.TruthRecord`, from a simulator bridge) are submitted the same
way and written to ``/sim/truth``; one that is not a valid sample is counted
(:attr:`Recorder.rejected`) and skipped. The consumer's ``/ground`` snapshots (a
:class:`~estimator.machine.MachineSnapshot`, with the stability margin) go to ``/ground``.

A write error (disk full, directory gone) never stops the service and never
shows a traceback: one log line says that recording stopped and why, the file is
abandoned (it reads back up to its last written chunk; ``portal-daq recover``
completes it) and a new one is tried every :data:`RETRY_AFTER_S` while items keep
coming; every item meanwhile is dropped and counted. A file that cannot even
take its header is removed again, so retries leave no empty files behind. When a
file opens again, one log line gives the seconds lost, and the new file begins
with a ``/daq/recording`` message saying when recording stopped, how long the gap
is and how many items were dropped (the report shows it). While recording is
stopped, :attr:`Recorder.failing` is true and the service is not healthy.

Items dropped on a full queue (the recorder fell behind) are a gap too
(:class:`Overflow`): the next item put is preceded by a ``/daq/recording`` message
saying since when and how many, so that the file says what it lacks, as the status did.

Any other exception while writing one item (a bug, a payload nobody foresaw) is
counted (:attr:`Recorder.failed_items`) and the item skipped.
:meth:`Recorder.close` (also on SIGTERM) finishes the file, so it has its
summary; after a crash the file reads back up to its last written chunk.
"""

import errno
import logging
import queue
import time
import uuid
from collections.abc import Callable, Mapping
from datetime import UTC, datetime
from pathlib import Path
from typing import Protocol

from cantools.database.can import Database

from daq._worker import Worker
from daq.errors import RecordingError
from daq.frames import BusEvent
from daq.mcap_file import (
    QUEUE_FULL,
    CountingFile,
    EncodedBatch,
    McapFile,
    RecordBatch,
    RecordingGap,
)
from daq.recording_run import run_metadata
from daq.recover import hold_while_writing, recover_cut_files
from daq.service_config import RecordingSettings
from daq.sim_truth import TruthRecord, truth_payload
from estimator.machine import MachineSnapshot

logger = logging.getLogger(__name__)

#: After a write error, the next file is tried this much later.
RETRY_AFTER_S = 5.0
#: On close, queued items are still written for at most this long (the rest: dropped,
#: counted). Within the recorder process's join (:data:`daq.recorder_process.JOIN_S`) and
#: systemd's TimeoutStopSec; at 0.5 s a CPU starved at the stop (deploy/demo.sh in UML on
#: a busy host) cut the last ~80 items of a recording that 2 s would have kept.
DRAIN_S = 2.0

Item = RecordBatch | EncodedBatch | BusEvent | TruthRecord | MachineSnapshot | RecordingGap


class ItemQueue(Protocol):
    """Where the recorder takes its items from: a ``queue.Queue`` in this process, or a
    ``multiprocessing`` queue in the recorder's process (:mod:`daq.recorder_process`)."""

    def put_nowait(self, item: Item) -> None: ...

    def get(self, block: bool = True, timeout: float | None = None) -> Item: ...

    def get_nowait(self) -> Item: ...

    def qsize(self) -> int: ...


class GilYield:
    """Lets the GIL go (``time.sleep(0)``) once ``every_s`` of the writer's work has passed:
    the frames' thread then waits at most that long for it while a batch is written, not
    the interpreter's switch interval; per message it cost a system call each, 30 us per
    frame with every frame's signals recorded (measured)."""

    def __init__(self, every_s: float = 0.00025) -> None:
        self.every_s = every_s
        self._since = time.perf_counter()

    def __call__(self) -> None:
        if time.perf_counter() - self._since >= self.every_s:
            time.sleep(0)
            self._since = time.perf_counter()


def file_name(machine_id: str, t_s: float) -> str:
    """``<machine>_<UTC time>.mcap``, sortable by name.

    >>> file_name("pam-1", 0.0)
    'pam-1_19700101T000000.000Z.mcap'
    """
    stamp = datetime.fromtimestamp(t_s, UTC)
    return f"{machine_id}_{stamp:%Y%m%dT%H%M%S}.{stamp.microsecond // 1000:03d}Z.mcap"


def count(item: Item) -> int:
    """What dropping ``item`` loses, as counted in ``dropped``: a batch counts its frames."""
    if isinstance(item, RecordBatch):
        return len(item.frames) or 1
    return (item.frame_count or 1) if isinstance(item, EncodedBatch) else 1


class Overflow:
    """The items a full queue dropped since the last one put, told in the file: the next
    item put is preceded by a :class:`~daq.mcap_file.RecordingGap` (:data:`QUEUE_FULL`)
    from the first drop to then, with the items dropped. Without it a recorder that fell
    behind (a slow disk, a CPU busy with other work) left a hole in the file that nothing
    in it explained: replayed, its legs were silent for as long, as if the sensors were.
    """

    def __init__(self, now: Callable[[], float] = time.time) -> None:
        self._now = now
        self._since_t_s: float | None = None
        self._dropped = 0

    def put(self, put_nowait: Callable[[Item], None], item: Item) -> bool:
        """``put_nowait(item)``, after the gap of what was dropped before it; False when
        the queue is full (``item`` is dropped: the caller counts it)."""
        try:
            if self._since_t_s is not None:
                gap = RecordingGap(self._since_t_s, self._now(), self._dropped, QUEUE_FULL)
                put_nowait(gap)
                self._since_t_s, self._dropped = None, 0
            put_nowait(item)
        except queue.Full:
            if self._since_t_s is None:
                self._since_t_s = self._now()
            self._dropped += count(item)
            return False
        return True


def cannot_create(exc: OSError) -> str:
    """Why the ``[recording] directory`` cannot be made, and what to do when it is a right.

    Under deploy/'s systemd unit (``ProtectSystem=strict``, user portal-daq) only
    /var/lib/portal-daq is writable: a directory elsewhere was ``Read-only file system``,
    with no word of the key or of the unit.
    """
    reason = f"cannot create it ([recording] directory): {exc.strerror or exc}"
    if exc.errno in (errno.EROFS, errno.EACCES, errno.EPERM):
        reason += (
            " (the service's user may not write there; under the portal-daq systemd unit"
            " only /var/lib/portal-daq is writable: record below it, or add"
            " ReadWritePaths= for it to the unit)"
        )
    return reason


class Recorder(Worker):
    """Writes what it is handed to MCAP files under ``settings.directory``.

    The constructor opens nothing; :meth:`start` (or ``with``) creates the
    directory, opens the first file and starts the thread.
    """

    thread_name = "recorder"

    def __init__(
        self,
        settings: RecordingSettings,
        database: Database,
        *,
        machine_id: str,
        attachments: Mapping[str, bytes] = {},
        decoded_units: Mapping[str, Mapping[str, str]] = {},
        now: Callable[[], float] = time.time,
        run_id: str | None = None,
        items: ItemQueue | None = None,
    ) -> None:
        """``items``: where to take the items from (default: a queue of its own, fed by
        :meth:`submit`); given, the recorder is alone in its process
        (:mod:`daq.recorder_process`) and has no thread to let the GIL go to."""
        if settings.directory is None:
            raise ValueError("settings.directory is None: recording is off")
        super().__init__()
        self.directory: Path = settings.directory
        self.settings = settings
        self._database = database
        self._machine_id = machine_id
        self._attachments = dict(attachments)
        self._decoded_units = decoded_units
        self._now = now
        #: Names this run of the service in every file's metadata; drawn at start if None.
        self.run_id = run_id
        self._queue: ItemQueue = items or queue.Queue(maxsize=settings.queue_size)
        self._overflow = Overflow(now)
        self._shares_gil = items is None
        self._file: McapFile | None = None
        self._stream: CountingFile | None = None
        self._last_flush = 0.0
        self._retry_at = 0.0
        #: Wall-clock time recording stopped at (a write error), None while recording.
        self.stopped_t_s: float | None = None
        self._dropped_at_stop = 0
        #: Items dropped (a batch counts its frames): queue full, or no file open after
        #: a write error.
        self.dropped = 0
        #: Write errors.
        self.errors = 0
        #: Truth samples skipped because they were not valid samples.
        self.rejected = 0
        #: Items whose writing raised something else than a write error (skipped).
        self.failed_items = 0
        #: Recording gaps so far: (stopped at, seconds lost), wall-clock time.
        self.gaps: list[tuple[float, float]] = []
        #: Their count and the seconds they lost (what the status shows).
        self.gap_count = 0
        self.lost_s = 0.0
        #: Files begun, and the current one.
        self.paths: list[Path] = []
        self._files_created = 0

    @property
    def depth(self) -> int:
        return self._queue.qsize()

    @property
    def current_path(self) -> Path | None:
        return self.paths[-1] if self._file is not None else None

    @property
    def failing(self) -> bool:
        """Recording has stopped after a write error (and not resumed yet)."""
        return self.stopped_t_s is not None

    @property
    def current_bytes(self) -> int:
        return self._stream.count if self._stream is not None else 0

    def _before_start(self) -> None:
        """Create the directory and open the first file.

        Raises :class:`RecordingError` when the directory cannot be written.
        """
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise RecordingError(self.directory, cannot_create(exc)) from exc
        if self.run_id is None:
            self.run_id = uuid.uuid4().hex
        recover_cut_files(self.directory, self._machine_id, self.settings.compression)
        self._guarded(lambda: self._open(self._now()))

    def submit(self, item: Item) -> None:
        """Queue ``item`` for writing; never blocks (a full queue drops and counts)."""
        if not self._overflow.put(self._queue.put_nowait, item):
            self.dropped += count(item)

    def _after_stop(self) -> None:
        """Finish the file; the thread wrote what was queued (for at most :data:`DRAIN_S`)."""
        self._close_file()

    # --- recorder thread ---------------------------------------------------

    def _run(self) -> None:
        period_s = self.settings.flush_period_s
        while not self._stop.is_set():
            try:
                item = self._queue.get(timeout=min(0.1, period_s))
            except queue.Empty:
                pass
            else:
                self._write_guarded(item)
            if time.monotonic() - self._last_flush >= period_s:
                self._guarded(self._flush)
        deadline = time.monotonic() + DRAIN_S
        left = 0
        while True:
            try:
                item = self._queue.get_nowait()
            except queue.Empty:
                break
            if time.monotonic() < deadline:
                self._write_guarded(item)
            else:
                left += count(item)
        if left:
            self.dropped += left
            logger.error("%d items not written: closing took longer than %.1f s", left, DRAIN_S)

    def _write_guarded(self, item: Item) -> None:
        try:
            self._write(item)
        except Exception:  # noqa: BLE001 -- one bad item must not stop the recording
            self.failed_items += 1
            if self.failed_items == 1:
                logger.exception("skipping an item the recorder cannot write (counting them)")

    def _write(self, item: Item) -> None:
        if isinstance(item, RecordBatch):
            item = EncodedBatch.of(item)
        if not self._ready(item):
            if isinstance(item, RecordingGap):  # its items go into the write error's gap
                self._dropped_at_stop -= item.dropped
            else:
                self.dropped += count(item)
            return
        if isinstance(item, EncodedBatch) and item.frame_count:
            # A batch spanning the file's duration: its later frames begin the next file.
            head, tail = item.split(self._rotation_t_s(item.first_t_s))
            if head.frame_count and tail.frame_count:
                self._write_to_file(head)
                self._write(tail)
                return
        self._write_to_file(item)

    def _ready(self, item: Item) -> bool:
        """A file to write ``item`` to: (re)opened after an error, rotated when due."""
        if self._file is None:
            if time.monotonic() < self._retry_at or not self._guarded(
                lambda: self._open(self._now())
            ):
                return False
        # Frame time drives rotation; bus events carry wall-clock time.
        first_t_s = _first_frame_t_s(item)
        if first_t_s is not None and self._due_for_rotation(first_t_s):
            self._close_file()
            return self._guarded(lambda: self._open(self._now()))
        return True

    def _write_to_file(self, item: Item) -> None:
        mcap = self._file
        assert mcap is not None
        if isinstance(item, RecordBatch | EncodedBatch):
            self._guarded(lambda: mcap.write_batch(item))
        elif isinstance(item, TruthRecord):
            sample = truth_payload(item)
            if sample is None:
                self.rejected += 1
                if self.rejected == 1:
                    logger.warning("skipping a truth sample that is not valid (counting them)")
                return
            self._guarded(lambda: mcap.write_truth(sample))
        elif isinstance(item, MachineSnapshot):
            self._guarded(lambda: mcap.write_ground(item))
        elif isinstance(item, RecordingGap):
            if self._guarded(lambda: mcap.write_gap(item)):
                self._count_gap(item.stopped_t_s, item.lost_s)
        else:
            self._guarded(lambda: mcap.write_event(item))

    def _due_for_rotation(self, t_s: float) -> bool:
        mcap, stream = self._file, self._stream
        if mcap is None or stream is None or mcap.message_count == 0:
            return False
        return stream.count >= self.settings.max_bytes or t_s >= self._rotation_t_s(t_s)

    def _rotation_t_s(self, t_s: float) -> float:
        """The frame time from which frames go into the next file (``t_s``: the first
        frame to write, which begins the file when the file is empty)."""
        mcap = self._file
        first_ns = mcap.first_log_time_ns if mcap is not None else None
        return (t_s if first_ns is None else first_ns / 1e9) + self.settings.max_duration_s

    def _guarded(self, action: Callable[[], object]) -> bool:
        """Run a file operation; a write error stops recording until a retry succeeds."""
        try:
            action()
        except (OSError, RecordingError) as exc:
            path = self.current_path  # before the file is abandoned
            self.errors += 1
            self._retry_at = time.monotonic() + RETRY_AFTER_S
            stopping = self.stopped_t_s is None
            if stopping:
                self.stopped_t_s = self._now()
                self._dropped_at_stop = self.dropped
            lost = self._abandon_file()  # counted as dropped, in this gap
            if stopping:
                logger.error(
                    "recording stopped: %s; %d items lost from the file; "
                    "check free space and the rights on %s; retrying every %.0f s",
                    _one_line(exc, path),
                    lost,
                    self.directory,
                    RETRY_AFTER_S,
                )
            return False
        return True

    def _flush(self) -> None:
        self._last_flush = time.monotonic()
        mcap, stream = self._file, self._stream
        if mcap is not None and stream is not None:
            mcap.flush()
            if stream.deleted:  # writing on would lose everything, unseen
                mcap.lost()
                raise RecordingError(self.paths[-1], "deleted while it was being written")

    def _open(self, t_s: float) -> None:
        try:  # a directory removed while recording is made again
            self.directory.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise RecordingError(self.directory, cannot_create(exc)) from exc
        path = self.directory / file_name(self._machine_id, t_s)
        serial = 0
        while path in self.paths or path.exists():
            serial += 1
            path = path.with_name(f"{file_name(self._machine_id, t_s)[:-5]}_{serial}.mcap")
        try:
            raw = open(path, "xb", buffering=0)  # noqa: SIM115 (closed in _close_file)
        except OSError as exc:
            raise RecordingError(path, f"cannot create it: {exc.strerror or exc}") from exc
        hold_while_writing(raw, path)
        stream = CountingFile(raw)
        mcap = McapFile(
            stream,
            self._database,
            decoded_units=self._decoded_units,
            compression=self.settings.compression,
            chunk_size=self.settings.chunk_size,
            pause=GilYield() if self._shares_gil else lambda: None,
        )
        assert self.run_id is not None  # drawn in _before_start
        run = run_metadata(self._machine_id, self.run_id, self._files_created)
        try:
            mcap.start(self._attachments, t_s, run)
            if self.stopped_t_s is not None:
                mcap.write_gap(self._gap(t_s))
            mcap.flush()  # header, attachments and gap on disk now, or the error now
        except BaseException:
            stream.close()
            path.unlink(missing_ok=True)  # no empty file per retry (and no index taken)
            raise
        self._files_created += 1
        self._file, self._stream = mcap, stream
        self._last_flush = time.monotonic()
        self.paths.append(path)
        if self.stopped_t_s is not None:
            lost_s = t_s - self.stopped_t_s
            self._count_gap(self.stopped_t_s, lost_s)
            logger.warning(
                "recording resumed in %s: %.1f s lost (%d items dropped)",
                path,
                lost_s,
                self.dropped - self._dropped_at_stop,
            )
            self.stopped_t_s = None
        else:
            logger.info("recording to %s", path)

    def _count_gap(self, stopped_t_s: float, lost_s: float) -> None:
        self.gaps.append((stopped_t_s, lost_s))
        self.gap_count += 1
        self.lost_s += lost_s

    def _gap(self, t_s: float) -> RecordingGap:
        stopped_t_s = self.stopped_t_s if self.stopped_t_s is not None else t_s
        return RecordingGap(
            stopped_t_s=stopped_t_s,
            resumed_t_s=t_s,
            dropped=self.dropped - self._dropped_at_stop,
        )

    def _close_file(self) -> None:
        mcap, stream = self._file, self._stream
        self._file = self._stream = None
        if mcap is None or stream is None:
            return
        path = self.paths[-1]
        try:
            mcap.close()
        except Exception as exc:  # noqa: BLE001 -- close runs on shutdown: log, never raise
            self._lose_unwritten(mcap, f"cannot finish {path}: {_one_line(exc)}")
        else:
            if stream.deleted:
                mcap.lost()
                self._lose_unwritten(mcap, f"{path} was deleted while it was being written")
        finally:
            stream.close()

    def _lose_unwritten(self, mcap: McapFile, what: str) -> None:
        """Count what ``mcap`` did not get onto the disk as dropped, with one line."""
        self.errors += 1
        self.dropped += mcap.unwritten
        logger.error("%s; %d items lost from the file", what, mcap.unwritten)

    def _abandon_file(self) -> int:
        """Give the file up after a write error; what the chunk it was building held
        is lost, and counted as dropped (returned)."""
        mcap, stream = self._file, self._stream
        self._file = self._stream = None
        lost = mcap.unwritten if mcap is not None else 0
        self.dropped += lost
        if stream is not None:
            try:
                stream.close()
            except OSError:
                pass
        return lost


def _first_frame_t_s(item: Item) -> float | None:
    """The frame time of a batch's first frame; None for anything else."""
    if isinstance(item, EncodedBatch) and item.frame_count:
        return item.first_t_s
    return None


def _one_line(exc: BaseException, path: Path | None = None) -> str:
    """An OS error as ``path: reason`` (errno text; ``path`` where the error names no
    file: a write's disk full said "No space left on device" alone), anything else as its
    first line."""
    if isinstance(exc, OSError) and exc.strerror:
        filename = exc.filename or path
        return f"{filename}: {exc.strerror}" if filename else exc.strerror
    return (str(exc).strip().splitlines() or [type(exc).__name__])[0]
