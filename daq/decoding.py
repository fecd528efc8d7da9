"""Decoding raw CAN frames against the DBC and checking their CRC and counter.

Pure computation: bytes and a time stamp in, a :class:`DecodedFrame` out, or a
:class:`~daq.errors.FrameError` the caller counts. The only state is each
protected message's last counter value.
"""

from collections.abc import Mapping
from dataclasses import dataclass

from cantools.database.can import Database, Message
from cantools.database.namedsignalvalue import NamedSignalValue

from daq.errors import FrameLengthError, SignalDecodeError, UnknownFrameError
from daq.machine import Protection
from daq.protection import CounterCheck, payload_crc

#: A decoded signal: its physical value in the DBC's unit, or its value-table name.
SignalValue = float | int | str


@dataclass(frozen=True, slots=True)
class DecodedFrame:
    """One frame, decoded and checked."""

    message: str
    #: Frame time (kernel time stamp), Unix seconds.
    t_s: float
    signals: Mapping[str, SignalValue]
    #: The CRC matched; True for messages without CRC.
    crc_ok: bool
    #: The counter advanced by one; True for messages without counter, for the
    #: first frame, and for frames whose CRC failed (their counter is not trusted).
    counter_ok: bool


class _MessageCodec:
    """Decoding and protection of one DBC message."""

    def __init__(self, message: Message, protection: Protection | None) -> None:
        self.message = message
        self.crc_byte: int | None = None
        self.counter: CounterCheck | None = None
        if protection is not None:
            signal = message.get_signal_by_name
            self.crc_byte = signal(protection.crc).start // 8
            self.crc_signal = protection.crc
            self.counter_signal = protection.counter
            self.counter = CounterCheck(2 ** signal(protection.counter).length)

    def decode(self, arbitration_id: int, data: bytes, t_s: float) -> DecodedFrame:
        message = self.message
        if len(data) != message.length:
            raise FrameLengthError(
                arbitration_id,
                f"{message.name} has DLC {len(data)}, the DBC says {message.length}",
            )
        try:
            decoded = message.decode(data, decode_choices=True, scaling=True)
        except Exception as exc:  # cantools raises several types; every one is a bad frame
            raise SignalDecodeError(arbitration_id, f"{message.name}: {exc}") from exc
        if not isinstance(decoded, dict):
            raise SignalDecodeError(
                arbitration_id, f"{message.name}: container messages unsupported"
            )
        signals: dict[str, SignalValue] = {
            name: value.name if isinstance(value, NamedSignalValue) else value
            for name, value in decoded.items()
            if isinstance(value, (int, float, str, NamedSignalValue))
        }
        crc_ok = counter_ok = True
        if self.crc_byte is not None and self.counter is not None:
            crc_ok = payload_crc(data, self.crc_byte) == data[self.crc_byte]
            if crc_ok:
                counter_ok = self.counter.update(int(signals[self.counter_signal]))
        return DecodedFrame(message.name, t_s, signals, crc_ok, counter_ok)


class FrameDecoder:
    """Decodes frames of the messages in ``database``; checks the protected ones.

    >>> decoder = FrameDecoder(database, config.protection)  # doctest: +SKIP
    >>> decoder.decode(0x100, frame_bytes, t_s=1.5).signals["SB1_F1_pPiston"]  # doctest: +SKIP
    12345000
    """

    def __init__(self, database: Database, protection: Mapping[str, Protection]) -> None:
        self._codecs = {
            (message.frame_id, bool(message.is_extended_frame)): _MessageCodec(
                message, protection.get(message.name)
            )
            for message in database.messages
        }

    @property
    def frame_ids(self) -> list[tuple[int, bool]]:
        """(ID, extended) of every known message, e.g. for kernel receive filters."""
        return sorted(self._codecs)

    def decode(
        self, arbitration_id: int, data: bytes, t_s: float, is_extended_id: bool = False
    ) -> DecodedFrame:
        """Decode one frame; raises a :class:`~daq.errors.FrameError` subclass if unusable."""
        codec = self._codecs.get((arbitration_id, is_extended_id))
        if codec is None:
            raise UnknownFrameError(arbitration_id, "ID not in the DBC")
        return codec.decode(arbitration_id, bytes(data), t_s)

    def reset_counters(self) -> None:
        """Forget the last counters, e.g. after the bus was down: no false 'counter' faults."""
        for codec in self._codecs.values():
            if codec.counter is not None:
                codec.counter.reset()
