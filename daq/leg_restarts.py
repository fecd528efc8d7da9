"""What a run's estimates do not show: legs whose filter restarted at every sample.

A leg sent less often than its stale time (its cycle time, from the DBC or the config,
shorter than the period it comes at) restarts its filter, contact and near-constant
window at each sample, its estimates all valid (:meth:`MachineEstimator.restarting_legs
<estimator.machine.MachineEstimator.restarting_legs>`). Replay says so at its end, the
service once per leg at a status period.
"""

import logging

from daq.pipeline import Pipeline

logger = logging.getLogger(__name__)


def warn_restarting_legs(pipeline: Pipeline, told: set[str] | None = None) -> None:
    """One line per leg whose filter restarted at most of its valid samples (see
    :meth:`~estimator.machine.MachineEstimator.restarting_legs`): its rows look valid.
    ``told``: the legs already told of (the service's, once each), updated."""
    estimator = pipeline.estimator
    for leg, (restarts, samples) in estimator.restarting_legs().items():
        if told is not None:
            if leg in told:
                continue
            told.add(leg)
        stale_s = estimator.legs[leg].stale_after_s
        cycles = estimator.legs[leg].settings.stale_after_cycles
        logger.warning(
            "legs.%s: %d of its %d valid samples came more than its stale time (%.3g ms: "
            "%g x its cycle time, %.3g ms) after the one before, so the filter, contact and "
            "near-constant window restarted at each (force_N is force_raw_N): is it sent "
            "less often? set its cycle time (%s)",
            leg,
            restarts,
            samples,
            stale_s * 1e3,
            cycles,
            stale_s / cycles * 1e3,
            pipeline.sampler.legs[leg].cycle_time_key,
        )
