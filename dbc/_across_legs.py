"""Checks and tables across the legs of a machine configuration, of what each leg's
chambers say about the senders on the bus: each simulated leg and each leg's chambers
taken once, a source address for every reader of a shared J1939 signal, and one unit
and one cycle time per J1939 transducer (:func:`unit_factors`,
:func:`sender_cycle_times_ms`). Called by :func:`dbc.machine.parse_machine_config`
once the legs are read; errors are raised through ``legs_table`` (``FILE: KEY: reason``).
"""

import logging
from collections.abc import Iterator, Mapping
from typing import TYPE_CHECKING

from cantools.database.can import Database

from dbc.decoding import is_j1939
from dbc.protection import protection_role
from dbc.toml_table import TomlTable
from dbc.units import chamber_unit, pressure_factor_to_Pa

if TYPE_CHECKING:
    from dbc.machine import ChamberSignal, LegConfig
    from dbc.protection import Protection

logger = logging.getLogger(__name__)


def _chambers(leg: "LegConfig") -> Iterator[tuple[str, "ChamberSignal"]]:
    """The leg's chambers by their key."""
    yield "piston", leg.piston
    yield "rod", leg.rod


def check_simulated_legs(legs_table: TomlTable, legs: Mapping[str, "LegConfig"]) -> None:
    """Each simulated leg is played onto one config leg at most."""
    taken: dict[str, str] = {}
    for name, leg in legs.items():
        if leg.simulated_leg is None:
            continue
        if leg.simulated_leg in taken:
            raise legs_table.error(
                f"{name}.simulated_leg",
                f"{leg.simulated_leg} is already legs.{taken[leg.simulated_leg]}'s simulated "
                "leg; each simulated leg plays onto one leg",
            )
        taken[leg.simulated_leg] = name


def check_own_chambers(legs_table: TomlTable, legs: Mapping[str, "LegConfig"]) -> None:
    """No leg reads both chambers of another (a leg table copied and not edited: its
    forces would be the other's, the weight check would count one foot twice). One
    chamber's transducer may be shared: chambers on a common line."""
    taken: dict[tuple[str, str], str] = {}
    for name, leg in legs.items():
        chambers = (str(leg.piston), str(leg.rod))
        if chambers in taken:
            raise legs_table.error(
                name,
                f"reads the chambers of legs.{taken[chambers]} ({', '.join(chambers)}): "
                "each leg needs its own",
            )
        taken[chambers] = name


def check_not_protection(
    legs_table: TomlTable, legs: Mapping[str, "LegConfig"], protection: Mapping[str, "Protection"]
) -> None:
    """No chamber reads its message's rolling counter, CRC or data ID nibble (a copied
    signal name, given a unit): the counter's 0..15 read as a valid pressure, and the
    bridge wrote the counter over the simulated one."""
    for leg in legs.values():
        for key, chamber in _chambers(leg):
            guard = protection.get(chamber.message)
            for role in ("counter", "crc", "data_id_nibble"):
                if guard is not None and getattr(guard, role) == chamber.signal:
                    raise legs_table.table(leg.name).error(
                        key,
                        f"{chamber.message}.{chamber.signal} is [protection."
                        f"{chamber.message}] {role}, not a pressure",
                    )


def warn_unchecked_protection(
    legs_table: TomlTable,
    legs: Mapping[str, "LegConfig"],
    protection: Mapping[str, "Protection"],
    database: Database,
) -> None:
    """One warning line per leg message whose DBC has a signal named as a rolling counter
    or a CRC (``Zaehler``, ``AliveCounter``, ``Pruefsumme``, ``Checksum``, ...) that its
    ``[protection.<MESSAGE>]`` does not name (or that has none): a config written for a
    foreign DBC took its frames unchecked, a frozen sender's or a corrupted frame's
    pressures valid, and nothing said so."""
    messages = dict.fromkeys(
        chamber.message for leg in legs.values() for _, chamber in _chambers(leg)
    )
    for name in messages:
        guard = protection.get(name)
        named = guard.signals if guard is not None else ()
        found = [
            f"{signal.name} (a {'rolling counter' if role == 'counter' else 'CRC'} by its name)"
            for signal in database.get_message_by_name(name).signals
            if (role := protection_role(signal)) is not None
            and signal.name not in named
            and (guard is None or getattr(guard, role) is None)
        ]
        if found:
            logger.warning(
                "%s: protection.%s: %s %s not checked: %s; name %s there (counter, crc, "
                "crc_algorithm as the sender computes it) to judge its frames",
                legs_table.source,
                name,
                ", ".join(found),
                "is" if len(found) == 1 else "are",
                f"[protection.{name}] names no {'crc' if guard.counter else 'counter'}"
                if guard is not None
                else f"the config has no [protection.{name}]",
                "it" if len(found) == 1 else "them",
            )


