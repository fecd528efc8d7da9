"""The I/O edge of the bridge: sends the playout's frames on a CAN bus, on time.

The bus (any python-can :class:`can.BusABC`), the clocks, the sleep function and the truth
sinks are passed in; the constructor opens nothing. Timing follows the absolute schedule
of :mod:`sim_bridge.schedule`: simulation time ``t`` is due at ``start + t / speed`` on
the monotonic ``clock``, so a late frame never delays the ones after it. With
``as_fast_as_possible`` nothing sleeps (benchmarks).

The **frame time** of an instant is the Unix time (``wall_clock`` at the start, plus the
monotonic time elapsed since) just before its first frame is sent, to the microsecond
(as SocketCAN stamps frames, and as a candump log keeps them); it stamps the
``can.Message`` and the ground-truth sample of that simulation time. With
``as_fast_as_possible`` it is the Unix time the instant is due at (as if played at
``speed``): the frames log and the truth of such a run keep the cycle's timing, so a
replay judges staleness, skew and silences as the live service would, and a report or a
calibration sees the cycle's seconds (stamped when sent, a 45 s cycle took a fraction of
a second: no transducer was ever stale, ``--silent`` showed nothing).

Every frame the bus took is also handed to ``frames_log`` (a python-can listener, e.g.
``can.Logger("cycle.log")``) when given: a log that ``portal-daq replay`` plays back.

A send the bus refuses (``can.CanError``, e.g. a full transmit queue) is counted and
logged, never fatal. :meth:`Emitter.stop` (safe from a signal handler) ends the run
after the current instant.
"""

import logging
import time
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import can

from dbc.encoding import EncodedFrame
from sim_bridge.playout import Playout, PlayoutCounts
from sim_bridge.schedule import NS_PER_S, check_speed, instants, schedule
from sim_bridge.truth import TruthSink, truth_sample

logger = logging.getLogger(__name__)

#: A frame later than this behind its due time counts as late (real-time runs only).
LATE_AFTER_S = 0.005


@dataclass
class EmitterStats:
    """What a run did."""

    #: Frames handed to the bus, per message.
    sent: Counter[str] = field(default_factory=Counter)
    #: Sends the bus refused, per message.
    send_errors: Counter[str] = field(default_factory=Counter)
    #: Frames built, dropped, corrupted, frozen, silenced or paused by faults.
    faults: PlayoutCounts = field(default_factory=PlayoutCounts)
    #: Instants whose frames went out more than LATE_AFTER_S after their due time.
    late_instants: int = 0
    max_lateness_s: float = 0.0
    truth_samples: int = 0
    #: Simulation time reached, s.
    sim_time_s: float = 0.0
    cycles_started: int = 0
    stopped: bool = False


def end_of_run_ns(cycle_ns: int, cycles: int, duration_s: float | None = None) -> int | None:
    """Simulation time at which a run ends: after ``cycles`` cycles of ``cycle_ns``
    (0: never) or ``duration_s`` seconds of simulated time, whichever comes first.

    >>> end_of_run_ns(10_000_000_000, cycles=2, duration_s=5.0)
    5000000000
    """
    if cycles < 0:
        raise ValueError(f"cycles must be >= 0 (0 = forever), got {cycles}")
    ends = [cycles * cycle_ns] if cycles else []
    if duration_s is not None:
        if not duration_s > 0:
            raise ValueError(f"duration must be > 0 s, got {duration_s!r}")
        ends.append(round(duration_s * NS_PER_S))
    return min(ends) if ends else None


