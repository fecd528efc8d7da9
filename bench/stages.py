"""Per-frame cost of each stage of the service's hot path, single-threaded, no I/O.

Run: ``.venv/bin/python -m bench.stages [--frames N] [--batch N]``. Prints microseconds
per frame (best of three) for:

- ``decode``: :meth:`FrameDecoder.decode` (DBC decoding, CRC and counter check);
- ``process``: :meth:`Pipeline.process` (decode, leg samples, estimator);
- ``consumer``: :meth:`Consumer.handle_batch` on batches of ``--batch`` frames, with a
  publisher and recorder that only queue (process, estimates encoded once, signals at
  the default rate limit);
- ``publish_json``: serialising what the consumer hands the publisher;
- ``record``: :meth:`McapFile.write_batch` of the consumer's batches into memory
  (binary ``/can/raw`` batch, estimates, MCAP, zstd);
- ``record_signals``: the same with ``[recording] signals = true``;
- ``record_raw``: only the ``/can/raw`` batches (no estimates);
- ``record_ros2``: the alternative measured for ``/can/raw``: one ROS 2
  ``can_msgs/msg/Frame`` message (CDR) per frame instead of the batches.

The threads, queues, Zenoh and the disk are left out: ``bench/run.py`` measures
those end to end. Run with the service's interpreter settings
(:func:`daq.interpreter.tuned_interpreter`). This is for measuring a change to one
stage, before and after.
"""

import argparse
import io
import struct
import time
from collections.abc import Callable, Sequence
from typing import Any

from mcap.writer import Writer

from bench.frames import EXAMPLE_CONFIG, simulated_frames
from daq.consumer import Consumer
from daq.frames import RawFrame
from daq.interpreter import tuned_interpreter
from daq.mcap_file import McapFile, RecordBatch
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

    def submit_batch(self, items: Sequence[Any]) -> None:
        self.items += items


#: ROS 2 ``can_msgs/msg/Frame`` in CDR (little endian): encapsulation header, then
#: ``std_msgs/Header`` (int32 sec, uint32 nanosec, string frame_id), uint32 id,
#: bool is_rtr, is_extended, is_error, uint8 dlc, uint8[8] data.
_ROS2_FRAME = struct.Struct("<4siiI5sxxxIBBBB8s")
ROS2_FRAME_MSG = """\
std_msgs/Header header
uint32 id
bool is_rtr
bool is_extended
bool is_error
uint8 dlc
uint8[8] data
"""


def ros2_frame_cdr(frame: RawFrame) -> bytes:
    t_ns = round(frame.t_s * 1e9)
    return _ROS2_FRAME.pack(
        b"\x00\x01\x00\x00",
        t_ns // 1_000_000_000,
        t_ns % 1_000_000_000,
        5,
        b"can0\x00",
        frame.arbitration_id,
        frame.is_remote_frame,
        frame.is_extended_id,
        frame.is_error_frame,
        len(frame.data),
        frame.data.ljust(8, b"\x00"),
    )


def best_us_per_frame(action: Callable[[], object], frames: int, repeat: int = 3) -> float:
    """Best wall time of ``repeat`` runs of ``action``, per frame, in microseconds."""
    best_s = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        action()
        best_s = min(best_s, time.perf_counter() - start)
    return round(best_s / frames * 1e6, 2)


def stage_costs(raw: Sequence[RawFrame], batch: int = 100) -> dict[str, float]:
    config, database = load_machine_config(EXAMPLE_CONFIG)
    n = len(raw)
    batches = [raw[at : at + batch] for at in range(0, n, batch)]

    def decode() -> None:
        decoder = FrameDecoder(database, config.protection)
        for frame in raw:
            decoder.decode(frame.arbitration_id, frame.data, frame.t_s, frame.is_extended_id)

    def process() -> list[FrameResult]:
        pipeline = Pipeline.from_config(config, database)
        return [pipeline.process(frame) for frame in raw]

    published, recorded = _Collect(), _Collect()

    def consume() -> None:
        published.items.clear()
        recorded.items.clear()
        consumer = Consumer(
            Pipeline.from_config(config, database),
            None,  # type: ignore[arg-type]  # handle_batch() only, no thread
            PublishSettings(),
            publisher=published,
            recorder=recorded,
        )
        for items in batches:
            consumer.handle_batch(items)

    results = process()
    result_batches = [results[at : at + batch] for at in range(0, n, batch)]

    def publish_json() -> None:
        for _, payload in published.items:
            payload_bytes(payload)

    def record(signals: bool = False) -> None:
        with McapFile(io.BytesIO(), database) as mcap:
            mcap.start()
            for chunk in result_batches:
                mcap.write_batch(RecordBatch.of(chunk, signals=signals))

    def record_raw() -> None:
        with McapFile(io.BytesIO(), database) as mcap:
            mcap.start()
            for frames in batches:
                mcap.write_batch(RecordBatch(frames, []))

    def record_ros2() -> None:
        with io.BytesIO() as stream:
            writer = Writer(stream, chunk_size=128 * 1024)
            writer.start(profile="ros2", library="bench")
            schema = writer.register_schema(
                name="can_msgs/msg/Frame", encoding="ros2msg", data=ROS2_FRAME_MSG.encode()
            )
            channel = writer.register_channel("/can/raw", "cdr", schema)
            for frame in raw:
                t_ns = round(frame.t_s * 1e9)
                writer.add_message(channel, t_ns, ros2_frame_cdr(frame), t_ns)
            writer.finish()  # type: ignore[no-untyped-call]

    costs = {
        "decode": best_us_per_frame(decode, n),
        "process": best_us_per_frame(process, n),
        "consumer": best_us_per_frame(consume, n),
    }
    costs["publish_json"] = best_us_per_frame(publish_json, n)
    costs["record"] = best_us_per_frame(record, n)
    costs["record_signals"] = best_us_per_frame(lambda: record(signals=True), n)
    costs["record_raw"] = best_us_per_frame(record_raw, n)
    costs["record_ros2"] = best_us_per_frame(record_ros2, n)
    return costs


def payload_bytes(payload: JsonObject | bytes) -> bytes:
    return payload if isinstance(payload, bytes) else json_bytes(payload)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=20_000)
    parser.add_argument("--batch", type=int, default=100, help="frames per consumer batch")
    args = parser.parse_args(argv)
    raw = [
        RawFrame(1.7e9 + i / 9000, m.arbitration_id, m.is_extended_id, bytes(m.data))
        for i, m in enumerate(simulated_frames(args.frames))
    ]
    with tuned_interpreter():  # as the service runs (the collector's thresholds matter)
        costs = stage_costs(raw, args.batch)
    for stage, us in costs.items():
        print(f"{stage:>13}: {us:6.2f} us/frame")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
