"""One MCAP recording file: channels and schemas of the service, written through mcap.

The stream is passed in (opened by :mod:`daq.recorder`, or a ``BytesIO`` in tests).
What is written comes in :class:`RecordBatch` es (one per batch of frames the
consumer processed), or as the :class:`EncodedBatch` they become (frames in their
``/can/raw`` bytes: what crosses to the recorder's process). Topics: ``/can/raw`` in
the binary layout of :mod:`daq.can_batch` (its schema in the file), the others with a
JSON Schema (``jsonschema``) and JSON messages:

=======================  ===================================================
``/can/raw``             every frame, bad ones included, a batch per message
                         (:data:`RAW_TOPIC`)
``/signals/<MESSAGE>``   the decoded signals of each good frame, only with
                         ``[recording] signals = true`` (replay and report
                         derive them from ``/can/raw`` otherwise)
``/leg/<LEG>/ground``    the leg's estimates of one batch: ``{"leg": LEG,
                         "estimates": [...]}``, the objects published on
                         Zenoh (files before batches:
                         one object per message; :func:`daq.mcap_reading.json_items`
                         reads both)
``/ground``              all legs, weight check and stability margin, at the
                         publish rate (:data:`GROUND_TOPIC`)
``/daq/bus``             bus state changes (:data:`BUS_TOPIC`)
``/sim/truth``           simulation ground truth, when a simulator bridge
                         publishes it (:data:`TRUTH_TOPIC`)
``/daq/recording``       a gap in the recording: after a write error, the first
                         message of the file that resumed it; after the
                         recorder's queue was full, just before the first item
                         written again (:data:`RECORDING_TOPIC`)
=======================  ===================================================

The file also carries the configuration and the DBC as attachments, so that a
recording replays without the files it was made with, and a metadata record
:data:`RUN_METADATA` saying which run of the service it belongs to (see
:mod:`daq.recording_run`).
"""

import json
import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import IO, Any, cast

import orjson
from cantools.database.can import Database
from mcap.writer import CompressionType, Writer

from daq import can_batch, payloads, schemas
from daq.frames import BusEvent, RawFrame
from daq.pipeline import FrameResult
from dbc.decoding import DecodedFrame
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


#: Why a :class:`RecordingGap` is: the file could not be written, or the recorder's queue
#: was full (the recorder fell behind: a slow disk, a CPU busy with other work).
WRITE_ERROR = "write error"
QUEUE_FULL = "recorder's queue full"


@dataclass(frozen=True, slots=True)
class RecordingGap:
    """Recording stopped at ``stopped_t_s`` and resumed at ``resumed_t_s``, for ``reason``."""

    #: Wall-clock times, Unix seconds.
    stopped_t_s: float
    resumed_t_s: float
    #: Items (frames with their results, bus events, truth samples) dropped meanwhile.
    dropped: int
    #: :data:`WRITE_ERROR` or :data:`QUEUE_FULL`.
    reason: str = WRITE_ERROR

    @property
    def lost_s(self) -> float:
        return self.resumed_t_s - self.stopped_t_s


@dataclass(frozen=True, slots=True)
class RecordBatch:
    """What one batch of frames gave, as the recorder writes it."""

    #: Every frame, bad ones included, in the order processed.
    frames: Sequence[RawFrame]
    #: (leg, frame time in Unix seconds, JSON of :func:`daq.payloads.leg_ground`): the
    #: bytes published on Zenoh, encoded once.
    estimates: Sequence[tuple[str, float, bytes]]
    #: The decoded frames, when signals are recorded (``[recording] signals``).
    decoded: Sequence[DecodedFrame] = ()

    @classmethod
    def of(cls, results: Iterable[FrameResult], *, signals: bool) -> "RecordBatch":
        """The batch of ``results`` (estimates encoded here; signals kept if ``signals``)."""
        results = list(results)
        return cls(
            [result.frame for result in results],
            [estimate for result in results for estimate in encoded_estimates(result)],
            decoded_frames(results) if signals else (),
        )


