"""The dashboard page in headless Chromium: a synthetic service on real Zenoh, the
dashboard as a process, the page's DOM and a screenshot checked pixel by pixel.

Skipped where Chromium is missing (``./dev test`` installs it). Set
``PORTAL_DASHBOARD_PNG=docs/dashboard.png`` to keep the screenshot (the README's).
"""

from __future__ import annotations

import html
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from matplotlib.image import imread

from tests.daq.live_support import synthetic_service
from tests.daq.service_support import WAIT_S, free_port, write_service_config
from tests.daq.test_dashboard import get_json, wait_for_json
from tests.helpers import LEGS, ROOT

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
pytestmark = pytest.mark.skipif(
    CHROMIUM is None, reason="needs chromium (apt-get install chromium; ./dev test does)"
)
PREFIX = "portal/pam-proto-1"
LIMIT_COLOUR = "#d62728"
COP_OK, FOOT = "#1a7f37", "#1e293b"
FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--window-size=1200,800",
    "--virtual-time-budget=5000",
    "--run-all-compositor-stages-before-draw",
]


def chromium(tmp_path: Path, url: str, *args: str) -> str:
    profile = tmp_path / f"profile-{uuid.uuid4().hex[:8]}"
    result = subprocess.run(
        [str(CHROMIUM), *FLAGS, f"--user-data-dir={profile}", *args, url],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    return result.stdout


def rgb(colour: str) -> np.ndarray:
    return np.array([int(colour[i : i + 2], 16) / 255 for i in (1, 3, 5)])


def pixels_of(image: np.ndarray, colour: str, tolerance: float = 0.06) -> np.ndarray:
    """(row, column) of the pixels within ``tolerance`` of ``colour`` in every channel."""
    close = np.all(np.abs(image[:, :, :3] - rgb(colour)) <= tolerance, axis=2)
    return np.argwhere(close)


def crop(image: np.ndarray, rect: dict[str, int], inset: int = 3) -> np.ndarray:
    x, y, w, h = rect["x"] + inset, rect["y"] + inset, rect["w"] - 2 * inset, rect["h"] - 2 * inset
    return image[y : y + h, x : x + w]


def body_data(dom: str, name: str) -> Any:
    match = re.search(rf'<body[^>]*\sdata-{name}="([^"]*)"', dom)
    assert match, f"no data-{name} on <body>"
    return json.loads(html.unescape(match.group(1)))


def cell(dom: str, element_id: str) -> str:
    match = re.search(rf'id="{element_id}"[^>]*>([^<]*)<', dom)
    assert match, f"no #{element_id}"
    return match.group(1)


def full_minute(history: Any) -> bool:
    """The history spans the plot's minute (Zenoh may drop a few of a burst's samples:
    its publishers' congestion control is "drop", so no exact count)."""
    t = history["t"]
    return len(t) >= 450 and t[-1] - t[0] >= 59.0


def test_dashboard_plots_the_pressures_and_shows_status(tmp_path: Path) -> None:
    port = free_port()
    config = write_service_config(tmp_path, port=port)
    with synthetic_service(port, PREFIX, start=False) as service:
        process = subprocess.Popen(
            [sys.executable, "-m", "daq", "dashboard", "--config", str(config)]
            + ["--http", "127.0.0.1:0"],
            cwd=ROOT,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            assert process.stdout is not None
            first = process.stdout.readline()
            match = re.fullmatch(rf"dashboard of {PREFIX} on (http://127\.0\.0\.1:\d+/)\n", first)
            assert match, first
            url = match.group(1)
            deadline = time.monotonic() + WAIT_S  # until the dashboard hears the service
            while get_json(url + "api/latest")["status"] is None:
                assert time.monotonic() < deadline, "the dashboard never heard the service"
                service.announce()
                time.sleep(0.1)
            service.backfill(60.0)  # a full minute to plot ...
            service.start()  # ... then live
            wait_for_json(url + "api/history", full_minute)
            dom = chromium(tmp_path, url, "--dump-dom")
            shot = tmp_path / "shot.png"
            chromium(tmp_path, url, f"--screenshot={shot}")
            process.send_signal(signal.SIGTERM)
            assert process.wait(timeout=WAIT_S) == 0
        finally:
            if process.poll() is None:
                process.kill()
            _, stderr = process.communicate()
    assert stderr == ""
    if os.environ.get("PORTAL_DASHBOARD_PNG"):
        shutil.copyfile(shot, ROOT / os.environ["PORTAL_DASHBOARD_PNG"])

    # The DOM after the page ran: status and every leg's row filled from the API.
    assert cell(dom, "bus-state") == "up"
    assert cell(dom, "frames-per-s") == "600" and cell(dom, "dropped") == "1"
    assert cell(dom, "health") == "healthy"
    for leg in LEGS:
        assert cell(dom, f"valid-{leg}") == "ok"
        assert cell(dom, f"contact-{leg}") in ("ground", "air")
        assert re.fullmatch(r"\d+\.\d", cell(dom, f"pressure-{leg}"))
    assert re.search(r'id="banner"[^>]*hidden', dom)  # no waiting / stale banner
    colours = dict(re.findall(r'data-color="(#[0-9a-f]{6})" data-leg="(\w+)"', dom))
    colours = {leg: colour for colour, leg in colours.items()}
    assert set(colours) == set(LEGS) and len(set(colours.values())) == len(LEGS)

    # The screenshot: each leg's line and the limit line inside the plot area.
    image = imread(shot)
    assert image.shape[:2] == (800, 1200)
    plot = crop(image, body_data(dom, "plot-rect"))
    for leg, colour in colours.items():
        found = pixels_of(plot, colour)
        assert len(found) >= 100, f"{leg}'s line ({colour}) is not plotted"
        columns = found[:, 1]
        assert columns.max() - columns.min() > 0.9 * plot.shape[1], f"{leg}: not 60 s wide"
    rows, counts = np.unique(pixels_of(plot, LIMIT_COLOUR)[:, 0], return_counts=True)
    limit_row = rows[counts.argmax()]  # the dashed line (its label is that colour too)
    assert counts.max() >= 0.4 * plot.shape[1], "no limit line"
    # SB1_F1 ramps up from 100 to 330 kPa over the minute: higher (smaller row) later on.
    ramp = pixels_of(plot, colours["SB1_F1"])
    width = plot.shape[1]
    early = ramp[ramp[:, 1] < 0.2 * width][:, 0].mean()
    late = ramp[(ramp[:, 1] > 0.6 * width) & (ramp[:, 1] < 0.85 * width)][:, 0].mean()
    assert late < early - 50
    assert late < limit_row < early  # and it crosses the limit
    # The plan view: the stability margin as text, the feet and the centre of pressure.
    assert re.search(
        r'id="stability-text" class="ok">margin \d\.\d\d m \(warning below 0\.30 m\)', dom
    )
    plan = crop(image, body_data(dom, "plan-rect"))
    assert f'data-cop-color="{COP_OK}"' in dom
    assert len(pixels_of(plan, COP_OK)) >= 60, "no centre of pressure drawn"
    assert len(pixels_of(plan, FOOT)) >= 6 * 30, "not every foot drawn"
    # The status bar holds text (light on dark), not nothing.
    status = crop(image, body_data(dom, "status-rect"), inset=0)
    assert (status[:, :, :3].mean(axis=2) > 0.8).sum() > 200
