"""All legs of the machine together: per-leg estimates, snapshots and the weight check.

Staleness is judged on *bus time*, not on frame time stamps directly: frame times
follow the wall clock, which may be stepped (NTP). Bus time is the sum of the
forward steps between successive frame times of the bus (:class:`BusClock`; every
message, fed through :meth:`MachineEstimator.observe` and :meth:`~MachineEstimator.update`): a
step back adds nothing, so the legs that keep sending stay fresh across it and a
silent leg still ages. It derives from frame times alone, so a replay computes the
same.
"""

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from estimator.geometry import LegGeometry
from estimator.kinematics import Point
from estimator.leg import LegEstimate, LegEstimator, LegSample
from estimator.metrics import SoilMetrics
from estimator.settings import EstimatorSettings
from estimator.stability import Stability, stability
from estimator.validity import both_chambers_heard
from estimator.weight import WeightCheck, weight_check


@dataclass(frozen=True, slots=True)
class MachineSnapshot:
    """Every leg's latest estimate at one moment, with the weight check over them."""

    #: The moment judged, on the frames' clock (Unix seconds).
    t_s: float
    legs: Mapping[str, LegEstimate]
    weight: WeightCheck
    #: Centre of pressure and margin of the feet in contact; None when undefined or
    #: no foot positions were given.
    stability: Stability | None = None


class BusClock:
    """Bus time (module docstring) of the frames observed, in the order received."""

    def __init__(self) -> None:
        #: How long the bus has run: the forward steps between frame times, summed.
        self.bus_time_s = 0.0
        #: Frame time of the latest frame observed (NaN before the first).
        self.latest_t_s = math.nan

    def observe(self, t_s: float) -> float:
        """Note the time stamp of a frame on the bus; the bus time after it."""
        step_s = t_s - self.latest_t_s
        if 0.0 < step_s < math.inf:  # NaN (the first frame) and a step back add nothing
            self.bus_time_s += step_s
        if math.isfinite(t_s):
            self.latest_t_s = t_s
        return self.bus_time_s

    def judged_s(self, now_s: float) -> float:
        """The bus time at ``now_s``, a time on the frames' clock: the latest frame's,
        plus how far ``now_s`` lies past that frame (nothing when it lies before it)."""
        ahead_s = now_s - self.latest_t_s
        return self.bus_time_s + (ahead_s if ahead_s > 0.0 else 0.0)


class MachineEstimator(BusClock):
    """One :class:`LegEstimator` per leg, addressed by leg name (e.g. ``SB1_F1``), on the
    bus time of every frame (:meth:`~BusClock.observe`, any message)."""

    def __init__(
        self,
        legs: Mapping[str, LegGeometry],
        settings: EstimatorSettings,
        weight_N: float,
        cycle_times_s: Mapping[str, float],
    ) -> None:
        missing = sorted(set(legs) - set(cycle_times_s))
        if missing:
            raise ValueError(f"no cycle time for legs {missing}")
        super().__init__()
        self.weight_N = weight_N
        self.legs = {
            name: LegEstimator(name, leg, settings, cycle_times_s[name])
            for name, leg in legs.items()
        }
        #: Bus time at each leg's latest sample.
        self._heard_at_s = dict.fromkeys(self.legs, math.nan)
        #: ... and at its latest sample with both chambers heard (:meth:`heard_at_s`).
        self._both_heard_at_s = dict.fromkeys(self.legs, math.nan)

    def update(self, leg: str, sample: LegSample) -> LegEstimate:
        """Feed one sample of ``leg`` (observing its frame time); returns its new estimate."""
        if sample.t_s != self.latest_t_s:  # the same frame time (usual) would add nothing
            self.observe(sample.t_s)
        self._heard_at_s[leg] = self.bus_time_s
        if not sample.faults or both_chambers_heard(sample.faults):
            self._both_heard_at_s[leg] = self.bus_time_s
        return self.legs[leg].update(sample, self.bus_time_s)

    def snapshot(
        self,
        now_s: float,
        place_feet: Callable[[Mapping[str, LegEstimate]], Mapping[str, Point] | None] | None = None,
    ) -> MachineSnapshot:
        """All legs judged at ``now_s`` (stale legs marked), plus the weight check, and
        with ``place_feet`` (the legs' estimates -> the feet's plan positions, None when
        unknown) the stability margin.

        ``now_s`` is a time on the frames' clock; the legs are judged at its bus time
        (:meth:`~BusClock.judged_s`).
        """
        judged_s = self.judged_s(now_s)
        estimates = {
            name: leg.snapshot(judged_s - self._heard_at_s[name]) for name, leg in self.legs.items()
        }
        feet_m = place_feet(estimates) if place_feet is not None else None
        return MachineSnapshot(
            t_s=now_s,
            legs=estimates,
            weight=weight_check(estimates.values(), self.weight_N),
            stability=stability(estimates.values(), feet_m) if feet_m is not None else None,
        )

    def heard_at_s(self) -> dict[str, float]:
        """The bus time (:attr:`bus_time_s`) at each leg's latest sample made with both
        chambers heard; 0.0 (the first frame's) for a leg never so heard. A leg with two
        transducers whose rod one fell silent still makes samples with each piston value
        (all ``rod_stale``): its sensors are silent all the same."""
        return {
            name: 0.0 if math.isnan(t_s) else t_s for name, t_s in self._both_heard_at_s.items()
        }

    def restarting_legs(self) -> dict[str, tuple[int, int]]:
        """Legs whose filter restarted at most of their valid samples: (restarts, valid
        samples). Sent less often than the stale time (its cycle time, from the DBC or the
        config, shorter than the period it comes at: a multiplexed hub's
        ``GenMsgCycleTime`` per frame where each page comes less often), every sample
        looked like one after an outage: the filter, the contact and the near-constant
        window restarted at each, unseen in the estimates themselves."""
        found = {}
        for name, leg in self.legs.items():
            restarts, samples = leg.restarts, leg.valid_samples
            if restarts > 1 and 2 * restarts > samples:
                found[name] = (restarts, samples)
        return found

    def metrics(self) -> dict[str, SoilMetrics]:
        """Soil metrics of every leg."""
        return {name: leg.metrics for name, leg in self.legs.items()}
