"""The DAQ service: reader, consumer, publisher and recorder wired together, and its main loop.

Everything that touches the outside is passed in: a factory that opens the CAN
bus, the Zenoh session, the recorder and the systemd notifier (built in
``daq.__main__``; in tests a python-can ``virtual`` bus, a loopback Zenoh
session and a temporary directory). Data path, as an event loop (``[service]
event_loop = true``, the default): one thread polls the bus and processes what came
in one go; the publisher (which may wait on a congested link) is handed what to put
through its bounded queue, the recorder (a process of its own) a batch every 0.1 s::

    bus --recv until none--> Consumer (BusReader.poll, Pipeline) --queue--> ZenohPublisher
                                 \\--queue--> Recorder (MCAP)

With ``event_loop = false`` the reader has a thread of its own too::

    bus --recv--> BusReader --queue--> Consumer (Pipeline) --queue--> ZenohPublisher
                                                         \\--queue--> Recorder (MCAP)
    Zenoh <prefix>/sim/truth --> TruthSubscriber --queue--> Recorder (/sim/truth)

:meth:`Service.run` is the main thread's loop: READY=1 once the bus is open
(the session is open before the service exists), ``<prefix>/status`` and
STATUS= every ``status_period_s``, WATCHDOG=1 while the service is healthy,
STOPPING=1 when ``stop`` is set, then a clean shutdown.

Alive, for the watchdog (:meth:`Service.alive`): every thread alive and each of the
reader, consumer and publisher loops turned within :data:`HEARTBEAT_MAX_AGE_S`. The
reader's loop turns at least every receive timeout (0.1 s) even on a quiet
bus, and while the bus is down or being reopened (the service repairs that
itself, so a restart by systemd would not help); the consumer's loop turns at
least every 0.1 s, and stops turning only when it hangs on a frame.

Healthy, on the status topic and STATUS= (:func:`problems`): alive, the bus neither down
nor absent, and during the last status period the recorder was recording, nothing was
lost anywhere (every key of ``dropped``, ``dropped.kernel`` and ``dropped.publish_failed``
included, ``bad.internal_error`` and ``recording.failed_items``: :func:`losses`), every
configured Zenoh ``connect`` endpoint was reached, no other service publishes under the
key prefix (:mod:`daq.prefix_owners`), and frames of the DBC came in (none
for a whole period, or for the legs' stale time when that is longer, is a problem).
``problems`` lists what is wrong, one short text each. None of these stops the watchdog
(a restart would not help).
"""

import logging
import math
import queue
import re
import time
from collections.abc import Callable, Mapping

import zenoh

from daq.bus_reader import BusFactory, BusReader, LinkProbe
from daq.consumer import Consumer
from daq.frames import BUS_ABSENT, BUS_DOWN, BusEvent, RawFrame
from daq.leg_restarts import warn_restarting_legs
from daq.payloads import JsonObject
from daq.pipeline import Pipeline, decoded_frames
from daq.prefix_owners import PrefixOwners
from daq.publisher import ZenohPublisher
from daq.recorder import Recorder
from daq.recorder_process import RecorderProcess
from daq.schemas import signal_units
from daq.sd_notify import SdNotifier
from daq.service_config import ServiceConfig
from daq.sim_truth import TRUTH_KEY, TruthSubscriber
from daq.socketcan import RCVBUF_BYTES_PER_FRAME
from daq.stop_signal import Stop
from daq.zenoh_links import Outages, zenoh_status
from daq.zenoh_session import connect_endpoints

logger = logging.getLogger(__name__)

