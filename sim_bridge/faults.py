"""Fault injection: what goes wrong on the bus and in the sensors, reproducibly.

Pure computation; the only state is a seeded :class:`numpy.random.Generator` and what a
stuck sensor holds. Times are seconds of **simulated** time since the bridge started
(cycle 0 starts at 0; a window is active for ``start <= t < start + duration``), so a
fault hits the same frames at any ``--speed``. The faults and their command-line flags:

``--drop P``
    Each frame is lost on the wire with probability P. The sender built it, so its
    rolling counter advanced: the receiver sees the next frame's counter jump (``counter``).
``--bad-crc P``
    Each frame is sent with its CRC byte inverted with probability P (``crc``).
``--freeze-counter TARGET@START:DURATION``
    The message's rolling counter stops advancing: every frame in the window repeats the
    last counter sent before it (``counter``); afterwards it advances from there again.
    TARGET is a message (``LEG_SB1_F1``), a config leg (``SB1_F1``, meaning its message, or its
    trigger chamber's transducer or page), one J1939 transducer (``HYD_PRESS@0x21``) or all
    transducers sending a message (``HYD_PRESS``), one page of a multiplexed message
    (``MUXHUB#1``) or all its pages (``MUXHUB``).
``--silent TARGET@START:DURATION``
    The message is not sent in the window (``stale`` after the stale time). Nothing is
    built either, so its counter resumes where it stopped. TARGET as above.
``--stuck LEG@START:DURATION``
    Both chamber pressures of the leg stay at the values of the window's first frame.
``--out-of-range LEG@START:DURATION``
    The leg's piston pressure is sent as ``out_of_range_Pa`` (default 45 MPa, above the
    transducers' 40 MPa but inside the DBC's 64.5 MPa), status still ok (``range``). A
    DBC range ending below it does not clip it (the service judges that range too), only
    what the signal's bits hold does.
``--sensor-fault LEG@START:DURATION``
    The leg's status signal says ``sensor_fault`` (``status_sensor_fault``), or where its
    value table has none, the value naming a fault (:func:`fault_status`: ``Fault``,
    ``Error``, ...; ``status_Error``).
``--pause START:DURATION``
    Nothing at all is sent in the window (a bus-off, a pulled connector); ground truth is
    still written. Counters resume where they stopped.
``--seed N``
    Seeds the generator of ``--drop`` and ``--bad-crc``: the same seed and flags drop and
    corrupt the same frames; without one a fresh seed is drawn and logged.

Every flag except the probabilities and the seed may be given more than once. Each frame
draws two random numbers, whether or not it is dropped, so changing ``--drop`` does not
move which frames ``--bad-crc`` hits.

>>> FaultWindow.parse("SB1_F2@5:3")
FaultWindow(target='SB1_F2', start_s=5.0, duration_s=3.0)
>>> FaultWindow.parse("30:1.5", targeted=False)
FaultWindow(target='', start_s=30.0, duration_s=1.5)
"""

import math
import secrets
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from dbc.errors import ConfigError
from sim_bridge.frames import LegOverride
from sim_bridge.result import SimulationResult, leg_column
from sim_bridge.schedule import NS_PER_S
from sim_bridge.senders import message_of

#: The source named by errors about fault flags.
SOURCE = "fault flags"
#: Status value-table name that ``--sensor-fault`` sends.
SENSOR_FAULT_STATUS = "sensor_fault"
#: Words of a status value naming a fault, for a DBC without ``sensor_fault`` (in order):
#: J1939 transducers' ``ShortCircuit``/``OpenCircuit``, German DBCs' ``Sensorfehler``,
#: ``Kabelbruch``, ``Kurzschluss``, French ``Défaut``, ``Erreur``.
FAULT_WORDS = (
    "fault",
    "error",
    "fail",
    "short",
    "open",
    "broken",
    "fehler",
    "defekt",
    "st\u00f6rung",
    "kurzschluss",
    "bruch",
    "d\u00e9faut",
    "erreur",
)


def fault_status(names: frozenset[str]) -> str | None:
    """The status value a sensor fault sends, of a leg's value-table ``names``:
    ``sensor_fault``, else the first (in name order) with a word of :data:`FAULT_WORDS`
    in it (a held-out DBC's ``Fault``, ``SensorError``); None if none names a fault.

    >>> fault_status(frozenset({"Ok", "Warning", "Error", "NotAvailable"}))
    'Error'
    >>> fault_status(frozenset({"i.O.", "Kurzschluss", "Kabelbruch", "SNA"}))
    'Kurzschluss'
    >>> fault_status(frozenset({"Ok", "OpenCircuit", "ShortCircuit", "NotAvailable"}))
    'ShortCircuit'
    >>> fault_status(frozenset({"ok", "busy"})) is None
    True
    """
    if SENSOR_FAULT_STATUS in names:
        return SENSOR_FAULT_STATUS
    for word in FAULT_WORDS:
        found = sorted(name for name in names if word in name.lower())
        if found:
            return found[0]
    return None


