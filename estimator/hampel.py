"""A causal Hampel filter: removes one-sample spikes without delaying the signal.

The running median (:mod:`estimator.median`) removes impulsive noise but lags by
(N-1)/2 samples, which costs several kN live while the force oscillates (the fold
stop). This filter lets every sample through unchanged unless it is an outlier,
judged against the ``window`` samples *before* it only (causal, no lag):

1. ``slope``: the median of the window's sample-to-sample steps;
2. each window sample ``x[i-j]`` projected to now, ``x[i-j] + j * slope``; their
   median is the prediction ``level``, and the median of their absolute distances
   to it is the MAD;
3. a sample farther than ``k * 1.4826 * MAD`` from ``level`` (1.4826 scales the MAD
   to a standard deviation for normal noise) is replaced by ``level``.

With a flat window this is the classic Hampel filter (trailing median and MAD).
Projecting along the median slope is what makes it work on ramps and oscillations:
against the plain trailing median a sample on a ramp sits (W-1)/2 steps behind, the
MAD grows with the slope, and a spike of the size of the simulator's (``--noise``,
up to 10.5 kN) passes whole while the force ramps or swings. The window holds the raw
input, spikes included: the medians are robust to fewer than half of it.

Until ``window`` samples have arrived every sample passes unchanged.
"""

from collections import deque

#: MAD of normally distributed noise times this is its standard deviation.
MAD_TO_SIGMA = 1.4826


def _median(values: list[float]) -> float:
    ordered = sorted(values)
    n = len(ordered)
    middle = n // 2
    if n % 2:
        return ordered[middle]
    return (ordered[middle - 1] + ordered[middle]) / 2


#: Longest window: the filter sorts its window twice per sample, O(W log W): ~50 us a
#: sample at 201 on the benchmark's machine, ~0.2 ms at 1,001 and ~2 ms at 10,001, where
#: six legs sending every 10 ms take more than a CPU and the service falls behind.
MAX_WINDOW = 201


def check_hampel(window: int, k: float) -> None:
    """Raise ValueError unless ``window`` is an integer in 3 .. :data:`MAX_WINDOW` and ``k``
    a finite number > 0."""
    if not isinstance(window, int) or isinstance(window, bool) or window < 3:
        raise ValueError(f"hampel_window must be an integer >= 3, got {window!r}")
    if window > MAX_WINDOW:
        raise ValueError(
            f"hampel_window must be at most {MAX_WINDOW}, got {window}: the filter sorts its "
            "window twice per sample (~2 ms a sample at 10,001: the service falls behind); "
            "an outlier is judged against the recent past"
        )
    if isinstance(k, bool) or not isinstance(k, int | float) or not 0 < k < float("inf"):
        raise ValueError(f"hampel_k must be a finite number > 0, got {k!r}")


class RunningHampel:
    """Causal Hampel filter over the last ``window`` raw samples; O(W log W) per sample.

    >>> h = RunningHampel(window=4, k=3.0)
    >>> [h.push(v) for v in (1.0, 2.0, 3.0, 4.0, 50.0, 6.0, 7.0)]
    [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]
    """

    def __init__(self, window: int, k: float) -> None:
        check_hampel(window, k)
        self.window = window
        self.k = k
        self._raw: deque[float] = deque(maxlen=window)
        self._value = float("nan")
        #: Samples replaced by the prediction so far.
        self.replaced = 0

    def clear(self) -> None:
        """Forget every sample (e.g. after an outage): warm-up starts again."""
        self._raw.clear()
        self._value = float("nan")

    def push(self, value: float) -> float:
        """Filter one sample: itself, or the prediction when it is an outlier."""
        raw = self._raw
        out = value
        if len(raw) == self.window:
            history = list(raw)
            slope = _median([b - a for a, b in zip(history, history[1:], strict=False)])
            n = len(history)
            projected = [x + (n - j) * slope for j, x in enumerate(history)]
            level = _median(projected)
            mad = _median([abs(x - level) for x in projected])
            if abs(value - level) > self.k * MAD_TO_SIGMA * mad:
                out = level
                self.replaced += 1
        raw.append(value)
        self._value = out
        return out

    @property
    def value(self) -> float:
        """The latest filtered value; NaN before the first sample."""
        return self._value
