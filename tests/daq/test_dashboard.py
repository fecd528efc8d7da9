"""The dashboard without a browser: its history and documents (pure), and the server
in-process against a synthetic service on real Zenoh, read with urllib."""

from __future__ import annotations

import http.client
import json
import re
import time
import urllib.error
import urllib.parse
import urllib.request
from collections.abc import Callable, Iterator
from typing import Any

import pytest
import zenoh

from daq.dashboard.api import history_document, latest_document
from daq.dashboard.cli import http_address
from daq.dashboard.history import PressureHistory
from daq.dashboard.server import Dashboard
from daq.live.state import NO_LINK, LiveState, parse_ground
from daq.live.viewer import ViewerConfig
from dbc.errors import ConfigError, PortalDaqError
from tests.daq.live_support import (
    ground_payload,
    leg_payload,
    pressures_Pa,
    status_payload,
    synthetic_service,
)
from tests.daq.service_support import WAIT_S, free_port, peer_config
from tests.helpers import LEGS

PREFIX = "portal/pam-proto-1"
VIEWER = ViewerConfig(
    source="test.toml",
    machine_id="pam-proto-1",
    prefix=PREFIX,
    legs=LEGS,
    pressure_limit_Pa=200e3,
    status_stale_s=3.0,
    ground_stale_s=1.0,
)


def ground(t_s: float, **pressures: float | None) -> Any:
    legs = {leg: leg_payload(leg, t_s, p) for leg, p in pressures.items()}
    return parse_ground(ground_payload(t_s, legs))


# --- history ------------------------------------------------------------------


def test_history_keeps_the_window_in_order_with_gaps_for_invalid_legs() -> None:
    history = PressureHistory(["A", "B"], window_s=60.0)
    assert history.add(ground(100.0, A=1e5, B=2e5))
    assert history.add(ground(100.1, A=1.1e5, B=None))  # B invalid: a gap
    assert not history.add(ground(100.1, A=9e9, B=9e9))  # a repeat
    assert not history.add(ground(99.0, A=9e9, B=9e9))  # older than the last
    assert history.since(None) == [(100.0, (1e5, 2e5)), (100.1, (1.1e5, None))]
    assert history.since(100.0) == [(100.1, (1.1e5, None))]
    assert history.since(100.1) == []
    history.add(ground(160.05, A=3e5, B=3e5))
    assert [t for t, _ in history.since(None)] == [100.1, 160.05]  # 100.0 left the window


def test_a_clock_jump_back_restarts_the_history() -> None:
    history = PressureHistory(["A"])
    history.add(ground(1000.0, A=1e5))
    assert history.generation == 0
    assert history.add(ground(900.0, A=2e5))
    assert history.generation == 1 and history.since(None) == [(900.0, (2e5,))]


def test_history_document_resets_on_a_new_generation() -> None:
    history = PressureHistory(["A", "B"])
    for k in range(3):
        history.add(ground(10.0 + k, A=1e5 * k, B=5e4))
    full = history_document(history, None, None)
    assert full["reset"] is True and full["t"] == [10.0, 11.0, 12.0]
    assert full["pressure_Pa"] == {"A": [0.0, 1e5, 2e5], "B": [5e4, 5e4, 5e4]}
    newer = history_document(history, 11.0, 0)
    assert newer["reset"] is False and newer["t"] == [12.0]
    assert newer["pressure_Pa"] == {"A": [2e5], "B": [5e4]}
    assert history_document(history, 11.0, 7)["reset"] is True  # stale generation


# --- latest -------------------------------------------------------------------


