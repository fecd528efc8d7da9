"""Benchmark: the service's pipeline against a naive baseline, frames/s and latency.

Run: ``.venv/bin/python -m bench.run`` (under a minute; ``--help`` for the knobs).
Writes ``bench/results.json`` and prints a markdown table.

1. Frames are simulated once, before anything is timed (:mod:`bench.frames`), and
   frozen out of the garbage collector's reach (``gc.freeze``).
2. This process is pinned to one CPU (``os.sched_setaffinity``) before any thread
   or Zenoh session exists: the sender, the service's threads (reader, consumer,
   publisher, recorder, main loop) and Zenoh's runtime all share that one core.
   The latency probe (:mod:`bench.subscriber`) runs in another process on another
   CPU.
3. One Zenoh session (peer, ``tcp/127.0.0.1:<free port>``, multicast scouting off)
   carries what the service and the baseline publish; the probe connects to it.
4. Systems, one after the other, each with a warm-up, a throughput and a paced
   measurement (:mod:`bench.measure`): the service as configured by default
   (``pipeline``, as deployed: 128 KiB MCAP chunks, 1 ms GIL switch interval); with the
   earlier defaults (``pipeline_tuned``: 1 MiB chunks, CPython's 5 ms interval); and
   the naive baseline (:class:`~bench.targets.NaiveBaseline`).
"""

import argparse
import gc
import json
import os
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from bench.frames import simulated_frames
from bench.machine import free_port, machine_info, pin_to_one_cpu, unpin
from bench.measure import Plan, run_system
from bench.probe import ProbeProcess
from bench.report import markdown_table, targets_met
from bench.subscriber import peer_config
from bench.targets import FEEDS, NaiveBaseline, ServiceUnderTest, service_config
from daq.run_command import GIL_SWITCH_INTERVAL_S

RESULTS = Path(__file__).resolve().parent / "results.json"
#: The frame rate of a saturated 1 Mbit/s bus: an 8-byte standard frame is up to
#: ~111 bits with stuff bits and the inter-frame space, i.e. ~111 us.
SATURATED_RATE_HZ = 9000.0
#: The variant with the earlier defaults, for comparison: 1 MiB MCAP chunks and
#: CPython's 5 ms GIL switch interval.
TUNED_CHUNK_SIZE = 1024 * 1024
TUNED_SWITCH_INTERVAL_S = 0.005
PIPELINE_PREFIX = "bench/pipeline"
BASELINE_PREFIX = "bench/baseline"
FEED_DESCRIPTIONS = {
    "bus": "python-can virtual bus and the service's reader thread",
    "queue": "service's reader queue (RawFrames put there directly; virtual bus bypassed)",
}


def run_benchmark(
    *,
    throughput_frames: int = 30_000,
    baseline_throughput_frames: int | None = None,
    paced_s: float = 10.0,
    rate_hz: float = SATURATED_RATE_HZ,
    warmup: int = 2_000,
    window: int = 1_000,
    feed: str = "bus",
    pin: bool = True,
    tuned: bool = True,
    rtol: float = 1e-3,
) -> dict[str, Any]:
    """Run every system; returns the results (the content of ``bench/results.json``).

    ``pin=False`` leaves the CPU affinity alone (e.g. in tests); ``tuned=False`` leaves
    out the tuned variant of the service.
    """
    baseline_throughput_frames = baseline_throughput_frames or throughput_frames
    paced_frames = max(1, round(paced_s * rate_hz))
    allowed = os.sched_getaffinity(0)
    cpu, probe_cpu = pin_to_one_cpu() if pin else (None, None)
    started = time.monotonic()
    try:
        count = warmup + max(throughput_frames, baseline_throughput_frames) + paced_frames
        frames = simulated_frames(count, rtol=rtol)
        generated_s = time.monotonic() - started
        gc.collect()
        gc.freeze()  # the frames are the benchmark's, not the service's garbage
        try:
            results = _run_systems(
                frames,
                Plan(warmup, throughput_frames, paced_frames, rate_hz, window),
                baseline_throughput_frames=baseline_throughput_frames,
                feed=feed,
                probe_cpu=probe_cpu,
                tuned=tuned,
            )
        finally:
            gc.unfreeze()
    finally:
        if pin:
            unpin(allowed)
    baseline_fps = results["baseline"]["throughput"]["frames_per_s"]
    ratios = {
        name: round(results[name]["throughput"]["frames_per_s"] / baseline_fps, 2)
        for name in ("pipeline", "pipeline_tuned")
        if name in results
    }
    return {
        "machine": machine_info(),
        "setup": {
            "feed": feed,
            "feed_description": FEED_DESCRIPTIONS[feed],
            "pinned_cpu": cpu,
            "probe_cpu": probe_cpu,
            "rate_hz": rate_hz,
            "window": window,
            "frames_generated": len(frames),
            "generation_s": round(generated_s, 2),
            "frame_mix": results.pop("frame_mix"),
            "zenoh": "peer, tcp/127.0.0.1:<free port>, multicast scouting off",
        },
        **results,
        "ratio_frames_per_s": ratios["pipeline"],
        "targets": targets_met(results["pipeline"], ratios["pipeline"], rate_hz),
        **(
            {
                "ratio_frames_per_s_tuned": ratios["pipeline_tuned"],
                "targets_tuned": targets_met(
                    results["pipeline_tuned"], ratios["pipeline_tuned"], rate_hz
                ),
            }
            if "pipeline_tuned" in results
            else {}
        ),
        "wall_s": round(time.monotonic() - started, 1),
    }


