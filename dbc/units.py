"""Units of DBC signals and their factor to SI: the one table of them.

Pressures (the legs' chambers) go to Pa; the bridge angles of ``[stability]`` to radians.

A DBC signal's physical value is in the unit its ``unit`` string names; the
service works in SI inside, so every pressure signal is converted to Pa when it
is decoded, and back when the simulator encodes one. The unit comes from the DBC
or, where the DBC's is empty or wrong, from the config (``unit = "bar"``), for one
J1939 transducer of a shared signal where the chamber pins its source address.

>>> pressure_factor_to_Pa("bar")
100000.0
>>> pressure_factor_to_Pa("PSI")
6894.757293168361
>>> pressure_factor_to_Pa("m") is None
True

A unit marked gauge (``psig``, ``barg``, ``bar(g)``, ``kPa gauge``) is that unit: the
chamber pressures are gauge pressures. An absolute one (``bara``, ``psia``) is none of
these units (it is off by the atmosphere's ~1 bar).

>>> pressure_factor_to_Pa("psi(g)") == pressure_factor_to_Pa("PSIG") == 6894.757293168361
True
>>> pressure_factor_to_Pa("bara") is None
True
"""

import math

#: Accepted pressure units (lower case) and what one of them is in Pa.
PRESSURE_UNITS_TO_PA: dict[str, float] = {
    "pa": 1.0,
    "kpa": 1.0e3,
    "mpa": 1.0e6,
    "bar": 1.0e5,
    "mbar": 1.0e2,
    # 1 lbf / in2 = 4.4482216152605 N / 0.00064516 m2 (exact by the definitions of lb and in).
    "psi": 6894.757293168361,
    "hpa": 1.0e2,
    "n/mm2": 1.0e6,
    # 1 kgf / cm2 = 9.80665 N / 1e-4 m2 (standard gravity; "kg/cm2" on older gauges).
    "kgf/cm2": 98066.5,
    "kg/cm2": 98066.5,
}

#: The accepted units as a person writes them, for error messages.
ACCEPTED_PRESSURE_UNITS = "Pa, kPa, MPa, bar, mbar, psi, hPa, N/mm2, kgf/cm2"


#: Marks of a gauge unit after the unit's name (longest first), e.g. "psig", "bar(g)".
GAUGE_MARKS = ("(gauge)", "gauge", "(g)", "g")


def pressure_factor_to_Pa(unit: str) -> float | None:
    """Pa per one ``unit`` (case-insensitive, surrounding blanks and a gauge mark
    ignored, "²" read as "2"); None if unknown."""
    name = unit.strip().lower().replace("²", "2")
    factor = PRESSURE_UNITS_TO_PA.get(name)
    if factor is None:
        mark = next((mark for mark in GAUGE_MARKS if name.endswith(mark)), None)
        if mark is not None:
            factor = PRESSURE_UNITS_TO_PA.get(name.removesuffix(mark).rstrip(" _-"))
    return factor


#: Accepted angle units (lower case) and what one of them is in radians: the bridge's
#: rotation and fold angles (``[stability]``). Vector's tools write degrees as "°".
ANGLE_UNITS_TO_RAD: dict[str, float] = {
    "deg": math.pi / 180.0,
    "°": math.pi / 180.0,
    "degree": math.pi / 180.0,
    "degrees": math.pi / 180.0,
    "rad": 1.0,
    "radian": 1.0,
    "radians": 1.0,
    "mrad": 1.0e-3,
}

#: The accepted angle units as a person writes them, for error messages.
ACCEPTED_ANGLE_UNITS = "deg, \u00b0, degree, rad, mrad"


def angle_factor_to_rad(unit: str) -> float | None:
    """Radians per one ``unit`` (case-insensitive, surrounding blanks ignored); None if
    unknown.

    >>> angle_factor_to_rad(" Deg ") == math.pi / 180
    True
    >>> angle_factor_to_rad("mrad")
    0.001
    """
    return ANGLE_UNITS_TO_RAD.get(unit.strip().lower())
