"""The viewers' shared core: parsing the service's payloads, the feed's ordering rule,
the viewer's Zenoh endpoints and settings drawn from the service config."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from daq import payloads
from daq.dashboard.api import history_document
from daq.dashboard.history import PressureHistory
from daq.frames import RawFrame
from daq.live.session import reachable, viewer_connect, viewer_zenoh_config
from daq.live.state import LiveState, Received
from daq.live.viewer import ViewerConfig, viewer_config
from daq.monitor.view import plain_line
from daq.pipeline import Pipeline
from daq.service_config import ZenohSettings, load_service_config
from dbc.encoding import FrameEncoder
from dbc.errors import ConfigError
from estimator.equations import foot_force_N
from tests.daq.live_support import ground_payload, leg_payload, status_payload
from tests.daq.service_support import leg_signals, write_service_config
from tests.helpers import LEGS, ROOT, example_machine

PREFIX = "portal/m"


def applied(key: str, payload: object, received_s: float = 1.0) -> LiveState:
    state = LiveState(PREFIX)
    assert state.apply(f"{PREFIX}/{key}", json.dumps(payload).encode(), received_s)
    return state


def test_ground_from_the_real_pipeline_and_serializer() -> None:
    """The payload the service really writes (NaN as null) parses to the same numbers."""
    machine, database = example_machine()
    pipeline = Pipeline.from_config(machine, database)
    encoder = FrameEncoder(database, machine.protection)
    frame = encoder.encode("LEG_SB1_F1", leg_signals("SB1_F1", 12e6, 1e6))
    pipeline.process(RawFrame(100.0, frame.arbitration_id, frame.is_extended_id, frame.data))
    payload = payloads.json_bytes(payloads.machine_ground(pipeline.snapshot(100.005)))

    state = LiveState(PREFIX)
    assert state.apply(f"{PREFIX}/ground", payload, received_s=7.0)
    assert state.ground is not None and state.ground.received_s == 7.0
    ground = state.ground.value
    assert ground.t_s == 100.005 and set(ground.legs) == set(LEGS)
    leg = ground.legs["SB1_F1"]
    geometry = machine.legs["SB1_F1"].geometry
    force_N = foot_force_N(12e6, 1e6, geometry)
    assert leg.force_N == pytest.approx(force_N) and leg.valid and leg.reasons == ()
    assert leg.pressure_Pa == pytest.approx(force_N / geometry.A_foot_m2)
    assert leg.contact is True  # 62 kN >= contact_on_N
    never = ground.legs["SB2_F3"]  # no frame yet: NaN published as null
    assert never.force_N is None and never.pressure_Pa is None
    assert never.valid is False and "stale" in never.reasons
    assert ground.weight_N == pytest.approx(machine.weight_N) and ground.complete is False


def test_a_lifted_foot_reads_0_kPa_in_the_views_with_its_cylinder_force() -> None:
    """A foot in the air has no soil pressure: the report draws it at 0 kPa, and the
    monitor showed the payload's eq. (5) of the lifted leg's cylinder force, ``-10.0 kPa
    air`` (seen with the simulator, SB2 lifted), the dashboard plotted it below zero."""
    legs = {
        "SB2_F1": leg_payload("SB2_F1", 50.0, -10e3),  # -3.3 kN: in the air, valid
        "SB1_F1": leg_payload("SB1_F1", 50.0, 150e3),  # on the ground
    }
    assert legs["SB2_F1"]["contact"] is False and legs["SB2_F1"]["valid"] is True
    ground = applied("ground", ground_payload(50.0, legs)).ground
    assert ground is not None
    lifted, down = ground.value.legs["SB2_F1"], ground.value.legs["SB1_F1"]
    assert lifted.pressure_Pa == 0.0 and lifted.force_N == pytest.approx(-3300.0)
    assert lifted.valid and not lifted.contact
    assert down.pressure_Pa == 150e3  # on the ground: the payload's own

    viewer = ViewerConfig("t.toml", "m", PREFIX, ("SB1_F1", "SB2_F1"), 200e3, 3.0, 1.0)
    line = plain_line(viewer, applied("ground", ground_payload(50.0, legs)), 1.5, 0.0)
    assert "| SB2_F1 -3.3 kN 0.0 kPa air ok" in line
    history = PressureHistory(["SB1_F1", "SB2_F1"])
    assert history.add(ground.value)
    assert history_document(history, None, None)["pressure_Pa"] == {
        "SB1_F1": [150e3],
        "SB2_F1": [0.0],
    }


def test_status_fields_and_dropped_summed() -> None:
    status = applied("status", status_payload(5.0, state="down", reason="link down")).status
    assert status is not None
    s = status.value
    assert (s.bus_state, s.bus_interface, s.bus_channel, s.bus_reason) == (
        "down",
        "virtual",
        "synthetic",
        "link down",
    )
    assert s.frames_per_s == 600.0 and s.frames_bad == 3 and s.frames_received == 7500
    assert s.dropped == 1 and s.healthy is True and s.uptime_s == 12.5


def test_metrics_per_leg() -> None:
    state = applied(
        "metrics",
        {"t": 3.0, "legs": {"SB1_F1": {"peak_pressure_Pa": 2.5e5, "time_above_limit_s": 1.5}}},
    )
    assert state.metrics is not None
    metrics = state.metrics.value.legs["SB1_F1"]
    assert metrics.peak_pressure_Pa == 2.5e5 and metrics.time_above_limit_s == 1.5
    assert metrics.near_constant_pressure_Pa is None


@pytest.mark.parametrize("payload", [b"not json", b"[1, 2]", b"\xff\xfe", b"null"])
def test_unusable_payloads_are_counted_not_fatal(payload: bytes) -> None:
    state = LiveState(PREFIX)
    assert state.apply(f"{PREFIX}/ground", payload, 1.0) is False
    assert state.ground is None and state.ignored == 1


def test_missing_and_wrongly_typed_fields_read_as_none() -> None:
    ground = applied("ground", {"legs": {"A": {"force_N": "12", "valid": 1}, "B": 3}}).ground
    assert ground is not None
    assert list(ground.value.legs) == ["A"]
    leg = ground.value.legs["A"]
    assert leg.force_N is None and leg.valid is False and leg.reasons == ()
    assert ground.value.t_s is None and ground.value.legs_in_contact is None


def test_other_keys_are_ignored() -> None:
    state = LiveState(PREFIX)
    assert state.apply(f"{PREFIX}/signals/LEG_SB1_F1", b"{}", 1.0) is False
    assert state.ignored == 1


def test_age_never_negative() -> None:
    received = Received("x", received_s=10.0)
    assert received.age_s(12.5) == 2.5 and received.age_s(9.0) == 0.0


def test_reachable_endpoints() -> None:
    assert reachable("tcp/0.0.0.0:7447") == "tcp/127.0.0.1:7447"
    assert reachable("tcp/[::]:7447") == "tcp/[::1]:7447"
    assert reachable("udp/0.0.0.0:7447") == "udp/127.0.0.1:7447"
    assert reachable("tcp/192.168.10.5:7447") == "tcp/192.168.10.5:7447"
    assert reachable("tcp/[::]:0") is None and reachable("tcp/127.0.0.1:0") is None
    assert viewer_connect(["tcp/10.0.0.1:7447"], ["tcp/0.0.0.0:7447", "tcp/[::]:0"]) == [
        "tcp/10.0.0.1:7447",
        "tcp/127.0.0.1:7447",
    ]
    assert viewer_connect(["tcp/127.0.0.1:7447"], ["tcp/127.0.0.1:7447"]) == ["tcp/127.0.0.1:7447"]


def endpoints(config: object, key: str) -> object:
    return json.loads(config.get_json(key))  # type: ignore[attr-defined]


def test_viewer_connects_where_the_service_listens_from_the_json5_file() -> None:
    """deploy/zenoh.json5 listens on tcp/127.0.0.1:7447: the viewer must not, it connects."""
    settings = ZenohSettings(config_file=ROOT / "deploy" / "zenoh.json5")
    config = viewer_zenoh_config(settings)
    assert endpoints(config, "connect/endpoints") == ["tcp/127.0.0.1:7447"]
    assert endpoints(config, "listen/endpoints") == ["tcp/127.0.0.1:0"]
    assert endpoints(config, "mode") == "peer"
    assert endpoints(config, "scouting/multicast/enabled") is False  # kept from the file


def test_viewer_overrides_win() -> None:
    settings = ZenohSettings(mode="peer", listen=("tcp/0.0.0.0:7447",))
    config = viewer_zenoh_config(settings, mode="client", connect=["tcp/10.1.1.1:7447"], listen=[])
    assert endpoints(config, "mode") == "client"
    assert endpoints(config, "connect/endpoints") == ["tcp/10.1.1.1:7447"]
    assert endpoints(config, "listen/endpoints") == []  # a client does not listen
    config = viewer_zenoh_config(settings, listen=["tcp/127.0.0.1:9000"])
    assert endpoints(config, "connect/endpoints") == ["tcp/127.0.0.1:7447"]
    assert endpoints(config, "listen/endpoints") == ["tcp/127.0.0.1:9000"]


def test_bad_endpoint_is_a_config_error() -> None:
    """Named by the option that gave it (``--connect``), by the config's key otherwise."""
    with pytest.raises(ConfigError, match=r"^--connect: Endpoints must be .*: not an endpoint$"):
        viewer_zenoh_config(ZenohSettings(), connect=["not an endpoint"], source="x.toml")
    with pytest.raises(ConfigError, match=r"^x\.toml: zenoh\.connect: Endpoints must be "):
        viewer_zenoh_config(ZenohSettings(connect=("not an endpoint",)), source="x.toml")


def test_viewer_config_from_the_service_config(tmp_path: Path) -> None:
    path = write_service_config(tmp_path, port=7447, status_period_s=0.5)
    path.write_text(
        path.read_text().replace("pressure_limit_Pa = 200000.0", "pressure_limit_Pa = 150000.0")
    )
    viewer = viewer_config(load_service_config(path))
    assert viewer.prefix == "portal/pam-proto-1" and viewer.machine_id == "pam-proto-1"
    assert viewer.legs == LEGS
    assert viewer.pressure_limit_Pa == 150e3
    assert viewer.status_stale_s == 1.5 and viewer.ground_stale_s == 1.0
    assert viewer.key("status") == "portal/pam-proto-1/status"