@dataclass(frozen=True, slots=True)
class FaultWindow:
    """A fault on ``target`` for ``duration_s`` of simulated time from ``start_s``."""

    #: Leg or message name; empty for bus-wide faults.
    target: str
    start_s: float
    duration_s: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.start_s) and self.start_s >= 0):
            raise ValueError(f"start must be a number of seconds >= 0, got {self.start_s!r}")
        if not (math.isfinite(self.duration_s) and self.duration_s > 0):
            raise ValueError(f"duration must be a number of seconds > 0, got {self.duration_s!r}")

    @classmethod
    def parse(cls, text: str, *, targeted: bool = True) -> "FaultWindow":
        """Read ``TARGET@START:DURATION`` (or ``START:DURATION`` when not ``targeted``)."""
        syntax = "TARGET@START:DURATION, e.g. SB1_F1@10:2" if targeted else "START:DURATION"
        target, at, times = text.rpartition("@")
        if targeted != bool(at) or (targeted and not target):
            raise ValueError(f"expected {syntax} (seconds), got {text!r}")
        start, colon, duration = times.partition(":")
        try:
            if not colon:
                raise ValueError
            start_s, duration_s = float(start), float(duration)
        except ValueError:
            raise ValueError(f"expected {syntax} (seconds), got {text!r}") from None
        return cls(target, start_s, duration_s)

    def active(self, sim_t_ns: int) -> bool:
        start_ns = round(self.start_s * NS_PER_S)
        return start_ns <= sim_t_ns < start_ns + round(self.duration_s * NS_PER_S)

    def __str__(self) -> str:
        where = f"{self.target}@" if self.target else ""
        return f"{where}{self.start_s:g}:{self.duration_s:g}"


@dataclass(frozen=True)
class FaultConfig:
    """Which faults to inject; the default injects none. See the module docstring."""

    #: Probability that a frame is lost on the wire.
    drop_probability: float = 0.0
    #: Probability that a frame is sent with a wrong CRC.
    bad_crc_probability: float = 0.0
    freeze_counter: tuple[FaultWindow, ...] = ()
    silent: tuple[FaultWindow, ...] = ()
    stuck: tuple[FaultWindow, ...] = ()
    out_of_range: tuple[FaultWindow, ...] = ()
    sensor_fault: tuple[FaultWindow, ...] = ()
    pause: tuple[FaultWindow, ...] = ()
    #: Seed of the random faults; None draws a fresh one (see :attr:`FaultInjector.seed`).
    seed: int | None = None
    #: Piston pressure an ``out_of_range`` fault sends.
    out_of_range_Pa: float = 45.0e6

    def __post_init__(self) -> None:
        for name in ("drop_probability", "bad_crc_probability"):
            value = getattr(self, name)
            if not (0.0 <= value <= 1.0):
                raise ValueError(f"{name} must be within 0..1, got {value!r}")
        if not math.isfinite(self.out_of_range_Pa):
            raise ValueError(f"out_of_range_Pa must be finite, got {self.out_of_range_Pa!r}")

    @property
    def any(self) -> bool:
        """Some fault is configured."""
        return bool(
            self.drop_probability
            or self.bad_crc_probability
            or self.freeze_counter
            or self.silent
            or self.stuck
            or self.out_of_range
            or self.sensor_fault
            or self.pause
        )


@dataclass(frozen=True)
class FaultTargets:
    """What the faults may name: the sent messages, each leg's message, status names."""

    messages: tuple[str, ...]
    #: Leg -> the message carrying its pressures.
    leg_messages: Mapping[str, str]
    #: Leg -> the names of its status value table (empty when it has no status signal).
    leg_status_names: Mapping[str, frozenset[str]] = field(default_factory=dict)
    #: Leg -> the simulated leg it plays, where that has another name.
    simulated_legs: Mapping[str, str] = field(default_factory=dict)

    def no_leg(self, target: str) -> str:
        """Why ``target`` is no leg: the legs are the config's, a simulated leg's name
        is not (a config leg may be called like another simulated leg than it plays)."""
        reason = f"no leg {target!r}; the legs are {', '.join(self.leg_messages)}"
        players = [leg for leg, simulated in self.simulated_legs.items() if simulated == target]
        if players:
            reason += f" (the config's names: simulated leg {target} is {players[0]}'s)"
        return reason


@dataclass(frozen=True, slots=True)
class FrameFate:
    """What happens to one built frame."""

    #: False: lost on the wire (built, counter advanced, never sent).
    send: bool = True
    corrupt_crc: bool = False
    #: Repeat the last counter instead of advancing it.
    freeze_counter: bool = False


