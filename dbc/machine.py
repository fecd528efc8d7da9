"""The machine configuration: legs, their geometry and DBC signals, estimator tuning.

Read from a TOML file (example: ``deploy/machine.example.toml``) once at
start-up into one frozen :class:`MachineConfig`, checked against the DBC so
that a wrong signal name stops the service at start with a message naming the
file and key. Sources, later ones winning: ``[leg_defaults]``, then each
``[legs.<LEG>]`` table.

>>> config, database = load_machine_config("deploy/machine.example.toml")  # doctest: +SKIP
>>> config.legs["SB1_F1"].geometry.A_foot_m2  # doctest: +SKIP
0.33
"""

import logging
import math
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from cantools.database.can import Database, Message, Signal

from dbc import DEFAULT_DBC_PATH, _across_legs
from dbc.database import load_database, unsound
from dbc.decoding import (
    CLASSIC_MAX_BYTES,
    J1939_NULL_ADDRESS,
    is_j1939,
    j1939_destination,
    j1939_pgn,
)
from dbc.errors import ConfigError
from dbc.machine_signals import NO_SIGNALS, MachineSignals, parse_signals
from dbc.names import did_you_mean, messages_with
from dbc.protection import (
    CRC_ALGORITHMS,
    DEFAULT_CRC_ALGORITHM,
    Protection,
    counter_modulo,
)
from dbc.signal_range import decoded_bounds, j1939_signed_codes, named_values, value_range
from dbc.stability_config import StabilityConfig, angle_signal, parse_stability
from dbc.toml_table import TomlTable
from dbc.units import ACCEPTED_PRESSURE_UNITS, chamber_unit
from estimator.geometry import LegGeometry
from estimator.settings import EstimatorSettings

logger = logging.getLogger(__name__)

#: Standard gravity, for the machine's weight force.
G_M_S2 = 9.80665

#: Leg and machine names become Zenoh key chunks: no '/', '*', '$', '?', '#'.
NAME_PATTERN = r"[A-Za-z0-9_\-]+"

GEOMETRY_KEYS = (
    "A_piston_m2",
    "A_rod_m2",
    "l_r_m",
    "l_z_m",
    "l_b_m",
    "l_gb_m",
    "alpha_cyl_deg",
    "F_gLeg_N",
    "A_foot_m2",
    "force_gain",
    "force_offset_N",
)
#: Geometry keys that may be left out, and their defaults (``portal-daq calibrate``'s output).
OPTIONAL_GEOMETRY = {"force_gain": 1.0, "force_offset_N": 0.0}
LEG_SIGNAL_KEYS = ("piston", "rod", "status", "status_ok", "trigger", "max_skew_s")
#: The co-simulation's legs (``sim_bridge.result.LEGS``): what a leg's ``simulated_leg``
#: may name, so the simulator bridge plays that leg's pressures onto this config's leg.
#: The service itself never reads the key.
SIMULATED_LEGS = ("SB1_F1", "SB1_F2", "SB1_F3", "SB2_F1", "SB2_F2", "SB2_F3")
#: Keys of a chamber written as a table: ``piston = { signal = "M.S", ... }``.
CHAMBER_KEYS = (
    "signal",
    "source_address",
    "multiplexer",
    "unit",
    "status",
    "status_ok",
    "cycle_time_ms",
)
PROTECTION_KEYS = (
    "counter",
    "crc",
    "crc_algorithm",
    "data_id",
    "data_id_mode",
    "data_id_nibble",
    "max_delta_counter",
)
#: Keys of ``[messages.<MESSAGE>]``: what the config says of a message the DBC leaves out.
MESSAGE_KEYS = ("cycle_time_ms",)
#: The shortest cycle time a config may give: an 8-byte frame takes ~0.11 ms at 1 Mbit/s
#: (a shorter period also rounds to nothing in the simulator's nanosecond schedule).
MIN_CYCLE_TIME_MS = 0.1
#: The longest: an hour. Staleness (``stale_after_cycles`` of it) and the service's "no
#: frame" problem are judged on it; 1e300 (or a slip, 10e6 for 10) was taken: a leg
#: whose transducer died would never be stale.
MAX_CYCLE_TIME_MS = 3_600_000.0
ESTIMATOR_KEYS = (
    "filter",
    "median_window",
    "hampel_window",
    "hampel_k",
    "stale_after_cycles",
    "contact_on_N",
    "contact_off_N",
    "pressure_limit_Pa",
    "near_constant_window_s",
)
SENSOR_RANGE_KEYS = ("pressure_min_Pa", "pressure_max_Pa")
SENSOR_KEYS = (*SENSOR_RANGE_KEYS, "status_ok")
#: Top-level tables of the machine configuration.
MACHINE_TABLES = (
    "machine",
    "estimator",
    "sensors",
    "leg_defaults",
    "legs",
    "protection",
    "messages",
    "stability",
    "signals",
)
#: What ``status_ok`` is when the config does not say.
DEFAULT_STATUS_OK: tuple[str | int, ...] = ("ok",)
#: Tables of the service configuration that may share the file; this loader leaves
#: them to :mod:`daq.service_config`, which checks them.
SERVICE_TABLES = ("service", "bus", "zenoh", "publish", "recording")


@dataclass(frozen=True, slots=True)
class SignalRef:
    """A signal of the DBC, written ``MESSAGE.SIGNAL`` in the config."""

    message: str
    signal: str

    def __str__(self) -> str:
        return f"{self.message}.{self.signal}"


#: A status value meaning "fine": a value-table name or a raw number.
StatusValue = str | int


@dataclass(frozen=True, slots=True)
class StatusCheck:
    """A sensor status signal and the values of it that mean the sensor is fine."""

    signal: str
    #: Names and raw numbers meaning "fine", each name also by its number and back
    #: (through the signal's value table), so either form of the decoded value matches.
    ok: frozenset[StatusValue]
    #: The first configured "fine" value: what the simulator sends.
    nominal: StatusValue

    def fault(self, value: object) -> str | None:
        """``status_<value>`` when ``value`` is not fine, else None."""
        if value in self.ok:
            return None
        if isinstance(value, float) and value.is_integer() and int(value) in self.ok:
            return None
        return f"status_{value}"


