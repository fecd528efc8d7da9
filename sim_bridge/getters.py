"""Getters: which series of a :class:`~sim_bridge.result.SimulationResult` a DBC signal
carries, where the config places it or found by its name (see :mod:`sim_bridge.frames`).
Pure computation.

>>> sorted(named_getters({}))[:3]
['Bridge_FoldAngle', 'Bridge_RotationAngle', 'SB1_F1_Stroke']
"""

import math
from collections.abc import Callable, Mapping

from cantools.database.can import Database, Signal

from dbc.decoding import SignalValue
from dbc.machine import MachineConfig, SignalRef
from dbc.machine_signals import phase_values
from dbc.units import angle_factor_to_rad, length_factor_to_m
from sim_bridge.result import LEGS, SimulationResult

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


def in_signal_unit(signal: Signal, getter: Getter) -> Getter:
    """A getter of :func:`named_getters` for ``signal``, in its DBC unit: the
    ``Bridge_...Angle`` getters' degrees where that is another angle unit (rad, mrad),
    the ``<LEG>_Stroke`` getters' metres where it is another length unit (cm, mm: sent
    as metres, a 1.2 m stroke was 1.2 mm)."""
    unit = signal.unit or ""
    if signal.name.endswith("Angle") and (rad_per_unit := angle_factor_to_rad(unit)):
        return degrees_in(getter, rad_per_unit)
    if signal.name.endswith("_Stroke") and (m_per_unit := length_factor_to_m(unit)):
        return scaled(getter, 1.0 / m_per_unit)
    return getter


def phase_getter(signal: Signal) -> Getter:
    """The phase by its value-table name when the DBC's table has the names, else its
    index (:func:`dbc.machine_signals.phase_values`)."""
    values = phase_values(signal.choices)

    def phase(result: SimulationResult, row: int, cycle: int) -> SignalValue:
        index = int(result.phase[row])
        return values[index] if 0 <= index < len(values) else index

    return phase


def named_getters(columns: Mapping[str, int]) -> dict[str, Getter]:
    """Getters of the signals found by their name in the DBC: the bridge angles (where
    ``[stability]`` does not place them) and ``<LEG>_Stroke``; ``columns``: each config
    leg's column, whose ``<LEG>_Stroke`` is its simulated leg's."""
    getters: dict[str, Getter] = {
        "Bridge_FoldAngle": series_getter("fold_deg"),
        "Bridge_RotationAngle": series_getter("rotation_deg"),
    }
    for leg, column in ({leg: i for i, leg in enumerate(LEGS)} | dict(columns)).items():
        getters[f"{leg}_Stroke"] = column_getter("stroke_m", column)
    return getters


def configured_getters(config: MachineConfig, database: Database) -> dict[str, Getter]:
    """Getters by ``MESSAGE.SIGNAL`` of the signals the config places: the ``[stability]``
    angles and the ``[signals]`` (or their defaults found in the DBC), in their units."""
    getters: dict[str, Getter] = {}
    if config.stability is not None:
        stability = config.stability
        getters[str(stability.rotation)] = degrees_in(
            series_getter("rotation_deg"), stability.rotation_rad_per_unit
        )
        getters[str(stability.fold)] = degrees_in(
            series_getter("fold_deg"), stability.fold_rad_per_unit
        )
    signals = config.signals
    status_ok = config.status_ok[0]
    series: list[tuple[SignalRef | None, Getter]] = [
        (signals.cycle_count, lambda result, row, cycle: cycle),
        (signals.cycle_time, scaled(series_getter("t_s"), 1.0 / signals.cycle_time_s_per_unit)),
        (signals.carriage, scaled(series_getter("carriage_m"), 1.0 / signals.carriage_m_per_unit)),
    ]
    if (phase := signals.phase) is not None:
        message = database.get_message_by_name(phase.message)
        series.append((phase, phase_getter(message.get_signal_by_name(phase.signal))))
    for b, base in enumerate(signals.bases):
        series += [
            (base.piston, column_getter("incl_p_piston_Pa", b)),
            (base.rod, column_getter("incl_p_rod_Pa", b)),
            (base.status, lambda result, row, cycle: status_ok),
            (
                base.inclination,
                degrees_in(column_getter("inclination_deg", b), base.inclination_rad_per_unit),
            ),
        ]
    getters |= {str(ref): getter for ref, getter in series if ref is not None}
    return getters