def test_latest_document_waiting_then_values_and_staleness() -> None:
    state = LiveState(PREFIX)
    waiting = latest_document(VIEWER, state, now_s=1.0)
    assert waiting["waiting_for"] == f"{PREFIX}/status"
    assert waiting["waiting"] == f"waiting for {PREFIX}/status"
    state.linked = False  # the dashboard's session has no link: the banner says so
    unlinked = latest_document(VIEWER, state, now_s=1.0)
    assert unlinked["waiting"] == f"waiting for {PREFIX}/status: {NO_LINK}"
    assert unlinked["zenoh_linked"] is False
    state.linked = True
    assert waiting["status"] is None and waiting["ground"] is None
    assert waiting["legs"] == list(LEGS) and waiting["pressure_limit_Pa"] == 200e3

    state.apply(f"{PREFIX}/status", json.dumps(status_payload(50.0)).encode(), 10.0)
    assert latest_document(VIEWER, state, 10.5)["waiting_for"] == f"{PREFIX}/ground"
    legs = {"SB1_F1": leg_payload("SB1_F1", 50.0, 250e3)}
    state.apply(f"{PREFIX}/ground", json.dumps(ground_payload(50.0, legs)).encode(), 10.0)
    document = latest_document(VIEWER, state, 10.5, dropped=2)
    assert document["waiting_for"] is None and document["viewer"]["dropped"] == 2
    status = document["status"]
    assert status["bus"]["state"] == "up" and status["frames_per_s"] == 600.0
    assert status["age_s"] == 0.5 and status["stale"] is False
    leg = document["ground"]["legs"]["SB1_F1"]
    assert leg == {
        "t": 50.0,
        "force_N": pytest.approx(82.5e3),
        "pressure_Pa": 250e3,
        "contact": True,
        "valid": True,
        "reasons": [],
    }
    later = latest_document(VIEWER, state, 12.0)
    assert later["ground"]["stale"] is True and later["status"]["stale"] is False
    assert latest_document(VIEWER, state, 13.5)["status"]["stale"] is True


def test_latest_document_says_why_the_service_is_unhealthy() -> None:
    # The page said "UNHEALTHY" and /api/latest had no word of why (a recording stopped,
    # an unreached endpoint), which only the service's own log and /status told.
    problems = ["recording stopped (write error)", "zenoh connect tcp/10.0.0.9:7447 not reached"]
    state = LiveState(PREFIX)
    payload = status_payload(50.0) | {"healthy": False, "problems": problems}
    state.apply(f"{PREFIX}/status", json.dumps(payload).encode(), 10.0)
    status = latest_document(VIEWER, state, 10.5)["status"]
    assert status["healthy"] is False and status["problems"] == problems
    state.apply(f"{PREFIX}/status", json.dumps(status_payload(51.0)).encode(), 11.0)
    assert latest_document(VIEWER, state, 11.5)["status"]["problems"] == []


def test_http_address() -> None:
    assert http_address("127.0.0.1:8080") == ("127.0.0.1", 8080)
    assert http_address("[::1]:0") == ("::1", 0)
    for bad in ("8080", "host:", ":80", "host:http", "h:70000"):
        with pytest.raises(ConfigError, match="expected HOST:PORT"):
            http_address(bad)


# --- the server, in-process -----------------------------------------------------


def get(url: str) -> tuple[int, str, bytes]:
    try:
        with urllib.request.urlopen(url, timeout=5) as response:
            return response.status, response.headers["Content-Type"], response.read()
    except urllib.error.HTTPError as exc:
        return exc.code, exc.headers["Content-Type"], exc.read()


def get_json(url: str) -> Any:
    status, content_type, body = get(url)
    assert status == 200 and content_type == "application/json"
    return json.loads(body)


def wait_for_json(url: str, ready: Callable[[Any], bool]) -> Any:
    deadline = time.monotonic() + WAIT_S
    while time.monotonic() < deadline:
        document = get_json(url)
        if ready(document):
            return document
        time.sleep(0.05)  # polling an HTTP API: there is no event to wait on
    raise AssertionError(f"{url} never ready: {document}")


@pytest.fixture
def dashboard_on_synthetic() -> Iterator[tuple[Dashboard, Any]]:
    port = free_port()
    config = peer_config(connect=f"tcp/127.0.0.1:{port}")
    with synthetic_service(port, PREFIX) as service, zenoh.open(config) as session:
        with Dashboard(session, VIEWER, ("127.0.0.1", 0)) as dashboard:
            yield dashboard, service