@dataclass(frozen=True, slots=True)
class ChamberSignal:
    """Where one chamber pressure of a leg is on the bus: ``MESSAGE.SIGNAL`` [from an address]."""

    message: str
    signal: str
    #: J1939 source address of the transducer; None: any sender of the message.
    source_address: int | None
    #: The unit the DBC value is in (from the DBC or the config's ``unit``).
    unit: str
    #: The chamber's own sensor status, judged with its own frame; None: never judged.
    status: StatusCheck | None
    #: How often the transducer sends, s: its chamber's ``cycle_time_ms``, else its
    #: message's (:attr:`MachineConfig.cycle_times_ms`).
    cycle_time_s: float
    #: The multiplexer values of the frames that carry the chamber's value (its signal's,
    #: or the one page its ``multiplexer`` names); None: every frame.
    mux_ids: tuple[int, ...] | None = None
    #: Where the signal is sent under several multiplexer values, one channel's value on
    #: each page (an I/O module's ``AIN_Pressure`` under ``Channel`` 0..3): the
    #: multiplexer signal and what it decodes to on this chamber's page (its number, and
    #: its value-table name); only those frames carry the chamber. None: every frame
    #: that carries the signal.
    page: tuple[str, frozenset[int | str]] | None = None
    #: The DBC signal's physical range ``[min|max]`` in Pa, half a step wider (rounding),
    #: within J1939's valid range in a J1939 message: a value outside it is none the DBC
    #: allows (J1939's error and "not available" codes lie above it). Unbounded where
    #: neither bounds it (:func:`dbc.signal_range.value_range`).
    range_Pa: tuple[float, float] = (-math.inf, math.inf)
    #: A J1939 chamber pinning no ``source_address``: the address in its message's DBC ID,
    #: whose frames alone are the chamber's (another node sending the PGN is counted
    #: ``unmapped_source``; its frames were read as the chamber's); None where that is
    #: the null address 0xFE or the global 0xFF (a DBC's placeholder: any sender).
    dbc_source_address: int | None = None
    #: Values inside ``range_Pa`` that are codes all the same, Pa: J1939's indicators of a
    #: signed parameter, read two's complement just below 0
    #: (:func:`dbc.signal_range.j1939_signed_codes`); (inf, inf) where none are.
    codes_Pa: tuple[float, float] = (math.inf, math.inf)
    #: The signal's value-table entries that name a pressure inside that range
    #: (``0 "Zero"``), by name, Pa; any other name in its place is a code: NaN
    #: (:func:`dbc.signal_range.named_values`).
    named_Pa: Mapping[str, float] = field(default_factory=dict)
    #: What the decoded pressure (Pa) is above the gauge pressure eq. (4) takes: the
    #: standard atmosphere for a transducer sending absolute pressure (``bara``, ``kPa
    #: abs``), else 0. ``range_Pa`` and ``named_Pa`` are gauge pressures, as the samples.
    atmosphere_Pa: float = 0.0

    def __str__(self) -> str:
        where = f"{self.message}.{self.signal}"
        if self.page is not None and self.mux_ids is not None:
            where += f"[{self.page[0]}={self.mux_ids[0]}]"
        return where if self.source_address is None else f"{where}@0x{self.source_address:02X}"


#: Which chamber's new value makes a leg sample.
TRIGGERS = ("piston", "rod")


@dataclass(frozen=True, slots=True)
class LegConfig:
    """One leg: its geometry and where its chamber pressures are on the bus."""

    name: str
    geometry: LegGeometry
    piston: ChamberSignal
    rod: ChamberSignal
    #: A sample is made when this chamber's value arrives (``piston`` or ``rod``).
    trigger: str = "piston"
    #: The other chamber's latest value is used if it is at most this much older.
    max_skew_s: float = 0.0
    #: The simulated leg (one of :data:`SIMULATED_LEGS`) the simulator bridge plays onto
    #: this leg; None: derived (``sim_bridge.leg_map``).
    simulated_leg: str | None = None

    @property
    def message(self) -> str:
        """The message of the trigger chamber (the one that makes samples)."""
        return self.trigger_chamber.message

    @property
    def trigger_chamber(self) -> ChamberSignal:
        return self.piston if self.trigger == "piston" else self.rod

    @property
    def cycle_time_s(self) -> float:
        """The trigger chamber's cycle time: staleness is judged on it."""
        return self.trigger_chamber.cycle_time_s

    @property
    def cycle_time_key(self) -> str:
        """Where the config sets that cycle time: the message's, or a J1939 transducer's own."""
        chamber = self.trigger_chamber
        if chamber.source_address is None:
            return f"[messages.{chamber.message}] cycle_time_ms"
        return f"legs.{self.name}.{self.trigger}.cycle_time_ms"


@dataclass(frozen=True)
class MachineConfig:
    """Everything the decoder and estimator need to know about the machine."""

    #: The file this was read from, for messages.
    source: str
    machine_id: str
    mass_kg: float
    dbc_path: Path
    estimator: EstimatorSettings
    legs: Mapping[str, LegConfig]
    protection: Mapping[str, Protection]
    #: Factor from the DBC unit to Pa of every pressure signal, by message and signal
    #: (the legs' chambers, and any other signal whose DBC unit is a pressure unit).
    unit_factors: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    #: The same (every pressure signal of the message) by message and J1939 source address,
    #: for the senders whose chamber gives another unit than the message's: a transducer's
    #: frames are converted by its own unit, other senders' by ``unit_factors``.
    sender_unit_factors: Mapping[tuple[str, int], Mapping[str, float]] = field(default_factory=dict)
    #: What the decoded values of a signal are in where that is not its DBC unit, by
    #: message and signal: ``"Pa"`` for a pressure signal (converted when decoded, by
    #: the factors above), also one whose DBC unit is empty and a chamber's ``unit`` says;
    #: where only some J1939 senders are converted, which. The label of ``/signals``.
    decoded_units: Mapping[str, Mapping[str, str]] = field(default_factory=dict)
    #: The cycle time of every message that has one, ms: ``[messages.<MESSAGE>]
    #: cycle_time_ms``, else the DBC's ``GenMsgCycleTime`` (the config wins). What
    #: staleness, skew, the counter's resynchronisation and the simulator's schedule use.
    cycle_times_ms: Mapping[str, float] = field(default_factory=dict)
    #: The cycle time of a J1939 transducer whose chamber gives it another than its
    #: message's (a chamber's ``cycle_time_ms``), ms, by message and source address.
    sender_cycle_times_ms: Mapping[tuple[str, int], float] = field(default_factory=dict)
    #: ``[sensors] status_ok``: the status values meaning "fine" where a leg does not say.
    status_ok: tuple[str | int, ...] = ("ok",)
    #: Feet, bridge and pose signals for the stability margin; None: not configured.
    stability: StabilityConfig | None = None
    #: ``[signals]``: machine state, carriage, inclination (the defaults' where not given).
    signals: MachineSignals = NO_SIGNALS

    @property
    def weight_N(self) -> float:
        return self.mass_kg * G_M_S2

    @property
    def pinned_senders(self) -> frozenset[tuple[str, int]]:
        """(message, source address) of every chamber that pins its J1939 transducer: the
        decoder reads that sender's frames of the message's PGN as that message, where
        another DBC message of the PGN would take them."""
        return frozenset(
            (chamber.message, chamber.source_address)
            for leg in self.legs.values()
            for chamber in (leg.piston, leg.rod)
            if chamber.source_address is not None
        )

    def cycle_time_ms(self, message: str, source_address: int | None = None) -> float | None:
        """How often ``message`` is sent (by the J1939 sender ``source_address``), ms;
        None: neither the DBC nor the config says (the message is not periodic)."""
        if source_address is not None and (message, source_address) in self.sender_cycle_times_ms:
            return self.sender_cycle_times_ms[(message, source_address)]
        return self.cycle_times_ms.get(message)


def load_machine_config(path: str | Path) -> tuple[MachineConfig, Database]:
    """Read and check a machine configuration file and the DBC it names.

    Raises :class:`ConfigError` (file, key, reason) or :class:`DbcError`.
    """
    return machine_from_toml(read_toml(path), str(path), Path(path).parent)


def machine_from_toml(
    data: dict[str, Any], source: str, config_dir: Path
) -> tuple[MachineConfig, Database]:
    """The machine part of parsed TOML and its DBC (``machine.dbc``, relative to ``config_dir``)."""
    dbc_path = _dbc_path(TomlTable(data, source), config_dir)
    database = load_database(dbc_path)
    return parse_machine_config(data, source, database, dbc_path), database


