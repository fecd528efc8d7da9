"""What a report needs from one recording, as arrays: legs, machine state, truth, counts.

Pure: :class:`RecordingCollector` takes the recording's messages one by one (topic and
JSON payload, as :mod:`daq.mcap_file` wrote them; raw frames as :class:`RawFrame` s), and
what a replay of the raw frames derives (:meth:`RecordingCollector.derive`: signals and
bad frames, which a recording of batches does not store, and estimates when none were
recorded), and builds a :class:`Recording`. Opening the file is
:mod:`daq.report.loading`'s job.

All times are frame times, Unix seconds (``t_s``), on one time line that never runs back
(:mod:`daq.report.timeline`: a clock that stepped back, or was set from 1970, joins its
stretches in the order they were recorded; unchanged when it did not). A recorded
``null`` (NaN) stays NaN.
"""

import json
from array import array
from collections import Counter, defaultdict
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from daq.frames import RawFrame
from daq.mcap_file import BUS_TOPIC, RAW_TOPIC, RECORDING_TOPIC, TRUTH_TOPIC
from daq.mcap_reading import json_items
from daq.payloads import leg_ground
from daq.payloads import signals as signals_payload
from daq.pipeline import FrameResult
from daq.report.timeline import Timeline
from dbc.machine import MachineConfig
from dbc.protection import COUNTER_JUMP, CRC_FAULT
from estimator.validity import both_chambers_heard

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
IntArray = npt.NDArray[np.int64]


#: (t, force_N, pressure_Pa, valid, force_raw_N, contact, heard), (t, count, cycle time,
#: phase), (t, {leg: force}).
LegRow = tuple[float, float, float, bool, float, bool, bool]
StateRow = tuple[float, int, float, str]
TruthRow = tuple[float, dict[str, float]]

SIGNALS_PREFIX = "/signals/"
LEG_PREFIX, LEG_SUFFIX = "/leg/", "/ground"


def _number(value: Any) -> float:
    """A JSON number as float; null (a NaN on the way in) and anything else as NaN."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return float("nan")
    return float(value)


@dataclass(frozen=True)
class LegTrack:
    """One leg's recorded estimates, in time order."""

    leg: str
    t_s: FloatArray
    #: The configured filter over the valid raw forces (eq. 4), as published live; NaN
    #: before the first valid sample.
    force_N: FloatArray
    #: Eq. (5) on ``force_N``.
    pressure_Pa: FloatArray
    valid: BoolArray
    #: Eq. (4) on each sample alone, unfiltered.
    force_raw_N: FloatArray
    #: The estimator's contact decision (hysteresis on ``force_N``): off the ground, a
    #: foot has no soil pressure, whatever eq. (5) gives.
    contact: BoolArray
    #: Made with both chambers heard (neither ``piston_stale`` nor ``rod_stale``): a leg
    #: whose rod transducer fell silent while its piston one goes on has estimates, all
    #: invalid, and its sensors are silent all the same (the service's status says so).
    heard: BoolArray

    @staticmethod
    def row(payload: Mapping[str, Any]) -> LegRow:
        """What a track keeps of one ``/leg/<LEG>/ground`` payload."""
        return (
            _number(payload["t"]),
            _number(payload["force_N"]),
            _number(payload["pressure_Pa"]),
            bool(payload["valid"]),
            _number(payload["force_raw_N"]),
            bool(payload["contact"]),
            both_chambers_heard(payload["reasons"]),
        )


