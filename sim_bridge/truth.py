"""Ground truth of a bridge run: what the simulation says each foot carries, and when.

A :class:`TruthSample` is one row of the simulation result as the bus reached it, stamped
with the Unix time at which the frames of that simulation time were sent (the frame
time a receiver's estimates are matched against). Per leg: the true foot force, the two
chamber pressures the simulation produced (before any fault), and the true contact
pressure ``force_true_N / A_foot_m2``. Unknown values (e.g. an external input without a
force column) are NaN, written as an empty CSV cell and as JSON ``null``.

Writers (each a context manager; the stream or Zenoh session is opened by the caller and
passed in, ``close()`` is idempotent and finishes the format but leaves the stream open):

- :class:`CsvTruthWriter`: columns ``t_unix_s, t_cycle_s, cycle`` then per leg
  ``force_true_N_<LEG>, p_piston_Pa_<LEG>, p_rod_Pa_<LEG>, pressure_true_Pa_<LEG>``.
- :class:`McapTruthWriter`: topic ``/sim/truth``, JSON-schema channel, one JSON message per
  sample (log time = frame time), chunks compressed with zstd or lz4 when installed.
- :class:`ZenohTruthPublisher`: ``<prefix>/sim/truth`` (the whole sample) and
  ``<prefix>/sim/truth/<LEG>`` (one leg), JSON.
"""

import csv
import importlib.util
import json
import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import TracebackType
from typing import IO, Any, Protocol, Self

from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter

from sim_bridge.frames import Position
from sim_bridge.result import SimulationResult, leg_column

logger = logging.getLogger(__name__)

TOPIC = "/sim/truth"
LEG_FIELDS = ("force_true_N", "p_piston_Pa", "p_rod_Pa", "pressure_true_Pa")


@dataclass(frozen=True, slots=True)
class LegTruth:
    force_true_N: float
    p_piston_Pa: float
    p_rod_Pa: float
    #: force_true_N / A_foot_m2.
    pressure_true_Pa: float


@dataclass(frozen=True, slots=True)
class TruthSample:
    """The simulation's truth at one row, as sent."""

    #: Frame time: Unix time at which this simulation time went onto the bus.
    t_unix_s: float
    #: Time since the cycle started.
    t_cycle_s: float
    #: Completed cycles before this one (0 in the first).
    cycle: int
    legs: Mapping[str, LegTruth]

    def as_json(self) -> dict[str, Any]:
        """A JSON-ready dict; NaN becomes None (JSON null)."""
        return {
            "t_unix_s": self.t_unix_s,
            "t_cycle_s": self.t_cycle_s,
            "cycle": self.cycle,
            "legs": {leg: leg_json(truth) for leg, truth in self.legs.items()},
        }


def leg_json(truth: LegTruth) -> dict[str, float | None]:
    return {name: _finite_or_none(getattr(truth, name)) for name in LEG_FIELDS}


def _finite_or_none(value: float) -> float | None:
    return value if math.isfinite(value) else None


def truth_sample(
    result: SimulationResult,
    position: Position,
    t_unix_s: float,
    feet_m2: Mapping[str, float],
    columns: Mapping[str, int] | None = None,
) -> TruthSample:
    """The truth of ``result`` at ``position``; ``feet_m2`` is each leg's foot area, by
    config leg, ``columns`` each config leg's column in ``result`` (None: the legs are
    named like the simulation's; see :func:`~sim_bridge.result.leg_column`)."""
    row = position.row
    legs = {}
    for leg, foot_m2 in feet_m2.items():
        column = leg_column(leg, columns)
        force_N = float(result.force_true_N[row, column])
        legs[leg] = LegTruth(
            force_true_N=force_N,
            p_piston_Pa=float(result.p_piston_Pa[row, column]),
            p_rod_Pa=float(result.p_rod_Pa[row, column]),
            pressure_true_Pa=force_N / foot_m2,
        )
    return TruthSample(t_unix_s, float(result.t_s[row]), position.cycle, legs)