def read_toml(path: str | Path) -> dict[str, Any]:
    """The parsed TOML file; a missing, unreadable or malformed file is a ConfigError."""
    source = str(path)
    try:
        with open(path, "rb") as file:
            return tomllib.load(file)
    except FileNotFoundError as exc:
        raise ConfigError(source, "", "no such file") from exc
    except OSError as exc:
        raise ConfigError(source, "", f"cannot read it: {exc.strerror or exc}") from exc
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(source, "", f"not valid TOML: {exc}{_no_config(path)}") from exc
    except UnicodeDecodeError as exc:  # TOML is UTF-8; e.g. a Latin-1 comment "46 °C"
        raise ConfigError(
            source,
            "",
            f"not UTF-8 (byte 0x{exc.object[exc.start]:02x} at offset {exc.start})"
            + (_no_config(path) or "; save the file as UTF-8"),
        ) from exc
    except ValueError as exc:  # int() of a number of more than 4,300 digits
        raise ConfigError(
            source, "", f"not valid TOML: a number too long to read ({str(exc).split(':')[0]})"
        ) from exc


def _no_config(path: str | Path) -> str:
    """What to do where another kind of file was given as the config (the DBC, the Zenoh
    file, a recording: "save the file as UTF-8" was the advice for an MCAP file)."""
    suffix = Path(path).suffix.lower()
    if suffix in ("", ".toml"):
        return ""
    return f"; a {suffix} file is no config: give the TOML file (e.g. portal-daq.toml)"


def _dbc_path(root: TomlTable, config_dir: Path) -> Path:
    machine = root.table("machine")
    if "dbc" not in machine:
        return DEFAULT_DBC_PATH
    return machine.file("dbc", config_dir)


def parse_machine_config(
    data: dict[str, Any], source: str, database: Database, dbc_path: Path = DEFAULT_DBC_PATH
) -> MachineConfig:
    """Build a :class:`MachineConfig` from parsed TOML, checking names against ``database``."""
    root = TomlTable(data, source)
    root.reject_unknown((*MACHINE_TABLES, *SERVICE_TABLES))
    machine = root.table("machine")
    machine.reject_unknown(("id", "mass_kg", "dbc"))
    mass_kg = machine.number("mass_kg")
    if mass_kg <= 0:
        raise machine.error("mass_kg", f"must be > 0, got {mass_kg}")

    estimator = root.table("estimator", required=False)
    estimator.reject_unknown(ESTIMATOR_KEYS)
    sensors = root.table("sensors", required=False)
    sensors.reject_unknown(SENSOR_KEYS)
    defaults = EstimatorSettings()
    owners = {key: estimator for key in ESTIMATOR_KEYS} | {
        key: sensors for key in SENSOR_RANGE_KEYS
    }
    settings_kwargs: dict[str, Any] = {
        "filter": estimator.string("filter", defaults.filter),
        "median_window": estimator.integer("median_window", defaults.median_window),
        "hampel_window": estimator.integer("hampel_window", defaults.hampel_window),
    }
    for key, table in owners.items():
        if key not in settings_kwargs:
            settings_kwargs[key] = table.number(key, getattr(defaults, key))
    status_ok = _status_values(sensors, "status_ok", DEFAULT_STATUS_OK)
    settings = root.build(EstimatorSettings, owners, **settings_kwargs)

    leg_defaults = root.table("leg_defaults", required=False)
    leg_defaults.reject_unknown(GEOMETRY_KEYS)
    legs_table = root.table("legs")
    if not legs_table.data:
        raise legs_table.error("", "no legs configured; add a [legs.<LEG>] table per leg")
    cycle_times_ms = _cycle_times_ms(root.table("messages", required=False), database)
    _warn_angle_in_radians([leg_defaults, *(table for _, table in legs_table.subtables())])
    legs = {
        name: _leg(name, table, leg_defaults, database, status_ok, cycle_times_ms)
        for name, table in legs_table.subtables()
    }
    _contact_below_the_weight_per_leg(estimator, settings, mass_kg, len(legs))
    _warn_implausible_areas(legs_table, leg_defaults, legs, mass_kg, settings)
    _across_legs.check_simulated_legs(legs_table, legs)
    _across_legs.check_own_chambers(legs_table, legs)
    sender_cycle_times_ms = _across_legs.sender_cycle_times_ms(legs_table, legs, cycle_times_ms)
    protection = {
        name: _protection(name, table, database, cycle_times_ms, sender_cycle_times_ms)
        for name, table in root.table("protection", required=False).subtables()
    }
    _across_legs.check_senders(legs_table, legs, database)
    _across_legs.check_not_protection(legs_table, legs, protection)
    _across_legs.warn_unchecked_protection(legs_table, legs, protection, database)
    unit_factors, sender_unit_factors, decoded_units = _across_legs.unit_factors(
        legs_table, legs, database
    )

    def signal_unit(ref: SignalRef) -> str | None:
        unit: str | None = (
            database.get_message_by_name(ref.message).get_signal_by_name(ref.signal).unit
        )
        return unit

    def signal_ref(table: TomlTable, key: str) -> SignalRef:
        return _signal(table, key, database)

    def named_ref(table: TomlTable, key: str) -> SignalRef:
        """``key``: a ``MESSAGE.SIGNAL``."""
        return signal_ref(*table.signal_table(key, ("signal",)))

    stability = parse_stability(
        root.table("stability", required=False), legs, signal_ref, signal_unit
    )
    return MachineConfig(
        source=source,
        machine_id=machine.string("id", pattern=NAME_PATTERN),
        mass_kg=mass_kg,
        dbc_path=dbc_path,
        estimator=settings,
        legs=legs,
        protection=protection,
        unit_factors=unit_factors,
        sender_unit_factors=sender_unit_factors,
        decoded_units=decoded_units,
        cycle_times_ms=cycle_times_ms,
        sender_cycle_times_ms=sender_cycle_times_ms,
        status_ok=status_ok,
        stability=stability,
        signals=parse_signals(
            root.table("signals", required=False),
            [base.name for base in stability.layout.bases] if stability is not None else None,
            named_ref,
            lambda name: _find_signal(name, database),
            lambda table, key: angle_signal(table, key, signal_ref, signal_unit),
            lambda ref: signal_unit(ref) or "",
        ),
    )


def _contact_below_the_weight_per_leg(
    table: TomlTable, settings: EstimatorSettings, mass_kg: float, legs: int
) -> None:
    """One warning line where ``contact_on_N`` is at least the machine's weight per leg (a
    light machine, the default 8 kN): with every foot down the mean foot carries that, so
    some would count as in the air, left out of the weight check, the stability margin
    and the report's soil pressures (drawn at 0 kPa)."""
    per_leg_N = mass_kg * G_M_S2 / legs
    if settings.contact_on_N >= per_leg_N:
        logger.warning(
            "%s: %s: %g N is at least the machine's weight per leg, %.0f N (%g kg on %d "
            "legs): with every foot down some would count as in the air; set contact_on_N "
            "and contact_off_N below it",
            table.source,
            table.key("contact_on_N"),
            settings.contact_on_N,
            per_leg_N,
            mass_kg,
            legs,
        )


