"""A held-out machine (tests/files/stranger/j1939_propa: J1939 transducers, one per
chamber) run by the service on python-can's virtual bus, with kernel-style receive
filters, a real Zenoh session on loopback: what it publishes and counts."""

import json
import shutil
import time
import uuid
from pathlib import Path

import can
import pytest
import zenoh

from daq.mcap_reading import RecordedMessage, RecordingStream
from daq.runner import build_recorder, bus_factory
from daq.service import Service
from daq.service_config import ServiceConfig, load_service_config
from daq.zenoh_session import zenoh_config
from dbc.decoding import FrameDecoder
from tests.daq.service_support import Collector, free_port, running, subscriber_session
from tests.dbc.test_held_out_machines import (
    STRANGER,
    UNITS_FORCES_N,
    UNITS_SENT,
    eq4_N,
    press_a,
    units_frames,
)


def held_out_service_config(
    tmp_path: Path, machine: str, publish: str = "", tables: str = ""
) -> tuple[ServiceConfig, int, str]:
    """The service config of the held-out ``machine`` (its DBC copied beside it) on a
    fresh virtual bus with kernel-style filters and Zenoh on a free loopback port, with
    more ``[publish]`` keys and more ``tables``; and that port and bus channel."""
    shutil.copy(STRANGER / f"{machine}.dbc", tmp_path)
    port, channel = free_port(), f"held-out-{uuid.uuid4().hex}"
    (tmp_path / "portal-daq.toml").write_text(
        f"""
[bus]
interface = "virtual"
channel = "{channel}"
kernel_filters = true

[zenoh]
mode = "peer"
listen = ["tcp/127.0.0.1:{port}"]
multicast_scouting = false

[publish]
status_period_s = 0.2
{publish}
{tables}
"""
        + (STRANGER / f"{machine}.toml").read_text()
    )
    return load_service_config(tmp_path / "portal-daq.toml"), port, channel


def send_on(channel: str, messages: list[can.Message]) -> None:
    """``messages`` onto python-can's virtual bus ``channel``, their time stamps kept."""
    bus = can.Bus(interface="virtual", channel=channel, preserve_timestamps=True)
    try:
        for message in messages:
            bus.send(message)
    finally:
        bus.shutdown()


def test_the_service_runs_a_held_out_j1939_machine(tmp_path: Path) -> None:
    config, port, channel = held_out_service_config(tmp_path, "j1939_propa")
    filters = FrameDecoder(config.database, config.machine.protection).receive_filters
    prefix = config.zenoh.key_prefix
    t0 = time.time()
    sent = [
        press_a(3, 0x27, source, 5, round(kPa / 0.05))
        for source, kPa in ((0x31, 800.0), (0x30, 2800.0), (0x34, 100.0))
    ]
    messages = [
        can.Message(timestamp=t0 + 0.001 * i, arbitration_id=f.arbitration_id, data=f.data)
        for i, f in enumerate(sent)
    ]
    messages.append(can.Message(timestamp=t0, arbitration_id=0x123, is_extended_id=False))
    with zenoh.open(zenoh_config(config.zenoh)) as session:
        service = Service(config, open_bus=bus_factory(config.bus, filters), session=session)
        with running(service), subscriber_session(port) as subscriber:
            collector = Collector(subscriber, f"{prefix}/**")
            collector.wait_for(f"{prefix}/status")
            send_on(channel, messages)
            estimate = collector.wait_for(f"{prefix}/leg/left-front/ground")
            status = collector.wait_for(
                f"{prefix}/status", lambda s: s["frames"]["processed"] == len(sent)
            )
    assert prefix == "portal/held-out-j1939"
    assert estimate["valid"] and estimate["force_raw_N"] == pytest.approx(eq4_N(2.8e6, 0.8e6))
    # The standard frame is filtered out (kernel_filters); 0x34 is a transducer of the
    # PGN that no chamber maps.
    assert status["bad"] == {"unmapped_source": 1}


