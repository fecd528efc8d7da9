"""``portal-daq check --config FILE``: check a configuration against its DBC, no bus.

Reads the service configuration (a machine configuration alone too), the DBC it
names and the Zenoh file and endpoints of ``[zenoh]`` as ``run`` and ``replay`` do (the
session is not opened), and prints what each leg reads: each chamber's
``MESSAGE.SIGNAL`` (with its J1939 sender and multiplexer page), unit, cycle time and
status. A wrong key is the one line ``FILE: KEY: reason``, exit 2, as ``run`` says it; a
user with the wheel alone had no way to see a config's mapping without a bus or a log.
"""

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from cantools.database.can import Database, Message

from daq.service_config import load_service_config
from daq.subcommand import PROG, Subcommand, fail, setup_logging
from daq.zenoh_session import session_config
from dbc.errors import ConfigError, DbcError
from dbc.machine import ChamberSignal, MachineConfig, StatusCheck
from dbc.protection import CRC_ALGORITHMS, DEFAULT_CRC_ALGORITHM, Protection, counter_modulo
from estimator.geometry import LegGeometry


def check_main(args: Sequence[str]) -> int:
    parser = argparse.ArgumentParser(
        prog=f"{PROG} check",
        description="Check a service or machine configuration against its DBC, without a "
        "bus, and print what each leg reads; a wrong key is one line FILE: KEY: reason "
        "(exit 2).",
    )
    parser.add_argument("--config", type=Path, required=True, help="service + machine TOML")
    options = parser.parse_args(args)
    setup_logging("WARNING")
    try:
        config = load_service_config(options.config)
        # The Zenoh file and endpoints, as run opens its session with them: a JSON5 file
        # Zenoh refuses, port 99999 or an access control gap passed here and stopped run.
        session_config(config.zenoh, config.source)
    except (ConfigError, DbcError) as exc:
        return fail(exc, 2)
    sys.stdout.write(describe(config.machine, config.database))
    return 0


def describe(machine: MachineConfig, database: Database) -> str:
    """What ``machine``'s legs read, a line per leg and chamber, and how each protected
    message is checked."""
    lines = [
        f"{machine.source}: machine {machine.machine_id}, {len(machine.legs)} legs, "
        f"DBC {machine.dbc_path} ({len(database.messages)} messages)"
    ]
    for leg in machine.legs.values():
        lines.append(
            f"leg {leg.name}: sample on each {leg.trigger} value, the other chamber's at "
            f"most {1000 * leg.max_skew_s:g} ms older"
        )
        lines.append(f"  piston: {_chamber(leg.piston)}")
        lines.append(f"  rod: {_chamber(leg.rod)}")
    lines += [_equation(leg.name, leg.geometry) for leg in machine.legs.values()]
    lines += [
        _protection(p, database.get_message_by_name(name)) for name, p in machine.protection.items()
    ]
    return "\n".join(lines) + "\n"


def _protection(p: Protection, message: Message) -> str:
    """How ``message``'s frames are checked: the counter's values and steps, the CRC's
    algorithm and data ID (profile 1: its mode)."""
    parts = []
    if p.counter is not None:
        last = counter_modulo(message, p.counter, p.crc_algorithm) - 1
        parts.append(f"counter {p.counter} 0..{last} (steps up to {p.max_delta_counter})")
    if p.crc is not None:
        crc = f"CRC {p.crc} {p.crc_algorithm}"
        if isinstance(p.data_id, tuple):
            crc += f", data ID list {', '.join(f'0x{i:02X}' for i in p.data_id)} by counter"
        elif p.crc_algorithm != DEFAULT_CRC_ALGORITHM:
            crc += f", data ID 0x{p.data_id:04X}"
        if CRC_ALGORITHMS[p.crc_algorithm].data_id_modes:
            mode = f"nibble in {p.data_id_nibble}" if p.data_id_nibble else p.data_id_mode
            crc += f" ({mode})"
        parts.append(crc)
    return f"protected {p.message}: {', '.join(parts)}"


def _equation(name: str, g: LegGeometry) -> str:
    """Eq. (4) and (5) of one leg with its constants, to check by hand."""
    calibrated = (
        f" (lever {g.force_ratio:.6g} x gain {g.force_gain:g}; leg {g.weight_term_N:.6g} N, "
        f"offset {g.force_offset_N:g} N)"
        if (g.force_gain, g.force_offset_N) != (1.0, 0.0)
        else ""
    )
    return (
        f"eq. (4) {name}: F_zFoot = {g.calibrated_ratio:.6g} x F_cyl "
        f"{'-' if g.calibrated_term_N < 0 else '+'} {abs(g.calibrated_term_N):.6g} N{calibrated}, "
        f"F_cyl = p_piston x {g.A_piston_m2:g} m2 - p_rod x {g.A_rod_m2:g} m2; "
        f"p_ground = F_zFoot / {g.A_foot_m2:g} m2"
    )


def _chamber(chamber: ChamberSignal) -> str:
    status = f", status {_status(chamber.status)}" if chamber.status is not None else ""
    gauge = " (absolute: less the standard atmosphere)" if chamber.atmosphere_Pa else ""
    sender = chamber.dbc_source_address
    where = f"{chamber}" if sender is None else f"{chamber} from 0x{sender:02X} (its DBC ID's)"
    return f"{where} in {chamber.unit!r}{gauge}, every {1000 * chamber.cycle_time_s:g} ms{status}"


def _status(status: StatusCheck) -> str:
    """The status signal and its fine values, by name where the value table names them."""
    names = sorted(str(value) for value in status.ok if isinstance(value, str))
    fine = names or sorted(str(value) for value in status.ok)
    return f"{status.signal} (fine: {', '.join(fine)})"


SUBCOMMAND = Subcommand(
    "check", "check a configuration against its DBC and show what each leg reads", check_main
)
