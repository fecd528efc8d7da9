"""Stopping a main loop on SIGTERM/SIGINT/SIGHUP without taking a lock in the signal handler.

A handler that calls ``threading.Event.set()`` can hang the process: Python runs
handlers in the main thread between byte codes, and when the signal lands while the
main thread is inside ``Event.wait()`` holding the event's internal (non-reentrant)
lock, ``set()`` waits for that lock forever (the shutdown never starts).
:class:`StopSignal` takes no lock on that path: its handler only sets a flag, and the
waiting loop is woken through a pipe that the interpreter's own C-level handler
writes the signal number to (``signal.set_wakeup_fd``), which :meth:`StopSignal.wait`
watches with ``select``. The service (:mod:`daq.run_command`) and the live views
(:mod:`daq.live.command`) both wait on it.
"""

import os
import select
import signal
import time
from collections.abc import Iterable
from typing import Protocol, Self


class Stop(Protocol):
    """What a main loop needs of its stop request (``threading.Event`` has it too, for
    tests); ``wait`` returns whether a stop was requested."""

    def is_set(self) -> bool: ...

    def wait(self, timeout: float | None = None) -> bool: ...


#: Byte :meth:`StopSignal.set` writes to the wake-up pipe (no signal has number 0).
_SET_BYTE = 0


class StopSignal:
    """A stop request, made by one of ``signals`` or by :meth:`set`: by default SIGTERM
    (systemd), SIGINT (Ctrl-C) and SIGHUP (the terminal closed; its default action
    killed the service without finishing its recording).

    A context manager (main thread only): entering installs the handlers and the
    wake-up pipe, leaving restores the handlers and wake-up fd that were there and
    closes the pipe. The constructor changes nothing.

    >>> with StopSignal() as stop:  # doctest: +SKIP
    ...     while not stop.wait(1.0):
    ...         do_periodic_work()
    """

    def __init__(
        self, signals: Iterable[signal.Signals] = (signal.SIGTERM, signal.SIGINT, signal.SIGHUP)
    ) -> None:
        self._signals = tuple(signals)
        self._wake_bytes = frozenset({_SET_BYTE, *(int(s) for s in self._signals)})
        self._requested = False
        self._read_fd = self._write_fd = -1
        self._previous_fd = -1
        self._previous_handlers: dict[signal.Signals, object] = {}

    def __enter__(self) -> Self:
        self._read_fd, self._write_fd = os.pipe()
        os.set_blocking(self._read_fd, False)
        os.set_blocking(self._write_fd, False)
        self._previous_fd = signal.set_wakeup_fd(self._write_fd, warn_on_full_buffer=False)
        for signum in self._signals:
            self._previous_handlers[signum] = signal.signal(signum, self._on_signal)
        return self

    def __exit__(self, *exc_info: object) -> None:
        for signum, handler in self._previous_handlers.items():
            signal.signal(signum, handler)  # type: ignore[arg-type]
        self._previous_handlers.clear()
        signal.set_wakeup_fd(self._previous_fd)
        for fd in (self._read_fd, self._write_fd):
            os.close(fd)
        self._read_fd = self._write_fd = -1

    def _on_signal(self, signum: int, frame: object) -> None:
        # Only an attribute store: no lock, nothing that could wait on the main thread.
        self._requested = True

    def set(self) -> None:
        """Request the stop from code (any thread) and wake the waiting loop."""
        self._requested = True
        try:
            os.write(self._write_fd, bytes([_SET_BYTE]))
        except BlockingIOError:
            pass  # the pipe is full: a wake-up is pending anyway

    def is_set(self) -> bool:
        return self._requested

    def wait(self, timeout: float | None = None) -> bool:
        """Wait until a stop is requested or ``timeout`` seconds passed; True when stopped.

        The signal's byte in the pipe counts as the request even before Python has
        run the handler (it runs in the main thread between byte codes, later).
        """
        deadline = None if timeout is None else time.monotonic() + timeout
        while not self._requested:
            remaining_s = None if deadline is None else deadline - time.monotonic()
            if remaining_s is not None and remaining_s <= 0.0:
                break
            readable, _, _ = select.select([self._read_fd], [], [], remaining_s)
            if readable:
                self._drain()
        return self._requested

    def _drain(self) -> None:
        while True:
            try:
                data = os.read(self._read_fd, 512)
            except BlockingIOError:
                return
            if not data:
                return
            if not self._wake_bytes.isdisjoint(data):
                self._requested = True
