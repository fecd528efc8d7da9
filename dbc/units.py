"""Units of DBC signals and their factor to SI: the one table of them.

Pressures (the legs' chambers) go to Pa; the bridge angles of ``[stability]`` to radians;
the machine state's time in cycle to seconds and the carriage position and leg strokes to
metres (the report reads the first, the simulator bridge sends them all).

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

A unit marked gauge (``psig``, ``barg``, ``bar(g)``, ``kPa gauge``; German DBCs write
relative pressure ``bar rel``, ``bar(ü)`` for *Überdruck*) is that unit: the chamber
pressures are gauge pressures. An absolute one (``bara``, ``psia``, ``kPa abs``) is none
of these units (it is off by the atmosphere's ~1 bar). A chamber's transducer may send
absolute pressure: :func:`chamber_unit` gives the factor and the standard atmosphere to
subtract, since eq. (4) takes gauge pressures.

>>> pressure_factor_to_Pa("psi(g)") == pressure_factor_to_Pa("PSIG") == 6894.757293168361
True
>>> pressure_factor_to_Pa("bar(ü)") == pressure_factor_to_Pa("[bar]") == 100000.0
True
>>> pressure_factor_to_Pa("bara") is None
True
>>> chamber_unit("bara"), chamber_unit("bar"), chamber_unit("m")
((100000.0, 101325.0), (100000.0, 0.0), None)
"""

import math

#: The standard atmosphere, Pa: what a chamber's absolute pressure is above its gauge
#: pressure. The real one varies by a few per cent with weather and height (~11 kPa at
#: 1,000 m): on a foot force that is the rod's cross-section times it, a few newtons.
STANDARD_ATMOSPHERE_PA = 101_325.0

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
    "kp/cm2": 98066.5,  # kilopond, German for kgf
    # The technical atmosphere (1 kgf/cm2): older German gauges' "atü" (gauge), "ata".
    "at": 98066.5,
    "n/cm2": 1.0e4,
    "dan/cm2": 1.0e5,  # decanewton: the bar of French and older European gauges
    # The same units spelled out in base units, as some DBC editors write them.
    "n/m2": 1.0,
    "kn/m2": 1.0e3,
    "lbf/in2": 6894.757293168361,
    "lb/in2": 6894.757293168361,
}

#: The accepted units as a person writes them, for error messages.
ACCEPTED_PRESSURE_UNITS = "Pa, kPa, MPa, bar, mbar, psi, hPa, N/mm2, N/cm2, daN/cm2, kgf/cm2"


#: Marks of a gauge unit after the unit's name (longest first), e.g. "psig", "bar(g)",
#: "bar rel", "bar (relative)", "bar(ü)" (German *Überdruck*, as Windows-1252 writes it);
#: abbreviated with a dot too ("bar rel.", "bar(rel.)": the dots are left out).
GAUGE_MARKS = (
    "(relative)",
    "relative",
    "(gauge)",
    "gauge",
    "(rel)",
    "rel",
    "(\u00fc)",
    "\u00fc",
    "(g)",
    "g",
)
#: Marks of an absolute unit after the unit's name (longest first), e.g. "psia", "kPa abs",
#: "bar abs.", "psi(abs.)".
ABSOLUTE_MARKS = ("(absolute)", "absolute", "(abs)", "abs", "(a)", "a")


def pressure_factor_to_Pa(unit: str) -> float | None:
    """Pa per one ``unit`` (case-insensitive, surrounding blanks, brackets, dots and a
    gauge mark ignored, "²" and "^2" read as "2"); None if unknown."""
    return _factor_marked(unit, GAUGE_MARKS)


def chamber_unit(unit: str) -> tuple[float, float] | None:
    """A chamber transducer's ``unit``: (Pa per one ``unit``, Pa to subtract for gauge
    pressure: :data:`STANDARD_ATMOSPHERE_PA` for an absolute unit, else 0); None if it is
    no pressure unit."""
    factor = pressure_factor_to_Pa(unit)
    if factor is not None:
        return factor, 0.0
    factor = _factor_marked(unit, ABSOLUTE_MARKS)
    return None if factor is None else (factor, STANDARD_ATMOSPHERE_PA)


def _factor_marked(unit: str, marks: tuple[str, ...]) -> float | None:
    """Pa per one ``unit``, which may end with one of ``marks``; None if unknown."""
    # No unit has a dot; an abbreviated mark has ("bar abs.", "bar(rel.)").
    name = unit.strip().lower().replace("\u00b2", "2").replace("^2", "2").replace(".", "")
    if name[:1] == "[" and name[-1:] == "]":  # "[bar]": some editors bracket the unit
        name = name[1:-1].strip()
    factor = PRESSURE_UNITS_TO_PA.get(name)
    if factor is None:
        mark = next((mark for mark in marks if name.endswith(mark)), None)
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
    """Radians per one ``unit`` (case-insensitive, surrounding blanks and brackets
    ignored); None if unknown.

    >>> angle_factor_to_rad(" Deg ") == math.pi / 180
    True
    >>> angle_factor_to_rad("[mrad]")
    0.001
    """
    return ANGLE_UNITS_TO_RAD.get(_bare(unit))


#: Accepted time units (lower case) and what one of them is in seconds: the machine
#: state's time in cycle (``[signals] cycle_time``).
TIME_UNITS_TO_S: dict[str, float] = {
    "s": 1.0,
    "sec": 1.0,
    "second": 1.0,
    "seconds": 1.0,
    "ms": 1.0e-3,
    "msec": 1.0e-3,
    "min": 60.0,
}
#: Accepted length units (lower case) and what one of them is in metres: the carriage
#: position (``[signals] carriage``) and the leg strokes (``<LEG>_Stroke``).
LENGTH_UNITS_TO_M: dict[str, float] = {"m": 1.0, "cm": 1.0e-2, "mm": 1.0e-3}


def time_factor_to_s(unit: str) -> float | None:
    """Seconds per one ``unit`` (as :func:`angle_factor_to_rad`); None if unknown.

    >>> time_factor_to_s("ms"), time_factor_to_s(" S "), time_factor_to_s("%")
    (0.001, 1.0, None)
    """
    return TIME_UNITS_TO_S.get(_bare(unit))


def length_factor_to_m(unit: str) -> float | None:
    """Metres per one ``unit`` (as :func:`angle_factor_to_rad`); None if unknown.

    >>> length_factor_to_m("mm"), length_factor_to_m("[m]"), length_factor_to_m("deg")
    (0.001, 1.0, None)
    """
    return LENGTH_UNITS_TO_M.get(_bare(unit))


def _bare(unit: str) -> str:
    """``unit`` in lower case without surrounding blanks and brackets (``[mm]``)."""
    name = unit.strip().lower()
    if name[:1] == "[" and name[-1:] == "]":
        name = name[1:-1].strip()
    return name