#: Numbers in a problem's text: a change of only those is not logged again (not the
#: digits of a name: legs A1 and A2 silent in turn are two events).
_NUMBER = re.compile(r"(?<![\w.])\d+(\.\d+)?")
#: A thread whose loop has not turned for this long is hung: no WATCHDOG=1.
HEARTBEAT_MAX_AGE_S = 2.0
#: A saturated 1 Mbit/s bus: an 8-byte standard frame takes up to ~111 us.
SATURATED_FRAMES_PER_S = 9000.0
#: Frames for this many status periods and no truth sample: said once (``[recording] truth``).
TRUTH_WAIT_PERIODS = 3
#: ``<prefix>/units`` answers a ``get`` with :func:`units`.
UNITS_KEY = "units"


def units(config: ServiceConfig) -> JsonObject:
    """What ``<prefix>/units`` answers: the unit each value of ``<prefix>/signals/<MESSAGE>``
    is in, by message and signal (Pa for every pressure the decoder converts, else the
    DBC's unit; ``""`` for none), so that a dashboard needs no DBC to label them."""
    decoded = config.machine.decoded_units
    return {
        "signals": {
            message.name: signal_units(message, decoded.get(message.name, {}))
            for message in config.database.messages
        }
    }


class Service:
    """The running service. The constructor opens nothing; :meth:`start` starts the threads."""

    def __init__(
        self,
        config: ServiceConfig,
        *,
        open_bus: BusFactory,
        session: zenoh.Session,
        recorder: Recorder | RecorderProcess | None = None,
        notifier: SdNotifier | None = None,
        link_up: LinkProbe | None = None,
        now: Callable[[], float] = time.time,
    ) -> None:
        self.config = config
        self._now = now
        self.event_loop = event_loop = config.service.event_loop
        self.inbox: queue.Queue[RawFrame | BusEvent] = queue.Queue(maxsize=config.bus.queue_size)
        self.pipeline = Pipeline.from_config(config.machine, config.database)
        self.publisher = ZenohPublisher(
            session,
            config.zenoh.key_prefix,
            queue_size=config.publish.queue_size,
            answers={UNITS_KEY: units(config)},
        )
        self.recorder = recorder
        #: Records the simulator bridge's truth, if any is published (``[recording] truth``).
        self.truth: TruthSubscriber | None = None
        if recorder is not None and config.recording.truth:
            key = f"{config.zenoh.key_prefix}/{TRUTH_KEY}"
            self.truth = TruthSubscriber(session, key, recorder.submit)
        self.notifier = notifier or SdNotifier(None)
        self.reader = BusReader(
            open_bus,
            None if event_loop else self.inbox,
            channel=config.bus.channel,
            link_up=link_up,
            now=now,
            threaded=not event_loop,
        )
        self.consumer = Consumer(
            self.pipeline,
            self.reader if event_loop else self.inbox,
            config.publish,
            publisher=self.publisher,
            recorder=recorder,
            record_signals=config.recording.signals,
            poll_period_s=config.service.poll_period_s,
            now=now,
        )
        self.session = session
        #: Other services publishing under the same key prefix (one machine id twice).
        self.owners = PrefixOwners(session, config.zenoh.key_prefix)
        #: The endpoints the session connects to (``[zenoh] connect`` or the JSON5 file);
        #: a client is connected when it has a link to any one of them.
        self._zenoh_mode, self.connect = connect_endpoints(config.zenoh, config.source)
        self._connect_any_one = self._zenoh_mode == "client"
        #: Times they went unreached, and for how long.
        self._outages = Outages()
        #: No frame for this long is a problem: the legs' stale time (at least a period),
        #: and the poll period, for which frames wait in the socket before they are taken:
        #: without it, statuses between two wake-ups 250 ms apart said "no frame for 0.1 s".
        longest_cycle_s = max(
            (leg.cycle_time_s for leg in config.machine.legs.values()), default=0.0
        )
        self.silence_s = (
            max(
                config.publish.status_period_s,
                config.machine.estimator.stale_after_s(longest_cycle_s),
            )
            + config.service.poll_period_s
        )
        self._started_monotonic = time.monotonic()
        self._rate_mark = (time.monotonic(), 0)
        self._frames_per_s = 0.0
        #: When frames of the DBC (:func:`~daq.pipeline.decoded_frames`) last came in, and
        #: any frame at all (monotonic); their count at the previous status.
        self._last_frame_monotonic = self._last_heard_monotonic = time.monotonic()
        self._decoded_mark = 0
        #: Each leg's latest sample (bus time) at the previous status (:meth:`_silent_legs`).
        self._heard_at_mark: dict[str, float] = {}
        #: The pipeline's error frames by kind at the previous status: a rise is a problem.
        self._error_frames_mark: dict[str, int] = {}
        #: :func:`losses` at the previous status: what rose since is a problem.
        self._lost_mark: dict[str, int] = {}
        self._reported_problems: list[str] = []
        #: The kernel drop count at the previous status (for the log line of a rise).
        self._kernel_dropped_mark = 0
        #: When the first frame was seen (monotonic), for :meth:`_truth_missing`.
        self._first_frame_monotonic: float | None = None
        self._truth_warned = False
        #: The other services under the key prefix already told of.
        self._owners_told: set[str] = set()
        #: The legs told of restarting their filter at every sample (once each).
        self._restarting_told: set[str] = set()
        self._started = False
        self._closed = False

    def __enter__(self) -> "Service":
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def start(self) -> None:
        if self._started:
            return
        self._started = True
        self._started_monotonic = time.monotonic()
        self._rate_mark = (self._started_monotonic, 0)
        self.publisher.start()
        self.owners.start()
        if self.recorder is not None:
            self.recorder.start()
        if self.truth is not None:
            self.truth.start()
        self.consumer.start()
        self.reader.start()
        # Silence is judged from now: starting (the recorder's process takes ~0.5 s to
        # spawn) is no time a frame could have come in.
        self._last_frame_monotonic = self._last_heard_monotonic = time.monotonic()

    def close(self) -> None:
        """Stop receiving, drain the queues, finish the recording. Idempotent."""
        if self._closed:
            return
        self._closed = True
        if self.event_loop:  # the consumer's thread polls the reader: stop it first
            self.consumer.close()
            self.reader.close()
        else:
            self.reader.close()
            self.consumer.close()
        self.publisher.close()
        self.owners.close()
        if self.truth is not None:
            self.truth.close()
        if self.recorder is not None:
            self.recorder.close()

    def run(self, stop: Stop) -> None:
        """Start, then publish status and notify systemd until ``stop`` is set; then close."""
        notifier = self.notifier
        period_s = self.config.publish.status_period_s
        watchdog_period_s = min(period_s, (notifier.watchdog_s or math.inf) / 2)
        ready = False
        next_status = next_watchdog = time.monotonic()
        try:
            self.start()
            while not stop.is_set():
                now = time.monotonic()
                if not ready and self.reader.opened.is_set():
                    ready = True
                    notifier.ready()
                    logger.info("ready: CAN bus %s open", self.config.bus.channel)
                    overflow = hold_overflow(self.config, self.reader.rcvbuf_bytes)
                    if overflow:
                        logger.warning("%s", overflow)
                if now >= next_status:
                    next_status = max(next_status + period_s, now)
                    status = self.status()
                    self.publisher.submit("status", status)
                    if ready:  # systemd hears READY=1 first
                        notifier.status(status_line(status))
                if ready and now >= next_watchdog:
                    next_watchdog = max(next_watchdog + watchdog_period_s, now)
                    if self.alive():
                        notifier.watchdog()
                    else:
                        logger.error("a service thread hangs: no WATCHDOG=1 (%s)", self.threads())
                wake = min(next_status, next_watchdog if ready else now + 0.05)
                stop.wait(max(0.0, wake - time.monotonic()))
        finally:
            notifier.stopping()
            logger.info("stopping")
            self.close()

    def threads(self) -> dict[str, float | None]:
        """Age in seconds of each thread's last loop turn; None for a dead thread."""
        now = time.monotonic()
        consumer = (self.consumer.alive, self.consumer.heartbeat)
        parts = {
            "reader": (self.reader.alive, self.reader.heartbeat),
            "consumer": consumer,
            "publisher": (self.publisher.alive, self.publisher.heartbeat),
        }
        if self.event_loop:  # the reader runs in the consumer's thread
            parts["reader"] = consumer
        return {name: now - beat if alive else None for name, (alive, beat) in parts.items()}

    def alive(self) -> bool:
        """Every thread alive and turning its loop: the watchdog's WATCHDOG=1 condition."""
        recorder_ok = self.recorder is None or self.recorder.alive
        return recorder_ok and all(
            age is not None and age < HEARTBEAT_MAX_AGE_S for age in self.threads().values()
        )

    def status(self) -> JsonObject:
        """The ``<prefix>/status`` payload (call from one thread: it keeps the rate mark)."""
        now = time.monotonic()
        received = self.reader.received
        mark_t, mark_received = self._rate_mark
        if now - mark_t > 0:
            self._frames_per_s = (received - mark_received) / (now - mark_t)
        self._rate_mark = (now, received)
        if received != mark_received:
            self._last_heard_monotonic = now
            if self._first_frame_monotonic is None:
                self._first_frame_monotonic = now
        # Frames before their kinds: a frame counted in both is never taken for decoded.
        processed = self.pipeline.frames
        bad = dict(self.pipeline.bad)
        # Silence is of the DBC's frames: error frames of a bus-off controller or a
        # foreign peer's flood of unknown IDs are no sensor talking.
        decoded = decoded_for_sure(processed, bad)
        if decoded > self._decoded_mark:
            self._decoded_mark = decoded
            self._last_frame_monotonic = now
        self._truth_missing(now)
        warn_restarting_legs(self.pipeline, self._restarting_told)
        # Read once: the status must show the very count its health was judged on.
        kernel_dropped = self.reader.kernel_dropped
        self._kernel_losses(kernel_dropped)  # logs a rise; health: see problems()
        recorder = self.recorder
        status: JsonObject = {
            "t": self._now(),
            "uptime_s": now - self._started_monotonic,
            "bus": {
                "interface": self.config.bus.interface,
                "channel": self.config.bus.channel,
                "state": self.reader.state,
                "reason": self.reader.reason,
                "reopens": self.reader.reopens,
                "rcvbuf_bytes": self.reader.rcvbuf_bytes,
            },
            "frames_per_s": self._frames_per_s,
            # Lost before they reached the bus interface, as the rolling counters tell.
            "frames_lost": self.pipeline.frames_lost,
            "frames": {
                "received": received,
                "processed": processed,
                "unknown": bad.get("unknown_id", 0),
                "bad": sum(bad.values()),
                "dropped": self.reader.dropped + kernel_dropped,
            },
            "bad": bad,
            "queues": {
                "rx": self.inbox.qsize(),
                "publish": self.publisher.depth,
                "record": recorder.depth if recorder is not None else 0,
            },
            "dropped": {
                "kernel": kernel_dropped,
                "rx": self.reader.dropped,
                "publish": self.publisher.dropped,
                # Messages whose put failed (an error of Zenoh's): lost as surely.
                "publish_failed": self.publisher.errors,
                "record": recorder.dropped if recorder is not None else 0,
            },
            "recording": None
            if recorder is None
            else {
                "file": str(recorder.current_path) if recorder.current_path else None,
                "bytes": recorder.current_bytes,
                "errors": recorder.errors,
                "failing": recorder.failing,
                "failed_items": recorder.failed_items,
                "rejected": recorder.rejected,
                "gaps": recorder.gap_count,
                "lost_s": recorder.lost_s,
            },
            "leg_faults": {
                leg: dict(faults) for leg, faults in sorted(self.pipeline.leg_faults.items())
            },
            "zenoh": zenoh_status(
                self.session, self.connect, self._outages, now, any_one=self._connect_any_one
            )
            | {"same_prefix": self.owners.others()},
        }
        self._tell_other_owners(status["zenoh"]["same_prefix"])
        self.owners.tell_behind_router(self._zenoh_mode, status["zenoh"]["routers"])
        error_frames = dict(self.pipeline.error_frame_kinds)
        silent_s = now - self._last_frame_monotonic
        silent_legs = self._silent_legs()
        if len(silent_legs) == len(self.config.machine.legs) and silent_s >= self.silence_s:
            silent_legs = {}  # no frame of the DBC at all: that one problem says it
        found = problems(
            status,
            alive=self.alive(),
            silent_legs=silent_legs,
            error_frames={
                kind: n - self._error_frames_mark.get(kind, 0)
                for kind, n in error_frames.items()
                if n > self._error_frames_mark.get(kind, 0)
            },
            lost_before=self._lost_mark,
            silent_s=silent_s,
            heard_s=now - self._last_heard_monotonic,
            silence_s=self.silence_s,
        )
        self._lost_mark = losses(status)
        self._error_frames_mark = error_frames
        kinds = [problem_kind(problem) for problem in found]
        if kinds != self._reported_problems:
            if found:
                logger.warning("not healthy: %s", "; ".join(found))
            else:
                logger.info("healthy again")
            self._reported_problems = kinds
        status["healthy"] = not found
        status["problems"] = found
        return status

    def _silent_legs(self) -> dict[str, float]:
        """The legs whose sensors are silent while other frames go by: no sample for
        :attr:`silence_s` of bus time (a leg never heard: since the first frame), nor since
        the previous status (a clock stepped forward adds its step to the bus time at
        once; the legs that talked through it are not silent); with that bus time."""
        estimator = self.pipeline.estimator
        bus_time_s, heard_at_s = estimator.bus_time_s, estimator.heard_at_s()
        before, self._heard_at_mark = self._heard_at_mark, heard_at_s
        return {
            leg: bus_time_s - t_s
            for leg, t_s in heard_at_s.items()
            if bus_time_s - t_s >= self.silence_s and before.get(leg) == t_s
        }

    def _tell_other_owners(self, others: list[str]) -> None:
        """One line per other service seen under the key prefix, with what to do."""
        for zid in sorted(set(others) - self._owners_told):
            logger.warning(
                "another service publishes under %s (zenoh session %s): give each machine "
                "its own [machine] id (or [zenoh] key_prefix); a fleet view shows the two "
                "as one machine. (This service's previous run, if it was killed just now, "
                "goes by itself within the router's lease.)",
                self.config.zenoh.key_prefix,
                zid,
            )
        self._owners_told = set(others)

    def _truth_missing(self, now: float) -> None:
        """Logs once when ``[recording] truth`` is on and frames have come in for
        :data:`TRUTH_WAIT_PERIODS` status periods without a truth sample: a bridge that
        publishes under another machine id, or over a link the access control refuses
        puts from (TCP: Zenoh drops them unseen), leaves the recording without truth."""
        first = self._first_frame_monotonic
        if self.truth is None or self._truth_warned or self.truth.received or first is None:
            return
        if now - first < TRUTH_WAIT_PERIODS * self.config.publish.status_period_s:
            return
        self._truth_warned = True
        logger.warning(
            "[recording] truth is on, but no sample came on %s in %.0f s of frames: is the "
            "bridge publishing (portal-sim --zenoh) with this config's machine id, connected "
            "through a listener whose puts the access control lets in (zenoh.json5: a Unix "
            "socket, not TCP)?",
            self.truth.key,
            now - first,
        )

    def _kernel_losses(self, total: int) -> None:
        """Logs the frames the kernel dropped since the previous status (``total`` now)."""
        lost, self._kernel_dropped_mark = total - self._kernel_dropped_mark, total
        if lost:
            logger.warning(
                "%d frames lost in the kernel since the last status (%d in all): the CAN "
                "socket's receive buffer (%s bytes) overflowed while the service stalled",
                lost,
                total,
                self.reader.rcvbuf_bytes,
            )


