"""The service in-process: python-can virtual bus in, real Zenoh on loopback and MCAP out."""

from __future__ import annotations

import io
import json
import queue
import subprocess
import sys
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import can
import pytest
import zenoh
from mcap.reader import make_reader

from daq import can_batch
from daq.bus_reader import BusReader, PythonCanSource
from daq.frames import BusEvent, RawFrame
from daq.mcap_reading import json_items
from daq.payloads import json_bytes, leg_ground
from daq.pipeline import Pipeline
from daq.replay import replay, results
from daq.report.loading import load_recording
from daq.runner import build_recorder, bus_factory
from daq.service import Service
from daq.service_config import ServiceConfig, load_service_config
from daq.zenoh_session import zenoh_config
from dbc.decoding import FrameDecoder
from dbc.encoding import FrameEncoder
from tests.daq.service_support import (
    WAIT_S,
    Collector,
    assert_estimates_match,
    can_message,
    free_port,
    leg_messages,
    leg_signals,
    pressure_series,
    running,
    subscriber_session,
    write_service_config,
)
from tests.helpers import LEGS, recorded_raw_frames

FRAMES_PER_LEG = 25


@pytest.fixture
def config(tmp_path: Path) -> ServiceConfig:
    path = write_service_config(
        tmp_path, channel=f"test-{uuid.uuid4().hex}", port=free_port(), recording=tmp_path / "rec"
    )
    return load_service_config(path)


@contextmanager
def live_service(config: ServiceConfig) -> Iterator[Service]:
    """The service on a virtual bus, with a real Zenoh session and recorder, running
    (:meth:`Service.run`) in a thread as it does in the main thread of the process."""
    filters = FrameDecoder(config.database, config.machine.protection).receive_filters
    recorder = build_recorder(config)  # as deployed: in a process of its own
    with zenoh.open(zenoh_config(config.zenoh)) as session:
        service = Service(
            config,
            open_bus=bus_factory(config.bus, filters),
            session=session,
            recorder=recorder,
        )
        with running(service):
            yield service


@contextmanager
def sender(config: ServiceConfig) -> Iterator[can.BusABC]:
    bus = can.Bus(interface="virtual", channel=config.bus.channel, preserve_timestamps=True)
    try:
        yield bus
    finally:
        bus.shutdown()


def zenoh_port(config: ServiceConfig) -> int:
    return int(config.zenoh.listen[0].rsplit(":", 1)[1])


def connected_collector(session: zenoh.Session, prefix: str) -> Collector:
    """A collector on ``<prefix>/**`` that has seen the service (so nothing is missed)."""
    collector = Collector(session, f"{prefix}/**")
    collector.wait_for(f"{prefix}/ground")
    return collector


def encoder_for(config: ServiceConfig) -> FrameEncoder:
    return FrameEncoder(config.database, config.machine.protection)


def recorded(path: Path) -> list[tuple[str, dict]]:
    """The JSON payloads of a recording, a leg's batches unpacked (``/can/raw`` batches:
    :func:`recorded_raw_frames`)."""
    with open(path, "rb") as file:
        reader = make_reader(file)
        return [
            (channel.topic, payload)
            for _, channel, message in reader.iter_messages(log_time_order=False)
            if channel.message_encoding == "json"
            for payload in json_items(message.data)
        ]


def test_published_estimates_match_equation_4_and_running_median(config: ServiceConfig) -> None:
    prefix = config.zenoh.key_prefix
    with live_service(config), subscriber_session(zenoh_port(config)) as session:
        collector = connected_collector(session, prefix)
        with sender(config) as bus:
            for message in leg_messages(encoder_for(config), FRAMES_PER_LEG, time.time()):
                bus.send(message)
        keys = {leg: f"{prefix}/leg/{leg}/ground" for leg in LEGS}
        collector.wait_until(
            lambda: all(len(collector.of(key)) >= FRAMES_PER_LEG for key in keys.values())
        )
        for seed, (leg, key) in enumerate(keys.items()):
            sent = pressure_series(FRAMES_PER_LEG, seed)
            assert_estimates_match(config.machine, leg, sent, collector.of(key))
        encodings = {encoding for key, _, encoding in collector.samples}
        assert encodings == {"application/json"}
        # 25 frames 10 ms apart, signals at most 10 Hz by default: frames 0, 10, 20
        # (or 11 and 21, as frame times round)
        signals = collector.of(f"{prefix}/signals/LEG_SB1_F1")
        assert len(signals) == 3 and signals[0]["crc_ok"] is True
        times = [s["t"] for s in signals]
        assert all(0.1 <= b - a < 0.12 for a, b in zip(times, times[1:], strict=False))

        ground = collector.wait_for(
            f"{prefix}/ground", lambda p: p["legs"]["SB2_F3"]["force_N"] is not None
        )
        assert set(ground["legs"]) == set(LEGS)
        assert ground["weight_N"] == pytest.approx(config.machine.weight_N)
        assert "residual_N" in ground and "total_force_N" in ground


