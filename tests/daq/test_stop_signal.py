"""The stop request of the service and the live views: SIGTERM never hangs the main loop.

A handler calling ``threading.Event.set()`` hangs when the signal lands while the main
thread holds the event's lock inside ``wait()`` (reproduced here with ``wait(0)``, which
the service's loop does when a deadline has passed: within a few hundred tries).
"""

import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

from daq.stop_signal import StopSignal

ROOT = Path(__file__).resolve().parents[2]

TRIES = 300

#: The main loop of the service and of the views, against a SIGTERM sent by another
#: thread after 0..3 ms: every other try waits 1 ms at a time, the others 0 s (a
#: deadline already passed, as Service.run and run_plain then wait), which is where the
#: signal lands while the loop runs inside ``wait`` rather than blocked in the kernel.
#: faulthandler turns a hang into a stack dump.
CHILD = f"""
import faulthandler, os, random, signal, sys, threading
from daq.stop_signal import StopSignal

faulthandler.dump_traceback_later(120, exit=True)
random.seed(15)
for attempt in range({TRIES}):
    with StopSignal() as stop:
        killer = threading.Timer(
            random.uniform(0.0, 0.003), os.kill, (os.getpid(), signal.SIGTERM)
        )
        killer.start()
        wait_s = 0.001 if attempt % 2 else 0.0
        while not stop.is_set():
            stop.wait(wait_s)
        killer.join()
print("stopped", attempt + 1, flush=True)
"""


def test_sigterm_during_wait_never_hangs_in_300_tries() -> None:
    result = subprocess.run(
        [sys.executable, "-c", CHILD],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,  # only a last resort: the child dumps its stack after 120 s
        check=False,
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["stopped", str(TRIES)]


def test_set_from_another_thread_wakes_the_wait() -> None:
    with StopSignal() as stop:
        assert stop.wait(0.0) is False
        setter = threading.Thread(target=stop.set)
        setter.start()
        assert stop.wait() is True  # no timeout: only the wake-up ends it
        setter.join()
        assert stop.is_set()


def test_a_signal_is_a_stop_and_the_handlers_come_back() -> None:
    before = signal.getsignal(signal.SIGTERM)
    with StopSignal() as stop:
        assert signal.getsignal(signal.SIGTERM) != before
        os.kill(os.getpid(), signal.SIGTERM)
        assert stop.wait() is True
    assert signal.getsignal(signal.SIGTERM) == before
    assert signal.set_wakeup_fd(-1) == -1  # the wake-up fd was restored (none)
