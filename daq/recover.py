"""Completing a recording cut short by a crash: ``portal-daq recover CUT.mcap [-o OUT.mcap]``.

A file whose writer was killed has no summary and no indexes: mcap's default
``make_reader()`` reads nothing of it, Foxglove wants an index. As the mcap
command-line tool's ``recover`` does, the file is read from the start record by
record (chunks decompressed, CRCs checked) up to the first record that is
incomplete or corrupt, and everything read (header profile, schemas, channels,
messages in file order, attachments, metadata) is written again through a new
writer, which adds the chunk and message indexes, the statistics and the summary.
Nothing after the cut can be had back; what was lost is reported.

The recorder runs :func:`recover_cut_files` on its directory when it starts: every file
of its machine cut short (:func:`is_cut_short`) is recovered in place.
"""

import fcntl
import logging
import os
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, cast

from mcap.records import Attachment, Channel, Footer, Header, Message, Metadata, Schema
from mcap.writer import Writer

from daq.errors import RecordingError
from daq.mcap_file import COMPRESSION
from daq.mcap_reading import RecordsToTheCut, summary_channels
from daq.output_file import replacing

logger = logging.getLogger(__name__)

#: Every MCAP file ends with these bytes (after the footer).
MAGIC = b"\x89MCAP0\r\n"


@dataclass(frozen=True, slots=True)
class Recovered:
    """What :func:`recover` wrote, and why reading stopped (None: the file was whole)."""

    messages: int
    attachments: int
    metadata: int
    #: The record that could not be read, e.g. ``EndOfFile``; None if the footer was read.
    stopped_by: str | None
    #: Chunks skipped in the middle of the file (CRC or compression failed).
    damaged_chunks: int = 0


