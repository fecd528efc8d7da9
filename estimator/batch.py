"""Batch path: a whole recorded leg series at once with numpy.

Gives bit-identical forces to feeding the same samples one by one through
:class:`estimator.leg.LegEstimator` (the streaming path), which the tests check.
Used for replays and reports where the whole series is at hand.
"""

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from estimator.equations import contact_pressure_Pa, foot_force_N
from estimator.filters import filter_series
from estimator.geometry import LegGeometry
from estimator.settings import EstimatorSettings
from estimator.validity import pressure_in_range

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]


@dataclass(frozen=True)
class LegSeries:
    """Estimates of one leg, one entry per input sample."""

    t_s: FloatArray
    force_raw_N: FloatArray
    #: The configured filter over the valid raw forces, held over invalid samples; NaN
    #: before the first.
    force_N: FloatArray
    pressure_Pa: FloatArray
    valid: BoolArray


def estimate_leg_series(
    t_s: npt.ArrayLike,
    p_piston_Pa: npt.ArrayLike,
    p_rod_Pa: npt.ArrayLike,
    leg: LegGeometry,
    settings: EstimatorSettings,
    checks_ok: npt.ArrayLike | None = None,
    *,
    cycle_time_s: float,
) -> LegSeries:
    """Eq. (4), validity and the configured filter over whole arrays.

    ``checks_ok`` marks the samples whose CRC, counter and status were fine
    (all of them when omitted); the pressure range is checked here. As in the
    streaming path, the filter restarts at a sample more than the stale time
    (``stale_after_cycles`` x ``cycle_time_s``) past the last valid one.
    """
    t = np.asarray(t_s, dtype=np.float64)
    p_piston = np.asarray(p_piston_Pa, dtype=np.float64)
    p_rod = np.asarray(p_rod_Pa, dtype=np.float64)
    if not t.shape == p_piston.shape == p_rod.shape:
        raise ValueError(
            f"t_s, p_piston_Pa and p_rod_Pa must have one shape, got "
            f"{t.shape}, {p_piston.shape}, {p_rod.shape}"
        )
    valid = np.asarray(
        pressure_in_range(p_piston, settings) & pressure_in_range(p_rod, settings), dtype=bool
    )
    if checks_ok is not None:
        valid &= np.asarray(checks_ok, dtype=bool)
    force_raw_N = foot_force_N(p_piston, p_rod, leg)
    # Outages cut the series into segments, each filtered from an empty filter.
    index = np.arange(t.size)
    latest_valid_index = np.maximum.accumulate(np.where(valid, index, -1))
    before = np.concatenate(([-1], latest_valid_index))[: t.size]
    t_before = np.where(before >= 0, t[np.maximum(before, 0)], np.nan)
    segment = np.cumsum((t - t_before) > settings.stale_after_s(cycle_time_s))
    valid_segment = segment[valid]
    starts = np.flatnonzero(np.diff(valid_segment)) + 1
    filtered = np.concatenate(
        [np.empty(0)]
        + [filter_series(part, settings) for part in np.split(force_raw_N[valid], starts)]
    )
    # Each sample takes the filtered value as of the latest valid sample at or before it,
    # when that sample is of its own segment.
    latest_valid = np.cumsum(valid) - 1
    seen_valid = (latest_valid >= 0) & (segment[np.maximum(latest_valid_index, 0)] == segment)
    force_N = np.full(t.shape, np.nan)
    force_N[seen_valid] = filtered[latest_valid[seen_valid]]
    return LegSeries(
        t_s=t,
        force_raw_N=force_raw_N,
        force_N=force_N,
        pressure_Pa=contact_pressure_Pa(force_N, leg.A_foot_m2),
        valid=valid,
    )
