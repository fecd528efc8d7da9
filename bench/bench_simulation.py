"""Benchmark: wall-clock time of one simulated movement cycle against real time.

Run: .venv/bin/python bench/bench_simulation.py  (prints one JSON line per tolerance)
"""

import json
import os
import platform
import time

from sim_bridge.cycle import CYCLE_END_S
from sim_bridge.model import simulate


def main() -> None:
    machine = f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores"
    for rtol in (1e-3, 1e-5):
        runs = []
        for _ in range(3):
            start = time.perf_counter()
            simulate(rtol=rtol)
            runs.append(time.perf_counter() - start)
        best_s = min(runs)
        print(
            json.dumps(
                {
                    "benchmark": "simulate one cycle",
                    "rtol": rtol,
                    "simulated_s": CYCLE_END_S,
                    "wall_s": round(best_s, 3),
                    "real_time_factor": round(CYCLE_END_S / best_s, 1),
                    "machine": machine,
                }
            )
        )


if __name__ == "__main__":
    main()
