"""The simulator bridge on a real SocketCAN vcan0, recorded by can-utils' ``candump``.

``python -m sim_bridge`` plays the model's cycle at ``SPEED`` x real time while ``candump -L``
records with kernel time stamps. Every frame of every message arrives, and the DBC's cycle
times show in the order of the frames on the wire: ten LEG_SB1_F1 frames (10 ms) between
two MACHINE_STATE frames (100 ms), two between two STROKE_SB1 frames (20 ms). Nothing here
depends on how fast the machine is (inside User-Mode Linux, or on a loaded host, the bridge
falls behind the wall clock at 2x): that the due times are kept in real time is tested with
a fake clock (``tests/sim_bridge/test_emitter.py``), speed in ``bench/``.
"""

import re
from pathlib import Path

import pytest

from tests.helpers import EXAMPLE_CONFIG
from tests.vcan.bridge_support import run_bridge_recorded

pytestmark = pytest.mark.vcan

SPEED = 2.0
DURATION_S = 6.0  # simulated: 3 s on the bus
CANDUMP_LINE = re.compile(r"^\((\d+\.\d+)\) vcan0 ([0-9A-F]{3})#([0-9A-F]*)$")


def candump_frames(path: Path) -> list[tuple[float, int]]:
    """(kernel time stamp, ID) of every frame, in the order candump logged them."""
    frames = []
    for line in path.read_text().splitlines():
        match = CANDUMP_LINE.match(line.strip())
        if match:
            frames.append((float(match.group(1)), int(match.group(2), 16)))
    return frames


def counts_between(ids: list[int], marker: int, counted: int) -> list[int]:
    """How many ``counted`` frames lie between each two successive ``marker`` frames."""
    counts, current = [], None
    for frame_id in ids:
        if frame_id == marker:
            if current is not None:
                counts.append(current)
            current = 0
        elif frame_id == counted and current is not None:
            current += 1
    return counts


def test_the_bridge_keeps_the_dbc_cycle_times_on_vcan0(tmp_path: Path) -> None:
    log = tmp_path / "candump.log"
    bridge = run_bridge_recorded(
        log,
        ["--config", str(EXAMPLE_CONFIG), "--channel", "vcan0", "--cycles", "1",
         "--speed", str(SPEED), "--duration", str(DURATION_S), "--rtol", "1e-3"],
    )  # fmt: skip
    assert bridge.returncode == 0, bridge.stderr
    frames = candump_frames(log)
    ids = [frame_id for _, frame_id in frames]
    # candump started well before the bridge (whose start-up takes seconds): all frames.
    assert ids.count(0x100) == DURATION_S / 0.01, bridge.stderr
    assert ids.count(0x130) == DURATION_S / 0.1
    assert all(ids.count(frame_id) == DURATION_S / 0.02 for frame_id in (0x120, 0x123))
    assert set(counts_between(ids, 0x130, 0x100)) == {10}
    assert set(counts_between(ids, 0x120, 0x100)) == {2}
    assert set(counts_between(ids, 0x130, 0x123)) == {5}
    times = [t_s for t_s, _ in frames]
    assert times == sorted(times)  # kernel time stamps, in the order sent
