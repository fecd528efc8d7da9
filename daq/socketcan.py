"""The service's own SocketCAN reader: a ``CAN_RAW`` socket that says what it lost.

python-can's socketcan interface neither reads the kernel's drop counter nor
forces the receive buffer past ``net.core.rmem_max``, so a stall could lose frames
without a trace. This socket:

- takes CAN FD frames too (``CAN_RAW_FD_FRAMES``); a classic-only socket never
  sees them, the kernel drops them unseen;
- takes the controller's error frames of every class (``CAN_RAW_ERR_FILTER``: bus off,
  error passive, an overflow of the controller's receive buffer, no ack, ...), which a
  socket gets only when it asks (python-can's did; this one did not, and a bus-off
  showed nowhere);
- asks for ``SO_RCVBUFFORCE`` (passes ``rmem_max``; needs CAP_NET_ADMIN), else
  ``SO_RCVBUF`` (clamped to ``rmem_max``), and reads back what it got
  (:attr:`SocketCanSource.rcvbuf_bytes`; Linux doubles the request for its
  bookkeeping, so a granted 4 MiB reads back as 8 MiB);
- keeps the kernel's receive time stamps (``SO_TIMESTAMPNS``) and its count of
  frames dropped because the buffer was full (``SO_RXQ_OVFL``), both from the
  ancillary data of each ``recvmsg``.

The bytes are parsed by :mod:`daq.socketcan_wire`; this module only does I/O.
OS errors are raised as they are (``OSError`` with ``errno``): the reader
(:class:`~daq.bus_reader.BusReader`) turns ENETDOWN/ENODEV into bus states.
"""

import errno
import logging
import socket
import struct
import time

from daq.frames import RawFrame
from daq.socketcan_wire import (
    ANCILLARY_BYTES,
    CAN_ERR_MASK,
    CAN_RAW_ERR_FILTER,
    CANFD_MTU,
    SO_RCVBUFFORCE,
    SO_RXQ_OVFL,
    SO_TIMESTAMPNS,
    pack_filters,
    parse_ancillary,
    parse_frame,
)
from dbc.decoding import ReceiveFilter

logger = logging.getLogger(__name__)

#: Bytes of the granted receive buffer (:attr:`SocketCanSource.rcvbuf_bytes`) a frame
#: waiting in it takes: the kernel charges each its socket buffer's true size, not
#: its 16 or 72 bytes (768 measured on vcan0; a driver's own buffers may differ a little).
RCVBUF_BYTES_PER_FRAME = 800


def set_receive_buffer(sock: socket.socket, size_bytes: int) -> int:
    """Ask for ``size_bytes`` of receive buffer, forced if allowed; the size granted."""
    try:
        sock.setsockopt(socket.SOL_SOCKET, SO_RCVBUFFORCE, size_bytes)
    except OSError as exc:
        if exc.errno not in (errno.EPERM, errno.EACCES, errno.ENOPROTOOPT):
            raise
        # Not privileged: the kernel clamps this one to net.core.rmem_max.
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, size_bytes)
    return int(sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF))


class SocketCanSource:
    """A bound ``CAN_RAW`` socket on ``channel``; a frame source for the reader.

    The constructor opens nothing; :meth:`open` (or ``with``) does, and raises
    ``OSError`` (e.g. ENODEV for a missing interface). ``receive_filters``
    installs them as kernel filters.
    """

    def __init__(
        self,
        channel: str,
        *,
        receive_buffer_bytes: int,
        receive_own_messages: bool = False,
        receive_filters: list[ReceiveFilter] | None = None,
    ) -> None:
        self.channel = channel
        self._requested_bytes = receive_buffer_bytes
        self._own = receive_own_messages
        self._receive_filters = receive_filters
        self._socket: socket.socket | None = None
        self._timeout_s: float | None = None
        #: Receive buffer the kernel granted (read back after setting it).
        self.rcvbuf_bytes: int | None = None
        #: Frames the kernel dropped on this socket (buffer full), as of the last frame.
        self.kernel_dropped = 0

    def __enter__(self) -> "SocketCanSource":
        self.open()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.shutdown()

    def open(self) -> None:
        if self._socket is not None:
            return
        sock = socket.socket(socket.AF_CAN, socket.SOCK_RAW | socket.SOCK_CLOEXEC, socket.CAN_RAW)
        try:
            sock.setsockopt(socket.SOL_CAN_RAW, socket.CAN_RAW_FD_FRAMES, 1)
            sock.setsockopt(socket.SOL_CAN_RAW, socket.CAN_RAW_RECV_OWN_MSGS, int(self._own))
            sock.setsockopt(socket.SOL_CAN_RAW, CAN_RAW_ERR_FILTER, struct.pack("=I", CAN_ERR_MASK))
            if self._receive_filters is not None:
                sock.setsockopt(
                    socket.SOL_CAN_RAW, socket.CAN_RAW_FILTER, pack_filters(self._receive_filters)
                )
            sock.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)
            sock.setsockopt(socket.SOL_SOCKET, SO_RXQ_OVFL, 1)
            # Sized before binding, so that no frame ever waits in a smaller buffer.
            self.rcvbuf_bytes = set_receive_buffer(sock, self._requested_bytes)
            sock.bind((self.channel,))
        except BaseException:
            sock.close()
            raise
        self._socket = sock

    def recv(self, timeout_s: float) -> RawFrame | None:
        """The next frame, or None after ``timeout_s`` without one (``timeout_s`` 0: at
        once, ``EAGAIN``); raises ``OSError``."""
        sock = self._socket
        if sock is None:
            raise OSError(errno.EBADF, "the CAN socket is not open")
        if timeout_s != self._timeout_s:  # settimeout costs a syscall: only on change
            sock.settimeout(timeout_s)
            self._timeout_s = timeout_s
        try:
            buffer, ancillary, _flags, _address = sock.recvmsg(CANFD_MTU, ANCILLARY_BYTES)
        except (TimeoutError, BlockingIOError):  # timeout 0: a non-blocking socket
            return None
        extra = parse_ancillary(ancillary)
        self.kernel_dropped = extra.dropped
        try:
            return parse_frame(buffer, extra.t_s if extra.t_s is not None else time.time())
        except ValueError as exc:  # never from CAN_RAW; if ever, a bus fault, not a crash
            raise OSError(errno.EPROTO, f"unexpected data from the CAN socket: {exc}") from exc

    def shutdown(self) -> None:
        """Close the socket. Idempotent."""
        sock, self._socket = self._socket, None
        if sock is not None:
            sock.close()
