"""Latency statistics of the benchmark."""

from collections.abc import Sequence
from typing import Any

import numpy as np

#: Percentiles reported, in percent.
PERCENTILES = {"median": 50.0, "p90": 90.0, "p99": 99.0, "p99_9": 99.9}


def latency_stats_ms(latencies_s: Sequence[float] | np.ndarray) -> dict[str, Any]:
    """Median, p90, p99, p99.9, mean and max of latencies given in s, in ms."""
    values = np.asarray(latencies_s, dtype=np.float64) * 1e3
    if values.size == 0:
        return {"count": 0} | {name: None for name in (*PERCENTILES, "mean", "max")}
    stats: dict[str, Any] = {"count": int(values.size)}
    for name, q in PERCENTILES.items():
        stats[name] = round(float(np.percentile(values, q)), 4)
    stats["mean"] = round(float(values.mean()), 4)
    stats["max"] = round(float(values.max()), 4)
    return stats
