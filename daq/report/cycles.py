"""Movement cycles and phases of a recording, and the soil metrics of each cycle.

Pure computation on :mod:`daq.report.tracks` arrays.

A cycle is a run of ``MACHINE_STATE`` frames with one ``Machine_CycleCount``; a new
one also begins where ``Machine_CycleTime`` runs backwards by more than
:data:`RESTART_S` under the same count (a controller that restarted its cycle without
counting). A cycle begins at ``t - Machine_CycleTime`` of its first frame (the state
message comes every 100 ms; this places the boundary on the frame that started the
cycle), unless that is before the previous ``MACHINE_STATE`` frame (an implausible
cycle time): then at its first frame. The first cycle begins with the recording, the
last ends with it. A recording without ``MACHINE_STATE`` is one cycle.

Per cycle and leg, the peak and the near-constant pressure (the highest mean over a
sliding ``near_constant_window_s``) come from the estimator's own
:class:`~estimator.metrics.SoilMetricsTracker`, fed with the valid filtered pressures
of the cycle exactly as the live service feeds it.
"""

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from daq.report.tracks import BoolArray, FloatArray, LegTrack, StateTrack
from estimator.metrics import SoilMetrics, SoilMetricsTracker

#: ``Machine_CycleTime`` running back by more than this under one count starts a cycle.
RESTART_S = 0.5


@dataclass(frozen=True, slots=True)
class Cycle:
    """One movement cycle: frames with ``start_s <= t < end_s`` belong to it."""

    #: ``Machine_CycleCount`` (completed cycles before it); None: no machine state.
    count: int | None
    start_s: float
    end_s: float
    #: The recording's last cycle, which also takes the frames at ``end_s``.
    final: bool = False

    def contains(self, t_s: FloatArray) -> BoolArray:
        """Which of the times ``t_s`` fall into this cycle."""
        before_end = t_s <= self.end_s if self.final else t_s < self.end_s
        return np.asarray((t_s >= self.start_s) & before_end, dtype=np.bool_)

    @property
    def duration_s(self) -> float:
        return self.end_s - self.start_s

    @property
    def label(self) -> str:
        return "whole recording" if self.count is None else f"cycle {self.count}"


@dataclass(frozen=True, slots=True)
class PhaseSpan:
    """A run of one movement phase, ``start_s`` to the first frame of the next phase."""

    phase: str
    start_s: float
    end_s: float


@dataclass(frozen=True, slots=True)
class CycleMetrics:
    """The soil metrics of one leg over one cycle."""

    cycle: Cycle
    leg: str
    metrics: SoilMetrics


def split_cycles(state: StateTrack, start_s: float, end_s: float) -> list[Cycle]:
    """The cycles of a recording spanning ``start_s .. end_s`` (see the module docstring).

    >>> import numpy as np
    >>> state = StateTrack(np.array([10.0, 10.1, 55.05]), np.array([3, 3, 4]),
    ...                    np.array([44.9, 45.0, 0.05]), ("unfold", "idle", "idle"))
    >>> [(c.count, c.start_s, c.end_s) for c in split_cycles(state, 9.0, 60.0)]
    [(3, 9.0, 55.0), (4, 55.0, 60.0)]
    """
    if len(state) == 0:
        return [Cycle(None, start_s, end_s, final=True)]
    counts: list[int] = []
    starts: list[float] = []
    previous_time_s = math.inf
    previous_t_s = start_s
    for t_s, count, time_in_cycle_s in zip(
        state.t_s.tolist(), state.cycle_count.tolist(), state.cycle_time_s.tolist(), strict=True
    ):
        restarted = time_in_cycle_s < previous_time_s - RESTART_S
        previous_time_s = time_in_cycle_s
        if not counts or count != counts[-1] or restarted:
            begin_s = t_s - time_in_cycle_s
            starts.append(begin_s if previous_t_s <= begin_s <= t_s else t_s)  # NaN: t_s
            counts.append(count)
        previous_t_s = t_s
    starts[0] = min(start_s, starts[0])
    ends = [*starts[1:], max(end_s, starts[-1])]
    finals = [False] * (len(counts) - 1) + [True]
    return [Cycle(c, a, b, f) for c, a, b, f in zip(counts, starts, ends, finals, strict=True)]


