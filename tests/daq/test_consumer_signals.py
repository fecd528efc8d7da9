"""The consumer publishes each message's decoded signals at most ``signals_max_rate_hz``
per J1939 sender and multiplexer value, by frame time."""

import queue
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from cantools.database import Database

from daq.consumer import Consumer
from daq.frames import RawFrame
from daq.pipeline import Pipeline
from daq.service_config import PublishSettings
from dbc.encoding import FrameEncoder
from dbc.machine import MachineConfig, load_machine_config
from tests.daq.service_support import leg_signals
from tests.helpers import ROOT

STRANGER = ROOT / "tests/files/stranger"


class Collect:
    """A publisher that keeps what it is given."""

    def __init__(self) -> None:
        self.published: list[tuple[str, Any]] = []

    def submit(self, suffix: str, payload: Any) -> None:
        self.published.append((suffix, payload))

    def submit_batch(self, messages: Sequence[tuple[str, Any]]) -> None:
        self.published.extend(messages)


def consumer_of(config_path: Path) -> tuple[Consumer, Collect, MachineConfig, Database]:
    config, database = load_machine_config(config_path)
    publisher = Collect()
    consumer = Consumer(
        Pipeline.from_config(config, database),
        queue.Queue(),
        PublishSettings(),
        publisher=publisher,
    )
    return consumer, publisher, config, database


def test_signals_are_rate_limited_per_j1939_sender() -> None:
    """Twelve transducers share one PGN: each sender's signals get the 10 Hz, not the
    PGN's (one sender would hide the others on a dashboard)."""
    consumer, publisher, config, database = consumer_of(
        ROOT / "deploy/examples/j1939/portal-daq.toml"
    )
    published = publisher.published
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


def test_signals_are_rate_limited_per_multiplexer_value() -> None:
    """A hub sends its two pages in turn every 10 ms: at 10 Hz for the message as one, the
    frame due every 100 ms would always be page 0 and page 1 never shown."""
    consumer, publisher, config, database = consumer_of(STRANGER / "mux_pages.toml")
    encoder = FrameEncoder.from_config(config, database)
    pages = [
        {"Page": 0, "pCap0": 50e5, "pAnn0": 10e5, "HubAlive": 0, "HubCrc": 0},
        {"Page": 1, "pCap1": 60e5, "pAnn1": 20e5, "Spare1": 0},
    ]
    frames = []
    for step in range(16):  # 160 ms
        encoded = encoder.encode("MUXHUB", pages[step % 2])  # the counter, CRC on page 0 only
        frames.append(RawFrame(100.0 + 0.01 * step, encoded.arbitration_id, False, encoded.data))
    consumer.handle_batch(frames)
    shown = [
        (str(payload["signals"]["Page"]), payload["t"])
        for suffix, payload in publisher.published
        if suffix == "signals/MUXHUB"
    ]
    assert [page for page, _ in shown] == ["bank_0", "bank_1", "bank_0", "bank_1"]
    (_, first0), (_, first1), (_, second0), (_, second1) = shown
    assert (first0, first1) == (100.0, 100.01)
    assert 0.1 <= second0 - first0 < 0.13 and 0.1 <= second1 - first1 < 0.13


def test_signals_go_on_after_the_clock_steps_back() -> None:
    """NTP steps the clock back an hour: the frames after the step are stamped before the
    last one published, and each message's signals must still go out at the rate (they
    went out again only once frame times passed that one, an hour later)."""
    consumer, publisher, config, database = consumer_of(ROOT / "dbc/machine.example.toml")
    encoder = FrameEncoder.from_config(config, database)
    encoded = encoder.encode("LEG_SB1_F1", leg_signals("SB1_F1", 9.0e6, 1.0e6))
    step_back_s = 3600.0
    frames = [  # 10 ms apart for 2 s, the clock stepped back after the first second
        RawFrame(
            1000.0 + 0.01 * step - (step_back_s if step >= 100 else 0.0),
            encoded.arbitration_id,
            False,
            encoded.data,
        )
        for step in range(200)
    ]
    consumer.handle_batch(frames)
    shown = [p["t"] for suffix, p in publisher.published if suffix == "signals/LEG_SB1_F1"]
    before = [t for t in shown if t >= 1000.0]
    after = [t for t in shown if t < 1000.0]
    assert len(before) == 10 and len(after) == 10
    assert after[0] == 1001.0 - step_back_s
