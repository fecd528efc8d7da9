"""Offering the frames: paced at a fixed rate, or as fast as the receiver takes them.

``send`` is where a frame goes onto the (simulated) bus: python-can's virtual bus,
or straight into the service's reader queue. It stamps the frame with ``time.time()``
as it sends it (the frame time the latency is measured from) and returns that stamp.
The paced sender also keeps each frame's due time: a frame that went out late (the
sender shares its CPU with the system under test) was "on the wire" since then.
"""

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import can

#: A frame more than this behind its due time counts as late (paced mode).
LATE_AFTER_S = 0.001
#: Frames sent between two looks at the receiver's backlog (throughput mode).
CHECK_EVERY = 32


@dataclass(frozen=True, slots=True)
class Sent:
    """What a sender did."""

    frames: int
    #: time.time() just before the first frame and just after the last one.
    start_s: float
    end_s: float
    #: Paced mode: frames that went out more than LATE_AFTER_S after their due time,
    #: and the worst lateness (the sender shares the CPU with the receiver).
    late_frames: int = 0
    max_lateness_s: float = 0.0
    #: Paced mode: frame time stamp -> due time (Unix seconds) of every frame.
    due_by_stamp: dict[float, float] | None = None

    @property
    def rate_hz(self) -> float:
        elapsed_s = self.end_s - self.start_s
        return self.frames / elapsed_s if elapsed_s > 0 else float("nan")


def send_paced(
    send: Callable[[can.Message], float], frames: Sequence[can.Message], rate_hz: float
) -> Sent:
    """Frame ``i`` due at ``start + i / rate_hz``; sleeps until due, late ones go at once.

    Due times come from ``i``, never from summed sleeps, so the offered rate is exact
    on average even when single sleeps overshoot.
    """
    period_s = 1.0 / rate_hz
    late = 0
    max_lateness_s = 0.0
    clock = time.perf_counter
    stamps: list[float] = []
    start_s = time.time()
    start = clock()
    for i, frame in enumerate(frames):
        due = start + i * period_s
        now = clock()
        if due > now:
            time.sleep(due - now)
        elif now - due > LATE_AFTER_S:
            late += 1
            max_lateness_s = max(max_lateness_s, now - due)
        stamps.append(send(frame))
    due_by_stamp = {stamp: start_s + i * period_s for i, stamp in enumerate(stamps)}
    return Sent(len(frames), start_s, time.time(), late, max_lateness_s, due_by_stamp)


def send_backpressured(
    send: Callable[[can.Message], float],
    frames: Sequence[can.Message],
    busy: Callable[[int], bool],
) -> Sent:
    """As fast as the receiver takes them: before every :data:`CHECK_EVERY` frames, waits
    while ``busy(frames sent so far)`` says the receiver's backlog is full."""
    start_s = time.time()
    for i, frame in enumerate(frames):
        if i % CHECK_EVERY == 0:
            while busy(i):
                time.sleep(0.0002)
        send(frame)
    return Sent(len(frames), start_s, time.time())
