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
- **The machine state, the carriage and the inclination cylinders** are the config's
  ``[signals]`` (:mod:`dbc.machine_signals`; by default the project DBC's names wherever
  the DBC has them): the phase by its value-table name, the completed cycles, the time
  since the cycle started, the carriage position, each base's inclination angle (in its
  unit), chamber pressures and status.
- **Every other signal** is found by its name in the DBC: ``<LEG>_Stroke`` (a simulated
  or a config leg), and ``Bridge_FoldAngle``, ``Bridge_RotationAngle`` without
  ``[stability]``.
- Counter and CRC signals (``[protection.<MESSAGE>]``) are left to the
  :class:`~dbc.encoding.FrameEncoder`. A signal nobody supplies is sent as 0 (clipped into
  its range) and listed in :attr:`FrameBuilder.defaulted`; a periodic message none of whose
  signals is supplied is not sent at all, nor is one with nested multiplexing
  (:attr:`FrameBuilder.skipped`; a leg's chamber in such a message is refused).
- A **multiplexed message** is sent as one sender per page (:mod:`sim_bridge.senders`):
  each cycle time, one frame of each multiplexer value its signals use, in value order,
  each with that page's signals (and the counter and CRC where that page has them).

Status signals say the first ``status_ok`` value of their chamber unless a fault says
otherwise. Every
number is clipped into its DBC signal's ``[minimum, maximum]`` (cantools' strict encoder
refuses anything else), fault values included; the pressure signals' DBC range
(-1 .. 64.535 MPa) is wider than the transducers' (-0.1 .. 40 MPa), so an out-of-range
fault of e.g. 45 MPa still goes out unchanged. NaN (no data) is sent as 0.
"""

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from cantools.database.can import Database, Message, Signal

from dbc.decoding import SignalValue
from dbc.errors import ConfigError
from dbc.machine import TRIGGERS, ChamberSignal, LegConfig, MachineConfig
from dbc.protection import Protection
from dbc.signal_range import decoded_bounds
from dbc.units import chamber_unit
from sim_bridge.getters import Getter, configured_getters, in_signal_unit, named_getters
from sim_bridge.leg_map import LegMap, leg_map
from sim_bridge.result import SimulationResult
from sim_bridge.schedule import NS_PER_MS, NS_PER_S, MessageCycle
from sim_bridge.senders import multiplexer_pages, on_page, sender_name


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
    #: The leg's sample is made when this chamber's value arrives (its trigger chamber).
    triggers: bool
    pressure: Signal
    #: The multiplexer values of the frames carrying this chamber (its signal's, or the
    #: one page the config's ``multiplexer`` names); None: every frame.
    pages: tuple[int, ...] | None
    #: Factor from the pressure signal's DBC unit to Pa.
    to_Pa: float
    #: Added to the simulation's gauge pressure: the atmosphere, for an absolute
    #: transducer (:attr:`dbc.machine.ChamberSignal.atmosphere_Pa`).
    atmosphere_Pa: float
    status: Signal | None
    #: What the status signal says when the sensor is fine.
    status_nominal: SignalValue
    #: Every status value this chamber's leg takes as fine (names and numbers).
    status_ok: frozenset[object] = frozenset()


@dataclass(frozen=True, slots=True)
class _MessagePlan:
    """What one sender's frames carry."""

    message: str
    #: J1939 source address the frames are sent from; None: the DBC's frame ID.
    source_address: int | None
    #: The multiplexer signal and its value (the page) in these frames; None: not multiplexed.
    multiplexer: str | None
    page: int | None
    chambers: tuple[_ChamberSignals, ...]
    #: Signals found by name, with their getters and the factor from the signal's DBC
    #: unit to SI (what the encoder divides by: a pressure in bar is clipped in bar).
    named: tuple[tuple[Signal, Getter, float], ...]
    #: Signals sent as a constant (nobody supplies them).
    constants: tuple[tuple[Signal, SignalValue], ...]
    #: The frames carry the message's rolling counter (all but a multiplexed message's
    #: pages without it; also True for a message without a counter).
    counted: bool
    #: The frames carry the message's CRC.
    crc: bool


