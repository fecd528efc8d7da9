"""Why a leg sample must not be trusted: the reasons an estimate is ``valid=false``.

Reason names are part of the published contract (the ``reasons`` list):

- ``crc``: a frame's CRC did not match its payload;
- ``counter``: a rolling counter jumped further than its profile's ``max_delta_counter``;
- ``counter_repeat``: a rolling counter repeated (a frozen sender);
- ``status_<value>``: a sensor reported a status other than fine, e.g. ``status_over_range``
  (a value-table name) or ``status_3`` (a number);
- ``piston_stale`` / ``rod_stale``: the other chamber's latest value is older than
  ``max_skew_s`` (or none came yet) when the leg's trigger chamber arrived;
- ``range``: a chamber pressure lies outside the transducers' range (or is not a number);
- ``stale``: no frame for more than ``stale_after_cycles`` cycle times.

All but ``range`` and ``stale`` come from the CAN layer (:mod:`dbc.samples`) as the
sample's ``faults``.
"""

from collections.abc import Iterable
from typing import TypeVar

import numpy as np
import numpy.typing as npt

from estimator.settings import EstimatorSettings

Value = TypeVar("Value", float, npt.NDArray[np.float64])

STALE = "stale"
#: A sample made without a fresh value of its other chamber (a transducer silent).
OTHER_CHAMBER_STALE = frozenset({"piston_stale", "rod_stale"})


def both_chambers_heard(reasons: Iterable[str]) -> bool:
    """Whether a sample or estimate of these fault ``reasons`` was made with both chambers
    fresh: its leg's sensors were heard (a leg whose every estimate is ``rod_stale`` is
    silent, live as in replay and the report).

    >>> [both_chambers_heard(reasons) for reasons in ((), ("range",), ("range", "rod_stale"))]
    [True, True, False]
    """
    return OTHER_CHAMBER_STALE.isdisjoint(reasons)


def pressure_in_range(p_Pa: Value, settings: EstimatorSettings) -> bool | npt.NDArray[np.bool_]:
    """True where a pressure is inside the sensor range; NaN is never inside."""
    return (p_Pa >= settings.pressure_min_Pa) & (p_Pa <= settings.pressure_max_Pa)


def sample_faults(
    *,
    p_piston_Pa: float,
    p_rod_Pa: float,
    faults: tuple[str, ...],
    settings: EstimatorSettings,
) -> tuple[str, ...]:
    """The reasons a freshly received sample is invalid: the CAN layer's ``faults`` and
    ``range``; empty when it is valid."""
    low, high = settings.pressure_min_Pa, settings.pressure_max_Pa
    if low <= p_piston_Pa <= high and low <= p_rod_Pa <= high:
        return faults  # the usual case, first (per frame): the same check as below
    reasons = list(faults)
    if not (pressure_in_range(p_piston_Pa, settings) and pressure_in_range(p_rod_Pa, settings)):
        reasons.append("range")
    return tuple(reasons)