def _warn_angle_in_radians(tables: list[TomlTable]) -> None:
    """One warning line per ``alpha_cyl_deg`` of at most 2 pi, a value in radians (1.309
    for 75 deg): read as degrees, the cylinder lies along the r axis and its lever arm is
    a fraction of the design's, each foot force as many times too low (or, with l_z_m >= 0,
    the lever is refused as negative, which did not say why)."""
    for table in tables:
        value = table.data.get("alpha_cyl_deg")
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            continue  # not a number: refused when the leg is read
        if 0 < abs(value) <= 2 * math.pi:
            logger.warning(
                "%s: %s: %g is in degrees, a cylinder %g deg off the r axis; if it is in "
                "radians, write %.4g (degrees)",
                table.source, table.key("alpha_cyl_deg"), value, value, math.degrees(value),
            )  # fmt: skip


#: Static soil pressure of a foot carrying the weight per leg, Pa, outside which its
#: A_foot_m2 is warned of: the paper's feet stand at ~60..190 kPa; 3300 (cm2 for 0.33 m2)
#: stood at 9 Pa and every soil pressure was 10,000 times too low, silently.
PLAUSIBLE_GROUND_PA = (1e3, 1e7)
#: Piston pressure, Pa, below which a leg cylinder holding the weight per leg is warned
#: of (above, the transducers' range ends it): 78.54 (cm2 for a 100 mm bore) held it at
#: 0.01 bar, and every foot force was 10,000 times too high.
PLAUSIBLE_PISTON_MIN_PA = 1e5


def _warn_implausible_areas(
    legs_table: TomlTable,
    defaults: TomlTable,
    legs: Mapping[str, LegConfig],
    mass_kg: float,
    settings: EstimatorSettings,
) -> None:
    """One warning line per key whose area puts the machine's weight per leg at a
    pressure no foot or leg cylinder stands at: an area written in cm2 or mm2 (or a mass
    in t). Warned, not refused: a machine may carry part of its weight on other supports."""
    per_leg_N = mass_kg * G_M_S2 / len(legs)
    warned: set[str] = set()

    def warn(name: str, key: str, value: str, why: str) -> None:
        table = legs_table.table(name)
        owner = table if key in table else defaults
        if owner.key(key) not in warned:
            warned.add(owner.key(key))
            logger.warning(
                "%s: %s: %s the weight per leg, %.0f N (machine.mass_kg %g on %d legs), at %s",
                owner.source, owner.key(key), value, per_leg_N, mass_kg, len(legs), why,
            )  # fmt: skip

    for name, leg in legs.items():
        geometry = leg.geometry
        unit = "areas are in m2: is it written in cm2 or mm2 (or the mass in t)?"
        foot = f"{geometry.A_foot_m2:g} m2 would carry"
        ground_Pa = per_leg_N / geometry.A_foot_m2
        if not PLAUSIBLE_GROUND_PA[0] <= ground_Pa <= PLAUSIBLE_GROUND_PA[1]:
            warn(name, "A_foot_m2", foot, f"{ground_Pa:.4g} Pa of soil pressure; {unit}")
        piston = f"{geometry.A_piston_m2:g} m2 would hold"
        cylinder_N = (per_leg_N - geometry.calibrated_term_N) / geometry.calibrated_ratio
        piston_Pa = cylinder_N / geometry.A_piston_m2
        if 0 < piston_Pa < PLAUSIBLE_PISTON_MIN_PA:
            warn(name, "A_piston_m2", piston, f"{piston_Pa:.4g} Pa in the piston chamber; {unit}")
        elif piston_Pa > settings.pressure_max_Pa:
            warn(
                name, "A_piston_m2", piston,
                f"{piston_Pa:.4g} Pa in the piston chamber, above [sensors] pressure_max_Pa "
                f"({settings.pressure_max_Pa:g}): every sample of the leg standing would be "
                "invalid (range)",
            )  # fmt: skip


def _find_signal(name: str, database: Database) -> SignalRef | None:
    """The signal ``name`` in the first message of the DBC that has it; None: none has."""
    for message in database.messages:
        if any(signal.name == name for signal in message.signals):
            return SignalRef(message.name, name)
    return None


def _leg(
    name: str,
    table: TomlTable,
    defaults: TomlTable,
    database: Database,
    status_ok: tuple[StatusValue, ...],
    cycle_times_ms: Mapping[str, float],
) -> LegConfig:
    if re.fullmatch(NAME_PATTERN, name) is None:
        raise table.error("", f"leg name {name!r} must match {NAME_PATTERN}")
    table.reject_unknown((*GEOMETRY_KEYS, *LEG_SIGNAL_KEYS, "simulated_leg"))
    values: dict[str, float] = {}
    owners: dict[str, TomlTable] = {}
    for key in GEOMETRY_KEYS:
        owner = table if key in table else defaults
        if key not in owner and key not in OPTIONAL_GEOMETRY:
            raise table.error(key, "missing (and not given in [leg_defaults])")
        values[key] = owner.number(key, OPTIONAL_GEOMETRY.get(key))
        owners[key] = owner
    values["alpha_cyl_rad"] = math.radians(values.pop("alpha_cyl_deg"))
    owners["alpha_cyl_rad"] = owners.pop("alpha_cyl_deg")
    geometry = table.build(LegGeometry, owners, **values)

    leg_status_ok = _status_values(table, "status_ok", status_ok)
    leg_status = _leg_status(table, database) if "status" in table else None
    chambers = {
        key: _chamber(table, key, database, leg_status_ok, cycle_times_ms) for key in TRIGGERS
    }
    if leg_status is not None:
        chambers = _attach_leg_status(table, chambers, leg_status, leg_status_ok)
    piston, rod = chambers["piston"], chambers["rod"]
    for key, chamber in chambers.items():
        for other in chambers.values():
            if other.status is not None and (chamber.message, chamber.signal) == (
                other.message,
                other.status.signal,
            ):  # with a unit, the status' codes were valid pressures
                raise table.error(
                    key, f"{chamber.message}.{chamber.signal} is this leg's status, not a pressure"
                )
    if str(piston) == str(rod):
        # A copy-paste slip, which eq. (4) would turn into p (A_piston - A_rod) silently.
        raise table.error("rod", f"is the piston's signal {piston}; each chamber has its own")
    trigger = table.string("trigger", "piston")
    if trigger not in TRIGGERS:
        raise table.error("trigger", f"must be one of {list(TRIGGERS)}, got {trigger!r}")
    other = rod if trigger == "piston" else piston
    max_skew_s = table.number("max_skew_s", other.cycle_time_s)
    if max_skew_s < 0:
        raise table.error("max_skew_s", f"must be >= 0, got {max_skew_s}")
    simulated_leg = table.string("simulated_leg") if "simulated_leg" in table else None
    if simulated_leg is not None and simulated_leg not in SIMULATED_LEGS:
        raise table.error(
            "simulated_leg",
            f"the simulation has no leg {simulated_leg!r}; "
            f"its legs are {', '.join(SIMULATED_LEGS)}",
        )
    return LegConfig(
        name=name,
        geometry=geometry,
        piston=piston,
        rod=rod,
        trigger=trigger,
        max_skew_s=max_skew_s,
        simulated_leg=simulated_leg,
    )