def test_the_service_runs_transducers_in_their_own_units_without_dbc_cycle_times(
    tmp_path: Path,
) -> None:
    """tests/files/stranger/j1939_units: one PGN from four transducers in psi, bar and MPa,
    a DBC without cycle times (the config gives them). The legs' forces are eq. (4) of
    the pressures converted here; /signals and the signals recording are in Pa for each
    sender."""
    config, port, channel = held_out_service_config(
        tmp_path,
        "j1939_units",
        publish="signals_max_rate_hz = 0",
        tables=f'[recording]\ndirectory = "{tmp_path / "recordings"}"\nsignals = true',
    )
    filters = FrameDecoder(config.database, config.machine.protection).receive_filters
    prefix = config.zenoh.key_prefix
    frames = units_frames()
    with zenoh.open(zenoh_config(config.zenoh)) as session:
        service = Service(
            config,
            open_bus=bus_factory(config.bus, filters),
            session=session,
            recorder=build_recorder(config),
        )
        with running(service), subscriber_session(port) as subscriber:
            collector = Collector(subscriber, f"{prefix}/**")
            collector.wait_for(f"{prefix}/status")
            send_on(
                channel,
                [
                    can.Message(
                        timestamp=frame.t_s, arbitration_id=frame.arbitration_id, data=frame.data
                    )
                    for frame in frames
                ],
            )
            status = collector.wait_for(
                f"{prefix}/status", lambda s: s["frames"]["processed"] == len(frames)
            )
            signals_key = f"{prefix}/signals/XDCR"
            collector.wait_until(lambda: len(collector.of(signals_key)) == len(frames))
            grounds = {leg: collector.first(f"{prefix}/leg/{leg}/ground") for leg in UNITS_FORCES_N}
    assert {leg: (g["valid"], g["force_raw_N"]) for leg, g in grounds.items()} == {
        leg: (True, pytest.approx(force_N, rel=1e-12)) for leg, force_N in UNITS_FORCES_N.items()
    }
    published = {s["source_address"]: s["signals"]["Pressure"] for s in collector.of(signals_key)}
    expected_Pa = {
        source: pytest.approx(value * unit, rel=1e-12) for source, value, unit in UNITS_SENT
    }
    assert published == expected_Pa
    (recording,) = (tmp_path / "recordings").glob("*.mcap")
    with open(recording, "rb") as file:
        recorded = [
            json.loads(record.data)
            for record in RecordingStream(file)
            if isinstance(record, RecordedMessage) and record.topic == "/signals/XDCR"
        ]
    assert {s["source_address"]: s["signals"]["Pressure"] for s in recorded} == expected_Pa
    assert len(recorded) == len(frames)
    assert status["bad"] == {"unmapped_source": 1}


def test_the_service_says_once_which_legs_restart_at_every_sample(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """tests/files/stranger/eight_legs_mux with HUB_VORNE's cycle time set to 5 ms, its
    pages coming each 20 ms: the four legs on it restarted their median at every sample,
    their estimates all valid, and nothing said so."""
    from sim_bridge.__main__ import cli

    log = tmp_path / "hubs.log"
    args = ["--config", str(STRANGER / "eight_legs_mux.toml"), "--interface", "virtual"]
    args += ["--channel", f"log-{uuid.uuid4()}", "--as-fast-as-possible", "-q"]
    assert cli([*args, "--duration", "0.5", "--frames-log", str(log)]) == 0
    with can.LogReader(log) as reader:
        messages = list(reader)
    config, port, channel = held_out_service_config(
        tmp_path, "eight_legs_mux", tables="[messages.HUB_VORNE]\ncycle_time_ms = 5"
    )
    prefix = config.zenoh.key_prefix
    with zenoh.open(zenoh_config(config.zenoh)) as session:
        service = Service(config, open_bus=bus_factory(config.bus, []), session=session)
        with running(service), subscriber_session(port) as subscriber:
            collector = Collector(subscriber, f"{prefix}/status")
            collector.wait_for(f"{prefix}/status")
            send_on(channel, messages)
            collector.wait_for(
                f"{prefix}/status", lambda s: s["frames"]["processed"] == len(messages)
            )
            seen = len(collector.of(f"{prefix}/status"))
            collector.wait_until(lambda: len(collector.of(f"{prefix}/status")) >= seen + 2)
    told = [r.getMessage() for r in caplog.records if r.name == "daq.leg_restarts"]
    assert [line.split(":")[0] for line in told] == ["legs.VL1", "legs.VL2", "legs.VR1", "legs.VR2"]
    assert "came more than its stale time (15 ms: 3 x its cycle time, 5 ms)" in told[0]
    assert all(line.endswith("([messages.HUB_VORNE] cycle_time_ms)") for line in told)
