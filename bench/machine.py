"""The machine the benchmark runs on: its description, CPU pinning, a free TCP port,
and what one sleep and wake-up costs it."""

import os
import platform
import socket
import statistics
import time
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path
from typing import Any

PACKAGES = ("python-can", "cantools", "eclipse-zenoh", "mcap", "numpy")


def pin_to_one_cpu() -> tuple[int, int | None]:
    """Pin every thread of this process to its first allowed CPU (threads started later
    inherit it); returns that CPU and another allowed one (None on a single CPU)."""
    cpus = sorted(os.sched_getaffinity(0))
    for task in os.listdir("/proc/self/task"):
        try:
            os.sched_setaffinity(int(task), {cpus[0]})
        except OSError:  # the thread ended meanwhile
            pass
    return cpus[0], cpus[1] if len(cpus) > 1 else None


def unpin(cpus: set[int]) -> None:
    """Give every thread of this process ``cpus`` again."""
    for task in os.listdir("/proc/self/task"):
        try:
            os.sched_setaffinity(int(task), cpus)
        except OSError:
            pass


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine_info() -> dict[str, Any]:
    """CPU model (``/proc/cpuinfo``), cores, Python, kernel, date, package versions."""
    versions: dict[str, str | None] = {}
    for package in PACKAGES:
        try:
            versions[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            versions[package] = None
    return {
        "cpu": cpu_model(),
        "cores": os.cpu_count(),
        "python": platform.python_version(),
        "implementation": platform.python_implementation(),
        "kernel": platform.release(),
        "date": datetime.now(UTC).isoformat(timespec="seconds"),
        "load_average": os.getloadavg(),
        "packages": versions,
    }


#: Sleeps measured by :func:`wakeup_cpu_us`, and how long each (a frame's gap at the
#: DBC's nominal rate).
WAKEUPS = 200
WAKEUP_SLEEP_S = 0.001


def wakeup_cpu_us(count: int = WAKEUPS) -> float:
    """CPU time (us, median) of one ``time.sleep(1 ms)`` of this thread: arming the timer,
    blocking, being woken and scheduled again, no work. At a frame per wake-up this is
    the machine's floor per frame (on a virtual machine, tens of microseconds)."""
    costs = []
    for _ in range(count):
        start = time.thread_time()
        time.sleep(WAKEUP_SLEEP_S)
        costs.append(time.thread_time() - start)
    return round(statistics.median(costs) * 1e6, 1)


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])
