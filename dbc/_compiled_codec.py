"""Precompiled decoding of one DBC message: the hot path.

:class:`CompiledMessage` is built once per message from its DBC layout: every
signal becomes a shift and a mask of the frame read as one integer (little- or
big-endian), a sign fix, its value table and the scale and offset of its cantools
conversion, applied with the same arithmetic (so the values, and their types, are
the ones ``Message.decode(data, decode_choices=True, scaling=True)`` gives, with
value-table entries as their names), written out as one straight-line function per
message (:func:`_decoder`). Messages it cannot express (multiplexed,
container, float signals) are left to cantools: :meth:`CompiledMessage.compile`
returns None for them.

Pressure signals are converted to Pa on the way (``to_si``: a factor per signal name,
applied after the DBC's scale and offset, as the reference path does).

Checked against the reference path (cantools) on random frames in
``tests/dbc/test_compiled_codec.py``.
"""

from collections.abc import Callable, Mapping

from cantools.database.can import Message
from cantools.database.conversion import (
    BaseConversion,
    IdentityConversion,
    LinearConversion,
    LinearIntegerConversion,
    NamedSignalConversion,
)
from cantools.database.namedsignalvalue import NamedSignalValue

#: A decoded signal value (as :data:`dbc.decoding.SignalValue`).
Value = float | int | str
#: name, big-endian, shift, mask, sign bit (0: unsigned), value table, scale, offset
#: (scale None: the raw value as it is), factor to SI (None: none).
_Field = tuple[
    str, bool, int, int, int, dict[int, str] | None, int | float | None, int | float, float | None
]


class CompiledMessage:
    """Decodes the payload of one message (of the DBC's length) into its signals."""

    def __init__(self, name: str, fields: list[_Field]) -> None:
        self.name = name
        self._fields = tuple(fields)
        #: The signals of a payload (of the message's length), in DBC order.
        self.decode: Callable[[bytes], dict[str, Value]] = _decoder(self._fields)

    @classmethod
    def compile(
        cls, message: Message, to_si: Mapping[str, float] | None = None
    ) -> "CompiledMessage | None":
        """The compiled decoder of ``message``; None if only cantools can decode it.

        ``to_si`` maps signal names to the factor that turns their DBC unit into SI.
        """
        if message.is_container or message.is_multiplexed() or not message.length:
            return None
        bits = 8 * message.length
        fields: list[_Field] = []
        for signal in message.signals:
            conversion = signal.conversion
            if conversion.is_float:
                return None
            choices = None
            if isinstance(conversion, NamedSignalConversion):
                choices = {
                    int(raw): value.name if isinstance(value, NamedSignalValue) else value
                    for raw, value in conversion.choices.items()
                }
                # What NamedSignalConversion falls back to for a raw value not in the table.
                conversion = BaseConversion.factory(
                    scale=conversion.scale, offset=conversion.offset, is_float=False
                )
            scale: int | float | None
            offset: int | float
            if isinstance(conversion, IdentityConversion):
                scale, offset = None, 0
            elif isinstance(conversion, (LinearConversion, LinearIntegerConversion)):
                scale, offset = conversion.scale, conversion.offset
            else:  # a conversion this module does not know
                return None
            length = signal.length
            if signal.byte_order == "little_endian":
                big_endian, shift = False, signal.start
            else:  # Motorola: start is the MSB, numbered MSB-first within each byte
                msb = 8 * (signal.start // 8) + (7 - signal.start % 8)
                big_endian, shift = True, bits - msb - length
            if shift < 0 or shift + length > bits:
                return None
            sign = 1 << (length - 1) if signal.is_signed else 0
            factor = (to_si or {}).get(signal.name)
            fields.append(
                (
                    signal.name,
                    big_endian,
                    shift,
                    (1 << length) - 1,
                    sign,
                    choices,
                    scale,
                    offset,
                    factor,
                )
            )
        return cls(message.name, fields)


def _decoder(fields: tuple[_Field, ...]) -> Callable[[bytes], dict[str, Value]]:
    """One function decoding every field, written out from the layout and compiled.

    Per field, as straight-line code (no loop, no tuple unpacking, no tests of what the
    layout fixes): the raw value is ``(word >> shift) & mask`` of the payload read as one
    little- or big-endian integer, minus ``2 * sign`` when its sign bit is set; then its
    value-table name if it has one, else ``raw * scale + offset`` (``raw`` without a
    scale), times the factor to SI if any. Constants of the layout are written as
    integer literals; names, scales, offsets, factors and value tables are passed as
    objects, so the arithmetic and the types are exactly cantools'.
    """
    namespace: dict[str, object] = {"from_bytes": int.from_bytes}
    lines = ["def decode(data):", "    little = from_bytes(data, 'little')"]
    if any(field[1] for field in fields):
        lines.append("    big = from_bytes(data, 'big')")
    entries = []
    for i, (name, big_endian, shift, mask, sign, choices, scale, offset, factor) in enumerate(
        fields
    ):
        lines.append(f"    raw = ({'big' if big_endian else 'little'} >> {shift}) & {mask}")
        if sign:
            lines += [f"    if raw & {sign}:", f"        raw -= {sign << 1}"]
        value = "raw" if scale is None else f"raw * scale_{i} + offset_{i}"
        if factor is not None:
            value = f"({value}) * factor_{i}"
        if choices is not None:
            lines += [f"    v{i} = choices_{i}.get(raw)", f"    if v{i} is None:"]
            lines.append(f"        v{i} = {value}")
        else:
            lines.append(f"    v{i} = {value}")
        namespace |= {
            f"name_{i}": name,
            f"choices_{i}": choices,
            f"scale_{i}": scale,
            f"offset_{i}": offset,
            f"factor_{i}": factor,
        }
        entries.append(f"name_{i}: v{i}")
    lines.append(f"    return {{{', '.join(entries)}}}")
    exec("\n".join(lines), namespace)
    decode: Callable[[bytes], dict[str, Value]] = namespace["decode"]  # type: ignore[assignment]
    return decode
