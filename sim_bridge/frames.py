"""From one row of a :class:`~sim_bridge.result.SimulationResult` to DBC signal values.

Pure computation. Which signal carries what:

- **Leg chambers** follow the machine configuration: ``[legs.<LEG>]`` names the piston
  and rod signals (in one message or two, J1939 ones from a source address each) and
  their status signals, so a different DBC works by editing the config. Each config leg
  plays one of the simulation's legs (:data:`~sim_bridge.result.LEGS`), as
  :mod:`sim_bridge.leg_map` finds it (by name, ``simulated_leg``, or derived). Pressures
  are in Pa here; the encoder converts them into the DBC signal's unit.
- **The bridge angles** are the ``[stability]`` ``rotation`` and ``fold`` signals where
  the config has that table, whatever their DBC names.
- **Every other signal** is found by its name in the DBC: ``INCL_<BASE>_pPiston`` /
  ``_pRod`` / ``_Status``, ``<LEG>_Stroke`` (a simulated or a config leg),
  ``<BASE>_InclinationAngle``,
  ``Bridge_FoldAngle``, ``Bridge_RotationAngle``, ``Carriage_Position``,
  ``Machine_Phase`` (value-table name), ``Machine_CycleCount`` (completed cycles) and
  ``Machine_CycleTime`` (time since the cycle started).
- Counter and CRC signals (``[protection.<MESSAGE>]``) are left to the
  :class:`~dbc.encoding.FrameEncoder`. A signal nobody supplies is sent as 0 (clipped into
  its range) and listed in :attr:`FrameBuilder.defaulted`; a periodic message none of whose
  signals is supplied is not sent at all, nor is a multiplexed one
  (:attr:`FrameBuilder.skipped`; a leg's chamber in a multiplexed message is refused).

Status signals say the first ``status_ok`` value of their chamber unless a fault says
otherwise. Every
number is clipped into its DBC signal's ``[minimum, maximum]`` (cantools' strict encoder
refuses anything else), fault values included; the pressure signals' DBC range
(-1 .. 64.535 MPa) is wider than the transducers' (-0.1 .. 40 MPa), so an out-of-range
fault of e.g. 45 MPa still goes out unchanged. NaN (no data) is sent as 0.
"""

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass

from cantools.database.can import Database, Message, Signal

from dbc.decoding import SignalValue
from dbc.errors import ConfigError
from dbc.machine import ChamberSignal, MachineConfig
from dbc.units import pressure_factor_to_Pa
from sim_bridge.leg_map import LegMap, leg_map
from sim_bridge.result import BASES, LEGS, PHASES, SimulationResult
from sim_bridge.schedule import NS_PER_MS, NS_PER_S, MessageCycle

#: A signal's value at one row: (result, row, completed cycles) -> physical value or name.
Getter = Callable[[SimulationResult, int, int], SignalValue]


@dataclass(frozen=True, slots=True)
class LegOverride:
    """What a fault makes one leg's message say instead of the simulation's values."""

    p_piston_Pa: float
    p_rod_Pa: float
    #: Status value-table name; None keeps the config's ``status_ok``.
    status: str | None = None


@dataclass(frozen=True, slots=True)
class Position:
    """Where a simulation time falls: which cycle, which row, how far into the cycle."""

    cycle: int
    row: int
    t_cycle_s: float


class Timeline:
    """Maps simulation time since the bridge started onto rows of a looping result.

    A cycle lasts ``len(result) * dt_s``; row ``i`` holds from ``i * dt_s`` until the next
    row (zero-order hold, as a sampling sensor would send it).

    >>> import numpy as np
    >>> timeline = Timeline(n_rows=4, dt_s=0.01)
    >>> timeline.position(50_000_000)
    Position(cycle=1, row=1, t_cycle_s=0.01)
    """

    def __init__(self, n_rows: int, dt_s: float) -> None:
        if n_rows < 2:
            raise ValueError(f"a simulation result needs at least 2 rows, got {n_rows}")
        if not (math.isfinite(dt_s) and dt_s > 0):
            raise ValueError(f"the result's time step must be > 0, got {dt_s!r} s")
        self.n_rows = n_rows
        self.dt_ns = max(1, round(dt_s * NS_PER_S))
        #: Length of one cycle, ns.
        self.cycle_ns = n_rows * self.dt_ns

    @classmethod
    def of(cls, result: SimulationResult) -> "Timeline":
        return cls(len(result), result.dt_s)

    def position(self, sim_t_ns: int) -> Position:
        cycle, t_in_cycle_ns = divmod(sim_t_ns, self.cycle_ns)
        row = t_in_cycle_ns // self.dt_ns
        return Position(cycle, row, row * self.dt_ns / NS_PER_S)