def _run_systems(
    frames: Sequence[Any],
    plan: Plan,
    *,
    baseline_throughput_frames: int,
    feed: str,
    probe_cpu: int | None,
    tuned: bool,
) -> dict[str, Any]:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    default_switch_s = sys.getswitchinterval()
    # As deployed: the config's default chunk size and the CLI's GIL switch interval.
    variants: list[tuple[str, int | None, float]] = [("pipeline", None, GIL_SWITCH_INTERVAL_S)]
    if tuned:
        variants.append(("pipeline_tuned", TUNED_CHUNK_SIZE, TUNED_SWITCH_INTERVAL_S))
    results: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix="portal-bench-") as tmp:
        import zenoh  # only now: its runtime threads inherit the CPU mask

        with (
            zenoh.open(peer_config(listen=endpoint)) as session,
            ProbeProcess(session, endpoint, probe_cpu) as probe,
        ):
            for name, chunk_size, switch_interval_s in variants:
                workdir = Path(tmp) / name
                workdir.mkdir()
                config = service_config(workdir, PIPELINE_PREFIX, chunk_size)
                leg_ids = {
                    config.database.get_message_by_name(leg.message).frame_id
                    for leg in config.machine.legs.values()
                }
                service = ServiceUnderTest(config, session, feed)
                sys.setswitchinterval(switch_interval_s)
                try:
                    with service:
                        result = run_system(service, probe, frames, leg_ids, plan)
                finally:
                    sys.setswitchinterval(default_switch_s)
                result["chunk_size"] = config.recording.chunk_size
                result["switch_interval_s"] = switch_interval_s
                result["recording"] = service.recording()
                results[name] = result
            with NaiveBaseline(
                config.machine, config.database, session, BASELINE_PREFIX
            ) as baseline:
                results["baseline"] = run_system(
                    baseline,
                    probe,
                    frames,
                    leg_ids,
                    replace(plan, throughput_frames=baseline_throughput_frames),
                )
    names = {message.frame_id: message.name for message in config.database.messages}
    results["frame_mix"] = dict(Counter(names[frame.arbitration_id] for frame in frames))
    return results


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--throughput-frames", type=int, default=30_000)
    parser.add_argument("--baseline-throughput-frames", type=int, default=None)
    parser.add_argument("--paced-s", type=float, default=10.0, help="seconds of paced frames")
    parser.add_argument("--rate", type=float, default=SATURATED_RATE_HZ, help="paced frames/s")
    parser.add_argument("--warmup", type=int, default=2_000, help="frames before measuring")
    parser.add_argument("--window", type=int, default=1_000, help="backlog limit, frames")
    parser.add_argument(
        "--feed",
        choices=FEEDS,
        default="bus",
        help="how the service gets its frames (the baseline always has its virtual bus)",
    )
    parser.add_argument("--no-pin", action="store_true", help="do not pin to one CPU")
    parser.add_argument("--no-tuned", action="store_true", help="leave out the tuned variant")
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    results = run_benchmark(
        throughput_frames=args.throughput_frames,
        baseline_throughput_frames=args.baseline_throughput_frames,
        paced_s=args.paced_s,
        rate_hz=args.rate,
        warmup=args.warmup,
        window=args.window,
        feed=args.feed,
        pin=not args.no_pin,
        tuned=not args.no_tuned,
    )
    args.out.write_text(json.dumps(results, indent=2) + "\n")
    print(markdown_table(results))
    busy = [
        f"{system} {mode}: {result['other_processes_cpu_pct']}%"
        for system in ("pipeline", "pipeline_tuned", "baseline")
        if system in results
        for mode, result in ((mode, results[system][mode]) for mode in ("throughput", "paced"))
        if result["elapsed_s"] >= 1.0 and result["other_processes_cpu_pct"] > 5
    ]
    if busy:
        warning = f"warning: other processes were busy meanwhile (% of a CPU): {', '.join(busy)}"
        print(f"\n{warning}", file=sys.stderr)
    print(f"\nwrote {args.out} ({results['wall_s']} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
