"""The ``[signals]`` table of the machine configuration: the controller's signals that are
neither a leg's chamber nor a ``[stability]`` angle.

Read by :func:`dbc.machine.parse_machine_config`; optional. Each key is a
``MESSAGE.SIGNAL`` of the DBC; a key left out is the signal of its default name (the
project's DBC, ``dbc/portal_sensors.dbc``) in whichever message of the DBC has it, or
none where the DBC has no such signal. Example (``tests/files/renamed/machine.toml``)::

    [signals]
    phase = "VEHICLE_STATE.StepPhase"            # movement phase (value-table names)
    cycle_count = "VEHICLE_STATE.StepCount"      # completed movement cycles
    cycle_time = "VEHICLE_STATE.StepTime_s"      # time since the cycle started: s, ms, min
    carriage = "BRIDGE_DRIVE.Trolley_m"          # crane carriage: m, cm, mm (+ towards SB1)
    [signals.bases.near]                         # a base of [stability.bases]
    inclination = "BRIDGE_GEOMETRY.TiltNear_deg" # deg, rad or mrad, as [stability]'s angles
    piston = "TILT_NEAR.TILT_NEAR_pPiston"       # inclination cylinder's chambers
    rod = "TILT_NEAR.TILT_NEAR_pRod"
    status = "TILT_NEAR.TILT_NEAR_Status"

The machine state (``phase``, ``cycle_count``, ``cycle_time``) is one message's: the
report and the leg calibration read cycles and phases from its frames; the simulator
bridge sends all of them (the others only it uses; the service publishes them under
``/signals/<MESSAGE>`` whatever they are called).
"""

import logging
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from dbc.toml_table import TomlTable
from dbc.units import angle_factor_to_rad, length_factor_to_m, time_factor_to_s

if TYPE_CHECKING:
    from dbc.machine import SignalRef

logger = logging.getLogger(__name__)

#: Machine-state keys and the default signal names.
STATE_DEFAULTS = {
    "phase": "Machine_Phase",
    "cycle_count": "Machine_CycleCount",
    "cycle_time": "Machine_CycleTime",
}
SIGNALS_KEYS = (*STATE_DEFAULTS, "carriage", "bases")
#: Default of ``carriage``.
CARRIAGE_DEFAULT = "Carriage_Position"
BASE_SIGNAL_KEYS = ("inclination", "piston", "rod", "status")
#: The simulation's bases, in order: what ``[signals.bases.<BASE>]`` is called without
#: ``[stability]``, and the prefix of the default names (``INCL_SB1_pPiston``, ...).
SIMULATED_BASES: tuple[str, str] = ("SB1", "SB2")
#: The movement phases, numbered as in the project DBC's ``Machine_Phase`` value table.
PHASES = ("idle", "move_carriage", "fold", "rotate", "unfold")


def phase_values(choices: Mapping[int, object] | None) -> tuple[str | int, ...]:
    """What the phase signal carries for each of :data:`PHASES`: the phase's name where
    the signal's value table (``choices``) has it, else its number (0..4), which a DBC
    may name otherwise (``0 "Ruhe"``) or not at all. The simulator bridge sends these.

    >>> phase_values({0: "idle", 1: "move_carriage", 2: "fold", 3: "rotate", 4: "unfold"})
    ('idle', 'move_carriage', 'fold', 'rotate', 'unfold')
    >>> phase_values({0: "Ruhe", 1: "Laufkatze"})
    (0, 1, 2, 3, 4)
    """
    names = {str(name) for name in (choices or {}).values()}
    return tuple(phase if phase in names else index for index, phase in enumerate(PHASES))


def phase_meanings(choices: Mapping[int, object] | None) -> dict[str, str]:
    """The movement phase of each value of the phase signal, by its text as decoded (a
    value-table name, or the number): the inverse of :func:`phase_values`.

    >>> phase_meanings({0: "Ruhe", 1: "Laufkatze"})["Laufkatze"], phase_meanings(None)["3"]
    ('move_carriage', 'rotate')
    """
    named = {int(number): str(name) for number, name in (choices or {}).items()}
    meanings: dict[str, str] = {}
    for phase, value in zip(PHASES, phase_values(choices), strict=True):
        if isinstance(value, str):
            meanings.setdefault(value, phase)
        elif value in named:
            meanings.setdefault(named[value], phase)
        else:  # decoded as a number: an integer, or a float where the signal scales
            meanings.setdefault(str(value), phase)
            meanings.setdefault(str(float(value)), phase)
    return meanings


def base_defaults(base: str) -> dict[str, str]:
    """The default signal names of the ``SB1`` or ``SB2`` base's keys."""
    return {
        "inclination": f"{base}_InclinationAngle",
        "piston": f"INCL_{base}_pPiston",
        "rod": f"INCL_{base}_pRod",
        "status": f"INCL_{base}_Status",
    }


@dataclass(frozen=True)
class BaseSignals:
    """One base's inclination cylinder: its angle and chambers; None: not in the DBC."""

    inclination: "SignalRef | None"
    #: Radians per unit of the inclination signal's values.
    inclination_rad_per_unit: float
    piston: "SignalRef | None"
    rod: "SignalRef | None"
    status: "SignalRef | None"


