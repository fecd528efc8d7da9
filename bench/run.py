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
4. Systems, all running at once and taking turns (:func:`bench.measure.run_systems`):
   a warm-up, five rounds as fast as taken (each system's fastest counts), a paced
   measurement, the paced one again while a CPU hog spins on the other CPU (at
   ``SCHED_IDLE``: see :class:`bench.cpu.CpuHog`), and one at the DBC's nominal rate;
   the CPU time of the systems not measured (their Python threads, idle meanwhile) is
   left out. The systems: the service as configured by default (``pipeline``, as
   deployed: one thread receives, processes and publishes, raw frames recorded in
   batches by the recorder's process, whose CPU counts too, signals published at most
   10 Hz per message and not recorded, the CLI's interpreter settings of
   :mod:`daq.interpreter`); with reader and publisher in threads of their own
   (``pipeline_threads``: ``[service] event_loop = false``); with every frame's signals
   recorded and published (``pipeline_tuned``, the earlier defaults: ``[recording]
   signals = true``, ``[publish] signals_max_rate_hz = 0``); with wake-ups coalesced
   (``pipeline_coalesced``: ``[service] poll_period_ms = 20``, the embedded PC's setting
   for a low CPU at the DBC's rate); and the naive baseline
   (:class:`~bench.targets.NaiveBaseline`).
"""

import argparse
import gc
import json
import logging
import os
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Sequence
from contextlib import ExitStack, nullcontext
from pathlib import Path
from typing import Any

from bench.frames import EXAMPLE_CONFIG, simulated_frames
from bench.machine import free_port, machine_info, pin_to_one_cpu, unpin, wakeup_cpu_us
from bench.measure import Plan, System, entered, run_systems
from bench.probe import ProbeProcess
from bench.report import markdown_table, targets_met
from bench.subscriber import peer_config
from bench.targets import NaiveBaseline, ServiceUnderTest, service_config
from daq.interpreter import tuned_interpreter
from dbc.machine import load_machine_config

RESULTS = Path(__file__).resolve().parent / "results.json"
#: The frame rate of a saturated 1 Mbit/s bus: an 8-byte standard frame is up to
#: ~111 bits with stuff bits and the inter-frame space, i.e. ~111 us.
SATURATED_RATE_HZ = 9000.0
#: The variants for comparison: four threads instead of the event loop; the earlier
#: defaults, every frame's signals recorded and published; and wake-ups coalesced
#: (frames held up to 20 ms: less CPU at low rates, that much more latency).
COMPARED = {
    "pipeline_threads": {"service": "event_loop = false"},
    "pipeline_tuned": {"recording": "signals = true", "publish": "signals_max_rate_hz = 0"},
    "pipeline_coalesced": {"service": "poll_period_ms = 20"},
}
#: Seconds of frames at the DBC's nominal rate.
NOMINAL_S = 5.0
PIPELINE_PREFIX = "bench/{name}"
BASELINE_PREFIX = "bench/baseline"


def run_benchmark(
    *,
    throughput_frames: int = 30_000,
    rounds: int = 5,
    paced_s: float = 10.0,
    nominal_s: float = NOMINAL_S,
    rate_hz: float = SATURATED_RATE_HZ,
    warmup: int = 2_000,
    window: int = 1_000,
    pin: bool = True,
    tuned: bool = True,
    rtol: float = 1e-3,
) -> dict[str, Any]:
    """Run every system; returns the results (the content of ``bench/results.json``).

    ``pin=False`` leaves the CPU affinity alone (e.g. in tests); ``tuned=False`` leaves
    out the tuned variant of the service.
    """
    paced_frames = max(1, round(paced_s * rate_hz))
    nominal_hz = nominal_rate_hz()
    nominal_frames = max(1, round(nominal_s * nominal_hz))
    allowed = os.sched_getaffinity(0)
    cpu, probe_cpu = pin_to_one_cpu() if pin else (None, None)
    hog_cpu = probe_cpu if pin else next(iter(allowed))
    started = time.monotonic()
    try:
        wakeup_us = wakeup_cpu_us()  # on the systems' CPU, before any of them runs
        plan = Plan(
            warmup,
            throughput_frames,
            paced_frames,
            rate_hz,
            window,
            hog_cpu=hog_cpu,
            nominal_frames=nominal_frames,
            nominal_rate_hz=nominal_hz,
            rounds=rounds,
        )
        frames = simulated_frames(plan.frames, rtol=rtol)
        generated_s = time.monotonic() - started
        gc.collect()
        gc.freeze()  # the frames are the benchmark's, not the service's garbage
        try:
            results = _run_systems(frames, plan, probe_cpu=probe_cpu, tuned=tuned)
        finally:
            gc.unfreeze()
    finally:
        if pin:
            unpin(allowed)
    baseline = results["baseline"]["throughput"]
    ratios = {
        name: round(results[name]["throughput"]["frames_per_s"] / baseline["frames_per_s"], 2)
        for name in ("pipeline", *COMPARED)
        if name in results
    }
    cpu_ratios = {
        name: round(
            results[name]["throughput"]["cpu_us_per_frame"]["total"]
            / baseline["cpu_us_per_frame"]["total"],
            2,
        )
        for name in ratios
    }
    return {
        "machine": {**machine_info(), "wakeup_cpu_us": wakeup_us},
        "setup": {
            "pinned_cpu": cpu,
            "probe_cpu": probe_cpu,
            "rate_hz": rate_hz,
            "nominal_rate_hz": nominal_hz,
            "hog_cpu": hog_cpu,
            "window": window,
            "throughput_rounds": rounds,
            "frames_generated": len(frames),
            "generation_s": round(generated_s, 2),
            "frame_mix": results.pop("frame_mix"),
            "zenoh": "peer, tcp/127.0.0.1:<free port>, multicast scouting off",
        },
        **results,
        "ratio_frames_per_s": ratios["pipeline"],
        "ratio_cpu_per_frame": cpu_ratios["pipeline"],
        "targets": targets_met(results["pipeline"], results["baseline"], rate_hz),
        **{
            key: value
            for name in COMPARED
            if name in results
            for key, value in (
                (f"ratio_frames_per_s{name[8:]}", ratios[name]),
                (f"ratio_cpu_per_frame{name[8:]}", cpu_ratios[name]),
                (f"targets{name[8:]}", targets_met(results[name], results["baseline"], rate_hz)),
            )
        },
        "wall_s": round(time.monotonic() - started, 1),
    }


def _run_systems(
    frames: Sequence[Any],
    plan: Plan,
    *,
    probe_cpu: int | None,
    tuned: bool,
) -> dict[str, Any]:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    # As deployed: the config's defaults and the CLI's interpreter settings; the baseline
    # as Python starts.
    variants: list[tuple[str, dict[str, str]]] = [("pipeline", {})]
    if tuned:
        variants += COMPARED.items()
    with tempfile.TemporaryDirectory(prefix="portal-bench-") as tmp, ExitStack() as stack:
        import zenoh  # only now: its runtime threads inherit the CPU mask

        session = stack.enter_context(zenoh.open(peer_config(listen=endpoint)))
        probe = stack.enter_context(ProbeProcess(session, endpoint, probe_cpu))
        services: dict[str, ServiceUnderTest] = {}
        systems: dict[str, System] = {}
        for name, tables in variants:
            workdir = Path(tmp) / name
            workdir.mkdir()
            config = service_config(workdir, PIPELINE_PREFIX.format(name=name), tables)
            services[name] = ServiceUnderTest(config, session)
            systems[name] = entered(stack, services[name], tuned_interpreter)
        baseline = NaiveBaseline(config.machine, config.database, session, BASELINE_PREFIX)
        systems["baseline"] = entered(stack, baseline, nullcontext)
        leg_ids = {
            config.database.get_message_by_name(leg.message).frame_id
            for leg in config.machine.legs.values()
        }
        results: dict[str, Any] = run_systems(systems, probe, frames, leg_ids, plan)
        stack.close()  # the services finish their files
        for name, tables in variants:
            results[name]["settings"] = tables
            results[name]["recording"] = services[name].recording()
    names = {message.frame_id: message.name for message in config.database.messages}
    results["frame_mix"] = dict(Counter(names[frame.arbitration_id] for frame in frames))
    return results


def nominal_rate_hz() -> float:
    """Frames per second of the example's periodic messages (their cycle times)."""
    config, _ = load_machine_config(EXAMPLE_CONFIG)
    return sum(1000.0 / cycle_time_ms for cycle_time_ms in config.cycle_times_ms.values())


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--throughput-frames", type=int, default=30_000)
    parser.add_argument(
        "--rounds", type=int, default=5, help="rounds as fast as taken, systems taking turns"
    )
    parser.add_argument("--paced-s", type=float, default=10.0, help="seconds of paced frames")
    parser.add_argument(
        "--nominal-s", type=float, default=NOMINAL_S, help="seconds at the DBC's rate"
    )
    parser.add_argument("--rate", type=float, default=SATURATED_RATE_HZ, help="paced frames/s")
    parser.add_argument("--warmup", type=int, default=2_000, help="frames before measuring")
    parser.add_argument("--window", type=int, default=1_000, help="backlog limit, frames")
    parser.add_argument("--no-pin", action="store_true", help="do not pin to one CPU")
    parser.add_argument(
        "--no-tuned", action="store_true", help="leave out the variants compared with"
    )
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    # The services idle while another system is measured, and say so ("not healthy: no
    # frame for 1.0 s"): true, and not what the benchmark reports.
    service_log = logging.getLogger("daq")
    level = service_log.level
    service_log.setLevel(logging.ERROR)
    try:
        results = run_benchmark(
            throughput_frames=args.throughput_frames,
            rounds=args.rounds,
            paced_s=args.paced_s,
            nominal_s=args.nominal_s,
            rate_hz=args.rate,
            warmup=args.warmup,
            window=args.window,
            pin=not args.no_pin,
            tuned=not args.no_tuned,
        )
    finally:
        service_log.setLevel(level)
    args.out.write_text(json.dumps(results, indent=2) + "\n")
    print(markdown_table(results))
    busy = [
        f"{system} {mode}: {result['other_processes_cpu_pct']}%"
        for system in ("pipeline", *COMPARED, "baseline")
        if system in results
        for mode, result in ((m, results[system][m]) for m in ("throughput", "paced", "nominal"))
        if result["elapsed_s"] >= 1.0 and result["other_processes_cpu_pct"] > 5
    ]
    if busy:
        warning = f"warning: other processes were busy meanwhile (% of a CPU): {', '.join(busy)}"
        print(f"\n{warning}", file=sys.stderr)
    print(f"\nwrote {args.out} ({results['wall_s']} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
