"""Getters: which series of a :class:`~sim_bridge.result.SimulationResult` a DBC signal
found by name carries (see :mod:`sim_bridge.frames`). Pure computation.

>>> sorted(named_getters("ok", {}))[:3]
['Bridge_FoldAngle', 'Bridge_RotationAngle', 'Carriage_Position']
"""

import math
from collections.abc import Callable, Mapping

from cantools.database.can import Signal

from dbc.decoding import SignalValue
from dbc.units import angle_factor_to_rad
from sim_bridge.result import BASES, LEGS, PHASES, SimulationResult

#: A signal's value at one row: (result, row, completed cycles) -> physical value or name.
Getter = Callable[[SimulationResult, int, int], SignalValue]


def column_getter(field: str, column: int) -> Getter:
    return lambda result, row, cycle: float(getattr(result, field)[row, column])


def series_getter(field: str) -> Getter:
    return lambda result, row, cycle: float(getattr(result, field)[row])


def scaled(getter: Getter, factor: float) -> Getter:
    if factor == 1.0:
        return getter
    return lambda result, row, cycle: float(getter(result, row, cycle)) * factor


def degrees_in(getter: Getter, rad_per_unit: float) -> Getter:
    """A getter of degrees (the simulation's angles) giving the angle in a unit of
    ``rad_per_unit`` radians."""
    return scaled(getter, math.radians(1.0) / rad_per_unit)


def in_angle_unit(signal: Signal, getter: Getter) -> Getter:
    """A getter of degrees (the ``...Angle`` getters) for ``signal``, in its DBC unit where
    that is another angle unit (rad, mrad)."""
    rad_per_unit = angle_factor_to_rad(signal.unit or "")
    if not signal.name.endswith("Angle") or rad_per_unit is None:
        return getter
    return degrees_in(getter, rad_per_unit)


def phase_getter(signal: Signal) -> Getter:
    """The phase by its value-table name when the DBC's table has the names, else its index."""
    names = {str(choice) for choice in (signal.choices or {}).values()}

    def phase(result: SimulationResult, row: int, cycle: int) -> SignalValue:
        index = int(result.phase[row])
        if 0 <= index < len(PHASES) and PHASES[index] in names:
            return PHASES[index]
        return index

    return phase


def named_getters(status_ok: SignalValue, columns: Mapping[str, int]) -> dict[str, Getter]:
    """Getters of the signals found by name in the DBC (Machine_Phase aside); ``columns``:
    each config leg's column, whose ``<LEG>_Stroke`` is its simulated leg's."""
    getters: dict[str, Getter] = {
        "Bridge_FoldAngle": series_getter("fold_deg"),
        "Bridge_RotationAngle": series_getter("rotation_deg"),
        "Carriage_Position": series_getter("carriage_m"),
        "Machine_CycleCount": lambda result, row, cycle: cycle,
        "Machine_CycleTime": lambda result, row, cycle: float(result.t_s[row]),
    }
    for b, base in enumerate(BASES):
        getters[f"INCL_{base}_pPiston"] = column_getter("incl_p_piston_Pa", b)
        getters[f"INCL_{base}_pRod"] = column_getter("incl_p_rod_Pa", b)
        getters[f"INCL_{base}_Status"] = lambda result, row, cycle: status_ok
        getters[f"{base}_InclinationAngle"] = column_getter("inclination_deg", b)
    for leg, column in ({leg: i for i, leg in enumerate(LEGS)} | dict(columns)).items():
        getters[f"{leg}_Stroke"] = column_getter("stroke_m", column)
    return getters
