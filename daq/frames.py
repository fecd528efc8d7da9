"""A received CAN frame as the pipeline sees it, independent of where it came from.

Live frames come from python-can (:func:`from_can_message`), replayed ones from an
MCAP recording or a candump/ASC/BLF log; all become a :class:`RawFrame`.
"""

from dataclasses import dataclass

import can

from estimator.records import fast_init

#: Unix time of 2000-01-01: an earlier frame time is no date (a clock not set yet, or a
#: log of another tool that counts from its start).
DATED_FROM_S = 946_684_800.0


@fast_init  # one per frame received
@dataclass(frozen=True, slots=True)
class RawFrame:
    """One CAN frame as received."""

    #: Receive time (the kernel's time stamp on SocketCAN), Unix seconds.
    t_s: float
    arbitration_id: int
    is_extended_id: bool
    data: bytes
    #: A CAN error frame (controller fault report); carries no signals.
    is_error_frame: bool = False
    #: A remote (RTR) frame; carries no data.
    is_remote_frame: bool = False
    #: A CAN FD frame (up to 64 data bytes).
    is_fd: bool = False

    @property
    def dlc(self) -> int:
        return len(self.data)


def from_can_message(message: can.Message) -> RawFrame:
    """The :class:`RawFrame` of a python-can message (live or from a log reader)."""
    return RawFrame(
        float(message.timestamp),
        int(message.arbitration_id),
        bool(message.is_extended_id),
        bytes(message.data or b""),
        bool(message.is_error_frame),
        bool(message.is_remote_frame),
        bool(message.is_fd),
    )


#: The classes of a SocketCAN error frame, by their bit in its ID (linux/can/error.h).
ERROR_CLASSES = {
    0x001: "tx timeout",
    0x002: "lost arbitration",
    0x004: "controller problems",
    0x008: "protocol violation",
    0x010: "transceiver status",
    0x020: "no ack",
    0x040: "bus off",
    0x080: "bus error",
    0x100: "controller restarted",
    0x200: "error counters",
}
#: The controller problems (``CAN_ERR_CRTL``) by their bit in the error frame's byte 1.
CONTROLLER_PROBLEMS = {
    0x01: "rx overflow",
    0x02: "tx overflow",
    0x04: "rx warning",
    0x08: "tx warning",
    0x10: "rx passive",
    0x20: "tx passive",
    0x40: "error active again",
}


def error_frame_kinds(frame: RawFrame) -> list[str]:
    """What an error frame reports, by name: its classes, a controller problem by its
    detail (``rx overflow``: frames lost in the controller); ``error frame`` when its ID
    names no class (an interface that gives none).

    >>> error_frame_kinds(RawFrame(0.0, 0x044, True, bytes([0, 0x11, 0, 0]), True))
    ['rx overflow', 'rx passive', 'bus off']
    """
    kinds = []
    for bit, name in ERROR_CLASSES.items():
        if frame.arbitration_id & bit:
            details = frame.data[1] if bit == 0x004 and len(frame.data) > 1 else 0
            found = [problem for b, problem in CONTROLLER_PROBLEMS.items() if details & b]
            kinds += found or [name]
    return kinds or ["error frame"]


#: Bus states reported on the status topic.
BUS_UP = "up"
BUS_DOWN = "down"
BUS_ABSENT = "absent"
BUS_CLOSED = "closed"


@dataclass(frozen=True, slots=True)
class BusEvent:
    """A change of the bus state, or a loss of frames, queued in order with the frames."""

    #: Wall-clock time of the change, Unix seconds.
    t_s: float
    #: :data:`BUS_UP`, :data:`BUS_DOWN`, :data:`BUS_ABSENT` or :data:`BUS_CLOSED`.
    state: str
    reason: str
    #: Reception resumes after a gap: the consumer resets the rolling counters
    #: (and a replay of the recording does the same at the same place).
    reset_counters: bool = False
    #: Frames lost just before this event, since the previous one: dropped by the
    #: kernel (the socket's receive buffer was full) and by the reader (its queue
    #: was full). An event that reports a loss keeps the state as it was.
    kernel_dropped: int = 0
    rx_dropped: int = 0