def test_stale_legs_and_nan_are_null_not_invalid_json(config: ServiceConfig) -> None:
    prefix = config.zenoh.key_prefix
    with live_service(config), subscriber_session(zenoh_port(config)) as session:
        collector = connected_collector(session, prefix)
        ground = collector.wait_for(f"{prefix}/ground")
        for leg in ground["legs"].values():  # no frame yet: stale, NaN forces as null
            assert leg["valid"] is False and "stale" in leg["reasons"]
            assert leg["force_N"] is None
        metrics = collector.wait_for(f"{prefix}/metrics")
        assert metrics["legs"]["SB1_F1"]["peak_pressure_Pa"] is None


def test_bad_frames_are_counted_and_recorded_raw(config: ServiceConfig) -> None:
    prefix = config.zenoh.key_prefix
    encoder = encoder_for(config)
    t0 = time.time()
    good = encoder.encode("LEG_SB1_F1", leg_signals("SB1_F1", 9e6, 1e6))
    bad_crc = encoder.encode("LEG_SB1_F1", leg_signals("SB1_F1", 9e6, 1e6), corrupt_crc=True)
    # After a bad CRC the counter check resynchronises on the next good frame.
    resync = encoder.encode("LEG_SB1_F1", leg_signals("SB1_F1", 9e6, 1e6))
    jump = encoder.encode("LEG_SB1_F1", leg_signals("SB1_F1", 9e6, 1e6), counter=9)
    messages = [
        can_message(good, t0),
        can.Message(timestamp=t0, arbitration_id=0x7AB, data=b"\x01\x02", is_extended_id=False),
        can.Message(timestamp=t0, arbitration_id=0x100, data=good.data[:7], is_extended_id=False),
        can.Message(timestamp=t0, arbitration_id=0x1ABCDE, data=b"", is_extended_id=True),
        can.Message(timestamp=t0, arbitration_id=0x100, is_remote_frame=True, dlc=8),
        can.Message(timestamp=t0, arbitration_id=0x80, is_error_frame=True, dlc=8, data=bytes(8)),
        can_message(bad_crc, t0 + 0.01),
        can_message(resync, t0 + 0.02),
        can_message(jump, t0 + 0.03),
    ]
    with live_service(config) as service, subscriber_session(zenoh_port(config)) as session:
        collector = connected_collector(session, prefix)
        with sender(config) as bus:
            for message in messages:
                bus.send(message)
        status = collector.wait_for(
            f"{prefix}/status", lambda s: s["frames"]["processed"] == len(messages)
        )
        assert status["bad"] == {
            "unknown_id": 2,
            "wrong_dlc": 1,
            "remote_frame": 1,
            "error_frame": 1,
            "crc": 1,
            "counter": 1,
        }
        assert status["frames"]["unknown"] == 2 and status["frames"]["bad"] == 7
        assert status["bus"]["state"] == "up" and status["dropped"]["rx"] == 0
        assert set(status["queues"]) == {"rx", "publish", "record"}
        assert status["uptime_s"] > 0 and status["frames_per_s"] >= 0
        # Healthy but for the silence after the burst, if a status period passed, and the
        # error frame (class 0x080), if this is the status of its period.
        expected = ("no frame for", "CAN controller: bus error +1 (error frames)")
        assert all(p.startswith(expected) for p in status["problems"]), status
        assert status["leg_faults"] == {"SB1_F1": {"crc": 1, "counter": 1}}
        leg = collector.of(f"{prefix}/leg/SB1_F1/ground")
        assert [m["reasons"] for m in leg] == [[], ["crc"], [], ["counter"]]
        path = service.recorder.paths[0]  # type: ignore[union-attr]
    raw = recorded_raw_frames(path)  # the frames as received; replay derives the kinds
    assert [r.arbitration_id for r in raw] == [0x100, 0x7AB, 0x100, 0x1ABCDE, 0x100, 0x80] + [
        0x100
    ] * 3
    assert raw[1].data == bytes([1, 2]) and raw[3].is_extended_id and raw[2].dlc == 7
    assert raw[4].is_remote_frame and raw[5].is_error_frame and not raw[0].is_remote_frame
    pipeline = Pipeline.from_config(config.machine, config.database)
    assert [pipeline.process(r).error_kind for r in raw] == [
        None,
        "unknown_id",
        "wrong_dlc",
        "unknown_id",
        "remote_frame",
        "error_frame",
        None,
        None,
        None,
    ]


