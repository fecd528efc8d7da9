"""Raw CAN frames in batches: the compact, versioned binary layout of ``/can/raw``.

One MCAP message on ``/can/raw`` holds every frame of one batch (what the consumer
took from its queue in one go, at most :data:`MAX_FRAMES`), in the order the
pipeline processed them. The layout is written into the file as the channel's
schema (:data:`SCHEMA_TEXT`), so a reader needs nothing else:

- header: ``uint8 version`` (:data:`VERSION`), ``uint32 count``;
- ``count`` frames, each ``float64 t_s`` (receive time, Unix seconds, exactly the
  value the pipeline saw, so a replay is bit for bit), ``uint32 id``, ``uint8 flags``
  (bit 0 extended ID, bit 1 error frame, bit 2 remote frame, bit 3 CAN FD),
  ``uint8 length`` (up to 64, CAN FD), then ``length`` data bytes;

little endian, no padding. What the service made of a frame (decoded signals, bad
frame kinds) is not stored: a replay derives it, the same as live.

Measured against one ROS 2 ``can_msgs/msg/Frame`` (CDR) message per frame
(``bench.stages``): a per-frame MCAP message costs ~10x the batch's bytes and time,
see the README's Benchmarks section.

Recordings made before (JSON ``/can/raw``, one message per frame, encoding
``json``) are read by :func:`decode_json_frame`.
"""

import json
import struct
from collections.abc import Iterator, Sequence

from daq.frames import RawFrame

SCHEMA_NAME = "portal.CanFrameBatch"
#: Schema and message encoding of ``/can/raw`` batches (the version is in every message).
ENCODING = "portal.can_batch"
#: The layout version written; readers refuse others by name.
VERSION = 1
#: Frames per message at most (the consumer's batches are cut to this).
MAX_FRAMES = 4096
SCHEMA_TEXT = f"""\
portal.CanFrameBatch version {VERSION}: CAN frames in receive order, little endian, no padding
header: uint8 version ({VERSION}); uint32 count
count x frame: float64 t_s (receive time, Unix seconds); uint32 id;
  uint8 flags (bit 0: extended 29-bit id, bit 1: error frame, bit 2: remote frame,
  bit 3: CAN FD); uint8 length (0..64); uint8 data[length]
"""

_HEADER = struct.Struct("<BI")
_FRAME = struct.Struct("<dIBB")
_EXTENDED, _ERROR, _REMOTE, _FD = 1, 2, 4, 8


class BatchFormatError(ValueError):
    """A ``/can/raw`` message that is not a batch this module can read."""


def encode(frames: Sequence[RawFrame]) -> bytes:
    """One batch message of ``frames`` (at most :data:`MAX_FRAMES`)."""
    pack = _FRAME.pack
    parts = [_HEADER.pack(VERSION, len(frames))]
    parts += [
        pack(
            f.t_s,
            f.arbitration_id,
            f.is_extended_id | (f.is_error_frame << 1) | (f.is_remote_frame << 2) | (f.is_fd << 3),
            len(f.data),
        )
        + f.data
        for f in frames
    ]
    return b"".join(parts)


def decode(data: bytes) -> Iterator[RawFrame]:
    """The frames of one batch message, in order; :class:`BatchFormatError` if malformed."""
    if len(data) < _HEADER.size:
        raise BatchFormatError(f"a batch of {len(data)} bytes has no header")
    version, count = _HEADER.unpack_from(data)
    if version != VERSION:
        raise BatchFormatError(f"batch layout version {version}; this reads {VERSION}")
    at = _HEADER.size
    unpack, size = _FRAME.unpack_from, _FRAME.size
    try:
        for _ in range(count):
            t_s, frame_id, flags, length = unpack(data, at)
            at += size
            payload = data[at : at + length]
            if len(payload) != length:
                raise BatchFormatError("the batch ends inside a frame")
            at += length
            yield RawFrame(
                t_s,
                frame_id,
                bool(flags & _EXTENDED),
                payload,
                bool(flags & _ERROR),
                bool(flags & _REMOTE),
                bool(flags & _FD),
            )
    except struct.error as exc:
        raise BatchFormatError("the batch ends inside a frame header") from exc
    if at != len(data):
        raise BatchFormatError(f"{len(data) - at} bytes after the last of {count} frames")


def recorded_frames(encoding: str, data: bytes) -> Iterator[RawFrame]:
    """The frames of one ``/can/raw`` message, by its channel's message encoding: a batch,
    or one JSON frame of a recording made before batches."""
    if encoding == ENCODING:
        return decode(data)
    if encoding == "json":
        return iter((decode_json_frame(data),))
    raise BatchFormatError(f"/can/raw in an unknown encoding {encoding!r}")


def decode_json_frame(data: bytes) -> RawFrame:
    """One frame of a recording made before batches (JSON ``/can/raw``, one per message)."""
    raw = json.loads(data)
    return RawFrame(
        t_s=raw["t"],
        arbitration_id=raw["id"],
        is_extended_id=raw["extended"],
        data=bytes.fromhex(raw["data"]),
        is_error_frame=raw["error_frame"],
        is_remote_frame=raw["remote_frame"],
        is_fd=raw.get("fd", False),  # recordings made before CAN FD lack it
    )
