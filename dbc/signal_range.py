"""Which decoded values of a DBC signal are values, not codes: its ``[min|max]``, and in
a J1939 message the valid range of a parameter of 1, 2 or 4 bytes; and which entries of
its value table name a value (``0 "Zero"``) rather than a code (:func:`named_values`).

J1939-71 reserves the top of such a parameter's raw range for indicators: above 0xFA,
0xFAFF, 0xFAFFFFFF come "parameter specific" (0xFB..), "error" (0xFE..) and "not
available" (0xFF..). A transducer without a value sends 0xFFFF; at 0.05 kPa/bit that is
3.28 MPa, a plausible pressure, so where the DBC declares no range (cantools reads the
DBC's ``[0|0]`` as none) only this rule tells the code from a measurement.

Any integer signal's last raw value (all ones; a signed signal's least too) is no
measurement either, whatever the declared range: it is a code ("not available" in most
vendors' DBCs) or a transducer saturated there, whose true pressure may be anything
above; read as a value, a 3000 psi transducer at 3127 psi was a valid 3000 psi.

J1939 has no two's complement: its SLOTs give a parameter negative values by an offset
(1/128 kPa/bit, offset -250 kPa), and a transducer sends its indicators as those bits
whatever its DBC declares. A J1939 pressure a DBC declares signed reads "not available"
(0xFFFF) as -1 step, -0.01 bar at 0.01 bar/bit: :func:`j1939_signed_codes`.
"""

import math

from cantools.database.can import Signal
from cantools.database.namedsignalvalue import NamedSignalValue

#: Largest valid raw value of an unsigned J1939 parameter, by its length in bits.
J1939_VALID_RAW_MAX = {8: 0xFA, 16: 0xFAFF, 32: 0xFAFFFFFF}


def value_range(signal: Signal, j1939: bool) -> tuple[float, float]:
    """The physical values ``signal`` may take, in its DBC unit, half a step wider for
    rounding; without the last raw value of its bits (see the module docstring); else
    unbounded where neither the DBC nor J1939 (``j1939``: the signal is in a J1939
    message) bounds it."""
    low, high = -math.inf, math.inf
    if signal.minimum is not None and signal.maximum is not None:
        if signal.minimum < signal.maximum:
            margin = 0.5 * abs(signal.scale) if not signal.is_float else 0.0
            margin += 1e-9 * max(abs(signal.minimum), abs(signal.maximum))
            low, high = signal.minimum - margin, signal.maximum + margin
    if signal.is_float or signal.scale == 0:
        return (low, high)
    # The raw values that are values, half a step inside the codes at the ends; a
    # negative factor (an inverted signal) turns them end for end.
    bits = signal.length - 1 if signal.is_signed else signal.length
    raw_high = (1 << bits) - 1.5
    raw_low = 0.5 - (1 << bits) if signal.is_signed else -math.inf
    raw_max = J1939_VALID_RAW_MAX.get(signal.length)
    if j1939 and raw_max is not None and not signal.is_signed:
        raw_high = min(raw_high, raw_max + 0.5)
    ends = sorted(raw * signal.scale + signal.offset for raw in (raw_low, raw_high))
    return (max(low, ends[0]), min(high, ends[1]))


def j1939_signed_codes(signal: Signal, j1939: bool) -> tuple[float, float] | None:
    """The physical values (DBC unit, half a step wider) that J1939's indicator codes
    decode to in ``signal`` where it is a signed parameter of 1, 2 or 4 bytes in a J1939
    message (``j1939``): the raw bits above 0xFA, 0xFAFF, 0xFAFFFFFF read two's
    complement, -5..-1, -1280..-1, -83886080..-1 steps; None for any other signal.

    A transducer's 0xFFFF ("not available") in a 16-bit signed ``(0.01,0) "bar"``
    signal decodes to -0.01 bar: a gauge pressure near 0, valid within any range that
    reaches below 0, where the transducer has no value at all. J1939 sends no two's
    complement (see the module docstring), so these are codes; a vendor's sender that
    does count below 0 so gets its readings between -12.8 and -0.01 bar (at 0.01
    bar/bit) flagged, never a code read as a pressure.

    >>> from cantools.database.can import Signal
    >>> from cantools.database.conversion import BaseConversion
    >>> p = Signal("p", 0, 16, is_signed=True, conversion=BaseConversion.factory(0.01, 0))
    >>> j1939_signed_codes(p, j1939=True)
    (-12.805, -0.005)
    >>> j1939_signed_codes(p, j1939=False) is None
    True
    """
    raw_max = J1939_VALID_RAW_MAX.get(signal.length)
    if not (j1939 and signal.is_signed and raw_max is not None) or signal.is_float:
        return None
    first = raw_max + 1 - (1 << signal.length)  # 0xFB00 read two's complement: -1280
    ends = sorted(raw * signal.scale + signal.offset for raw in (first - 0.5, -0.5))
    return (ends[0], ends[1])


