"""Staleness on the ground message is judged against the bus, so a consumer that lags
the bus by a moment does not call fresh legs stale, while a silent sensor still is; and
not on the wall clock, so a clock stepped back or forward changes nothing."""

import queue

import pytest

from daq.consumer import LAG_TOLERANCE_S, Consumer
from daq.frames import RawFrame
from daq.pipeline import Pipeline
from daq.service_config import PublishSettings
from dbc.encoding import FrameEncoder
from estimator.machine import MachineSnapshot
from tests.helpers import LEGS, example_machine

CONFIG, DATABASE = example_machine()


def feed(consumer: Consumer, encoder: FrameEncoder, leg: str, t_s: float) -> None:
    frame = encoder.encode(
        f"LEG_{leg}", {f"{leg}_pPiston": 5e6, f"{leg}_pRod": 1e6, f"{leg}_Status": "ok"}
    )
    consumer.handle(RawFrame(t_s, frame.arbitration_id, frame.is_extended_id, frame.data))


class Clocks:
    """The wall clock and the monotonic clock the consumer reads, set by the test."""

    def __init__(self) -> None:
        self.wall_s = 100.0
        self.monotonic_s = 5000.0


def make() -> tuple[Consumer, FrameEncoder, Clocks]:
    clocks = Clocks()
    consumer = Consumer(
        Pipeline.from_config(CONFIG, DATABASE),
        queue.Queue(),
        PublishSettings(),
        now=lambda: clocks.wall_s,
        monotonic=lambda: clocks.monotonic_s,
    )
    return consumer, FrameEncoder(DATABASE, CONFIG.protection), clocks


def test_lagging_consumer_does_not_make_fresh_legs_stale() -> None:
    consumer, encoder, clocks = make()
    for leg in LEGS:
        feed(consumer, encoder, leg, 100.0)
    clocks.monotonic_s += LAG_TOLERANCE_S * 0.8  # nothing more for 0.4 s
    clocks.wall_s += LAG_TOLERANCE_S * 0.8
    snapshot = consumer.pipeline.snapshot(consumer.judged_at())
    assert all(estimate.valid for estimate in snapshot.legs.values())


def test_a_silent_sensor_is_stale_while_the_others_talk() -> None:
    consumer, encoder, _ = make()
    for leg in LEGS:
        feed(consumer, encoder, leg, 100.0)
    for step in range(1, 6):  # 50 ms more of every leg but SB2_F3
        for leg in LEGS[:5]:
            feed(consumer, encoder, leg, 100.0 + 0.01 * step)
    snapshot = consumer.pipeline.snapshot(consumer.judged_at())
    assert snapshot.legs["SB2_F3"].reasons == ("stale",)
    assert all(snapshot.legs[leg].valid for leg in LEGS[:5])


@pytest.mark.parametrize("wall_step_s", [0.0, -5.0, 5.0])
def test_a_silent_bus_makes_every_leg_stale_after_the_tolerance(wall_step_s: float) -> None:
    consumer, encoder, clocks = make()
    for leg in LEGS:
        feed(consumer, encoder, leg, 100.0)
    clocks.monotonic_s += LAG_TOLERANCE_S + 0.05
    clocks.wall_s += LAG_TOLERANCE_S + 0.05 + wall_step_s  # the wall clock may step too
    snapshot = consumer.pipeline.snapshot(consumer.judged_at())
    assert all(estimate.reasons == ("stale",) for estimate in snapshot.legs.values())


def run_traffic(
    consumer: Consumer,
    encoder: FrameEncoder,
    clocks: Clocks,
    t0_s: float,
    rounds: int,
    legs: tuple[str, ...] = LEGS,
) -> list[MachineSnapshot]:
    """``rounds`` x 10 ms of frames of ``legs`` from frame time ``t0_s``, the clocks
    following; a ground snapshot after every frame, as the consumer may take one there."""
    snapshots = []
    for i in range(rounds):
        for leg in legs:
            clocks.monotonic_s += 0.01 / len(legs)
            clocks.wall_s = t0_s + 0.01 * i
            feed(consumer, encoder, leg, t0_s + 0.01 * i)
            snapshots.append(consumer.pipeline.snapshot(consumer.judged_at()))
    return snapshots


def test_a_clock_stepped_back_keeps_the_talking_legs_valid() -> None:
    consumer, encoder, clocks = make()
    run_traffic(consumer, encoder, clocks, 100.0, 100)  # 1 s of healthy traffic
    after = run_traffic(consumer, encoder, clocks, 96.0, 300)  # NTP steps back 5 s; 3 s more
    assert all(estimate.valid for s in after for estimate in s.legs.values())
    assert all(s.weight.complete and abs(s.weight.residual_N) < 50e3 for s in after)


def test_a_clock_stepped_forward_makes_no_leg_stale_for_longer_than_a_cycle() -> None:
    consumer, encoder, clocks = make()
    run_traffic(consumer, encoder, clocks, 100.0, 100)
    after = run_traffic(consumer, encoder, clocks, 106.0, 300)  # steps forward 5 s
    # Until each leg has sent once after the step it looks silent for 5 s; then never.
    assert all(estimate.valid for s in after[len(LEGS) :] for estimate in s.legs.values())


def test_a_leg_silent_across_a_step_back_stays_stale() -> None:
    consumer, encoder, clocks = make()
    run_traffic(consumer, encoder, clocks, 100.0, 100)
    run_traffic(consumer, encoder, clocks, 101.0, 50, LEGS[:5])  # SB2_F3 falls silent
    after = run_traffic(consumer, encoder, clocks, 96.5, 50, LEGS[:5])  # steps back 5 s
    assert all(s.legs["SB2_F3"].reasons == ("stale",) for s in after)
    assert all(s.legs[leg].valid for s in after for leg in LEGS[:5])
