"""The benchmark's side of the latency probe (:mod:`bench.subscriber`): start, sync, collect."""

import json
import select
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import zenoh

from bench.subscriber import PING_KEY

ROOT = Path(__file__).resolve().parent.parent


class ProbeProcess:
    """The subscriber process; :meth:`start` returns once its subscription is routed."""

    def __init__(self, session: zenoh.Session, endpoint: str, cpu: int | None) -> None:
        self._session = session
        self._endpoint = endpoint
        self._cpu = cpu
        self._process: subprocess.Popen[str] | None = None

    def __enter__(self) -> "ProbeProcess":
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def start(self, timeout_s: float = 30.0) -> None:
        command = [sys.executable, "-m", "bench.subscriber", "--connect", self._endpoint]
        if self._cpu is not None:
            command += ["--cpu", str(self._cpu)]
        self._process = process = subprocess.Popen(
            command, cwd=ROOT, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
        )
        assert process.stdout is not None
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            self._session.put(PING_KEY, b"ping")
            readable, _, _ = select.select([process.stdout], [], [], 0.05)
            if readable:
                line = process.stdout.readline().strip()
                if line == "ready":
                    return
                raise RuntimeError(f"the latency probe said {line!r} instead of 'ready'")
            if process.poll() is not None:
                raise RuntimeError(f"the latency probe exited with status {process.returncode}")
        raise RuntimeError(f"the latency probe was not ready within {timeout_s} s")

    @property
    def pid(self) -> int:
        assert self._process is not None
        return self._process.pid

    def collect(self, expected: int, timeout_s: float = 10.0) -> dict[str, Any]:
        """Statistics of the leg samples since the last collect (waits for ``expected``)."""
        process = self._process
        assert process is not None and process.stdin is not None and process.stdout is not None
        process.stdin.write(f"collect {expected} {timeout_s}\n")
        process.stdin.flush()
        line = process.stdout.readline()
        if not line:
            raise RuntimeError("the latency probe ended unexpectedly")
        result: dict[str, Any] = json.loads(line)
        return result

    def close(self) -> None:
        process, self._process = self._process, None
        if process is None:
            return
        try:
            if process.stdin is not None:
                process.stdin.write("quit\n")
                process.stdin.close()
            process.wait(timeout=10)
        except (OSError, subprocess.TimeoutExpired):
            process.kill()
            process.wait()
        if process.stdout is not None:
            process.stdout.close()
