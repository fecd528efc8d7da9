"""The ``[stability]`` table of the machine configuration: feet, bridge, pose signals.

Read by :func:`dbc.machine.parse_machine_config`; optional (no table: no stability
margin). Example (``deploy/machine.example.toml``)::

    [stability]
    rotation = "BRIDGE_MOTION.Bridge_RotationAngle"   # about the standing base; 0: its x
    fold = "BRIDGE_POSE.Bridge_FoldAngle"             # 0 = unfolded
    bridge_length_m = 6.0
    hinge_m = 3.0
    warning_margin_m = 0.3
    [stability.bases.SB1]                             # the first base stands at start
    axis_m = [0.07, 0.0]
    feet_m = { SB1_F1 = [1.6, 0.0], SB1_F2 = [-0.8, 1.3856], SB1_F3 = [-0.8, -1.3856] }
    [stability.bases.SB2]
    ...

The angles are in the DBC signal's unit (deg, rad, mrad: :data:`dbc.units.ANGLE_UNITS_TO_RAD`),
or in the one the config gives where the DBC's is empty or wrong:
``rotation = { signal = "POSE.Rot", unit = "rad" }``.
"""

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from dbc.toml_table import TomlTable
from dbc.units import ACCEPTED_ANGLE_UNITS, angle_factor_to_rad
from estimator.kinematics import BaseLayout, MachineLayout, Point

if TYPE_CHECKING:
    from dbc.machine import SignalRef

STABILITY_KEYS = (
    "rotation",
    "fold",
    "bridge_length_m",
    "hinge_m",
    "warning_margin_m",
    "bases",
)
BASE_KEYS = ("axis_m", "feet_m")
#: Keys of an angle given as a table: ``{ signal = "M.S", unit = "rad" }``.
ANGLE_KEYS = ("signal", "unit")
#: Default of ``warning_margin_m``.
WARNING_MARGIN_M = 0.3


@dataclass(frozen=True)
class StabilityConfig:
    """What the stability margin needs: the layout and where the pose is on the bus."""

    layout: MachineLayout
    #: Bridge rotation angle signal.
    rotation: "SignalRef"
    #: Bridge fold angle signal.
    fold: "SignalRef"
    #: Monitor and dashboard warn when the margin falls below this, m.
    warning_margin_m: float
    #: Radians per unit of the rotation and the fold signal's values.
    rotation_rad_per_unit: float = math.pi / 180.0
    fold_rad_per_unit: float = math.pi / 180.0


def parse_stability(
    table: TomlTable,
    legs: Iterable[str],
    signal: Callable[[TomlTable, str], "SignalRef"],
    unit: Callable[["SignalRef"], str | None],
) -> StabilityConfig | None:
    """The ``[stability]`` table (None when it is absent or empty).

    ``signal`` resolves the ``signal`` of a signal table
    (:meth:`~dbc.toml_table.TomlTable.signal_table`) against the DBC, its errors naming
    the key it is given; ``unit`` gives a signal's unit; every configured leg must have
    exactly one foot.
    """
    if not table.data:
        return None
    table.reject_unknown(STABILITY_KEYS)
    refs = {}
    rad_per_unit = {}
    for key in ("rotation", "fold"):
        refs[key], rad_per_unit[key] = angle_signal(table, key, signal, unit)
    warning_m = table.number("warning_margin_m", WARNING_MARGIN_M)
    if warning_m < 0:
        raise table.error("warning_margin_m", f"must be >= 0, got {warning_m}")
    bases_table = table.table("bases")
    bases = [_base(name, base) for name, base in bases_table.subtables()]
    if len(bases) != 2:
        raise bases_table.error("", f"needs two bases, got {len(bases)}")
    placed = [leg for base in bases for leg in base.feet_m]
    missing = sorted(set(legs) - set(placed))
    unknown = sorted(set(placed) - set(legs))
    # A foot in both bases: the second base's place was taken for it, silently.
    twice = sorted({leg for leg in placed if placed.count(leg) > 1})
    wrong = [
        f"{what} {names}"
        for what, names in (("missing", missing), ("not legs", unknown), ("in both bases", twice))
        if names
    ]
    if wrong:
        raise bases_table.error("", f"every leg needs one foot: {', '.join(wrong)}")
    layout = table.build(
        MachineLayout,
        bases=(bases[0], bases[1]),
        bridge_length_m=table.number("bridge_length_m"),
        hinge_m=table.number("hinge_m"),
    )
    return StabilityConfig(
        layout,
        refs["rotation"],
        refs["fold"],
        warning_m,
        rotation_rad_per_unit=rad_per_unit["rotation"],
        fold_rad_per_unit=rad_per_unit["fold"],
    )


def angle_signal(
    table: TomlTable,
    key: str,
    signal: Callable[[TomlTable, str], "SignalRef"],
    unit: Callable[["SignalRef"], str | None],
) -> tuple["SignalRef", float]:
    """An angle's signal (``"M.S"`` or ``{ signal = "M.S", unit = "rad" }``) and radians per
    unit of its value: the config's unit, else the DBC's."""
    angle, signal_key = table.signal_table(key, ANGLE_KEYS)
    ref = signal(angle, signal_key)
    if "unit" in angle:
        given = angle.string("unit")
        factor = angle_factor_to_rad(given)
        if factor is None:
            raise angle.error(
                "unit", f"{given!r} is not an angle unit; use one of {ACCEPTED_ANGLE_UNITS}"
            )
        return ref, factor
    dbc_unit = unit(ref) or ""
    factor = angle_factor_to_rad(dbc_unit)
    if factor is None:
        raise angle.error(
            "",
            f"{ref} has unit {dbc_unit!r} in the DBC, not an angle unit; give its unit: "
            f'{key} = {{ signal = "{ref}", unit = "deg" }} (one of {ACCEPTED_ANGLE_UNITS})',
        )
    return ref, factor


def _base(name: str, table: TomlTable) -> BaseLayout:
    table.reject_unknown(BASE_KEYS)
    feet = table.table("feet_m")
    return BaseLayout(
        name=name,
        axis_m=_point(table, "axis_m", table.data.get("axis_m")),
        feet_m={leg: _point(feet, leg, value) for leg, value in feet.data.items()},
    )


def _point(table: TomlTable, key: str, value: Any) -> Point:
    """``[x, y]``, each a finite number (NaN and inf were taken: the stability margin
    was NaN; an integer beyond 64 bits was an OverflowError traceback)."""
    if not isinstance(value, list) or len(value) != 2:
        raise table.error(key, f"must be [x, y] in metres, got {value!r}")
    return (table.finite(key, value[0]), table.finite(key, value[1]))