def phase_spans(state: StateTrack, end_s: float) -> list[PhaseSpan]:
    """Runs of one phase; the last one ends at ``end_s``.

    >>> import numpy as np
    >>> state = StateTrack(np.array([0.0, 0.1, 0.2]), np.array([0, 0, 0]),
    ...                    np.array([0.0, 0.1, 0.2]), ("idle", "fold", "fold"))
    >>> [(span.phase, span.start_s, span.end_s) for span in phase_spans(state, 0.5)]
    [('idle', 0.0, 0.1), ('fold', 0.1, 0.5)]
    """
    spans: list[PhaseSpan] = []
    for t_s, phase in zip(state.t_s.tolist(), state.phase, strict=True):
        if spans and spans[-1].phase == phase:
            continue
        if spans:
            spans[-1] = PhaseSpan(spans[-1].phase, spans[-1].start_s, t_s)
        spans.append(PhaseSpan(phase, t_s, t_s))
    if spans:
        spans[-1] = PhaseSpan(spans[-1].phase, spans[-1].start_s, max(end_s, spans[-1].start_s))
    return spans


def leg_cycle_metrics(
    track: LegTrack,
    cycle: Cycle,
    *,
    limit_Pa: float,
    window_s: float,
    max_gap_s: float = math.inf,
) -> SoilMetrics:
    """The soil metrics of ``track``'s valid samples within ``cycle``."""
    tracker = SoilMetricsTracker(limit_Pa, window_s, max_gap_s)
    use = cycle.contains(track.t_s) & track.valid & np.isfinite(track.pressure_Pa)
    for t_s, pressure_Pa in zip(
        track.t_s[use].tolist(), track.pressure_Pa[use].tolist(), strict=True
    ):
        tracker.update(t_s, pressure_Pa)
    return tracker.metrics


def cycle_metrics(
    tracks: Mapping[str, LegTrack],
    cycles: Sequence[Cycle],
    *,
    limit_Pa: float,
    window_s: float,
    max_gap_s: Mapping[str, float] | None = None,
) -> list[CycleMetrics]:
    """Every leg's metrics in every cycle, cycle by cycle, legs in ``tracks``' order."""
    gaps = max_gap_s or {}
    return [
        CycleMetrics(
            cycle,
            leg,
            leg_cycle_metrics(
                track,
                cycle,
                limit_Pa=limit_Pa,
                window_s=window_s,
                max_gap_s=gaps.get(leg, math.inf),
            ),
        )
        for cycle in cycles
        for leg, track in tracks.items()
    ]


@dataclass(frozen=True)
class CycleClock:
    """Frame time -> time in cycle, from the ``MACHINE_STATE`` frames of each cycle.

    Between two state frames of a cycle the time in cycle is interpolated linearly (so a
    cycle played at half speed maps onto the machine's own seconds); before the first
    and after the last it runs on at the cycle's mean rate (1 with a single frame). A
    cycle without state frames (the part of the recording before the first) runs at 1
    from its start.
    """

    cycles: tuple[Cycle, ...]
    #: Per cycle: its state frames' times and times in cycle, and the rate between them.
    frame_t_s: tuple[FloatArray, ...]
    cycle_time_s: tuple[FloatArray, ...]
    rate: tuple[float, ...]

    @classmethod
    def of(cls, state: StateTrack, cycles: Sequence[Cycle]) -> "CycleClock":
        frames, times, rates = [], [], []
        usable = np.isfinite(state.cycle_time_s)
        for cycle in cycles:
            inside = cycle.contains(state.t_s) & usable
            t_s, time_s = state.t_s[inside], state.cycle_time_s[inside]
            span_s = float(t_s[-1] - t_s[0]) if t_s.size > 1 else 0.0
            rate = float(time_s[-1] - time_s[0]) / span_s if span_s > 0 else 1.0
            frames.append(t_s)
            times.append(time_s)
            rates.append(rate if rate > 0 else 1.0)
        return cls(tuple(cycles), tuple(frames), tuple(times), tuple(rates))

    def __call__(self, t_s: FloatArray) -> FloatArray:
        """The time in cycle of each frame time (NaN outside every cycle).

        >>> import numpy as np
        >>> state = StateTrack(np.array([100.0, 102.0, 104.0]), np.array([0, 0, 0]),
        ...                    np.array([1.0, 2.0, 3.0]), ("idle",) * 3)
        >>> clock = CycleClock.of(state, [Cycle(0, 98.0, 110.0, final=True)])
        >>> clock(np.array([98.0, 101.0, 104.0, 106.0])).tolist()
        [0.0, 1.5, 3.0, 4.0]
        """
        t = np.asarray(t_s, dtype=np.float64)
        out = np.full(t.shape, np.nan)
        for cycle, frames, times, rate in zip(
            self.cycles, self.frame_t_s, self.cycle_time_s, self.rate, strict=True
        ):
            inside = cycle.contains(t)
            if frames.size == 0:
                out[inside] = (t[inside] - cycle.start_s) * rate
                continue
            here = t[inside]
            mapped = np.interp(here, frames, times)
            before, after = here < frames[0], here > frames[-1]
            mapped[before] = times[0] - (frames[0] - here[before]) * rate
            mapped[after] = times[-1] + (here[after] - frames[-1]) * rate
            out[inside] = mapped
        return out