def hold_while_writing(file: IO[bytes], path: Path) -> None:
    """Mark ``file`` as being written: an exclusive advisory lock (``flock``), released when
    the file is closed or its process dies (a crash, SIGKILL), so :func:`recover_file`
    leaves a file alone whose writer is alive, and takes one it left cut."""
    try:
        fcntl.flock(file.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:  # a file system without locks: nothing is kept from recover
        logger.debug("%s: no lock for writing it: %s", path, exc.strerror or exc)


def _refuse_while_written(file: IO[bytes], path: Path) -> None:
    try:
        fcntl.flock(file.fileno(), fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        raise RecordingError(
            path,
            "a running service is writing it (it holds the file's lock): rewritten in place, "
            "what the service writes after would be lost; -o OUT copies what it holds so far",
        ) from None
    except OSError:  # a file system without locks: nobody can tell
        pass


def is_cut_short(path: Path) -> bool:
    """The file does not end with the MCAP magic: its writer did not finish it."""
    try:
        with open(path, "rb") as file:
            if file.seek(0, os.SEEK_END) < 2 * len(MAGIC):
                return True
            file.seek(-len(MAGIC), os.SEEK_END)
            return file.read() != MAGIC
    except OSError as exc:
        raise RecordingError(path, f"cannot read it: {exc.strerror or exc}") from exc


def recover(
    source: IO[bytes],
    target: IO[bytes],
    *,
    compression: str = "zstd",
    chunk_size: int = 1 << 20,
    name: str = "recording",
) -> Recovered:
    """Copy every readable record of ``source`` into a complete MCAP on ``target``.

    Raises :class:`RecordingError` (naming ``name``) when ``source`` is no MCAP at all or
    holds no record of one (0 bytes: nothing to recover)."""
    writer = Writer(
        cast(IO[Any], target), chunk_size=chunk_size, compression=COMPRESSION[compression]
    )
    schemas: dict[int, int] = {0: 0}  # schema id 0: no schema
    channels: dict[int, int] = {}
    messages = attachments = metadata = 0
    footer = False
    started = False
    # a whole file's summary names every channel, also one whose chunk is damaged
    summary_schemas, summary_channels_ = summary_channels(source)
    known: list[Schema | Channel] = [*summary_schemas.values(), *summary_channels_.values()]
    records = RecordsToTheCut(source, name)
    for record in records:
        if isinstance(record, Header):
            writer.start(profile=record.profile, library=record.library)
            started = True
            continue
        if not started:  # no readable header: start one anyway
            writer.start()
            started = True
        while known:  # after the header
            _register(writer, known.pop(0), schemas, channels)
        if isinstance(record, Schema | Channel):
            _register(writer, record, schemas, channels)
        elif isinstance(record, Message) and record.channel_id in channels:
            writer.add_message(
                channels[record.channel_id],
                log_time=record.log_time,
                data=record.data,
                publish_time=record.publish_time,
                sequence=record.sequence,
            )
            messages += 1
        elif isinstance(record, Attachment):
            writer.add_attachment(
                record.create_time, record.log_time, record.name, record.media_type, record.data
            )
            attachments += 1
        elif isinstance(record, Metadata):
            writer.add_metadata(record.name, record.metadata)
            metadata += 1
        elif isinstance(record, Footer):
            footer = True
    if not records.started:  # 0 bytes, or cut in its header: it was rewritten as an MCAP
        raise RecordingError(
            name,
            f"holds no MCAP record ({records.stopped_by}): nothing was recorded in it (the "
            "recorder stopped as it opened the file); nothing to recover",
        )
    writer.finish()  # type: ignore[no-untyped-call]
    stopped_by = records.stopped_by or (None if footer else "no footer")
    return Recovered(messages, attachments, metadata, stopped_by, records.damaged_chunks)


def _register(
    writer: Writer, record: Schema | Channel, schemas: dict[int, int], channels: dict[int, int]
) -> None:
    """Register ``record`` (of the source's ids) with ``writer``, once per id."""
    if isinstance(record, Schema):
        if record.id not in schemas:
            schemas[record.id] = writer.register_schema(record.name, record.encoding, record.data)
    elif record.id not in channels and record.schema_id in schemas:
        channels[record.id] = writer.register_channel(
            record.topic, record.message_encoding, schemas[record.schema_id], record.metadata
        )


def recover_file(path: Path, out: Path | None = None, *, compression: str = "zstd") -> Recovered:
    """Recover ``path`` into ``out``, or in place, through
    :func:`~daq.output_file.replacing`: a recovery that fails leaves what was there as it
    was (a file of the user's, a device such as /dev/null, the cut file itself).

    Raises :class:`RecordingError` when a file cannot be read or written.
    """
    target = out or path
    try:
        with open(path, "rb") as source:
            if out is None:
                # Rewritten under its writer, the file would be replaced by a copy and all
                # written after would go to the old one, unlinked: lost, nothing said.
                _refuse_while_written(source, path)
            with replacing(target, "wb") as sink:
                return recover(source, sink, compression=compression, name=str(path))
    except OSError as exc:
        # The output's error names the path given, not the .part written beside it.
        where = path if exc.filename in (None, str(path)) else target
        raise RecordingError(where, f"cannot recover: {exc.strerror}") from exc


def recover_cut_files(directory: Path, machine_id: str, compression: str = "zstd") -> None:
    """Recover in place every file of ``machine_id`` in ``directory`` that a crash cut
    short, one log line each; remove one that holds no MCAP record (the recorder stopped
    as it opened it: nothing was recorded in it). Every file, not only the newest by
    name: a clock stepped back, or a machine without a real-time clock (from 1970 at every
    start until NTP sets it), names the last file before older ones, and its cut file
    was never recovered. A file that cannot be recovered is logged and left as it is."""
    for path in sorted(directory.glob(f"{machine_id}_*.mcap")):
        try:
            if not is_cut_short(path):
                continue
            if _holds_no_record(path):
                path.unlink()
                logger.warning("removed %s: it holds no MCAP record (nothing was recorded)", path)
                continue
            result = recover_file(path, compression=compression)
        except (RecordingError, OSError) as exc:
            reason = exc.reason if isinstance(exc, RecordingError) else exc.strerror
            logger.error("cannot recover %s (cut short): %s", path, reason)
            continue
        logger.warning(
            "recovered %s (cut short by a crash): %d messages, %d attachments kept",
            path,
            result.messages,
            result.attachments,
        )


def _holds_no_record(path: Path) -> bool:
    """``path`` holds no MCAP record (0 bytes, or cut in its header); raises
    :class:`RecordingError` when it is no MCAP file at all, or a running service writes
    it (it may have just opened it)."""
    with open(path, "rb") as stream:
        _refuse_while_written(stream, path)
        records = RecordsToTheCut(stream, str(path))
        next(iter(records), None)
        return not records.started