class TruthSink(Protocol):
    """Where truth samples go."""

    def write(self, sample: TruthSample) -> None: ...


class _Closing:
    """Context-manager plumbing: ``__exit__`` calls the idempotent ``close()``."""

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()

    def close(self) -> None:
        raise NotImplementedError


def csv_header(legs: Sequence[str]) -> list[str]:
    return ["t_unix_s", "t_cycle_s", "cycle"] + [
        f"{name}_{leg}" for leg in legs for name in LEG_FIELDS
    ]


class CsvTruthWriter(_Closing):
    """Writes samples as CSV rows to a text stream (open it with ``newline=""``)."""

    def __init__(self, stream: IO[str], legs: Sequence[str]) -> None:
        self._stream = stream
        self._legs = tuple(legs)
        self._writer = csv.writer(stream, lineterminator="\n")
        self._started = self._closed = False

    def write(self, sample: TruthSample) -> None:
        if not self._started:
            self._writer.writerow(csv_header(self._legs))
            self._started = True
        row: list[str] = [repr(sample.t_unix_s), repr(sample.t_cycle_s), str(sample.cycle)]
        for leg in self._legs:
            truth = sample.legs[leg]
            row += [_csv_number(getattr(truth, name)) for name in LEG_FIELDS]
        self._writer.writerow(row)

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        if not self._started:
            self._writer.writerow(csv_header(self._legs))
        self._stream.flush()


def _csv_number(value: float) -> str:
    return repr(value) if math.isfinite(value) else ""


def best_compression() -> CompressionType:
    """zstd when ``zstandard`` is installed, else lz4 when ``lz4`` is, else none."""
    if importlib.util.find_spec("zstandard") is not None:
        return CompressionType.ZSTD
    if importlib.util.find_spec("lz4") is not None:
        return CompressionType.LZ4
    return CompressionType.NONE


def truth_json_schema(legs: Sequence[str]) -> dict[str, Any]:
    number = {"type": ["number", "null"]}
    leg_schema = {
        "type": "object",
        "properties": {name: number for name in LEG_FIELDS},
        "required": list(LEG_FIELDS),
    }
    return {
        "title": "portal_daq.SimTruth",
        "description": "Ground truth of the portal-daq simulator bridge: one simulation sample",
        "type": "object",
        "properties": {
            "t_unix_s": {"type": "number", "description": "frame time, Unix seconds"},
            "t_cycle_s": {"type": "number", "description": "time since the cycle started, s"},
            "cycle": {"type": "integer", "description": "completed cycles"},
            "legs": {"type": "object", "properties": {leg: leg_schema for leg in legs}},
        },
        "required": ["t_unix_s", "t_cycle_s", "cycle", "legs"],
    }


class McapTruthWriter(_Closing):
    """Writes samples to an MCAP stream (binary, seekable not needed) on ``/sim/truth``.

    The MCAP header is written on ``__enter__`` (or the first sample), the summary and
    footer by ``close()``, so leaving the ``with`` block for any reason (SIGTERM included,
    when the caller turns it into a clean exit) leaves a valid file.
    """

    def __init__(
        self,
        stream: IO[bytes],
        legs: Sequence[str],
        compression: CompressionType | None = None,
    ) -> None:
        self._stream = stream
        self._legs = tuple(legs)
        self._compression = best_compression() if compression is None else compression
        self._writer: McapWriter | None = None
        self._channel_id = 0
        self._sequence = 0
        self._closed = False

    def __enter__(self) -> Self:
        self._start()
        return self

    def _start(self) -> McapWriter:
        if self._writer is None:
            if self._closed:
                raise ValueError("the MCAP truth writer is closed")
            writer = McapWriter(self._stream, compression=self._compression)
            writer.start(profile="", library="portal-daq sim_bridge")
            schema_id = writer.register_schema(
                name="portal_daq.SimTruth",
                encoding="jsonschema",
                data=json.dumps(truth_json_schema(self._legs)).encode(),
            )
            self._channel_id = writer.register_channel(
                topic=TOPIC, message_encoding="json", schema_id=schema_id
            )
            self._writer = writer
        return self._writer

    def write(self, sample: TruthSample) -> None:
        writer = self._start()
        t_ns = round(sample.t_unix_s * 1e9)
        writer.add_message(
            channel_id=self._channel_id,
            log_time=t_ns,
            publish_time=t_ns,
            sequence=self._sequence,
            data=json.dumps(sample.as_json()).encode(),
        )
        self._sequence += 1

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        if self._writer is not None:
            self._writer.finish()  # type: ignore[no-untyped-call]
        self._stream.flush()