def test_late_joiner_gets_the_latest_value_of_every_key(config: ServiceConfig) -> None:
    """zenoh.ext: an advanced subscriber with history gets each key's latest sample."""
    prefix = config.zenoh.key_prefix
    with live_service(config), subscriber_session(zenoh_port(config)) as session:
        collector = connected_collector(session, prefix)
        with sender(config) as bus:
            for message in leg_messages(encoder_for(config), 5, time.time()):
                bus.send(message)
        last_key = f"{prefix}/leg/SB2_F3/ground"
        collector.wait_until(lambda: len(collector.of(last_key)) == 5)
        collector.wait_for(f"{prefix}/status")
        with subscriber_session(zenoh_port(config)) as late:
            history = Collector(late, f"{prefix}/leg/*/ground", advanced=True)
            history.wait_until(lambda: len({k for k, _, _ in history.samples}) == len(LEGS))
        for leg in LEGS:
            key = f"{prefix}/leg/{leg}/ground"
            assert history.of(key) == [collector.of(key)[-1]]


def test_liveliness_token_while_running(config: ServiceConfig) -> None:
    prefix = config.zenoh.key_prefix
    with live_service(config), subscriber_session(zenoh_port(config)) as session:
        connected_collector(session, prefix)
        tokens = [str(r.ok.key_expr) for r in session.liveliness().get(f"{prefix}/alive")]
        assert tokens == [f"{prefix}/alive"]


def send_and_wait(config: ServiceConfig, messages: list[can.Message]) -> list[Path]:
    """Run the service, send ``messages``, wait until it processed them; its files."""
    with live_service(config) as service:
        with sender(config) as bus:
            for message in messages:
                bus.send(message)
        deadline = time.monotonic() + WAIT_S
        while service.pipeline.frames < len(messages) and time.monotonic() < deadline:
            time.sleep(0.01)
        assert service.pipeline.frames == len(messages)
        recorder = service.recorder
        assert recorder is not None
    return recorder.paths


def assert_replay_is_live(
    paths: Path | list[Path], live: list[dict], config_path: Path | None = None
) -> None:
    """Replaying ``paths`` gives the ``live`` estimates (:func:`live_estimates`), bit for
    bit, in the same order of time and leg."""
    out = io.StringIO()
    assert replay(paths, out, config_path) == len(live)
    rows = out.getvalue().splitlines()
    assert rows[0].startswith("leg,t,force_N,force_raw_N,pressure_Pa")
    replayed = sorted((row.split(",") for row in rows[1:]), key=lambda row: (float(row[1]), row[0]))
    for row, estimate in zip(replayed, live, strict=True):
        assert row[0] == estimate["leg"]
        numbers = [float(x) for x in row[1:7]]
        keys = ("t", "force_N", "force_raw_N", "pressure_Pa", "p_piston_Pa", "p_rod_Pa")
        assert numbers == [estimate[k] for k in keys]  # bit for bit
        assert row[7:9] == [str(int(estimate["contact"])), str(int(estimate["valid"]))]
        assert row[9] == "|".join(estimate["reasons"])


def live_estimates(paths: list[Path]) -> list[dict]:
    """The recorded leg estimates by time, then leg (the file has a batch per leg)."""
    estimates = [p for path in paths for topic, p in recorded(path) if topic.startswith("/leg/")]
    return sorted(estimates, key=lambda estimate: (estimate["t"], estimate["leg"]))


def test_replay_of_the_recording_equals_the_live_estimates(config: ServiceConfig) -> None:
    encoder = encoder_for(config)
    messages = leg_messages(encoder, FRAMES_PER_LEG, time.time())
    t = messages[-1].timestamp
    messages += [  # faults too: they must replay the same way
        can_message(encoder.encode("LEG_SB1_F2", leg_signals("SB1_F2", 2e7, 1e6), counter=3), t),
        can_message(
            encoder.encode("LEG_SB1_F2", leg_signals("SB1_F2", 1e7, 1e6), corrupt_crc=True),
            t + 0.01,
        ),
        can_message(encoder.encode("LEG_SB1_F2", leg_signals("SB1_F2", 1e7, 1e6)), t + 0.02),
    ]
    paths = send_and_wait(config, messages)
    live = live_estimates(paths[:1])
    assert len(live) == 6 * FRAMES_PER_LEG + 3

    for config_path in (None, Path(config.source)):
        assert_replay_is_live(paths[0], live, config_path)
    sb1_f2 = [estimate for estimate in live if estimate["leg"] == "SB1_F2"]
    assert sb1_f2[-3]["reasons"] == ["counter"] and sb1_f2[-2]["reasons"] == ["crc"]