@dataclass(frozen=True)
class MachineSignals:
    """Where the controller's signals are; None: the DBC has none (nothing is sent)."""

    phase: "SignalRef | None"
    cycle_count: "SignalRef | None"
    cycle_time: "SignalRef | None"
    carriage: "SignalRef | None"
    #: The base standing at start (the simulation's SB1), then the other one.
    bases: tuple[BaseSignals, BaseSignals]
    #: Their names: ``[stability.bases]``'s, else the simulation's.
    base_names: tuple[str, str] = SIMULATED_BASES
    #: Seconds per unit of ``cycle_time``'s values, metres per unit of ``carriage``'s
    #: (their DBC units: a time in cycle in ms, a carriage in mm).
    cycle_time_s_per_unit: float = 1.0
    carriage_m_per_unit: float = 1.0

    @property
    def state_message(self) -> str | None:
        """The machine state's message (cycles and phases); None: the DBC has none."""
        refs = (self.cycle_count, self.cycle_time, self.phase)
        return next((ref.message for ref in refs if ref is not None), None)

    def absent(self) -> list[str]:
        """The keys of ``[signals]`` no signal of the DBC is for (``bases.far.piston``)."""
        missing = [key for key in (*STATE_DEFAULTS, "carriage") if getattr(self, key) is None]
        for base, signals in zip(self.base_names, self.bases, strict=True):
            missing += [
                f"bases.{base}.{key}" for key in BASE_SIGNAL_KEYS if getattr(signals, key) is None
            ]
        return missing


_NO_BASE = BaseSignals(None, math.radians(1.0), None, None, None)
#: A DBC without any of the signals.
NO_SIGNALS = MachineSignals(None, None, None, None, (_NO_BASE, _NO_BASE))


def parse_signals(
    table: TomlTable,
    base_names: Sequence[str] | None,
    signal: Callable[[TomlTable, str], "SignalRef"],
    find: Callable[[str], "SignalRef | None"],
    angle: Callable[[TomlTable, str], tuple["SignalRef", float]],
    unit_of: Callable[["SignalRef"], str],
) -> MachineSignals:
    """The ``[signals]`` table (may be empty).

    ``base_names``: the ``[stability.bases]`` names in order (None: no ``[stability]``,
    the bases are ``SB1``, ``SB2``); ``signal`` resolves a ``MESSAGE.SIGNAL`` key against
    the DBC, ``find`` a default signal name (the first message that has it), ``angle`` an
    angle key (as ``[stability]``'s: its signal and radians per unit), ``unit_of`` a
    signal's DBC unit (an inclination without an angle unit is in degrees, a time in cycle
    without a time unit in seconds, a carriage without a length unit in metres).
    """
    table.reject_unknown(SIGNALS_KEYS)

    def ref(at: TomlTable, key: str, default: str) -> "SignalRef | None":
        return signal(at, key) if key in at else find(default)

    state = {key: ref(table, key, default) for key, default in STATE_DEFAULTS.items()}
    refs = [(key, ref) for key, ref in state.items() if ref is not None]
    other = next((key for key, ref in refs if ref.message != refs[0][1].message), None)
    if other is not None:
        where = ", ".join(f"{key} = {ref}" for key, ref in refs)
        raise table.error(
            other,
            f"the machine state is one message's (the report reads cycles and phases from "
            f"its frames); got {where}",
        )
    names = tuple(base_names) if base_names is not None else SIMULATED_BASES
    bases_table = table.table("bases", required=False)
    by_base = dict(bases_table.subtables())
    unknown = [name for name in by_base if name not in names]
    if unknown:
        raise bases_table.error(
            unknown[0],
            f"no base {unknown[0]!r}; the bases are {', '.join(names)}"
            + (" ([stability.bases])" if base_names is not None else " (the simulation's)"),
        )
    bases = []
    for name, simulated in zip(names, SIMULATED_BASES, strict=True):
        at = by_base.get(name, TomlTable({}, table.source, bases_table.key(name)))
        at.reject_unknown(BASE_SIGNAL_KEYS)
        defaults = base_defaults(simulated)
        inclination = None
        rad_per_unit = math.radians(1.0)
        if "inclination" in at:
            inclination, rad_per_unit = angle(at, "inclination")
        elif (inclination := find(defaults["inclination"])) is not None:
            rad_per_unit = angle_factor_to_rad(unit_of(inclination)) or rad_per_unit
        bases.append(
            BaseSignals(
                inclination=inclination,
                inclination_rad_per_unit=rad_per_unit,
                piston=ref(at, "piston", defaults["piston"]),
                rod=ref(at, "rod", defaults["rod"]),
                status=ref(at, "status", defaults["status"]),
            )
        )
    carriage = ref(table, "carriage", CARRIAGE_DEFAULT)
    return MachineSignals(
        phase=state["phase"],
        cycle_count=state["cycle_count"],
        cycle_time=state["cycle_time"],
        carriage=carriage,
        bases=(bases[0], bases[1]),
        base_names=(names[0], names[1]),
        cycle_time_s_per_unit=_per_unit(
            table, "cycle_time", state["cycle_time"], unit_of, time_factor_to_s, "s, ms, min"
        ),
        carriage_m_per_unit=_per_unit(
            table, "carriage", carriage, unit_of, length_factor_to_m, "m, cm, mm"
        ),
    )


def _per_unit(
    table: TomlTable,
    key: str,
    ref: "SignalRef | None",
    unit_of: Callable[["SignalRef"], str],
    factor: Callable[[str], float | None],
    accepted: str,
) -> float:
    """SI per unit of ``ref``'s values, by its DBC unit; 1 (SI) where it has none, or
    one ``factor`` does not know (one warning line: its number is taken as SI)."""
    if ref is None:
        return 1.0
    unit = unit_of(ref)
    per_unit = factor(unit)
    if per_unit is None and unit.strip():
        logger.warning(
            "%s: %s: %s has unit %r, none of %s: its values are taken in %s",
            table.source,
            table.key(key),
            ref,
            unit,
            accepted,
            accepted.split(",")[0],
        )
    return per_unit or 1.0
