"""What a report says about one recording: cycles, metrics, deviations; time axis, gaps.

Pure: :func:`analyse` turns a :class:`~daq.report.tracks.Recording` into a
:class:`ReportContent`, which the figures (:mod:`daq.report.figures`) and the page
(:mod:`daq.report.page`) only draw.

Times shown: with the machine state (``MACHINE_STATE``, or where ``[signals]`` puts it) in
the recording, the machine's time in cycle (as the paper's figures; a cycle played at
half speed still spans its 45 s); without it, seconds since the first frame. The header
keeps the wall-clock times.
"""

import math
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import UTC, datetime

import numpy as np

from daq.frames import DATED_FROM_S
from daq.report.cycles import (
    Cycle,
    CycleClock,
    CycleMetrics,
    PhaseSpan,
    cycle_metrics,
    phase_spans,
    split_cycles,
)
from daq.report.deviation import (
    DeviationStats,
    LegComparison,
    compare,
    deviation_stats,
    most_loaded,
    sample_period_s,
)
from daq.report.tracks import BoolArray, FloatArray, Recording
from daq.silences import leg_silences, stale_times_s
from estimator.settings import EstimatorSettings

#: Without a machine configuration, a step longer than this many sample periods of a
#: leg is drawn as a gap (the service's own default staleness is 3 cycle times).
GAP_PERIODS = 3.0


def log_time(t_s: float) -> str | None:
    """``t_s`` in words when it is a log's own time (no date to show), else None."""
    return f"{t_s:.3f} s (log time, no date)" if t_s < DATED_FROM_S else None


@dataclass(frozen=True)
class TimeAxis:
    """Frame time (Unix s) -> the time the report shows."""

    #: The recording's first frame time.
    start_t_s: float
    #: Time in cycle from the machine state; None: seconds since ``start_t_s``.
    clock: CycleClock | None
    #: The machine state's message (``[signals]``), for the label.
    state_message: str = "MACHINE_STATE"

    def __call__(self, t_s: FloatArray) -> FloatArray:
        if self.clock is not None:
            return self.clock(t_s)
        return np.asarray(t_s, dtype=np.float64) - self.start_t_s

    def at(self, t_s: float) -> float:
        """One time; NaN stays NaN."""
        return float(self(np.array([t_s]))[0])

    def before(self, t_s: float) -> float:
        """The time just before ``t_s``, e.g. a cycle's end (the next cycle starts at its
        end); the float just below, as Unix seconds resolve only ~0.2 us."""
        return self.at(math.nextafter(t_s, -math.inf))

    @property
    def in_cycle(self) -> bool:
        return self.clock is not None

    @property
    def label(self) -> str:
        if self.clock is not None:
            return f"time in cycle / s ({self.state_message})"
        start = datetime.fromtimestamp(self.start_t_s, UTC)
        return f"time since {log_time(self.start_t_s) or f'{start:%Y-%m-%d %H:%M:%S} UTC'} / s"


@dataclass(frozen=True)
class ReportContent:
    """Everything the report shows, computed."""

    recording: Recording
    #: The estimator settings the metrics use (the machine's, or the defaults).
    settings: EstimatorSettings
    cycles: list[Cycle]
    phases: list[PhaseSpan]
    #: Per cycle, per leg.
    metrics: list[CycleMetrics]
    #: Leg -> a step between two estimates longer than this is a gap (and, in the
    #: metrics, adds at most this to the time above the limit).
    gap_after_s: Mapping[str, float]
    #: Leg -> (times, seconds in all) it had no estimate for longer than its gap time
    #: (a sensor silent, the log's start or end included); only legs that had one.
    silences: Mapping[str, tuple[int, float]]
    #: Leg -> its usual step (the median) where that is longer than its gap time: its
    #: cycle time is shorter than the period it is sent at (:func:`slow_legs`).
    slow_legs: Mapping[str, float]
    #: Only with truth in the recording: leg -> matched samples, and the statistics of
    #: their stance (foot on the ground) and swing samples.
    comparisons: Mapping[str, LegComparison]
    deviations: Mapping[str, DeviationStats]
    swing_deviations: Mapping[str, DeviationStats]
    #: The leg with the highest mean true stance force (for Figure 5), if any.
    most_loaded: str | None
    #: The times shown in the pictures and tables.
    time: TimeAxis


def gap_after_s(recording: Recording) -> dict[str, float]:
    """Per leg: the machine's staleness time, else :data:`GAP_PERIODS` sample periods."""
    machine = recording.machine
    gaps: dict[str, float] = {}
    stale_s = stale_times_s(machine) if machine is not None else {}
    for leg, track in recording.legs.items():
        gaps[leg] = stale_s.get(leg, GAP_PERIODS * sample_period_s(track.t_s))
    return gaps


