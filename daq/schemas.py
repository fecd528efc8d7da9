"""JSON Schemas of the MCAP channels (encoding ``jsonschema``, messages ``json``).

Foxglove reads these to offer the fields for plotting. Numbers that may be NaN
are written as ``null`` (see :func:`daq.payloads.json_bytes`), hence the
``["number", "null"]`` types.
"""

from collections.abc import Mapping
from typing import Any

from cantools.database.can import Message

Schema = dict[str, Any]

_NUMBER = {"type": ["number", "null"]}
_TIME = {"type": "number", "description": "frame time (kernel time stamp), Unix seconds"}


def _object(title: str, properties: dict[str, Any], optional: tuple[str, ...] = ()) -> Schema:
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": title,
        "type": "object",
        "properties": properties,
        "required": [name for name in properties if name not in optional],
    }


LEG_GROUND = _object(
    "portal.LegGround",
    {
        "leg": {"type": "string"},
        "t": _TIME,
        "force_N": _NUMBER | {"description": "running median of the valid raw forces"},
        "force_raw_N": _NUMBER | {"description": "eq. (4) on this frame alone"},
        "pressure_Pa": _NUMBER | {"description": "eq. (5) on the filtered force"},
        "p_piston_Pa": _NUMBER,
        "p_rod_Pa": _NUMBER,
        "contact": {"type": "boolean"},
        "valid": {"type": "boolean"},
        "reasons": {"type": "array", "items": {"type": "string"}},
    },
)

LEG_GROUND_BATCH = _object(
    "portal.LegGroundBatch",
    {
        "leg": {"type": "string"},
        "estimates": {
            "type": "array",
            "items": LEG_GROUND,
            "description": "the leg's estimates of one batch of frames, in the order processed",
        },
    },
)

BUS_EVENT = _object(
    "portal.BusEvent",
    {
        "t": {"type": "number", "description": "wall-clock time, Unix seconds"},
        "state": {"type": "string", "description": "up, down or absent"},
        "reason": {"type": "string"},
        "reset_counters": {
            "type": "boolean",
            "description": "reception resumed after a gap: rolling counters were reset",
        },
        "kernel_dropped": {
            "type": "integer",
            "description": "frames the kernel dropped just before (receive buffer full)",
        },
        "rx_dropped": {
            "type": "integer",
            "description": "frames the service's reader dropped just before (queue full)",
        },
    },
)

RECORDING_GAP = _object(
    "portal.RecordingGap",
    {
        "t": {"type": "number", "description": "wall-clock time recording resumed, Unix seconds"},
        "stopped_t": {"type": "number", "description": "when it stopped"},
        "lost_s": {"type": "number", "description": "seconds not recorded"},
        "dropped": {"type": "integer", "description": "items dropped meanwhile"},
        "reason": {
            "type": "string",
            "description": 'why: "write error" or "recorder\'s queue full" (older files: '
            "none, a write error)",
        },
    },
    optional=("reason",),
)

_XY = {"type": "array", "items": {"type": "number"}, "minItems": 2, "maxItems": 2}

#: ``/ground``: the ``<prefix>/ground`` aggregate, at the publish rate.
GROUND = _object(
    "portal.Ground",
    {
        "t": {"type": "number", "description": "moment judged, frames' clock, Unix seconds"},
        "legs": {"type": "object", "additionalProperties": LEG_GROUND},
        "total_force_N": _NUMBER,
        "weight_N": _NUMBER,
        "residual_N": _NUMBER,
        "legs_in_contact": {"type": "integer"},
        "complete": {"type": "boolean"},
        "stability": {
            "type": ["object", "null"],
            "description": "null with fewer than three feet in contact, an invalid leg "
            "or an unknown bridge pose",
            "properties": {
                "cop_m": _XY | {"description": "centre of pressure, m"},
                "margin_m": {
                    "type": "number",
                    "description": "to the nearest support polygon edge, m; negative outside",
                },
                "legs": {"type": "array", "items": {"type": "string"}},
                "polygon_m": {"type": "array", "items": _XY},
                "feet_m": {"type": "object", "additionalProperties": _XY},
            },
        },
    },
)

_LEG_TRUTH = {
    "type": "object",
    "properties": {
        "force_true_N": _NUMBER | {"description": "true vertical foot force"},
        "p_piston_Pa": _NUMBER | {"description": "simulated piston chamber pressure"},
        "p_rod_Pa": _NUMBER | {"description": "simulated rod chamber pressure"},
        "pressure_true_Pa": _NUMBER | {"description": "force_true_N / A_foot_m2"},
    },
}

#: ``/sim/truth``: a simulator bridge sample as published on ``<prefix>/sim/truth``
#: (same name and fields as the bridge's own ``--truth-mcap`` channel).
SIM_TRUTH: Schema = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": "portal_daq.SimTruth",
    "type": "object",
    "properties": {
        "t_unix_s": {"type": "number", "description": "frame time of the sample, Unix seconds"},
        "t_cycle_s": {"type": "number", "description": "time since the cycle started, s"},
        "cycle": {"type": "integer", "description": "completed cycles"},
        "legs": {"type": "object", "additionalProperties": _LEG_TRUTH},
    },
    "required": ["t_unix_s", "legs"],
}


def signal_units(message: Message, units: Mapping[str, str] = {}) -> dict[str, str]:
    """The unit each decoded signal of ``message`` is in, by name: ``units``' (what the
    decoder converted it to, from :attr:`dbc.machine.MachineConfig.decoded_units`), else
    the DBC's; ``""`` for none. The schema's descriptions and ``<prefix>/units``."""
    return {signal.name: units.get(signal.name, signal.unit or "") for signal in message.signals}


def signals_schema(message: Message, units: Mapping[str, str] = {}) -> Schema:
    """Schema of ``/signals/<MESSAGE>``: the message's signals by name, each described
    by its unit: ``units``' (what the decoder converted it to, from
    :attr:`dbc.machine.MachineConfig.decoded_units`), else the DBC's."""
    signal_types: dict[str, Any] = {}
    described = signal_units(message, units)
    for signal in message.signals:
        types = ["number", "null"] + (["string"] if signal.choices else [])
        signal_types[signal.name] = {"type": types, "description": described[signal.name]}
    return _object(
        f"portal.signals.{message.name}",
        {
            "t": _TIME,
            "crc_ok": {"type": "boolean"},
            "counter_ok": {"type": "boolean"},
            "faults": {"type": "array", "items": {"type": "string"}},
            "frames_lost": {"type": "integer"},
            "source_address": {"type": "integer"},
            "signals": {"type": "object", "properties": signal_types},
        },
        optional=("source_address",),
    )