class FaultInjector:
    """Decides each frame's fate and each leg's faulty values for one run.

    Raises :class:`~daq.errors.ConfigError` when a fault names an unknown leg or message.
    """

    def __init__(self, faults: FaultConfig, targets: FaultTargets) -> None:
        self.faults = faults
        #: The seed in use (drawn when ``faults.seed`` is None), to log for a rerun.
        self.seed = faults.seed if faults.seed is not None else secrets.randbits(32)
        self._rng = np.random.default_rng(self.seed)
        self._freeze = [
            pair
            for w in faults.freeze_counter
            for pair in _message_windows(w, "--freeze-counter", targets)
        ]
        self._silent = [
            pair for w in faults.silent for pair in _message_windows(w, "--silent", targets)
        ]
        for flag, windows in (
            ("--stuck", faults.stuck),
            ("--out-of-range", faults.out_of_range),
            ("--sensor-fault", faults.sensor_fault),
        ):
            for window in windows:
                _check_leg(flag, window, targets)
        #: Leg -> the status value a sensor fault sends (:func:`fault_status`).
        self._fault_status: dict[str, str] = {}
        for window in faults.sensor_fault:
            names = targets.leg_status_names.get(window.target, frozenset())
            status = fault_status(names)
            if status is None:
                raise ConfigError(
                    SOURCE,
                    f"--sensor-fault {window}",
                    f"leg {window.target} has no status value naming a fault in the DBC "
                    f"({SENSOR_FAULT_STATUS!r}, or one with {', '.join(FAULT_WORDS)} in its "
                    f"name); its status values: {', '.join(sorted(names)) or 'none'}",
                )
            self._fault_status[window.target] = status
        self._random = bool(faults.drop_probability or faults.bad_crc_probability)
        #: Stuck window index -> the (piston, rod) pressures it holds.
        self._held: dict[int, tuple[float, float]] = {}

    def paused(self, sim_t_ns: int) -> bool:
        """The whole bus is silent at this time."""
        return any(window.active(sim_t_ns) for window in self.faults.pause)

    def silent(self, message: str, sim_t_ns: int) -> bool:
        """``message`` is not sent at this time."""
        return any(m == message and w.active(sim_t_ns) for m, w in self._silent)

    def fate(self, message: str, sim_t_ns: int) -> FrameFate:
        """The fate of the next built frame of ``message``."""
        freeze = any(m == message and w.active(sim_t_ns) for m, w in self._freeze)
        if not self._random:
            return FrameFate(freeze_counter=freeze)
        draw_drop, draw_crc = self._rng.random(2)
        return FrameFate(
            send=bool(draw_drop >= self.faults.drop_probability),
            corrupt_crc=bool(draw_crc < self.faults.bad_crc_probability),
            freeze_counter=freeze,
        )

    def overrides(
        self,
        result: SimulationResult,
        row: int,
        sim_t_ns: int,
        columns: Mapping[str, int] | None = None,
    ) -> dict[str, LegOverride]:
        """The legs whose pressures or status a fault changes at this time; ``columns``:
        each leg's column in ``result`` (see :func:`~sim_bridge.result.leg_column`)."""
        faults = self.faults
        changed: dict[str, tuple[float, float, str | None]] = {}

        def current(leg: str) -> tuple[float, float, str | None]:
            if leg in changed:
                return changed[leg]
            column = leg_column(leg, columns)
            return (
                float(result.p_piston_Pa[row, column]),
                float(result.p_rod_Pa[row, column]),
                None,
            )

        for index, window in enumerate(faults.stuck):
            if window.active(sim_t_ns):
                p_piston, p_rod, status = current(window.target)
                held = self._held.setdefault(index, (p_piston, p_rod))
                changed[window.target] = (*held, status)
        for window in faults.out_of_range:
            if window.active(sim_t_ns):
                _, p_rod, status = current(window.target)
                changed[window.target] = (faults.out_of_range_Pa, p_rod, status)
        for window in faults.sensor_fault:
            if window.active(sim_t_ns):
                p_piston, p_rod, _ = current(window.target)
                changed[window.target] = (p_piston, p_rod, self._fault_status[window.target])
        return {leg: LegOverride(*values) for leg, values in changed.items()}


def _check_leg(flag: str, window: FaultWindow, targets: FaultTargets) -> None:
    if window.target not in targets.leg_messages:
        raise ConfigError(
            SOURCE,
            f"{flag} {window}",
            targets.no_leg(window.target),
        )


def _message_windows(
    window: FaultWindow, flag: str, targets: FaultTargets
) -> list[tuple[str, FaultWindow]]:
    """(sender, window) pairs for a fault that names a sender, a leg, or a DBC message
    sent by several J1939 transducers (``HYD_PRESS``: every ``HYD_PRESS@0x..``) or in
    pages (``MUXHUB``: every ``MUXHUB#..``)."""
    if window.target in targets.messages:
        return [(window.target, window)]
    if window.target in targets.leg_messages:
        return [(targets.leg_messages[window.target], window)]
    senders = [sender for sender in targets.messages if message_of(sender) == window.target]
    if senders:
        return [(sender, window) for sender in senders]
    raise ConfigError(
        SOURCE,
        f"{flag} {window}",
        f"no message or {targets.no_leg(window.target).removeprefix('no ')}; "
        f"the messages are {', '.join(targets.messages)}",
    )
