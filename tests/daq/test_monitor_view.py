"""The monitor's pure rendering: numbers, bars, waiting and stale states, the plain line."""

from __future__ import annotations

import json
import re
import time

import pytest

from daq.live.state import NO_LINK, LiveState
from daq.live.viewer import ViewerConfig
from daq.monitor.view import (
    ALARM,
    DIM,
    OK,
    WARN,
    plain_line,
    pressure_bar,
    render,
    render_text,
)
from tests.daq.live_support import ground_payload, leg_payload, status_payload
from tests.helpers import LEGS

PREFIX = "portal/m"
VIEWER = ViewerConfig(
    source="test.toml",
    machine_id="m",
    prefix=PREFIX,
    legs=LEGS,
    pressure_limit_Pa=200e3,
    status_stale_s=3.0,
    ground_stale_s=1.0,
)
PRESSURES_PA = {
    "SB1_F1": 250e3,  # above the limit
    "SB1_F2": 170e3,  # above 80 % of it
    "SB1_F3": 100e3,
    "SB2_F1": 0.0,
    "SB2_F2": 300e3,  # at the bar's full scale
    "SB2_F3": None,  # stale: no value
}


def state_at(received_s: float = 100.0, **leg_extra: dict[str, object]) -> LiveState:
    state = LiveState(PREFIX)
    legs = {
        leg: leg_payload(leg, 50.0, p, **leg_extra.get(leg, {})) for leg, p in PRESSURES_PA.items()
    }
    for key, payload in (
        ("ground", ground_payload(50.0, legs)),
        ("status", status_payload(50.0)),
        (
            "metrics",
            {
                "t": 50.0,
                "legs": {"SB1_F1": {"peak_pressure_Pa": 312.34e3, "time_above_limit_s": 4.25}},
            },
        ),
    ):
        assert state.apply(f"{PREFIX}/{key}", json.dumps(payload).encode(), received_s)
    return state


def row(lines: list[str], leg: str) -> str:
    (found,) = [line for line in lines if line.startswith(leg + " ")]
    return found


@pytest.mark.parametrize(
    ("pressure_Pa", "bar"),
    [
        (0.0, "[....................|.........]"),
        (-5e3, "[....................|.........]"),
        (10e3, "[#...................|.........]"),
        (100e3, "[##########..........|.........]"),
        (200e3, "[####################|.........]"),
        (250e3, "[####################!!!!!.....]"),
        (300e3, "[####################!!!!!!!!!!]"),
        (1e6, "[####################!!!!!!!!!!]"),
        (None, "[                              ]"),
    ],
)
def test_pressure_bar_against_the_limit(pressure_Pa: float | None, bar: str) -> None:
    assert pressure_bar(pressure_Pa, 200e3) == bar


def test_bar_scales_with_the_configured_limit() -> None:
    assert pressure_bar(100e3, 100e3) == "[####################|.........]"
    assert pressure_bar(100e3, 400e3) == "[#####...............|.........]"


def test_leg_rows_show_force_pressure_bar_contact_and_validity() -> None:
    lines = render_text(VIEWER, state_at(), now_s=100.5)
    # 250 kPa on 0.33 m2 = 82.5 kN; peak and time above from <prefix>/metrics.
    assert row(lines, "SB1_F1").split() == [
        "SB1_F1",
        "82.5",
        "250.0",
        "[####################!!!!!.....]",
        "125%",
        "ground",
        "312.3",
        "4.2",
        "ok",
    ]
    assert row(lines, "SB1_F3").split()[:6] == [
        "SB1_F3",
        "33.0",
        "100.0",
        "[##########..........|.........]",
        "50%",
        "ground",
    ]
    assert row(lines, "SB2_F1").split()[:6] == [
        "SB2_F1",
        "0.0",
        "0.0",
        "[....................|.........]",
        "0%",
        "air",
    ]
    stale = row(lines, "SB2_F3").split()
    assert stale[:3] == ["SB2_F3", "-", "-"] and stale[-2:] == ["INVALID", "stale"]


def test_columns_line_up_under_the_header() -> None:
    lines = render_text(VIEWER, state_at(), now_s=100.5)
    header = next(line for line in lines if line.startswith("LEG "))
    for leg in LEGS:
        line = row(lines, leg)
        assert line.index("[") == header.index("vs LIMIT")
        assert line.find("ground") in (header.index("CONTACT"), -1)


def test_tones_follow_the_limit_and_validity() -> None:
    tones = {line.text.split()[0]: line.tone for line in render(VIEWER, state_at(), 100.5)[5:11]}
    assert tones == {
        "SB1_F1": ALARM,
        "SB1_F2": WARN,
        "SB1_F3": OK,
        "SB2_F1": OK,
        "SB2_F2": ALARM,
        "SB2_F3": ALARM,
    }


def test_reasons_are_listed() -> None:
    state = state_at(SB1_F3={"valid": False, "reasons": ["crc", "counter"]})
    assert row(render_text(VIEWER, state, 100.5), "SB1_F3").endswith("INVALID crc,counter")


def test_status_and_weight_lines() -> None:
    lines = render_text(VIEWER, state_at(received_s=100.0), now_s=100.4)
    assert "portal/m" in lines[0] and "200.0 kPa" in lines[0]
    assert lines[1] == (
        "bus up (virtual synthetic), 600 frames/s, 3 bad, 1 dropped, healthy, status 0.4 s ago"
    )
    # Legs in contact: 82.5 + 56.1 + 33.0 + 99.0 kN = 270.6 kN; weight 18.8 t = 184.4 kN.
    assert lines[2] == (
        "weight check: 270.6 kN on the feet of 184.4 kN, residual +86.2 kN, "
        "4 legs in contact, incomplete (a leg is invalid)"
    )


