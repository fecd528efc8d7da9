"""sd_notify: datagrams on a real AF_UNIX socket, path and abstract addresses."""

import os
import socket
from pathlib import Path

import pytest

from daq.sd_notify import SdNotifier


def receive(sock: socket.socket) -> str:
    sock.settimeout(5)
    return sock.recv(4096).decode()


@pytest.mark.parametrize("abstract", [False, True])
def test_messages_arrive_in_order(tmp_path: Path, abstract: bool) -> None:
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as sock:
        if abstract:
            name = f"portal-daq-test-{os.getpid()}"
            sock.bind("\0" + name)
            address = "@" + name
        else:
            address = str(tmp_path / "notify")
            sock.bind(address)
        with SdNotifier.from_environment({"NOTIFY_SOCKET": address}) as notifier:
            assert notifier.ready() and notifier.status("bus up") and notifier.watchdog()
            assert notifier.stopping()
        assert [receive(sock) for _ in range(4)] == [
            "READY=1",
            "STATUS=bus up",
            "WATCHDOG=1",
            "STOPPING=1",
        ]


def test_without_notify_socket_nothing_is_sent() -> None:
    with SdNotifier.from_environment({}) as notifier:
        assert not notifier.enabled and notifier.ready() is False


def test_send_failure_is_not_fatal(tmp_path: Path) -> None:
    with SdNotifier(str(tmp_path / "nobody-listens")) as notifier:
        assert notifier.ready() is False
        assert notifier.ready() is False


def test_watchdog_interval_from_environment() -> None:
    env = {"NOTIFY_SOCKET": "/x", "WATCHDOG_USEC": "3000000", "WATCHDOG_PID": str(os.getpid())}
    assert SdNotifier.from_environment(env).watchdog_s == 3.0
    assert SdNotifier.from_environment(env | {"WATCHDOG_PID": "1"}).watchdog_s is None


def test_a_full_notify_socket_never_blocks_the_service(tmp_path: Path) -> None:
    """A reader that stopped reading (queue full) must not hang the main loop."""
    address = str(tmp_path / "full.sock")
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as receiver:
        receiver.bind(address)
        notifier = SdNotifier(address)
        notifier.open()
        try:
            results = [notifier.status(f"message {i}") for i in range(2000)]
        finally:
            notifier.close()
    assert results[0] is True
    assert results[-1] is False and notifier.dropped > 0
    assert results.count(True) + notifier.dropped == 2000