class FrameBuilder:
    """Builds each periodic sender's signal values from a simulation row.

    A *sender* (:mod:`sim_bridge.senders`) is one message, or for a J1939 message mapped
    to source addresses one per address (``HYD_PRESS@0x21``; a chamber of the message
    pinning none, reading every sender, is in each of their frames), or for a
    multiplexed message one per page (``MUXHUB#1``);
    each sends at its message's cycle time. Within one instant the senders go out in DBC,
    address and page order, except that one carrying a leg's trigger chamber without its
    other chamber (in another page, from another address, or in another message) goes
    after the others: each leg sample then pairs the chamber values of one simulation row
    (skew 0), from the very first sample on.
    Values are in SI; the encoder turns them into the DBC's units. Constructed once
    from the machine configuration and the DBC; raises :class:`~dbc.errors.ConfigError`
    when the config's legs cannot be mapped onto the simulated legs
    (:func:`~sim_bridge.leg_map.leg_map`), or a leg's chamber is in a message with
    nested multiplexing.
    """

    def __init__(self, config: MachineConfig, database: Database) -> None:
        #: Which simulated leg plays each config leg.
        self.leg_map: LegMap = leg_map(config)
        columns = self.leg_map.columns
        chambers_by_sender: dict[tuple[str, int | None], list[_ChamberSignals]] = {}
        for leg in config.legs.values():
            for chamber in TRIGGERS:
                mapped: ChamberSignal = getattr(leg, chamber)
                message = database.get_message_by_name(mapped.message)
                if multiplexer_pages(message) is None:
                    raise ConfigError(
                        config.source,
                        f"legs.{leg.name}.{chamber}",
                        f"message {message.name} has nested multiplexing: the bridge plays "
                        "one multiplexer signal only (the service decodes it)",
                    )
                chambers_by_sender.setdefault((mapped.message, mapped.source_address), []).append(
                    _chamber_signals(message, leg, columns[leg.name], chamber, mapped)
                )
        # Where the config places a signal, whatever the DBC calls it; else by its name.
        getters = named_getters(columns) | configured_getters(config, database)
        self._plans: dict[str, _MessagePlan] = {}
        #: Signals sent as a constant 0, as "MESSAGE.SIGNAL".
        self.defaulted: list[str] = []
        #: Periodic messages not sent: the simulation supplies none of their signals, or
        #: they have nested multiplexing (no leg's chamber may be in such a message).
        self.skipped: list[str] = []
        #: The senders built, with their cycle times (the DBC's, or the config's: the
        #: message's or the transducer's ``cycle_time_ms``), in the order of an instant.
        self.cycles: list[MessageCycle] = []
        for message in database.messages:
            pages = multiplexer_pages(message)
            # A chamber pinning no sender reads every sender's frames: where others pin
            # senders, it is in each of theirs (a frame of the DBC's ID besides would come
            # from one of them, or from a sender nobody reads, its other chambers 0).
            any_sender = chambers_by_sender.get((message.name, None), [])
            addresses: list[int | None] = [
                *sorted(
                    a for name, a in chambers_by_sender if name == message.name and a is not None
                )
            ] or [None]
            cycle_times_ms = {
                address: cycle_time_ms
                for address in addresses
                if (cycle_time_ms := config.cycle_time_ms(message.name, address)) is not None
            }
            if not cycle_times_ms:  # not periodic
                continue
            if pages is None:
                self.skipped.append(message.name)
                continue
            plans = [
                _plan(
                    message,
                    address,
                    page,
                    [
                        *chambers_by_sender.get((message.name, address), ()),
                        *(any_sender if address is not None else ()),
                    ],
                    getters,
                    config.protection.get(message.name),
                    _sender_to_si(config, message.name, address),
                )
                for address in cycle_times_ms
                for page in pages
            ]
            if not any(plan.chambers or plan.named for plan in plans):
                self.skipped.append(message.name)
                continue
            for plan in plans:
                cycle_time_ms = cycle_times_ms[plan.source_address]
                self.defaulted += [
                    name
                    for name in (f"{message.name}.{signal.name}" for signal, _ in plan.constants)
                    if name not in self.defaulted
                ]
                sender = sender_name(message.name, plan.source_address, plan.page)
                self._plans[sender] = plan
                self.cycles.append(MessageCycle(sender, round(cycle_time_ms * NS_PER_MS)))
        # A sender carrying a leg's trigger chamber without the other goes after the other
        # senders of an instant, those of its message and of other messages (a leg's rod
        # in a frame of its own); sorted is stable: DBC, address and page order otherwise.
        self.cycles.sort(key=lambda cycle: _pairs_late(self._plans[cycle.message]))
        #: Leg name -> the sender of its trigger chamber (what faults on a leg act on).
        self.leg_messages = {
            leg.name: next(
                sender
                for sender, plan in self._plans.items()
                if any(c.leg == leg.name and c.triggers for c in plan.chambers)
            )
            for leg in config.legs.values()
        }

    def leg_status_names(self) -> dict[str, frozenset[str]]:
        """Leg -> the names every status signal of the leg has in its value table and
        the leg does not take as fine (what a fault may set them all to; empty without a
        status signal, or one without a value table). A status the legs of a message
        share, each fine with the others' fault bits (``SENSOR_FAULT_F1`` is fine for
        F2), offers each leg its own: the first fault name was sent for every leg."""
        names: dict[str, frozenset[str]] = {}
        for plan in self._plans.values():
            for chamber in plan.chambers:
                if chamber.status is None:
                    continue
                choices = frozenset(str(c) for c in (chamber.status.choices or {}).values())
                choices -= chamber.status_ok
                names[chamber.leg] = names.get(chamber.leg, choices) & choices
        return names

    @property
    def messages(self) -> list[str]:
        """The senders this builder can fill, in the order of an instant (:attr:`cycles`)."""
        return [cycle.message for cycle in self.cycles]

    def target(self, sender: str) -> tuple[str, int | None]:
        """The DBC message of ``sender`` and the J1939 source address it sends from."""
        plan = self._plans[sender]
        return plan.message, plan.source_address

    def has_crc(self, sender: str) -> bool:
        """``sender``'s frames carry a CRC (what ``--bad-crc`` can corrupt)."""
        return self._plans[sender].crc

    def counter_key(self, sender: str) -> tuple[str, int | None] | None:
        """The rolling counter ``sender``'s frames advance: the message's, per J1939
        source address, which the pages of a multiplexed message that carry it share (the
        receiver counts their frames in turn); None for a page without it."""
        plan = self._plans[sender]
        return (plan.message, plan.source_address) if plan.counted else None

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
        if plan.multiplexer is not None and plan.page is not None:
            values[plan.multiplexer] = plan.page
        for chamber in plan.chambers:
            override = (overrides or {}).get(chamber.leg)
            status: SignalValue
            if override is None:
                field = result.p_piston_Pa if chamber.chamber == "piston" else result.p_rod_Pa
                p_Pa = float(field[row, chamber.column])
                status = chamber.status_nominal
            else:
                piston = chamber.chamber == "piston"
                p_Pa = override.p_piston_Pa if piston else override.p_rod_Pa
                status = override.status or chamber.status_nominal
            p_Pa += chamber.atmosphere_Pa
            # Into the bits only, not the DBC's range: a pressure beyond the transducer's
            # range (a 3000 psi one at 216 bar, or --out-of-range) goes out beyond it, or as
            # the bits' end, which the service flags; clipped to the range's end it was a
            # valid sample the truth disagreed with.
            values[chamber.pressure.name] = clip(chamber.pressure, p_Pa, chamber.to_Pa, False)
            # A status the legs of the message share keeps a faulty leg's fault: the
            # next leg's "fine" overwrote it, and --sensor-fault sent nothing.
            if chamber.status is not None and (
                chamber.status.name not in values or status != chamber.status_nominal
            ):
                values[chamber.status.name] = status
        for signal, getter, to_si in plan.named:
            values[signal.name] = clip(signal, getter(result, row, cycle), to_si)
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