def decoded_bounds(signal: Signal) -> tuple[float, float]:
    """The least and greatest value the signal's bits decode to (scale and offset
    applied; a float signal: unbounded)."""
    if signal.is_float:
        return (-math.inf, math.inf)
    bits = signal.length - 1 if signal.is_signed else signal.length
    low_raw, high_raw = (-(1 << bits) if signal.is_signed else 0), (1 << bits) - 1
    ends = (low_raw * signal.scale + signal.offset, high_raw * signal.scale + signal.offset)
    return (min(ends), max(ends))


def named_values(signal: Signal, j1939: bool) -> dict[str, float]:
    """The entries of ``signal``'s value table that name a measurement, by name: their
    physical value, in its DBC unit.

    An entry is a measurement where its value lies inside the range the DBC declares
    (``[min|max]``, and J1939's valid range in a J1939 message: :func:`value_range`),
    e.g. ``0 "Zero"`` of a pressure in ``[0|642.55]``; else it is a code ("not
    available", "error", usually at the top of the raw range). So is an entry at the end
    of what the bits hold (:func:`codes_at_the_ends`) whatever the declared range: a
    range that reaches the top of the bits (CANdb++'s default) does not make ``4095
    "SNA"`` of a 12-bit 250 bar transducer a valid 204.75 bar. Without a declared range
    (``[0|0]``) every entry is a code: nothing tells a code from a value. A name given
    to two raw values names no one value.

    >>> from cantools.database.can import Signal
    >>> from cantools.database.conversion import BaseConversion
    >>> conversion = BaseConversion.factory(0.01, 0, {0: "Zero", 65535: "SNA"})
    >>> p = Signal("p", 0, 16, conversion=conversion, minimum=0, maximum=642.55)
    >>> named_values(p, j1939=False)
    {'Zero': 0.0}
    >>> top = BaseConversion.factory(0.05, 0, {0: "Zero", 4094: "Error", 4095: "SNA"})
    >>> named_values(Signal("p", 0, 12, conversion=top, minimum=0, maximum=204.75), False)
    {'Zero': 0.0}
    """
    if not signal.choices or signal.minimum is None or signal.maximum is None:
        return {}
    if not signal.minimum < signal.maximum:
        return {}
    low, high = value_range(signal, j1939)
    code_low, code_high = j1939_signed_codes(signal, j1939) or (math.inf, math.inf)
    codes = codes_at_the_ends(signal)
    values: dict[str, float] = {}
    names: list[str] = []
    for raw, choice in signal.choices.items():
        name = choice.name if isinstance(choice, NamedSignalValue) else str(choice)
        names.append(name)
        value = float(raw * signal.scale + signal.offset)  # as the decoders compute it
        if low <= value <= high and raw not in codes and not code_low <= value <= code_high:
            values[name] = value
    return {name: value for name, value in values.items() if names.count(name) == 1}


def codes_at_the_ends(signal: Signal) -> set[int]:
    """The raw values of ``signal``'s value table that are codes by their place: the
    named value at the top of what the bits hold (all ones; a signed signal's greatest,
    its least, and its all ones, -1, too) and the named values next to it, one after
    another (``4095 "SNA"``, ``4094 "Error"``, ``4093 "Init"``; signed ``-1 "SNA"``,
    ``-2 "Error"``), but never 0 (``0 "Zero"``). A vendor names these ends for "not
    available" and "error"; a measurement named at the very end of the bits would be a
    saturated one, no pressure either. A signed signal's -1 is a measurement (-1 step)
    where the table does not name it; named, it is the transducer's 0xFFFF "not
    available" (a signed 16-bit ``[-10|400] "bar"`` pressure's ``-1 "SNA"`` was a valid
    -0.01 bar)."""
    if signal.is_float or not signal.choices:
        return set()
    named = {int(raw) for raw in signal.choices}
    if signal.is_signed:
        half = 1 << (signal.length - 1)
        ends = [(half - 1, -1), (-half, 1), (-1, -1)]
    else:
        ends = [((1 << signal.length) - 1, -1)]
    codes: set[int] = set()
    for raw, step in ends:
        while raw in named and raw != 0:
            codes.add(raw)
            raw += step
    return codes
