"""Running ``python -m sim_bridge`` on vcan0 while ``candump -L`` records what goes out."""

import signal
import subprocess
import sys
from pathlib import Path

from tests.helpers import ROOT

#: candump's socket receive buffer: in the loaded guest candump falls behind by seconds,
#: and its default buffer (~250 frames; 4 MiB too) overflowed.
CANDUMP_RCVBUF_BYTES = 32 * 1024 * 1024


def run_bridge_recorded(
    log: Path, bridge_args: list[str], *, timeout_s: float = 120
) -> subprocess.CompletedProcess[str]:
    """Run the bridge with ``bridge_args`` (``--channel`` included) while candump records
    vcan0 into ``log``."""
    candump = ["candump", "-L", "-r", str(CANDUMP_RCVBUF_BYTES), "vcan0"]
    with open(log, "w") as out, subprocess.Popen(candump, stdout=out) as dump:
        try:
            return subprocess.run(
                [sys.executable, "-m", "sim_bridge", *bridge_args],
                cwd=ROOT,
                capture_output=True,
                text=True,
                timeout=timeout_s,
            )
        finally:
            dump.send_signal(signal.SIGINT)  # candump flushes its output and exits
            dump.wait(timeout=30)
