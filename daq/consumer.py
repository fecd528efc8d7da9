"""The consumer thread: the one place where frames are decoded and estimated.

It takes frames and bus events from the reader's queue, runs each frame
through the :class:`~daq.pipeline.Pipeline`, and hands the results to the
publisher and the recorder through their own bounded queues (``submit`` never
blocks). It owns the estimator, so it also builds the timed messages: the
all-legs ground message at ``ground_rate_hz`` and the soil metrics every
``status_period_s``.
"""

import logging
import math
import queue
import time
from collections.abc import Callable
from typing import Protocol

from daq import payloads
from daq._worker import Worker
from daq.frames import BusEvent, RawFrame
from daq.pipeline import FrameResult, Pipeline
from daq.service_config import PublishSettings
from estimator.machine import MachineSnapshot

logger = logging.getLogger(__name__)

#: On close, queued frames are still processed for at most this long.
DRAIN_S = 0.5

#: Staleness is judged against the bus, not the wall clock: a leg is stale when newer
#: frames of other messages went by without its own (the estimator's bus time, see
#: :mod:`estimator.machine`), or, on a silent bus, when the monotonic clock has run
#: this much past the moment the latest frame was handled. Processing that lags the
#: bus by less than this (a slow moment, a burst) therefore never makes fresh legs
#: "stale", and a wall clock stepped back or forward changes nothing.
LAG_TOLERANCE_S = 0.5


class Publisher(Protocol):
    def submit(self, suffix: str, payload: payloads.JsonObject) -> None: ...


class Recording(Protocol):
    def submit(self, item: FrameResult | BusEvent | MachineSnapshot) -> None: ...


class Consumer(Worker):
    """Drains ``inbox`` in a thread of its own; the constructor starts nothing.

    ``close`` processes what is queued (for at most :data:`DRAIN_S`) and stops.
    """

    thread_name = "consumer"

    def __init__(
        self,
        pipeline: Pipeline,
        inbox: "queue.Queue[RawFrame | BusEvent]",
        settings: PublishSettings,
        *,
        publisher: Publisher | None = None,
        recorder: Recording | None = None,
        now: Callable[[], float] = time.time,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        super().__init__()
        self.pipeline = pipeline
        self._inbox = inbox
        self._settings = settings
        self._publisher = publisher
        self._recorder = recorder
        #: ``/ground`` snapshots are taken at the publish rate for the publisher and
        #: the recorder.
        self._snapshots = publisher is not None or recorder is not None
        self._now = now
        self._monotonic = monotonic
        #: ``monotonic()`` when the latest frame was handled.
        self._latest_handled_s = float("nan")
        #: time.monotonic() of the thread's last loop turn (for the watchdog).
        self.heartbeat = time.monotonic()
        #: Bus events seen that reset the rolling counters.
        self.resets = 0

    def handle(self, item: RawFrame | BusEvent) -> FrameResult | None:
        """Process one item (the thread's work; callable directly in tests)."""
        if isinstance(item, BusEvent):
            if item.reset_counters:
                self.pipeline.reset_counters()
                self.resets += 1
            if self._recorder is not None:
                self._recorder.submit(item)
            return None
        result = self.pipeline.process(item)
        self._latest_handled_s = self._monotonic()
        if self._recorder is not None:
            self._recorder.submit(result)
        publisher = self._publisher
        if publisher is not None:
            for estimate in result.estimates:
                publisher.submit(f"leg/{estimate.leg}/ground", payloads.leg_ground(estimate))
            if self._settings.signals and result.decoded is not None:
                publisher.submit(
                    f"signals/{result.decoded.message}", payloads.signals(result.decoded)
                )
        return result

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
        next_ground = next_metrics = time.monotonic()
        timeout_s = min(0.1, ground_period_s)
        while True:
            self.heartbeat = now = time.monotonic()
            if self._snapshots and now >= next_ground:
                next_ground = max(next_ground + ground_period_s, now)
                snapshot = self.pipeline.snapshot(self.judged_at())
                if self._publisher is not None:
                    self._publisher.submit("ground", payloads.machine_ground(snapshot))
                if self._recorder is not None:
                    self._recorder.submit(snapshot)
            if self._publisher is not None and now >= next_metrics:
                next_metrics = max(next_metrics + metrics_period_s, now)
                metrics = payloads.soil_metrics(self._now(), self.pipeline.metrics())
                self._publisher.submit("metrics", metrics)
            if self._stop.is_set():
                break
            wait_s = timeout_s
            if self._snapshots:
                wait_s = max(0.0, min(timeout_s, next_ground - time.monotonic()))
            try:
                item = self._inbox.get(timeout=wait_s)
            except queue.Empty:
                continue
            self._handle_guarded(item)
        deadline = time.monotonic() + DRAIN_S
        while time.monotonic() < deadline:
            try:
                item = self._inbox.get_nowait()
            except queue.Empty:
                break
            self._handle_guarded(item)

    def _handle_guarded(self, item: RawFrame | BusEvent) -> None:
        try:
            self.handle(item)
        except Exception:  # noqa: BLE001 -- a bug on one frame must not stop the service
            self.pipeline.bad["internal_error"] += 1
            logger.exception("processing %r failed", item)
