"""Calculated against true foot force: matching by time and the deviation statistics.

Pure computation, as in section 3.4 of the paper (Figures 5 and 6). An estimate is
matched to the truth sample nearest to it in time, if that is at most half a sample
period away, of the truth's or the leg's estimates', whichever is shorter (a period is
the median spacing of the samples): the truth is stamped with the Unix time its frames
went onto the bus, the estimate with the frame time of the frame it came from, so the
two agree to the receive latency. Truth sampled more sparsely than the estimates
(``portal-sim --truth-every 100``: one a second) is compared with the estimates made at
its instants only: within half the truth's period, every estimate was compared with a
truth sample up to 0.5 s away, and a correct estimator was out of the paper's bounds.

The deviation is the calculated, median-filtered force minus the true force, over the
valid estimates that have a known true force. The paper filters offline, with a
median centred on each sample; the service's running median is causal and lags by
``h = (N - 1) / 2`` valid samples (50 ms with N = 11 at 10 ms), which alone makes
several kN of difference while the force oscillates. So the calculated force of a
frame is the median centred on it: the running median of the valid raw forces ``h``
valid samples later (the last ``h`` frames have none and are left out). The value as
published at the frame's own time, by whichever filter was configured (running median
or Hampel), is kept too (:attr:`LegComparison.published_N`), to show what the live
filter costs.

The paper's comparison is about feet on the ground. A sample is *stance* when its true
force is above the estimator's contact threshold (``contact_on_N``), else *swing* (the
leg lifted or folded: its cylinder pressures then carry the leg's own inertia and the
cylinder friction, nothing eq. (4) models). The statistics are taken over each apart.
"""

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from daq.report.tracks import BoolArray, FloatArray, LegTrack, TruthTrack
from estimator.median import running_median

IntArray = npt.NDArray[np.intp]


def sample_period_s(t_s: FloatArray) -> float:
    """The median spacing of sorted times (NaN with fewer than two distinct times).

    >>> import numpy as np
    >>> sample_period_s(np.array([0.0, 0.01, 0.02, 0.05]))
    0.01
    """
    steps = np.diff(t_s)
    steps = steps[steps > 0]
    return float(np.median(steps)) if steps.size else math.nan


def match_nearest(t_s: FloatArray, reference_t_s: FloatArray, tolerance_s: float) -> IntArray:
    """For each of ``t_s``, the index of the nearest of the sorted ``reference_t_s``, or -1
    when none is within ``tolerance_s`` (inclusive). A tie goes to the earlier sample.

    >>> import numpy as np
    >>> match_nearest(np.array([0.9, 1.004, 1.006, 3.0]), np.array([1.0, 1.01]), 0.005)
    array([-1,  0,  1, -1])
    """
    t = np.asarray(t_s, dtype=np.float64)
    if reference_t_s.size == 0:
        return np.full(t.shape, -1, dtype=np.intp)
    right = np.clip(np.searchsorted(reference_t_s, t, side="left"), 0, reference_t_s.size - 1)
    left = np.clip(right - 1, 0, None)
    left_gap = np.abs(t - reference_t_s[left])
    right_gap = np.abs(reference_t_s[right] - t)
    nearest = np.where(left_gap <= right_gap, left, right)
    gap = np.minimum(left_gap, right_gap)
    return np.where(gap <= tolerance_s, nearest, -1).astype(np.intp)


@dataclass(frozen=True)
class LegComparison:
    """One leg's matched samples: frame time, calculated and true force."""

    leg: str
    t_s: FloatArray
    #: The median of the raw forces centred on the frame (see the module docstring).
    calculated_N: FloatArray
    true_N: FloatArray
    #: The configured filter's value as published at the frame's time (the running
    #: median lags by h samples).
    published_N: FloatArray
    #: The foot was on the ground: true force above the contact threshold.
    stance: BoolArray

    @property
    def deviation_N(self) -> FloatArray:
        """Calculated (centred) minus true."""
        return np.asarray(self.calculated_N - self.true_N, dtype=np.float64)

    @property
    def published_deviation_N(self) -> FloatArray:
        """Published (live-filtered) minus true."""
        return np.asarray(self.published_N - self.true_N, dtype=np.float64)


@dataclass(frozen=True, slots=True)
class DeviationStats:
    """Statistics of one leg's deviation (calculated - true), N."""

    leg: str
    samples: int
    median_N: float
    mean_N: float
    #: Half of the absolute deviations are at most this (median of |deviation|) ...
    abs50_N: float
    #: ... and 95 % at most this (numpy's linear quantile).
    abs95_N: float
    max_abs_N: float
    #: Mean true force over the matched samples (how loaded the leg was).
    mean_true_N: float
    #: 95 % of the absolute deviations of the published (live-filtered) values are at most this.
    published_abs95_N: float


