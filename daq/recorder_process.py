"""The recorder in a process of its own: MCAP writing off the GIL of the frames' thread.

Writing MCAP is pure Python (records, chunk indexes): in the service's process the
recorder's thread held the GIL up to ~0.7 ms at a time, the thread processing frames
waited, and that was the tail of the frame -> subscriber latency (paced 9,000
frames/s, bench/). :class:`RecorderProcess` runs a :class:`~daq.recorder.Recorder` in a
child process (``multiprocessing``, *spawn*: the Zenoh runtime's threads must not be
forked) and stands, for the service, in the recorder's place:

- :meth:`RecorderProcess.submit` never blocks. The item goes into a bounded
  ``multiprocessing`` queue (``[recording] queue_size`` items) whose feeder thread
  pickles it into a pipe; a full queue drops the item and counts it (a batch as its
  frames), and the next item put is preceded by the gap this left in the file
  (:class:`~daq.recorder.Overflow`). A :class:`~daq.mcap_file.RecordBatch` crosses as the
  :class:`~daq.mcap_file.EncodedBatch` the recorder writes (frames as one byte
  string: pickled ~20x faster than an object per frame).
- The child's recorder takes from that queue itself and shares its counters (dropped,
  errors, failing, ...), the current file and the gaps through shared memory, which
  the status reads without waiting on the child.
- The child ignores SIGINT, SIGTERM and SIGHUP (a terminal and systemd signal the whole
  group), blocked from its very start (:data:`GROUP_SIGNALS`: one landing while it
  imports, before it could ignore them, killed it with a traceback, and the service
  exited 1 as if the recorder could not start):
  :meth:`RecorderProcess.close` waits until the child has taken every item, then tells
  it to stop (a flag in shared memory: a ``multiprocessing.Event`` would wait forever
  on a child killed while waiting on it); it finishes the file (last chunk, summary) and
  exits. Items it never took (a child that died, or hung and was killed after
  :data:`JOIN_S`) are counted as dropped; a dead child makes the service not alive. A
  child whose parent died finishes its file and exits.
- The child runs at ``SCHED_IDLE``: any wake-up of the service's threads preempts it at
  once, and it writes in the CPU time they leave (on a machine of several cores, on
  another core). At nice +5 instead, on one CPU, a frame waited behind its writing: the
  paced p99 was 3.2 ms against 2.0 ms with the recorder in a thread; at ``SCHED_IDLE``
  1.5-2.2 against 1.6-3.5 ms (bench/, measured side by side). A CPU saturated by other
  work starves it: its queue takes up the slack, beyond it batches are dropped and counted.
  On close it is put back at ``SCHED_OTHER`` (the service's threads have stopped), so
  that such a CPU still lets it finish its file.
- Its log lines go to stderr with the service's level, as the service's own do (the
  journal takes them as the service's).
"""

import ctypes
import json
import logging
import multiprocessing
import os
import signal
import time
from collections import deque
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from multiprocessing.context import SpawnProcess
from pathlib import Path
from typing import Any

from cantools.database.can import Database

from daq.errors import RecordingError
from daq.mcap_file import EncodedBatch, RecordBatch
from daq.recorder import Item, Overflow, Recorder, count
from daq.service_config import RecordingSettings
from daq.subcommand import setup_logging

logger = logging.getLogger(__name__)

#: What a terminal (Ctrl-C, a hang-up) or systemd sends the whole process group: the
#: child ignores them, the service stops it (as multiprocessing's resource tracker, the child
#: inherits them blocked, so that none lands before it ignores them).
GROUP_SIGNALS = frozenset({signal.SIGINT, signal.SIGTERM, signal.SIGHUP})
#: How often the child shares its counters (and checks that its parent lives).
SHARE_PERIOD_S = 0.25
#: Longest wait for the child to open its first file.
START_TIMEOUT_S = 60.0
#: On close, the longest wait for the child to take what is queued, and again to finish.
JOIN_S = 3.0
#: Shared text (current file, files begun, gaps), bytes.
TEXT_BYTES = 64 * 1024
#: Of the gaps and of the files begun, the latest this many are shared.
_KEPT = 200

_CONTEXT = multiprocessing.get_context("spawn")
_NO_TEXT: dict[str, Any] = {"path": None, "paths": [], "gaps": [], "error": None}