def problem_kind(problem: str) -> str:
    """A problem without its numbers: a change of those alone is not logged again; the
    digits of a name stay (legs A1 and A2 silent in turn are two events).

    >>> problem_kind("dropped.rx +12"), problem_kind("legs silent: A1 2.5 s")
    ('dropped.rx +N', 'legs silent: A1 N s')
    """
    return _NUMBER.sub("N", problem)


def hold_overflow(config: ServiceConfig, rcvbuf_bytes: int | None) -> str | None:
    """Why a saturated bus's frames of one poll period (``[service] poll_period_ms``) may
    not fit where they wait: the CAN socket's receive buffer of ``rcvbuf_bytes`` (as
    granted) in the event loop, the reader's queue otherwise; None when they fit (or
    the room is unknown: not a kernel socket). Logged once at start.
    """
    held = config.service.poll_period_s * SATURATED_FRAMES_PER_S
    if config.service.event_loop:
        if rcvbuf_bytes is None:
            return None
        room = rcvbuf_bytes // RCVBUF_BYTES_PER_FRAME
        where = f"the CAN socket's receive buffer ({rcvbuf_bytes} bytes, ~{room} frames)"
        remedy = "raise [bus] receive_buffer_bytes (and net.core.rmem_max)"
    else:
        room = config.bus.queue_size
        where = f"the reader's queue ({room} frames)"
        remedy = "raise [bus] queue_size"
    if held <= room:
        return None
    return (
        f"[service] poll_period_ms = {config.service.poll_period_ms:g} holds up to "
        f"{held:.0f} frames of a saturated bus, more than {where}: frames would be lost "
        f"(counted as dropped) under a full load; lower poll_period_ms or {remedy}"
    )


