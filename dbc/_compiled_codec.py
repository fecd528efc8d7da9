"""Precompiled decoding of one DBC message, and a table-driven CRC-8: the hot path.

:class:`CompiledMessage` is built once per message from its DBC layout: every
signal becomes a shift and a mask of the frame read as one integer (little- or
big-endian), a sign fix, its value table and the scale and offset of its cantools
conversion, applied with the same arithmetic (so the values, and their types, are
the ones ``Message.decode(data, decode_choices=True, scaling=True)`` gives, with
value-table entries as their names). Messages it cannot express (multiplexed,
container, float signals) are left to cantools: :meth:`CompiledMessage.compile`
returns None for them.

:class:`TableCrc8` computes the frame's CRC with a 256-entry table built from the CRC's
parameters; :mod:`dbc.protection` (the ``crc`` package) stays the reference.

Both are checked against the reference path (cantools, ``payload_crc``) on random
frames in ``tests/dbc/test_compiled_codec.py``.
"""

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
#: (scale None: the raw value as it is).
_Field = tuple[str, bool, int, int, int, dict[int, str] | None, int | float | None, int | float]


class CompiledMessage:
    """Decodes the payload of one message (of the DBC's length) into its signals."""

    def __init__(self, name: str, fields: list[_Field]) -> None:
        self.name = name
        self._fields = tuple(fields)
        self._big_endian = any(field[1] for field in fields)

    @classmethod
    def compile(cls, message: Message) -> "CompiledMessage | None":
        """The compiled decoder of ``message``; None if only cantools can decode it."""
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
            fields.append(
                (signal.name, big_endian, shift, (1 << length) - 1, sign, choices, scale, offset)
            )
        return cls(message.name, fields)

    def decode(self, data: bytes) -> dict[str, Value]:
        """The signals of ``data`` (which has the message's length), in DBC order."""
        little = int.from_bytes(data, "little")
        big = int.from_bytes(data, "big") if self._big_endian else 0
        values: dict[str, Value] = {}
        for name, big_endian, shift, mask, sign, choices, scale, offset in self._fields:
            raw = ((big if big_endian else little) >> shift) & mask
            if raw & sign:
                raw -= sign << 1
            if choices is not None:
                choice = choices.get(raw)
                if choice is not None:
                    values[name] = choice
                    continue
            values[name] = raw if scale is None else raw * scale + offset
        return values


class TableCrc8:
    """Table-driven CRC-8 (MSB first, no reflection) over a payload minus its CRC byte.

    >>> TableCrc8(0x1D, 0xFF, 0xFF).checksum(b"123456789")  # SAE J1850 check value
    75
    """

    def __init__(self, polynomial: int, init: int, final_xor: int) -> None:
        table = []
        for byte in range(256):
            register = byte
            for _ in range(8):
                register = (register << 1) ^ polynomial if register & 0x80 else register << 1
            table.append(register & 0xFF)
        self._table = tuple(table)
        self._init = init
        self._final_xor = final_xor

    def checksum(self, data: bytes) -> int:
        table = self._table
        register = self._init
        for byte in data:
            register = table[register ^ byte]
        return register ^ self._final_xor

    def payload_crc(self, data: bytes, crc_byte: int) -> int:
        """As :func:`dbc.protection.payload_crc`: the CRC with byte ``crc_byte`` left out."""
        return self.checksum(data[:crc_byte] + data[crc_byte + 1 :])
