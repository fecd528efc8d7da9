"""The two systems under test, behind one small interface the measurement drives.

- :class:`ServiceUnderTest`: the real service (:class:`daq.service.Service`, as
  :func:`daq.runner.run_service` builds it) with its reader, consumer, publisher and
  recorder threads and its main loop, on a python-can ``virtual`` bus, publishing on
  the benchmark's Zenoh session and recording MCAP into a temporary directory.
- :class:`NaiveBaseline`: what one would write first: a python-can ``Notifier`` on a
  virtual bus calling a listener that decodes with ``Database.decode_message``, and
  for a leg frame computes eq. (4) inline and puts ``json.dumps`` of the sample on
  Zenoh (one put per leg sample, no declared publisher); no CRC/counter check, no
  median, no recording.
"""

import json
import threading
import time
import uuid
from collections import Counter
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import can
import zenoh
from cantools.database.can import Database
from mcap.reader import make_reader

from bench.frames import EXAMPLE_CONFIG
from daq.can_batch import recorded_frames
from daq.mcap_file import RAW_TOPIC
from daq.mcap_reading import json_items
from daq.recorder_process import RecorderProcess
from daq.runner import build_recorder, bus_factory
from daq.service import Service
from daq.service_config import ServiceConfig, load_service_config
from dbc.decoding import FrameDecoder
from dbc.machine import MachineConfig

_SERVICE_TABLES = """
[service]
{service}

[bus]
interface = "virtual"
channel = "{channel}"

[zenoh]
key_prefix = "{prefix}"

[publish]
{publish}

[recording]
directory = "{directory}"
{recording}
"""


def service_config(workdir: Path, prefix: str, tables: Mapping[str, str] = {}) -> ServiceConfig:
    """The example machine with the service's defaults, a virtual bus and a recording dir,
    and the extra lines ``tables`` gives for ``service``, ``publish`` and ``recording``."""
    path = workdir / "portal-daq.toml"
    text = _SERVICE_TABLES.format(
        channel=f"bench-{uuid.uuid4().hex}",
        prefix=prefix,
        directory=workdir / "recordings",
        service=tables.get("service", ""),
        publish=tables.get("publish", ""),
        recording=tables.get("recording", ""),
    )
    path.write_text(text + "\n" + EXAMPLE_CONFIG.read_text())
    return load_service_config(path)


class ServiceUnderTest:
    """The service running in threads of this process, fed through a virtual bus."""

    def __init__(self, config: ServiceConfig, session: zenoh.Session) -> None:
        self.config = config
        filters = FrameDecoder(config.database, config.machine.protection).receive_filters
        recorder = build_recorder(config)
        assert recorder is not None, "the benchmark's config records"
        self.recorder = recorder
        self.service = Service(
            config,
            open_bus=bus_factory(config.bus, filters),
            session=session,
            recorder=self.recorder,
        )
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self.service.run, args=(self._stop,), name="main")
        self._bus: can.BusABC | None = None

    def __enter__(self) -> "ServiceUnderTest":
        self._thread.start()
        if not self.service.reader.opened.wait(10.0):
            raise RuntimeError("the service did not open its bus")
        self._bus = can.Bus(
            interface="virtual", channel=self.config.bus.channel, preserve_timestamps=True
        )
        return self

    def __exit__(self, *exc_info: object) -> None:
        self._stop.set()
        self._thread.join()
        if self._bus is not None:
            self._bus.shutdown()

    def send(self, message: can.Message) -> float:
        """Put ``message`` on the bus now; its time stamp."""
        assert self._bus is not None
        message.timestamp = stamp = time.time()
        self._bus.send(message)
        return stamp

    def processed(self) -> int:
        return self.service.pipeline.frames

    def queued(self) -> int:
        """The longest of the publisher's and the recorder's queues."""
        return max(self.service.publisher.depth, self.recorder.depth)

    def wait_processed(self, count: int, timeout_s: float) -> float:
        """time.time() once ``count`` frames are processed and published/recorded."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self.processed() >= count and self.queued() == 0:
                break
            time.sleep(0.001)
        return time.time()

    def processes(self) -> dict[int, str]:
        """The recorder's process, if it has one."""
        recorder = self.recorder
        if isinstance(recorder, RecorderProcess) and recorder.pid is not None:
            return {recorder.pid: "recorder-process"}
        return {}

    def counters(self) -> dict[str, Any]:
        service = self.service
        status = service.status()
        return {
            "frames_processed": status["frames"]["processed"],
            "bad": status["bad"],
            "dropped": status["dropped"],
            "published": service.publisher.published,
            "recording_errors": self.recorder.errors,
        }

    def recording(self) -> dict[str, Any]:
        """Files written, their size, messages per kind of topic (from the MCAP
        summaries), the raw frames and the leg estimates in them (call after the service
        closed: the files are finished then)."""
        paths = sorted(self.recorder.directory.glob("*.mcap"))
        messages: Counter[str] = Counter()
        frames = estimates = 0
        for path in paths:
            with open(path, "rb") as file:
                reader = make_reader(file)
                summary = reader.get_summary()
                if summary is None or summary.statistics is None:
                    continue
                for channel_id, count in summary.statistics.channel_message_counts.items():
                    topic = summary.channels[channel_id].topic
                    messages[topic.split("/")[1]] += count  # can, signals, leg, daq
                for _, channel, message in reader.iter_messages():
                    if channel.topic == RAW_TOPIC:
                        frames += sum(
                            1 for _ in recorded_frames(channel.message_encoding, message.data)
                        )
                    elif channel.topic.startswith("/leg/"):
                        estimates += len(json_items(message.data))
        return {
            "files": len(paths),
            "bytes": sum(path.stat().st_size for path in paths),
            "messages": dict(messages),
            "raw_frames": frames,
            "leg_estimates": estimates,
        }