def losses(status: JsonObject) -> dict[str, int]:
    """What ``status`` counts as lost by the service since it started, by field: every key
    of ``dropped``, the frames whose processing failed (``bad.internal_error``: a bug) and
    the items the recorder skipped (``recording.failed_items``).

    >>> losses({"dropped": {"rx": 5, "publish_failed": 1}, "bad": {"internal_error": 3},
    ...         "recording": {"failed_items": 2}})  # doctest: +NORMALIZE_WHITESPACE
    {'dropped.rx': 5, 'dropped.publish_failed': 1, 'bad.internal_error': 3,
     'recording.failed_items': 2}
    """
    found = {f"dropped.{where}": count for where, count in status["dropped"].items()}
    found["bad.internal_error"] = status.get("bad", {}).get("internal_error", 0)
    recording = status.get("recording")
    if recording is not None:
        found["recording.failed_items"] = recording["failed_items"]
    return found


#: Frames the consumer may have counted as processed and not yet by kind when a status
#: reads the counters: the one it is processing (the pipeline counts a frame, then its
#: kind once decoding has refused it).
IN_FLIGHT_FRAMES = 1


def decoded_for_sure(processed: int, bad: Mapping[str, int]) -> int:
    """Of ``processed`` frames, those of the DBC's messages for sure, the counters read
    while the consumer runs (:func:`~daq.pipeline.decoded_frames` less the frame it may
    be in the middle of). Read as they were, a foreign frame counted and not yet refused
    was taken for a sensor's: during a flood of unknown IDs or error frames, a status now
    and then judged the bus talking, and the next ones said "no frame for 0.3 s" where
    "no frame of the DBC" was meant (and healthy, when no other problem was).

    >>> decoded_for_sure(4001, {"unknown_id": 4000})  # the 4001st not refused yet
    0
    >>> decoded_for_sure(4012, {"unknown_id": 4000})
    11
    """
    return max(0, decoded_frames(processed, bad) - IN_FLIGHT_FRAMES)