class Emitter:
    """Plays one :class:`~sim_bridge.playout.Playout` onto ``bus``.

    ``end_sim_ns`` ends the run before that simulation time (None: run until
    :meth:`stop`; :func:`end_of_run_ns` computes it from cycles and a duration).
    ``truth_every`` writes every n-th simulation row the bus reaches to each of
    ``truth_sinks``, with foot areas ``feet_m2`` (config leg -> m2); the truth names the
    config's legs, each with its simulated leg's values (the playout's leg map).
    """

    def __init__(
        self,
        bus: can.BusABC,
        playout: Playout,
        *,
        end_sim_ns: int | None,
        speed: float = 1.0,
        as_fast_as_possible: bool = False,
        truth_sinks: Sequence[TruthSink] = (),
        feet_m2: Mapping[str, float] | None = None,
        truth_every: int = 1,
        frames_log: can.Listener | None = None,
        clock: Callable[[], float] = time.monotonic,
        wall_clock: Callable[[], float] = time.time,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        if truth_every < 1:
            raise ValueError(f"truth_every must be >= 1, got {truth_every}")
        if truth_sinks and not feet_m2:
            raise ValueError("truth sinks need the legs' foot areas (feet_m2)")
        self._bus = bus
        self._playout = playout
        self._end_sim_ns = end_sim_ns
        self._speed = check_speed(speed)
        self._afap = as_fast_as_possible
        self._truth_sinks = tuple(truth_sinks)
        self._feet_m2 = dict(feet_m2 or {})
        self._truth_every = truth_every
        self._frames_log = frames_log
        self._clock = clock
        self._wall_clock = wall_clock
        self._sleep = sleep
        self._stop = False

    def stop(self) -> None:
        """End the run after the current instant; safe to call from a signal handler."""
        self._stop = True

    def run(self) -> EmitterStats:
        """Send until the end time or :meth:`stop`; returns what was done."""
        stats = EmitterStats(faults=self._playout.counts)
        cycles = self._playout.cycles
        stats.sent.update({cycle.message: 0 for cycle in cycles})  # report in DBC order
        start_s = self._clock()
        unix_offset_s = self._wall_clock() - start_s
        last_row: tuple[int, int] | None = None
        rows_reached = 0
        logger.info(
            "sending %d messages at %s",
            len(cycles),
            "full speed" if self._afap else f"{self._speed:g}x real time",
        )
        frames = schedule(cycles, start_s=start_s, speed=self._speed, end_sim_ns=self._end_sim_ns)
        for instant in instants(frames):
            if self._stop:
                stats.stopped = True
                break
            position, outgoing = self._playout.frames(instant)
            if self._afap:
                t_unix_s = round(instant.due_s + unix_offset_s, 6)
            else:
                self._wait_until(instant.due_s, stats)
                t_unix_s = round(self._clock() + unix_offset_s, 6)
            for item in outgoing:
                self._send(item.message, item.frame, t_unix_s, stats)
            stats.sim_time_s = instant.sim_t_ns / NS_PER_S
            stats.cycles_started = position.cycle + 1
            if (position.cycle, position.row) != last_row:
                last_row = (position.cycle, position.row)
                if self._truth_sinks and rows_reached % self._truth_every == 0:
                    sample = truth_sample(
                        self._playout.result,
                        position,
                        t_unix_s,
                        self._feet_m2,
                        self._playout.leg_columns,
                    )
                    for sink in self._truth_sinks:
                        sink.write(sample)
                    stats.truth_samples += 1
                rows_reached += 1
            if instant.sim_t_ns == 0:
                logger.debug("first instant sent at Unix time %.6f", t_unix_s)
        return stats

    def _wait_until(self, due_s: float, stats: EmitterStats) -> None:
        delay_s = due_s - self._clock()
        if delay_s > 0:
            self._sleep(delay_s)
        elif -delay_s > LATE_AFTER_S:
            stats.late_instants += 1
            if stats.late_instants == 1:
                logger.warning(
                    "falling behind the schedule (%.1f ms late); lower --speed", -delay_s * 1e3
                )
            stats.max_lateness_s = max(stats.max_lateness_s, -delay_s)

    def _send(
        self, message: str, frame: EncodedFrame, t_unix_s: float, stats: EmitterStats
    ) -> None:
        sent = can.Message(
            timestamp=t_unix_s,
            arbitration_id=frame.arbitration_id,
            is_extended_id=frame.is_extended_id,
            data=frame.data,
            is_fd=frame.is_fd,
        )
        try:
            self._bus.send(sent)
        except can.CanError as exc:
            stats.send_errors[message] += 1
            if sum(stats.send_errors.values()) == 1:
                logger.warning("the bus refused a %s frame: %s (counting the rest)", message, exc)
        else:
            stats.sent[message] += 1
            if self._frames_log is not None:
                self._frames_log.on_message_received(sent)
