"""The dashboard's JSON documents, from the viewer's state. Pure.

``/api/latest``: the latest values, each with its age on the dashboard's clock
and whether it is stale::

    {"machine_id", "prefix", "legs": [...], "pressure_limit_Pa", "warning_margin_m",
     "waiting_for": "<prefix>/status" | "<prefix>/ground" | null,
     "waiting": "waiting for <prefix>/status[: no Zenoh link ...]" | null,
     "zenoh_linked": true | false | null (the dashboard's session has a link: not known),
     "status": null | {"age_s", "stale", "bus": {"state", "interface", "channel",
                "reason", "reopens"}, "frames_per_s", "frames_received",
                "frames_bad", "dropped", "healthy", "problems", "uptime_s", "t"},
     "ground": null | {"age_s", "stale", "t", "total_force_N", "weight_N",
                "residual_N", "legs_in_contact", "complete",
                "stability": null | {"margin_m", "cop_m", "legs", "polygon_m", "feet_m"},
                "legs": {LEG: {"t", "force_N", "pressure_Pa", "contact", "valid",
                               "reasons"}}},
     "metrics": null | {"age_s", "t", "legs": {LEG: {"peak_pressure_Pa",
                "near_constant_pressure_Pa", "time_above_limit_s"}}},
     "viewer": {"dropped", "missed", "ignored"}}

``/api/history?since=T&generation=G``: the plot's points after ``T`` (all of
them, with ``"reset": true``, when ``G`` is not the history's generation)::

    {"generation", "reset", "window_s", "t": [...],
     "pressure_Pa": {LEG: [... | null]}}
"""

from dataclasses import asdict
from typing import Any

from daq.dashboard.history import PressureHistory
from daq.live.state import (
    GROUND,
    STATUS,
    GroundReading,
    LiveState,
    MetricsReading,
    Received,
    StatusReading,
)
from daq.live.viewer import ViewerConfig
from daq.payloads import JsonObject


def latest_document(
    viewer: ViewerConfig, state: LiveState, now_s: float, *, dropped: int = 0, missed: int = 0
) -> JsonObject:
    status = state.status
    ground = state.ground
    metrics = state.metrics
    waiting_for = waiting = None
    if status is None or ground is None:
        suffix = STATUS if status is None else GROUND
        waiting_for, waiting = viewer.key(suffix), state.waiting_for(suffix)
    return {
        "machine_id": viewer.machine_id,
        "prefix": viewer.prefix,
        "legs": list(viewer.legs),
        "pressure_limit_Pa": viewer.pressure_limit_Pa,
        "warning_margin_m": viewer.warning_margin_m,
        "waiting_for": waiting_for,
        "waiting": waiting,
        "zenoh_linked": state.linked,
        "status": None if status is None else _status(status, now_s, viewer.status_stale_s),
        "ground": None if ground is None else _ground(ground, now_s, viewer.ground_stale_s),
        "metrics": None if metrics is None else _metrics(metrics, now_s, viewer.status_stale_s),
        "viewer": {"dropped": dropped, "missed": missed, "ignored": state.ignored},
    }


def history_document(
    history: PressureHistory, since_s: float | None, generation: int | None
) -> JsonObject:
    reset = since_s is None or generation != history.generation
    points = history.since(None if reset else since_s)
    return {
        "generation": history.generation,
        "reset": reset,
        "window_s": history.window_s,
        "t": [t_s for t_s, _ in points],
        "pressure_Pa": {
            leg: [pressures[index] for _, pressures in points]
            for index, leg in enumerate(history.legs)
        },
    }


def _aged(received: Received[Any], now_s: float, stale_after_s: float) -> JsonObject:
    age_s = received.age_s(now_s)
    return {"age_s": age_s, "stale": age_s > stale_after_s}


def _status(received: Received[StatusReading], now_s: float, stale_after_s: float) -> JsonObject:
    status = received.value
    return _aged(received, now_s, stale_after_s) | {
        "t": status.t_s,
        "uptime_s": status.uptime_s,
        "bus": {
            "state": status.bus_state,
            "interface": status.bus_interface,
            "channel": status.bus_channel,
            "reason": status.bus_reason,
            "reopens": status.bus_reopens,
        },
        "frames_per_s": status.frames_per_s,
        "frames_received": status.frames_received,
        "frames_bad": status.frames_bad,
        "dropped": status.dropped,
        "healthy": status.healthy,
        "problems": list(status.problems),
    }


def _ground(received: Received[GroundReading], now_s: float, stale_after_s: float) -> JsonObject:
    ground = received.value
    return _aged(received, now_s, stale_after_s) | {
        "t": ground.t_s,
        "total_force_N": ground.total_force_N,
        "weight_N": ground.weight_N,
        "residual_N": ground.residual_N,
        "legs_in_contact": ground.legs_in_contact,
        "complete": ground.complete,
        "stability": None if ground.stability is None else asdict(ground.stability),
        "legs": {
            name: {
                "t": leg.t_s,
                "force_N": leg.force_N,
                "pressure_Pa": leg.pressure_Pa,
                "contact": leg.contact,
                "valid": leg.valid,
                "reasons": list(leg.reasons),
            }
            for name, leg in ground.legs.items()
        },
    }


def _metrics(received: Received[MetricsReading], now_s: float, stale_after_s: float) -> JsonObject:
    metrics = received.value
    return _aged(received, now_s, stale_after_s) | {
        "t": metrics.t_s,
        "legs": {name: asdict(leg) for name, leg in metrics.legs.items()},
    }
