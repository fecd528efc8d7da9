"""Benchmark: the campaign report's time for N recordings, local processes vs one process.

Run: ``.venv/bin/python -m bench.campaign [--recordings 8] [--seconds 20]``. Writes
``bench/campaign_results.json`` and prints a markdown table.

The recordings are made before anything is timed: the simulator's frames
(:mod:`bench.frames`) through the service's :class:`~daq.pipeline.Pipeline` into
MCAP files, the config and DBC attached, exactly as the service records them
(``--seconds`` of one machine each). Then the rows of all of them
(:func:`daq.report.campaign_run.campaign`) are computed three ways, each timed from
the call to the last row: in this one process (``--workers 1``); on local processes,
one per CPU (the default of ``portal-daq report --campaign``, process start-up
included); and, when Dask distributed is installed, on a ``LocalCluster`` with one
worker process per CPU (the cluster started before the clock). The figure of merit is
the ratio of each to the one-process time in the same run; the rows are checked equal.
"""

import argparse
import json
import os
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from bench.frames import EXAMPLE_CONFIG, simulated_frames
from bench.machine import machine_info
from daq.frames import RawFrame
from daq.mcap_file import CONFIG_ATTACHMENT, DBC_ATTACHMENT, McapFile
from daq.pipeline import Pipeline
from daq.recording_run import runs
from daq.report.campaign import CampaignRow
from daq.report.campaign_run import campaign
from dbc.machine import load_machine_config

RESULTS = Path(__file__).resolve().parent / "campaign_results.json"
#: The bridge sends 101 frames per 100 ms.
FRAMES_PER_S = 1010
T0_S = 1_750_000_000.0


def make_recordings(folder: Path, count: int, seconds: float) -> list[Path]:
    """``count`` recordings of ``seconds`` each, one hour apart (each its own run)."""
    config, database = load_machine_config(EXAMPLE_CONFIG)
    frames = simulated_frames(round(seconds * FRAMES_PER_S))
    attachments = {
        CONFIG_ATTACHMENT: EXAMPLE_CONFIG.read_bytes(),
        DBC_ATTACHMENT: config.dbc_path.read_bytes(),
    }
    paths = []
    for index in range(count):
        t0_s = T0_S + 3600.0 * index
        path = folder / f"bench-{index:03d}.mcap"
        pipeline = Pipeline.from_config(config, database)
        with open(path, "wb") as stream, McapFile(stream, database) as mcap:
            mcap.start(attachments, t0_s)
            for k, frame in enumerate(frames):
                t_s = t0_s + k / FRAMES_PER_S
                raw = RawFrame(t_s, frame.arbitration_id, frame.is_extended_id, bytes(frame.data))
                mcap.write_result(pipeline.process(raw))
        paths.append(path)
    return paths


def timed(work: Any) -> tuple[float, list[CampaignRow]]:
    start = time.perf_counter()
    rows = work()
    return time.perf_counter() - start, rows


def run_benchmark(recordings: int, seconds: float, *, dask: bool = True) -> dict[str, Any]:
    workers = os.cpu_count() or 1
    with tempfile.TemporaryDirectory(prefix="portal-campaign-") as folder:
        paths = make_recordings(Path(folder), recordings, seconds)
        found = runs(paths)
        size = sum(p.stat().st_size for p in paths)
        one_s, one = timed(lambda: campaign(found, workers=1))
        local_s, local = timed(lambda: campaign(found, workers=workers))
        results: dict[str, Any] = {
            "machine": machine_info(),
            "recordings": recordings,
            "seconds_each": seconds,
            "megabytes": size / 1e6,
            "rows": len(one),
            "workers": workers,
            "one_process_s": one_s,
            "local_processes_s": local_s,
            "local_speedup": one_s / local_s,
            "rows_equal": same(local, one),
        }
        if dask:
            results |= _dask(found, workers, one_s, one)
        return results


def _dask(found: Any, workers: int, one_s: float, one: list[CampaignRow]) -> dict[str, Any]:
    try:
        from distributed import LocalCluster
    except ImportError:
        return {}
    with LocalCluster(
        n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        dask_s, rows = timed(lambda: campaign(found, cluster=cluster.scheduler_address))
    return {
        "dask_local_cluster_s": dask_s,
        "dask_speedup": one_s / dask_s,
        "dask_rows_equal": same(rows, one),
    }


def same(a: list[CampaignRow], b: list[CampaignRow]) -> bool:
    """Equal rows (``repr``: NaN equals NaN)."""
    return [repr(r) for r in a] == [repr(r) for r in b]


def markdown(results: dict[str, Any]) -> str:
    n = results["recordings"]
    lines = [
        f"{n} recordings x {results['seconds_each']:g} s ({results['megabytes']:.1f} MB, "
        f"{results['rows']} rows), {results['workers']} CPUs",
        "",
        "| executor | time (s) | vs one process |",
        "| --- | ---: | ---: |",
        f"| one process | {results['one_process_s']:.2f} | 1.00x |",
        f"| local processes ({results['workers']}) | {results['local_processes_s']:.2f} | "
        f"{results['local_speedup']:.2f}x |",
    ]
    if "dask_local_cluster_s" in results:
        lines.append(
            f"| Dask LocalCluster ({results['workers']} workers) | "
            f"{results['dask_local_cluster_s']:.2f} | {results['dask_speedup']:.2f}x |"
        )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--recordings", type=int, default=8)
    parser.add_argument("--seconds", type=float, default=20.0, help="length of each recording")
    parser.add_argument("--no-dask", action="store_true", help="leave out the Dask cluster")
    parser.add_argument("--out", type=Path, default=RESULTS)
    args = parser.parse_args(argv)
    results = run_benchmark(args.recordings, args.seconds, dask=not args.no_dask)
    args.out.write_text(json.dumps(results, indent=2) + "\n")
    print(markdown(results))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
