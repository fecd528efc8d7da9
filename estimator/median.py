"""Running median over the last N samples: a streaming path and a numpy batch path.

Both give bit-identical results on the same input. Until N samples have
arrived the median is that of the samples so far; with an even count it is the
mean of the two middle values, computed as ``(a + b) / 2`` in both paths. A zero
median is +0.0 in both: -0.0 and 0.0 compare equal, and which of them the sorted list
and numpy's selection put in the middle differs (``+ 0.0`` turns -0.0 into 0.0).
"""

from bisect import insort
from collections import deque
from collections.abc import Callable
from functools import partial

import numpy as np
import numpy.typing as npt
from numpy.lib.stride_tricks import sliding_window_view
from sortedcontainers import SortedList

# Rows of the sliding-window matrix partitioned at once in the batch path; bounds
# its temporary memory to about _BATCH_ROWS * window * 8 bytes.
_BATCH_ROWS = 65536
# The batch path selects each output from its window's row (O(N) time, N x 8 bytes per
# row: 5.2 GB for N = 10001) up to this size; larger windows go through the streaming
# path, O(log N) per value, which is faster there (measured, 200,000 values: 0.055 vs
# 0.086 s at N = 31, 0.22 vs 0.11 s at 51, 1.6 vs 0.08 s at 1001 of 40,000 values).
_BATCH_MAX_WINDOW = 31
# Windows up to this size keep their values in a plain sorted list: insort and the
# list's own (linear, C) remove beat SortedList's Python code up to about 200 values
# (measured: 0.16 vs 0.73 us per push at 11, even at 201); larger ones use SortedList.
_PLAIN_LIST_MAX_WINDOW = 201


def _check_window(window: int) -> None:
    if not isinstance(window, int) or isinstance(window, bool) or window < 1 or window % 2 == 0:
        raise ValueError(f"median window must be an odd integer >= 1, got {window!r}")


class RunningMedian:
    """Median of the last ``window`` pushed values, O(log N) per sample (small windows:
    a plain list, O(N) in C, which is faster there).

    >>> m = RunningMedian(3)
    >>> [m.push(v) for v in (5.0, 1.0, 3.0, 10.0, 0.0)]
    [5.0, 3.0, 3.0, 3.0, 3.0]
    """

    def __init__(self, window: int) -> None:
        _check_window(window)
        self.window = window
        self._arrival: deque[float] = deque()
        # Both remove the leftmost equal value and insert after equal ones: the same order.
        self._sorted: list[float] | SortedList
        self._insert: Callable[[float], None]
        if window <= _PLAIN_LIST_MAX_WINDOW:
            self._sorted = []
            self._insert = partial(insort, self._sorted)
        else:
            self._sorted = SortedList()
            self._insert = self._sorted.add

    def __len__(self) -> int:
        return len(self._arrival)

    def clear(self) -> None:
        """Forget every value (e.g. after an outage): the median is NaN again."""
        self._arrival.clear()
        self._sorted.clear()

    def push(self, value: float) -> float:
        """Add a value, drop the oldest once the window is full, return the median."""
        arrival, ordered = self._arrival, self._sorted
        if len(arrival) == self.window:
            ordered.remove(arrival.popleft())
        arrival.append(value)
        self._insert(value)
        n = len(ordered)
        if n % 2:  # always, once the window is full
            return float(ordered[n // 2]) + 0.0
        return self.value

    @property
    def value(self) -> float:
        """The current median; NaN before the first value."""
        n = len(self._sorted)
        if n == 0:
            return float("nan")
        middle = n // 2
        if n % 2:
            return float(self._sorted[middle]) + 0.0
        return float((self._sorted[middle - 1] + self._sorted[middle]) / 2) + 0.0


def running_median(values: npt.ArrayLike, window: int) -> npt.NDArray[np.float64]:
    """Batch path: the running median of every prefix-bounded window of ``values``.

    ``out[i]`` is the median of ``values[max(0, i - window + 1) : i + 1]``, exactly
    what :class:`RunningMedian` returns after pushing ``values[i]``.
    """
    _check_window(window)
    x = np.asarray(values, dtype=np.float64)
    if x.ndim != 1:
        raise ValueError(f"values must be one-dimensional, got shape {x.shape}")
    if window > _BATCH_MAX_WINDOW:
        streaming = RunningMedian(window)
        return np.array([streaming.push(v) for v in x.tolist()], dtype=np.float64)
    out = np.empty_like(x)
    for i in range(min(window - 1, x.size)):
        head = np.sort(x[: i + 1])
        middle = (i + 1) // 2
        out[i] = (head[middle] if (i + 1) % 2 else (head[middle - 1] + head[middle]) / 2) + 0.0
    if x.size >= window:
        windows = sliding_window_view(x, window)
        for start in range(0, windows.shape[0], _BATCH_ROWS):
            chunk = windows[start : start + _BATCH_ROWS]
            # An odd window's median is its middle order statistic: a selection,
            # no arithmetic, hence identical to the streaming path.
            selected = np.partition(chunk, window // 2, axis=1)[:, window // 2]
            out[window - 1 + start : window - 1 + start + chunk.shape[0]] = selected + 0.0
    return out
