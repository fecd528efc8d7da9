"""Reading the service's MCAP files back in file order, tolerating a cut-off end.

A file whose writer was killed has no summary and may end inside a chunk. The
mcap package's seeking reader needs the summary; this reads the records one by
one (mcap's ``StreamReader``, chunk CRCs checked) and stops quietly at the
first record that is incomplete, so everything up to the last complete chunk
comes back. File order is the order the recorder wrote, i.e. the order the
frames went through the pipeline (which replay relies on).
"""

import json
import logging
from collections.abc import Iterator
from dataclasses import dataclass
from typing import IO, Any

from mcap.exceptions import InvalidMagic
from mcap.records import Attachment, Channel, Footer, McapRecord, Message, Metadata
from mcap.stream_reader import StreamReader

from daq.errors import RecordingError

logger = logging.getLogger(__name__)


@dataclass(frozen=True, slots=True)
class RecordedMessage:
    topic: str
    log_time_ns: int
    data: bytes
    #: The channel's message encoding (``json``, or :data:`daq.can_batch.ENCODING`).
    encoding: str = "json"


@dataclass(frozen=True, slots=True)
class RecordedAttachment:
    name: str
    data: bytes


@dataclass(frozen=True, slots=True)
class RecordedMetadata:
    name: str
    metadata: dict[str, str]


def json_items(data: bytes) -> list[Any]:
    """The JSON payloads of one recorded message: each of a leg's batch of estimates
    (``{"leg": ..., "estimates": [...]}``), else the one value (every other topic, and
    leg estimates in files written before batches)."""
    value = json.loads(data)
    estimates = value.get("estimates") if isinstance(value, dict) else None
    return estimates if isinstance(estimates, list) else [value]


class RecordsToTheCut:
    """The raw mcap records of one stream in file order, up to the first incomplete one.

    After iteration, :attr:`stopped_by` says why reading stopped early (None when the
    stream ended normally); :mod:`daq.recover` rewrites what this yields.
    """

    def __init__(self, stream: IO[bytes], name: str = "recording") -> None:
        self._stream = stream
        self.name = name
        self.stopped_by: str | None = None

    def __iter__(self) -> Iterator[McapRecord]:
        records = StreamReader(self._stream, validate_crcs=True).records
        started = False
        while True:
            try:
                record = next(records)
            except StopIteration:
                return
            except InvalidMagic as exc:
                if not started:  # not an MCAP file at all (a CAN log, say): nothing to recover
                    raise RecordingError(
                        self.name, "not an MCAP file (a service recording is .mcap)"
                    ) from exc
                self.stopped_by = f"{type(exc).__name__}: {exc}"
                return
            # A cut-off file fails in many ways (EndOfFile, struct.error, a
            # decompression error, a CRC mismatch): each means "the end is missing".
            except Exception as exc:  # noqa: BLE001
                self.stopped_by = f"{type(exc).__name__}: {exc}".rstrip(": ")
                return
            started = True
            yield record


class RecordingStream:
    """Iterates over the messages, attachments and metadata of one MCAP stream, in file
    order.

    After iteration, :attr:`complete` tells whether the file ended properly
    (footer read) and :attr:`stopped_by` why reading stopped early, if it did.
    """

    def __init__(self, stream: IO[bytes], name: str = "recording") -> None:
        self._stream = stream
        self.name = name
        self.complete = False
        self.stopped_by: str | None = None

    def __iter__(self) -> Iterator[RecordedMessage | RecordedAttachment | RecordedMetadata]:
        channels: dict[int, Channel] = {}
        records = RecordsToTheCut(self._stream, self.name)
        for record in records:
            if isinstance(record, Channel):
                channels[record.id] = record
            elif isinstance(record, Message):
                channel = channels.get(record.channel_id)
                if channel is not None:
                    yield RecordedMessage(
                        channel.topic, record.log_time, record.data, channel.message_encoding
                    )
            elif isinstance(record, Attachment):
                yield RecordedAttachment(record.name, record.data)
            elif isinstance(record, Metadata):
                yield RecordedMetadata(record.name, dict(record.metadata))
            elif isinstance(record, Footer):
                self.complete = True
        self.stopped_by = records.stopped_by
        if self.stopped_by is not None:
            logger.warning(
                "%s ends without its summary (%s): read up to its last complete chunk",
                self.name,
                self.stopped_by,
            )
