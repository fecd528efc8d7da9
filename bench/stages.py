"""Per-frame cost of each stage of the service's hot path, single-threaded, no I/O.

Run: ``.venv/bin/python -m bench.stages [--frames N]``. Prints microseconds per frame
(best of three) for:

- ``decode``: :meth:`FrameDecoder.decode` (DBC decoding, CRC and counter check);
- ``process``: :meth:`Pipeline.process` (decode, leg samples, estimator);
- ``consumer``: :meth:`Consumer.handle` with a publisher and recorder that only
  queue (process + the payloads handed on);
- ``publish_json``: serialising what the consumer hands the publisher;
- ``record``: :meth:`McapFile.write_result` into memory (JSON, MCAP, zstd).

The threads, queues, Zenoh and the disk are left out: ``bench/run.py`` measures
those end to end. This is for measuring a change to one stage, before and after.
"""

import argparse
import io
import time
from collections.abc import Callable, Sequence
from typing import Any

from bench.frames import EXAMPLE_CONFIG, simulated_frames
from daq.consumer import Consumer
from daq.frames import RawFrame
from daq.mcap_file import McapFile
from daq.payloads import JsonObject, json_bytes
from daq.pipeline import FrameResult, Pipeline
from daq.service_config import PublishSettings
from dbc.decoding import FrameDecoder
from dbc.machine import load_machine_config


class _Collect:
    def __init__(self) -> None:
        self.items: list[Any] = []

    def submit(self, *item: Any) -> None:
        self.items.append(item)


def best_us_per_frame(action: Callable[[], object], frames: int, repeat: int = 3) -> float:
    """Best wall time of ``repeat`` runs of ``action``, per frame, in microseconds."""
    best_s = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        action()
        best_s = min(best_s, time.perf_counter() - start)
    return round(best_s / frames * 1e6, 2)


def stage_costs(raw: Sequence[RawFrame]) -> dict[str, float]:
    config, database = load_machine_config(EXAMPLE_CONFIG)
    n = len(raw)

    def decode() -> None:
        decoder = FrameDecoder(database, config.protection)
        for frame in raw:
            decoder.decode(frame.arbitration_id, frame.data, frame.t_s, frame.is_extended_id)

    def process() -> list[FrameResult]:
        pipeline = Pipeline.from_config(config, database)
        return [pipeline.process(frame) for frame in raw]

    published = _Collect()

    def consume() -> None:
        published.items.clear()
        consumer = Consumer(
            Pipeline.from_config(config, database),
            None,  # type: ignore[arg-type]  # handle() only, no thread
            PublishSettings(),
            publisher=published,
            recorder=_Collect(),
        )
        for frame in raw:
            consumer.handle(frame)

    results = process()

    def publish_json() -> None:
        for _, payload in published.items:
            payload_bytes(payload)

    def record() -> None:
        with McapFile(io.BytesIO(), database) as mcap:
            mcap.start()
            for result in results:
                mcap.write_result(result)

    costs = {
        "decode": best_us_per_frame(decode, n),
        "process": best_us_per_frame(process, n),
        "consumer": best_us_per_frame(consume, n),
    }
    costs["publish_json"] = best_us_per_frame(publish_json, n)
    costs["record"] = best_us_per_frame(record, n)
    return costs


def payload_bytes(payload: JsonObject | bytes) -> bytes:
    return payload if isinstance(payload, bytes) else json_bytes(payload)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=20_000)
    args = parser.parse_args(argv)
    raw = [
        RawFrame(1.7e9 + i / 9000, m.arbitration_id, m.is_extended_id, bytes(m.data))
        for i, m in enumerate(simulated_frames(args.frames))
    ]
    for stage, us in stage_costs(raw).items():
        print(f"{stage:>13}: {us:6.2f} us/frame")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
