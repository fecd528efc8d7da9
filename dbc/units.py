"""Pressure units of DBC signals and their factor to Pa: the one table of them.

A DBC signal's physical value is in the unit its ``unit`` string names; the
service works in SI inside, so every pressure signal is converted to Pa when it
is decoded, and back when the simulator encodes one. The unit comes from the DBC
or, where the DBC's is empty or wrong, from the config (``unit = "bar"``).

>>> pressure_factor_to_Pa("bar")
100000.0
>>> pressure_factor_to_Pa("PSI")
6894.757293168361
>>> pressure_factor_to_Pa("m") is None
True
"""

#: Accepted pressure units (lower case) and what one of them is in Pa.
PRESSURE_UNITS_TO_PA: dict[str, float] = {
    "pa": 1.0,
    "kpa": 1.0e3,
    "mpa": 1.0e6,
    "bar": 1.0e5,
    "mbar": 1.0e2,
    # 1 lbf / in2 = 4.4482216152605 N / 0.00064516 m2 (exact by the definitions of lb and in).
    "psi": 6894.757293168361,
}

#: The accepted units as a person writes them, for error messages.
ACCEPTED_PRESSURE_UNITS = "Pa, kPa, MPa, bar, mbar, psi"


def pressure_factor_to_Pa(unit: str) -> float | None:
    """Pa per one ``unit`` (case-insensitive, surrounding blanks ignored); None if unknown."""
    return PRESSURE_UNITS_TO_PA.get(unit.strip().lower())
