"""All legs of the machine together: per-leg estimates, snapshots and the weight check."""

from collections.abc import Mapping
from dataclasses import dataclass

from estimator.geometry import LegGeometry
from estimator.leg import LegEstimate, LegEstimator, LegSample
from estimator.metrics import SoilMetrics
from estimator.settings import EstimatorSettings
from estimator.weight import WeightCheck, weight_check


@dataclass(frozen=True, slots=True)
class MachineSnapshot:
    """Every leg's latest estimate at one moment, with the weight check over them."""

    t_s: float
    legs: Mapping[str, LegEstimate]
    weight: WeightCheck


class MachineEstimator:
    """One :class:`LegEstimator` per leg, addressed by leg name (e.g. ``SB1_F1``)."""

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
        self.weight_N = weight_N
        self.legs = {
            name: LegEstimator(name, leg, settings, cycle_times_s[name])
            for name, leg in legs.items()
        }

    def update(self, leg: str, sample: LegSample) -> LegEstimate:
        """Feed one sample of ``leg``; returns that leg's new estimate."""
        return self.legs[leg].update(sample)

    def snapshot(self, now_s: float) -> MachineSnapshot:
        """All legs judged at ``now_s`` (stale legs marked), plus the weight check."""
        estimates = {name: leg.snapshot(now_s) for name, leg in self.legs.items()}
        return MachineSnapshot(
            t_s=now_s, legs=estimates, weight=weight_check(estimates.values(), self.weight_N)
        )

    def metrics(self) -> dict[str, SoilMetrics]:
        """Soil metrics of every leg."""
        return {name: leg.metrics for name, leg in self.legs.items()}