def problems(
    status: JsonObject,
    *,
    alive: bool,
    lost_before: dict[str, int],
    silent_s: float,
    heard_s: float,
    silence_s: float,
    error_frames: Mapping[str, int] = {},
    silent_legs: Mapping[str, float] = {},
) -> list[str]:
    """What makes ``status`` unhealthy (see the module docstring); empty when healthy.
    ``lost_before`` is :func:`losses` of the previous status; ``silent_s`` the time since
    a frame of the DBC came in, ``heard_s`` since any frame did; ``error_frames`` what
    the error frames of the period reported, by kind (a CAN bus in order has none);
    ``silent_legs`` the legs silent for ``silence_s`` or more of bus time (the other
    frames went by without theirs), with that time.

    >>> problems({"dropped": {"rx": 5, "kernel": 2}, "recording": None,
    ...           "zenoh": {"unreached": []}}, alive=True, lost_before={"dropped.rx": 5},
    ...          silent_s=0.1, heard_s=0.1, silence_s=1.0)
    ['dropped.kernel +2']
    >>> problems({"dropped": {}, "recording": None, "zenoh": {"unreached": []}},
    ...          alive=True, lost_before={}, silent_s=3.0, heard_s=0.0, silence_s=1.0)
    ['no frame of the DBC for 3.0 s, only frames it does not use (see bad)']
    >>> problems({"dropped": {}, "recording": None, "zenoh": {"unreached": []}},
    ...          alive=True, lost_before={}, silent_s=0.0, heard_s=0.0, silence_s=1.0,
    ...          error_frames={"rx overflow": 2, "bus off": 1})
    ['CAN controller: rx overflow +2, bus off +1 (error frames)']
    >>> problems({"dropped": {}, "recording": None, "zenoh": {"unreached": []}},
    ...          alive=True, lost_before={}, silent_s=0.0, heard_s=0.0, silence_s=1.0,
    ...          silent_legs={"SB1_F3": 12.34})
    ['legs silent: SB1_F3 12.3 s']
    """
    found = [] if alive else ["a service thread hangs or died"]
    bus = status.get("bus") or {}
    if bus.get("state") in (BUS_DOWN, BUS_ABSENT):  # no frame can come in
        found.append(f"bus {bus['state']}: {bus['reason']}")
    recording = status.get("recording")
    if recording is not None and recording.get("failing"):
        found.append("recording stopped (write error)")
    for name, count in losses(status).items():
        if count > lost_before.get(name, 0):
            found.append(f"{name} +{count - lost_before.get(name, 0)}")
    if silent_legs:
        silent = ", ".join(f"{leg} {s:.1f} s" for leg, s in silent_legs.items())
        found.append(f"legs silent: {silent}")
    if error_frames:
        reported = ", ".join(f"{kind} +{n}" for kind, n in error_frames.items())
        found.append(f"CAN controller: {reported} (error frames)")
    found += [f"zenoh connect {endpoint} not reached" for endpoint in status["zenoh"]["unreached"]]
    found += [
        f"another service publishes under this key prefix (zenoh session {zid})"
        for zid in status["zenoh"].get("same_prefix", ())
    ]
    if silent_s >= silence_s:
        found.append(
            f"no frame for {silent_s:.1f} s"
            if heard_s >= silent_s
            else f"no frame of the DBC for {silent_s:.1f} s, only frames it does not use (see bad)"
        )
    return found


def status_line(status: JsonObject) -> str:
    """One line for systemd's STATUS=, e.g. ``bus up, 600 frames/s, 0 bad, 0 dropped,
    healthy`` or ``..., NOT HEALTHY: recording stopped (write error)``."""
    frames = status["frames"]
    dropped = sum(status["dropped"].values())
    health = "healthy" if status["healthy"] else "NOT HEALTHY: " + "; ".join(status["problems"])
    return (
        f"bus {status['bus']['state']}, {status['frames_per_s']:.0f} frames/s, "
        f"{frames['bad']} bad, {dropped} dropped, {health}"
    )
