"""The fleet over a site router: three services, one router, the fleet dashboard.

Three services run in-process, each on its own python-can ``virtual`` bus fed by
the simulator bridge in real time (the model's first seconds, looped), each with
its own machine id and a Zenoh session in client mode connected only to the
router. The router is ``portal-daq router`` with the shipped
``deploy/zenoh-router.json5`` (its port changed), the dashboard a
``portal-daq dashboard --fleet`` process connected only to the router. Headless
Chromium renders the fleet page; one service stops and its row turns "gone"
(its liveliness token went), the others stay live.

Skipped without Chromium (``./dev test`` installs it). Set
``PORTAL_FLEET_PNG=docs/fleet.png`` to keep the screenshot (the README's).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

import can
import pytest
import zenoh

from daq.dashboard.fleet import FleetDashboard
from daq.live.feed import Item
from daq.live.fleet import FleetSettings
from daq.runner import bus_factory
from daq.service import Service
from daq.service_config import ServiceConfig, load_service_config
from daq.zenoh_session import zenoh_config
from dbc.decoding import FrameDecoder
from dbc.encoding import FrameEncoder
from sim_bridge.emitter import Emitter
from sim_bridge.frames import FrameBuilder
from sim_bridge.model import simulate
from sim_bridge.params import ModelParams
from sim_bridge.playout import Playout
from sim_bridge.result import SimulationResult
from tests.daq.live_support import synthetic_service
from tests.daq.service_support import WAIT_S, KeysSeen, free_port, peer_config
from tests.daq.test_dashboard import get, get_json, wait_for_json
from tests.daq.test_dashboard_chromium import CHROMIUM, chromium
from tests.helpers import EXAMPLE_CONFIG, LEGS, ROOT, example_machine

MACHINES = ("fleet-a", "fleet-b", "fleet-c")
ROUTER_CONFIG = ROOT / "deploy" / "zenoh-router.json5"


def router_file(tmp_path: Path, port: int) -> Path:
    """The shipped router config, listening on loopback at ``port``."""
    text = ROUTER_CONFIG.read_text()
    assert '"tcp/0.0.0.0:7447"' in text
    path = tmp_path / "zenoh-router.json5"
    path.write_text(text.replace('"tcp/0.0.0.0:7447"', f'"tcp/127.0.0.1:{port}"'))
    return path


@contextmanager
def process(args: list[str]) -> Iterator[tuple[subprocess.Popen[str], str]]:
    """``python -m daq ARGS`` and the first line it prints; SIGTERM at the end (exit 0)."""
    child = subprocess.Popen(
        [sys.executable, "-m", "daq", *args],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert child.stdout is not None
        yield child, child.stdout.readline()
        child.send_signal(signal.SIGTERM)
        assert child.wait(timeout=WAIT_S) == 0, child.communicate()[1]
    finally:
        if child.poll() is None:
            child.kill()
        child.communicate()


def machine_config(tmp_path: Path, machine_id: str, router: str) -> ServiceConfig:
    example = EXAMPLE_CONFIG.read_text()
    assert 'id = "pam-proto-1"' in example
    text = f"""
[bus]
interface = "virtual"
channel = "fleet-test-{machine_id}"

[zenoh]
mode = "client"
connect = ["{router}"]
multicast_scouting = false

[publish]
ground_rate_hz = 10.0
status_period_s = 0.5
"""
    path = tmp_path / f"{machine_id}.toml"
    path.write_text(text + example.replace('id = "pam-proto-1"', f'id = "{machine_id}"'))
    return load_service_config(path)


class Machine:
    """A service and the simulator bridge feeding its bus, each in a thread."""

    def __init__(self, config: ServiceConfig, cycle: SimulationResult) -> None:
        self.config = config
        filters = FrameDecoder(config.database, config.machine.protection).receive_filters
        self.session = zenoh.open(zenoh_config(config.zenoh))
        self.service = Service(
            config, open_bus=bus_factory(config.bus, filters), session=self.session
        )
        self.bus = can.Bus(interface="virtual", channel=config.bus.channel)
        playout = Playout(
            cycle,
            FrameBuilder(config.machine, config.database),
            FrameEncoder(config.database, config.machine.protection),
        )
        # Half speed: three buses and services in one process share the GIL.
        self.emitter = Emitter(self.bus, playout, end_sim_ns=None, speed=0.5)
        self._stop = threading.Event()
        self._threads = [
            threading.Thread(target=self.service.run, args=(self._stop,)),
            threading.Thread(target=self.emitter.run),
        ]
        self._stopped = False

    def start(self) -> None:
        self._threads[0].start()
        assert self.service.reader.opened.wait(WAIT_S)
        self._threads[1].start()

    def stop(self) -> None:
        """Stop the bridge and the service (which undeclares its token), close the session."""
        if self._stopped:
            return
        self._stopped = True
        self.emitter.stop()
        self._stop.set()
        for thread in self._threads:
            if thread.is_alive():
                thread.join()
        self.bus.shutdown()
        self.session.close()


@pytest.fixture(scope="module")
def cycle() -> SimulationResult:
    """The model's first 8 s (all six feet down, carriage moving): enough to loop."""
    machine, _ = example_machine()
    leg = next(iter(machine.legs.values())).geometry
    return simulate(ModelParams(leg=leg), rtol=1e-3, t_end_s=8.0)


