"""Building protected CAN frames from physical signal values (the decoder's mirror).

Pure computation: values come in SI (pressures in Pa) and are encoded in the DBC's
units; each protected message gets its rolling counter and CRC; a J1939 message
is sent from the source address given. The simulator bridge sends what this
builds; the tests use it to make frames.
"""

from collections.abc import Mapping
from dataclasses import dataclass

from cantools.database.can import Database, Message

from dbc.decoding import (
    SenderUnitFactors,
    SignalValue,
    UnitFactors,
    frame_length,
    is_fd_message,
    is_j1939,
)
from dbc.machine import MachineConfig
from dbc.protection import CrcCheck, Protection, counter_modulo


@dataclass(frozen=True, slots=True)
class EncodedFrame:
    arbitration_id: int
    is_extended_id: bool
    data: bytes
    #: A CAN FD frame (of a message the DBC defines as FD).
    is_fd: bool = False


class FrameEncoder:
    """Encodes messages of ``database`` by name, counting and CRC-ing protected ones.

    ``to_si`` holds the unit factors of the pressure signals (as for the decoder):
    their values are divided by it before encoding; ``sender_to_si`` those of a J1939
    sender in its own unit, used for frames sent from that ``source_address``.

    >>> encoder = FrameEncoder(database, config.protection)  # doctest: +SKIP
    >>> encoder.encode("LEG_SB1_F1", {"SB1_F1_pPiston": 12e6, "SB1_F1_pRod": 1e6,
    ...                               "SB1_F1_Status": "ok"}).data.hex()  # doctest: +SKIP
    'c832d007000000b1'
    """

    def __init__(
        self,
        database: Database,
        protection: Mapping[str, Protection],
        to_si: UnitFactors | None = None,
        sender_to_si: SenderUnitFactors | None = None,
    ) -> None:
        self._database = database
        self._protection = dict(protection)
        self._to_si = dict(to_si or {})
        self._sender_to_si = dict(sender_to_si or {})
        self._counters: dict[tuple[str, int | None], int] = {}
        # Built once per message: a CRC check builds its lookup table (~0.2 ms).
        self._crc_checks: dict[str, CrcCheck | None] = {}

    @classmethod
    def from_config(cls, config: MachineConfig, database: Database) -> "FrameEncoder":
        """The encoder of ``config``'s protection profiles and pressure units."""
        return cls(database, config.protection, config.unit_factors, config.sender_unit_factors)

    def encode(
        self,
        message_name: str,
        signals: Mapping[str, SignalValue],
        *,
        counter: int | None = None,
        corrupt_crc: bool = False,
        source_address: int | None = None,
    ) -> EncodedFrame:
        """Encode one frame; ``counter`` overrides the rolling counter (fault injection),
        ``corrupt_crc`` sends a wrong CRC, ``source_address`` sets a J1939 sender. A value
        outside its signal's DBC range is encoded as it is (the receiver judges the range);
        one its bits cannot hold raises cantools' OverflowError.

        A multiplexed message's frame is the page its multiplexer value in ``signals``
        selects, with that page's signals only; a counter or CRC under other multiplexer
        values is not in it (nor advanced: the receiver counts the frames carrying it).
        """
        message = self._database.get_message_by_name(message_name)
        factors = self._to_si.get(message_name, {})
        if source_address is not None:
            factors = self._sender_to_si.get((message_name, source_address), factors)
        values = {
            name: value / factors[name] if name in factors and not isinstance(value, str) else value
            for name, value in signals.items()
        }
        protection = self._protection.get(message_name)
        if protection is not None and _carries(message, protection.counter, values):
            assert protection.counter is not None
            key = (message_name, source_address)
            if counter is None:
                counter = self._counters.get(key, -1) + 1
            counter %= counter_modulo(message, protection.counter, protection.crc_algorithm)
            self._counters[key] = counter
            counter_signal = message.get_signal_by_name(protection.counter)
            # ``counter`` is what the bits carry; a scaled or signed counter is encoded from
            # its value (a signed one's upper half of counts from below zero).
            raw = counter
            if counter_signal.is_signed and counter >= 2 ** (counter_signal.length - 1):
                raw -= 2**counter_signal.length
            values[protection.counter] = raw * counter_signal.scale + counter_signal.offset
        with_crc = protection is not None and _carries(message, protection.crc, values)
        if with_crc:
            assert protection is not None and protection.crc is not None
            values[protection.crc] = 0
            if protection.data_id_nibble is not None:
                values[protection.data_id_nibble] = protection.nibble_value
        # Not strict: a value beyond the DBC's range is encoded (the bridge's --out-of-range
        # sends one, as a faulty transducer does); one beyond what the bits hold raises.
        data = bytearray(message.encode(values, scaling=True, padding=False, strict=False))
        if message_name not in self._crc_checks:
            self._crc_checks[message_name] = (
                protection.crc_check(message) if protection is not None else None
            )
        crc = self._crc_checks[message_name]
        if crc is not None and with_crc:
            crc.write(data, counter, corrupt=corrupt_crc)
        frame_id = message.frame_id
        if source_address is not None:
            if not is_j1939(message):
                raise ValueError(f"{message_name} is not a J1939 message: no source address")
            frame_id = (frame_id & ~0xFF) | source_address
        if is_fd_message(message):  # as the controller pads it: 30 bytes go out as 32
            data += bytes(frame_length(message) - len(data))
        return EncodedFrame(
            frame_id, bool(message.is_extended_frame), bytes(data), is_fd_message(message)
        )


def _carries(message: Message, signal_name: str | None, values: Mapping[str, SignalValue]) -> bool:
    """The frame of ``values`` carries the signal: it is not multiplexed, or ``values``
    put its multiplexer at one of its values (by number or value-table name)."""
    if signal_name is None:
        return False
    signal = message.get_signal_by_name(signal_name)
    if not signal.multiplexer_ids or signal.multiplexer_signal is None:
        return True
    multiplexer = message.get_signal_by_name(signal.multiplexer_signal)
    page = values.get(multiplexer.name)
    if isinstance(page, str):
        names = {str(name): raw for raw, name in (multiplexer.choices or {}).items()}
        return names.get(page) in signal.multiplexer_ids
    return page in signal.multiplexer_ids
