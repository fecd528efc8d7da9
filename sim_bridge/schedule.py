"""The absolute send schedule: every message at its DBC cycle time, merged in time order.

Pure computation. Frame ``k`` of a message with cycle time ``cycle_s`` belongs to
simulation time ``k * cycle_s`` (since the bridge started) and is due on the sender's
clock at ``start_s + k * cycle_s / speed``. Due times are computed from ``k``, never by
adding up sleep durations, so a late frame delays only itself: the next one is due on
time again and the schedule cannot drift.

Simulation times are kept as integer nanoseconds (``k * cycle_ns``), so frames of
different messages that belong to the same instant compare equal exactly and come out
together, in the DBC's message order.

>>> cycles = [MessageCycle("FAST", 10_000_000), MessageCycle("SLOW", 20_000_000)]
>>> [(f.message, f.k) for f in schedule(cycles, end_sim_ns=30_000_000)]
[('FAST', 0), ('SLOW', 0), ('FAST', 1), ('FAST', 2), ('SLOW', 1)]
>>> [f.due_s for f in schedule(cycles, start_s=100.0, speed=2.0, end_sim_ns=20_000_000)]
[100.0, 100.0, 100.005]
"""

import heapq
import itertools
import math
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass

NS_PER_S = 1_000_000_000
NS_PER_MS = 1_000_000


@dataclass(frozen=True, slots=True)
class MessageCycle:
    """One periodic message and its cycle time."""

    message: str
    #: The message's cycle time (the DBC's GenMsgCycleTime, or the config's), ns.
    cycle_ns: int

    @property
    def cycle_s(self) -> float:
        return self.cycle_ns / NS_PER_S


@dataclass(frozen=True, slots=True)
class ScheduledFrame:
    """Frame ``k`` of ``message``: when it is due and which simulation time it carries."""

    message: str
    #: Index of this frame in its message's sequence (0, 1, 2, ...).
    k: int
    #: Simulation time since the bridge started: ``k * cycle_ns``.
    sim_t_ns: int
    #: When it is due on the sender's clock: ``start_s + k * cycle_s / speed``, seconds.
    due_s: float


@dataclass(frozen=True, slots=True)
class Instant:
    """All frames that belong to one simulation time, in DBC message order."""

    sim_t_ns: int
    due_s: float
    frames: tuple[ScheduledFrame, ...]

    @property
    def messages(self) -> tuple[str, ...]:
        return tuple(frame.message for frame in self.frames)


def check_speed(speed: float) -> float:
    """``speed`` if it is a finite number > 0, else ValueError."""
    if not (math.isfinite(speed) and speed > 0):
        raise ValueError(f"speed must be a finite number > 0, got {speed!r}")
    return speed


def due_time_s(start_s: float, k: int, cycle_s: float, speed: float = 1.0) -> float:
    """Due time of frame ``k`` of a message with cycle time ``cycle_s``."""
    return start_s + k * cycle_s / speed


def _frames_of(
    cycle: MessageCycle, start_s: float, speed: float, end_sim_ns: int | None
) -> Iterator[ScheduledFrame]:
    cycle_s = cycle.cycle_s
    for k in itertools.count():
        sim_t_ns = k * cycle.cycle_ns
        if end_sim_ns is not None and sim_t_ns >= end_sim_ns:
            return
        yield ScheduledFrame(cycle.message, k, sim_t_ns, due_time_s(start_s, k, cycle_s, speed))


def schedule(
    cycles: Sequence[MessageCycle],
    *,
    start_s: float = 0.0,
    speed: float = 1.0,
    end_sim_ns: int | None = None,
) -> Iterator[ScheduledFrame]:
    """Every frame of every message, in time order (ties in the order of ``cycles``).

    Frames with ``sim_t_ns >= end_sim_ns`` are left out; ``None`` runs forever.
    """
    check_speed(speed)
    for cycle in cycles:
        if cycle.cycle_ns <= 0:
            raise ValueError(f"{cycle.message}: cycle time must be > 0, got {cycle.cycle_ns} ns")
    streams = [
        ((frame.sim_t_ns, order, frame) for frame in _frames_of(cycle, start_s, speed, end_sim_ns))
        for order, cycle in enumerate(cycles)
    ]
    for _, _, frame in heapq.merge(*streams, key=lambda item: (item[0], item[1])):
        yield frame


def instants(frames: Iterable[ScheduledFrame]) -> Iterator[Instant]:
    """Groups a time-ordered frame stream by simulation time."""
    for sim_t_ns, group in itertools.groupby(frames, key=lambda frame: frame.sim_t_ns):
        members = tuple(group)
        yield Instant(sim_t_ns, min(frame.due_s for frame in members), members)
