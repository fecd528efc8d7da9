"""``portal-daq monitor`` end to end: the real service pipeline (python-can virtual bus,
real Zenoh on loopback) in this process, the monitor as a process in a real terminal
(tmux), its screen read back with ``tmux capture-pane``.

Skipped where tmux is missing (``./dev test`` installs it).
"""

from __future__ import annotations

import re
import shlex
import shutil
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from daq.service_config import ServiceConfig, load_service_config
from estimator.equations import foot_force_N
from tests.daq.service_support import (
    WAIT_S,
    can_message,
    free_port,
    leg_signals,
    write_service_config,
)
from tests.daq.test_service_live import encoder_for, live_service, sender
from tests.helpers import LEGS, ROOT

pytestmark = pytest.mark.skipif(
    shutil.which("tmux") is None, reason="needs tmux (apt-get install tmux; ./dev test does)"
)

#: Chamber pressures (piston, rod) per leg, multiples of the DBC's 1000 Pa step.
CHAMBERS_PA = {
    "SB1_F1": (16e6, 1e6),  # 252.5 kPa: above the 200 kPa limit
    "SB1_F2": (12e6, 1e6),
    "SB1_F3": (9e6, 1e6),
    "SB2_F1": (6e6, 1e6),
    "SB2_F2": (4e6, 1e6),
    "SB2_F3": (1e6, 1e6),  # 4.3 kN: below contact_on_N, in the air
}


class Tmux:
    """A tmux server of its own (``-L``), so a user's sessions are never touched."""

    def __init__(self, tmp_path: Path) -> None:
        self.socket = f"portal-test-{uuid.uuid4().hex[:8]}"
        self.status_file = tmp_path / "status"
        self.stderr_file = tmp_path / "stderr"

    def run(self, *args: str) -> str:
        return subprocess.run(
            ["tmux", "-L", self.socket, "-f", "/dev/null", *args],
            capture_output=True,
            text=True,
            check=True,
            timeout=10,
        ).stdout

    def start(self, command: list[str]) -> None:
        """Run ``command`` in a 120x40 pane; its exit status goes to ``status_file``."""
        line = (
            f"cd {shlex.quote(str(ROOT))} && {shlex.join(command)} 2>{self.stderr_file}; "
            f"echo $? > {self.status_file}; sleep 600"
        )
        self.run("new-session", "-d", "-x", "120", "-y", "40", line)

    def screen(self) -> str:
        return self.run("capture-pane", "-p")

    def wait_for_screen(self, ready: Callable[[str], bool], timeout: float = WAIT_S) -> str:
        deadline = time.monotonic() + timeout
        screen = ""
        while time.monotonic() < deadline:
            screen = self.screen()
            if ready(screen):
                return screen
            time.sleep(0.1)  # polling the pane: there is no event to wait on
        stderr = self.stderr_file.read_text() if self.stderr_file.exists() else ""
        raise AssertionError(f"screen never ready:\n{screen}\nstderr:\n{stderr}")

    def exit_status(self, timeout: float = WAIT_S) -> int:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self.status_file.exists() and self.status_file.read_text().strip():
                return int(self.status_file.read_text())
            time.sleep(0.05)
        raise AssertionError(f"the monitor did not exit:\n{self.screen()}")

    def kill(self) -> None:
        subprocess.run(["tmux", "-L", self.socket, "kill-server"], capture_output=True, timeout=10)


@pytest.fixture
def tmux(tmp_path: Path) -> Iterator[Tmux]:
    terminal = Tmux(tmp_path)
    try:
        yield terminal
    finally:
        terminal.kill()


@pytest.fixture
def config(tmp_path: Path) -> ServiceConfig:
    path = write_service_config(
        tmp_path, channel=f"test-{uuid.uuid4().hex}", port=free_port(), recording=tmp_path / "rec"
    )
    return load_service_config(path)


@contextmanager
def sending_frames(config: ServiceConfig) -> Iterator[None]:
    """Every leg's frame every 10 ms, stamped now (else the legs go stale), from a thread."""
    stop = threading.Event()
    encoder = encoder_for(config)

    def run() -> None:
        with sender(config) as bus:
            while not stop.wait(0.01):
                now = time.time()
                for leg, (p_piston, p_rod) in CHAMBERS_PA.items():
                    frame = encoder.encode(f"LEG_{leg}", leg_signals(leg, p_piston, p_rod))
                    bus.send(can_message(frame, now))

    thread = threading.Thread(target=run, name="can-sender")
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()


