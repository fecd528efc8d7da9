"""Simulation truth in the service's recording: Zenoh ``<prefix>/sim/truth`` to MCAP ``/sim/truth``.

Real Zenoh sessions on loopback, the service in-process on a python-can ``virtual``
bus, real MCAP files; the truth is put by the simulator bridge's own publisher.
"""

from __future__ import annotations

import json
import math
import threading
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
import zenoh
from mcap.reader import make_reader

from daq.recorder import Recorder
from daq.service_config import RecordingSettings, ServiceConfig, load_service_config
from daq.sim_truth import TruthRecord, TruthSubscriber, truth_payload
from dbc.errors import ConfigError
from sim_bridge.truth import LegTruth, TruthSample, ZenohTruthPublisher
from tests.daq.service_support import (
    WAIT_S,
    can_message,
    free_port,
    leg_signals,
    peer_config,
    write_service_config,
)
from tests.daq.test_service_live import encoder_for, live_service, sender, zenoh_port
from tests.helpers import LEGS, example_machine

T0_S = 1_750_000_000.0


def sample(i: int) -> TruthSample:
    """A truth sample with distinct values per leg and row (and one unknown force)."""
    legs = {
        leg: LegTruth(
            force_true_N=math.nan if (i, leg) == (2, "SB2_F3") else 1000.0 * i + j,
            p_piston_Pa=9e6 + i,
            p_rod_Pa=1e6 + j,
            pressure_true_Pa=(1000.0 * i + j) / 0.33,
        )
        for j, leg in enumerate(LEGS)
    }
    return TruthSample(t_unix_s=T0_S + 0.01 * i, t_cycle_s=0.01 * i, cycle=0, legs=legs)


def truth_messages(path: Path) -> list[tuple[int, dict[str, Any]]]:
    """(log time ns, payload) of every /sim/truth message; checks channel and schema."""
    with open(path, "rb") as file:
        reader = make_reader(file)
        out = []
        for schema, channel, message in reader.iter_messages(topics=["/sim/truth"]):
            assert schema is not None and schema.name == "portal_daq.SimTruth"
            assert schema.encoding == "jsonschema" and channel.message_encoding == "json"
            payload = json.loads(message.data)
            assert set(json.loads(schema.data)["required"]) <= set(payload)
            out.append((message.log_time, payload))
    return out


def wait_for_subscriber(session: zenoh.Session, key: str) -> None:
    """Return once a subscriber elsewhere matches ``key`` (so nothing put is lost)."""
    matched = threading.Event()
    publisher = session.declare_publisher(key)
    listener = publisher.declare_matching_listener(
        lambda status: matched.set() if status.matching else None
    )
    try:
        if not publisher.matching_status.matching:
            assert matched.wait(WAIT_S), f"no subscriber on {key}"
    finally:
        listener.undeclare()
        publisher.undeclare()


@contextmanager
def bridge_session(config: ServiceConfig) -> Iterator[zenoh.Session]:
    """A Zenoh session as the simulator bridge opens it, connected to the service."""
    session = zenoh.open(peer_config(connect=f"tcp/127.0.0.1:{zenoh_port(config)}"))
    try:
        yield session
    finally:
        session.close()


def service_config(tmp_path: Path, extra: str = "", truth: bool | None = True) -> ServiceConfig:
    path = write_service_config(
        tmp_path,
        channel=f"test-{uuid.uuid4().hex}",
        port=free_port(),
        recording=tmp_path / "rec",
        truth=truth,
        extra=extra,
    )
    return load_service_config(path)