def silences(recording: Recording, gaps: Mapping[str, float]) -> dict[str, tuple[int, float]]:
    """Per leg of the recording or its machine: :func:`daq.silences.leg_silences` of its
    estimates made with both chambers heard, between the recording's first and last frame."""
    legs = recording.machine.legs if recording.machine else ()
    times = {leg: track.t_s[track.heard] for leg, track in recording.legs.items()}
    return leg_silences(times, legs, recording.start_t_s, recording.end_t_s, gaps)


def slow_legs(recording: Recording, gaps: Mapping[str, float]) -> dict[str, float]:
    """Per leg whose samples come, as a rule, further apart than its gap time: its median
    step. Its cycle time (the DBC's or the config's) is shorter than the period it is sent
    at, a multiplexed hub's ``GenMsgCycleTime`` given per frame where each page comes
    less often, say: every step is a silence, and the estimator (live as in the report)
    restarted its filter, contact and near-constant window at each sample, so the leg
    was drawn as gaps alone and its metrics were those of single samples."""
    found: dict[str, float] = {}
    for leg, track in recording.legs.items():
        if track.t_s.size < 3:
            continue
        step_s = float(np.median(np.diff(track.t_s)))
        if step_s > gaps.get(leg, math.inf):
            found[leg] = step_s
    return found


def analyse(recording: Recording) -> ReportContent:
    """Split into cycles, compute each cycle's metrics and, with truth, the deviations."""
    machine = recording.machine
    settings = machine.estimator if machine is not None else EstimatorSettings()
    cycles = split_cycles(recording.state, recording.start_t_s, recording.end_t_s)
    gaps = gap_after_s(recording)
    metrics = cycle_metrics(
        recording.legs,
        cycles,
        limit_Pa=settings.pressure_limit_Pa,
        window_s=settings.near_constant_window_s,
        max_gap_s={leg: gap for leg, gap in gaps.items() if math.isfinite(gap)},
    )
    comparisons = {}
    if len(recording.truth):
        comparisons = compare(
            recording.legs, recording.truth, settings.median_window, settings.contact_on_N
        )
    deviations = {leg: deviation_stats(c) for leg, c in comparisons.items()}
    clock = CycleClock.of(recording.state, cycles) if len(recording.state) else None
    return ReportContent(
        recording=recording,
        settings=settings,
        cycles=cycles,
        phases=phase_spans(recording.state, recording.end_t_s),
        metrics=metrics,
        gap_after_s=gaps,
        silences=silences(recording, gaps),
        slow_legs=slow_legs(recording, gaps),
        comparisons=comparisons,
        deviations=deviations,
        swing_deviations={leg: deviation_stats(c, stance=False) for leg, c in comparisons.items()},
        most_loaded=most_loaded(deviations),
        time=TimeAxis(recording.start_t_s, clock, recording.state_signals.message),
    )


def with_gaps(
    t_s: FloatArray, values: FloatArray, valid: BoolArray | None, gap_after_s: float
) -> tuple[FloatArray, FloatArray]:
    """``values`` ready to draw as a line: NaN where not ``valid``, and a NaN point
    inserted wherever two samples are more than ``gap_after_s`` apart.

    >>> import numpy as np
    >>> t, v = with_gaps(np.array([0.0, 0.01, 0.1, 0.11]), np.array([1.0, 2, 3, 4]),
    ...                  np.array([True, False, True, True]), 0.03)
    >>> t.tolist(), v.tolist()
    ([0.0, 0.01, 0.055, 0.1, 0.11], [1.0, nan, nan, 3.0, 4.0])
    """
    shown = np.array(values, dtype=np.float64)
    if valid is not None:
        shown[~np.asarray(valid, dtype=np.bool_)] = np.nan
    if not math.isfinite(gap_after_s) or t_s.size < 2:
        return np.array(t_s, dtype=np.float64), shown
    breaks = np.flatnonzero(np.diff(t_s) > gap_after_s) + 1
    midpoints = (t_s[breaks - 1] + t_s[breaks]) / 2
    return (
        np.insert(t_s, breaks, midpoints).astype(np.float64),
        np.insert(shown, breaks, np.nan).astype(np.float64),
    )


def on_axis(
    time: TimeAxis, t_s: FloatArray, values: FloatArray, valid: BoolArray | None, gap_after_s: float
) -> tuple[FloatArray, FloatArray]:
    """:func:`with_gaps`, then the times as ``time`` shows them, broken (a NaN point)
    wherever the shown time runs backwards: at a new cycle, lines start afresh.

    >>> import numpy as np
    >>> x, v = on_axis(TimeAxis(10.0, None), np.array([10.0, 11.0]), np.ones(2), None, 5.0)
    >>> x.tolist(), v.tolist()
    ([0.0, 1.0], [1.0, 1.0])
    """
    t, shown = with_gaps(t_s, values, valid, gap_after_s)
    x = time(t)
    breaks = np.flatnonzero(np.diff(x) < 0) + 1
    return (
        np.insert(x, breaks, np.nan).astype(np.float64),
        np.insert(shown, breaks, np.nan).astype(np.float64),
    )