class _Shared:
    """What the child shares with the service: counters and a text, each with one writer.

    The text (JSON of the current file, the gaps and a start error) is guarded by a
    sequence number, odd while it is being written; the counters are single numbers.
    """

    NUMBERS = (
        "state",  # 0 starting, 1 recording, -1 failed to start
        "taken",  # items taken from the queue
        "dropped",
        "errors",
        "failed_items",
        "rejected",
        "current_bytes",
        "failing",
        "gap_count",  # all of them: the text holds the latest _KEPT gaps only
        "lost_s",
        "writer_alive",
        "stop",  # set by the service: finish the file and end
        "text_version",
    )
    _INDEX = {name: at for at, name in enumerate(NUMBERS)}

    def __init__(self) -> None:
        self.numbers = _CONTEXT.RawArray(ctypes.c_double, len(self.NUMBERS))
        self.text = _CONTEXT.RawArray(ctypes.c_char, TEXT_BYTES)
        self._text_seen: tuple[float, dict[str, Any]] = (-1.0, _NO_TEXT)

    def __getstate__(self) -> dict[str, Any]:
        return {"numbers": self.numbers, "text": self.text}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.numbers, self.text = state["numbers"], state["text"]
        self._text_seen = (-1.0, _NO_TEXT)

    def get(self, name: str) -> float:
        return float(self.numbers[self._INDEX[name]])

    def set(self, name: str, value: float) -> None:
        self.numbers[self._INDEX[name]] = value

    def write_text(self, content: Mapping[str, Any]) -> None:
        data = json.dumps(content).encode()
        if len(data) >= TEXT_BYTES:  # long paths: the current one is what counts
            data = json.dumps({**content, "paths": content.get("paths", [])[-1:]}).encode()
        version = self.get("text_version")
        self.set("text_version", version + 1)
        self.text.raw = data[: TEXT_BYTES - 1] + b"\0"
        self.set("text_version", version + 2)

    def read_text(self) -> dict[str, Any]:
        """The text as last written completely (the previous one while it is rewritten)."""
        version = self.get("text_version")
        seen_version, seen = self._text_seen
        if version == seen_version or version % 2:
            return seen
        data = self.text.value
        if self.get("text_version") != version:
            return seen
        content: dict[str, Any] = json.loads(data) if data else seen
        self._text_seen = (version, content)
        return content


class _TakenCounter:
    """The child's side of the queue: counts what the recorder takes (for ``close``)."""

    def __init__(self, items: "multiprocessing.Queue[Item]", shared: _Shared) -> None:
        self._items = items
        self._shared = shared

    def put_nowait(self, item: Item) -> None:
        raise RuntimeError("the recorder's process only takes items")

    def get(self, block: bool = True, timeout: float | None = None) -> Item:
        item = self._items.get(block, timeout)
        self._shared.set("taken", self._shared.get("taken") + 1)
        return item

    def get_nowait(self) -> Item:
        return self.get(False)

    def qsize(self) -> int:
        return self._items.qsize()