def test_server_serves_latest_history_and_the_page(
    dashboard_on_synthetic: tuple[Dashboard, Any],
) -> None:
    dashboard, service = dashboard_on_synthetic
    url = dashboard.url
    assert re.fullmatch(r"http://127\.0\.0\.1:\d+/", url)
    latest = wait_for_json(url + "api/latest", lambda d: d["ground"] and d["status"])
    assert latest["status"]["bus"] == {
        "state": "up",
        "interface": "virtual",
        "channel": "synthetic",
        "reason": None,
        "reopens": 0,
    }
    legs = latest["ground"]["legs"]
    phase_s = legs["SB1_F1"]["t"] - service.t0_s
    for leg, pressure_Pa in pressures_Pa(phase_s).items():
        assert legs[leg]["pressure_Pa"] == pytest.approx(pressure_Pa)
        assert legs[leg]["valid"] is True
    assert latest["ground"]["stale"] is False and latest["ground"]["age_s"] < 1.0

    history = wait_for_json(url + "api/history", lambda d: len(d["t"]) >= 5)
    assert history["reset"] is True and set(history["pressure_Pa"]) == set(LEGS)
    assert history["t"] == sorted(history["t"])
    last = history["t"][-1]
    newer = wait_for_json(
        url + f"api/history?since={last}&generation={history['generation']}",
        lambda d: len(d["t"]) >= 1,
    )
    assert newer["reset"] is False and newer["t"][0] > last

    status, content_type, page = get(url)
    assert status == 200 and content_type == "text/html; charset=utf-8"
    assert b'id="plot"' in page and b'id="bus-state"' in page
    # No internet on the machine: nothing may be loaded from elsewhere.
    assert not re.search(rb"""(src|href)\s*=\s*["']?(https?:)?//""", page)
    assert b"@import" not in page and b"url(" not in page

    status, content_type, body = get(url + "nowhere")
    assert status == 404 and json.loads(body) == {"error": "no route /nowhere"}


def test_late_joiner_gets_the_services_cache() -> None:
    """A dashboard started after the service's last status has it at once (the history
    of zenoh.ext's advanced subscriber, from the publisher's cache)."""
    port = free_port()
    with synthetic_service(port, PREFIX, start=False) as service:
        service.announce()
        deadline = time.monotonic() + WAIT_S  # the publisher's cache answers the get
        while service.publisher.published < 1 and time.monotonic() < deadline:
            time.sleep(0.01)
        config = peer_config(connect=f"tcp/127.0.0.1:{port}")
        with zenoh.open(config) as session, Dashboard(session, VIEWER, ("127.0.0.1", 0)) as board:
            latest = wait_for_json(board.url + "api/latest", lambda d: d["status"] is not None)
    assert latest["status"]["bus"]["state"] == "up"
    assert latest["waiting_for"] == f"{PREFIX}/ground"


def request_with_host(url: str, host: str | None) -> int:
    """The status of GET ``url`` sent with the ``Host`` header ``host`` (None: none)."""
    parts = urllib.parse.urlsplit(url)
    connection = http.client.HTTPConnection(parts.hostname or "", parts.port, timeout=5)
    try:
        connection.putrequest("GET", "/api/latest", skip_host=True)
        if host is not None:
            connection.putheader("Host", host)
        connection.endheaders()
        return connection.getresponse().status
    finally:
        connection.close()


def test_host_header_is_checked_against_dns_rebinding() -> None:
    with zenoh.open(peer_config()) as session:
        address = ("127.0.0.1", 0)
        with Dashboard(session, VIEWER, address, allowed_hosts=["PAM-1.local"]) as board:
            port = int(board.url.rsplit(":", 1)[1].strip("/"))
            for host in (f"127.0.0.1:{port}", f"localhost:{port}", "[::1]", f"pam-1.local:{port}"):
                assert request_with_host(board.url, host) == 200, host
            for host in (f"attacker.example:{port}", "127.0.0.1.attacker.example", "", None):
                assert request_with_host(board.url, host) == 403, host
            status, _, body = get(board.url.replace("127.0.0.1", "localhost") + "api/latest")
            assert status == 200 and json.loads(body)["viewer"]["missed"] == 0


def test_taken_port_is_a_portal_daq_error() -> None:
    with zenoh.open(peer_config()) as session:
        with Dashboard(session, VIEWER, ("127.0.0.1", 0)) as first:
            port = int(first.url.rsplit(":", 1)[1].strip("/"))
            second = Dashboard(session, VIEWER, ("127.0.0.1", port))
            with pytest.raises(PortalDaqError, match=f"HTTP: cannot listen on 127.0.0.1:{port}"):
                second.start()
            second.close()
