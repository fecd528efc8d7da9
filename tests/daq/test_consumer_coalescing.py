"""The consumer's poll period (``[service] poll_period_ms``): after a wake-up that took
frames, the source is left alone for the period, so what arrives meanwhile is handled as
one batch; the timers still run on time, ``close`` ends a hold at once, and a period of 0
changes nothing.

A fake source and a fake monotonic clock (advanced only by the source's waits and the
consumer's) make every batch boundary exact: frames arrive every 1/1024 s, half-way
between ticks, and the period is 20/1024 s.
"""

import threading
from collections.abc import Sequence
from itertools import pairwise
from pathlib import Path
from typing import Any

from daq.can_batch import MAX_FRAMES
from daq.consumer import HAND_OVER_FRAMES, RECORD_PERIOD_S, Consumer
from daq.frames import BusEvent, RawFrame
from daq.mcap_file import RecordBatch
from daq.pipeline import Pipeline
from daq.service import hold_overflow
from daq.service_config import PublishSettings, ServiceConfig, load_service_config
from dbc.encoding import FrameEncoder
from estimator.machine import MachineSnapshot
from tests.helpers import LEGS, ROOT, example_machine

CONFIG, DATABASE = example_machine()
START_S = 1000.0
TICK_S = 1 / 1024
PERIOD_S = 20 * TICK_S
#: Signals off: each leg frame is one message to the publisher (its leg's estimate).
SETTINGS = PublishSettings(ground_rate_hz=10.0, signals=False)


class FakeClock:
    """The consumer's monotonic clock; a wait only moves it on."""

    def __init__(self) -> None:
        self.t_s = START_S
        self.waits: list[float] = []

    def monotonic(self) -> float:
        return self.t_s

    def wait(self, timeout_s: float) -> bool:
        self.waits.append(timeout_s)
        self.t_s += timeout_s
        return False


class ScriptedSource:
    """Frames that arrive at given times on ``clock``: a poll waits (moving the clock) for
    the first one within its timeout, then takes every one there, at most MAX_FRAMES.
    ``done`` is set once every frame was taken and a poll then found none."""

    def __init__(self, clock: FakeClock, arrivals: list[tuple[float, RawFrame]]) -> None:
        self.clock = clock
        self.arrivals = arrivals
        self.taken = 0
        #: (clock time, timeout, items returned) of each poll.
        self.polls: list[tuple[float, float, int]] = []
        self.done = threading.Event()

    def poll(self, timeout_s: float) -> Sequence[RawFrame | BusEvent]:
        clock, arrivals = self.clock, self.arrivals
        if self.taken < len(arrivals) and arrivals[self.taken][0] > clock.t_s:
            clock.t_s = min(arrivals[self.taken][0], clock.t_s + timeout_s)
        elif self.taken == len(arrivals):
            clock.t_s += timeout_s
        start = self.taken
        while (
            self.taken < len(arrivals)
            and arrivals[self.taken][0] <= clock.t_s
            and self.taken - start < MAX_FRAMES
        ):
            self.taken += 1
        self.polls.append((clock.t_s, timeout_s, self.taken - start))
        if self.taken == len(arrivals) and start == self.taken:
            self.done.set()
        return [frame for _, frame in arrivals[start : self.taken]]


class Collect:
    """Publisher and recorder at once: what was handed over, and when (clock time)."""

    def __init__(self, clock: FakeClock) -> None:
        self.clock = clock
        self.batches: list[int] = []  # messages (leg frames) per consumer batch
        self.grounds: list[float] = []
        self.recorded: list[tuple[float, RecordBatch]] = []
        self.handled = threading.Event()

    def submit(self, item: Any, payload: Any = None) -> None:
        if item == "ground":
            self.grounds.append(self.clock.t_s)
        elif isinstance(item, RecordBatch):
            self.recorded.append((self.clock.t_s, item))
        else:
            assert item == "metrics" or isinstance(item, (MachineSnapshot, BusEvent))

    def submit_batch(self, messages: Sequence[tuple[str, Any]]) -> None:
        self.batches.append(len(messages))
        self.handled.set()


def leg_frames(count: int) -> list[RawFrame]:
    encoder = FrameEncoder(DATABASE, CONFIG.protection)
    frames = []
    for i in range(count):
        leg = LEGS[i % len(LEGS)]
        signals = {f"{leg}_pPiston": 5e6, f"{leg}_pRod": 1e6, f"{leg}_Status": "ok"}
        encoded = encoder.encode(f"LEG_{leg}", signals)
        frames.append(RawFrame(START_S + i, encoded.arbitration_id, False, encoded.data))
    return frames


