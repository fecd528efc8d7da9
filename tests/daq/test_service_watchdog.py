"""The service in-process with a scripted frame source: kernel losses on /status, the watchdog.

A real Zenoh session on loopback and a real AF_UNIX notify socket; the frame
source stands in for the kernel socket (frames on demand, a drop counter, a
receive that can hang).
"""

from __future__ import annotations

import queue
import socket
import threading
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
import zenoh

from daq.frames import RawFrame
from daq.sd_notify import SdNotifier
from daq.service import HEARTBEAT_MAX_AGE_S, Service
from daq.service_config import ServiceConfig, load_service_config
from daq.zenoh_session import zenoh_config
from tests.daq.service_support import WAIT_S, free_port, running, write_service_config


class KernelSource:
    """Frames pushed by the test, each with the kernel's drop count; ``hang`` makes
    ``recv`` block (a reader thread stuck in a call) until ``release``."""

    rcvbuf_bytes = 8192

    def __init__(self) -> None:
        self.frames: queue.Queue[tuple[RawFrame, int]] = queue.Queue()
        self.kernel_dropped = 0
        self.hang = threading.Event()
        self.release = threading.Event()
        self.hanging = threading.Event()

    def recv(self, timeout_s: float) -> RawFrame | None:
        if self.hang.is_set():
            self.hanging.set()
            self.release.wait()
        try:
            frame, self.kernel_dropped = self.frames.get(timeout=timeout_s)
        except queue.Empty:
            return None
        return frame

    def shutdown(self) -> None:
        self.release.set()


@pytest.fixture
def config(tmp_path: Path) -> ServiceConfig:
    path = write_service_config(tmp_path, channel=f"test-{uuid.uuid4().hex}", port=free_port())
    return load_service_config(path)


@contextmanager
def service_on(
    config: ServiceConfig, source: KernelSource, notifier: SdNotifier | None = None
) -> Iterator[Service]:
    """The service reading ``source``, run by :meth:`Service.run` in a thread."""
    with zenoh.open(zenoh_config(config.zenoh)) as session:
        service = Service(config, open_bus=lambda: source, session=session, notifier=notifier)
        with running(service):
            try:
                yield service
            finally:
                source.release.set()  # a hung reader must return for the service to close


def wait_until(condition: object, timeout_s: float = WAIT_S) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():  # type: ignore[operator]
        assert time.monotonic() < deadline, "condition not met in time"
        time.sleep(0.01)


def test_kernel_drops_show_on_status_and_make_only_that_period_unhealthy(
    tmp_path: Path,
) -> None:
    # The periods are the test's own status() calls: the service's loop takes its first
    # status at start and the next an hour later (at 0.2 s it could take the drops' one).
    path = write_service_config(
        tmp_path, channel=f"test-{uuid.uuid4().hex}", port=free_port(), status_period_s=3600.0
    )
    config = load_service_config(path)
    source = KernelSource()
    with service_on(config, source) as service:
        # The loop's first status must be behind us: taken after the drops, it took their
        # period and the test's own call below found it healthy (a race, seen once).
        wait_until(lambda: service._lost_mark)
        before = service.status()
        source.frames.put((RawFrame(time.time(), 0x7AA, False, b""), 0))
        source.frames.put((RawFrame(time.time(), 0x7AA, False, b""), 7))
        wait_until(lambda: service.reader.received == 2)
        lost = service.status()
        after = service.status()
    assert before["bus"]["rcvbuf_bytes"] == 8192
    # Only the drops matter here: "no frame for ..." may join in on a slow machine.
    assert (before["dropped"]["kernel"], dropped_problems(before)) == (0, [])
    assert (lost["dropped"]["kernel"], lost["frames"]["dropped"], lost["healthy"]) == (7, 7, False)
    assert dropped_problems(lost) == ["dropped.kernel +7"]
    assert (after["dropped"]["kernel"], dropped_problems(after)) == (7, [])


def dropped_problems(status: dict[str, Any]) -> list[str]:
    return [problem for problem in status["problems"] if problem.startswith("dropped")]


def notifications(sock: socket.socket, timeout_s: float = WAIT_S) -> Iterator[str]:
    """Each line of each datagram the service sends, until ``timeout_s`` ends."""
    deadline = time.monotonic() + timeout_s
    while (left_s := deadline - time.monotonic()) > 0:
        sock.settimeout(left_s)
        try:
            datagram = sock.recv(4096)
        except TimeoutError:
            return
        yield from datagram.decode().splitlines()


def test_a_hung_reader_thread_stops_the_watchdog_pings(
    config: ServiceConfig, tmp_path: Path
) -> None:
    address = str(tmp_path / "notify.sock")
    source = KernelSource()
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as sock:
        sock.bind(address)
        notifier = SdNotifier(address, watchdog_usec=400_000)
        with notifier, service_on(config, source, notifier):
            lines = notifications(sock)
            assert "WATCHDOG=1" in lines  # healthy: pinged
            source.hang.set()
            assert source.hanging.wait(WAIT_S)
            # Pings go on until the reader's heartbeat is HEARTBEAT_MAX_AGE_S old; then
            # status after status must come without one.
            quiet_statuses = 0
            for line in notifications(sock, WAIT_S + HEARTBEAT_MAX_AGE_S):
                if line == "WATCHDOG=1":
                    quiet_statuses = 0
                elif line.startswith("STATUS="):
                    quiet_statuses += 1
                if quiet_statuses == 10:
                    break
            assert quiet_statuses == 10, "WATCHDOG=1 went on while the reader hung"
            source.release.set()
            source.hang.clear()
            assert "WATCHDOG=1" in notifications(sock)  # turning again: pinged again