def clip(
    signal: Signal, value: SignalValue, to_si: float = 1.0, dbc_range: bool = True
) -> SignalValue:
    """``value`` (SI) clipped into the signal's DBC range (in its unit, ``to_si`` per unit;
    unless ``dbc_range`` is off) and what its bits hold (a DBC without a range); names pass
    unchanged, NaN becomes 0."""
    if isinstance(value, str):
        return value
    number = float(value)
    if math.isnan(number):
        number = 0.0
    if dbc_range and signal.minimum is not None:
        number = max(number, float(signal.minimum) * to_si)
    if dbc_range and signal.maximum is not None:
        number = min(number, float(signal.maximum) * to_si)
    low, high = decoded_bounds(signal)  # a DBC without a range: what the bits hold
    number = min(max(number, low * to_si), high * to_si)
    if not signal.is_float and signal.scale == 1 and signal.offset == 0 and to_si == 1.0:
        return round(number)
    return number


def _chamber_signals(
    message: Message, leg: LegConfig, column: int, chamber: str, mapped: ChamberSignal
) -> _ChamberSignals:
    in_Pa = chamber_unit(mapped.unit)
    assert in_Pa is not None  # the config loader checked the unit
    status = mapped.status
    return _ChamberSignals(
        leg=leg.name,
        column=column,
        chamber=chamber,
        triggers=chamber == leg.trigger,
        pressure=message.get_signal_by_name(mapped.signal),
        pages=mapped.mux_ids,
        to_Pa=in_Pa[0],
        atmosphere_Pa=mapped.atmosphere_Pa,
        status=message.get_signal_by_name(status.signal) if status is not None else None,
        status_nominal=status.nominal if status is not None else 0,
        status_ok=status.ok if status is not None else frozenset(),
    )


