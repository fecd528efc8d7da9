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

import math
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cantools.database.can import Database, Message

from dbc import DEFAULT_DBC_PATH
from dbc.database import load_database
from dbc.errors import ConfigError
from dbc.toml_table import TomlTable
from estimator.geometry import LegGeometry
from estimator.settings import EstimatorSettings

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
)
LEG_SIGNAL_KEYS = ("piston", "rod", "status")
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
SENSOR_KEYS = ("pressure_min_Pa", "pressure_max_Pa", "status_ok")
#: Top-level tables of the machine configuration.
MACHINE_TABLES = ("machine", "estimator", "sensors", "leg_defaults", "legs", "protection")
#: Tables of the service configuration that may share the file; this loader leaves
#: them to :mod:`daq.service_config`, which checks them.
SERVICE_TABLES = ("bus", "zenoh", "publish", "recording")


@dataclass(frozen=True, slots=True)
class SignalRef:
    """A signal of the DBC, written ``MESSAGE.SIGNAL`` in the config."""

    message: str
    signal: str

    def __str__(self) -> str:
        return f"{self.message}.{self.signal}"


@dataclass(frozen=True, slots=True)
class LegConfig:
    """One leg: its geometry and where its chamber pressures are on the bus."""

    name: str
    geometry: LegGeometry
    piston: SignalRef
    rod: SignalRef
    #: Sensor status signal with a value table; None when the DBC has none.
    status: SignalRef | None
    #: GenMsgCycleTime of the leg's message.
    cycle_time_s: float

    @property
    def message(self) -> str:
        """The one message that carries both chamber pressures of this leg."""
        return self.piston.message


@dataclass(frozen=True, slots=True)
class Protection:
    """The end-to-end protection signals of one message."""

    message: str
    counter: str
    crc: str


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

    @property
    def weight_N(self) -> float:
        return self.mass_kg * G_M_S2


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
        raise ConfigError(source, "", f"not valid TOML: {exc}") from exc
    except UnicodeDecodeError as exc:  # TOML is UTF-8; e.g. a Latin-1 comment "46 °C"
        raise ConfigError(
            source,
            "",
            f"not UTF-8 (byte 0x{exc.object[exc.start]:02x} at offset {exc.start}); "
            "save the file as UTF-8",
        ) from exc


def _dbc_path(root: TomlTable, config_dir: Path) -> Path:
    machine = root.table("machine")
    if "dbc" not in machine:
        return DEFAULT_DBC_PATH
    return config_dir / machine.string("dbc")


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
    owners = {key: estimator for key in ESTIMATOR_KEYS} | {key: sensors for key in SENSOR_KEYS}
    settings_kwargs: dict[str, Any] = {
        "filter": estimator.string("filter", defaults.filter),
        "median_window": estimator.integer("median_window", defaults.median_window),
        "hampel_window": estimator.integer("hampel_window", defaults.hampel_window),
        "status_ok": sensors.string("status_ok", defaults.status_ok),
    }
    for key, table in owners.items():
        if key not in settings_kwargs:
            settings_kwargs[key] = table.number(key, getattr(defaults, key))
    settings = root.build(EstimatorSettings, owners, **settings_kwargs)

    leg_defaults = root.table("leg_defaults", required=False)
    leg_defaults.reject_unknown(GEOMETRY_KEYS)
    legs_table = root.table("legs")
    if not legs_table.data:
        raise legs_table.error("", "no legs configured; add a [legs.<LEG>] table per leg")
    legs = {
        name: _leg(name, table, leg_defaults, database) for name, table in legs_table.subtables()
    }
    protection = {
        name: _protection(name, table, database)
        for name, table in root.table("protection", required=False).subtables()
    }
    return MachineConfig(
        source=source,
        machine_id=machine.string("id", pattern=NAME_PATTERN),
        mass_kg=mass_kg,
        dbc_path=dbc_path,
        estimator=settings,
        legs=legs,
        protection=protection,
    )


def _leg(name: str, table: TomlTable, defaults: TomlTable, database: Database) -> LegConfig:
    if re.fullmatch(NAME_PATTERN, name) is None:
        raise table.error("", f"leg name {name!r} must match {NAME_PATTERN}")
    table.reject_unknown((*GEOMETRY_KEYS, *LEG_SIGNAL_KEYS))
    values: dict[str, float] = {}
    owners: dict[str, TomlTable] = {}
    for key in GEOMETRY_KEYS:
        owner = table if key in table else defaults
        if key not in owner:
            raise table.error(key, "missing (and not given in [leg_defaults])")
        values[key] = owner.number(key)
        owners[key] = owner
    values["alpha_cyl_rad"] = math.radians(values.pop("alpha_cyl_deg"))
    owners["alpha_cyl_rad"] = owners.pop("alpha_cyl_deg")
    geometry = table.build(LegGeometry, owners, **values)

    piston = _signal(table, "piston", database)
    rod = _signal(table, "rod", database)
    status = _signal(table, "status", database) if "status" in table else None
    for key, ref in (("rod", rod), ("status", status)):
        if ref is not None and ref.message != piston.message:
            raise table.error(
                key,
                f"{ref} is not in {piston.message}, the message of the piston pressure: "
                "piston, rod and status must share one frame so that each frame is one sample",
            )
    message = database.get_message_by_name(piston.message)
    if not message.cycle_time:
        raise table.error(
            "piston",
            f"message {message.name} has no GenMsgCycleTime in the DBC; "
            "staleness cannot be judged without it",
        )
    return LegConfig(
        name=name,
        geometry=geometry,
        piston=piston,
        rod=rod,
        status=status,
        cycle_time_s=message.cycle_time / 1000.0,
    )


def _signal(table: TomlTable, key: str, database: Database) -> SignalRef:
    text = table.string(key)
    message_name, dot, signal_name = text.partition(".")
    if not dot or not message_name or not signal_name:
        raise table.error(key, f"{text!r} must be written MESSAGE.SIGNAL")
    message = _message(table, key, message_name, database)
    if signal_name not in {signal.name for signal in message.signals}:
        raise table.error(key, f"no signal {signal_name!r} in message {message_name} of the DBC")
    return SignalRef(message_name, signal_name)


def _message(table: TomlTable, key: str, name: str, database: Database) -> Message:
    try:
        return database.get_message_by_name(name)
    except KeyError:
        raise table.error(key, f"no message {name!r} in the DBC") from None


def _protection(name: str, table: TomlTable, database: Database) -> Protection:
    table.reject_unknown(("counter", "crc"))
    message = _message(table, "", name, database)
    signals = {signal.name: signal for signal in message.signals}
    counter_name, crc_name = table.string("counter"), table.string("crc")
    for key, signal_name in (("counter", counter_name), ("crc", crc_name)):
        if signal_name not in signals:
            raise table.error(key, f"no signal {signal_name!r} in message {name} of the DBC")
    crc = signals[crc_name]
    if crc.length != 8 or crc.start % 8 or crc.byte_order != "little_endian":
        raise table.error("crc", f"{crc_name} must be an 8-bit signal on a byte boundary")
    if crc.start // 8 >= message.length:
        raise table.error("crc", f"{crc_name} lies outside the {message.length}-byte frame")
    return Protection(message=name, counter=counter_name, crc=crc_name)
