"""Hostile payloads over a real Zenoh session: counted and skipped, never fatal (issue 15.2)."""

from __future__ import annotations

import json
import uuid
from pathlib import Path

import pytest
import zenoh
from mcap.reader import make_reader

from daq.live.feed import LiveFeed
from daq.live.state import LiveState
from daq.service_config import load_service_config
from tests.daq.service_support import (
    WAIT_S,
    Collector,
    free_port,
    peer_config,
    subscriber_session,
    write_service_config,
)
from tests.daq.test_report_truth_recording import wait_for_subscriber
from tests.daq.test_service_live import live_service, zenoh_port

HOSTILE = [
    b'{"t_unix_s": 1750000000000.0, "legs": {}}',  # milliseconds: beyond the MCAP log time
    b"[" * 100_000,  # RecursionError in json
    b'{"t_unix_s": 1' + b"0" * 400 + b', "legs": {}}',  # OverflowError
    b'{"t_unix_s": 1750000000.0, "legs": {"SB1_F1": {"force_true_N": 1' + b"0" * 400 + b"}}}",
    b"\xff\xfe",
]
#: A 100 kB payload must not be dropped on the way by the default congestion control.
BLOCK = zenoh.CongestionControl.BLOCK
GOOD = b'{"t_unix_s": 1750000000.5, "legs": {"SB1_F1": {"force_true_N": 5.0}}}'


def test_recorder_counts_hostile_truth_and_keeps_recording(tmp_path: Path) -> None:
    path = write_service_config(
        tmp_path,
        channel=f"test-{uuid.uuid4().hex}",
        port=free_port(),
        recording=tmp_path / "rec",
        truth=True,
    )
    config = load_service_config(path)
    prefix = config.zenoh.key_prefix
    with live_service(config) as service, subscriber_session(zenoh_port(config)) as session:
        collector = Collector(session, f"{prefix}/status")
        collector.wait_for(f"{prefix}/status")
        for payload in [*HOSTILE, GOOD, *HOSTILE, GOOD]:
            session.put(f"{prefix}/sim/truth", payload, congestion_control=BLOCK)
        status = collector.wait_for(
            f"{prefix}/status", lambda s: s["recording"]["rejected"] == 2 * len(HOSTILE)
        )
        assert service.recorder is not None and service.recorder.alive
        assert status["recording"]["failed_items"] == 0 and not status["recording"]["failing"]
        recorded_path = service.recorder.paths[0]
    with open(recorded_path, "rb") as file:
        reader = make_reader(file)
        assert reader.get_summary() is not None
        truth = [json.loads(m.data) for _, _, m in reader.iter_messages(topics=["/sim/truth"])]
    assert truth == [json.loads(GOOD)] * 2


@pytest.mark.parametrize("suffix", ["ground", "status", "metrics"])
def test_live_view_counts_hostile_payloads_and_keeps_going(suffix: str) -> None:
    port = free_port()
    prefix = f"portal/{uuid.uuid4().hex}"
    hostile = [
        *HOSTILE,
        b'{"t": 1'
        + b"0" * 400
        + b', "uptime_s": 1e999, "legs": {"A": {"force_N": 1'
        + b"0" * 400
        + b'}}, "dropped": {"rx": 1'
        + b"0" * 400
        + b'}, "legs_in_contact": 1'
        + b"0" * 400
        + b"}",
        b'{"legs": {"A": {"reasons": [1' + b"0" * 400 + b']}}, "bus": [], "frames": 5}',
    ]
    with (
        zenoh.open(peer_config(listen=f"tcp/127.0.0.1:{port}")) as publisher,
        subscriber_session(port) as viewer,
        LiveFeed(viewer, prefix) as feed,
    ):
        state = LiveState(prefix)
        wait_for_subscriber(publisher, f"{prefix}/{suffix}")
        for payload in [*hostile, b'{"t": 1750000000.0}']:
            publisher.put(f"{prefix}/{suffix}", payload, congestion_control=BLOCK)
        received = 0
        while received < len(hostile) + 1:
            item = feed.wait(WAIT_S)
            assert item is not None, f"{received} received"
            received += 1
            state.apply(item.key, item.payload, item.received_s)
    held = {"ground": state.ground, "status": state.status, "metrics": state.metrics}[suffix]
    assert held is not None and held.value.t_s == 1750000000.0
    assert state.ignored == 2  # the two that are no JSON object; the rest read as None