class MatchingStatus(Protocol):
    @property
    def matching(self) -> bool: ...


class ZenohPublisher(Protocol):
    def put(self, payload: bytes) -> Any: ...

    def undeclare(self) -> Any: ...

    @property
    def matching_status(self) -> MatchingStatus: ...


class ZenohSession(Protocol):
    """The part of :class:`zenoh.Session` the truth publisher uses."""

    def declare_publisher(self, key_expr: str, *, encoding: str) -> ZenohPublisher: ...


class ZenohTruthPublisher(_Closing):
    """Puts each sample on ``<prefix>/sim/truth`` and each leg on ``.../sim/truth/<LEG>``.

    Publishers are declared on ``__enter__`` and undeclared by ``close()``; the session
    belongs to the caller. ``close()`` says when no subscriber matched any of the keys
    while it wrote (:attr:`matched`): the truth went nowhere.
    """

    def __init__(self, session: ZenohSession, prefix: str, legs: Sequence[str]) -> None:
        self._session = session
        self.key = f"{prefix.rstrip('/')}/sim/truth"
        self._legs = tuple(legs)
        self._all: ZenohPublisher | None = None
        self._per_leg: dict[str, ZenohPublisher] = {}
        self._closed = False
        #: Samples written, and whether a subscriber (the service's, a dashboard's) ever
        #: matched one of the keys while they were.
        self.written = 0
        self.matched = False

    def __enter__(self) -> Self:
        self._declare()
        return self

    def _declare(self) -> ZenohPublisher:
        if self._all is None:
            if self._closed:
                raise ValueError("the Zenoh truth publisher is closed")
            declare = self._session.declare_publisher
            self._all = declare(self.key, encoding="application/json")
            self._per_leg = {
                leg: declare(f"{self.key}/{leg}", encoding="application/json") for leg in self._legs
            }
        return self._all

    def write(self, sample: TruthSample) -> None:
        everything = self._declare()
        head = {"t_unix_s": sample.t_unix_s, "t_cycle_s": sample.t_cycle_s, "cycle": sample.cycle}
        for leg, publisher in self._per_leg.items():
            publisher.put(json.dumps(head | {"leg": leg} | leg_json(sample.legs[leg])).encode())
        everything.put(json.dumps(sample.as_json()).encode())
        self.written += 1
        if not self.matched:
            publishers = (everything, *self._per_leg.values())
            self.matched = any(publisher.matching_status.matching for publisher in publishers)

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        if self.written and not self.matched:
            logger.warning(
                "nobody subscribed to %s while %d truth samples were put: they went nowhere "
                "(to record them, the service needs [recording] truth = true, the machine id "
                "in this key, and the bridge connected to it: --connect)",
                self.key,
                self.written,
            )
        for publisher in [*self._per_leg.values(), *([self._all] if self._all else [])]:
            try:
                publisher.undeclare()
            except Exception as exc:  # zenoh raises its own error types; closing goes on
                logger.warning("undeclaring a Zenoh truth publisher failed: %s", exc)
        self._per_leg, self._all = {}, None