def _split_ref(table: TomlTable, key: str, text: str, database: Database) -> tuple[Message, str]:
    message_name, dot, signal_name = text.partition(".")
    if not dot or not message_name or not signal_name:
        raise table.error(key, f"{text!r} must be written MESSAGE.SIGNAL{_written(text, database)}")
    message = _message(table, key, message_name, database)
    if signal_name not in {signal.name for signal in message.signals}:
        raise table.error(key, _no_signal(signal_name, message, database))
    return message, signal_name


def _written(text: str, database: Database) -> str:
    """How ``text`` (a name without its message, or a message alone) is written whole."""
    whole = [f"{message}.{text.strip('.')}" for message in messages_with(database, text.strip("."))]
    if whole:
        return f": {', '.join(whole)}"
    names = {message.name: message for message in database.messages}
    message = names.get(text.strip("."))
    if message is not None:
        return f"; {message.name}'s signals are {', '.join(s.name for s in message.signals)}"
    return ""


def _comment_of(signal: Signal) -> str:
    """The DBC's comment on ``signal``, on one line, to end a refusal with: a vendor's DBC
    often says a transducer's unit only there (``CM_ SG_ ... "Rod pressure in bar"``)."""
    comment = " ".join(str(signal.comment or "").split())
    if not comment:
        return ""
    return f" (the DBC's comment on it: {comment[:120] + ('...' if len(comment) > 120 else '')!r})"


def _no_signal(signal: str, message: Message, database: Database) -> str:
    """Why ``signal`` is not ``message``'s: the messages that do have it, else the names
    it has that are close."""
    reason = f"no signal {signal!r} in message {message.name} of the DBC"
    if elsewhere := messages_with(database, signal):
        return f"{reason}; it is in {', '.join(elsewhere)}"
    return reason + did_you_mean(signal, (s.name for s in message.signals))


def _signal(table: TomlTable, key: str, database: Database) -> SignalRef:
    """The ``signal`` of a signal table (:meth:`TomlTable.signal_table`): a
    ``MESSAGE.SIGNAL`` of the DBC; errors name ``key``."""
    message, signal = _split_ref(table, key, table.string("signal"), database)
    return SignalRef(message.name, signal)


def _chamber(
    table: TomlTable,
    key: str,
    database: Database,
    status_ok: tuple[StatusValue, ...],
    cycle_times_ms: Mapping[str, float],
) -> ChamberSignal:
    chamber, signal_key = table.signal_table(key, CHAMBER_KEYS)
    message, signal_name = _split_ref(chamber, signal_key, chamber.string("signal"), database)
    source_address = _source_address(chamber, message, database)
    signal = message.get_signal_by_name(signal_name)
    if signal.is_multiplexer:  # with a unit it was taken, and the bridge crashed on it
        raise chamber.error(
            signal_key,
            f"signal {message.name}.{signal_name} is the message's multiplexer (which page "
            "a frame is), not a pressure",
        )
    if signal.multiplexer_signal is not None:
        multiplexer = message.get_signal_by_name(signal.multiplexer_signal)
        if (multiplexer.scale, multiplexer.offset) != (1, 0):
            # cantools picks a frame's signals by the multiplexer's scaled value, where the
            # DBC's pages (m2, SG_MUL_VAL_) are raw: a channel counted from 1, (1,1),
            # read page 2's frames as page 3's.
            raise chamber.error(
                signal_key,
                f"{message.name}'s multiplexer {multiplexer.name} has factor "
                f"{multiplexer.scale:g} and offset {multiplexer.offset:g}: its frames' pages "
                "would be taken by the scaled value, not the raw one the DBC's pages are; "
                "give it (1,0) in the DBC",
            )
    if is_j1939(message) and message.length > CLASSIC_MAX_BYTES and not message.is_fd:
        # J1939-21 sends it in TP.CM/TP.DT packets: no frame of its PGN ever comes, the
        # leg was silent with nothing saying why (and the bridge sent FD frames of it).
        raise chamber.error(
            signal_key,
            f"{message.name} is a J1939 parameter group of {message.length} bytes: J1939 "
            "sends one of more than 8 in transport-protocol packets (TP.CM/TP.DT, PGN "
            "0xEC00/0xEB00), which are not reassembled, so no frame of it would come; a "
            "chamber needs one of up to 8 bytes (or a CAN FD message: VFrameFormat "
            "ExtendedCAN_FD)",
        )
    if _enumerated(signal):  # with a unit, a 2-bit status was a valid 0..3 bar
        names = ", ".join(f'{raw} "{name}"' for raw, name in sorted((signal.choices or {}).items()))
        raise chamber.error(
            signal_key,
            f"signal {message.name}.{signal_name} names every value it takes ({names}): a "
            "status, not a pressure",
        )
    mux_ids, page = _page(chamber, signal_key, message, signal_name)
    unit = chamber.string("unit") if "unit" in chamber else (signal.unit or "")
    in_Pa = chamber_unit(unit)
    if in_Pa is None:
        where = "unit" if "unit" in chamber else signal_key
        raise chamber.error(
            where,
            f"signal {message.name}.{signal_name} has unit {unit!r}, not a pressure unit; "
            f"set unit = one of {ACCEPTED_PRESSURE_UNITS}{_comment_of(signal)}",
        )
    if signal.scale == 0:  # cantools takes it: a constant, published as a valid pressure
        raise chamber.error(
            signal_key,
            f"signal {message.name}.{signal_name} has factor 0 in the DBC: every value "
            f"would be its offset, {signal.offset:g} {unit}",
        )
    status = None
    if "status" in chamber:
        status_message, status_signal = _status_ref(chamber, message, database)
        if status_message.name != message.name:
            raise chamber.error(
                "status", f"must be a signal of {message.name}, the chamber's own message"
            )
        if not _in_frames_of(message, status_signal, mux_ids):
            raise chamber.error(
                "status",
                f"{status_signal} is sent under another multiplexer value than {signal_name}",
            )
        chamber_ok = _status_values(chamber, "status_ok", status_ok)
        status = _status_check(chamber, "status_ok", message, status_signal, chamber_ok)
    elif "status_ok" in chamber:
        raise chamber.error("status_ok", "given without a status signal")
    factor, atmosphere_Pa = in_Pa
    low, high = value_range(signal, is_j1939(message))
    named = named_values(signal, is_j1939(message))
    code_low, code_high = j1939_signed_codes(signal, is_j1939(message)) or (math.inf, math.inf)
    dbc_address = int(message.frame_id & 0xFF)
    dbc_sender = source_address is None and is_j1939(message) and dbc_address < J1939_NULL_ADDRESS
    return ChamberSignal(
        message=message.name,
        signal=signal_name,
        source_address=source_address,
        unit=unit,
        status=status,
        cycle_time_s=_cycle_time_s(chamber, signal_key, message, source_address, cycle_times_ms),
        mux_ids=mux_ids,
        page=page,
        range_Pa=(low * factor - atmosphere_Pa, high * factor - atmosphere_Pa),
        codes_Pa=(code_low * factor - atmosphere_Pa, code_high * factor - atmosphere_Pa),
        dbc_source_address=dbc_address if dbc_sender else None,
        named_Pa={name: value * factor - atmosphere_Pa for name, value in named.items()},
        atmosphere_Pa=atmosphere_Pa,
    )


