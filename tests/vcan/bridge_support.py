"""Running ``python -m sim_bridge`` on vcan0 while ``candump -L`` records what goes out."""

import re
import signal
import subprocess
import sys
import time
from pathlib import Path

from tests.helpers import ROOT

#: candump's socket receive buffer: in the loaded guest candump falls behind by seconds,
#: and its default buffer (~250 frames) overflows.
CANDUMP_RCVBUF_BYTES = 32 * 1024 * 1024
#: How long candump may take to write out the frames it is behind by ...
CATCH_UP_S = 60.0
#: ... judged done when its log has not grown for this long (it writes in 4 KiB blocks,
#: ~60 frames, several times a second while it is behind).
QUIET_S = 2.0
#: The bridge's closing log line: how many frames it sent.
BRIDGE_SENT = re.compile(r"sent (\d+) frames in")


def frames_sent(bridge: subprocess.CompletedProcess[str]) -> int:
    """How many frames the bridge says it sent (from its log on stderr)."""
    match = BRIDGE_SENT.search(bridge.stderr)
    assert match, bridge.stderr
    return int(match.group(1))


def run_bridge_recorded(
    log: Path, bridge_args: list[str], *, timeout_s: float = 120
) -> subprocess.CompletedProcess[str]:
    """Run the bridge with ``bridge_args`` (``--channel`` included) while candump records
    vcan0 into ``log``, one line per frame; candump is stopped once it has caught up:
    stopped earlier, it would drop the frames it has not read yet. (Line-buffered output
    would show its progress exactly, but a write per frame slows the one-CPU guest so much
    that the bridge falls behind.)"""
    candump = ["candump", "-L", "-r", str(CANDUMP_RCVBUF_BYTES), "vcan0"]
    with open(log, "w") as out, subprocess.Popen(candump, stdout=out) as dump:
        try:
            bridge = subprocess.run(
                [sys.executable, "-m", "sim_bridge", *bridge_args],
                cwd=ROOT,
                capture_output=True,
                text=True,
                timeout=timeout_s,
            )
            deadline = time.monotonic() + CATCH_UP_S
            size, quiet_since = -1, time.monotonic()
            while time.monotonic() < deadline and time.monotonic() - quiet_since < QUIET_S:
                if log.stat().st_size != size:
                    size, quiet_since = log.stat().st_size, time.monotonic()
                time.sleep(0.1)
            return bridge
        finally:
            dump.send_signal(signal.SIGINT)  # candump flushes its output and exits
            dump.wait(timeout=30)
