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
    #: constant" pressure, 5 s by default); NaN until a run of samples without a
    #: gap or a clock step back covers one window.
    near_constant_pressure_Pa: float = NAN
    #: End time of the window that gave it.
    near_constant_t_s: float = NAN
    #: Time the contact pressure spent above the configured limit.
    time_above_limit_s: float = 0.0
    #: Valid samples counted.
    samples: int = 0


class SoilMetricsTracker:
    """Updates :class:`SoilMetrics` sample by sample, O(1) amortised per sample.

    Times are frame times, which follow the wall clock and may step. Between two
    samples only a forward step counts: ``max_gap_s`` caps the time one step may add
    above the limit (a sensor outage is not time above the limit), and a step back
    adds nothing. A gap longer than ``max_gap_s`` or a step back breaks the run of
    samples: the sliding window restarts, and a near-constant mean is taken only
    from a run that spans the whole window.
    The running values are plain attributes; :attr:`metrics` builds the frozen
    :class:`SoilMetrics` from them when asked (once per change), not per sample.
    """

    def __init__(self, limit_Pa: float, window_s: float, max_gap_s: float = math.inf) -> None:
        self.limit_Pa = limit_Pa
        self.window_s = window_s
        self.max_gap_s = max_gap_s
        self.reset()

    def reset(self) -> None:
        """Start afresh, e.g. at the beginning of a movement cycle."""
        self._peak_Pa = NAN
        self._peak_t_s = NAN
        self._near_Pa = NAN
        self._near_t_s = NAN
        self._above_s = 0.0
        self._samples = 0
        self._metrics: SoilMetrics | None = SoilMetrics()
        self._window: deque[tuple[float, float]] = deque()
        self._window_sum_Pa = 0.0
        #: Frame time of the first sample of the current run (no gap, no step back).
        self._run_start_t_s = NAN
        self._previous: tuple[float, float] | None = None

    @property
    def samples(self) -> int:
        """Valid samples counted (:attr:`SoilMetrics.samples`, without building it: safe to
        read from another thread)."""
        return self._samples

    @property
    def metrics(self) -> SoilMetrics:
        metrics = self._metrics
        if metrics is None:
            metrics = self._metrics = SoilMetrics(
                peak_pressure_Pa=self._peak_Pa,
                peak_t_s=self._peak_t_s,
                near_constant_pressure_Pa=self._near_Pa,
                near_constant_t_s=self._near_t_s,
                time_above_limit_s=self._above_s,
                samples=self._samples,
            )
        return metrics

    def update(self, t_s: float, pressure_Pa: float) -> SoilMetrics:
        """Add one valid filtered contact pressure at frame time ``t_s``."""
        self.add(t_s, pressure_Pa)
        return self.metrics

    def add(self, t_s: float, pressure_Pa: float) -> None:
        """:meth:`update` without building the :class:`SoilMetrics` (the per-frame path)."""
        if not pressure_Pa <= self._peak_Pa:  # also true while the peak is still NaN
            self._peak_Pa, self._peak_t_s = pressure_Pa, t_s

        step_s = math.nan
        if self._previous is not None:
            previous_t_s, previous_Pa = self._previous
            step_s = t_s - previous_t_s
            if previous_Pa > self.limit_Pa and step_s > 0.0:
                self._above_s += min(step_s, self.max_gap_s)
        self._previous = (t_s, pressure_Pa)

        window = self._window
        if not 0.0 <= step_s <= self.max_gap_s:  # first sample, a gap or a step back
            window.clear()
            self._window_sum_Pa = 0.0
            self._run_start_t_s = t_s
        window.append(self._previous)
        window_sum_Pa = self._window_sum_Pa + pressure_Pa
        oldest_kept_t_s = t_s - self.window_s
        while window and window[0][0] <= oldest_kept_t_s:  # empty: a time of 1e300, inf
            window_sum_Pa -= window.popleft()[1]
        self._window_sum_Pa = window_sum_Pa
        if t_s - self._run_start_t_s >= self.window_s:
            mean_Pa = window_sum_Pa / len(window)
            if not mean_Pa <= self._near_Pa:
                self._near_Pa, self._near_t_s = mean_Pa, t_s

        self._samples += 1
        self._metrics = None