def _page(
    table: TomlTable, key: str, message: Message, signal_name: str
) -> tuple[tuple[int, ...] | None, tuple[str, frozenset[int | str]] | None]:
    """A chamber's multiplexer values (:attr:`ChamberSignal.mux_ids`) and page
    (:attr:`ChamberSignal.page`): its ``multiplexer`` (a number, or a name of the
    multiplexer's value table) where the signal is under several multiplexer values,
    which it must then name: an I/O module sends one channel per page in the same
    signal, and a chamber reading every page read four sensors in turn as one."""
    own = _mux_ids(message, signal_name)
    signal = message.get_signal_by_name(signal_name)
    multiplexer = signal.multiplexer_signal
    choices: Mapping[int, object] = (
        message.get_signal_by_name(multiplexer).choices or {} if multiplexer else {}
    )
    if "multiplexer" not in table:
        if own is not None and len(own) > 1:
            raise table.error(
                key,
                f"{message.name}.{signal_name} is sent under {multiplexer} = "
                f"{_pages(own, choices)}, a value on each page: set multiplexer = the page of "
                "this chamber's",
            )
        return own, None
    if own is None or multiplexer is None:
        raise table.error("multiplexer", f"{message.name}.{signal_name} is not under a multiplexer")
    value = table.data["multiplexer"]
    by_name = {str(name): int(raw) for raw, name in choices.items()}
    page = by_name.get(value) if isinstance(value, str) else value
    if isinstance(page, bool) or not isinstance(page, int) or page not in own:
        raise table.error(
            "multiplexer",
            f"{value!r} is no page of {message.name}.{signal_name}: it is sent under "
            f"{multiplexer} = {_pages(own, choices)}",
        )
    if len(own) == 1:  # the only page it is on: every frame carrying it is that page
        return own, None
    decoded: set[int | str] = {page}
    if page in choices:
        decoded.add(str(choices[page]))
    return (page,), (multiplexer, frozenset(decoded))


def _pages(pages: tuple[int, ...], choices: Mapping[int, object]) -> str:
    """Multiplexer values for a message, with their value-table names where a few have
    them (``0 (AIN1), 1 (AIN2)``), else runs of them (``0..255``)."""
    if len(pages) <= 8 and choices:
        return ", ".join(
            f"{page} ({choices[page]})" if page in choices else str(page) for page in pages
        )
    runs: list[list[int]] = []
    for page in sorted(pages):
        if runs and page == runs[-1][-1] + 1:
            runs[-1].append(page)
        else:
            runs.append([page])
    return ", ".join(str(run[0]) if len(run) < 3 else f"{run[0]}..{run[-1]}" for run in runs)


def _enumerated(signal: Signal) -> bool:
    """``signal``'s value table names every raw value its bits hold: an enumeration (a
    status, a mode), never a measurement."""
    choices: Mapping[int, object] = signal.choices or {}
    return not signal.is_float and signal.length <= 16 and len(choices) >= 1 << signal.length


def _mux_ids(message: Message, signal_name: str) -> tuple[int, ...] | None:
    """The multiplexer values under which ``message`` carries the signal; None: always."""
    ids = message.get_signal_by_name(signal_name).multiplexer_ids
    return tuple(ids) if ids else None


def _in_frames_of(message: Message, signal_name: str, mux_ids: tuple[int, ...] | None) -> bool:
    """Every frame carrying multiplexer values ``mux_ids`` (None: any) carries the signal."""
    own = _mux_ids(message, signal_name)
    return own is None or (mux_ids is not None and set(mux_ids) <= set(own))


def _source_address(table: TomlTable, message: Message, database: Database) -> int | None:
    """The pinned J1939 sender: the configured one; for a message that shares its PGN with
    others (one DBC message per sender) the address in its own ID; else None (any).

    A 29-bit message the DBC does not mark J1939 (``VFrameFormat`` ``J1939PG``; cantools,
    for one, writes no frame format) becomes one here, in ``database``, when a chamber
    pins a sender of it: only a J1939 ID has a source address.
    """
    if "source_address" not in table:
        if is_j1939(message) and _shares_pgn(message, database):
            return int(message.frame_id & 0xFF)
        return None
    if not message.is_extended_frame:
        raise table.error(
            "source_address",
            f"{message.name} is not a J1939 message: its 11-bit ID has no source address",
        )
    address = table.integer("source_address")
    if not 0 <= address < J1939_NULL_ADDRESS:
        # 254 and 255 are no sender's: J1939-81's null address (a node that could not
        # claim one may send only its Cannot Claim from it) and the global destination.
        special = {254: " (0xFE: the null address, a node without a claimed one)"}
        special[255] = " (0xFF: the global address, a destination, no sender)"
        raise table.error(
            "source_address",
            f"must be a J1939 address 0..253, got {address}{special.get(address, '')}",
        )
    message.protocol = "j1939"
    pgn = j1939_pgn(message.frame_id)
    for other in database.messages:
        if other is not message and is_j1939(other) and j1939_pgn(other.frame_id) == pgn:
            if other.frame_id & 0xFF == address:
                raise table.error(
                    "source_address",
                    f"0x{address:02X} sends {other.name} in the DBC (0x{other.frame_id:X}, the "
                    f"PGN of {message.name}): its frames are that message's",
                )
    return address


def _shares_pgn(message: Message, database: Database) -> bool:
    pgn = j1939_pgn(message.frame_id)
    return any(
        other is not message and is_j1939(other) and j1939_pgn(other.frame_id) == pgn
        for other in database.messages
    )


def _cycle_time_s(
    table: TomlTable,
    key: str,
    message: Message,
    source_address: int | None,
    cycle_times_ms: Mapping[str, float],
) -> float:
    """A chamber's cycle time: its transducer's ``cycle_time_ms`` (one pinned by source
    address), else its message's (:func:`_cycle_times_ms`)."""
    if "cycle_time_ms" in table:
        if source_address is None:
            raise table.error(
                "cycle_time_ms",
                "only for a transducer pinned by source_address (a chamber without one "
                f"reads every sender); for the message: [messages.{message.name}] cycle_time_ms",
            )
        return _positive_ms(table) / 1000.0
    if message.name not in cycle_times_ms:
        given = "no GenMsgCycleTime"
        if message.cycle_time:  # below MIN_CYCLE_TIME_MS: no period (-5, a typo)
            given = f"GenMsgCycleTime {message.cycle_time:g}, no period,"
        raise table.error(
            key,
            f"message {message.name} has {given} in the DBC{_other_cycle_time(message)}: "
            f"set [messages.{message.name}] cycle_time_ms (staleness and skew are judged on it)",
        )
    return cycle_times_ms[message.name] / 1000.0


def _other_cycle_time(message: Message) -> str:
    """Where the DBC gives ``message`` a cycle time under another name than
    ``GenMsgCycleTime`` (``CycleTime``, ``GenMsgCycleTimeFast``: other tools' names,
    which cantools does not read): that attribute and its value, to copy if it is the
    message's period; else nothing."""
    if message.dbc is None:
        return ""
    own = message.dbc.attributes
    for name, definition in (message.dbc.attribute_definitions or {}).items():
        if name == "GenMsgCycleTime" or "cycle" not in name.lower() or definition.kind != "BO_":
            continue
        value = own[name].value if name in own else definition.default_value
        if value:
            return f" (it has {name} {value}: its period?)"
    return ""


