"""SocketCAN's wire formats, parsed and built without touching a socket.

Pure functions over the bytes that a ``CAN_RAW`` socket exchanges with the kernel
(Linux ``include/uapi/linux/can.h``), kept apart from the socket I/O in
:mod:`daq.socketcan` as python-can keeps ``dissect_can_frame`` apart from
``capture_message``:

- a received frame: ``struct can_frame`` (16 bytes) or ``struct canfd_frame``
  (72 bytes, only with ``CAN_RAW_FD_FRAMES``): :func:`parse_frame`;
- the ancillary data of each ``recvmsg``: the kernel time stamp
  (``SO_TIMESTAMPNS``) and the socket's drop counter (``SO_RXQ_OVFL``):
  :func:`parse_ancillary`;
- receive filters (``CAN_RAW_FILTER``): :func:`pack_filters`; the error frames asked
  for (``CAN_RAW_ERR_FILTER``): :data:`CAN_ERR_MASK`, every class.

>>> frame = parse_frame(bytes([0x23, 0x01, 0, 0, 2, 0, 0, 0]) + bytes(8), t_s=1.5)
>>> frame.arbitration_id, frame.data, frame.is_fd
(291, b'\\x00\\x00', False)
"""

import socket
import struct
from collections.abc import Iterable
from dataclasses import dataclass

from daq.frames import RawFrame
from dbc.decoding import ReceiveFilter

#: Sizes of ``struct can_frame`` and ``struct canfd_frame``: how a received frame
#: says whether it is classic or FD.
CAN_MTU = 16
CANFD_MTU = 72

CAN_EFF_FLAG = 0x80000000
CAN_RTR_FLAG = 0x40000000
CAN_ERR_FLAG = 0x20000000
CAN_SFF_MASK = 0x000007FF
CAN_EFF_MASK = 0x1FFFFFFF

#: Every class of error frame (bus off, controller problems, no ack, ...; linux/can/error.h).
CAN_ERR_MASK = 0x1FFFFFFF

# Socket options Python's socket module does not name (Linux values).
CAN_RAW_ERR_FILTER: int = getattr(socket, "CAN_RAW_ERR_FILTER", 2)
SO_RCVBUFFORCE: int = getattr(socket, "SO_RCVBUFFORCE", 33)
SO_TIMESTAMPNS: int = getattr(socket, "SO_TIMESTAMPNS", 35)
SO_RXQ_OVFL: int = getattr(socket, "SO_RXQ_OVFL", 40)

#: can_id, len, flags (FD) and two reserved bytes (len8_dlc of classic frames), payload after.
_HEADER = struct.Struct("=IBB2x")
_TIMESPEC = struct.Struct("@ll")
_DROPS = struct.Struct("=I")

#: Room for the ancillary data the reader asks for: a time stamp and a drop counter.
ANCILLARY_BYTES = socket.CMSG_SPACE(_TIMESPEC.size) + socket.CMSG_SPACE(_DROPS.size)


@dataclass(frozen=True, slots=True)
class Ancillary:
    """What the kernel attached to one received frame."""

    #: Kernel receive time stamp, Unix seconds; None if the kernel gave none.
    t_s: float | None
    #: Frames the socket has dropped since it was opened (its receive buffer was
    #: full), as of this frame. The kernel leaves the field out while it is 0.
    dropped: int


def parse_frame(buffer: bytes, t_s: float) -> RawFrame:
    """The :class:`RawFrame` of one ``can_frame``/``canfd_frame`` as ``recvmsg`` gave it.

    Raises ValueError for bytes of another size (never from a ``CAN_RAW`` socket).
    """
    if len(buffer) not in (CAN_MTU, CANFD_MTU):
        raise ValueError(f"a CAN frame is {CAN_MTU} or {CANFD_MTU} bytes, got {len(buffer)}")
    can_id, length, _flags = _HEADER.unpack_from(buffer)
    extended = bool(can_id & CAN_EFF_FLAG)
    error = bool(can_id & CAN_ERR_FLAG)
    remote = bool(can_id & CAN_RTR_FLAG) and not error
    mask = CAN_EFF_MASK if extended or error else CAN_SFF_MASK
    return RawFrame(
        t_s=t_s,
        arbitration_id=can_id & mask,
        is_extended_id=extended,
        data=b"" if remote else bytes(buffer[8 : 8 + min(length, len(buffer) - 8)]),
        is_error_frame=error,
        is_remote_frame=remote,
        is_fd=len(buffer) == CANFD_MTU,
    )


def parse_ancillary(messages: Iterable[tuple[int, int, bytes]]) -> Ancillary:
    """Time stamp and drop counter from ``recvmsg``'s ancillary (level, type, data) list."""
    t_s: float | None = None
    dropped = 0
    for level, kind, data in messages:
        if level != socket.SOL_SOCKET:
            continue
        if kind == SO_TIMESTAMPNS and len(data) >= _TIMESPEC.size:
            seconds, nanoseconds = _TIMESPEC.unpack_from(data)
            t_s = seconds + nanoseconds * 1e-9
        elif kind == SO_RXQ_OVFL and len(data) >= _DROPS.size:
            (dropped,) = _DROPS.unpack_from(data)
    return Ancillary(t_s, dropped)


def pack_filters(filters: Iterable[ReceiveFilter]) -> bytes:
    """``CAN_RAW_FILTER`` bytes of the given filters (each matches its frame format only)."""
    words: list[int] = []
    for can_id, can_mask, extended in filters:
        if extended:
            words += [can_id | CAN_EFF_FLAG, can_mask | CAN_EFF_FLAG]
        else:
            words += [can_id, can_mask | CAN_EFF_FLAG]
    return struct.pack(f"={len(words)}I", *words)
