"""JSON payloads of the Zenoh keys and MCAP channels (one shape for both).

Pure functions from the pipeline's values to JSON-ready dicts, and
:func:`json_bytes`, which writes NaN and infinities as ``null`` (they are not
valid JSON). Field names carry their units; times are Unix seconds.
"""

import json
import math
from collections.abc import Mapping
from typing import Any

import orjson

from daq.frames import BusEvent
from dbc.decoding import DecodedFrame
from estimator.leg import LegEstimate
from estimator.machine import MachineSnapshot
from estimator.metrics import SoilMetrics
from estimator.stability import Stability

JsonObject = dict[str, Any]


#: The encoder of what orjson does not take: a Mapping that is not a dict, non-string
#: keys, integers beyond 64 bits.
_ENCODER = json.JSONEncoder(separators=(",", ":"), allow_nan=False)


def json_bytes(payload: Mapping[str, Any]) -> bytes:
    """Compact UTF-8 JSON; NaN and +-inf become ``null``. Keys are strings.

    Hot path (every message published and recorded): orjson, which writes NaN and
    infinities as ``null`` itself, and numpy scalars as numbers; only what it refuses
    is rebuilt with :func:`_finite` for the standard library's encoder.
    """
    try:
        # orjson (3.12 on) returns its bytes in the 4 KiB buffer it wrote them into,
        # never trimmed: a leg estimate's ~230 bytes held 4 KiB while it waited in the
        # publisher's queue, a batch or the recorder's backlog, and each new one
        # touched fresh pages (page faults: ~1.3 us per frame of the frames' thread as
        # fast as taken, bench/). The copy costs ~0.1 us.
        return b"".join((orjson.dumps(payload, option=orjson.OPT_SERIALIZE_NUMPY), b""))
    except orjson.JSONEncodeError:
        return _ENCODER.encode(_finite(payload)).encode()


def _finite(value: Any) -> Any:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, Mapping):
        return {str(key): _finite(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(item) for item in value]
    return value


#: Unix times outside this range (2000-01-01 .. 2100-01-01) are not plausible in a
#: payload from outside: e.g. milliseconds instead of seconds.
PLAUSIBLE_UNIX_S = (946_684_800.0, 4_102_444_800.0)


def finite_number(value: Any) -> float | None:
    """``value`` as a finite float, or None (not a number, a bool, NaN, inf, or too big).

    >>> finite_number(1), finite_number(True), finite_number(10**400), finite_number("1")
    (1.0, None, None, None)
    """
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    try:
        number = float(value)
    except OverflowError:  # an int beyond the float range, e.g. 400 digits
        return None
    return number if math.isfinite(number) else None


def unix_time_s(value: Any) -> float | None:
    """``value`` as Unix seconds within :data:`PLAUSIBLE_UNIX_S`, or None.

    >>> unix_time_s(1750000000.5), unix_time_s(1750000000500)
    (1750000000.5, None)
    """
    t_s = finite_number(value)
    low, high = PLAUSIBLE_UNIX_S
    return t_s if t_s is not None and low <= t_s <= high else None


def parse_json(payload: bytes) -> Any:
    """The JSON value of ``payload`` from outside, or None when it is not JSON
    (not UTF-8, malformed, nested too deep, a number too long to convert)."""
    try:
        return json.loads(payload)
    except (UnicodeDecodeError, ValueError, RecursionError):
        return None


def leg_ground(estimate: LegEstimate) -> JsonObject:
    """``<prefix>/leg/<LEG>/ground`` and the MCAP channel ``/leg/<LEG>/ground``."""
    return {
        "leg": estimate.leg,
        "t": estimate.t_s,
        "force_N": estimate.force_N,
        "force_raw_N": estimate.force_raw_N,
        "pressure_Pa": estimate.pressure_Pa,
        "p_piston_Pa": estimate.p_piston_Pa,
        "p_rod_Pa": estimate.p_rod_Pa,
        "contact": estimate.contact,
        "valid": estimate.valid,
        "reasons": list(estimate.reasons),
    }


def machine_ground(snapshot: MachineSnapshot) -> JsonObject:
    """``<prefix>/ground``: every leg judged at ``snapshot.t_s``, and the weight check."""
    weight = snapshot.weight
    return {
        "t": snapshot.t_s,
        "legs": {name: leg_ground(estimate) for name, estimate in snapshot.legs.items()},
        "total_force_N": weight.total_force_N,
        "weight_N": weight.weight_N,
        "residual_N": weight.residual_N,
        "legs_in_contact": weight.legs_in_contact,
        "complete": weight.complete,
        "stability": stability(snapshot.stability),
    }


def stability(margin: Stability | None) -> JsonObject | None:
    """The ``stability`` member of ``<prefix>/ground``: null when undefined."""
    if margin is None:
        return None
    return {
        "cop_m": list(margin.cop_m),
        "margin_m": margin.margin_m,
        "legs": list(margin.legs),
        "polygon_m": [list(corner) for corner in margin.polygon_m],
        "feet_m": {leg: list(xy) for leg, xy in margin.feet_m.items()},
    }


def soil_metrics(t_s: float, metrics: Mapping[str, SoilMetrics]) -> JsonObject:
    """``<prefix>/metrics``: each leg's soil metrics."""
    return {
        "t": t_s,
        "legs": {
            name: {
                "peak_pressure_Pa": m.peak_pressure_Pa,
                "peak_t": m.peak_t_s,
                "near_constant_pressure_Pa": m.near_constant_pressure_Pa,
                "near_constant_t": m.near_constant_t_s,
                "time_above_limit_s": m.time_above_limit_s,
                "samples": m.samples,
            }
            for name, m in metrics.items()
        },
    }


def signals(frame: DecodedFrame) -> JsonObject:
    """``<prefix>/signals/<MESSAGE>`` and ``/signals/<MESSAGE>``: one decoded frame.

    Pressure signals are in Pa; ``source_address`` only for J1939 messages.
    """
    payload: JsonObject = {
        "t": frame.t_s,
        "crc_ok": frame.crc_ok,
        "counter_ok": frame.counter_ok,
        "faults": list(frame.faults),
        "frames_lost": frame.frames_lost,
        "signals": dict(frame.signals),
    }
    if frame.source_address is not None:
        payload["source_address"] = frame.source_address
    return payload


def bus_event(event: BusEvent) -> JsonObject:
    """MCAP ``/daq/bus``: a change of the bus state, or frames lost."""
    return {
        "t": event.t_s,
        "state": event.state,
        "reason": event.reason,
        "reset_counters": event.reset_counters,
        "kernel_dropped": event.kernel_dropped,
        "rx_dropped": event.rx_dropped,
    }