def test_bus_down_is_an_alarm() -> None:
    state = state_at()
    payload = status_payload(51.0, state="down", reason="No such device")
    state.apply(f"{PREFIX}/status", json.dumps(payload).encode(), 100.0)
    line = render(VIEWER, state, 100.1)[1]
    assert line.tone == ALARM and line.text.startswith("bus down (virtual synthetic): No such")


def test_waiting_before_anything_arrived() -> None:
    lines = render(VIEWER, LiveState(PREFIX), now_s=5.0)
    assert lines[1].text == "waiting for portal/m/status" and lines[1].tone == WARN
    assert lines[2].text == "waiting for portal/m/ground"
    rows = [line for line in lines if line.text.split()[:1] == ["SB1_F1"]]
    assert rows[0].text.split()[1:3] == ["-", "-"] and rows[0].tone == DIM


def test_stale_status_and_ground_are_flagged_and_dimmed() -> None:
    lines = render(VIEWER, state_at(received_s=100.0), now_s=110.0)
    assert lines[1].tone == ALARM
    assert lines[1].text.startswith("STALE: no status for 10.0 s; last: bus up")
    assert lines[2].tone == ALARM and lines[2].text.startswith("STALE: no ground for 10.0 s")
    assert all(line.tone == DIM for line in lines[5:11])
    assert "82.5" in lines[5].text  # the last values stay visible


def test_just_fresh_is_not_stale() -> None:
    lines = render(VIEWER, state_at(received_s=100.0), now_s=100.9)
    assert not lines[1].text.startswith("STALE") and not lines[2].text.startswith("STALE")


def test_unknown_legs_are_shown_after_the_configured_ones() -> None:
    state = LiveState(PREFIX)
    legs = {"SB1_F1": leg_payload("SB1_F1", 1.0, 1e5), "EXTRA": leg_payload("EXTRA", 1.0, 2e5)}
    state.apply(f"{PREFIX}/ground", json.dumps(ground_payload(1.0, legs)).encode(), 1.0)
    names = [line.split()[0] for line in render_text(VIEWER, state, 1.0)[5:12]]
    assert names == [*LEGS, "EXTRA"]


def test_plain_line() -> None:
    wall_s = time.mktime((2025, 5, 1, 12, 0, 1, 0, 0, -1))
    line = plain_line(VIEWER, state_at(received_s=100.0), now_s=100.5, wall_s=wall_s)
    assert line.startswith("12:00:01 bus up 600 frames/s 3 bad 1 dropped healthy | weight ")
    # the weight check, and per leg the soil metrics, as the full screen shows them
    ground = state_at().ground
    assert ground is not None
    g = ground.value
    assert (
        f"| weight {g.total_force_N / 1e3:.1f} of {g.weight_N / 1e3:.1f} kN residual "
        f"{g.residual_N / 1e3:+.1f} kN {g.legs_in_contact} in contact "
        f"{'complete' if g.complete else 'incomplete'} | SB1_F1 82.5 kN 250.0 kPa" in line
    )
    assert "| SB1_F1 82.5 kN 250.0 kPa ground ok peak 312.3 kPa above 4.2 s |" in line
    assert "| SB2_F1 0.0 kN 0.0 kPa air ok |" in line
    assert line.endswith("| SB2_F3 - kN - kPa air INVALID:stale")
    assert "\n" not in line
    assert re.fullmatch(r"[ -~]+", line)  # plain ASCII for any log


def test_an_unhealthy_status_says_why_on_the_screen_and_the_plain_line() -> None:
    # The status's problems (a recording stopped, an unreached endpoint) showed nowhere:
    # the screen said only UNHEALTHY and the plain line not even that ("0 dropped").
    problems = ["recording stopped (write error)", "zenoh connect tcp/10.0.0.9:7447 not reached"]
    state = LiveState(PREFIX)
    payload = status_payload(1.0) | {"healthy": False, "problems": problems}
    assert state.apply(f"{PREFIX}/status", json.dumps(payload).encode(), 100.0)
    why = "UNHEALTHY: recording stopped (write error); zenoh connect tcp/10.0.0.9:7447 not reached"
    assert render_text(VIEWER, state, 100.4)[1].endswith(f"1 dropped, {why}, status 0.4 s ago")
    assert f" 1 dropped {why} | waiting for " in plain_line(VIEWER, state, 100.4, 0.0)


def test_plain_line_waiting_and_stale() -> None:
    waiting = plain_line(VIEWER, LiveState(PREFIX), now_s=1.0, wall_s=0.0)
    assert waiting.endswith(" waiting for portal/m/status | waiting for portal/m/ground")
    stale = plain_line(VIEWER, state_at(received_s=100.0), now_s=104.0, wall_s=0.0)
    assert " STALE status 4.0 s: bus up" in stale and "| STALE ground 4.0 s |" in stale


def test_waiting_without_a_zenoh_link_says_so() -> None:
    """A wrong --connect, or no service where the viewer looks, said only "waiting for
    portal/m/status", as when the service is there and about to talk."""
    state = LiveState(PREFIX)
    state.linked = True  # linked: nothing more to say
    assert plain_line(VIEWER, state, 1.0, 0.0).endswith(
        " waiting for portal/m/status | waiting for portal/m/ground"
    )
    state.linked = False
    line = plain_line(VIEWER, state, 1.0, 0.0)
    assert line.endswith(
        f" waiting for portal/m/status: {NO_LINK} | waiting for portal/m/ground: {NO_LINK}"
    )
    assert NO_LINK.startswith("no Zenoh link to any peer or router yet")
    assert f"waiting for portal/m/status: {NO_LINK}" in render_text(VIEWER, state, 1.0)
