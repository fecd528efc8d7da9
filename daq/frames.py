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
