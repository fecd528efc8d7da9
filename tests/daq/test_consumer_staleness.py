"""Staleness on the ground message is judged against the bus, so a consumer that lags
the bus by a moment does not call fresh legs stale, while a silent sensor still is."""

import queue

from daq.consumer import LAG_TOLERANCE_S, Consumer
from daq.frames import RawFrame
from daq.pipeline import Pipeline
from daq.service_config import PublishSettings
from dbc.encoding import FrameEncoder
from tests.helpers import LEGS, example_machine

CONFIG, DATABASE = example_machine()


def feed(consumer: Consumer, encoder: FrameEncoder, leg: str, t_s: float) -> None:
    frame = encoder.encode(
        f"LEG_{leg}", {f"{leg}_pPiston": 5e6, f"{leg}_pRod": 1e6, f"{leg}_Status": "ok"}
    )
    consumer.handle(RawFrame(t_s, frame.arbitration_id, frame.is_extended_id, frame.data))


def make() -> tuple[Consumer, FrameEncoder, list[float]]:
    clock = [0.0]
    consumer = Consumer(
        Pipeline.from_config(CONFIG, DATABASE),
        queue.Queue(),
        PublishSettings(),
        now=lambda: clock[0],
    )
    return consumer, FrameEncoder(DATABASE, CONFIG.protection), clock


def test_lagging_consumer_does_not_make_fresh_legs_stale() -> None:
    consumer, encoder, clock = make()
    for leg in LEGS:
        feed(consumer, encoder, leg, 100.0)
    clock[0] = 100.0 + LAG_TOLERANCE_S * 0.8  # the consumer is 0.4 s behind the bus
    snapshot = consumer.pipeline.snapshot(consumer.judged_at())
    assert all(estimate.valid for estimate in snapshot.legs.values())


def test_a_silent_sensor_is_stale_while_the_others_talk() -> None:
    consumer, encoder, clock = make()
    for leg in LEGS:
        feed(consumer, encoder, leg, 100.0)
    for step in range(1, 6):  # 50 ms more of every leg but SB2_F3
        for leg in LEGS[:5]:
            feed(consumer, encoder, leg, 100.0 + 0.01 * step)
    clock[0] = 100.06
    snapshot = consumer.pipeline.snapshot(consumer.judged_at())
    assert snapshot.legs["SB2_F3"].reasons == ("stale",)
    assert all(snapshot.legs[leg].valid for leg in LEGS[:5])


def test_a_silent_bus_makes_every_leg_stale_after_the_tolerance() -> None:
    consumer, encoder, clock = make()
    for leg in LEGS:
        feed(consumer, encoder, leg, 100.0)
    clock[0] = 100.0 + LAG_TOLERANCE_S + 0.05
    snapshot = consumer.pipeline.snapshot(consumer.judged_at())
    assert all(estimate.reasons == ("stale",) for estimate in snapshot.legs.values())
