"""Reading the service's MCAP files back in file order, tolerating a cut-off end.

A file whose writer was killed has no summary and may end inside a chunk. The
mcap package's seeking reader needs the summary; this reads the records one by
one (mcap's ``StreamReader``, chunk CRCs checked) and stops quietly at the
first record that is incomplete, so everything up to the last complete chunk
comes back. A chunk damaged in the middle of a file (its CRC or its compression
fails, a flipped bit on the storage) is skipped with a warning and reading goes on
with the next record: only that chunk's messages are lost (the channels, which the
recorder writes into the chunk of their first message, come from the file's summary
when it has one). File order is the order
the recorder wrote, i.e. the order the frames went through the pipeline (which replay
relies on).
"""

import json
import logging
from collections.abc import Iterator
from dataclasses import dataclass
from typing import IO, Any

from mcap.exceptions import InvalidMagic
from mcap.reader import SeekingReader
from mcap.records import (
    Attachment,
    Channel,
    Chunk,
    Footer,
    McapRecord,
    Message,
    Metadata,
    Schema,
)
from mcap.stream_reader import CRCValidationError, StreamReader
from zstandard import ZstdError

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


def summary_channels(stream: IO[bytes]) -> tuple[dict[int, Schema], dict[int, Channel]]:
    """The schemas and channels in the summary of a whole file (none of a cut one, which
    has no summary), read first; the stream is put back where it was."""
    if not stream.seekable():
        return {}, {}
    at = stream.tell()
    try:
        summary = SeekingReader(stream).get_summary()
    except Exception:  # noqa: BLE001  # a cut file fails in many ways: no summary
        summary = None
    finally:
        stream.seek(at)
    return ({}, {}) if summary is None else (dict(summary.schemas), dict(summary.channels))


class RecordsToTheCut:
    """The raw mcap records of one stream in file order, up to the first incomplete one.

    After iteration, :attr:`stopped_by` says why reading stopped early (None when the
    stream ended normally) and :attr:`damaged_chunks` how many chunks were skipped;
    :mod:`daq.recover` rewrites what this yields.
    """

    def __init__(self, stream: IO[bytes], name: str = "recording") -> None:
        self._stream = stream
        self.name = name
        self.stopped_by: str | None = None
        self.damaged_chunks = 0
        #: A record was read (False after iteration: the stream held none, e.g. 0 bytes).
        self.started = False

    def __iter__(self) -> Iterator[McapRecord]:
        records = StreamReader(self._stream, validate_crcs=True).records
        while True:
            try:
                record = next(records)
            except StopIteration:
                return
            except InvalidMagic as exc:
                if not self.started:  # not an MCAP file at all (a CAN log, say): nothing to recover
                    raise RecordingError(
                        self.name, "not an MCAP file (a service recording is .mcap)"
                    ) from exc
                self.stopped_by = f"{type(exc).__name__}: {exc}"
                return
            except (CRCValidationError, ZstdError) as exc:
                if isinstance(exc, CRCValidationError) and not isinstance(exc.record, Chunk):
                    self.stopped_by = f"{type(exc).__name__}: {exc}"
                    return
                # The chunk was read whole (its length intact), only its content is bad:
                # the reader stands at the next record. A cut one ends in EndOfFile.
                self.damaged_chunks += 1
                logger.warning(
                    "%s: a damaged chunk skipped (%s: %s): its messages are lost",
                    self.name,
                    type(exc).__name__,
                    exc,
                )
                records = StreamReader(self._stream, skip_magic=True, validate_crcs=True).records
                continue
            # A cut-off file fails in many ways (EndOfFile, struct.error, an incomplete
            # record): each means "the end is missing".
            except Exception as exc:  # noqa: BLE001
                self.stopped_by = f"{type(exc).__name__}: {exc}".rstrip(": ")
                return
            self.started = True
            yield record


class RecordingStream:
    """Iterates over the messages, attachments and metadata of one MCAP stream, in file
    order.

    After iteration, :attr:`complete` tells whether the file ended properly
    (footer read) and :attr:`stopped_by` why reading stopped early, if it did; that is
    logged as a warning unless ``warn`` is False (a look for the run's metadata, which
    the full read that follows it warns about).
    """

    def __init__(self, stream: IO[bytes], name: str = "recording", *, warn: bool = True) -> None:
        self._stream = stream
        self.name = name
        self.complete = False
        self.stopped_by: str | None = None
        self._warn = warn

    def __iter__(self) -> Iterator[RecordedMessage | RecordedAttachment | RecordedMetadata]:
        channels = summary_channels(self._stream)[1]
        records = RecordsToTheCut(self._stream, self.name)
        orphans = 0
        for record in records:
            if isinstance(record, Channel):
                channels[record.id] = record
            elif isinstance(record, Message):
                channel = channels.get(record.channel_id)
                if channel is None:
                    orphans += 1  # its channel was in a damaged chunk of a cut file
                    continue
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
        if not self._warn:
            return
        if orphans:
            logger.warning(
                "%s: %d messages skipped: their channel's record was lost", self.name, orphans
            )
        if self.stopped_by is not None and not records.started:
            logger.warning(
                "%s holds no MCAP record (%s): nothing was recorded in it (0 bytes, or cut in "
                "its header: the recorder stopped as it opened the file)",
                self.name,
                self.stopped_by,
            )
        elif self.stopped_by is not None:
            logger.warning(
                "%s ends without its summary (%s): read up to its last complete chunk",
                self.name,
                self.stopped_by,
            )
