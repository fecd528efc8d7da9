"""Soil-stress metrics per leg: peak pressure, near-constant pressure, time above a limit."""

import math
from collections import deque
from dataclasses import dataclass

NAN = float("nan")


@dataclass(frozen=True, slots=True)
class SoilMetrics:
    """What one foot did to the soil since the tracker started (or was reset)."""

    #: Highest filtered contact pressure; NaN before the first valid sample.
    peak_pressure_Pa: float = NAN
    #: Frame time of that peak.
    peak_t_s: float = NAN
    #: Highest mean contact pressure over a sliding window (the paper's "near
    #: constant" pressure, 5 s by default); NaN until one window is covered.
    near_constant_pressure_Pa: float = NAN
    #: End time of the window that gave it.
    near_constant_t_s: float = NAN
    #: Time the contact pressure spent above the configured limit.
    time_above_limit_s: float = 0.0
    #: Valid samples counted.
    samples: int = 0


class SoilMetricsTracker:
    """Updates :class:`SoilMetrics` sample by sample, O(1) amortised per sample.

    ``max_gap_s`` caps the time one sample-to-sample step may add above the
    limit, so that a sensor outage is not counted as time above the limit.
    """

    def __init__(self, limit_Pa: float, window_s: float, max_gap_s: float = math.inf) -> None:
        self.limit_Pa = limit_Pa
        self.window_s = window_s
        self.max_gap_s = max_gap_s
        self.reset()

    def reset(self) -> None:
        """Start afresh, e.g. at the beginning of a movement cycle."""
        self._metrics = SoilMetrics()
        self._window: deque[tuple[float, float]] = deque()
        self._window_sum_Pa = 0.0
        self._first_t_s = NAN
        self._previous: tuple[float, float] | None = None

    @property
    def metrics(self) -> SoilMetrics:
        return self._metrics

    def update(self, t_s: float, pressure_Pa: float) -> SoilMetrics:
        """Add one valid filtered contact pressure at frame time ``t_s``."""
        m = self._metrics
        peak_Pa, peak_t_s = m.peak_pressure_Pa, m.peak_t_s
        if not pressure_Pa <= peak_Pa:  # also true while the peak is still NaN
            peak_Pa, peak_t_s = pressure_Pa, t_s

        above_s = m.time_above_limit_s
        if self._previous is not None:
            previous_t_s, previous_Pa = self._previous
            if previous_Pa > self.limit_Pa:
                above_s += min(t_s - previous_t_s, self.max_gap_s)
        self._previous = (t_s, pressure_Pa)

        if math.isnan(self._first_t_s):
            self._first_t_s = t_s
        self._window.append((t_s, pressure_Pa))
        self._window_sum_Pa += pressure_Pa
        while self._window[0][0] <= t_s - self.window_s:
            self._window_sum_Pa -= self._window.popleft()[1]
        near_Pa, near_t_s = m.near_constant_pressure_Pa, m.near_constant_t_s
        if t_s - self._first_t_s >= self.window_s:
            mean_Pa = self._window_sum_Pa / len(self._window)
            if not mean_Pa <= near_Pa:
                near_Pa, near_t_s = mean_Pa, t_s

        self._metrics = SoilMetrics(
            peak_pressure_Pa=peak_Pa,
            peak_t_s=peak_t_s,
            near_constant_pressure_Pa=near_Pa,
            near_constant_t_s=near_t_s,
            time_above_limit_s=above_s,
            samples=m.samples + 1,
        )
        return self._metrics
