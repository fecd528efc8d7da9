"""The latency probe: a Zenoh subscriber in a process of its own, on a CPU of its own.

``python -m bench.subscriber --connect tcp/127.0.0.1:PORT [--cpu N]`` subscribes to
``bench/**`` and stamps every sample with ``time.time()`` on arrival. Samples on a
``.../leg/...`` key (the per-frame leg estimates, pipeline and baseline alike) carry
the frame time ``t`` in their JSON; the latency of one is ``arrival - t``. Nothing is
parsed in the callback, so the probe keeps up with the publishers.

It runs in its own process (pinned away from the measured CPU) so that its Python
work neither takes the measured process's GIL nor its core. Both processes read the
same system clock (``CLOCK_REALTIME``), so the times compare.

Protocol on stdin/stdout, one line each:

- it prints ``ready`` once a sample on ``bench/ping`` arrived (the route is up);
- ``collect EXPECTED TIMEOUT_S``: waits until ``EXPECTED`` leg samples arrived (or the
  timeout, or :data:`QUIET_S` without a new sample: a lost one never comes), prints
  one JSON object (:func:`summary`: each leg sample's frame time and arrival time)
  and starts counting afresh;
- ``quit`` (or end of input) closes the session.
"""

import argparse
import json
import os
import sys
import threading
import time
from collections.abc import Sequence
from typing import Any

import zenoh

PING_KEY = "bench/ping"
KEY = "bench/**"
#: ``collect`` gives up waiting for missing samples after this long without a new one.
QUIET_S = 2.0


def peer_config(*, connect: str | None = None, listen: str = "tcp/127.0.0.1:0") -> zenoh.Config:
    """Peer mode, multicast scouting off, loopback only."""
    config = zenoh.Config()
    config.insert_json5("mode", '"peer"')
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("listen/endpoints", json.dumps([listen]))
    if connect:
        config.insert_json5("connect/endpoints", json.dumps([connect]))
    return config


class Probe:
    """Keeps (arrival time, payload) of every leg sample; counts the others."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._legs: list[tuple[float, bytes]] = []
        self._others = 0
        self.ready = threading.Event()

    def on_sample(self, sample: zenoh.Sample) -> None:
        arrival_s = time.time()
        key = str(sample.key_expr)
        if "/leg/" in key:
            payload = sample.payload.to_bytes()
            with self._lock:
                self._legs.append((arrival_s, payload))
        elif key == PING_KEY:
            self.ready.set()
        else:
            with self._lock:
                self._others += 1

    def count(self) -> int:
        with self._lock:
            return len(self._legs)

    def take(self) -> tuple[list[tuple[float, bytes]], int]:
        with self._lock:
            legs, self._legs = self._legs, []
            others, self._others = self._others, 0
        return legs, others


def summary(legs: list[tuple[float, bytes]], others: int) -> dict[str, Any]:
    """The leg samples as [frame time, arrival] pairs, and the count of the others."""
    return {
        "leg_samples": [[json.loads(payload)["t"], arrival] for arrival, payload in legs],
        "other_samples": others,
    }


def serve(probe: Probe, lines: Any, out: Any) -> None:
    """Answer the commands read from ``lines`` on ``out`` (see the module docstring)."""
    for line in lines:
        words = line.split()
        if not words or words[0] == "quit":
            break
        if words[0] == "collect":
            expected, timeout_s = int(words[1]), float(words[2])
            deadline = time.monotonic() + timeout_s
            count, changed = probe.count(), time.monotonic()
            while count < expected and time.monotonic() < min(deadline, changed + QUIET_S):
                time.sleep(0.002)
                if probe.count() != count:
                    count, changed = probe.count(), time.monotonic()
            out.write(json.dumps(summary(*probe.take())) + "\n")
            out.flush()


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--connect", required=True, help="Zenoh endpoint of the publishers")
    parser.add_argument("--cpu", type=int, default=None, help="pin this process to one CPU")
    args = parser.parse_args(argv)
    if args.cpu is not None:
        os.sched_setaffinity(0, {args.cpu})
    probe = Probe()
    with zenoh.open(peer_config(connect=args.connect)) as session:
        subscriber = session.declare_subscriber(KEY, probe.on_sample)
        if not probe.ready.wait(30.0):
            return 1
        sys.stdout.write("ready\n")
        sys.stdout.flush()
        serve(probe, sys.stdin, sys.stdout)
        subscriber.undeclare()
    return 0


if __name__ == "__main__":
    sys.exit(main())
