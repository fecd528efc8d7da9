"""One MCAP recording file: channels and JSON schemas of the service, written through mcap.

The stream is passed in (opened by :mod:`daq.recorder`, or a ``BytesIO`` in tests).
Topics, each with a JSON Schema (``jsonschema``) and JSON messages:

=======================  ===================================================
``/can/raw``             every frame, bad ones included (:data:`RAW_TOPIC`)
``/signals/<MESSAGE>``   the decoded signals of each good frame
``/leg/<LEG>/ground``    each leg estimate
``/ground``              all legs, weight check and stability margin, at the
                         publish rate (:data:`GROUND_TOPIC`)
``/daq/bus``             bus state changes (:data:`BUS_TOPIC`)
``/sim/truth``           simulation ground truth, when a simulator bridge
                         publishes it (:data:`TRUTH_TOPIC`)
``/daq/recording``       a gap in the recording: the first message of the file
                         that resumed it (:data:`RECORDING_TOPIC`)
=======================  ===================================================

The file also carries the configuration and the DBC as attachments, so that a
recording replays without the files it was made with, and a metadata record
:data:`RUN_METADATA` saying which run of the service it belongs to (see
:mod:`daq.recording_run`).
"""

import json
from collections.abc import Mapping
from dataclasses import dataclass
from typing import IO, Any, cast

from cantools.database.can import Database
from mcap.writer import CompressionType, Writer

from daq import payloads, schemas
from daq.frames import BusEvent
from daq.pipeline import FrameResult
from estimator.machine import MachineSnapshot

RAW_TOPIC = "/can/raw"
BUS_TOPIC = "/daq/bus"
SIGNALS_TOPIC = "/signals/{message}"
LEG_TOPIC = "/leg/{leg}/ground"
TRUTH_TOPIC = "/sim/truth"
RECORDING_TOPIC = "/daq/recording"
GROUND_TOPIC = "/ground"
#: MCAP profile: none of the standard ones (ros1, ros2) fits JSON messages.
PROFILE = ""
#: Metadata record naming the run a file belongs to: keys ``machine_id``, ``run_id``,
#: ``file_index`` (decimal).
RUN_METADATA = "portal-daq.run"
#: Attachment names of the configuration and the DBC.
CONFIG_ATTACHMENT = "portal-daq.toml"
DBC_ATTACHMENT = "portal_sensors.dbc"
COMPRESSION = {
    "zstd": CompressionType.ZSTD,
    "lz4": CompressionType.LZ4,
    "none": CompressionType.NONE,
}


@dataclass(frozen=True, slots=True)
class RecordingGap:
    """Recording stopped (a write error) at ``stopped_t_s`` and resumed at ``resumed_t_s``."""

    #: Wall-clock times, Unix seconds.
    stopped_t_s: float
    resumed_t_s: float
    #: Items (frames with their results, bus events, truth samples) dropped meanwhile.
    dropped: int

    @property
    def lost_s(self) -> float:
        return self.resumed_t_s - self.stopped_t_s


class CountingFile:
    """Writes straight to a raw (unbuffered) file and counts the bytes.

    No user-space buffer: every chunk the MCAP writer finishes is in the kernel
    at once and survives a crash of the process. (Not an ``io.RawIOBase``: mcap
    would wrap that in a ``BufferedWriter``.)
    """

    def __init__(self, raw: IO[bytes]) -> None:
        self._raw = raw
        #: Bytes written so far, i.e. the file's size.
        self.count = 0

    def write(self, data: bytes) -> int:
        view = memoryview(data).cast("B")
        while view:
            written = self._raw.write(view) or 0
            view = view[written:]
            self.count += written
        return len(data)

    def tell(self) -> int:
        return self.count

    def flush(self) -> None:
        self._raw.flush()

    def close(self) -> None:
        self._raw.close()


def _ns(t_s: float) -> int:
    return max(0, round(t_s * 1e9))