class LegColumns:
    """A leg's rows as they come, a typed array per column: 35 bytes a row where a tuple
    of Python objects took ~190, so that a long recording's report fits in memory (8 h
    of six legs at 100 Hz: ~0.6 GB instead of ~3 GB)."""

    def __init__(self) -> None:
        self.t_s, self.force_N, self.pressure_Pa, self.force_raw_N = (array("d") for _ in "1234")
        self.valid, self.contact, self.heard = array("b"), array("b"), array("b")

    def __len__(self) -> int:
        return len(self.t_s)

    def append(self, row: LegRow) -> None:
        t_s, force_N, pressure_Pa, valid, force_raw_N, contact, heard = row
        self.t_s.append(t_s)
        self.force_N.append(force_N)
        self.pressure_Pa.append(pressure_Pa)
        self.valid.append(valid)
        self.force_raw_N.append(force_raw_N)
        self.contact.append(contact)
        self.heard.append(heard)

    def track(self, leg: str, shift_s: float = 0.0) -> LegTrack:
        """The rows in time order (equal times in the order they came), their times less
        ``shift_s``."""

        def numbers(column: "array[float]") -> FloatArray:
            return np.array(column, dtype=np.float64)

        def flags(column: "array[int]") -> BoolArray:
            return np.array(column, dtype=np.bool_)

        t_s = numbers(self.t_s)
        order = np.argsort(t_s, kind="stable")
        return LegTrack(
            leg=leg,
            t_s=t_s[order] - shift_s,
            force_N=numbers(self.force_N)[order],
            pressure_Pa=numbers(self.pressure_Pa)[order],
            valid=flags(self.valid)[order],
            force_raw_N=numbers(self.force_raw_N)[order],
            contact=flags(self.contact)[order],
            heard=flags(self.heard)[order],
        )


@dataclass(frozen=True, slots=True)
class StateSignals:
    """Where a recording's machine state is: the message whose signals delimit movement
    cycles, and those signals (the machine config's ``[signals]``; without a config,
    the project DBC's names)."""

    message: str = "MACHINE_STATE"
    cycle_count: str = "Machine_CycleCount"
    cycle_time: str = "Machine_CycleTime"
    phase: str = "Machine_Phase"
    #: Seconds per unit of ``cycle_time``'s values (its DBC unit: ms, a time in cycle of
    #: 22,500 ms was 22,500 s).
    cycle_time_s_per_unit: float = 1.0

    @classmethod
    def of(cls, machine: MachineConfig | None) -> "StateSignals | None":
        """``machine``'s machine state; the defaults without one; None: its DBC has none."""
        if machine is None:
            return cls()
        signals = machine.signals
        message = signals.state_message
        if message is None:
            return None
        count, time, phase = (
            ref.signal if ref is not None else ""
            for ref in (signals.cycle_count, signals.cycle_time, signals.phase)
        )
        return cls(message, count, time, phase, signals.cycle_time_s_per_unit)

    @property
    def topic(self) -> str:
        return SIGNALS_PREFIX + self.message


@dataclass(frozen=True)
class StateTrack:
    """``MACHINE_STATE`` frames whose CRC was fine, in time order."""

    t_s: FloatArray
    #: Completed movement cycles (``Machine_CycleCount``).
    cycle_count: IntArray
    #: Time since the cycle started (``Machine_CycleTime``), s.
    cycle_time_s: FloatArray
    #: Movement phase name (``Machine_Phase``), or its number as text.
    phase: tuple[str, ...]

    @staticmethod
    def row(payload: Mapping[str, Any], names: StateSignals) -> StateRow | None:
        """What a track keeps of one payload of the machine state's message (``names``);
        None for a frame whose CRC failed or that has no cycle count."""
        signals = payload["signals"]
        count = signals.get(names.cycle_count)
        if not payload.get("crc_ok", True) or not isinstance(count, int | float):
            return None
        return (
            _number(payload["t"]),
            int(count),
            _number(signals.get(names.cycle_time)) * names.cycle_time_s_per_unit,
            str(signals.get(names.phase, "")),
        )

    @classmethod
    def of(cls, rows: Iterable[StateRow]) -> "StateTrack":
        ordered = sorted(rows, key=lambda row: row[0])
        columns = list(zip(*ordered, strict=True)) if ordered else [(), (), (), ()]
        return cls(
            t_s=np.array(columns[0], dtype=np.float64),
            cycle_count=np.array(columns[1], dtype=np.int64),
            cycle_time_s=np.array(columns[2], dtype=np.float64),
            phase=tuple(columns[3]),
        )

    def __len__(self) -> int:
        return int(self.t_s.size)