def compare_leg(
    track: LegTrack, truth: TruthTrack, tolerance_s: float, median_window: int, contact_N: float
) -> LegComparison:
    """``track``'s valid estimates matched to ``truth`` (see the module docstring);
    ``median_window`` is the running median's N, ``contact_N`` the stance threshold."""
    lag = (median_window - 1) // 2
    usable = np.flatnonzero(
        track.valid & np.isfinite(track.force_N) & np.isfinite(track.force_raw_N)
    )
    centred = running_median(track.force_raw_N[usable], median_window)
    frames = usable[: max(usable.size - lag, 0)]
    true_all = truth.force_true_N.get(track.leg)
    if true_all is None:
        frames = frames[:0]
        true_all = np.zeros(0, dtype=np.float64)
    index = match_nearest(track.t_s[frames], truth.t_s, tolerance_s)
    matched = index >= 0
    true_N = true_all[index[matched]]
    known = np.isfinite(true_N)
    frames = frames[matched][known]
    later = np.searchsorted(usable, frames) + lag  # h valid samples on
    return LegComparison(
        leg=track.leg,
        t_s=track.t_s[frames],
        calculated_N=centred[later],
        true_N=true_N[known],
        published_N=track.force_N[frames],
        stance=np.asarray(true_N[known] > contact_N, dtype=np.bool_),
    )


def compare(
    tracks: Mapping[str, LegTrack], truth: TruthTrack, median_window: int, contact_N: float
) -> dict[str, LegComparison]:
    """Every leg that has truth, matched within half the shorter of the truth's and the
    leg's sample period; stance where the true force is above ``contact_N``."""
    truth_period_s = sample_period_s(truth.t_s)
    return {
        leg: compare_leg(
            track, truth, _tolerance_s(truth_period_s, track.t_s), median_window, contact_N
        )
        for leg, track in tracks.items()
        if leg in truth.force_true_N
    }


def _tolerance_s(truth_period_s: float, t_s: FloatArray) -> float:
    """Half the shorter of the truth's period and that of the estimates at ``t_s``; 0
    (only an estimate at a truth sample's instant) where neither has one."""
    periods = [p for p in (truth_period_s, sample_period_s(t_s)) if math.isfinite(p)]
    return min(periods) / 2 if periods else 0.0


def deviation_stats(comparison: LegComparison, stance: bool = True) -> DeviationStats:
    """The statistics of one leg's deviation over its stance (or swing) samples; NaN
    when there are none.

    >>> import numpy as np
    >>> zero = np.zeros(6)
    >>> calculated = np.array([-3.0, -1, 0, 2, 4, 10])
    >>> on_ground = np.array([True] * 5 + [False])
    >>> c = LegComparison("L", zero, calculated, zero, zero, on_ground)
    >>> s = deviation_stats(c)
    >>> (s.samples, s.median_N, s.mean_N, s.abs50_N, s.abs95_N, s.max_abs_N)
    (5, 0.0, 0.4, 2.0, 3.8, 4.0)
    >>> deviation_stats(c, stance=False).max_abs_N
    10.0
    """
    use = comparison.stance if stance else ~comparison.stance
    deviation = comparison.deviation_N[use]
    if deviation.size == 0:
        nan = math.nan
        return DeviationStats(comparison.leg, 0, nan, nan, nan, nan, nan, nan, nan)
    magnitude = np.abs(deviation)
    return DeviationStats(
        leg=comparison.leg,
        samples=int(deviation.size),
        median_N=float(np.median(deviation)),
        mean_N=float(np.mean(deviation)),
        abs50_N=float(np.quantile(magnitude, 0.5)),
        abs95_N=float(np.quantile(magnitude, 0.95)),
        max_abs_N=float(np.max(magnitude)),
        mean_true_N=float(np.mean(comparison.true_N[use])),
        published_abs95_N=float(np.quantile(np.abs(comparison.published_deviation_N[use]), 0.95)),
    )


def most_loaded(stats: Mapping[str, DeviationStats]) -> str | None:
    """The leg with the highest mean true force (Figure 5's "leg with the highest load")."""
    loaded = {leg: s.mean_true_N for leg, s in stats.items() if s.samples}
    return max(loaded, key=lambda leg: loaded[leg]) if loaded else None