def sender_cycle_times_ms(
    legs_table: TomlTable, legs: Mapping[str, "LegConfig"], cycle_times_ms: Mapping[str, float]
) -> dict[tuple[str, int], float]:
    """The J1939 transducers whose chamber gives them another cycle time than their
    message's, ms, by message and source address; one transducer has one cycle time."""
    times: dict[tuple[str, int], tuple[float, str]] = {}
    for leg in legs.values():
        for key, chamber in _chambers(leg):
            if chamber.source_address is None:
                continue
            where = f"legs.{leg.name}.{key}"
            sender = (chamber.message, chamber.source_address)
            cycle_s, other = times.setdefault(sender, (chamber.cycle_time_s, where))
            if cycle_s != chamber.cycle_time_s:
                raise legs_table.table(leg.name).error(
                    key,
                    f"{chamber.message}@0x{chamber.source_address:02X} is sent every "
                    f"{1000 * chamber.cycle_time_s:g} ms here and every {1000 * cycle_s:g} ms "
                    f"for {other}: one transducer has one cycle time (give cycle_time_ms to both)",
                )
    return {
        sender: 1000.0 * cycle_s
        for sender, (cycle_s, _) in times.items()
        if sender[0] not in cycle_times_ms or cycle_s != cycle_times_ms[sender[0]] / 1000.0
    }


def check_senders(
    legs_table: TomlTable, legs: Mapping[str, "LegConfig"], database: Database
) -> None:
    """A J1939 signal that several chambers read (one transducer each, one PGN) needs each
    chamber's source address: without it, every transducer's frames would feed it."""
    readers: dict[tuple[str, str, object], list[tuple[str, str, int | None]]] = {}
    for leg in legs.values():
        for key, chamber in _chambers(leg):
            # Chambers on other pages of one signal are no two readers of one value.
            where = (chamber.message, chamber.signal, chamber.page and chamber.mux_ids)
            readers.setdefault(where, []).append((leg.name, key, chamber.source_address))
    for (message, signal, _), chambers in readers.items():
        if len(chambers) < 2 or not is_j1939(database.get_message_by_name(message)):
            continue
        for leg_name, key, address in chambers:
            if address is None:
                other_leg, other_key, other_address = next(
                    c for c in chambers if c[:2] != (leg_name, key)
                )
                sender = "any sender" if other_address is None else f"0x{other_address:02X}"
                raise legs_table.table(leg_name).error(
                    key,
                    f"{message}.{signal} is also legs.{other_leg}.{other_key}'s (from {sender}): "
                    "give each chamber its transducer's source_address",
                )


#: By message and signal name: the unit of the decoded values where it is not the DBC's.
DecodedUnits = dict[str, dict[str, str]]


