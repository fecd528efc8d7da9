"""CPU time per thread of this process, and what other processes took meanwhile.

Per thread from Linux's ``/proc/self/task/*/schedstat``; other processes' share from
``/proc/stat`` minus this process's and the probe's ticks (the machine may be
shared: a busy neighbour makes the numbers worse, and the results say so).

Python threads are named by their ``threading`` name (the OS name of a thread is not
set by Python 3.11; python-can's ``Notifier for bus ...`` becomes ``Notifier``), the
others (Zenoh's runtime) by their OS name, digits removed so that a pool counts as
one (``rx-0``, ``rx-1`` -> ``rx-``).
"""

import os
import re
import subprocess
import sys
import threading
import time
from collections.abc import Collection, Mapping
from pathlib import Path

TASKS = Path("/proc/self/task")


def _ran_ns(task: Path) -> int | None:
    """Nanoseconds the thread ``/proc/.../task/<tid>`` ran so far; None once it ended."""
    try:
        return int((task / "schedstat").read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return None


def thread_cpu_ns(
    exclude: Collection[int] = (), children: Mapping[int, str] = {}
) -> dict[str, int]:
    """Nanoseconds each (named) thread of this process ran so far, but those in
    ``exclude`` (native thread IDs: e.g. another system's, idle meanwhile); and each child
    process in ``children`` (process ID -> name), all its threads under that name."""
    names = {thread.native_id: thread.name for thread in threading.enumerate()}
    totals: dict[str, int] = {}
    for task in TASKS.iterdir():
        if int(task.name) in exclude:
            continue
        ran_ns = _ran_ns(task)
        if ran_ns is None:
            continue
        try:
            os_name = (task / "comm").read_text().strip()
        except OSError:  # the thread ended meanwhile
            continue
        name = names.get(int(task.name)) or re.sub(r"\d+", "", os_name)
        name = name.split(" for bus ")[0]  # python-can's "Notifier for bus <channel>"
        totals[name] = totals.get(name, 0) + ran_ns
    for pid, name in children.items():
        for task in Path(f"/proc/{pid}/task").glob("*"):
            ran_ns = _ran_ns(task)
            if ran_ns is not None:
                totals[name] = totals.get(name, 0) + ran_ns
    return totals


def cpu_us_per_frame(
    before: dict[str, int], after: dict[str, int], frames: int
) -> dict[str, float]:
    """CPU microseconds per frame of each thread between two :func:`thread_cpu_ns` calls."""
    spent = {name: after[name] - before.get(name, 0) for name in after}
    per_frame = {
        name: round(ns / 1e3 / frames, 2) for name, ns in sorted(spent.items(), key=lambda x: -x[1])
    }
    per_frame = {name: us for name, us in per_frame.items() if us >= 0.05}
    per_frame["total"] = round(sum(spent.values()) / 1e3 / frames, 2)
    return per_frame


def busy_ticks() -> int:
    """Clock ticks all CPUs spent busy so far (``/proc/stat``: all but idle and iowait)."""
    ticks = [int(value) for value in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
    return sum(ticks) - ticks[3] - ticks[4]


def process_ticks(pid: int | str = "self") -> int:
    """Clock ticks a process ran so far (user + system, all threads); 0 once it is gone."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0
    return int(fields[11]) + int(fields[12])


class ForeignLoad:
    """How much CPU other processes took during a measurement: all CPUs' busy time
    minus this process's and the probe's (``pids``), in per cent of one CPU."""

    def __init__(self, pids: tuple[int | str, ...] = ("self",)) -> None:
        self.pids = pids
        self._start = self._sample()

    def _sample(self) -> tuple[float, int, int]:
        own = sum(process_ticks(pid) for pid in self.pids)
        return time.monotonic(), busy_ticks(), own

    def percent(self) -> float:
        (t0, busy0, own0), (t1, busy1, own1) = self._start, self._sample()
        foreign = (busy1 - busy0) - (own1 - own0)
        return round(max(0.0, 100.0 * foreign / os.sysconf("SC_CLK_TCK") / (t1 - t0)), 1)


class CpuHog:
    """A process spinning on ``cpu`` while the context lasts (a second job on the machine).

    It spins at ``SCHED_IDLE``: every cycle of that CPU nobody else wants. On a machine of
    two CPUs the latency probe (the measuring instrument, :mod:`bench.probe`) has to share
    the hog's CPU; at the same priority the hog delayed the probe's wake-ups by up to
    the scheduler's slice (the naive loop's p99 went from ~0.7 to ~4 ms), which measured
    the probe, not the system under test. What the hog does to that system (caches,
    memory bandwidth, a sibling hyperthread) it does at any priority.
    """

    def __init__(self, cpu: int) -> None:
        self.cpu = cpu
        self._process: subprocess.Popen[bytes] | None = None

    def __enter__(self) -> "CpuHog":
        self._process = subprocess.Popen([sys.executable, "-c", "while True: pass"])
        os.sched_setaffinity(self._process.pid, {self.cpu})
        os.sched_setscheduler(self._process.pid, os.SCHED_IDLE, os.sched_param(0))
        return self

    def __exit__(self, *exc_info: object) -> None:
        if self._process is not None:
            self._process.kill()
            self._process.wait()