@dataclass(frozen=True, slots=True)
class _ChamberSignals:
    """One chamber pressure of a leg in a sender's frame, and its status signal."""

    leg: str
    #: The leg's column in the result's per-leg arrays (its simulated leg).
    column: int
    #: "piston" or "rod".
    chamber: str
    pressure: Signal
    #: Factor from the pressure signal's DBC unit to Pa.
    to_Pa: float
    status: Signal | None
    #: What the status signal says when the sensor is fine.
    status_nominal: SignalValue


@dataclass(frozen=True, slots=True)
class _MessagePlan:
    message: str
    #: J1939 source address the frames are sent from; None: the DBC's frame ID.
    source_address: int | None
    chambers: tuple[_ChamberSignals, ...]
    #: Signals found by name, with their getters.
    named: tuple[tuple[Signal, Getter], ...]
    #: Signals sent as a constant (nobody supplies them).
    constants: tuple[tuple[Signal, SignalValue], ...]


def sender_name(message: str, source_address: int | None) -> str:
    """What the bridge calls one sender: the message, and ``@0x21`` for a J1939 transducer."""
    return message if source_address is None else f"{message}@0x{source_address:02X}"


class FrameBuilder:
    """Builds each periodic sender's signal values from a simulation row.

    A *sender* is one message, or for a J1939 message mapped to several source
    addresses (one transducer per chamber) one per address (``HYD_PRESS@0x21``);
    each sends at its message's cycle time. Within one instant the senders of a
    message go out in address order, those of the legs' other chambers before those
    of trigger chambers: each leg sample then pairs the chamber values of one
    simulation row (skew 0), from the very first sample on. Values are in SI; the encoder turns
    them into the DBC's units. Constructed once from the machine configuration and
    the DBC; raises :class:`~dbc.errors.ConfigError` when the config's legs cannot be
    mapped onto the simulated legs (:func:`~sim_bridge.leg_map.leg_map`).
    """

    def __init__(self, config: MachineConfig, database: Database) -> None:
        status_ok = config.status_ok[0]
        protected = {
            (name, signal)
            for name, protection in config.protection.items()
            for signal in (protection.counter, protection.crc)
            if signal is not None
        }
        self._with_crc = frozenset(
            name for name, protection in config.protection.items() if protection.crc is not None
        )
        #: Which simulated leg plays each config leg.
        self.leg_map: LegMap = leg_map(config)
        columns = self.leg_map.columns
        chambers_by_sender: dict[tuple[str, int | None], list[_ChamberSignals]] = {}
        for leg in config.legs.values():
            for chamber in ("piston", "rod"):
                mapped: ChamberSignal = getattr(leg, chamber)
                message = database.get_message_by_name(mapped.message)
                if message.is_multiplexed():
                    raise ConfigError(
                        config.source,
                        f"legs.{leg.name}.{chamber}",
                        f"message {message.name} is multiplexed: the bridge cannot play it "
                        "(the service decodes it)",
                    )
                chambers_by_sender.setdefault((mapped.message, mapped.source_address), []).append(
                    _chamber_signals(message, leg.name, columns[leg.name], chamber, mapped)
                )
        # Senders carrying a leg's trigger chamber go after the others of their message.
        triggers = {
            (leg.trigger_chamber.message, leg.trigger_chamber.source_address)
            for leg in config.legs.values()
        }
        getters = _named_getters(status_ok, columns)
        # The bridge angles where [stability] says they are, whatever the DBC calls them.
        pose_getters: dict[tuple[str, str], Getter] = {}
        if config.stability is not None:
            stability = config.stability
            for ref, rad_per_unit, name in (
                (stability.rotation, stability.rotation_rad_per_unit, "Bridge_RotationAngle"),
                (stability.fold, stability.fold_rad_per_unit, "Bridge_FoldAngle"),
            ):
                # The simulation's angles are in degrees; the DBC's signal may be in another unit.
                pose_getters[(ref.message, ref.signal)] = _scaled(
                    getters[name], math.radians(1.0) / rad_per_unit
                )
        self._plans: dict[str, _MessagePlan] = {}
        #: Signals sent as a constant 0, as "MESSAGE.SIGNAL".
        self.defaulted: list[str] = []
        #: Periodic messages not sent: the simulation supplies none of their signals, or
        #: they are multiplexed (which the bridge cannot play; no leg's chamber may be in one).
        self.skipped: list[str] = []
        #: The senders built, with their cycle times (the DBC's, or the config's: the
        #: message's or the transducer's ``cycle_time_ms``), in DBC order.
        self.cycles: list[MessageCycle] = []
        for message in database.messages:
            addresses = sorted(
                {address for name, address in chambers_by_sender if name == message.name},
                key=lambda address: (
                    (message.name, address) in triggers,
                    -1 if address is None else address,
                ),
            ) or [None]
            cycle_times_ms = {
                address: cycle_time_ms
                for address in addresses
                if (cycle_time_ms := config.cycle_time_ms(message.name, address)) is not None
            }
            if not cycle_times_ms:
                continue
            if message.is_multiplexed():
                self.skipped.append(message.name)
                continue
            for address, cycle_time_ms in cycle_times_ms.items():
                chambers = tuple(chambers_by_sender.get((message.name, address), ()))
                taken = {s.name for c in chambers for s in (c.pressure, c.status) if s is not None}
                named: list[tuple[Signal, Getter]] = []
                constants: list[tuple[Signal, SignalValue]] = []
                for signal in message.signals:
                    if signal.name in taken or (message.name, signal.name) in protected:
                        continue
                    if (message.name, signal.name) in pose_getters:
                        named.append((signal, pose_getters[(message.name, signal.name)]))
                    elif signal.name == "Machine_Phase":
                        named.append((signal, _phase_getter(signal)))
                    elif signal.name in getters:
                        named.append((signal, getters[signal.name]))
                    else:
                        constants.append((signal, clip(signal, 0.0)))
                if not chambers and not named:
                    self.skipped.append(message.name)
                    continue
                self.defaulted += [
                    name
                    for name in (f"{message.name}.{signal.name}" for signal, _ in constants)
                    if name not in self.defaulted
                ]
                sender = sender_name(message.name, address)
                self._plans[sender] = _MessagePlan(
                    message.name, address, chambers, tuple(named), tuple(constants)
                )
                self.cycles.append(MessageCycle(sender, round(cycle_time_ms * NS_PER_MS)))
        #: Leg name -> the sender of its trigger chamber (what faults on a leg act on).
        self.leg_messages = {
            leg.name: sender_name(leg.trigger_chamber.message, leg.trigger_chamber.source_address)
            for leg in config.legs.values()
        }

    def leg_status_names(self) -> dict[str, frozenset[str]]:
        """Leg -> the names in its status signals' value tables (empty without one)."""
        names: dict[str, set[str]] = {}
        for plan in self._plans.values():
            for chamber in plan.chambers:
                choices = chamber.status.choices if chamber.status is not None else None
                names.setdefault(chamber.leg, set()).update(
                    str(choice) for choice in (choices or {}).values()
                )
        return {leg: frozenset(values) for leg, values in names.items()}

    @property
    def messages(self) -> list[str]:
        """The senders this builder can fill, in DBC order."""
        return list(self._plans)

    def target(self, sender: str) -> tuple[str, int | None]:
        """The DBC message of ``sender`` and the J1939 source address it sends from."""
        plan = self._plans[sender]
        return plan.message, plan.source_address

    def has_crc(self, sender: str) -> bool:
        """``sender``'s message carries a CRC (what ``--bad-crc`` can corrupt)."""
        return self._plans[sender].message in self._with_crc

    def signals(
        self,
        message: str,
        result: SimulationResult,
        row: int,
        cycle: int,
        overrides: Mapping[str, LegOverride] | None = None,
    ) -> dict[str, SignalValue]:
        """The signal values (SI) of sender ``message`` at ``row`` (counter, CRC left out)."""
        plan = self._plans[message]
        values: dict[str, SignalValue] = {}
        for chamber in plan.chambers:
            override = (overrides or {}).get(chamber.leg)
            status: SignalValue
            if override is None:
                field = result.p_piston_Pa if chamber.chamber == "piston" else result.p_rod_Pa
                p_Pa = float(field[row, chamber.column])
                status = chamber.status_nominal
            else:
                p_Pa = override.p_piston_Pa if chamber.chamber == "piston" else override.p_rod_Pa
                status = override.status or chamber.status_nominal
            values[chamber.pressure.name] = clip(chamber.pressure, p_Pa, chamber.to_Pa)
            if chamber.status is not None:
                values[chamber.status.name] = status
        for signal, getter in plan.named:
            values[signal.name] = clip(signal, getter(result, row, cycle))
        for signal, constant in plan.constants:
            values[signal.name] = constant
        return values

    def frames(
        self,
        result: SimulationResult,
        row: int,
        messages: Iterable[str],
        cycle: int,
        overrides: Mapping[str, LegOverride] | None = None,
    ) -> list[tuple[str, dict[str, SignalValue]]]:
        """(sender, signals) for each of ``messages`` (senders) at ``row``."""
        return [
            (message, self.signals(message, result, row, cycle, overrides)) for message in messages
        ]


