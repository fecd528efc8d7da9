"""The stability margin in the live views: parsing, monitor lines and the warning."""

from __future__ import annotations

import json
from dataclasses import replace

from daq import payloads
from daq.live.state import LiveState
from daq.live.viewer import ViewerConfig, viewer_config
from daq.monitor.view import ALARM, DIM, OK, plain_line, render, stability_line
from daq.service_config import load_service_config
from estimator.stability import Stability
from tests.daq.live_support import ground_payload, leg_payload
from tests.helpers import LEGS, ROOT

PREFIX = "portal/m"
VIEWER = ViewerConfig(
    source="test.toml",
    machine_id="m",
    prefix=PREFIX,
    legs=LEGS,
    pressure_limit_Pa=200e3,
    status_stale_s=3.0,
    ground_stale_s=1.0,
    warning_margin_m=0.3,
)
FEET = {"SB1_F1": (1.6, 0.0), "SB1_F2": (-0.8, 1.39), "SB1_F3": (-0.8, -1.39)}


def state_with(margin_m: float | None) -> LiveState:
    legs = {leg: leg_payload(leg, 50.0, 150e3) for leg in LEGS}
    ground = ground_payload(50.0, legs)
    ground["stability"] = payloads.stability(
        None
        if margin_m is None
        else Stability(
            cop_m=(0.5, -0.25),
            margin_m=margin_m,
            legs=tuple(FEET),
            polygon_m=tuple(FEET.values()),
            feet_m=FEET | {"SB2_F1": (7.6, 0.0)},
        )
    )
    state = LiveState(PREFIX)
    assert state.apply(f"{PREFIX}/ground", json.dumps(ground).encode(), 100.0)
    return state


def test_the_ground_payload_s_stability_is_parsed() -> None:
    ground = state_with(0.55).ground
    assert ground is not None and ground.value.stability is not None
    margin = ground.value.stability
    assert margin.margin_m == 0.55 and margin.cop_m == (0.5, -0.25)
    assert margin.legs == ("SB1_F1", "SB1_F2", "SB1_F3")
    assert margin.polygon_m[1] == (-0.8, 1.39) and margin.feet_m["SB2_F1"] == (7.6, 0.0)
    assert state_with(None).ground.value.stability is None  # type: ignore[union-attr]


def test_monitor_warns_below_the_configured_margin() -> None:
    fine = stability_line(VIEWER, state_with(0.55))
    assert fine.tone == OK
    assert fine.text == (
        "stability margin 0.55 m (warning below 0.30 m), centre of pressure (0.50, -0.25) m, "
        "feet SB1_F1 SB1_F2 SB1_F3"
    )
    low = stability_line(VIEWER, state_with(0.29))
    assert low.tone == ALARM and low.text.startswith("STABILITY WARNING: stability margin 0.29 m")
    outside = stability_line(VIEWER, state_with(-0.1))
    assert outside.tone == ALARM and "margin -0.10 m" in outside.text
    undefined = stability_line(VIEWER, state_with(None))
    assert undefined.tone == DIM and undefined.text.startswith("stability: - (fewer than three")
    assert stability_line(replace(VIEWER, warning_margin_m=None), state_with(0.55)).tone == DIM
    assert any(line.text == fine.text for line in render(VIEWER, state_with(0.55), 100.5))


def test_plain_line_carries_the_margin() -> None:
    assert plain_line(VIEWER, state_with(0.55), 100.5, 0.0).endswith(" | margin 0.55 m")
    assert plain_line(VIEWER, state_with(0.2), 100.5, 0.0).endswith(
        " | MARGIN WARNING margin 0.20 m"
    )


def test_viewer_takes_the_threshold_from_the_config() -> None:
    config = load_service_config(ROOT / "deploy" / "portal-daq.example.toml")
    assert viewer_config(config).warning_margin_m == 0.3