def test_replay_of_a_run_rotated_every_second_equals_the_live_estimates(tmp_path: Path) -> None:
    path = write_service_config(
        tmp_path,
        channel=f"test-{uuid.uuid4().hex}",
        port=free_port(),
        recording=tmp_path / "rec",
        max_duration_s=1.0,
    )
    config = load_service_config(path)
    # 3.5 s of frame time, every leg on the ground (contact) with a median to carry over.
    # Stamped 30 s after the service's start, so that the file its bus event (wall time)
    # opens holds nothing else: a file spans max_duration_s from its first message.
    paths = send_and_wait(config, leg_messages(encoder_for(config), 350, time.time() + 30.0))
    assert len(paths) == 5 and live_estimates(paths[:1]) == []
    live = live_estimates(paths)
    assert len(live) == 6 * 350
    second_file = live_estimates(paths[2:3])
    assert second_file and all(e["contact"] for e in second_file)

    assert_replay_is_live([tmp_path / "rec"], live)  # the directory
    assert_replay_is_live(paths[::-1], live)  # the files, in any order
    report_input = load_recording(tmp_path / "rec")  # the report reads the whole run too
    assert report_input.counts.frames == len(live)
    assert report_input.name.endswith("(5 files)")


def test_mcap_channels_and_schemas_are_readable(config: ServiceConfig) -> None:
    with live_service(config) as service:
        with sender(config) as bus:
            for message in leg_messages(encoder_for(config), 3, time.time()):
                bus.send(message)
        deadline = time.monotonic() + WAIT_S
        while service.pipeline.frames < 18 and time.monotonic() < deadline:
            time.sleep(0.01)
        recorder = service.recorder
        assert recorder is not None
    with open(recorder.paths[0], "rb") as file:
        reader = make_reader(file)
        summary = reader.get_summary()
        assert summary is not None  # finished cleanly: summary present
        topics = {channel.topic: channel for channel in summary.channels.values()}
        # signals are not recorded by default ([recording] signals = false)
        legs = {f"/leg/{leg}/ground" for leg in LEGS}
        assert set(topics) == {"/can/raw", "/daq/bus", "/ground"} | legs
        raw = topics.pop("/can/raw")
        assert raw.message_encoding == can_batch.ENCODING
        raw_schema = summary.schemas[raw.schema_id]
        assert (
            raw_schema.name == "portal.CanFrameBatch"
            and raw_schema.encoding == raw.message_encoding
        )
        assert raw_schema.data.decode() == can_batch.SCHEMA_TEXT
        for channel in topics.values():
            assert channel.message_encoding == "json"
            schema = summary.schemas[channel.schema_id]
            assert schema.encoding == "jsonschema"
            assert json.loads(schema.data)["type"] == "object"
        assert summary.statistics is not None and summary.statistics.message_count > 0
        names = {a.name for a in reader.iter_attachments()}
        assert names == {"portal-daq.toml", "portal_sensors.dbc"}
        frames = 0
        for schema, channel, message in reader.iter_messages():
            assert schema is not None
            if channel.topic == "/can/raw":
                frames += len(list(can_batch.decode(message.data)))
                continue
            payload = json.loads(message.data)
            assert set(json.loads(schema.data)["required"]) <= set(payload)
            if channel.topic.startswith("/leg/"):  # a leg's estimates, one batch
                assert payload["leg"] == channel.topic.split("/")[2]
                required = json.loads(schema.data)["properties"]["estimates"]["items"]["required"]
                assert all(set(required) <= set(item) for item in payload["estimates"])
        assert frames == 18


