"""The fleet's pure parts: machines from liveliness and data, summaries, the fleet
monitor's text; and ``portal-daq router``'s config checks as a process."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest
import zenoh

from daq.live.feed import Item, LiveFeed
from daq.live.fleet import GONE, WAITING, FleetSettings, FleetState, fleet_document
from daq.live.state import NO_LINK
from daq.monitor.fleet_view import fleet_plain_line, fleet_render
from daq.monitor.view import ALARM, DIM, OK, WARN
from tests.daq.live_support import ground_payload, leg_payload, status_payload
from tests.daq.test_viewer_cli import assert_one_line, run

SETTINGS = FleetSettings("portal", pressure_limit_Pa=200e3, status_stale_s=3.0, ground_stale_s=1.0)


def data(key: str, payload: dict[str, Any], received_s: float) -> Item:
    return Item(key, json.dumps(payload).encode(), received_s)


def token(machine_id: str, alive: bool, received_s: float) -> Item:
    return Item(f"portal/{machine_id}/alive", b"", received_s, alive)


def ground(pressures_Pa: dict[str, float | None], **extra: Any) -> dict[str, Any]:
    legs = {leg: leg_payload(leg, 50.0, p) for leg, p in pressures_Pa.items()}
    return ground_payload(50.0, legs) | extra


PRESSURES_PA = {"SB1_F1": 150e3, "SB1_F2": 230e3, "SB2_F1": None}  # SB2_F1 invalid


def machine(
    fleet: FleetState,
    machine_id: str,
    received_s: float,
    pressures: dict[str, float | None] = PRESSURES_PA,
    **extra: Any,
) -> None:
    assert fleet.apply(token(machine_id, True, received_s))
    assert fleet.apply(data(f"portal/{machine_id}/status", status_payload(50.0), received_s))
    assert fleet.apply(data(f"portal/{machine_id}/ground", ground(pressures, **extra), received_s))


def test_summary_of_a_live_machine() -> None:
    fleet = FleetState(SETTINGS)
    machine(fleet, "pam-2", 10.0, stability={"cop_m": [0.1, 0.2], "margin_m": 0.42})
    machine(fleet, "pam-1", 10.0)
    first, second = fleet.summaries(now_s=10.5)
    assert (first.machine_id, second.machine_id) == ("pam-1", "pam-2")  # by id
    assert first.state == "live" and first.healthy is True and first.bus_state == "up"
    assert first.legs == 3 and first.legs_in_contact == 2
    # The invalid leg does not count, even though its (null) pressure would not either.
    assert (first.max_pressure_leg, first.max_pressure_Pa) == ("SB1_F2", 230e3)
    assert first.stability_margin_m is None and second.stability_margin_m == 0.42
    assert first.data_age_s == 0.5 and first.gone_for_s is None
    document = fleet_document(fleet, now_s=10.5, dropped=3)
    assert document["root"] == "portal" and document["viewer"] == {
        "dropped": 3,
        "ignored": 0,
        "zenoh_linked": None,
    }
    assert [m["machine_id"] for m in document["machines"]] == ["pam-1", "pam-2"]
    assert document["machines"][1]["stability_margin_m"] == 0.42


def test_stale_is_not_gone_and_gone_comes_back() -> None:
    fleet = FleetState(SETTINGS)
    machine(fleet, "pam-1", 10.0)
    [summary] = fleet.summaries(now_s=11.5)  # ground older than 1 s, token still there
    assert summary.state == "stale" and summary.gone_for_s is None
    assert fleet.apply(token("pam-1", False, 12.0))
    assert not fleet.apply(token("pam-1", False, 12.5))  # no change
    [summary] = fleet.summaries(now_s=13.5)
    assert summary.state == "gone" and summary.gone_for_s == 1.5
    assert summary.max_pressure_Pa == 230e3  # the last values stay, marked gone
    machine(fleet, "pam-1", 20.0)
    [summary] = fleet.summaries(now_s=20.1)
    assert summary.state == "live" and summary.gone_for_s is None


def test_foreign_keys_are_ignored() -> None:
    fleet = FleetState(SETTINGS)
    machine(fleet, "pam-1", 10.0)
    old = ground({"SB1_F1": 50e3})
    assert not fleet.apply(data("other/pam-1/ground", old, 11.0))
    assert not fleet.apply(data("portal/ground", old, 11.0))
    assert fleet.ignored == 2
    assert fleet.apply(token("pam-9", True, 11.0))
    [_, waiting] = fleet.summaries(11.0)
    assert waiting.state == "waiting" and waiting.data_age_s is None


def test_single_machine_view_settings_come_from_the_fleet() -> None:
    fleet = FleetState(SETTINGS)
    assert fleet.viewer("portal/pam-1") is None
    machine(fleet, "pam-1", 10.0)
    viewer = fleet.viewer("portal/pam-1")
    assert viewer is not None
    assert (viewer.machine_id, viewer.prefix) == ("pam-1", "portal/pam-1")
    assert viewer.legs == ("SB1_F1", "SB1_F2", "SB2_F1")  # the service's order
    assert viewer.pressure_limit_Pa == 200e3


def test_fleet_monitor_text() -> None:
    fleet = FleetState(SETTINGS)
    machine(fleet, "pam-1", 10.0, stability={"margin_m": -0.05})
    machine(fleet, "pam-2", 10.0)
    fleet.apply(token("pam-2", False, 10.0))
    summaries = fleet.summaries(now_s=12.0)
    lines = fleet_render(SETTINGS, summaries, fleet.waiting())
    assert "1 of 2 machines present" in lines[0].text
    row_1, row_2 = lines[3], lines[4]
    assert row_1.text.split() == [
        "pam-1", "STALE", "healthy", "up", "2/3", "230.0", "SB1_F2", "-0.05", "2.0"
    ]  # fmt: skip
    assert row_1.tone == ALARM  # stale (and a negative margin)
    assert row_2.text.startswith("pam-2") and "GONE 2 s" in row_2.text and row_2.tone == DIM
    line = fleet_plain_line(fleet.summaries(now_s=10.5), 0.0, fleet.waiting())
    assert "| pam-2 GONE 0 s" in line
    assert "pam-1 live healthy 2/3 230.0 kPa SB1_F2 margin -0.05 m age 0.5 s" in line
    fresh = FleetState(SETTINGS)
    machine(fresh, "a", 10.0)  # 230 kPa: above the limit
    machine(fresh, "b", 10.0, {"SB1_F1": 170e3})  # above 80 % of it
    machine(fresh, "c", 10.0, {"SB1_F1": 100e3})
    machine(fresh, "d", 10.0, {"SB1_F1": 100e3}, stability={"margin_m": -0.01})
    tones = [line.tone for line in fleet_render(SETTINGS, fresh.summaries(10.1), "")[3:]]
    assert tones == [ALARM, WARN, OK, ALARM]
    empty = FleetState(SETTINGS)
    assert fleet_plain_line([], 0.0, empty.waiting()).endswith(
        " no machine yet: waiting for liveliness tokens portal/*/alive"
    )
    assert fleet_render(SETTINGS, [], empty.waiting())[-1].text == empty.waiting()


def test_a_fleet_view_without_any_zenoh_link_says_so() -> None:
    """A fleet view whose ``--connect`` reaches nothing said "no machine yet" for ever, as
    if no service were up; the single-machine views said it already."""
    fleet = FleetState(SETTINGS)
    fleet.linked = False
    assert fleet.waiting() == f"waiting for liveliness tokens portal/*/alive: {NO_LINK}"
    assert fleet_document(fleet, now_s=0.0)["waiting"] == fleet.waiting()
    assert fleet_document(fleet, now_s=0.0)["viewer"]["zenoh_linked"] is False
    fleet.linked = True
    assert fleet.waiting() == "waiting for liveliness tokens portal/*/alive"


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ('{mode: "peer"}', "mode: must be 'router' for a router, got 'peer'"),
        ("{mode: ", "not a valid Zenoh config"),
    ],
)
def test_router_bad_config_exits_2(tmp_path: Path, text: str, expected: str) -> None:
    path = tmp_path / "router.json5"
    path.write_text(text)
    line = assert_one_line(run("router", "--config", str(path)), 2, "portal-daq: ")
    assert str(path) in line and expected in line


def test_fleet_without_a_router_exits_2() -> None:
    line = assert_one_line(run("dashboard", "--fleet"), 2, "portal-daq dashboard: ")
    assert "--connect" in line
    line = assert_one_line(run("monitor", "--plain"), 2, "portal-daq monitor: ")
    assert "--config" in line


def test_a_machine_going_is_seen_even_when_the_feed_queue_was_full() -> None:
    """Zenoh's callbacks only enqueue into a bounded queue; a burst of data fills it. A
    liveliness change then waits aside (the latest per machine) instead of being dropped,
    and comes out after the queued data: the fleet shows m1 gone, m2 alive."""
    clock = iter(float(t) for t in range(100)).__next__
    feed = LiveFeed(None, "portal/*", queue_size=2, clock=clock, liveliness=True)  # type: ignore[arg-type]

    def change(machine_id: str, kind: zenoh.SampleKind) -> None:
        feed._on_token(SimpleNamespace(key_expr=f"portal/{machine_id}/alive", kind=kind))  # type: ignore[arg-type]

    change("m1", zenoh.SampleKind.PUT)
    feed._enqueue(data("portal/m1/status", status_payload(0.5), 0.5))  # the queue is full now
    change("m1", zenoh.SampleKind.DELETE)
    change("m2", zenoh.SampleKind.PUT)
    feed._enqueue(data("portal/m1/status", status_payload(0.6), 0.6))  # dropped, counted
    assert feed.dropped == 1
    items = []
    while (item := feed.wait(0.0)) is not None:
        items.append(item)
    assert [(i.key, i.alive) for i in items] == [
        ("portal/m1/alive", True),
        ("portal/m1/status", None),
        ("portal/m1/alive", False),
        ("portal/m2/alive", True),
    ]
    fleet = FleetState(SETTINGS)
    for item in items:
        fleet.apply(item)
    assert {s.machine_id: s.state for s in fleet.summaries(10.0)} == {"m1": GONE, "m2": WAITING}
    # m1 comes and goes while the queue is full: once one change waits aside, the later
    # ones follow it there (the latest wins) even when the queue has room again, never
    # overtaking it through the queue.
    feed._enqueue(data("portal/m2/status", status_payload(0.7), 0.7))
    feed._enqueue(data("portal/m2/status", status_payload(0.8), 0.8))
    change("m1", zenoh.SampleKind.PUT)  # aside: the queue is full
    assert feed.wait(0.0) == data("portal/m2/status", status_payload(0.7), 0.7)
    change("m1", zenoh.SampleKind.DELETE)  # room in the queue, but m1 has one aside
    assert [(i.key, i.alive) for i in iter(lambda: feed.wait(0.0), None)] == [
        ("portal/m2/status", None),
        ("portal/m1/alive", False),
    ]