def clip(signal: Signal, value: SignalValue, to_si: float = 1.0) -> SignalValue:
    """``value`` (SI) clipped into the signal's DBC range (in its unit, ``to_si`` per unit);
    names pass unchanged, NaN becomes 0."""
    if isinstance(value, str):
        return value
    number = float(value)
    if math.isnan(number):
        number = 0.0
    if signal.minimum is not None:
        number = max(number, float(signal.minimum) * to_si)
    if signal.maximum is not None:
        number = min(number, float(signal.maximum) * to_si)
    if not signal.is_float and signal.scale == 1 and signal.offset == 0 and to_si == 1.0:
        return round(number)
    return number


def _chamber_signals(
    message: Message, leg: str, column: int, chamber: str, mapped: ChamberSignal
) -> _ChamberSignals:
    factor = pressure_factor_to_Pa(mapped.unit)
    assert factor is not None  # the config loader checked the unit
    status = mapped.status
    return _ChamberSignals(
        leg=leg,
        column=column,
        chamber=chamber,
        pressure=message.get_signal_by_name(mapped.signal),
        to_Pa=factor,
        status=message.get_signal_by_name(status.signal) if status is not None else None,
        status_nominal=status.nominal if status is not None else 0,
    )


def _column(field: str, column: int) -> Getter:
    return lambda result, row, cycle: float(getattr(result, field)[row, column])