def unit_factors(
    legs_table: TomlTable, legs: Mapping[str, "LegConfig"], database: Database
) -> tuple[dict[str, dict[str, float]], dict[tuple[str, int], dict[str, float]], DecodedUnits]:
    """Pa per DBC unit of every pressure signal: by message, what frames of any sender
    are decoded with (the unit of a chamber pinning no sender, else the DBC's; where the
    DBC's is none, the one unit all chambers of the signal agree on), and by message and
    J1939 sender, for the transducers whose chamber gives another unit than that; and
    what the decoded values are in, where that is not the DBC's unit (the label of
    ``/signals``: ``Pa``, or which senders are in Pa where the others are not).

    One sender has one unit: two for one source address, or a chamber pinning no sender
    in one unit and another chamber of the signal in another, stop the config.
    """
    factors: dict[str, dict[str, float]] = {}
    in_Pa: set[tuple[str, str]] = set()  # decoded in Pa, whichever the sender
    for message in database.messages:
        for signal in message.signals:
            factor = pressure_factor_to_Pa(signal.unit or "")
            if factor is not None:
                in_Pa.add((message.name, signal.name))
            if factor is not None and factor != 1.0:
                factors.setdefault(message.name, {})[signal.name] = factor
    # (message, signal) -> [(source address, factor, unit, leg, chamber key)]
    readers: dict[tuple[str, str], list[tuple[int | None, float, str, str, str]]] = {}
    for leg in legs.values():
        for key, chamber in _chambers(leg):
            unit_in_Pa = chamber_unit(chamber.unit)
            assert unit_in_Pa is not None  # checked when the chamber was read
            factor = unit_in_Pa[0]
            address = chamber.source_address
            others = readers.setdefault((chamber.message, chamber.signal), [])
            for other_address, _, other_unit, other_leg, other_key in others:
                pinned = None not in (address, other_address)
                if chamber_unit(other_unit) == unit_in_Pa or (pinned and address != other_address):
                    continue
                sender = (
                    f"both from 0x{address:02X}"
                    if pinned and address is not None
                    else "a chamber without source_address reads every sender"
                )
                if chamber.page is not None:  # inputs of one I/O module, each on a page
                    sender, rule = "pages of one signal", "a signal's pages have one unit"
                else:
                    rule = "one transducer has one unit"
                raise legs_table.table(leg.name).error(
                    key,
                    f"{chamber} is in {chamber.unit!r} here and in {other_unit!r} for "
                    f"legs.{other_leg}.{other_key} ({sender}); {rule}",
                )
            others.append((address, factor, chamber.unit, leg.name, key))
    for (message_name, signal_name), chambers in readers.items():
        unpinned = [factor for address, factor, *_ in chambers if address is None]
        agreed = {factor for _, factor, *_ in chambers}
        signal = database.get_message_by_name(message_name).get_signal_by_name(signal_name)
        in_dbc = pressure_factor_to_Pa(signal.unit or "")
        default = unpinned[0] if unpinned else in_dbc
        if default is None and len(agreed) == 1:
            default = agreed.pop()
        if default is not None:
            _set_factor(factors.setdefault(message_name, {}), signal_name, default)
            in_Pa.add((message_name, signal_name))
    by_sender: dict[tuple[str, int], dict[str, float]] = {}
    for (message_name, signal_name), chambers in readers.items():
        defaults = factors.get(message_name, {})
        for address, factor, *_ in chambers:
            if address is not None and factor != defaults.get(signal_name, 1.0):
                table = by_sender.setdefault((message_name, address), dict(defaults))
                _set_factor(table, signal_name, factor)
    units: DecodedUnits = {}
    for (message_name, signal_name), chambers in readers.items():
        if (message_name, signal_name) not in in_Pa:  # only some senders are converted
            senders = {address for address, *_ in chambers if address is not None}
            addresses = ", ".join(f"0x{address:02X}" for address in sorted(senders))
            unit = _dbc_unit(database, message_name, signal_name)
            units.setdefault(message_name, {})[signal_name] = (
                f"Pa from {addresses}{_absolute_from(chambers)}; "
                f"other senders as sent ({unit or 'no unit'} in the DBC)"
            )
    for message_name, signal_name in in_Pa:
        chambers = readers.get((message_name, signal_name), [])
        if chambers and all(_atmosphere_Pa(unit) > 0 for _, _, unit, *_ in chambers):
            units.setdefault(message_name, {})[signal_name] = "Pa absolute"
        elif absolute_from := _absolute_from(chambers):
            units.setdefault(message_name, {})[signal_name] = f"Pa{absolute_from}"
        elif _dbc_unit(database, message_name, signal_name) != "Pa":
            units.setdefault(message_name, {})[signal_name] = "Pa"
    return {name: table for name, table in factors.items() if table}, by_sender, units


def _absolute_from(chambers: list[tuple[int | None, float, str, str, str]]) -> str:
    """``"; absolute from 0x21, ..."`` naming the senders read in an absolute unit
    (``other senders`` for a chamber without ``source_address``), or ``""``."""
    absolute = {address for address, _, unit, *_ in chambers if _atmosphere_Pa(unit) > 0}
    names = sorted(f"0x{address:02X}" for address in absolute if address is not None)
    names += ["other senders"] * (None in absolute)
    return "; absolute from " + ", ".join(names) if names else ""


def _atmosphere_Pa(unit: str) -> float:
    """What a chamber's ``unit`` (checked when the chamber was read) is above gauge, Pa."""
    unit_in_Pa = chamber_unit(unit)
    assert unit_in_Pa is not None
    return unit_in_Pa[1]


def _dbc_unit(database: Database, message: str, signal: str) -> str:
    return database.get_message_by_name(message).get_signal_by_name(signal).unit or ""


def _set_factor(factors: dict[str, float], signal: str, factor: float) -> None:
    """``signal``'s factor to Pa in ``factors``; none for Pa (the value as decoded)."""
    if factor == 1.0:
        factors.pop(signal, None)
    else:
        factors[signal] = factor
