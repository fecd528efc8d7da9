"""The lifecycle the service's background workers share: one thread each.

Reader, consumer, publisher and recorder each run a loop in a daemon thread of their
own, unless ``threaded`` is False (the reader and the publisher in the service's
event loop: the consumer's thread calls them). The constructor starts nothing;
``start`` (or entering the context) prepares the resource and starts the thread;
``close`` (or leaving the context) asks the loop to stop, joins it and releases the
resource. Both are idempotent.
"""

import threading
from typing import Self


class Worker:
    """Runs :meth:`_run` in a daemon thread named :attr:`thread_name`.

    Subclasses implement ``_run`` (which returns once ``self._stop`` is set) and may
    override ``_before_start`` (open what the thread needs; may raise) and
    ``_after_stop`` (release it once the thread has ended).
    """

    thread_name = "worker"
    #: False: ``start`` only prepares the resource; another thread calls the worker.
    threaded = True

    def __init__(self) -> None:
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._started = False

    def __enter__(self) -> Self:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    @property
    def alive(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> None:
        if self._started:
            return
        self._before_start()
        self._started = True
        if not self.threaded:
            return
        self._thread = threading.Thread(target=self._run, name=self.thread_name, daemon=True)
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        self._after_stop()

    def _before_start(self) -> None:
        """Open what the thread needs (runs in ``start``, before the thread)."""

    def _after_stop(self) -> None:
        """Release what the thread used (runs in ``close``, after the thread ended)."""

    def _run(self) -> None:
        raise NotImplementedError
