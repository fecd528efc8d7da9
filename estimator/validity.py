"""Why a leg sample must not be trusted: the reasons an estimate is ``valid=false``.

Reason names are part of the published contract (the ``reasons`` list):

- ``crc``: the frame's CRC-8 did not match its payload;
- ``counter``: the rolling counter repeated or jumped (frozen or lost sender);
- ``status_<name>``: the sensor reported a status other than ok, e.g. ``status_over_range``;
- ``range``: a chamber pressure lies outside the transducers' range (or is not a number);
- ``stale``: no frame for more than ``stale_after_cycles`` cycle times.
"""

from typing import TypeVar

import numpy as np
import numpy.typing as npt

from estimator.settings import EstimatorSettings

Value = TypeVar("Value", float, npt.NDArray[np.float64])

STALE = "stale"


def pressure_in_range(p_Pa: Value, settings: EstimatorSettings) -> bool | npt.NDArray[np.bool_]:
    """True where a pressure is inside the sensor range; NaN is never inside."""
    return (p_Pa >= settings.pressure_min_Pa) & (p_Pa <= settings.pressure_max_Pa)


def sample_faults(
    *,
    p_piston_Pa: float,
    p_rod_Pa: float,
    status: str,
    crc_ok: bool,
    counter_ok: bool,
    settings: EstimatorSettings,
) -> tuple[str, ...]:
    """The reasons a freshly received sample is invalid; empty when it is valid."""
    low, high = settings.pressure_min_Pa, settings.pressure_max_Pa
    if (
        crc_ok
        and counter_ok
        and status == settings.status_ok
        and low <= p_piston_Pa <= high
        and low <= p_rod_Pa <= high
    ):
        return ()  # the usual case, first (per frame): the same checks as below
    reasons: list[str] = []
    if not crc_ok:
        reasons.append("crc")
    if not counter_ok:
        reasons.append("counter")
    if status != settings.status_ok:
        reasons.append(f"status_{status}")
    if not (pressure_in_range(p_piston_Pa, settings) and pressure_in_range(p_rod_Pa, settings)):
        reasons.append("range")
    return tuple(reasons)
