"""The consumer thread: the one place where frames are decoded and estimated.

It takes frames and bus events from the reader's queue, everything queued in one go
(at most :data:`~daq.can_batch.MAX_FRAMES`), runs each frame through the
:class:`~daq.pipeline.Pipeline`, and hands the results on through bounded queues
(``submit`` never blocks): to the recorder one :class:`~daq.mcap_file.RecordBatch`
per run of frames (a bus event between frames is handed on in its place), to the
publisher, as one batch, each leg estimate (JSON encoded once, the same bytes the
recorder writes) and the decoded signals of each message (of each J1939 sender) at
most ``[publish] signals_max_rate_hz`` (by frame time). It owns the estimator, so it
also builds the timed messages: the all-legs ground message at ``ground_rate_hz`` and
the soil metrics every ``status_period_s``.

With a poll period (``[service] poll_period_ms``), a wake-up that took something is
followed by a hold: the source is not polled again until the period has passed since
that wake-up, so what arrives meanwhile waits where it is (the kernel's receive
buffer, the reader's queue) and comes in one go. Each wake-up costs tens of
microseconds however few frames it carries (cold caches, the hand-offs to the
publisher's thread and Zenoh's), so at the DBC's rate, a frame or two per wake-up,
fewer wake-ups are most of the CPU saved (bench/). The timers above still run on
time during a hold, ``close`` ends it at once, and a quiet bus costs nothing more:
without frames the source is waited on as before.
"""

import logging
import math
import queue
import time
from collections.abc import Callable, Sequence
from typing import Protocol

from daq import payloads
from daq._worker import Worker
from daq.can_batch import MAX_FRAMES
from daq.frames import BusEvent, RawFrame
from daq.mcap_file import RecordBatch, decoded_frames, encoded_estimates
from daq.pipeline import Pipeline
from daq.service_config import PublishSettings
from dbc.decoding import DecodedFrame
from estimator.machine import MachineSnapshot

logger = logging.getLogger(__name__)

#: On close, queued frames are still processed for at most this long.
DRAIN_S = 0.5
#: The recorder is handed what was processed at most this often (a frame's batch
#: waits at most this long): one hand-off per period, not per wake-up, however the
#: frames trickle in (at the DBC's rate one wake-up carries a frame or two). The
#: default ground period: the batch goes with the ``/ground`` snapshot, one wake-up of
#: the recorder's process for both (at 50 ms it cost ~16 us per frame at the DBC's rate).
RECORD_PERIOD_S = 0.1
#: ... or once this many frames wait (a saturated bus's 9,000 frames/s: every ~28 ms).
#: Handing over is work in the frames' thread (joining the batches, encoding the frames
#: for the recorder's process) that delays the frames behind it: ~1 ms for 0.1 s of a
#: saturated bus, when the period alone set the size; at most a quarter of that now.
HAND_OVER_FRAMES = 256

#: Staleness is judged against the bus, not the wall clock: a leg is stale when newer
#: frames of other messages went by without its own (the estimator's bus time, see
#: :mod:`estimator.machine`), or, on a silent bus, when the monotonic clock has run
#: this much past the moment the latest frame was handled. Processing that lags the
#: bus by less than this (a slow moment, a burst) therefore never makes fresh legs
#: "stale", and a wall clock stepped back or forward changes nothing.
LAG_TOLERANCE_S = 0.5


class Publisher(Protocol):
    def submit(self, suffix: str, payload: payloads.JsonObject | bytes) -> None: ...

    def submit_batch(self, messages: Sequence[tuple[str, payloads.JsonObject | bytes]]) -> None: ...


class Recording(Protocol):
    def submit(self, item: RecordBatch | BusEvent | MachineSnapshot) -> None: ...


class Source(Protocol):
    """Where the frames come from: one call is one wake-up's worth (see :meth:`poll`)."""

    def poll(self, timeout_s: float) -> Sequence[RawFrame | BusEvent]:
        """What arrived within ``timeout_s``: everything there after the first item."""
        ...


class QueueSource:
    """The reader thread's queue as a :class:`Source`: waits for one item, then drains."""

    def __init__(self, inbox: "queue.Queue[RawFrame | BusEvent]") -> None:
        self._inbox = inbox

    def poll(self, timeout_s: float) -> list[RawFrame | BusEvent]:
        items: list[RawFrame | BusEvent] = []
        get = self._inbox.get_nowait
        try:
            items.append(self._inbox.get(timeout=timeout_s) if timeout_s > 0 else get())
            while len(items) < MAX_FRAMES:
                items.append(get())
        except queue.Empty:
            pass
        return items


