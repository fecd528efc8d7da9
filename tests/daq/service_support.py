"""Helpers of the service tests (in-process and vcan): configs, Zenoh peers, frames, expectations.

Real things only: python-can buses, Zenoh sessions on loopback (peer mode,
multicast scouting off), MCAP files in a temporary directory.
"""

from __future__ import annotations

import json
import socket
import statistics
import threading
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import can
import zenoh
import zenoh.ext

from daq.live.feed import HISTORY, RECOVERY
from daq.service import Service
from dbc.encoding import FrameEncoder
from dbc.machine import MachineConfig
from estimator.equations import foot_force_N
from tests.helpers import EXAMPLE_CONFIG, LEGS

WAIT_S = 20.0  # generous: inside User-Mode Linux everything is slow


@contextmanager
def running(service: Service) -> Iterator[Service]:
    """``service`` run by :meth:`Service.run` in a thread, as in the main thread of the
    process, once its bus is open; stopped and joined at the end."""
    stop = threading.Event()
    runner = threading.Thread(target=service.run, args=(stop,))
    runner.start()
    try:
        assert service.reader.opened.wait(WAIT_S)
        yield service
    finally:
        stop.set()
        runner.join()


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def service_toml(
    *,
    interface: str = "virtual",
    channel: str = "test",
    port: int,
    recording: Path | None = None,
    status_period_s: float = 0.2,
    chunk_size: int = 1024 * 1024,
    max_duration_s: float = 3600.0,
    receive_buffer_bytes: int | None = None,
    truth: bool | None = None,
    extra: str = "",
) -> str:
    """A full service config: the example machine plus service tables for a test."""
    text = f"""
[bus]
interface = "{interface}"
channel = "{channel}"
"""
    if receive_buffer_bytes is not None:
        text += f"receive_buffer_bytes = {receive_buffer_bytes}\n"
    text += f"""
[zenoh]
mode = "peer"
listen = ["tcp/127.0.0.1:{port}"]
multicast_scouting = false

[publish]
ground_rate_hz = 10.0
status_period_s = {status_period_s}
"""
    if recording is not None:
        text += f"""
[recording]
directory = "{recording}"
chunk_size = {chunk_size}
max_bytes = {max(chunk_size, 1024 * 1024)}
max_duration_s = {max_duration_s}
flush_period_s = 0.2
"""
        if truth is not None:
            text += f"truth = {str(truth).lower()}\n"
    return text + extra + "\n" + EXAMPLE_CONFIG.read_text()


def write_service_config(tmp_path: Path, **kwargs: Any) -> Path:
    path = tmp_path / "portal-daq.toml"
    path.write_text(service_toml(**kwargs))
    return path


def peer_config(*, listen: str | None = None, connect: str | None = None) -> zenoh.Config:
    config = zenoh.Config()
    config.insert_json5("mode", '"peer"')
    config.insert_json5("scouting/multicast/enabled", "false")
    # Zenoh's default listener is tcp/[::]:0, which fails where there is no IPv6
    # (the User-Mode Linux guest): always listen on IPv4 loopback.
    config.insert_json5("listen/endpoints", json.dumps([listen or "tcp/127.0.0.1:0"]))
    if connect:
        config.insert_json5("connect/endpoints", json.dumps([connect]))
    return config


class Collector:
    """A subscriber on ``key`` that keeps every (key, JSON payload, encoding) it gets."""

    def __init__(self, session: zenoh.Session, key: str, *, advanced: bool = False) -> None:
        """``advanced``: a zenoh.ext advanced subscriber with history (the latest sample
        of each key when it joins) whose miss listener counts :attr:`missed`."""
        self.samples: list[tuple[str, Any, str]] = []
        self.missed = 0
        self._changed = threading.Condition()
        self._subscriber: Any
        if advanced:
            self._subscriber = zenoh.ext.declare_advanced_subscriber(
                session, key, self._on_sample, history=HISTORY, recovery=RECOVERY
            )
            self._listener = self._subscriber.sample_miss_listener(self._on_miss)
        else:
            self._subscriber = session.declare_subscriber(key, self._on_sample)

    def _on_miss(self, miss: zenoh.ext.Miss) -> None:
        with self._changed:
            self.missed += miss.nb
            self._changed.notify_all()

    def _on_sample(self, sample: zenoh.Sample) -> None:
        payload = json.loads(sample.payload.to_bytes())
        with self._changed:
            self.samples.append((str(sample.key_expr), payload, str(sample.encoding)))
            self._changed.notify_all()

    def of(self, key: str) -> list[Any]:
        """Payloads received on ``key``, in order."""
        with self._changed:
            return [payload for k, payload, _ in self.samples if k == key]

    def wait_until(self, condition: Callable[[], bool], timeout: float = WAIT_S) -> None:
        with self._changed:
            assert self._changed.wait_for(condition, timeout), "Zenoh samples missing"

    def wait_for(
        self, key: str, predicate: Callable[[Any], bool] = lambda _: True, timeout: float = WAIT_S
    ) -> Any:
        """The first payload on ``key`` (received from now on) satisfying ``predicate``."""
        with self._changed:
            start = len(self.samples)
        return self.first(key, predicate, timeout, start=start)

    def first(
        self,
        key: str,
        predicate: Callable[[Any], bool] = lambda _: True,
        timeout: float = WAIT_S,
        *,
        start: int = 0,
    ) -> Any:
        """The first payload on ``key`` satisfying ``predicate``, among those received
        since sample ``start`` (0: ever), waiting for one if there is none yet."""
        found: list[Any] = []

        def seen() -> bool:
            found[:] = [p for k, p, _ in self.samples[start:] if k == key and predicate(p)]
            return bool(found)

        self.wait_until(seen, timeout)
        return found[0]


