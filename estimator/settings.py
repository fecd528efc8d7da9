"""Tuning of the streaming estimator: filter length, validity limits, contact and metrics."""

from dataclasses import dataclass

from estimator._checks import require_finite, require_positive
from estimator.hampel import check_hampel

#: Shortest ``near_constant_window_s``: the DBC's legs send every 10 ms.
NEAR_CONSTANT_WINDOW_MIN_S = 0.01


@dataclass(frozen=True, slots=True)
class EstimatorSettings:
    """How the estimator filters, validates and judges samples; SI units.

    >>> EstimatorSettings(median_window=4)
    Traceback (most recent call last):
    ...
    ValueError: median_window must be an odd integer >= 1, got 4
    """

    #: The force filter: ``"median"`` (the paper's running median) or ``"hampel"``
    #: (causal Hampel filter, no delay); see :mod:`estimator.filters`.
    filter: str = "median"
    #: Samples in the running median (odd). The filter delays by (N-1)/2 samples.
    median_window: int = 11
    #: Trailing samples the Hampel filter judges a sample against (>= 3).
    hampel_window: int = 7
    #: A sample farther than k x 1.4826 x MAD from the Hampel prediction is replaced.
    hampel_k: float = 3.0
    #: A leg's frame is stale when none came for this many cycle times (> 1).
    stale_after_cycles: float = 3.0
    #: Lowest pressure the transducers measure; below it a sample is invalid ("range").
    pressure_min_Pa: float = -1.0e5
    #: Highest pressure the transducers measure; above it a sample is invalid ("range").
    pressure_max_Pa: float = 40.0e6
    #: Filtered foot force at or above which a foot in the air counts as down.
    contact_on_N: float = 8000.0
    #: Filtered foot force at or below which a foot on the ground counts as lifted.
    contact_off_N: float = 4000.0
    #: Contact pressure whose exceedance time the soil metrics add up.
    pressure_limit_Pa: float = 200.0e3
    #: Length of the sliding window of the "near constant" pressure metric.
    near_constant_window_s: float = 5.0

    def __post_init__(self) -> None:
        if (
            not isinstance(self.median_window, int)
            or isinstance(self.median_window, bool)
            or self.median_window < 1
            or self.median_window % 2 == 0
        ):
            raise ValueError(
                f"median_window must be an odd integer >= 1, got {self.median_window!r}"
            )
        if self.filter not in ("median", "hampel"):
            raise ValueError(f'filter must be "median" or "hampel", got {self.filter!r}')
        check_hampel(self.hampel_window, self.hampel_k)
        require_finite("stale_after_cycles", self.stale_after_cycles)
        if not self.stale_after_cycles > 1.0:
            # One cycle or less: every regular next frame would come after the stale time,
            # so the filter, the contact and the near-constant window would restart at
            # each sample and each step add only the stale time above the limit.
            raise ValueError(
                f"stale_after_cycles must be > 1, got {self.stale_after_cycles!r}: a leg "
                "would be stale between two of its frames, and its median and soil "
                "metrics restart at each"
            )
        require_finite("pressure_min_Pa", self.pressure_min_Pa)
        require_finite("pressure_max_Pa", self.pressure_max_Pa)
        if self.pressure_min_Pa >= self.pressure_max_Pa:
            raise ValueError(
                f"pressure_min_Pa ({self.pressure_min_Pa}) must be below "
                f"pressure_max_Pa ({self.pressure_max_Pa})"
            )
        require_positive("contact_on_N", self.contact_on_N)
        require_finite("contact_off_N", self.contact_off_N)
        if self.contact_off_N >= self.contact_on_N:
            raise ValueError(
                f"contact_off_N ({self.contact_off_N}) must be below contact_on_N "
                f"({self.contact_on_N}): the gap between them is the hysteresis"
            )
        require_positive("pressure_limit_Pa", self.pressure_limit_Pa)
        require_finite("near_constant_window_s", self.near_constant_window_s)
        if not self.near_constant_window_s >= NEAR_CONSTANT_WINDOW_MIN_S:
            # Shorter than the resolution of a frame time (1e-300 s), the window dropped
            # the sample just added: a ZeroDivisionError; shorter than a frame cycle, it
            # holds one sample and its mean is the peak.
            raise ValueError(
                f"near_constant_window_s must be at least {NEAR_CONSTANT_WINDOW_MIN_S:g} s, "
                f"got {self.near_constant_window_s!r}: the window of the mean pressure spans "
                "several frames of a leg"
            )

    def stale_after_s(self, cycle_time_s: float) -> float:
        """How long a leg sent every ``cycle_time_s`` may go without a sample before it is
        stale (and the next sample starts its filter afresh): ``stale_after_cycles`` of it."""
        return self.stale_after_cycles * cycle_time_s