def _series(field: str) -> Getter:
    return lambda result, row, cycle: float(getattr(result, field)[row])


def _scaled(getter: Getter, factor: float) -> Getter:
    if factor == 1.0:
        return getter
    return lambda result, row, cycle: float(getter(result, row, cycle)) * factor


def _phase_getter(signal: Signal) -> Getter:
    """The phase by its value-table name when the DBC's table has the names, else its index."""
    names = {str(choice) for choice in (signal.choices or {}).values()}

    def phase(result: SimulationResult, row: int, cycle: int) -> SignalValue:
        index = int(result.phase[row])
        if 0 <= index < len(PHASES) and PHASES[index] in names:
            return PHASES[index]
        return index

    return phase


def _named_getters(status_ok: SignalValue, columns: Mapping[str, int]) -> dict[str, Getter]:
    """Getters of the signals found by name in the DBC (Machine_Phase aside); ``columns``:
    each config leg's column, whose ``<LEG>_Stroke`` is its simulated leg's."""
    getters: dict[str, Getter] = {
        "Bridge_FoldAngle": _series("fold_deg"),
        "Bridge_RotationAngle": _series("rotation_deg"),
        "Carriage_Position": _series("carriage_m"),
        "Machine_CycleCount": lambda result, row, cycle: cycle,
        "Machine_CycleTime": lambda result, row, cycle: float(result.t_s[row]),
    }
    for b, base in enumerate(BASES):
        getters[f"INCL_{base}_pPiston"] = _column("incl_p_piston_Pa", b)
        getters[f"INCL_{base}_pRod"] = _column("incl_p_rod_Pa", b)
        getters[f"INCL_{base}_Status"] = lambda result, row, cycle: status_ok
        getters[f"{base}_InclinationAngle"] = _column("inclination_deg", b)
    for leg, column in ({leg: i for i, leg in enumerate(LEGS)} | dict(columns)).items():
        getters[f"{leg}_Stroke"] = _column("stroke_m", column)
    return getters