def _plan(
    message: Message,
    source_address: int | None,
    page: int | None,
    chambers: Iterable[_ChamberSignals],
    getters: Mapping[str, Getter],
    protection: Protection | None,
    to_si: Mapping[str, float],
) -> _MessagePlan:
    """What the frames of one sender carry: ``page``'s signals (None: all) of ``message``
    from ``source_address``; ``getters`` by signal name, or by ``MESSAGE.SIGNAL``;
    ``to_si``: the factors the encoder converts this sender's signals by."""
    mine = tuple(
        chamber
        for chamber in chambers
        if page is None or chamber.pages is None or page in chamber.pages
    )
    taken = {s.name for c in mine for s in (c.pressure, c.status) if s is not None}
    if protection is not None:
        taken |= set(protection.signals)
    named: list[tuple[Signal, Getter, float]] = []
    constants: list[tuple[Signal, SignalValue]] = []
    multiplexer = None
    for signal in message.signals:
        factor = to_si.get(signal.name, 1.0)
        if signal.is_multiplexer:
            multiplexer = signal.name
        elif not on_page(signal, page) or signal.name in taken:
            continue
        elif f"{message.name}.{signal.name}" in getters:
            named.append((signal, getters[f"{message.name}.{signal.name}"], factor))
        elif signal.name in getters:
            named.append((signal, in_signal_unit(signal, getters[signal.name]), factor))
        else:
            constants.append((signal, clip(signal, 0.0, factor)))

    def carried(name: str | None) -> bool:
        return name is not None and on_page(message.get_signal_by_name(name), page)

    return _MessagePlan(
        message=message.name,
        source_address=source_address,
        multiplexer=multiplexer,
        page=page,
        chambers=mine,
        named=tuple(named),
        constants=tuple(constants),
        counted=protection is None or protection.counter is None or carried(protection.counter),
        crc=protection is not None and carried(protection.crc),
    )


def _sender_to_si(
    config: MachineConfig, message: str, source_address: int | None
) -> Mapping[str, float]:
    """The factors to SI the encoder converts ``message``'s signals from
    ``source_address`` by (:meth:`dbc.encoding.FrameEncoder.encode`)."""
    factors = config.unit_factors.get(message, {})
    if source_address is None:
        return factors
    return config.sender_unit_factors.get((message, source_address), factors)


def _pairs_late(plan: _MessagePlan) -> bool:
    """``plan``'s frames carry a leg's trigger chamber but not its other chamber: sent
    after the other senders of an instant, the leg's sample pairs the chamber values of
    one simulation row (skew 0) from the very first sample on."""
    legs = [chamber.leg for chamber in plan.chambers]
    return any(chamber.triggers and legs.count(chamber.leg) == 1 for chamber in plan.chambers)
