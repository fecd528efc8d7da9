"""Streaming soil-pressure estimator of the portal advancing mechanism.

Pure computation, no I/O: eq. (4) (foot force from the leg cylinder's chamber
pressures), eq. (5) (contact pressure = force / foot area), a running median,
per-sample validity, contact detection, soil metrics and the weight check.
"""

from estimator.batch import LegSeries, estimate_leg_series
from estimator.equations import contact_pressure_Pa, cylinder_force_N, foot_force_N
from estimator.geometry import LegGeometry
from estimator.leg import LegEstimate, LegEstimator, LegSample
from estimator.machine import MachineEstimator, MachineSnapshot
from estimator.median import RunningMedian, running_median
from estimator.metrics import SoilMetrics, SoilMetricsTracker
from estimator.settings import EstimatorSettings
from estimator.weight import WeightCheck, weight_check

__all__ = [
    "EstimatorSettings",
    "LegEstimate",
    "LegEstimator",
    "LegGeometry",
    "LegSample",
    "LegSeries",
    "MachineEstimator",
    "MachineSnapshot",
    "RunningMedian",
    "SoilMetrics",
    "SoilMetricsTracker",
    "WeightCheck",
    "contact_pressure_Pa",
    "cylinder_force_N",
    "estimate_leg_series",
    "foot_force_N",
    "running_median",
    "weight_check",
]
