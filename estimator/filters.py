"""The force filter the estimator applies, chosen by ``[estimator] filter``.

``median``: the paper's running median (:mod:`estimator.median`), (N-1)/2 samples of
delay. ``hampel``: the causal Hampel filter (:mod:`estimator.hampel`), no delay. Both
take the valid raw forces of one leg in arrival order, one at a time (streaming) or
as one array (batch); the two paths give bit-identical values.
"""

from typing import Protocol

import numpy as np
import numpy.typing as npt

from estimator.hampel import RunningHampel
from estimator.median import RunningMedian, running_median
from estimator.settings import EstimatorSettings

#: The values of ``[estimator] filter``.
FILTERS = ("median", "hampel")


class ForceFilter(Protocol):
    """A streaming filter of one leg's valid raw forces."""

    def push(self, value: float) -> float:
        """Take the next valid raw force, return the filtered one."""

    @property
    def value(self) -> float:
        """The latest filtered force; NaN before the first."""

    def clear(self) -> None:
        """Forget every force (after an outage)."""


def make_filter(settings: EstimatorSettings) -> ForceFilter:
    """A fresh streaming filter as configured."""
    if settings.filter == "hampel":
        return RunningHampel(settings.hampel_window, settings.hampel_k)
    return RunningMedian(settings.median_window)


def filter_series(values: npt.ArrayLike, settings: EstimatorSettings) -> npt.NDArray[np.float64]:
    """Batch path: the filtered forces of a whole series of valid raw forces."""
    if settings.filter == "median":
        return running_median(values, settings.median_window)
    streaming = make_filter(settings)
    # The Hampel filter's window is a handful of samples: the streaming path itself
    # is fast enough for a recording and is bit-identical by construction.
    return np.array([streaming.push(float(v)) for v in np.asarray(values, dtype=np.float64)])
