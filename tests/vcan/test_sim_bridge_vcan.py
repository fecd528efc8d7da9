"""The simulator bridge on a real SocketCAN vcan0, recorded by can-utils' ``candump``.

``python -m sim_bridge`` plays the model's cycle at ``SPEED`` x real time while ``candump -L``
records with kernel time stamps; the mean inter-arrival of LEG_SB1_F1 (0x100, 10 ms) and
MACHINE_STATE (0x130, 100 ms) must be the cycle time / ``SPEED`` within 30 %. Only means:
inside User-Mode Linux every system call costs ~0.1 ms, which allows a few thousand frames
per second (the full DBC at 2x is ~2000/s; at 10x, 10000/s, the sender falls behind), and
single frames can be late by tens of ms.
"""

import re
from collections import defaultdict
from pathlib import Path

import pytest

from tests.helpers import EXAMPLE_CONFIG
from tests.vcan.bridge_support import run_bridge_recorded

pytestmark = pytest.mark.vcan

SPEED = 2.0
DURATION_S = 6.0  # simulated: 3 s on the bus
CANDUMP_LINE = re.compile(r"^\((\d+\.\d+)\) vcan0 ([0-9A-F]{3})#([0-9A-F]*)$")


def candump_times(path: Path) -> dict[int, list[float]]:
    times: dict[int, list[float]] = defaultdict(list)
    for line in path.read_text().splitlines():
        match = CANDUMP_LINE.match(line.strip())
        if match:
            times[int(match.group(2), 16)].append(float(match.group(1)))
    return times


def mean_interval_s(times: list[float]) -> float:
    return (times[-1] - times[0]) / (len(times) - 1)


def test_the_bridge_keeps_the_dbc_cycle_times_on_vcan0(tmp_path: Path) -> None:
    log = tmp_path / "candump.log"
    bridge = run_bridge_recorded(
        log,
        ["--config", str(EXAMPLE_CONFIG), "--channel", "vcan0", "--cycles", "1",
         "--speed", str(SPEED), "--duration", str(DURATION_S), "--rtol", "1e-3"],
    )  # fmt: skip
    assert bridge.returncode == 0, bridge.stderr
    times = candump_times(log)
    legs, state = times[0x100], times[0x130]
    # candump started well before the bridge (whose start-up takes seconds): all frames.
    assert len(legs) == DURATION_S / 0.01, bridge.stderr
    assert len(state) == DURATION_S / 0.1
    assert mean_interval_s(legs) == pytest.approx(0.010 / SPEED, rel=0.3), bridge.stderr
    assert mean_interval_s(state) == pytest.approx(0.100 / SPEED, rel=0.3), bridge.stderr
    assert all(len(times[frame_id]) == DURATION_S / 0.02 for frame_id in (0x120, 0x123))