class RecorderProcess:
    """A :class:`~daq.recorder.Recorder` in a child process, with the recorder's interface.

    The constructor starts nothing; :meth:`start` (or ``with``) starts the process and
    returns once it has opened its first file (raises :class:`RecordingError` when it
    cannot); :meth:`close` finishes the recording and ends the process.
    """

    def __init__(
        self,
        settings: RecordingSettings,
        database: Database,
        *,
        machine_id: str,
        attachments: Mapping[str, bytes] = {},
        decoded_units: Mapping[str, Mapping[str, str]] = {},
    ) -> None:
        if settings.directory is None:
            raise ValueError("settings.directory is None: recording is off")
        self.directory: Path = settings.directory
        self.settings = settings
        self._database = database
        self._machine_id = machine_id
        self._attachments = dict(attachments)
        self._decoded_units = {name: dict(units) for name, units in decoded_units.items()}
        self._items: multiprocessing.Queue[Item] | None = None
        self._shared: _Shared | None = None
        self._process: SpawnProcess | None = None
        self._submitted = 0
        #: What each item the child has not taken yet counts (for a child that dies).
        self._untaken: deque[int] = deque()
        self._dropped_here = 0
        self._overflow = Overflow()
        self._closed = False

    def __enter__(self) -> "RecorderProcess":
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    @property
    def pid(self) -> int | None:
        """The child's process ID (None before start)."""
        return self._process.pid if self._process is not None else None

    def start(self) -> None:
        """Start the child; return once it records. Raises :class:`RecordingError`."""
        if self._process is not None:
            return
        # Blocked when a child starts, they stay blocked in it: in the recorder's process
        # until it ignores them, in multiprocessing's resource tracker (started for the
        # queue's semaphores) for good, as it unblocks only SIGINT and SIGTERM (SIGHUP
        # killed it, and the service relaunched it with a traceback per semaphore). Twice:
        # the tracker's start unblocks SIGINT and SIGTERM in this thread.
        with _group_signals_blocked():
            self._items = _CONTEXT.Queue(maxsize=self.settings.queue_size)
            self._shared = shared = _Shared()
        self._process = _CONTEXT.Process(
            target=_child_main,
            name="recorder",
            args=(
                self.settings,
                self._database,
                self._machine_id,
                self._attachments,
                self._decoded_units,
                self._items,
                self._shared,
                logging.getLevelName(logging.getLogger("daq").getEffectiveLevel()),
            ),
            daemon=True,
        )
        with _group_signals_blocked():
            self._process.start()
        deadline = time.monotonic() + START_TIMEOUT_S
        while shared.get("state") == 0:
            if not self._process.is_alive() or time.monotonic() > deadline:
                self._process.kill()
                self._process.join()
                raise RecordingError(
                    self.directory,
                    f"the recorder's process did not start (exit code {self._process.exitcode})",
                )
            time.sleep(0.01)
        if shared.get("state") < 0:
            self._process.join()
            error = shared.read_text().get("error") or "unknown error"
            raise RecordingError(self.directory, error)

    def submit(self, item: Item) -> None:
        """Queue ``item`` for the child; never blocks (a full queue drops and counts)."""
        if self._items is None or self._closed:
            self._dropped_here += count(item)
            return
        if isinstance(item, RecordBatch):
            item = EncodedBatch.of(item)
        if not self._overflow.put(self._put, item):
            self._dropped_here += count(item)

    def _put(self, item: Item) -> None:
        assert self._items is not None  # started
        self._items.put_nowait(item)
        self._submitted += 1
        self._untaken.append(count(item))
        self._forget_taken()

    def _forget_taken(self) -> None:
        untaken = self._untaken
        while len(untaken) > self.depth:
            untaken.popleft()

    def close(self) -> None:
        """Let the child take what is queued, finish its file and end. Idempotent."""
        process, items, shared = self._process, self._items, self._shared
        if self._closed or process is None or items is None or shared is None:
            return
        self._closed = True
        if process.pid is not None:
            _leave_idle(process.pid)
        deadline = time.monotonic() + JOIN_S
        while self.depth and time.monotonic() < deadline:
            if not process.is_alive():
                break
            time.sleep(0.005)
        # A flag, not a multiprocessing Event: setting an Event waits for the child's
        # acknowledgement, forever if the child was killed while waiting on it.
        shared.set("stop", 1.0)
        process.join(JOIN_S)
        if process.is_alive():
            logger.error("the recorder's process did not finish in %.0f s: killed", JOIN_S)
            process.kill()
            process.join()
        self._forget_taken()
        if self._untaken:
            lost = sum(self._untaken)
            self._dropped_here += lost
            self._untaken.clear()
            logger.error("%d frames and items never written: the recorder's process ended", lost)
        items.cancel_join_thread()  # whatever is left has been counted
        items.close()

    # --- the recorder's interface, for the service's status ----------------

    def _number(self, name: str) -> float:
        return 0.0 if self._shared is None else self._shared.get(name)

    def _text(self) -> dict[str, Any]:
        return _NO_TEXT if self._shared is None else self._shared.read_text()

    @property
    def alive(self) -> bool:
        process = self._process
        return process is not None and process.is_alive() and self._number("writer_alive") > 0

    @property
    def depth(self) -> int:
        return self._submitted - int(self._number("taken"))

    @property
    def dropped(self) -> int:
        return self._dropped_here + int(self._number("dropped"))

    @property
    def errors(self) -> int:
        return int(self._number("errors"))

    @property
    def failed_items(self) -> int:
        return int(self._number("failed_items"))

    @property
    def rejected(self) -> int:
        return int(self._number("rejected"))

    @property
    def failing(self) -> bool:
        return self._number("failing") > 0

    @property
    def current_bytes(self) -> int:
        return int(self._number("current_bytes"))

    @property
    def current_path(self) -> Path | None:
        path = self._text().get("path")
        return Path(path) if path else None

    @property
    def paths(self) -> list[Path]:
        """The files begun (the latest :data:`_KEPT`)."""
        return [Path(path) for path in self._text().get("paths", [])]

    @property
    def gaps(self) -> list[tuple[float, float]]:
        """The latest :data:`_KEPT` gaps."""
        return [(stopped, lost) for stopped, lost in self._text().get("gaps", [])]

    @property
    def gap_count(self) -> int:
        """Every gap since the start (:attr:`gaps` holds the latest only)."""
        return int(self._number("gap_count"))

    @property
    def lost_s(self) -> float:
        return self._number("lost_s")