@dataclass(frozen=True)
class TruthTrack:
    """Simulation truth samples (``/sim/truth``), in time order."""

    #: Frame time of each sample: when its frames went onto the bus.
    t_s: FloatArray
    #: Leg -> true vertical foot force per sample (NaN: unknown).
    force_true_N: Mapping[str, FloatArray]

    @staticmethod
    def row(payload: Mapping[str, Any]) -> TruthRow:
        """What a track keeps of one ``/sim/truth`` payload: time, true force per leg."""
        legs = payload["legs"]
        return (
            _number(payload["t_unix_s"]),
            {leg: _number((legs[leg] or {}).get("force_true_N")) for leg in legs},
        )

    @classmethod
    def of(cls, rows: Iterable[TruthRow]) -> "TruthTrack":
        ordered = sorted(rows, key=lambda row: row[0])
        legs = sorted({leg for _, forces in ordered for leg in forces})
        nan = float("nan")
        return cls(
            t_s=np.array([t_s for t_s, _ in ordered], dtype=np.float64),
            force_true_N={
                leg: np.array([forces.get(leg, nan) for _, forces in ordered], dtype=np.float64)
                for leg in legs
            },
        )

    def __len__(self) -> int:
        return int(self.t_s.size)


@dataclass(frozen=True)
class RecordingCounts:
    """What went by in the recording, for the report's header."""

    #: Frames recorded (``/can/raw``), bad ones included.
    frames: int = 0
    #: Decoded frames per message (``/signals/<MESSAGE>``).
    messages: Mapping[str, int] = field(default_factory=dict)
    #: Bad frames by kind, as the service counts them: ``unknown_id``, ``wrong_dlc``,
    #: ``decode_error``, ``error_frame``, ``remote_frame``, and ``crc`` / ``counter`` for
    #: decoded frames whose protection failed.
    bad: Mapping[str, int] = field(default_factory=dict)
    #: Frames lost before they reached the bus interface, as the rolling counters tell.
    frames_lost: int = 0
    #: Leg estimates, and the invalid ones by reason.
    estimates: int = 0
    invalid: Mapping[str, int] = field(default_factory=dict)
    #: Bus state changes (``/daq/bus``) and truth samples (``/sim/truth``).
    bus_events: int = 0
    truth_samples: int = 0
    #: Frames lost before the service could handle them, as its ``/daq/bus`` loss
    #: events tell: by the kernel (socket receive buffer full) and by its queue.
    kernel_dropped: int = 0
    rx_dropped: int = 0
    #: Gaps in the recording (``/daq/recording``: recording stopped on a write error)
    #: and the seconds they lost.
    recording_gaps: int = 0
    recording_lost_s: float = 0.0
    #: Steps back of the frame times (and a clock set from before 2000): the times
    #: before each were moved to join the times after it (:mod:`daq.report.timeline`).
    clock_steps: int = 0


@dataclass(frozen=True)
class Recording:
    """Everything a report shows of one recording."""

    #: File name of the recording (for the header).
    name: str
    machine_id: str
    #: The machine configuration (``--config``, or the one embedded); None if neither.
    machine: MachineConfig | None
    #: First and last frame time in the recording.
    start_t_s: float
    end_t_s: float
    legs: Mapping[str, LegTrack]
    state: StateTrack
    truth: TruthTrack
    counts: RecordingCounts
    #: The estimates were recomputed from ``/can/raw`` (none were recorded).
    recomputed: bool = False
    #: The file ended with its summary (False: cut short, read to its last chunk).
    complete: bool = True

    @property
    def duration_s(self) -> float:
        return max(0.0, self.end_t_s - self.start_t_s)

    @property
    def state_signals(self) -> StateSignals:
        """Where the machine state was read from (its names where the DBC has none)."""
        return StateSignals.of(self.machine) or StateSignals()