def expected_row(config: ServiceConfig, leg: str) -> re.Pattern[str]:
    """The leg's row, numbers computed here from eq. (4) and (5)."""
    geometry = config.machine.legs[leg].geometry
    force_N = foot_force_N(*CHAMBERS_PA[leg], geometry)
    pressure_kPa = force_N / geometry.A_foot_m2 / 1e3
    contact = "ground" if force_N >= config.machine.estimator.contact_on_N else "air"
    # A foot in the air shows 0 kPa (the soil metrics' peak keeps eq. 5 of its force).
    shown_kPa = pressure_kPa if contact == "ground" else 0.0
    percent = shown_kPa * 1e3 / config.machine.estimator.pressure_limit_Pa * 100
    return re.compile(
        rf"^{leg}\s+{force_N / 1e3:.1f}\s+{shown_kPa:.1f}\s+\[[#!.|]{{30}}\]\s+"
        rf"{percent:.0f}%\s+{contact}\s+{pressure_kPa:.1f}\s+[\d.]+\s+ok\s*$",
        re.MULTILINE,
    )


def monitor(config: ServiceConfig, *args: str) -> list[str]:
    return [sys.executable, "-m", "daq", "monitor", "--config", config.source, *args]


def test_monitor_shows_the_live_service_in_a_terminal(config: ServiceConfig, tmux: Tmux) -> None:
    rows = {leg: expected_row(config, leg) for leg in LEGS}
    stale_row = re.compile(r"^SB1_F1\s+83\.3\s+252\.5\s.*INVALID stale$", re.MULTILINE)
    with live_service(config):
        with sending_frames(config):
            tmux.start(monitor(config))  # no --connect: found from the config's listen endpoint
            screen = tmux.wait_for_screen(lambda s: all(row.search(s) for row in rows.values()))
        # Frames stop: once the bus has been silent for LAG_TOLERANCE_S, the service
        # judges every leg stale, and the monitor shows it with the last values.
        stale_screen = tmux.wait_for_screen(lambda s: stale_row.search(s) is not None)
    # SB1_F1 at 252.5 kPa: 25 of 30 cells, 20 below the limit, 5 above.
    assert "[####################!!!!!.....]  126%  ground" in screen
    # SB2_F3 at 4.3 kN, below contact_on_N: in the air, 0 kPa (was 13.1 kPa, 7 %).
    assert re.search(r"^SB2_F3 .*\[\.{20}\|\.{9}\]\s+0%\s+air\s", screen, re.MULTILINE)
    lines = screen.splitlines()
    assert lines[0].startswith("portal-daq monitor  portal/pam-proto-1  pressure limit 200.0 kPa")
    assert re.match(
        r"bus up \(virtual test-\w+\), \d+ frames/s, 0 bad, 0 dropped, healthy", lines[1]
    )
    assert "5 legs in contact, complete" in lines[2]
    assert "SB2_F3" in stale_screen
    # Then the service stops: the monitor says so and keeps the last values in view.
    tmux.wait_for_screen(lambda s: "STALE: no status" in s and stale_row.search(s) is not None)
    tmux.run("send-keys", "C-c")
    assert tmux.exit_status() == 0
    assert tmux.stderr_file.read_text() == ""


def test_monitor_waits_for_the_service_and_quits_on_q(config: ServiceConfig, tmux: Tmux) -> None:
    tmux.start(monitor(config))
    screen = tmux.wait_for_screen(lambda s: "waiting for portal/pam-proto-1/status" in s)
    assert "waiting for portal/pam-proto-1/ground" in screen
    tmux.run("send-keys", "q")
    assert tmux.exit_status() == 0


def test_plain_mode_prints_one_line_per_second(config: ServiceConfig) -> None:
    with live_service(config), sending_frames(config):
        result = subprocess.run(
            monitor(config, "--plain", "--duration", "3"),
            capture_output=True,
            text=True,
            timeout=60,
            cwd=ROOT,
        )
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert len(lines) == 3, result.stdout
    geometry = config.machine.legs["SB1_F1"].geometry
    force_N = foot_force_N(*CHAMBERS_PA["SB1_F1"], geometry)
    expected = (
        f"SB1_F1 {force_N / 1e3:.1f} kN {force_N / geometry.A_foot_m2 / 1e3:.1f} kPa ground ok"
    )
    assert expected in lines[-1] and " bus up " in lines[-1]
