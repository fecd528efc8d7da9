"""Reading recordings for the calibration: the file-touching edge.

Each recording (a service MCAP file) is replayed from ``/can/raw`` through the
pipeline of the machine configuration (``--config``, else the one embedded in the
file), exactly as live; the leg estimates are sampled every :data:`PERIOD_S` like the
``<prefix>/ground`` snapshots. The movement phase comes from the machine state's frames
(``[signals]``, by default ``MACHINE_STATE``) of the same replay (so also from a
recording made without ``[recording] signals``). A CAN log of another tool (candump
``.log``, ``.asc``, ``.blf``, ...) is replayed the same way and needs ``--config``.
Several recordings are read one after the other, each with a fresh pipeline, and their
instants pooled: each CAN log, and each run of the service among the MCAP files and
directories given (a rotated run's files chained in the order of the run, as replay and
report read them).
"""

import tomllib
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from daq.errors import RecordingError
from daq.mcap_file import CONFIG_ATTACHMENT
from daq.mcap_reading import RecordedAttachment, RecordedMessage, RecordingStream
from daq.payloads import signals as signals_payload
from daq.recording_run import expand, runs
from daq.replay import Machine, embedded_machine, is_can_log, recording_results
from daq.report.tracks import StateRow, StateSignals, StateTrack
from dbc.errors import ConfigError
from dbc.machine import load_machine_config
from dbc.machine_signals import phase_meanings
from estimator.calibration import Snapshots, quasi_static, snapshots
from estimator.leg import LegEstimate

#: Spacing of the snapshots, s (the service's default ``ground_rate_hz`` of 10).
PERIOD_S = 0.1
#: Snapshots either side that must be steady (0.5 s).
WINDOW = 5
#: A leg's filtered force may change by at most this over the window.
MAX_CHANGE_N = 5000.0
#: Movement phases in which no leg stroke or fold moves; others are left out (cylinder
#: friction and inertia break the balance there). A recording without machine state
#: is judged on the forces alone. A DBC that names the phases otherwise (``0 "Ruhe"``)
#: or not at all is read by their numbers (:func:`dbc.machine_signals.phase_meanings`).
STILL_PHASES = ("idle", "move_carriage", "rotate")


@dataclass(frozen=True)
class Instants:
    """The quasi-static instants of all recordings, pooled."""

    legs: tuple[str, ...]
    t_s: npt.NDArray[np.float64]
    #: Filtered forces as recorded (the configured calibration applied).
    force_N: npt.NDArray[np.float64]
    contact: npt.NDArray[np.bool_]
    #: Snapshots read in all.
    total: int
    #: Of them, those with every leg valid and steady, in any phase.
    steady: int
    #: The movement phases seen (as decoded, in the order first seen; empty without
    #: machine state), and those of them that are still.
    phases: tuple[str, ...] = ()
    still_phases: tuple[str, ...] = ()
    #: The legs valid in no snapshot of any recording.
    never_valid: tuple[str, ...] = ()
    #: Snapshots of the longest recording (an instant needs :data:`WINDOW` either side).
    longest: int = 0

    def why_none(self) -> str:
        """Why there is no instant (:attr:`t_s` empty), for the user."""
        if not self.steady and self.longest <= 2 * WINDOW:
            return (
                f"no quasi-static instant: the longest recording has {self.longest} snapshots "
                f"({self.longest * PERIOD_S:.1f} s), and an instant needs "
                f"{WINDOW * PERIOD_S:.1f} s steady either side"
            )
        if not self.steady:
            return (
                f"no quasi-static instant: none of {self.total} snapshots had every leg "
                f"valid and steady"
                + (
                    f" ({', '.join(self.never_valid)} never valid: the balance needs every "
                    "leg's force)"
                    if self.never_valid
                    else ""
                )
            )
        return (
            f"no quasi-static instant: {self.steady} of {self.total} snapshots had every leg "
            f"valid and steady, none in a still movement phase ({', '.join(STILL_PHASES)}; "
            f"the machine state said {', '.join(self.phases)})"
        )


def machine_for(paths: Sequence[Path], config_path: Path | None) -> Machine:
    """``config_path``'s machine, else the one embedded in the first recording (of a
    directory, its first file), which the recordings embedding a config must all name
    (one machine's recordings: a campaign's folder holds several)."""
    if config_path is not None:
        return load_machine_config(config_path)
    files = expand(paths)
    first = files[0]
    if is_can_log(first):
        raise ConfigError(first, "", "calibrating from a CAN log needs --config")
    machine = embedded_machine(_attachments(first), first)
    machine_id = machine[0].machine_id
    for path in files[1:]:
        other = None if is_can_log(path) else _embedded_id(_attachments(path))
        if other is not None and other != machine_id:
            raise RecordingError(
                path,
                f"a recording of machine {other!r}, {first} of {machine_id!r}: calibrate one "
                "machine at a time (--config reads them all as one)",
            )
    return machine