class Consumer(Worker):
    """Polls ``source`` (a :class:`Source`, e.g. the bus reader in the event loop, or the
    reader thread's queue) in a thread of its own; the constructor starts nothing.

    ``poll_period_s`` > 0: after a wake-up that took something, the source is polled
    again only once that long has passed (the module docstring). ``close`` processes
    what is queued (for at most :data:`DRAIN_S`) and stops.
    """

    thread_name = "consumer"

    def __init__(
        self,
        pipeline: Pipeline,
        source: "Source | queue.Queue[RawFrame | BusEvent]",
        settings: PublishSettings,
        *,
        publisher: Publisher | None = None,
        recorder: Recording | None = None,
        record_signals: bool = False,
        poll_period_s: float = 0.0,
        now: Callable[[], float] = time.time,
        monotonic: Callable[[], float] = time.monotonic,
        wait: Callable[[float], object] | None = None,
    ) -> None:
        """``now``, ``monotonic`` and ``wait`` (for at most the given seconds, returning
        early once closing; the stop event's ``wait`` by default) are the clocks of the
        loop, passed in by tests."""
        super().__init__()
        self.pipeline = pipeline
        self._source = QueueSource(source) if isinstance(source, queue.Queue) else source
        self._settings = settings
        self._publisher = publisher
        self._recorder = recorder
        self._record_signals = record_signals
        #: ``/ground`` snapshots are taken at the publish rate for the publisher and
        #: the recorder.
        self._snapshots = publisher is not None or recorder is not None
        self._now = now
        rate_hz = settings.signals_max_rate_hz
        self._signals_period_s = 1.0 / rate_hz if rate_hz > 0 else 0.0
        #: Frame time of the signals last published, by message, J1939 sender and
        #: multiplexer values (None: not multiplexed).
        self._signals_published_t_s: dict[
            tuple[str, int | None, tuple[object, ...] | None], float
        ] = {}
        self._multiplexers = pipeline.decoder.multiplexers
        self._monotonic = monotonic
        self._wait = self._stop.wait if wait is None else wait
        #: After a wake-up that took something, the source is not polled for this long.
        self._poll_period_s = poll_period_s
        #: ``monotonic()`` when the latest frame was handled.
        self._latest_handled_s = float("nan")
        #: time.monotonic() of the thread's last loop turn (for the watchdog).
        self.heartbeat = time.monotonic()
        #: Bus events seen that reset the rolling counters.
        self.resets = 0
        #: Batches processed but not yet handed to the recorder, and when they are due.
        self._unrecorded: list[RecordBatch] = []
        self._unrecorded_frames = 0
        self._record_due = float("inf")

    def handle(self, item: RawFrame | BusEvent) -> None:
        """Process one item (callable directly in tests)."""
        self.handle_batch((item,))

    def handle_batch(self, items: Sequence[RawFrame | BusEvent]) -> None:
        """Process what was taken from the queue in one go (the thread's work): each run
        of frames is one batch, events keep their place."""
        start = 0
        for at, item in enumerate(items):
            if isinstance(item, BusEvent):
                self._frames(items[start:at])  # type: ignore[arg-type]  # frames only
                self._event(item)
                start = at + 1
        self._frames(items[start:])  # type: ignore[arg-type]

    def _event(self, event: BusEvent) -> None:
        if event.reset_counters:
            self.pipeline.reset_counters()
            self.resets += 1
        if self._recorder is not None:
            self._hand_over()
            self._recorder.submit(event)

    def _hand_over(self) -> None:
        """Hand the recorder what was processed since the last time, as one batch."""
        batches = self._unrecorded
        if self._recorder is None or not batches:
            return
        self._unrecorded = []
        self._unrecorded_frames = 0
        self._record_due = float("inf")
        if len(batches) == 1:
            self._recorder.submit(batches[0])
            return
        self._recorder.submit(
            RecordBatch(
                [frame for batch in batches for frame in batch.frames],
                [estimate for batch in batches for estimate in batch.estimates],
                [decoded for batch in batches for decoded in batch.decoded],
            )
        )

    def _frames(self, frames: Sequence[RawFrame]) -> None:
        if not frames:
            return
        process = self.pipeline.process
        results = [process(frame) for frame in frames]
        self._latest_handled_s = handled_s = self._monotonic()
        publisher = self._publisher
        signals = publisher is not None and self._settings.signals
        estimates: list[tuple[str, float, bytes]] = []
        messages: list[tuple[str, payloads.JsonObject | bytes]] = []
        for result in results:  # each frame's messages in its place: signals not last
            if result.estimates:
                encoded = encoded_estimates(result)
                estimates += encoded
                messages += [(f"leg/{leg}/ground", data) for leg, _, data in encoded]
            if signals and result.decoded is not None and self._signals_due(result.decoded):
                message = result.decoded.message
                messages.append((f"signals/{message}", payloads.signals(result.decoded)))
        if publisher is not None:
            publisher.submit_batch(messages)
        if self._recorder is None:
            return
        decoded = decoded_frames(results) if self._record_signals else ()
        if not self._unrecorded:
            self._record_due = handled_s + RECORD_PERIOD_S
        self._unrecorded.append(RecordBatch(frames, estimates, decoded))
        self._unrecorded_frames += len(frames)
        if self._unrecorded_frames >= HAND_OVER_FRAMES or handled_s >= self._record_due:
            self._hand_over()

    def _signals_due(self, decoded: DecodedFrame) -> bool:
        """At most one frame's signals per ``signals_max_rate_hz`` (by frame time) for each
        message, sender and page: J1939 transducers sharing a PGN, and a hub's multiplexer
        values, each get their share (one would hide the others on a dashboard). A frame
        time before the last one published (the clock stepped back) is due at once: the
        message's signals went out again only once frame times passed that one, an hour
        after a step back of an hour."""
        multiplexers = self._multiplexers.get(decoded.message)
        page = None
        if multiplexers is not None:
            page = tuple(decoded.signals.get(name) for name in multiplexers)
        key = (decoded.message, decoded.source_address, page)
        since_s = decoded.t_s - self._signals_published_t_s.get(key, float("-inf"))
        if 0.0 <= since_s < self._signals_period_s:
            return False
        self._signals_published_t_s[key] = decoded.t_s
        return True

    def judged_at(self) -> float:
        """The time, on the frames' clock, at which legs are judged stale: the latest
        frame's time, plus the silence since it beyond :data:`LAG_TOLERANCE_S` measured
        on the monotonic clock; the wall clock before the first frame."""
        latest_t_s = self.pipeline.latest_t_s
        if math.isnan(latest_t_s):
            return self._now()
        silence_s = self._monotonic() - self._latest_handled_s - LAG_TOLERANCE_S
        return latest_t_s + max(0.0, silence_s)

    def _run(self) -> None:
        ground_period_s = 1.0 / self._settings.ground_rate_hz
        metrics_period_s = self._settings.status_period_s
        monotonic = self._monotonic
        next_ground = next_metrics = monotonic()
        timeout_s = min(0.1, ground_period_s)
        # The source is polled again not before this (the hold after a wake-up).
        poll_at = -math.inf
        while True:
            self.heartbeat = time.monotonic()
            now = monotonic()
            if self._snapshots and now >= next_ground:
                next_ground = max(next_ground + ground_period_s, now)
                snapshot = self.pipeline.snapshot(self.judged_at())
                if self._publisher is not None:
                    self._publisher.submit("ground", payloads.machine_ground(snapshot))
                if self._recorder is not None:
                    self._hand_over()  # the frames before it, first
                    self._recorder.submit(snapshot)
            if self._publisher is not None and now >= next_metrics:
                next_metrics = max(next_metrics + metrics_period_s, now)
                metrics = payloads.soil_metrics(self._now(), self.pipeline.metrics())
                self._publisher.submit("metrics", metrics)
            if now >= self._record_due:
                self._hand_over()
            if self._stop.is_set():
                break
            wait_s = min(timeout_s, self._record_due - now)
            if self._snapshots:
                wait_s = min(wait_s, next_ground - now)
            if now < poll_at:  # holding: what arrives waits in the source
                self._wait(min(wait_s, poll_at - now))
                continue
            wait_s = max(0.0, wait_s - (monotonic() - now))
            items = self._source.poll(wait_s)
            # A wake-up cut at MAX_FRAMES left frames waiting: no hold then.
            if items and self._poll_period_s > 0 and len(items) < MAX_FRAMES:
                poll_at = monotonic() + self._poll_period_s
            self._handle_guarded(items)
        deadline = monotonic() + DRAIN_S
        while monotonic() < deadline:
            items = self._source.poll(0.0)
            if not items:
                break
            self._handle_guarded(items)
        self._hand_over()

    def _handle_guarded(self, items: Sequence[RawFrame | BusEvent]) -> None:
        if not items:
            return
        try:
            self.handle_batch(items)
        except Exception:  # noqa: BLE001 -- a bug on one frame must not stop the service
            # The batch's frames are neither published nor recorded: each is lost (one,
            # counted as 1 for the batch, was 4,096 at most: under a full load).
            frames = sum(isinstance(item, RawFrame) for item in items)
            self.pipeline.bad["internal_error"] += frames or 1
            logger.exception(
                "processing a batch of %d items failed: its %d frames are lost", len(items), frames
            )