def _positive_ms(table: TomlTable) -> float:
    """``cycle_time_ms`` of ``table``: a period, :data:`MIN_CYCLE_TIME_MS` ..
    :data:`MAX_CYCLE_TIME_MS`."""
    cycle_time_ms = table.number("cycle_time_ms")
    if not cycle_time_ms >= MIN_CYCLE_TIME_MS:
        raise table.error(
            "cycle_time_ms",
            f"must be at least {MIN_CYCLE_TIME_MS:g} ms (the message's period; one frame "
            f"takes about that long on the bus), got {cycle_time_ms:g}",
        )
    if cycle_time_ms > MAX_CYCLE_TIME_MS:
        raise table.error(
            "cycle_time_ms",
            f"must be at most {MAX_CYCLE_TIME_MS:.0f} ms (an hour: staleness is judged on "
            f"it), got {cycle_time_ms:g}",
        )
    return cycle_time_ms


def _cycle_times_ms(table: TomlTable, database: Database) -> dict[str, float]:
    """Each message's cycle time, ms: ``[messages.<MESSAGE>] cycle_time_ms``, else the
    DBC's ``GenMsgCycleTime`` (vendor DBCs, J1939 ones especially, often give none)
    where it is a period: one below :data:`MIN_CYCLE_TIME_MS` (``-5``) is none, as 0 is
    (it was taken, and told as the leg's ``max_skew_s`` "must be >= 0")."""
    times = {
        message.name: float(message.cycle_time)
        for message in database.messages
        if message.cycle_time and message.cycle_time >= MIN_CYCLE_TIME_MS
    }
    for name, message_table in table.subtables():
        message_table.reject_unknown(MESSAGE_KEYS)
        _message(message_table, "", name, database)
        if "cycle_time_ms" in message_table:
            times[name] = _positive_ms(message_table)
    return times


def _status_ref(table: TomlTable, message: Message, database: Database) -> tuple[Message, str]:
    """A chamber's ``status``: ``SIGNAL`` of its own message, or ``MESSAGE.SIGNAL``."""
    text = table.string("status")
    if "." not in text:
        text = f"{message.name}.{text}"
    return _split_ref(table, "status", text, database)


def _status_values(
    table: TomlTable, key: str, default: tuple[StatusValue, ...]
) -> tuple[StatusValue, ...]:
    """``status_ok``: one value or a list, each a value-table name or a number."""
    if key not in table:
        return default
    value = table.data[key]
    items = value if isinstance(value, list) else [value]
    if not items or not all(
        (isinstance(item, str) and item) or (isinstance(item, int) and not isinstance(item, bool))
        for item in items
    ):
        raise table.error(
            key, f"must be a value-table name or number, or a list of them, got {value!r}"
        )
    return tuple(items)


def _status_check(
    table: TomlTable,
    key: str,
    message: Message,
    signal_name: str,
    status_ok: tuple[StatusValue, ...],
) -> StatusCheck:
    signal = message.get_signal_by_name(signal_name)
    choices: Mapping[int, object] = signal.choices or {}
    by_name = {str(name): int(raw) for raw, name in choices.items()}
    ok: set[StatusValue] = set()
    for value in status_ok:
        if isinstance(value, str):
            if value not in by_name:
                known = (
                    f"its value table has {sorted(by_name)}"
                    if by_name
                    else (
                        "it has no value table here; give the number meaning fine (status_ok = 0)"
                    )
                )
                raise table.error(
                    key,
                    f"{value!r} is not a value of {message.name}.{signal_name}: {known}"
                    + _inherited(table, key),
                )
            ok |= {value, by_name[value]}
        else:
            ok.add(value)
            if value in choices:
                ok.add(str(choices[value]))
    low, high = decoded_bounds(signal)
    if not any(isinstance(value, str) or low <= value <= high for value in status_ok):
        raise table.error(
            key,
            f"{message.name}.{signal_name} takes {low:g}..{high:g}: none of {list(status_ok)} "
            "is one of them (every sample would be invalid)" + _inherited(table, key),
        )
    return StatusCheck(signal=signal_name, ok=frozenset(ok), nominal=status_ok[0])


def _inherited(table: TomlTable, key: str) -> str:
    """Where a ``status_ok`` that ``table`` does not set comes from, for an error about it:
    a foreign DBC's status names its fine value otherwise than the default ``"ok"``, and
    the error named a key the config does not have."""
    if key in table.data:
        return ""
    chamber = table.path.count(".") > 1  # legs.VL.piston: a chamber's table, in its leg's
    source = "the leg's status_ok, or " if chamber else ""
    return (
        f" (no {key} in {table.path}: {source}[sensors] status_ok, "
        f"{list(DEFAULT_STATUS_OK)} by default; set {key} in {table.path})"
    )


def _leg_status(table: TomlTable, database: Database) -> tuple[Message, str, int | None]:
    """The leg-level ``status`` (``"M.S"`` or ``{ signal, source_address }``)."""
    status, signal_key = table.signal_table("status", ("signal", "source_address"))
    message, signal = _split_ref(status, signal_key, status.string("signal"), database)
    return message, signal, _source_address(status, message, database)


def _attach_leg_status(
    table: TomlTable,
    chambers: dict[str, ChamberSignal],
    leg_status: tuple[Message, str, int | None],
    status_ok: tuple[StatusValue, ...],
) -> dict[str, ChamberSignal]:
    """A leg-level status follows the frames of the chamber(s) whose message carries it."""
    message, signal, source_address = leg_status
    check = _status_check(table, "status_ok", message, signal, status_ok)
    attached = {
        key: replace(chamber, status=check)
        for key, chamber in chambers.items()
        if chamber.message == message.name
        and (source_address is None or chamber.source_address in (None, source_address))
        and chamber.status is None
        and _in_frames_of(message, signal, chamber.mux_ids)
    }
    if not attached and not any(c.message == message.name for c in chambers.values()):
        carrying = " and ".join(sorted({chamber.message for chamber in chambers.values()}))
        raise table.error(
            "status",
            f"{message.name}.{signal} is not in the chambers' message ({carrying}): a "
            "status is judged with the frame that carries it and the pressures; one sent "
            "in a message of its own cannot be (leave status out: the leg is not judged "
            "by status)",
        )
    if not attached:
        raise table.error(
            "status",
            f"{message.name}.{signal} is in neither chamber's frames (or already judged by "
            "the chamber's own status); give it as the chamber's status instead",
        )
    return chambers | attached


def _message(table: TomlTable, key: str, name: str, database: Database) -> Message:
    """The DBC's message ``name``; one whose name or ID another message has too is an
    error (cantools keeps the last: the config would read another message's frames),
    and so is one whose signals overlap or do not fit in it."""
    try:
        message = database.get_message_by_name(name)
    except KeyError:
        hint = did_you_mean(name, (message.name for message in database.messages))
        raise table.error(key, f"no message {name!r} in the DBC{hint}") from None
    problem = unsound(message)  # a message cantools' checks refused (see dbc.database)
    if problem is not None:
        raise table.error(key, f"message {name} of the DBC: {problem}")
    wire = _wire(message)
    for other in database.messages:
        if other is message:
            continue
        if other.name == name:
            raise table.error(key, f"the DBC has two messages named {name}: rename one")
        if _wire(other) == wire:
            what = (
                "frame ID"
                if not is_j1939(message)
                else "PGN and source address"
                if wire[-1] is None
                else "PGN, source and destination address"
            )
            raise table.error(
                key,
                f"{name} has the {what} of {other.name} too in the DBC (0x{message.frame_id:X}, "
                f"0x{other.frame_id:X}): their frames cannot be told apart",
            )
    return message


