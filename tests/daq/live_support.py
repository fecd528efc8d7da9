"""Helpers of the viewer tests (monitor, dashboard): a synthetic service on real Zenoh.

:class:`SyntheticService` publishes payloads shaped exactly like the service's
(:mod:`daq.payloads`, :meth:`daq.service.Service.status`) through the real
:class:`~daq.publisher.ZenohPublisher` (so late joiners get its cache too), on a
real Zenoh session listening on loopback: ``<prefix>/ground`` at 10 Hz,
``/status`` and ``/metrics`` at 2 Hz. The cycle (:func:`pressures_Pa`) is
deterministic: SB1_F1 ramps from 100 to 330 kPa over 60 s, crossing the 200 kPa
limit; the others wave gently; SB2_F3 is lifted (air) for 10 s of each minute.
"""

from __future__ import annotations

import functools
import math
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import zenoh

from daq import payloads
from daq.publisher import ZenohPublisher
from dbc.machine import load_machine_config
from estimator.leg import LegEstimate
from estimator.stability import stability
from tests.daq.service_support import peer_config
from tests.helpers import EXAMPLE_CONFIG, LEGS

A_FOOT_M2 = 0.33
WEIGHT_N = 18800.0 * 9.80665
LIMIT_PA = 200e3
PERIOD_S = 60.0


def pressures_Pa(phase_s: float) -> dict[str, float]:
    """Each leg's contact pressure ``phase_s`` seconds into the synthetic cycle."""
    s = phase_s % PERIOD_S
    return {
        "SB1_F1": 100e3 + 230e3 * s / PERIOD_S,
        "SB1_F2": 150e3 + 15e3 * math.sin(2 * math.pi * s / 20),
        "SB1_F3": 135e3 + 10e3 * math.sin(2 * math.pi * s / 15 + 1),
        "SB2_F1": 95e3 + 8e3 * math.sin(2 * math.pi * s / 30 + 2),
        "SB2_F2": 75e3 + 6e3 * math.sin(2 * math.pi * s / 12 + 3),
        "SB2_F3": 0.0 if 20.0 <= s < 30.0 else 55e3 + 5e3 * math.sin(2 * math.pi * s / 10),
    }


def leg_payload(leg: str, t_s: float, pressure_Pa: float | None, **extra: Any) -> dict[str, Any]:
    """A ``<prefix>/leg/<LEG>/ground`` payload (the service's fields, plausible values)."""
    force_N = None if pressure_Pa is None else pressure_Pa * A_FOOT_M2
    p_rod_Pa = 1.0e6
    p_piston_Pa = None if force_N is None else (force_N / 0.6705 + p_rod_Pa * 4.737e-3) / 7.854e-3
    payload = {
        "leg": leg,
        "t": t_s,
        "force_N": force_N,
        "force_raw_N": force_N,
        "pressure_Pa": pressure_Pa,
        "p_piston_Pa": p_piston_Pa,
        "p_rod_Pa": p_rod_Pa,
        "contact": force_N is not None and force_N >= 8000.0,
        "valid": pressure_Pa is not None,
        "reasons": [] if pressure_Pa is not None else ["stale"],
    }
    return payload | extra


@functools.cache
def _feet_m() -> dict[str, tuple[float, float]]:
    """The example machine's feet, bridge unfolded along SB1's x axis."""
    stability = load_machine_config(EXAMPLE_CONFIG)[0].stability
    assert stability is not None
    return stability.layout.feet_m(0.0, 0.0)


def _stability(legs: dict[str, dict[str, Any]]) -> dict[str, Any] | None:
    """The ``stability`` member the service computes from these leg payloads."""
    nan = float("nan")
    estimates = [
        LegEstimate(
            leg=name,
            t_s=leg["t"],
            force_N=nan if leg["force_N"] is None else leg["force_N"],
            force_raw_N=nan,
            pressure_Pa=nan,
            p_piston_Pa=nan,
            p_rod_Pa=nan,
            contact=leg["contact"],
            valid=leg["valid"],
            reasons=tuple(leg["reasons"]),
        )
        for name, leg in legs.items()
    ]
    return payloads.stability(stability(estimates, _feet_m()))