class NaiveBaseline:
    """Notifier + ``decode_message`` + eq. (4) inline + one ``put(json.dumps(...))`` per leg."""

    def __init__(
        self,
        machine: MachineConfig,
        database: Database,
        session: zenoh.Session,
        prefix: str = "bench/baseline",
    ) -> None:
        self._database = database
        self._session = session
        self._channel = f"bench-{uuid.uuid4().hex}"
        # frame ID -> legs it carries: (name, piston signal, rod signal, geometry)
        self._legs: dict[int, list[tuple[str, str, str, Any]]] = {}
        for leg in machine.legs.values():
            frame_id = database.get_message_by_name(leg.message).frame_id
            self._legs.setdefault(frame_id, []).append(
                (leg.name, leg.piston.signal, leg.rod.signal, leg.geometry)
            )
        self._prefix = prefix
        self._processed = 0
        self._rx: can.BusABC | None = None
        self._tx: can.BusABC | None = None
        self._notifier: can.Notifier | None = None

    def __enter__(self) -> "NaiveBaseline":
        self._rx = can.Bus(interface="virtual", channel=self._channel)
        self._tx = can.Bus(interface="virtual", channel=self._channel, preserve_timestamps=True)
        self._notifier = can.Notifier(self._rx, [self.on_message_received])
        return self

    def __exit__(self, *exc_info: object) -> None:
        if self._notifier is not None:
            self._notifier.stop()
        for bus in (self._tx, self._rx):
            if bus is not None:
                bus.shutdown()

    def on_message_received(self, message: can.Message) -> None:
        signals = self._database.decode_message(message.arbitration_id, message.data)
        for name, piston, rod, leg in self._legs.get(message.arbitration_id, ()):
            p_piston_Pa, p_rod_Pa = signals[piston], signals[rod]
            force_N = (
                p_piston_Pa * leg.A_piston_m2 - p_rod_Pa * leg.A_rod_m2
            ) * leg.force_ratio + leg.weight_term_N
            sample = {
                "leg": name,
                "t": message.timestamp,
                "p_piston_Pa": p_piston_Pa,
                "p_rod_Pa": p_rod_Pa,
                "force_N": force_N,
                "pressure_Pa": force_N / leg.A_foot_m2,
            }
            self._session.put(f"{self._prefix}/leg/{name}", json.dumps(sample))
        self._processed += 1

    def send(self, message: can.Message) -> float:
        """Put ``message`` on the bus now; its time stamp."""
        assert self._tx is not None
        message.timestamp = stamp = time.time()
        self._tx.send(message)
        return stamp

    def processed(self) -> int:
        return self._processed

    def queued(self) -> int:
        return 0

    def wait_processed(self, count: int, timeout_s: float) -> float:
        deadline = time.monotonic() + timeout_s
        while self._processed < count and time.monotonic() < deadline:
            time.sleep(0.001)
        return time.time()

    def counters(self) -> dict[str, Any]:
        return {"frames_processed": self._processed}

    def processes(self) -> dict[int, str]:
        return {}
