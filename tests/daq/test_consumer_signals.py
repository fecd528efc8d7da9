"""The consumer publishes each message's decoded signals at most ``signals_max_rate_hz``
per J1939 sender, by frame time."""

import queue
from collections.abc import Sequence
from typing import Any

from daq.consumer import Consumer
from daq.frames import RawFrame
from daq.pipeline import Pipeline
from daq.service_config import PublishSettings
from dbc.encoding import FrameEncoder
from dbc.machine import load_machine_config
from tests.helpers import ROOT


def test_signals_are_rate_limited_per_j1939_sender() -> None:
    """Twelve transducers share one PGN: each sender's signals get the 10 Hz, not the
    PGN's (one sender would hide the others on a dashboard)."""
    config, database = load_machine_config(ROOT / "deploy/examples/j1939/portal-daq.toml")
    published: list[tuple[str, Any]] = []

    class Collect:
        def submit(self, suffix: str, payload: Any) -> None:
            published.append((suffix, payload))

        def submit_batch(self, messages: Sequence[tuple[str, Any]]) -> None:
            published.extend(messages)

    consumer = Consumer(
        Pipeline.from_config(config, database),
        queue.Queue(),
        PublishSettings(),
        publisher=Collect(),
    )
    encoder = FrameEncoder.from_config(config, database)
    signals = {"Pressure": 100e5, "Status": 0, "Temperature": 40.0}
    frames = [
        RawFrame(100.0 + 0.01 * step, encoded.arbitration_id, True, encoded.data)
        for step in range(15)  # 150 ms: each sender is due at 0 and 100 ms
        for address in (0x21, 0x22, 0x23)
        for encoded in [encoder.encode("HYD_PRESS", signals, source_address=address)]
    ]
    consumer.handle_batch(frames)
    senders = [
        (payload["source_address"], payload["t"])
        for suffix, payload in published
        if suffix == "signals/HYD_PRESS"
    ]
    for address in (0x21, 0x22, 0x23):  # at 0 and 100 ms (or 110, as frame times round)
        first, second = [t for sender, t in senders if sender == address]
        assert first == 100.0 and 0.1 <= second - first < 0.12
    assert len(senders) == 6
