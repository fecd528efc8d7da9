"""The service's latest values as a viewer received them: pure parsing, no I/O.

:class:`LiveState` takes raw Zenoh payloads (``<prefix>/ground``, ``/status``,
``/metrics``; JSON as :mod:`daq.payloads` writes it, NaN as ``null``) with the
viewer's monotonic receive time, and keeps the latest of each as typed,
frozen readings. A payload that is not a JSON object is counted in
:attr:`LiveState.ignored`; missing or ``null`` fields read as ``None`` (the
contract may grow; a viewer must not crash on an older or newer service).

Ages are judged on the viewer's own clock (time since received), never by
comparing the service's ``t`` with the viewer's wall clock, so a skewed clock
on either side cannot make data look fresh or stale.
"""

import logging
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

from daq.payloads import finite_number, parse_json

logger = logging.getLogger(__name__)

T = TypeVar("T")

#: The keys a viewer subscribes to, relative to the service's prefix.
GROUND, STATUS, METRICS = "ground", "status", "metrics"
SUFFIXES = (GROUND, STATUS, METRICS)
#: The service's liveliness token (no payload: it exists while the service runs).
ALIVE = "alive"
#: What a viewer without a Zenoh link says while it waits.
NO_LINK = "no Zenoh link to any peer or router yet (is the service running there? --connect?)"


@dataclass(frozen=True, slots=True)
class LegReading:
    """One leg's estimate, as judged in the service's ``<prefix>/ground`` snapshot."""

    leg: str
    #: Frame time of the leg's last estimate, Unix seconds (service clock).
    t_s: float | None
    #: Filtered vertical foot force (eq. 4 + running median).
    force_N: float | None
    #: Contact pressure (eq. 5) from the filtered force; 0 for a foot not in
    #: ``contact``, as the report draws it: the payload's eq. (5) of a lifted leg's
    #: cylinder force (the leg's own weight and inertia, -10 kPa say) is no soil
    #: pressure, and the monitor and dashboard showed it as one.
    pressure_Pa: float | None
    contact: bool
    valid: bool
    #: Why the estimate is invalid, e.g. ``("stale",)``; empty when valid.
    reasons: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class StabilityReading:
    """The ``stability`` member of ``<prefix>/ground`` (plan positions in metres)."""

    #: Signed distance of the centre of pressure to the nearest support edge; < 0 outside.
    margin_m: float
    #: Centre of pressure; None when not given.
    cop_m: tuple[float, float] | None
    #: The feet in contact that span the support polygon.
    legs: tuple[str, ...]
    polygon_m: tuple[tuple[float, float], ...]
    feet_m: Mapping[str, tuple[float, float]]


@dataclass(frozen=True, slots=True)
class GroundReading:
    """``<prefix>/ground``: every leg, the weight check and the stability margin."""

    #: Snapshot time, Unix seconds (service clock).
    t_s: float | None
    legs: Mapping[str, LegReading]
    total_force_N: float | None
    weight_N: float | None
    residual_N: float | None
    legs_in_contact: int | None
    complete: bool
    #: None when the service found it undefined (or is older than the margin).
    stability: StabilityReading | None = None

    @property
    def stability_margin_m(self) -> float | None:
        """``stability.margin_m`` when the service publishes it: signed distance (m) from
        the centre of pressure to the nearest support-polygon edge; None when absent or null."""
        return None if self.stability is None else self.stability.margin_m


@dataclass(frozen=True, slots=True)
class StatusReading:
    """``<prefix>/status``: the service's health, once a status period."""

    t_s: float | None
    uptime_s: float | None
    #: ``up``, ``down``, ``opening``, ``closed`` ... (the bus reader's state).
    bus_state: str
    bus_interface: str
    bus_channel: str
    bus_reason: str | None
    bus_reopens: int
    frames_per_s: float | None
    frames_received: int
    #: Frames with a fault (unknown ID, DLC, CRC, counter ...), all kinds.
    frames_bad: int
    #: Messages dropped anywhere (kernel, receive, publish and record queues).
    dropped: int
    healthy: bool | None
    #: Why it is not healthy, a few words each (``no frame for 2.0 s``); empty when healthy.
    problems: tuple[str, ...] = ()


@dataclass(frozen=True, slots=True)
class LegMetrics:
    """One leg's soil metrics from ``<prefix>/metrics``."""

    peak_pressure_Pa: float | None
    near_constant_pressure_Pa: float | None
    time_above_limit_s: float | None


@dataclass(frozen=True, slots=True)
class MetricsReading:
    t_s: float | None
    legs: Mapping[str, LegMetrics]


@dataclass(frozen=True, slots=True)
class Received(Generic[T]):
    """A reading and when the viewer received it (``time.monotonic()`` seconds)."""

    value: T
    received_s: float

    def age_s(self, now_s: float) -> float:
        return max(0.0, now_s - self.received_s)