def ground_payload(t_s: float, legs: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """``<prefix>/ground`` over the given leg payloads, with the weight check and the
    stability margin."""
    down = [leg for leg in legs.values() if leg["valid"] and leg["contact"]]
    total_N = sum(leg["force_N"] for leg in down)
    return {
        "t": t_s,
        "legs": legs,
        "total_force_N": total_N,
        "weight_N": WEIGHT_N,
        "residual_N": total_N - WEIGHT_N,
        "legs_in_contact": len(down),
        "complete": all(leg["valid"] for leg in legs.values()),
        "stability": _stability(legs),
    }


def status_payload(t_s: float, **bus: Any) -> dict[str, Any]:
    """``<prefix>/status`` as :meth:`daq.service.Service.status` builds it."""
    return {
        "t": t_s,
        "uptime_s": 12.5,
        "bus": {"interface": "virtual", "channel": "synthetic", "state": "up", "reason": None}
        | {"reopens": 0}
        | bus,
        "frames_per_s": 600.0,
        "frames": {"received": 7500, "processed": 7500, "unknown": 0, "bad": 3, "dropped": 0},
        "bad": {"crc": 2, "counter": 1},
        "queues": {"rx": 0, "publish": 0, "record": 0},
        "dropped": {"rx": 0, "publish": 1, "record": 0},
        "recording": None,
        "healthy": True,
    }


class SyntheticService:
    """Publishes the synthetic cycle under ``prefix`` on ``session`` from a thread."""

    def __init__(self, session: zenoh.Session, prefix: str) -> None:
        self.publisher = ZenohPublisher(session, prefix)
        self.t0_s = time.time()
        self._peak_Pa = dict.fromkeys(LEGS, 0.0)
        self._above_s = dict.fromkeys(LEGS, 0.0)
        self._last_t_s: float | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="synthetic-service", daemon=True)
        #: Ground snapshots published so far.
        self.published = 0

    def start(self) -> None:
        """Publish live from now on (after an optional :meth:`backfill`)."""
        self.publisher.start()
        if not self._thread.is_alive():
            self._thread.start()

    def announce(self) -> None:
        """Publish one status (a viewer sees the service) without starting the cycle."""
        self.publisher.start()
        self.publisher.submit("status", status_payload(time.time()))

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join()
        self.publisher.close()

    def backfill(self, seconds: float) -> None:
        """Publish ``seconds`` of past snapshots at 10 Hz at once (a minute of history)."""
        self.publisher.start()
        now = time.time()
        self.t0_s = now - seconds
        for k in range(int(seconds * 10)):
            self._ground(self.t0_s + k * 0.1)

    def _ground(self, t_s: float) -> None:
        values = pressures_Pa(t_s - self.t0_s)
        dt_s = 0.0 if self._last_t_s is None else t_s - self._last_t_s
        self._last_t_s = t_s
        for leg, p in values.items():
            self._peak_Pa[leg] = max(self._peak_Pa[leg], p)
            self._above_s[leg] += dt_s if p > LIMIT_PA else 0.0
        legs = {leg: leg_payload(leg, t_s, p) for leg, p in values.items()}
        self.publisher.submit("ground", ground_payload(t_s, legs))
        self.published += 1

    def _run(self) -> None:
        tick = 0
        start = time.monotonic()
        while not self._stop.is_set():
            now = time.time()
            self._ground(now)
            if tick % 5 == 0:
                self.publisher.submit("status", status_payload(now))
                self.publisher.submit("metrics", self.metrics(now))
            tick += 1
            self._stop.wait(max(0.0, start + tick * 0.1 - time.monotonic()))

    def metrics(self, t_s: float) -> dict[str, Any]:
        return {
            "t": t_s,
            "legs": {
                leg: {
                    "peak_pressure_Pa": self._peak_Pa[leg],
                    "peak_t": t_s,
                    "near_constant_pressure_Pa": None,
                    "near_constant_t": None,
                    "time_above_limit_s": self._above_s[leg],
                    "samples": self.published,
                }
                for leg in LEGS
            },
        }


@contextmanager
def synthetic_service(port: int, prefix: str, *, start: bool = True) -> Iterator[SyntheticService]:
    """A synthetic service on a session listening on ``tcp/127.0.0.1:<port>``; not yet
    publishing with ``start=False`` (then :meth:`SyntheticService.announce`, ``backfill``,
    ``start``)."""
    with zenoh.open(peer_config(listen=f"tcp/127.0.0.1:{port}")) as session:
        service = SyntheticService(session, prefix)
        if start:
            service.start()
        try:
            yield service
        finally:
            service.close()