def _leave_idle(pid: int) -> None:
    """Every thread of process ``pid`` back at the normal policy (``SCHED_OTHER``).

    On close the service's threads have stopped: the child no longer has to leave them the
    CPU. Left at ``SCHED_IDLE`` on a CPU that other work saturates, it got ~1 % of a core,
    took seconds to take what was queued and finish its file, and was killed after
    :data:`JOIN_S` (the file cut, the items lost; a SIGTERM'd service took 4.7 s to stop,
    systemd kills at 5 s). Leaving ``SCHED_IDLE`` needs an ``RLIMIT_NICE`` of 20 (the
    unit's ``LimitNICE=+0``) or CAP_SYS_NICE; without, the child stays idle (logged).
    """
    try:
        threads = [int(tid) for tid in os.listdir(f"/proc/{pid}/task")]
    except OSError:  # gone, or no /proc: nothing to do
        return
    for tid in threads:
        try:
            os.sched_setscheduler(tid, os.SCHED_OTHER, os.sched_param(0))
        except ProcessLookupError:  # that thread ended meanwhile
            continue
        except OSError as exc:
            logger.info(
                "the recorder's process finishes its file at SCHED_IDLE: %s (LimitNICE=+0 "
                "lets it leave)",
                exc.strerror,
            )
            return


@contextmanager
def _group_signals_blocked() -> Iterator[None]:
    """:data:`GROUP_SIGNALS` blocked in this thread (and in a child started meanwhile)."""
    blocked = signal.pthread_sigmask(signal.SIG_BLOCK, GROUP_SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, blocked)


def _child_main(
    settings: RecordingSettings,
    database: Database,
    machine_id: str,
    attachments: Mapping[str, bytes],
    decoded_units: Mapping[str, Mapping[str, str]],
    items: "multiprocessing.Queue[Item]",
    shared: _Shared,
    log_level: str,
) -> None:
    """The child process: records what comes through ``items`` until the ``stop`` flag."""
    for signum in GROUP_SIGNALS:
        signal.signal(signum, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, GROUP_SIGNALS)  # those pending are dropped
    setup_logging(log_level)
    try:
        os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))
    except OSError as exc:  # e.g. a seccomp filter: frames may wait longer, nothing lost
        logger.warning("the recorder's process could not take SCHED_IDLE: %s", exc.strerror)
    recorder = Recorder(
        settings,
        database,
        machine_id=machine_id,
        attachments=attachments,
        decoded_units=decoded_units,
        items=_TakenCounter(items, shared),
    )
    try:
        recorder.start()
    except RecordingError as exc:
        shared.write_text({"error": exc.reason})
        shared.set("state", -1)
        return
    shared.set("state", 1)
    parent = multiprocessing.parent_process()
    text: dict[str, Any] = {}
    while True:
        text = _share(recorder, shared, text)
        time.sleep(SHARE_PERIOD_S)
        if shared.get("stop"):
            break
        if parent is not None and not parent.is_alive():
            logger.error("the service ended without stopping the recorder: finishing the file")
            break
    recorder.close()
    _share(recorder, shared, text)


def _share(recorder: Recorder, shared: _Shared, text: dict[str, Any]) -> dict[str, Any]:
    """Publish the recorder's counters, and its text when it changed; the text shared."""
    shared.set("writer_alive", 1.0 if recorder.alive else 0.0)
    shared.set("dropped", recorder.dropped)
    shared.set("errors", recorder.errors)
    shared.set("failed_items", recorder.failed_items)
    shared.set("rejected", recorder.rejected)
    shared.set("current_bytes", recorder.current_bytes)
    shared.set("failing", 1.0 if recorder.failing else 0.0)
    shared.set("gap_count", recorder.gap_count)
    shared.set("lost_s", recorder.lost_s)
    path = recorder.current_path
    now = {
        "path": str(path) if path else None,
        "paths": [str(begun) for begun in recorder.paths[-_KEPT:]],
        "gaps": recorder.gaps[-_KEPT:],
        "error": None,
    }
    if now != text:
        shared.write_text(now)
    return now