def _wire(message: Message) -> tuple[int | None, ...]:
    """What tells a message's frames on the bus: its ID, or a J1939 PGN, sender and (peer
    to peer) destination."""
    if is_j1939(message):
        frame_id = message.frame_id
        return (1, j1939_pgn(frame_id), frame_id & 0xFF, j1939_destination(frame_id))
    return (0, message.frame_id, int(bool(message.is_extended_frame)))


def _protection(
    name: str,
    table: TomlTable,
    database: Database,
    cycle_times_ms: Mapping[str, float],
    sender_cycle_times_ms: Mapping[tuple[str, int], float],
) -> Protection:
    table.reject_unknown(PROTECTION_KEYS)
    message = _message(table, "", name, database)
    signals = {signal.name: signal for signal in message.signals}
    if "counter" not in table and "crc" not in table:
        raise table.error("", "names neither a counter nor a crc signal")
    for key in ("counter", "crc"):
        if key in table and table.string(key) not in signals:
            raise table.error(key, _no_signal(table.string(key), message, database))
    counter = table.string("counter") if "counter" in table else None
    crc = table.string("crc") if "crc" in table else None
    if counter is not None and counter == crc:
        # Its CRC taken for a count: every frame a counter jump, every sample invalid.
        raise table.error(
            "counter", f"{counter} is the crc too: the rolling counter is a signal of its own"
        )
    algorithm_name = table.string("crc_algorithm", DEFAULT_CRC_ALGORITHM)
    if algorithm_name not in CRC_ALGORITHMS:
        raise table.error(
            "crc_algorithm", f"unknown {algorithm_name!r}; one of {', '.join(CRC_ALGORITHMS)}"
        )
    algorithm = CRC_ALGORITHMS[algorithm_name]
    # An E2E config that leaves crc_algorithm out gets the default: say that it is one.
    chosen = (
        algorithm_name
        if "crc_algorithm" in table
        else f"{algorithm_name} (the default: no crc_algorithm given)"
    )
    if crc is not None:
        signal = signals[crc]
        bits = 8 * algorithm.width_bytes
        aligned = signal.start % 8 == (7 if signal.byte_order == "big_endian" else 0)
        if signal.length != bits or not aligned:
            raise table.error(
                "crc",
                f"{crc} must be {'an' if bits == 8 else 'a'} {bits}-bit signal on byte boundaries "
                f"for {chosen}, is {signal.length} bits from bit {signal.start}"
                + ("" if "crc_algorithm" in table else "; e2e_p5's CRC is 16 bits"),
            )
        if signal.start // 8 + algorithm.width_bytes > message.length:
            raise table.error("crc", f"{crc} lies outside the {message.length}-byte frame")
    data_id = _data_id(table, algorithm.data_id_layout, chosen)
    if isinstance(data_id, tuple) and counter is None:
        raise table.error(
            "data_id", "a DataIDList is picked by the counter's value: name the counter too"
        )
    data_id_mode, data_id_nibble = _data_id_mode(
        table, algorithm_name, message, database, (counter, crc)
    )
    max_delta = table.integer("max_delta_counter", 2)
    if counter is not None:
        modulo = counter_modulo(message, counter, algorithm_name)
        if not 1 <= max_delta < modulo:
            raise table.error(
                "max_delta_counter", f"must be 1..{modulo - 1} for {counter}, got {max_delta}"
            )
    return Protection(
        message=name,
        counter=counter,
        crc=crc,
        crc_algorithm=algorithm_name,
        data_id=data_id,
        data_id_mode=data_id_mode,
        data_id_nibble=data_id_nibble,
        max_delta_counter=max_delta,
        cycle_time_s=cycle_times_ms[name] / 1000.0 if name in cycle_times_ms else None,
        sender_cycle_times_s=tuple(
            (address, ms / 1000.0)
            for (message, address), ms in sorted(sender_cycle_times_ms.items())
            if message == name
        ),
    )


def _data_id(table: TomlTable, layout: str, algorithm: str) -> int | tuple[int, ...]:
    if layout == "none":
        if "data_id" in table:
            e2e = ", ".join(name for name in CRC_ALGORITHMS if name.startswith("e2e_"))
            raise table.error(
                "data_id", f"{algorithm} has no data ID (the E2E profiles have: {e2e})"
            )
        return 0
    if "data_id" not in table:
        raise table.error("data_id", "missing: the E2E profile's CRC covers a data ID")
    value = table.data["data_id"]
    limit = 0xFF if layout == "after8" else 0xFFFF
    if layout == "after8" and isinstance(value, list):
        if len(value) != 16 or not all(_is_id(item, limit) for item in value):
            raise table.error("data_id", f"a DataIDList must be 16 numbers 0..{limit}")
        return tuple(value)
    if not _is_id(value, limit):
        raise table.error("data_id", f"must be a number 0..{limit:#x}, got {value!r}")
    return int(value)


def _data_id_mode(
    table: TomlTable,
    algorithm_name: str,
    message: Message,
    database: Database,
    counter_crc: tuple[str | None, str | None],
) -> tuple[str, str | None]:
    """AUTOSAR E2E profile 1's DataIDMode and, in mode nibble, the signal of the nibble."""
    modes = CRC_ALGORITHMS[algorithm_name].data_id_modes
    if "data_id_mode" in table and not modes:
        raise table.error("data_id_mode", "only e2e_p1 and e2e_p11 have a data ID mode")
    given = table.string("data_id_mode", modes[0] if modes else "both")
    # As AUTOSAR's configuration tools write it too: E2E_P01_DATAID_ALT, BOTH.
    mode = re.sub(r"^(e2e_p\d+_)?dataid_", "", given.lower())
    if modes and mode not in modes:
        raise table.error(
            "data_id_mode", f"unknown {given!r} for {algorithm_name}; one of {', '.join(modes)}"
        )
    if mode == "alt" and counter_crc[0] is None:
        raise table.error(
            "data_id_mode",
            "alt takes the data ID's low or high byte by the counter's value: name the counter",
        )
    if mode != "nibble":
        if "data_id_nibble" in table:
            raise table.error("data_id_nibble", 'only with data_id_mode = "nibble"')
        return mode, None
    if "data_id_nibble" not in table:
        raise table.error(
            "data_id_nibble",
            "missing: data_id_mode nibble sends the data ID's high nibble in the frame: "
            "name its 4-bit signal",
        )
    nibble = table.string("data_id_nibble")
    if nibble not in {signal.name for signal in message.signals}:
        raise table.error("data_id_nibble", _no_signal(nibble, message, database))
    if message.get_signal_by_name(nibble).length != 4 or nibble in counter_crc:
        raise table.error(
            "data_id_nibble", f"{nibble} must be a 4-bit signal of its own (the data ID nibble)"
        )
    return mode, nibble


def _is_id(value: object, limit: int) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and 0 <= value <= limit
