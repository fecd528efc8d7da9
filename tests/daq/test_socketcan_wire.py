"""SocketCAN's frame, ancillary-data and filter bytes, parsed and built without a socket."""

import socket
import struct

import pytest

from daq.frames import RawFrame
from daq.socketcan_wire import (
    SO_RXQ_OVFL,
    SO_TIMESTAMPNS,
    pack_filters,
    parse_ancillary,
    parse_frame,
)
from dbc.decoding import ReceiveFilter


def can_frame(can_id: int, data: bytes) -> bytes:
    """``struct can_frame`` as the kernel hands it out: header, 8 data bytes."""
    return struct.pack("=IB3x", can_id, len(data)) + data.ljust(8, b"\0")


def canfd_frame(can_id: int, data: bytes, flags: int = 0x05) -> bytes:
    """``struct canfd_frame``: header with flags (BRS|FDF), 64 data bytes."""
    return struct.pack("=IBB2x", can_id, len(data), flags) + data.ljust(64, b"\0")


def test_classic_frames_standard_and_extended() -> None:
    assert parse_frame(can_frame(0x123, b"\x01\x02\x03"), 2.5) == RawFrame(
        2.5, 0x123, False, b"\x01\x02\x03"
    )
    extended = parse_frame(can_frame(0x18FEF100 | 0x80000000, bytes(range(8))), 1.0)
    assert (extended.arbitration_id, extended.is_extended_id) == (0x18FEF100, True)
    assert extended.data == bytes(range(8)) and not extended.is_fd


def test_fd_frame_is_marked_and_keeps_all_its_bytes() -> None:
    payload = bytes(range(48))
    frame = parse_frame(canfd_frame(0x100, payload), 3.0)
    assert frame == RawFrame(3.0, 0x100, False, payload, is_fd=True)
    assert frame.dlc == 48


def test_remote_and_error_frames() -> None:
    remote = parse_frame(can_frame(0x7FF | 0x40000000, bytes(4)), 0.0)
    assert (remote.arbitration_id, remote.is_remote_frame, remote.data) == (0x7FF, True, b"")
    error = parse_frame(can_frame(0x20000004, bytes([0, 0x10, 0, 0, 0, 0, 0, 0])), 0.0)
    assert (error.is_error_frame, error.arbitration_id, error.dlc) == (True, 0x4, 8)
    assert not error.is_remote_frame


def test_bytes_of_another_size_are_refused() -> None:
    with pytest.raises(ValueError, match="16 or 72 bytes, got 8"):
        parse_frame(bytes(8), 0.0)


def test_time_stamp_and_drop_counter_from_ancillary_data() -> None:
    stamp = struct.pack("@ll", 1_700_000_000, 250_000_000)
    ancillary = [
        (socket.SOL_SOCKET, SO_TIMESTAMPNS, stamp),
        (socket.SOL_SOCKET, SO_RXQ_OVFL, struct.pack("=I", 1234)),
    ]
    extra = parse_ancillary(ancillary)
    assert extra.t_s == pytest.approx(1_700_000_000.25, abs=1e-6)
    assert extra.dropped == 1234
    # No drop counter: the kernel leaves it out while nothing was dropped.
    assert parse_ancillary(ancillary[:1]).dropped == 0
    assert parse_ancillary([]).t_s is None
    # Another level's message with the same type number is not ours.
    assert parse_ancillary([(socket.SOL_IP, SO_RXQ_OVFL, struct.pack("=I", 9))]).dropped == 0


def test_filters_match_standard_and_extended_ids_exactly() -> None:
    filters = [ReceiveFilter(0x100, 0x7FF, False), ReceiveFilter(0x18FEF100, 0x1FFFFFFF, True)]
    packed = pack_filters(filters)
    assert struct.unpack("=4I", packed) == (0x100, 0x800007FF, 0x98FEF100, 0x9FFFFFFF)
    assert pack_filters([]) == b""