class RecordingCollector:
    """Gathers a recording's messages; :meth:`recording` builds the :class:`Recording`.

    ``state_signals``: where the machine state is (None: nowhere); may be set before the
    first message (a recording's embedded config comes before its messages)."""

    def __init__(self, state_signals: StateSignals | None = StateSignals()) -> None:
        self.state_signals = state_signals
        self._legs: dict[str, LegColumns] = defaultdict(LegColumns)
        self._state: list[StateRow] = []
        self._truth: list[TruthRow] = []
        self._frames = 0
        self._frames_lost = 0
        self._messages: Counter[str] = Counter()
        self._bad: Counter[str] = Counter()
        self._invalid: Counter[str] = Counter()
        self._bus_events = 0
        self._dropped: Counter[str] = Counter()
        self._gaps: list[float] = []
        self._first_s = float("inf")
        self._last_s = float("-inf")
        #: The time lines of the frames as recorded, of the frames as a replay gives them
        #: (:meth:`derive`), and of each recorded topic's own frame times.
        self._frames_line = Timeline()
        self._derived_line = Timeline()
        self._lines: defaultdict[str, Timeline] = defaultdict(Timeline)

    @property
    def has_estimates(self) -> bool:
        return bool(self._legs)

    @property
    def has_signals(self) -> bool:
        return bool(self._messages)

    @property
    def frames(self) -> int:
        return self._frames

    @property
    def truth_samples(self) -> int:
        return len(self._truth)

    def add_frames(self, frames: Iterable[RawFrame]) -> None:
        """Raw frames of a ``/can/raw`` batch (what they decode to comes from :meth:`derive`)."""
        for frame in frames:
            self._frames += 1
            self._seen(self._frames_line.advance(frame.t_s))

    def derive(self, result: FrameResult, *, bad: bool, signals: bool, estimates: bool) -> None:
        """What a replay of one raw frame gave, as far as the recording lacks it: the kind
        of a bad frame (``bad``), the decoded signals with their CRC and counter checks
        (``signals``), the leg estimates (``estimates``)."""
        self._derived_line.advance(result.frame.t_s)
        if bad and result.error is not None:
            self._bad[result.error.kind] += 1
        if signals and result.decoded is not None:
            self._add_signals(result.decoded.message, signals_payload(result.decoded), derived=True)
        if estimates:
            for estimate in result.estimates:
                self.add_estimate(leg_ground(estimate), derived=True)

    def count_bad(self, kind: str, count: int) -> None:
        """Frames a replay left unused with no error of their own (``unmapped_source``:
        a leg's J1939 PGN from a source address no chamber maps)."""
        if count:
            self._bad[kind] += count

    def count_lost(self, lost: Counter[str]) -> None:
        """Frames lost before a CAN log was written, by ``kernel_dropped`` and
        ``rx_dropped`` (:func:`daq.replay.results`), as a recording's loss events."""
        self._dropped.update(lost)

    def add(self, topic: str, data: bytes) -> None:
        """One recorded JSON message; topics a report does not use are skipped (and
        ``/can/raw`` batches go to :meth:`add_frames`)."""
        if topic == RAW_TOPIC:  # a recording made before batches: one JSON frame
            raw = json.loads(data)
            self._frames += 1
            self._seen(self._frames_line.advance(_number(raw["t"])))
            if raw.get("error") is not None:
                self._bad[raw["error"]] += 1
        elif topic.startswith(SIGNALS_PREFIX):
            self._add_signals(topic.removeprefix(SIGNALS_PREFIX), json.loads(data))
        elif topic.startswith(LEG_PREFIX) and topic.endswith(LEG_SUFFIX):
            for estimate in json_items(data):
                self.add_estimate(estimate)
        elif topic == TRUTH_TOPIC:
            t_s, forces = TruthTrack.row(json.loads(data))
            self._truth.append((self._time(t_s, TRUTH_TOPIC), forces))
        elif topic == BUS_TOPIC:
            event = json.loads(data)
            lost = {key: event.get(key, 0) for key in ("kernel_dropped", "rx_dropped")}
            self._dropped.update(lost)
            self._bus_events += not any(lost.values())  # a loss keeps the state
        elif topic == RECORDING_TOPIC:
            lost_s = _number(json.loads(data).get("lost_s"))
            self._gaps.append(lost_s if lost_s == lost_s else 0.0)

    def _time(self, t_s: float, stream: str, *, derived: bool = False) -> float:
        """``t_s`` on the report's time line: a replayed frame's on the replay's, a
        recorded message's on its topic's (each topic is in processing order)."""
        return self._derived_line.at(t_s) if derived else self._lines[stream].advance(t_s)

    def _add_signals(
        self, message: str, payload: Mapping[str, Any], *, derived: bool = False
    ) -> None:
        self._messages[message] += 1
        if "faults" in payload:
            self._bad.update(str(fault) for fault in payload["faults"])
            self._frames_lost += int(payload.get("frames_lost", 0))
        elif not payload.get("crc_ok", True):  # recordings before the faults list
            self._bad[CRC_FAULT] += 1
        elif not payload.get("counter_ok", True):
            self._bad[COUNTER_JUMP] += 1
        names = self.state_signals
        if names is not None and message == names.message:
            state = StateTrack.row(payload, names)
            if state is not None:
                t_s = self._time(state[0], names.topic, derived=derived)
                self._state.append((t_s, *state[1:]))

    def add_estimate(self, payload: dict[str, Any], *, derived: bool = False) -> None:
        """One leg estimate in the shape of :func:`daq.payloads.leg_ground`; ``derived``:
        of the frame :meth:`derive` was given."""
        row = LegTrack.row(payload)
        t_s = self._time(row[0], LEG_PREFIX + payload["leg"], derived=derived)
        self._legs[payload["leg"]].append((t_s, *row[1:]))
        self._seen(t_s)
        self._invalid.update(payload["reasons"])

    def _seen(self, t_s: Any) -> None:
        t = _number(t_s)
        if t == t:  # not NaN
            self._first_s = min(self._first_s, t)
            self._last_s = max(self._last_s, t)

    def recording(
        self,
        name: str,
        machine: MachineConfig | None,
        *,
        machine_id: str,
        recomputed: bool = False,
        complete: bool = True,
    ) -> Recording:
        legs = list(machine.legs) if machine is not None else []
        legs += sorted(leg for leg in self._legs if leg not in legs)
        # The last stretch keeps its wall-clock times (the frames' line, else a topic's).
        line = (
            self._frames_line
            if self._frames
            else max(self._lines.values(), key=lambda line: line.steps, default=self._frames_line)
        )
        shift_s = line.offset_s
        first, last = (self._first_s, self._last_s) if self._last_s >= self._first_s else (0, 0)
        state, truth = StateTrack.of(self._state), TruthTrack.of(self._truth)
        return Recording(
            name=name,
            machine_id=machine_id,
            machine=machine,
            start_t_s=float(first) - shift_s,
            end_t_s=float(last) - shift_s,
            legs={leg: self._legs.get(leg, LegColumns()).track(leg, shift_s) for leg in legs},
            state=replace(state, t_s=state.t_s - shift_s),
            truth=replace(truth, t_s=truth.t_s - shift_s),
            counts=RecordingCounts(
                frames=self._frames,
                messages=dict(sorted(self._messages.items())),
                bad=dict(self._bad.most_common()),
                frames_lost=self._frames_lost,
                estimates=sum(len(rows) for rows in self._legs.values()),
                invalid=dict(self._invalid.most_common()),
                bus_events=self._bus_events,
                truth_samples=len(self._truth),
                kernel_dropped=self._dropped["kernel_dropped"],
                rx_dropped=self._dropped["rx_dropped"],
                recording_gaps=len(self._gaps),
                recording_lost_s=sum(self._gaps),
                clock_steps=line.steps,
            ),
            recomputed=recomputed,
            complete=complete,
        )