class KeysSeen:
    """A subscriber on ``key`` that keeps the key of every sample it gets, whatever the
    payload: which puts got through (an access control's test)."""

    def __init__(self, session: zenoh.Session, key: str = "**") -> None:
        self._keys: list[str] = []
        self._arrived = threading.Condition()
        self._subscriber = session.declare_subscriber(key, self._on_sample)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        with self._arrived:
            self._keys.append(str(sample.key_expr))
            self._arrived.notify_all()

    def __contains__(self, key: str) -> bool:
        with self._arrived:
            return key in self._keys

    def routed(self, put: Callable[[], None], key: str) -> None:
        """``put`` again until a sample on ``key`` arrived: the routes are up."""
        with self._arrived:
            while key not in self._keys:
                put()
                self._arrived.wait(0.1)

    def wait_for(self, key: str) -> None:
        with self._arrived:
            assert self._arrived.wait_for(lambda: key in self._keys, WAIT_S), f"no {key}"

    def undeclare(self) -> None:
        self._subscriber.undeclare()


@contextmanager
def subscriber_session(port: int) -> Iterator[zenoh.Session]:
    session = zenoh.open(peer_config(connect=f"tcp/127.0.0.1:{port}"))
    try:
        yield session
    finally:
        session.close()


def leg_signals(leg: str, p_piston_Pa: float, p_rod_Pa: float) -> dict[str, Any]:
    return {f"{leg}_pPiston": p_piston_Pa, f"{leg}_pRod": p_rod_Pa, f"{leg}_Status": "ok"}


def pressure_series(count: int, seed: int = 0) -> list[tuple[float, float]]:
    """Chamber pressures with a step and impulsive spikes (what the median is for)."""
    series = []
    for i in range(count):
        p_piston = 9.0e6 + 2.0e4 * i + (4.0e6 if i % 7 == 3 else 0.0) + 1000.0 * seed
        p_rod = 1.0e6 + (5.0e5 if i > count // 2 else 0.0)
        series.append((p_piston, p_rod))
    return series


def can_message(frame: Any, t_s: float) -> can.Message:
    return can.Message(
        timestamp=t_s,
        arbitration_id=frame.arbitration_id,
        is_extended_id=frame.is_extended_id,
        data=frame.data,
    )


def leg_messages(
    encoder: FrameEncoder, count: int, t0_s: float, legs: Iterable[str] = LEGS
) -> list[can.Message]:
    """``count`` frames per leg, 10 ms apart, all legs interleaved."""
    series = {leg: pressure_series(count, seed) for seed, leg in enumerate(legs)}
    messages = []
    for i in range(count):
        for leg, values in series.items():
            frame = encoder.encode(f"LEG_{leg}", leg_signals(leg, *values[i]))
            messages.append(can_message(frame, t0_s + 0.01 * i))
    return messages


def expected_forces(
    machine: MachineConfig, leg: str, pressures: list[tuple[float, float]], t_s: list[float]
) -> list[tuple[float, float]]:
    """(raw, filtered) force per sample, computed independently: eq. (4) and a
    brute-force median over the last N raw forces (every sample valid), started afresh
    after a gap longer than the stale time (a stalled sender under load is an outage)."""
    geometry = machine.legs[leg].geometry
    window = machine.estimator.median_window
    stale_after_s = machine.estimator.stale_after_cycles * machine.legs[leg].cycle_time_s
    raw = [foot_force_N(p, r, geometry) for p, r in pressures]
    start = 0
    expected = []
    for i in range(len(raw)):
        if i and t_s[i] - t_s[i - 1] > stale_after_s:
            start = i
        expected.append((raw[i], statistics.median(raw[max(start, i + 1 - window) : i + 1])))
    return expected


def assert_estimates_match(
    machine: MachineConfig,
    leg: str,
    sent: list[tuple[float, float]],
    received: list[dict[str, Any]],
) -> None:
    """Published estimates of ``leg`` match eq. (4) + running median to 1 N."""
    assert len(received) == len(sent)
    decoded = [(m["p_piston_Pa"], m["p_rod_Pa"]) for m in received]
    for (p, r), (dp, dr) in zip(sent, decoded, strict=True):
        assert abs(p - dp) <= 500.0 and abs(r - dr) <= 500.0  # DBC resolution 1000 Pa
    for message, (raw_N, filtered_N) in zip(
        received, expected_forces(machine, leg, decoded, [m["t"] for m in received]), strict=True
    ):
        assert message["valid"] is True, message
        assert abs(message["force_raw_N"] - raw_N) <= 1.0
        assert abs(message["force_N"] - filtered_N) <= 1.0
        geometry = machine.legs[leg].geometry
        assert abs(message["pressure_Pa"] - filtered_N / geometry.A_foot_m2) <= 1.0 / 0.33