def test_truth_published_by_the_bridge_is_recorded_at_its_frame_time(tmp_path: Path) -> None:
    config = service_config(tmp_path)
    prefix = config.zenoh.key_prefix
    samples = [sample(i) for i in range(5)]
    with live_service(config) as service, bridge_session(config) as session:
        assert service.truth is not None and service.truth.key == f"{prefix}/sim/truth"
        wait_for_subscriber(session, f"{prefix}/sim/truth")
        with ZenohTruthPublisher(session, prefix, LEGS) as publisher:
            for truth in samples[:3]:
                publisher.write(truth)
            session.put(f"{prefix}/sim/truth", b'{"legs": {}}')  # no time: rejected
            session.put(f"{prefix}/sim/truth", b"not json")  # rejected
            for truth in samples[3:]:
                publisher.write(truth)
        with sender(config) as bus:  # frames go on being recorded next to the truth
            frame = encoder_for(config).encode("LEG_SB1_F1", leg_signals("SB1_F1", 9e6, 1e6))
            bus.send(can_message(frame, T0_S))
        deadline = time.monotonic() + WAIT_S
        while (
            service.truth.received < 7 or service.pipeline.frames < 1
        ) and time.monotonic() < deadline:
            time.sleep(0.01)
        assert service.truth.received == 7  # the per-leg keys are not subscribed
        recorder = service.recorder
        assert recorder is not None
    assert recorder.rejected == 2 and recorder.dropped == 0 and recorder.errors == 0
    recorded = truth_messages(recorder.paths[0])
    assert [t_ns for t_ns, _ in recorded] == [round(s.t_unix_s * 1e9) for s in samples]
    assert [payload for _, payload in recorded] == [s.as_json() for s in samples]
    assert recorded[2][1]["legs"]["SB2_F3"]["force_true_N"] is None  # NaN stays null
    with open(recorder.paths[0], "rb") as file:
        topics = {c.topic for c in make_reader(file).get_summary().channels.values()}  # type: ignore[union-attr]
    assert {"/sim/truth", "/can/raw", "/leg/SB1_F1/ground"} <= topics


def test_truth_recording_can_be_switched_off(tmp_path: Path) -> None:
    config = service_config(tmp_path, extra="truth = false\n", truth=None)
    assert config.recording.truth is False
    with live_service(config) as service:
        assert service.truth is None
        recorder = service.recorder
        assert recorder is not None
    assert truth_messages(recorder.paths[0]) == []


def test_truth_switch_must_be_a_boolean(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"recording\.truth"):
        service_config(tmp_path, extra='truth = "yes"\n', truth=None)


def test_the_callback_only_enqueues_and_a_full_queue_drops(tmp_path: Path) -> None:
    """The recorder thread is not running: the callback must neither block nor write."""
    _, database = example_machine()
    settings = RecordingSettings(directory=tmp_path, queue_size=2)
    recorder = Recorder(settings, database, machine_id="m")
    config = zenoh.Config()
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("listen/endpoints", "[]")
    five = threading.Event()

    def submit(record: TruthRecord) -> None:
        recorder.submit(record)
        if subscriber.received == 5:
            five.set()

    with zenoh.open(config) as session:
        subscriber = TruthSubscriber(session, "test/sim/truth", submit)
        with subscriber:
            for i in range(5):
                session.put("test/sim/truth", json.dumps(sample(i).as_json()))
            assert five.wait(WAIT_S)
        subscriber.close()  # idempotent
    assert recorder.depth == 2 and recorder.dropped == 3
    with recorder:  # now the thread writes what was queued
        pass
    recorded = truth_messages(recorder.paths[0])
    assert [payload["t_unix_s"] for _, payload in recorded] == [T0_S, T0_S + 0.01]


@pytest.mark.parametrize(
    ("payload", "valid"),
    [
        (b'{"t_unix_s": 1750000000.5, "legs": {}}', True),
        (b'{"t_unix_s": 1750000000, "t_cycle_s": 0.0, "cycle": 0, "legs": {"A": {}}}', True),
        (b'{"t_unix_s": 1750000000500, "legs": {}}', False),  # milliseconds
        (b'{"t_unix_s": 12.5, "legs": {}}', False),  # not a plausible Unix time
        (b'{"t_unix_s": 1750000000, "legs": {"A": {"force_true_N": "1"}}}', False),
        (b'{"t_unix_s": 1750000000, "legs": {"A": {"force_true_N": 1e999}}}', False),
        (b'{"t_unix_s": 1750000000, "legs": {"A": {"force_true_N": 1' + b"0" * 400 + b"}}}", False),
        (b'{"t_unix_s": 1' + b"0" * 400 + b', "legs": {}}', False),
        (b"[" * 100_000, False),
        (b'{"t_unix_s": null, "legs": {}}', False),
        (b'{"t_unix_s": true, "legs": {}}', False),
        (b'{"t_unix_s": "12.5", "legs": {}}', False),
        (b'{"t_unix_s": 12.5, "legs": []}', False),
        (b'{"t_unix_s": 12.5}', False),
        (b'{"t_unix_s": 1e999, "legs": {}}', False),  # json reads inf
        (b"[1, 2]", False),
        (b"\xff\xfe", False),
        (b"", False),
    ],
)
def test_what_counts_as_a_truth_sample(payload: bytes, valid: bool) -> None:
    parsed = truth_payload(TruthRecord(payload))
    assert (parsed is not None) is valid
    if valid:
        assert parsed == json.loads(payload)