def by_id(document: dict[str, Any]) -> dict[str, dict[str, Any]]:
    return {machine["machine_id"]: machine for machine in document["machines"]}


def all_live(document: dict[str, Any]) -> bool:
    """Every machine live with its six feet down and valid, and a status from after its bus
    opened (a loaded CI may take a moment: a bridge falling behind makes legs stale for a
    while; the first status may be sent before the bus is open)."""
    machines = by_id(document)
    return set(machines) == set(MACHINES) and all(
        m["state"] == "live"
        and m["bus_state"] == "up"
        and m["legs_in_contact"] == 6
        and m["stability_margin_m"] is not None
        for m in machines.values()
    )


def rows(dom: str) -> dict[str, str]:
    """machine id -> data-state of each row of the fleet table."""
    found = re.findall(r'<tr data-machine="([^"]+)" data-state="(\w+)"', dom)
    return dict(found)


@pytest.mark.skipif(CHROMIUM is None, reason="needs chromium (./dev test installs it)")
def test_fleet_page_shows_three_machines_and_one_gone(
    tmp_path: Path, cycle: SimulationResult
) -> None:
    port = free_port()
    router = f"tcp/127.0.0.1:{port}"
    with ExitStack() as stack:
        _, ready = stack.enter_context(
            process(["router", "--config", str(router_file(tmp_path, port))])
        )
        assert re.fullmatch(rf"router \w+ listening on {router}\n", ready), ready
        machines = {
            machine_id: Machine(machine_config(tmp_path, machine_id, router), cycle)
            for machine_id in MACHINES
        }
        for machine in machines.values():
            stack.callback(machine.stop)
            machine.start()
        dashboard, first = stack.enter_context(
            process(
                ["dashboard", "--fleet", "--connect", router, "--mode", "client"]
                + ["--http", "127.0.0.1:0"]
            )
        )
        match = re.fullmatch(r"dashboard of fleet portal/\* on (http://127\.0\.0\.1:\d+/)\n", first)
        assert match, first
        url = match.group(1)

        fleet = wait_for_json(url + "api/fleet", all_live)
        for machine_id, summary in by_id(fleet).items():
            assert summary["prefix"] == f"portal/{machine_id}"
            assert summary["healthy"] is True and summary["bus_state"] == "up"
            assert summary["legs"] == 6 and summary["legs_in_contact"] == 6  # all feet down
            # Six feet down share the 18.8 t: the most loaded one at 100..200 kPa.
            assert summary["max_pressure_leg"] in machines[machine_id].config.machine.legs
            assert 80e3 < summary["max_pressure_Pa"] < 250e3
            # Six feet down: the centre of pressure on the bridge's axis, 1.386 m from the
            # support polygon's long edges (issue 13's stability margin).
            assert summary["stability_margin_m"] == pytest.approx(1.3856, abs=0.01)
            assert summary["gone_for_s"] is None
        dom = chromium(tmp_path, url, "--dump-dom")
        # Present: live (or, on a loaded CI, a moment stale), none gone.
        assert set(rows(dom)) == set(MACHINES)
        assert set(rows(dom).values()) <= {"live", "stale"}
        assert 'href="machine/fleet-b/"' in dom
        assert "3 of 3 machines present" in dom

        # The monitor finds them too, connected only to the router.
        monitor = subprocess.run(
            [sys.executable, "-m", "daq", "monitor", "--fleet", "--plain", "--duration", "2.5"]
            + ["--connect", router, "--mode", "client"],
            cwd=ROOT,
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert monitor.returncode == 0, monitor.stderr
        for machine_id in MACHINES:  # in some line (a loaded CI may show a moment stale)
            pattern = rf"{machine_id} live healthy 6/6 \d+\.\d kPa SB\d_F\d"
            assert re.search(pattern, monitor.stdout), monitor.stdout

        # One machine's view, as a click on its row opens it.
        machine_url = url + "machine/fleet-b/"
        latest = get_json(machine_url + "api/latest")
        assert latest["machine_id"] == "fleet-b" and latest["prefix"] == "portal/fleet-b"
        assert latest["legs"] == list(machines["fleet-b"].config.machine.legs)
        page = chromium(tmp_path, machine_url, "--dump-dom")
        assert re.search(r'id="machine">fleet-b<', page)
        assert re.search(r'id="valid-SB1_F1"[^>]*>ok<', page)

        machines["fleet-b"].stop()
        fleet = wait_for_json(
            url + "api/fleet", lambda doc: by_id(doc)["fleet-b"]["state"] == "gone"
        )
        assert by_id(fleet)["fleet-b"]["gone_for_s"] is not None
        assert {by_id(fleet)[m]["state"] for m in ("fleet-a", "fleet-c")} <= {"live", "stale"}
        dom = chromium(tmp_path, url, "--dump-dom")
        shown = rows(dom)
        assert set(shown) == set(MACHINES) and shown.pop("fleet-b") == "gone"
        assert set(shown.values()) <= {"live", "stale"}
        assert "2 of 3 machines present" in dom
        if os.environ.get("PORTAL_FLEET_PNG"):
            shot = tmp_path / "fleet.png"
            chromium(tmp_path, url, f"--screenshot={shot}", "--window-size=1200,330")
            shutil.copyfile(shot, ROOT / os.environ["PORTAL_FLEET_PNG"])


def client_config(router: str) -> zenoh.Config:
    config = zenoh.Config()
    config.insert_json5("mode", '"client"')
    config.insert_json5("connect/endpoints", f'["{router}"]')
    config.insert_json5("scouting/multicast/enabled", "false")
    return config


def test_the_router_lets_no_simulation_truth_through(tmp_path: Path) -> None:
    """The shipped router's access control: data passes, ``portal/*/sim/**`` does not."""
    port = free_port()
    router = f"tcp/127.0.0.1:{port}"
    with (
        process(["router", "--config", str(router_file(tmp_path, port))]),
        zenoh.open(client_config(router)) as viewer,
        zenoh.open(client_config(router)) as other,
    ):
        received = KeysSeen(viewer, "portal/**")
        received.routed(lambda: other.put("portal/m/ground", b"{}"), "portal/m/ground")
        other.put("portal/m/sim/truth", b"{}")
        other.put("portal/m/status", b"{}")  # after the truth, from the same session
        received.wait_for("portal/m/status")
        received.undeclare()
    assert "portal/m/sim/truth" not in received


def test_fleet_routes_in_process() -> None:
    """The fleet dashboard's routes against a synthetic service (real Zenoh, loopback)."""
    port = free_port()
    with (
        synthetic_service(port, "portal/pam-x") as service,
        zenoh.open(peer_config(connect=f"tcp/127.0.0.1:{port}")) as session,
        FleetDashboard(session, FleetSettings("portal"), ("127.0.0.1", 0)) as dashboard,
    ):
        url = dashboard.url
        fleet = wait_for_json(
            url + "api/fleet", lambda doc: [m["state"] for m in doc["machines"]] == ["live"]
        )
        [machine] = fleet["machines"]
        assert (machine["machine_id"], machine["legs"]) == ("pam-x", len(LEGS))
        history = wait_for_json(url + "machine/pam-x/api/history", lambda doc: doc["t"])
        assert list(history["pressure_Pa"]) == list(LEGS)
        latest = get_json(url + "machine/pam-x/api/latest")
        assert latest["legs"] == list(LEGS) and latest["status"]["healthy"] is True
        status, kind, page = get(url + "machine/pam-x/")
        assert status == 200 and kind.startswith("text/html") and b'id="plot"' in page
        status, kind, page = get(url)
        assert status == 200 and b"portal-daq fleet" in page
        for missing in ("machine/nobody/api/latest", "machine/pam-x/api/other", "elsewhere"):
            assert get(url + missing)[0] == 404, missing
        service.close()  # its token goes: gone
        wait_for_json(url + "api/fleet", lambda doc: doc["machines"][0]["state"] == "gone")


def test_a_machine_back_with_other_legs_is_plotted_with_them() -> None:
    """A machine id that comes back with another config (other legs): its page's plot
    kept the first legs for ever, every new point a gap."""

    def ground(t_s: float, legs: tuple[str, ...]) -> Item:
        payload = {"t": t_s, "legs": {leg: {"pressure_Pa": 1e5, "valid": True} for leg in legs}}
        return Item("portal/rig/ground", json.dumps(payload).encode(), t_s)

    with zenoh.open(peer_config()) as session:
        dashboard = FleetDashboard(session, FleetSettings("portal"), ("127.0.0.1", 0))
        dashboard._apply(Item("portal/rig/alive", b"", 0.0, True))
        dashboard._apply(ground(1.0, ("A1", "A2")))
        dashboard._apply(ground(2.0, ("B1", "B2", "B3")))  # restarted as another rig
        code, _, body = dashboard.respond("/machine/rig/api/history", {})
    history = json.loads(body)
    assert code == 200 and history["generation"] == 1  # the page starts its plot anew
    assert history["t"] == [2.0]
    assert history["pressure_Pa"] == {"B1": [1e5], "B2": [1e5], "B3": [1e5]}