def run(poll_period_s: float, arrivals_s: list[float]) -> tuple[ScriptedSource, Collect]:
    """The consumer's thread on the scripted arrivals until every frame was taken."""
    clock = FakeClock()
    source = ScriptedSource(clock, list(zip(arrivals_s, leg_frames(len(arrivals_s)), strict=True)))
    collect = Collect(clock)
    consumer = Consumer(
        Pipeline.from_config(CONFIG, DATABASE),
        source,
        SETTINGS,
        publisher=collect,
        recorder=collect,
        poll_period_s=poll_period_s,
        monotonic=clock.monotonic,
        wait=clock.wait,
    )
    with consumer:
        assert source.done.wait(timeout=30.0)
    assert consumer.pipeline.frames == len(arrivals_s)
    assert consumer.pipeline.bad == {}
    return source, collect


#: A frame every tick for 100 ticks, half-way between ticks (1,024 frames/s).
ARRIVALS_S = [START_S + (k + 0.5) * TICK_S for k in range(100)]


def test_frames_arriving_within_a_period_are_handled_as_one_batch() -> None:
    source, collect = run(PERIOD_S, ARRIVALS_S)
    # The first frame wakes the loop; the next 20 arrive during the hold, and so on.
    assert collect.batches == [1, 20, 20, 20, 20, 19]
    taking = [(t_s, count) for t_s, _, count in source.polls if count]
    assert [count for _, count in taking] == collect.batches
    # Each poll after a hold comes the period after the previous wake-up, not before.
    starts = [t_s for t_s, _ in taking]
    assert [b - a for a, b in pairwise(starts)] == [PERIOD_S] * 5
    # No poll in between: the source was left alone while the frames came.
    last_frame_s = ARRIVALS_S[-1]
    assert sum(1 for t_s, _, _ in source.polls if t_s <= last_frame_s + PERIOD_S) == 6


def test_timers_run_on_time_during_the_holds() -> None:
    source, collect = run(PERIOD_S, ARRIVALS_S)
    ground_period_s = 1.0 / SETTINGS.ground_rate_hz
    assert len(collect.grounds) >= 3
    for a, b in pairwise(collect.grounds):
        assert abs(b - a - ground_period_s) < 1e-9
    # Every frame reaches the recorder, at most RECORD_PERIOD_S after it was taken.
    taken_at = {}
    frames = iter(ARRIVALS_S)
    for t_s, _, count in source.polls:
        for _ in range(count):
            taken_at[next(frames)] = t_s
    recorded = [(t_s, frame) for t_s, batch in collect.recorded for frame in batch.frames]
    assert [frame.t_s for _, frame in recorded] == [START_S + i for i in range(100)]
    for (handed_s, _), arrival_s in zip(recorded, ARRIVALS_S, strict=True):
        assert handed_s - taken_at[arrival_s] <= RECORD_PERIOD_S + 1e-9


def test_a_period_of_zero_handles_each_wake_up_at_once() -> None:
    source, collect = run(0.0, ARRIVALS_S)
    assert collect.batches == [1] * 100
    taking = [t_s for t_s, _, count in source.polls if count]
    assert taking == ARRIVALS_S  # each frame taken the moment it came


def test_a_wake_up_cut_at_max_frames_is_not_followed_by_a_hold() -> None:
    backlog = [START_S + 0.5 * TICK_S] * (MAX_FRAMES + 10)  # a stall's worth at once
    source, collect = run(PERIOD_S, backlog + [START_S + 1.5 * TICK_S])
    assert collect.batches == [MAX_FRAMES, 10, 1]
    polls = [(t_s, count) for t_s, _, count in source.polls if count]
    assert polls[0][0] == polls[1][0]  # the rest taken at once
    assert polls[2][0] == polls[1][0] + PERIOD_S  # then the hold


