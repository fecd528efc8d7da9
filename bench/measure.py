"""One measurement: offer frames to a system, wait for every estimate, report.

A system under test (:class:`Target`) takes frames (``send``, which stamps and
returns the frame time), says how many it processed and how long its publish and
record queues are. :func:`measure` offers a slice of frames in one of two modes:

- **throughput** (``rate_hz=None``): as fast as the system takes them; the sender
  waits while more than ``window`` frames are unprocessed or a queue is that long,
  so nothing is dropped. frames/s = frames / (first send until the last estimate
  reached the probe and the queues are empty).
- **paced**: frame ``i`` due at ``start + i / rate_hz``; also while a CPU hog
  (:class:`~bench.cpu.CpuHog`) runs on the other CPU (``paced_hog``), and at the DBC's
  nominal rate (``nominal``), where what counts is the CPU the service takes.

CPU: per thread of this process and of the system's child processes (the recorder's
process, :mod:`daq.recorder_process`) (``cpu_us_per_frame``); ``service_cpu_pct`` is every
thread but the sender's (``MainThread``) in per cent of one CPU over the measurement.

Latency is per leg estimate: from the frame's time stamp to the probe's arrival
time. In paced mode it is also reported from each frame's *due* time (a frame
the sender could only send late, because it shares the CPU, was "on the wire"
since then, as a kernel time stamp would say).
"""

import threading
from collections.abc import Callable, Collection, Mapping, Sequence
from contextlib import AbstractContextManager, ExitStack
from dataclasses import dataclass
from typing import Any, Protocol

import can
import numpy as np

from bench.cpu import CpuHog, ForeignLoad, cpu_us_per_frame, thread_cpu_ns
from bench.probe import ProbeProcess
from bench.sender import Sent, send_backpressured, send_paced
from bench.stats import latency_stats_ms


class Target(Protocol):
    def send(self, message: can.Message) -> float: ...
    def processed(self) -> int: ...
    def queued(self) -> int: ...
    def wait_processed(self, count: int, timeout_s: float) -> float: ...
    def counters(self) -> dict[str, Any]: ...
    def processes(self) -> Mapping[int, str]:
        """Child processes whose CPU is the system's (process ID -> name)."""
        ...


@dataclass(frozen=True)
class Plan:
    """What one system gets: frame counts, the paced rate, the backlog limit."""

    warmup: int
    throughput_frames: int
    paced_frames: int
    rate_hz: float
    window: int
    #: The paced measurement again while a CPU hog runs on this CPU (None: left out).
    hog_cpu: int | None = None
    #: Frames offered at ``nominal_rate_hz`` (0: left out).
    nominal_frames: int = 0
    nominal_rate_hz: float = 0.0
    #: Rounds as fast as taken (the systems take turns; each one's fastest counts).
    rounds: int = 1

    @property
    def frames(self) -> int:
        """Frames each system is offered in all."""
        return (
            self.warmup
            + self.rounds * self.throughput_frames
            + (2 if self.hog_cpu is not None else 1) * self.paced_frames
            + self.nominal_frames
        )


def measure(
    target: Target,
    probe: ProbeProcess,
    frames: Sequence[can.Message],
    leg_ids: set[int],
    *,
    rate_hz: float | None,
    window: int,
    timeout_s: float = 30.0,
    others: Collection[int] = (),
) -> dict[str, Any]:
    """Offer ``frames`` (paced at ``rate_hz``, or as fast as taken), wait until every
    estimate arrived, and report frames/s, latency and CPU time per frame."""
    base = target.processed()
    expected_legs = sum(1 for frame in frames if frame.arbitration_id in leg_ids)
    children = target.processes()
    cpu_before = thread_cpu_ns(others, children)
    foreign = ForeignLoad(("self", probe.pid, *children))
    if rate_hz is None:

        def busy(sent: int) -> bool:
            return sent - (target.processed() - base) > window or target.queued() > window

        sent: Sent = send_backpressured(target.send, frames, busy)
    else:
        sent = send_paced(target.send, frames, rate_hz)
    done_s = target.wait_processed(base + len(frames), timeout_s)
    cpu_per_frame = cpu_us_per_frame(cpu_before, thread_cpu_ns(others, children), len(frames))
    foreign_pct = foreign.percent()
    received = probe.collect(expected_legs, timeout_s)
    pairs = np.array(received["leg_samples"], dtype=np.float64).reshape(-1, 2)
    stamps, arrivals = pairs[:, 0], pairs[:, 1]
    end_s = max(done_s, float(arrivals.max())) if arrivals.size else done_s
    elapsed_s = end_s - sent.start_s
    result: dict[str, Any] = {
        "mode": "throughput" if rate_hz is None else "paced",
        "offered_rate_hz": rate_hz,
        "frames": len(frames),
        "sent_rate_hz": round(sent.rate_hz, 1),
        "elapsed_s": round(elapsed_s, 4),
        "frames_per_s": round(len(frames) / elapsed_s, 1),
        "processed": target.processed() - base,
        "leg_estimates_expected": expected_legs,
        "leg_estimates_received": int(arrivals.size),
        "other_messages_received": received["other_samples"],
        "latency_ms": latency_stats_ms(arrivals - stamps),
    }
    if sent.due_by_stamp is not None:
        due = np.array([sent.due_by_stamp.get(stamp, np.nan) for stamp in stamps.tolist()])
        result["latency_from_due_ms"] = latency_stats_ms((arrivals - due)[~np.isnan(due)])
        result["late_sends"] = sent.late_frames
        result["max_send_lateness_ms"] = round(sent.max_lateness_s * 1e3, 3)
    result["cpu_us_per_frame"] = cpu_per_frame
    service_us = cpu_per_frame["total"] - cpu_per_frame.get("MainThread", 0.0)
    result["service_cpu_pct"] = round(service_us * len(frames) / elapsed_s / 1e4, 2)
    result["other_processes_cpu_pct"] = foreign_pct
    return result