class LiveState:
    """The latest ground, status and metrics under ``prefix``; one thread applies.

    >>> state = LiveState("portal/m")
    >>> state.apply("portal/m/status", b'{"bus": {"state": "up"}}', received_s=5.0)
    True
    >>> state.status.value.bus_state if state.status else None
    'up'
    """

    def __init__(self, prefix: str) -> None:
        self.prefix = prefix
        self.ground: Received[GroundReading] | None = None
        self.status: Received[StatusReading] | None = None
        self.metrics: Received[MetricsReading] | None = None
        #: Payloads that were not JSON objects, could not be read, or came on a key
        #: not viewed.
        self.ignored = 0
        #: Whether the viewer's session has a Zenoh link (:meth:`LiveFeed.linked
        #: <daq.live.feed.LiveFeed.linked>`); None: not known.
        self.linked: bool | None = None

    def key(self, suffix: str) -> str:
        return f"{self.prefix}/{suffix}"

    def waiting_for(self, suffix: str) -> str:
        """``waiting for <prefix>/<suffix>``, saying so when the viewer has no Zenoh link
        at all (the same line said nothing of it: a wrong ``--connect`` and a service
        that is down looked like a service about to talk)."""
        text = f"waiting for {self.key(suffix)}"
        if self.linked is False:
            text += f": {NO_LINK}"
        return text

    def apply(self, key: str, payload: bytes, received_s: float) -> bool:
        """Take one payload received on ``key``; False (and counted) when unusable.

        The payload comes from outside: it is checked field by field (types,
        finite numbers, plausible times), and anything else that goes wrong while
        reading it is counted in :attr:`ignored` too, never raised.
        """
        data = parse_json(payload)
        if not isinstance(data, dict):
            self.ignored += 1
            return False
        try:
            if key == self.key(GROUND):
                self.ground = Received(parse_ground(data), received_s)
            elif key == self.key(STATUS):
                self.status = Received(parse_status(data), received_s)
            elif key == self.key(METRICS):
                self.metrics = Received(parse_metrics(data), received_s)
            else:
                self.ignored += 1
                return False
        except Exception:  # noqa: BLE001 -- one odd payload must not stop a viewer
            self.ignored += 1
            logger.debug("unusable payload on %s", key, exc_info=True)
            return False
        return True


def parse_leg(name: str, data: Mapping[str, Any]) -> LegReading:
    reasons = data.get("reasons")
    pressure_Pa = _number(data, "pressure_Pa")
    lifted = data.get("contact") is False and pressure_Pa is not None
    return LegReading(
        leg=name,
        t_s=_number(data, "t"),
        force_N=_number(data, "force_N"),
        pressure_Pa=0.0 if lifted else pressure_Pa,
        contact=data.get("contact") is True,
        valid=data.get("valid") is True,
        reasons=tuple(str(r) for r in reasons) if isinstance(reasons, list) else (),
    )


def parse_ground(data: Mapping[str, Any]) -> GroundReading:
    legs = _table(data, "legs")
    count = _number(data, "legs_in_contact")
    return GroundReading(
        t_s=_number(data, "t"),
        legs={
            str(name): parse_leg(str(name), leg)
            for name, leg in legs.items()
            if isinstance(leg, dict)
        },
        total_force_N=_number(data, "total_force_N"),
        weight_N=_number(data, "weight_N"),
        residual_N=_number(data, "residual_N"),
        legs_in_contact=None if count is None else int(count),
        complete=data.get("complete") is True,
        stability=parse_stability(data.get("stability")),
    )


def parse_stability(data: Any) -> StabilityReading | None:
    """The ``stability`` member; None when null or without a margin."""
    if not isinstance(data, dict):
        return None
    margin_m = _number(data, "margin_m")
    cop = _point(data.get("cop_m"))
    if margin_m is None:
        return None
    polygon = data.get("polygon_m")
    corners = [_point(corner) for corner in polygon] if isinstance(polygon, list) else []
    legs = data.get("legs")
    feet = _table(data, "feet_m")
    return StabilityReading(
        margin_m=margin_m,
        cop_m=cop,
        legs=tuple(str(leg) for leg in legs) if isinstance(legs, list) else (),
        polygon_m=tuple(corner for corner in corners if corner is not None),
        feet_m={str(leg): xy for leg, xy in ((leg, _point(v)) for leg, v in feet.items()) if xy},
    )


def _point(value: Any) -> tuple[float, float] | None:
    if not isinstance(value, list) or len(value) != 2:
        return None
    x, y = finite_number(value[0]), finite_number(value[1])
    return None if x is None or y is None else (x, y)


def parse_status(data: Mapping[str, Any]) -> StatusReading:
    bus = _table(data, "bus")
    frames = _table(data, "frames")
    dropped = _table(data, "dropped")
    healthy = data.get("healthy")
    problems = data.get("problems")
    reason = bus.get("reason")
    return StatusReading(
        t_s=_number(data, "t"),
        uptime_s=_number(data, "uptime_s"),
        bus_state=str(bus.get("state") or "unknown"),
        bus_interface=str(bus.get("interface") or ""),
        bus_channel=str(bus.get("channel") or ""),
        bus_reason=str(reason) if reason else None,
        bus_reopens=_count(bus, "reopens"),
        frames_per_s=_number(data, "frames_per_s"),
        frames_received=_count(frames, "received"),
        frames_bad=_count(frames, "bad"),
        dropped=sum(_count(dropped, name) for name in dropped),
        healthy=healthy if isinstance(healthy, bool) else None,
        problems=tuple(str(p) for p in problems) if isinstance(problems, list) else (),
    )


def parse_metrics(data: Mapping[str, Any]) -> MetricsReading:
    legs = _table(data, "legs")
    return MetricsReading(
        t_s=_number(data, "t"),
        legs={
            str(name): LegMetrics(
                peak_pressure_Pa=_number(leg, "peak_pressure_Pa"),
                near_constant_pressure_Pa=_number(leg, "near_constant_pressure_Pa"),
                time_above_limit_s=_number(leg, "time_above_limit_s"),
            )
            for name, leg in legs.items()
            if isinstance(leg, dict)
        },
    )


def _number(data: Mapping[str, Any], name: str) -> float | None:
    return finite_number(data.get(name))


def _count(data: Mapping[str, Any], name: str) -> int:
    value = _number(data, name)
    return 0 if value is None else int(value)


def _table(data: Mapping[str, Any], name: str) -> Mapping[str, Any]:
    value = data.get(name)
    return value if isinstance(value, dict) else {}
