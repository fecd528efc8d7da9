"""Building protected CAN frames from physical signal values (the decoder's mirror).

Pure computation: fills each protected message's rolling counter and CRC-8.
The simulator bridge sends what this builds; the tests use it to make frames.
"""

from collections.abc import Mapping
from dataclasses import dataclass

from cantools.database.can import Database

from dbc.decoding import SignalValue
from dbc.machine import Protection
from dbc.protection import payload_crc


@dataclass(frozen=True, slots=True)
class EncodedFrame:
    arbitration_id: int
    is_extended_id: bool
    data: bytes


class FrameEncoder:
    """Encodes messages of ``database`` by name, counting and CRC-ing protected ones.

    >>> encoder = FrameEncoder(database, config.protection)  # doctest: +SKIP
    >>> encoder.encode("LEG_SB1_F1", {"SB1_F1_pPiston": 12e6, "SB1_F1_pRod": 1e6,
    ...                               "SB1_F1_Status": "ok"}).data.hex()  # doctest: +SKIP
    'c832d007000000b1'
    """

    def __init__(self, database: Database, protection: Mapping[str, Protection]) -> None:
        self._database = database
        self._protection = dict(protection)
        self._counters: dict[str, int] = {}

    def encode(
        self,
        message_name: str,
        signals: Mapping[str, SignalValue],
        *,
        counter: int | None = None,
        corrupt_crc: bool = False,
    ) -> EncodedFrame:
        """Encode one frame; ``counter`` overrides the rolling counter (fault injection),
        ``corrupt_crc`` sends a wrong CRC."""
        message = self._database.get_message_by_name(message_name)
        values = dict(signals)
        protection = self._protection.get(message_name)
        if protection is not None:
            if counter is None:
                counter = self._counters.get(message_name, -1) + 1
            modulo = 2 ** message.get_signal_by_name(protection.counter).length
            counter %= modulo
            self._counters[message_name] = counter
            values[protection.counter] = counter
            values[protection.crc] = 0
        data = bytearray(message.encode(values, scaling=True, padding=False, strict=True))
        if protection is not None:
            crc_byte = message.get_signal_by_name(protection.crc).start // 8
            data[crc_byte] = payload_crc(bytes(data), crc_byte) ^ (0xFF if corrupt_crc else 0)
        return EncodedFrame(message.frame_id, bool(message.is_extended_frame), bytes(data))
