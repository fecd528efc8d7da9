"""The systemd notify protocol (``Type=notify``), implemented directly.

One datagram per notification, ``KEY=value`` lines, to the AF_UNIX socket named
by ``$NOTIFY_SOCKET`` (a leading ``@`` means the abstract namespace). Without
``$NOTIFY_SOCKET`` (not under systemd) every call does nothing. A failed send is
logged once and never fatal.

>>> with SdNotifier(None) as notifier:
...     notifier.notify("READY=1")
False
"""

import logging
import os
import socket
from collections.abc import Mapping

logger = logging.getLogger(__name__)


class SdNotifier:
    """Sends sd_notify messages to ``address``; None disables it.

    The constructor opens nothing; :meth:`open` (or ``with``) creates the socket.
    """

    def __init__(self, address: str | None, watchdog_usec: int | None = None) -> None:
        self.address = address
        #: The watchdog timeout systemd set (WatchdogSec=), or None.
        self.watchdog_s = watchdog_usec / 1e6 if watchdog_usec else None
        self._socket: socket.socket | None = None
        self._warned = False
        #: Messages dropped because the notify socket's queue was full.
        self.dropped = 0

    @classmethod
    def from_environment(cls, environ: Mapping[str, str] = os.environ) -> "SdNotifier":
        """From ``$NOTIFY_SOCKET`` and ``$WATCHDOG_USEC`` (honouring ``$WATCHDOG_PID``)."""
        watchdog_usec: int | None = None
        pid = environ.get("WATCHDOG_PID")
        if pid is None or pid == str(os.getpid()):
            try:
                watchdog_usec = int(environ.get("WATCHDOG_USEC", "")) or None
            except ValueError:
                watchdog_usec = None
        return cls(environ.get("NOTIFY_SOCKET") or None, watchdog_usec)

    def __enter__(self) -> "SdNotifier":
        self.open()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    @property
    def enabled(self) -> bool:
        return self.address is not None

    def open(self) -> None:
        if self.address is not None and self._socket is None:
            self._socket = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC)

    def close(self) -> None:
        """Idempotent."""
        sock, self._socket = self._socket, None
        if sock is not None:
            sock.close()

    def notify(self, *lines: str) -> bool:
        """Send one datagram of ``lines``; True if it was sent."""
        if self._socket is None or self.address is None:
            return False
        target = "\0" + self.address[1:] if self.address.startswith("@") else self.address
        try:
            # Never block the service's main loop on a notify socket whose reader is
            # slow or gone: a full queue drops the message (the next one follows soon).
            self._socket.sendto("\n".join(lines).encode(), socket.MSG_DONTWAIT, target)
        except BlockingIOError:
            self.dropped += 1
            logger.debug("notify socket %s is full: message dropped", self.address)
            return False
        except OSError as exc:
            if not self._warned:
                self._warned = True
                logger.warning(
                    "cannot notify systemd at %s: %s (is NOTIFY_SOCKET right?)",
                    self.address,
                    exc.strerror or exc,
                )
            return False
        return True

    def ready(self) -> bool:
        return self.notify("READY=1")

    def status(self, text: str) -> bool:
        return self.notify(f"STATUS={text}")

    def watchdog(self) -> bool:
        return self.notify("WATCHDOG=1")

    def stopping(self) -> bool:
        return self.notify("STOPPING=1")