def _attachments(path: Path) -> dict[str, bytes]:
    """A recording file's attachments: read up to its first message (the recorder writes
    them before)."""
    attachments = {}
    try:
        with open(path, "rb") as stream:
            for record in RecordingStream(stream, str(path), warn=False):  # read again
                if isinstance(record, RecordedMessage):
                    break
                if isinstance(record, RecordedAttachment):
                    attachments[record.name] = record.data
    except OSError as exc:
        raise RecordingError(path, f"cannot read it: {exc.strerror or exc}") from exc
    return attachments


def _embedded_id(attachments: Mapping[str, bytes]) -> str | None:
    """The machine id of an embedded config; None without one (or unreadable: the
    replay reads every recording with the first one's config anyway)."""
    try:
        machine = tomllib.loads(attachments[CONFIG_ATTACHMENT].decode()).get("machine")
    except (KeyError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return None
    machine_id = machine.get("id") if isinstance(machine, dict) else None
    return machine_id if isinstance(machine_id, str) else None


def read_instants(paths: Sequence[Path], machine: Machine, channel: str | None = None) -> Instants:
    """The quasi-static instants of every recording in ``paths`` (of CAN logs, only
    ``channel``'s frames when it is given)."""
    legs = tuple(machine[0].legs)
    parts: list[Snapshots] = []
    total = steady = longest = 0
    phases: dict[str, None] = {}
    ever_valid = np.zeros(len(legs), dtype=bool)
    config = machine[0]
    meanings = _phase_meanings(machine)
    # A leg is stale as in the service: after stale_after_cycles of its cycle times (the
    # slowest leg's, one time for the snapshots of all).
    stale_s = config.estimator.stale_after_s(max(leg.cycle_time_s for leg in config.legs.values()))
    for files in recordings(paths):
        snaps, states = _replayed(files, machine, channel, stale_s)
        if not len(snaps.t_s):
            raise RecordingError(files[0], "no leg estimates: no leg frames to replay")
        still = _still(states, snaps.t_s, meanings)
        steady_here = quasi_static(snaps, WINDOW, MAX_CHANGE_N)
        keep = steady_here & still
        total += len(snaps.t_s)
        longest = max(longest, len(snaps.t_s))
        steady += int(steady_here.sum())
        ever_valid |= snaps.valid.any(axis=0)
        phases.update(dict.fromkeys(phase for _, _, _, phase in states))
        parts.append(
            Snapshots(
                legs, snaps.t_s[keep], snaps.force_N[keep], snaps.valid[keep], snaps.contact[keep]
            )
        )
    return Instants(
        legs=legs,
        t_s=np.concatenate([p.t_s for p in parts]),
        force_N=np.vstack([p.force_N for p in parts]),
        contact=np.vstack([p.contact for p in parts]),
        total=total,
        steady=steady,
        phases=tuple(phases),
        still_phases=tuple(phase for phase in phases if meanings.get(phase) in STILL_PHASES),
        never_valid=tuple(leg for leg, ever in zip(legs, ever_valid, strict=True) if not ever),
        longest=longest,
    )


def _phase_meanings(machine: Machine) -> dict[str, str]:
    """The movement phase of each decoded value of the machine's phase signal."""
    config, database = machine
    ref = config.signals.phase
    if ref is None:
        return {}
    signal = database.get_message_by_name(ref.message).get_signal_by_name(ref.signal)
    return phase_meanings(signal.choices)


def recordings(paths: Sequence[Path]) -> list[list[Path]]:
    """The recordings ``paths`` name, each as the files one pipeline replays: a CAN log
    alone; the MCAP files of each run of the service among the files and directories
    given, in the order of the run (a directory was "cannot read it: Is a directory")."""
    logs = [path for path in paths if not path.is_dir() and is_can_log(path)]
    others = [path for path in paths if path not in logs]
    return [[log] for log in logs] + ([files for _, files in runs(others)] if others else [])


def _replayed(
    files: Sequence[Path], machine: Machine, channel: str | None, stale_s: float
) -> tuple[Snapshots, list[StateRow]]:
    """The leg estimates of one recording (a CAN log, or the files of one run), replayed,
    sampled every :data:`PERIOD_S` as they come (an hour of estimates kept took ~0.5 GB),
    and the machine states (of the machine state's frames whose CRC was fine)."""
    states: list[StateRow] = []
    names = StateSignals.of(machine[0])

    def estimates() -> Iterator[LegEstimate]:
        for result in recording_results(files, machine, channel=channel):
            yield from result.estimates
            decoded = result.decoded
            if decoded is not None and names is not None and decoded.message == names.message:
                state = StateTrack.row(signals_payload(decoded), names)
                if state is not None:
                    states.append(state)

    return snapshots(estimates(), tuple(machine[0].legs), PERIOD_S, stale_s), states


def _still(
    rows: Sequence[StateRow], t_s: npt.NDArray[np.float64], meanings: Mapping[str, str]
) -> npt.NDArray[np.bool_]:
    """True at the times whose movement phase (the latest machine state before) is still;
    ``meanings``: the phase each decoded value stands for."""
    if not rows:
        return np.ones(t_s.shape, dtype=bool)
    state = StateTrack.of(rows)
    latest = np.searchsorted(state.t_s, t_s, side="right") - 1
    phases = np.array([meanings.get(phase, "") for phase in state.phase])
    return (latest >= 0) & np.isin(phases[np.maximum(latest, 0)], STILL_PHASES)