@dataclass(frozen=True, slots=True)
class EncodedBatch:
    """A :class:`RecordBatch` with its frames in the ``/can/raw`` layout and its signals
    as JSON: what the recorder writes, and what crosses to the recorder's process
    (:mod:`daq.recorder_process`): a few byte strings and tuples instead of an object per
    frame pickle ~20x faster."""

    #: The frames, :func:`daq.can_batch.encode` d (empty without frames).
    raw: bytes
    #: Frames in ``raw`` (a dropped batch counts as its frames).
    frame_count: int
    #: Frame time of the first frame (the ``/can/raw`` message's log time); 0 without.
    first_t_s: float
    #: (leg, frame time, JSON), as in :attr:`RecordBatch.estimates`.
    estimates: Sequence[tuple[str, float, bytes]]
    #: (message name, frame time, JSON of its signals), with ``[recording] signals``.
    signals: Sequence[tuple[str, float, bytes]] = ()

    @classmethod
    def of(cls, batch: RecordBatch) -> "EncodedBatch":
        frames = batch.frames
        signals = [
            (decoded.message, decoded.t_s, payloads.json_bytes(payloads.signals(decoded)))
            for decoded in batch.decoded
        ]
        return cls._of_frames(frames, batch.estimates, signals)

    @classmethod
    def _of_frames(
        cls,
        frames: Sequence[RawFrame],
        estimates: Sequence[tuple[str, float, bytes]],
        signals: Sequence[tuple[str, float, bytes]],
    ) -> "EncodedBatch":
        raw = can_batch.encode(frames) if frames else b""
        return cls(raw, len(frames), frames[0].t_s if frames else 0.0, estimates, signals)

    def split(self, t_s: float) -> tuple["EncodedBatch", "EncodedBatch"]:
        """What came before the first frame at or after frame time ``t_s``, and the rest,
        cut there and never sorted: after a clock stepped back within the batch, the
        frames after the step (earlier by their time) stay behind the frame they followed
        (sorted by time, they went into the file before it, and replay read them out of
        order). Estimates and signals are cut at their first at or after ``t_s``.

        >>> frames = [RawFrame(t, 0x100, False, b"") for t in (9.0, 10.0, 3.0)]
        >>> head, tail = EncodedBatch._of_frames(frames, [], []).split(10.0)
        >>> [f.t_s for f in can_batch.decode(head.raw)], [f.t_s for f in can_batch.decode(tail.raw)]
        ([9.0], [10.0, 3.0])
        """
        frames = list(can_batch.decode(self.raw)) if self.raw else []
        cut = _first_at([frame.t_s for frame in frames], t_s)
        cut_estimates = _first_at([estimate[1] for estimate in self.estimates], t_s)
        cut_signals = _first_at([signal[1] for signal in self.signals], t_s)
        return (
            self._of_frames(
                frames[:cut], self.estimates[:cut_estimates], self.signals[:cut_signals]
            ),
            self._of_frames(
                frames[cut:], self.estimates[cut_estimates:], self.signals[cut_signals:]
            ),
        )


def _first_at(times: Sequence[float], t_s: float) -> int:
    """Index of the first of ``times`` at or after ``t_s``; their number if none is."""
    return next((i for i, t in enumerate(times) if t >= t_s), len(times))


def encoded_estimates(result: FrameResult) -> list[tuple[str, float, bytes]]:
    """(leg, frame time, JSON) of each estimate of ``result``, as published and recorded."""
    return [
        (estimate.leg, estimate.t_s, payloads.json_bytes(payloads.leg_ground(estimate)))
        for estimate in result.estimates
    ]


def decoded_frames(results: Iterable[FrameResult]) -> list[DecodedFrame]:
    """The decoded frames of ``results`` (those that decoded)."""
    return [result.decoded for result in results if result.decoded is not None]


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

    @property
    def deleted(self) -> bool:
        """The file has no name left (deleted while written: what goes in is lost)."""
        return os.fstat(self._raw.fileno()).st_nlink == 0

    def flush(self) -> None:
        self._raw.flush()

    def close(self) -> None:
        self._raw.close()