@dataclass(frozen=True)
class System:
    """A system under test, the interpreter settings it runs with (e.g. the service's
    :func:`daq.interpreter.tuned_interpreter`), and its own Python threads (native IDs;
    left out of the others' CPU time while they are measured)."""

    target: Target
    interpreter: Callable[[], AbstractContextManager[None]]
    threads: frozenset[int]


class ManagedTarget(Target, Protocol):
    """A :class:`Target` that starts on entering and stops on leaving its context."""

    def __enter__(self) -> Any: ...

    def __exit__(self, *exc_info: object) -> Any: ...


def entered(
    stack: ExitStack,
    target: ManagedTarget,
    interpreter: Callable[[], AbstractContextManager[None]],
) -> System:
    """``target`` entered on ``stack`` (started), as a :class:`System` whose threads are the
    Python threads that entering it started."""

    def python_threads() -> frozenset[int]:
        return frozenset(t.native_id for t in threading.enumerate() if t.native_id is not None)

    before = python_threads()
    stack.enter_context(target)
    return System(target, interpreter, python_threads() - before)


def run_systems(
    systems: Mapping[str, System],
    probe: ProbeProcess,
    frames: Sequence[can.Message],
    leg_ids: set[int],
    plan: Plan,
) -> dict[str, dict[str, Any]]:
    """Every system (by name) on the same consecutive slices of ``frames`` (the rolling
    counters run on, so every frame passes its checks), taking turns: the warm-up, then
    :attr:`Plan.rounds` rounds as fast as taken, then paced, paced with a CPU hog,
    nominal, each system after the other, so that a neighbour's burst of load on a
    shared machine hits them alike. Of the rounds as fast as taken, each system's
    fastest is its ``throughput`` (all in ``throughput_rounds``)."""
    at = 0

    def take(count: int) -> Sequence[can.Message]:
        nonlocal at
        at += count
        return frames[at - count : at]

    def turns(chunk: Sequence[can.Message], rate_hz: float | None) -> dict[str, dict[str, Any]]:
        results = {}
        for name, system in systems.items():
            others = set().union(*(s.threads for n, s in systems.items() if n != name))
            with system.interpreter():
                results[name] = measure(
                    system.target,
                    probe,
                    chunk,
                    leg_ids,
                    rate_hz=rate_hz,
                    window=plan.window,
                    others=others,
                )
        return results

    measured: dict[str, list[dict[str, Any]]] = {name: [] for name in systems}
    results: dict[str, dict[str, Any]] = {name: {} for name in systems}

    def keep(mode: str, by_system: dict[str, dict[str, Any]]) -> None:
        for name, result in by_system.items():
            result["mode"] = mode
            results[name][mode] = result
            measured[name].append(result)

    for name, result in turns(take(plan.warmup), None).items():
        measured[name].append(result)
    rounds = [turns(take(plan.throughput_frames), None) for _ in range(plan.rounds)]
    for name in systems:
        mine = [by_system[name] for by_system in rounds]
        measured[name] += mine
        results[name]["throughput"] = max(mine, key=lambda result: result["frames_per_s"])
        results[name]["throughput_rounds"] = [
            {
                "frames_per_s": result["frames_per_s"],
                "cpu_us_per_frame": result["cpu_us_per_frame"]["total"],
                "other_processes_cpu_pct": result["other_processes_cpu_pct"],
            }
            for result in mine
        ]
    keep("paced", turns(take(plan.paced_frames), plan.rate_hz))
    if plan.hog_cpu is not None:
        with CpuHog(plan.hog_cpu):
            keep("paced_hog", turns(take(plan.paced_frames), plan.rate_hz))
    if plan.nominal_frames:
        keep("nominal", turns(take(plan.nominal_frames), plan.nominal_rate_hz))
    for name, system in systems.items():
        results[name]["offered"] = {
            "frames": sum(result["frames"] for result in measured[name]),
            "leg_frames": sum(result["leg_estimates_expected"] for result in measured[name]),
        }
        results[name]["counters"] = system.target.counters()
    return results
