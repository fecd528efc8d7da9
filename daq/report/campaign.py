"""A campaign's table: per recording, cycle and foot, the soil figures. Pure but for reading.

:func:`run_rows` is the per-recording work of ``portal-daq report --campaign``: the
files of one run (one file, or the rotated files of one run of the service) in,
:class:`CampaignRow` s out. It only reads the files and computes, so any executor
can run it anywhere the files are (local processes, a Dask cluster:
:mod:`daq.report.campaign_run`). :func:`campaign_rows` is the pure part, on a
:class:`~daq.report.tracks.Recording` already read.

Per cycle (:func:`~daq.report.cycles.split_cycles`) and foot: the peak and the
near-constant contact pressure and the time above ``pressure_limit_Pa`` (the
estimator's own :class:`~estimator.metrics.SoilMetricsTracker`, as in the single
report), the fraction of the foot's estimates that were invalid, and, for the cycle
as a whole, the **weight residual**: at each estimate of the first leg, the sum of
the filtered forces of the legs in contact (each leg's latest estimate, no older
than its staleness time) minus the machine's weight, where every leg is valid; its
median and its largest magnitude over the cycle (NaN without the machine's
configuration, or without one complete instant).
"""

import logging
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from daq.errors import EmptyRecordingError
from daq.report.content import analyse
from daq.report.cycles import Cycle
from daq.report.loading import load_recording
from daq.report.tracks import FloatArray, LegTrack, Recording

logger = logging.getLogger(__name__)

NAN = math.nan


@dataclass(frozen=True, slots=True)
class CampaignRow:
    """One foot in one cycle of one recording. NaN where a figure is undefined."""

    #: The recording's name (its file, or the first .. last file of a rotated run).
    recording: str
    machine_id: str
    #: ``Machine_CycleCount``; -1 when the recording has no machine state (one cycle).
    cycle: int
    #: Start of the cycle (frame time, Unix seconds) and its length.
    cycle_start_s: float
    cycle_duration_s: float
    leg: str
    peak_pressure_Pa: float
    peak_t_s: float
    near_constant_pressure_Pa: float
    time_above_limit_s: float
    #: The foot's estimates in the cycle, and the fraction of them that were invalid.
    estimates: int
    invalid_fraction: float
    #: The cycle's weight residual (the same in every foot's row of the cycle).
    weight_residual_median_N: float
    weight_residual_max_abs_N: float
    #: The limit ``time_above_limit_s`` counts against (the machine's, or the default).
    pressure_limit_Pa: float
    #: False: a file of the recording ends without its summary (cut short by a crash or
    #: a power loss): read up to its last complete chunk, its end is missing.
    complete: bool


#: The table's columns, in order (the CSV header).
COLUMNS = tuple(f.name for f in fields(CampaignRow))


def run_rows(files: Sequence[Path], config_path: Path | None = None) -> list[CampaignRow]:
    """The rows of one recording (the files of one run); none of one that holds nothing
    (a file cut right after it was opened: a season has some); else raises as
    :func:`~daq.report.loading.load_recording` does."""
    try:
        recording = load_recording(list(files), config_path)
    except EmptyRecordingError as exc:
        logger.warning("%s: left out of the campaign", exc)
        return []
    return campaign_rows(recording)


def campaign_rows(recording: Recording) -> list[CampaignRow]:
    """Every foot's row in every cycle of ``recording``, cycle by cycle."""
    content = analyse(recording)
    weight_N = recording.machine.weight_N if recording.machine is not None else NAN
    residuals = {
        cycle: weight_residuals_N(recording.legs, cycle, content.gap_after_s, weight_N)
        for cycle in content.cycles
    }
    rows = []
    for entry in content.metrics:
        cycle, metrics = entry.cycle, entry.metrics
        track = recording.legs[entry.leg]
        inside = cycle.contains(track.t_s)
        estimates = int(inside.sum())
        invalid = int((inside & ~track.valid).sum())
        residual = residuals[cycle]
        rows.append(
            CampaignRow(
                recording=recording.name,
                machine_id=recording.machine_id,
                cycle=-1 if cycle.count is None else cycle.count,
                cycle_start_s=cycle.start_s,
                cycle_duration_s=cycle.duration_s,
                leg=entry.leg,
                peak_pressure_Pa=metrics.peak_pressure_Pa,
                peak_t_s=metrics.peak_t_s,
                near_constant_pressure_Pa=metrics.near_constant_pressure_Pa,
                time_above_limit_s=metrics.time_above_limit_s,
                estimates=estimates,
                invalid_fraction=invalid / estimates if estimates else NAN,
                weight_residual_median_N=float(np.median(residual)) if residual.size else NAN,
                weight_residual_max_abs_N=float(np.abs(residual).max()) if residual.size else NAN,
                pressure_limit_Pa=content.settings.pressure_limit_Pa,
                complete=recording.complete,
            )
        )
    return rows


def weight_residuals_N(
    legs: Mapping[str, LegTrack], cycle: Cycle, max_age_s: Mapping[str, float], weight_N: float
) -> FloatArray:
    """The weight residual at each instant of ``cycle`` where every leg is valid.

    The instants are the first leg's estimate times; each leg contributes its latest
    estimate at or before the instant, if no older than ``max_age_s[leg]``.

    >>> import numpy as np
    >>> def track(name, forces, contact=True):
    ...     n = len(forces)
    ...     return LegTrack(name, np.arange(n) * 0.01, np.array(forces), np.zeros(n),
    ...                     np.ones(n, bool), np.array(forces), np.full(n, contact),
    ...                     np.ones(n, bool))
    >>> legs = {"A": track("A", [60.0, 70.0]), "B": track("B", [40.0, 40.0]),
    ...         "C": track("C", [3.0, 3.0], contact=False)}
    >>> weight_residuals_N(legs, Cycle(None, 0.0, 1.0, final=True), {}, 100.0).tolist()
    [0.0, 10.0]
    """
    tracks = list(legs.values())
    if not tracks or not math.isfinite(weight_N):
        return np.empty(0)
    instants = tracks[0].t_s[cycle.contains(tracks[0].t_s)]
    total_N = np.zeros(instants.size)
    complete = np.ones(instants.size, dtype=np.bool_)
    for track in tracks:
        index = np.searchsorted(track.t_s, instants, side="right") - 1
        known = index >= 0
        index = np.maximum(index, 0)
        fresh = known & (instants - track.t_s[index] <= max_age_s.get(track.leg, math.inf))
        complete &= fresh & track.valid[index]
        total_N += np.where(track.contact[index], np.nan_to_num(track.force_N[index]), 0.0)
    return np.asarray(total_N[complete] - weight_N, dtype=np.float64)