def test_reader_never_blocks_and_counts_overflow() -> None:
    channel = f"test-{uuid.uuid4().hex}"
    inbox: queue.Queue[RawFrame | BusEvent] = queue.Queue(maxsize=5)
    reader = BusReader(
        lambda: PythonCanSource(can.Bus(interface="virtual", channel=channel)),
        inbox,
        channel=channel,
    )
    with reader:
        assert reader.opened.wait(WAIT_S)
        with can.Bus(interface="virtual", channel=channel) as bus:
            for i in range(20):
                bus.send(can.Message(arbitration_id=0x100 + i, data=b"", is_extended_id=False))
            deadline = time.monotonic() + WAIT_S
            while reader.received < 20 and time.monotonic() < deadline:
                time.sleep(0.01)
    assert reader.received == 20
    items = [inbox.get_nowait() for _ in range(inbox.qsize())]
    assert isinstance(items[0], BusEvent) and items[0].state == "up"
    assert [f.arbitration_id for f in items[1:] if isinstance(f, RawFrame)] == [
        0x100,
        0x101,
        0x102,
        0x103,
    ]
    assert reader.dropped == 16
    assert reader.state == "closed"


@pytest.mark.parametrize(
    ("service_table", "event_loop", "poll_period_s"),
    [("event_loop = true", True, 0.0), ("event_loop = false", False, 0.0)]
    + [("event_loop = true\npoll_period_ms = 20", True, 0.02)],
    ids=["event_loop", "threads", "coalesced"],
)
def test_raw_batches_read_by_mcap_and_portal_daq_replay_give_the_live_estimates(
    tmp_path: Path, service_table: str, event_loop: bool, poll_period_s: float
) -> None:
    """The recording's /can/raw batches, read with mcap's own reader and decoded by the
    layout in daq.can_batch, and `portal-daq replay` of the file, give the estimates
    received live on Zenoh, bit for bit (faults included; both thread layouts, and
    wake-ups coalesced)."""
    path = write_service_config(
        tmp_path,
        channel=f"test-{uuid.uuid4().hex}",
        port=free_port(),
        recording=tmp_path / "rec",
        extra=f"\n[service]\n{service_table}\n",
    )
    config = load_service_config(path)
    assert config.service.event_loop is event_loop
    assert config.service.poll_period_s == poll_period_s
    encoder = encoder_for(config)
    messages = leg_messages(encoder, FRAMES_PER_LEG, time.time())
    t = messages[-1].timestamp + 0.01
    messages += [
        can_message(encoder.encode("LEG_SB2_F1", leg_signals("SB2_F1", 2e7, 1e6), counter=5), t),
        can_message(
            encoder.encode("LEG_SB2_F1", leg_signals("SB2_F1", 1e7, 1e6), corrupt_crc=True), t
        ),
    ]
    prefix = config.zenoh.key_prefix
    with live_service(config) as service, subscriber_session(zenoh_port(config)) as session:
        collector = connected_collector(session, prefix)
        with sender(config) as bus:
            for message in messages:
                bus.send(message)
        collector.wait_until(
            lambda: (
                sum(len(collector.of(f"{prefix}/leg/{leg}/ground")) for leg in LEGS)
                == len(messages)
            )
        )
        recorder = service.recorder
        assert recorder is not None
    live = [payload for key, payload, _ in collector.samples if "/leg/" in key]
    (recording,) = recorder.paths
    # mcap's reader, file order; the batches decoded with the documented layout
    items: list[RawFrame | BusEvent] = []
    with open(recording, "rb") as file:
        reader = make_reader(file)
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            if channel.topic == "/can/raw":
                assert schema is not None and schema.name == "portal.CanFrameBatch"
                items += can_batch.decode(message.data)
            elif channel.topic == "/daq/bus":
                event = json.loads(message.data)
                fields = ("t", "state", "reason", "reset_counters")
                items.append(BusEvent(*(event[field] for field in fields)))
    assert sum(isinstance(item, RawFrame) for item in items) == len(messages)
    pipeline = Pipeline.from_config(config.machine, config.database)
    replayed = [e for result in results(pipeline, items) for e in result.estimates]
    # JSON floats round-trip exactly (repr), NaN as null: equal payloads are equal bits
    assert [json.loads(json_bytes(leg_ground(e))) for e in replayed] == live
    assert live[-2]["reasons"] == ["counter"] and live[-1]["reasons"] == ["crc"]
    # portal-daq replay, the command line
    done = subprocess.run(
        [sys.executable, "-m", "daq", "replay", str(recording)],
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    )
    rows = [row.split(",") for row in done.stdout.splitlines()[1:]]
    keys = ("t", "force_N", "force_raw_N", "pressure_Pa", "p_piston_Pa", "p_rod_Pa")
    for row, estimate in zip(rows, live, strict=True):
        assert row[0] == estimate["leg"] and row[9] == "|".join(estimate["reasons"])
        for value, key in zip(row[1:7], keys, strict=True):
            assert float(value) == estimate[key] or (value == "nan" and estimate[key] is None)