class McapFile:
    """The service's channels in one MCAP file; schemas and channels registered on use.

    ``close()`` writes the summary (``Writer.finish``); it is idempotent and does
    not close ``stream``.
    """

    def __init__(
        self,
        stream: "IO[bytes] | CountingFile",
        database: Database,
        *,
        compression: str = "zstd",
        chunk_size: int = 1024 * 1024,
    ) -> None:
        self._stream = stream
        self._writer = Writer(
            cast(IO[Any], stream),
            chunk_size=chunk_size,
            compression=COMPRESSION[compression],
        )
        self._messages = {message.name: message for message in database.messages}
        self._channels: dict[str, int] = {}
        self._schemas: dict[str, int] = {}
        self._started = False
        self._closed = False
        #: Messages written.
        self.message_count = 0
        #: Frame time (ns) of the first message, for rotation by duration.
        self.first_log_time_ns: int | None = None

    def __enter__(self) -> "McapFile":
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def start(
        self,
        attachments: Mapping[str, bytes] = {},
        t_s: float = 0.0,
        run: Mapping[str, str] | None = None,
    ) -> None:
        """Write the header, the attachments (e.g. config and DBC) and the ``run``
        metadata (:data:`RUN_METADATA`), if given."""
        self._writer.start(profile=PROFILE, library="portal-daq")
        for name, data in attachments.items():
            self._writer.add_attachment(
                create_time=_ns(t_s),
                log_time=_ns(t_s),
                name=name,
                media_type="text/plain",
                data=data,
            )
        if run is not None:
            self._writer.add_metadata(RUN_METADATA, dict(run))
        self._started = True

    def write_result(self, result: FrameResult) -> None:
        """The raw frame, its signals and its leg estimates."""
        t_ns = _ns(result.frame.t_s)
        self._write(
            RAW_TOPIC, "portal.RawFrame", schemas.RAW_FRAME, t_ns, payloads.raw_frame(result)
        )
        if result.decoded is not None:
            name = result.decoded.message
            self._write(
                SIGNALS_TOPIC.format(message=name),
                f"portal.signals.{name}",
                None,
                t_ns,
                payloads.signals(result.decoded),
            )
        for estimate in result.estimates:
            self._write(
                LEG_TOPIC.format(leg=estimate.leg),
                "portal.LegGround",
                schemas.LEG_GROUND,
                t_ns,
                payloads.leg_ground(estimate),
            )

    def write_event(self, event: BusEvent) -> None:
        self._write(
            BUS_TOPIC,
            "portal.BusEvent",
            schemas.BUS_EVENT,
            _ns(event.t_s),
            payloads.bus_event(event),
        )

    def write_gap(self, gap: RecordingGap) -> None:
        """The gap before this file, logged at the time recording resumed."""
        payload = {
            "t": gap.resumed_t_s,
            "stopped_t": gap.stopped_t_s,
            "lost_s": gap.lost_s,
            "dropped": gap.dropped,
        }
        self._write(
            RECORDING_TOPIC,
            "portal.RecordingGap",
            schemas.RECORDING_GAP,
            _ns(gap.resumed_t_s),
            payload,
        )

    def write_ground(self, snapshot: MachineSnapshot) -> None:
        """The ``/ground`` aggregate (with the stability margin), logged at its moment."""
        self._write(
            GROUND_TOPIC,
            "portal.Ground",
            schemas.GROUND,
            _ns(snapshot.t_s),
            payloads.machine_ground(snapshot),
        )

    def write_truth(self, sample: payloads.JsonObject) -> None:
        """A simulation truth sample (see :func:`daq.sim_truth.truth_payload`), logged at
        its frame time ``t_unix_s``."""
        self._write(
            TRUTH_TOPIC, "portal_daq.SimTruth", schemas.SIM_TRUTH, _ns(sample["t_unix_s"]), sample
        )

    def _write(
        self,
        topic: str,
        schema_name: str,
        schema: schemas.Schema | None,
        t_ns: int,
        payload: payloads.JsonObject,
    ) -> None:
        channel = self._channels.get(topic)
        if channel is None:
            channel = self._channels[topic] = self._register(topic, schema_name, schema)
        self._writer.add_message(
            channel_id=channel, log_time=t_ns, publish_time=t_ns, data=payloads.json_bytes(payload)
        )
        self.message_count += 1
        if self.first_log_time_ns is None:
            self.first_log_time_ns = t_ns

    def _register(self, topic: str, schema_name: str, schema: schemas.Schema | None) -> int:
        schema_id = self._schemas.get(schema_name)
        if schema_id is None:
            if schema is None:  # a signals channel: the schema comes from the DBC
                message = self._messages[schema_name.removeprefix("portal.signals.")]
                schema = schemas.signals_schema(message)
            schema_id = self._writer.register_schema(
                name=schema_name, encoding="jsonschema", data=json.dumps(schema).encode()
            )
            self._schemas[schema_name] = schema_id
        return self._writer.register_channel(
            topic=topic, message_encoding="json", schema_id=schema_id
        )

    def flush(self) -> None:
        """Write out the chunk being built, so that a crash cannot lose it."""
        if self._started and not self._closed:
            self._writer.flush()  # type: ignore[no-untyped-call]

    def close(self) -> None:
        """Finish the file: last chunk, indexes and summary. Idempotent."""
        if self._closed:
            return
        self._closed = True
        if self._started:
            self._writer.finish()  # type: ignore[no-untyped-call]
            self._stream.flush()