def _ns(t_s: float) -> int:
    return max(0, round(t_s * 1e9))


class McapFile:
    """The service's channels in one MCAP file; schemas and channels registered on use.

    ``close()`` writes the summary (``Writer.finish``); it is idempotent and does
    not close ``stream``. ``pause`` is called after each message written: the
    recorder's thread lets the GIL go there now and then (:class:`daq.recorder.GilYield`),
    so that writing a batch holds up the thread that processes frames for a fraction of
    a millisecond, not for the interpreter's switch interval (measured: the paced p99).
    ``decoded_units``: the machine config's :attr:`~dbc.machine.MachineConfig.decoded_units`,
    the units the ``/signals`` schemas name where the decoder converted a signal
    (a pressure to Pa); without them, each signal is described by its DBC unit.
    """

    def __init__(
        self,
        stream: "IO[bytes] | CountingFile",
        database: Database,
        *,
        decoded_units: Mapping[str, Mapping[str, str]] = {},
        compression: str = "zstd",
        chunk_size: int = 1024 * 1024,
        pause: Callable[[], object] = lambda: None,
    ) -> None:
        self._stream = stream
        self._pause = pause
        self._writer = Writer(
            cast(IO[Any], stream),
            chunk_size=chunk_size,
            compression=COMPRESSION[compression],
        )
        self._messages = {message.name: message for message in database.messages}
        self._decoded_units = decoded_units
        self._channels: dict[str, int] = {}
        self._schemas: dict[str, int] = {}
        self._started = False
        self._closed = False
        #: Messages written.
        self.message_count = 0
        #: Frame time (ns) of the first message, for rotation by duration.
        self.first_log_time_ns: int | None = None
        #: What the messages not yet in a chunk on the stream hold (frames of a batch, 1
        #: for any other item): lost with the chunk if writing it fails (a full disk).
        self.unwritten = 0
        #: What every message added holds, counted as :attr:`unwritten` is.
        self.items = 0

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

    def write_batch(self, batch: "RecordBatch | EncodedBatch") -> None:
        """The batch's raw frames (one message), its estimates and signals (one each)."""
        encoded = batch if isinstance(batch, EncodedBatch) else EncodedBatch.of(batch)
        if encoded.frame_count:
            channel = self._channels.get(RAW_TOPIC) or self._raw_channel()
            self._add(channel, _ns(encoded.first_t_s), encoded.raw, encoded.frame_count)
        # One message per leg and batch: mcap's add_message costs more than encoding an
        # estimate, and the batch is only the published bytes joined.
        by_leg: dict[str, list[tuple[float, bytes]]] = {}
        for leg, t_s, data in encoded.estimates:
            by_leg.setdefault(leg, []).append((t_s, data))
        for leg, estimates in by_leg.items():
            topic = LEG_TOPIC.format(leg=leg)
            channel = self._channels.get(topic) or self._json_channel(
                topic, "portal.LegGroundBatch", schemas.LEG_GROUND_BATCH
            )
            joined = b",".join(data for _, data in estimates)
            payload = b'{"leg":' + orjson.dumps(leg) + b',"estimates":[' + joined + b"]}"
            self._add(channel, _ns(estimates[0][0]), payload, 0)  # counted with the frames
        for message, t_s, data in encoded.signals:
            topic = SIGNALS_TOPIC.format(message=message)
            channel = self._channels.get(topic) or self._json_channel(
                topic, f"portal.signals.{message}", None
            )
            self._add(channel, _ns(t_s), data, 0)

    def write_result(self, result: FrameResult, *, signals: bool = True) -> None:
        """One processed frame as a batch of its own (offline writers and tests; the
        service writes the consumer's batches)."""
        self.write_batch(RecordBatch.of([result], signals=signals))

    def write_event(self, event: BusEvent) -> None:
        self._write_json(
            BUS_TOPIC,
            "portal.BusEvent",
            schemas.BUS_EVENT,
            _ns(event.t_s),
            payloads.bus_event(event),
        )

    def write_gap(self, gap: RecordingGap) -> None:
        """A gap in the recording, logged at the time recording resumed."""
        payload = {
            "t": gap.resumed_t_s,
            "stopped_t": gap.stopped_t_s,
            "lost_s": gap.lost_s,
            "dropped": gap.dropped,
            "reason": gap.reason,
        }
        self._write_json(
            RECORDING_TOPIC,
            "portal.RecordingGap",
            schemas.RECORDING_GAP,
            _ns(gap.resumed_t_s),
            payload,
        )

    def write_ground(self, snapshot: MachineSnapshot) -> None:
        """The ``/ground`` aggregate (with the stability margin), logged at its moment."""
        self._write_json(
            GROUND_TOPIC,
            "portal.Ground",
            schemas.GROUND,
            _ns(snapshot.t_s),
            payloads.machine_ground(snapshot),
        )

    def write_truth(self, sample: payloads.JsonObject) -> None:
        """A simulation truth sample (see :func:`daq.sim_truth.truth_payload`), logged at
        its frame time ``t_unix_s``."""
        self._write_json(
            TRUTH_TOPIC, "portal_daq.SimTruth", schemas.SIM_TRUTH, _ns(sample["t_unix_s"]), sample
        )

    def _write_json(
        self,
        topic: str,
        schema_name: str,
        schema: schemas.Schema | None,
        t_ns: int,
        payload: payloads.JsonObject,
    ) -> None:
        channel = self._channels.get(topic) or self._json_channel(topic, schema_name, schema)
        self._add(channel, t_ns, payloads.json_bytes(payload), 1)

    def _add(self, channel: int, t_ns: int, data: bytes, items: int) -> None:
        """Add a message holding ``items`` (see :attr:`unwritten`)."""
        self.unwritten += items
        self.items += items
        at = self._stream.tell()
        self._writer.add_message(channel_id=channel, log_time=t_ns, publish_time=t_ns, data=data)
        if self._stream.tell() != at:  # it filled the chunk, which went out with it
            self.unwritten = 0
        self.message_count += 1
        if self.first_log_time_ns is None:
            self.first_log_time_ns = t_ns
        self._pause()

    def _json_channel(self, topic: str, schema_name: str, schema: schemas.Schema | None) -> int:
        if schema is None:  # a signals channel: the schema comes from the DBC
            message = self._messages[schema_name.removeprefix("portal.signals.")]
            schema = schemas.signals_schema(message, self._decoded_units.get(message.name, {}))
        return self._register(topic, schema_name, "jsonschema", json.dumps(schema).encode(), "json")

    def _raw_channel(self) -> int:
        return self._register(
            RAW_TOPIC,
            can_batch.SCHEMA_NAME,
            can_batch.ENCODING,
            can_batch.SCHEMA_TEXT.encode(),
            can_batch.ENCODING,
        )

    def _register(
        self,
        topic: str,
        schema_name: str,
        schema_encoding: str,
        schema_data: bytes,
        message_encoding: str,
    ) -> int:
        schema_id = self._schemas.get(schema_name)
        if schema_id is None:
            schema_id = self._writer.register_schema(
                name=schema_name, encoding=schema_encoding, data=schema_data
            )
            self._schemas[schema_name] = schema_id
        channel = self._writer.register_channel(
            topic=topic, message_encoding=message_encoding, schema_id=schema_id
        )
        self._channels[topic] = channel
        return channel

    def lost(self) -> None:
        """The file is gone (deleted while written): all it holds counts as unwritten."""
        self.unwritten = self.items

    def flush(self) -> None:
        """Write out the chunk being built, so that a crash cannot lose it."""
        if self._started and not self._closed:
            self._writer.flush()  # type: ignore[no-untyped-call]
            self.unwritten = 0

    def close(self) -> None:
        """Finish the file: last chunk, indexes and summary. Idempotent."""
        if self._closed:
            return
        self._closed = True
        if self._started:
            self._writer.finish()  # type: ignore[no-untyped-call]
            self._stream.flush()
            self.unwritten = 0