def test_a_saturated_bus_is_handed_to_the_recorder_in_bounded_batches() -> None:
    """At 9,000 frames/s, one frame per wake-up, the recorder gets a batch each
    HAND_OVER_FRAMES frames, well before RECORD_PERIOD_S: handing over 0.1 s of frames at
    once held the frames' thread ~1 ms."""
    count = 2 * HAND_OVER_FRAMES + 88
    arrivals_s = [START_S + (k + 0.5) / 9000 for k in range(count)]
    assert arrivals_s[-1] - arrivals_s[0] < RECORD_PERIOD_S
    source, collect = run(0.0, arrivals_s)
    sizes = [len(batch.frames) for _, batch in collect.recorded]
    assert sizes == [HAND_OVER_FRAMES, HAND_OVER_FRAMES, 88]
    # each handed over on the wake-up that took its last frame
    handed = [t_s for t_s, _ in collect.recorded]
    assert handed[:2] == [arrivals_s[HAND_OVER_FRAMES - 1], arrivals_s[2 * HAND_OVER_FRAMES - 1]]


class Once:
    """One frame at the first poll, then nothing (each poll noted with its timeout)."""

    def __init__(self, frame: RawFrame) -> None:
        self.items: list[RawFrame | BusEvent] = [frame]
        self.timeouts: list[float] = []

    def poll(self, timeout_s: float) -> Sequence[RawFrame | BusEvent]:
        self.timeouts.append(timeout_s)
        items, self.items = self.items, []
        return items


def test_close_during_a_hold_returns_at_once() -> None:
    """An hour's period on the real clocks: ``close`` must end the hold, not wait it out."""
    source = Once(leg_frames(1)[0])
    collect = Collect(FakeClock())
    consumer = Consumer(
        Pipeline.from_config(CONFIG, DATABASE),
        source,
        SETTINGS,
        publisher=collect,
        poll_period_s=3600.0,
    )
    consumer.start()
    assert collect.handled.wait(timeout=30.0)  # the frame was handled: the hold begins
    closer = threading.Thread(target=consumer.close)
    closer.start()
    closer.join(timeout=30.0)
    assert not closer.is_alive() and not consumer.alive
    # Polled once with a timeout; after it only the drain at close (no wait).
    assert source.timeouts[0] > 0 and all(t == 0.0 for t in source.timeouts[1:])
    assert consumer.pipeline.frames == 1


def test_a_quiet_bus_is_waited_on_as_without_a_period() -> None:
    """No frame, no hold: every turn is one poll that waits the loop's longest wait."""
    clock = FakeClock()
    source = ScriptedSource(clock, [])
    consumer = Consumer(
        Pipeline.from_config(CONFIG, DATABASE),
        source,
        SETTINGS,
        poll_period_s=PERIOD_S,
        monotonic=clock.monotonic,
        wait=clock.wait,
    )
    with consumer:
        assert source.done.wait(timeout=30.0)
    assert clock.waits == []
    assert source.polls[0][1] == 0.1  # the loop's longest wait


def config_with(tmp_path: Path, service: str, bus: str = "") -> ServiceConfig:
    path = tmp_path / "portal-daq.toml"
    machine = (ROOT / "deploy" / "machine.example.toml").read_text()
    path.write_text(f"[service]\n{service}\n[bus]\n{bus}\n{machine}")
    return load_service_config(path)


#: What Linux grants when ``SO_RCVBUF`` is clamped to the default ``net.core.rmem_max``.
CLAMPED_RCVBUF_BYTES = 2 * 212_992


def test_a_period_a_saturated_bus_overflows_is_warned_about(tmp_path: Path) -> None:
    fits = config_with(tmp_path, "poll_period_ms = 50")  # 450 frames, room for 532
    assert hold_overflow(fits, CLAMPED_RCVBUF_BYTES) is None
    assert hold_overflow(fits, None) is None  # not a kernel socket: room unknown
    too_long = config_with(tmp_path, "poll_period_ms = 100")
    warning = hold_overflow(too_long, CLAMPED_RCVBUF_BYTES)
    assert warning is not None and "poll_period_ms = 100 holds up to 900 frames" in warning
    assert f"({CLAMPED_RCVBUF_BYTES} bytes, ~532 frames)" in warning
    assert hold_overflow(too_long, 4 * CLAMPED_RCVBUF_BYTES) is None
    threads = config_with(tmp_path, "event_loop = false\npoll_period_ms = 20", "queue_size = 100")
    warning = hold_overflow(threads, None)  # the reader's queue holds them then
    assert warning is not None and "the reader's queue (100 frames)" in warning
    assert "queue_size" in warning
    assert hold_overflow(config_with(tmp_path, ""), 1024) is None  # no period, no hold
