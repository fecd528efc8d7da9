"""Decoding raw CAN frames against the DBC and checking their CRC and counter.

Pure computation: bytes and a time stamp in, a :class:`DecodedFrame` out, or a
:class:`~daq.errors.FrameError` the caller counts. The only state is each
protected message's last counter value.

Two paths give the same frames: the precompiled one (:mod:`dbc._compiled_codec`:
shifts and masks compiled once per message from the DBC layout, a table-driven
CRC), used by default, and the reference one (cantools' ``Message.decode`` and
:func:`dbc.protection.payload_crc`), ``FrameDecoder(..., compiled=False)``, which
also serves the messages the compiler leaves out (multiplexed, container, float
signals). The tests decode random frames both ways and compare.
"""

from collections.abc import Mapping
from dataclasses import dataclass

from cantools.database.can import Database, Message
from cantools.database.namedsignalvalue import NamedSignalValue
from crc import Crc8

from dbc._compiled_codec import CompiledMessage, TableCrc8
from dbc.errors import FdFrameError, FrameLengthError, SignalDecodeError, UnknownFrameError
from dbc.machine import Protection
from dbc.protection import CounterCheck, payload_crc

_J1850 = Crc8.SAEJ1850.value
#: The CRC of dbc.protection (CRC-8 SAE J1850), table-driven.
_TABLE_CRC8 = TableCrc8(_J1850.polynomial, _J1850.init_value, _J1850.final_xor_value)

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
    """Decoding and protection of one DBC message (precompiled unless ``compiled`` is off)."""

    def __init__(self, message: Message, protection: Protection | None, compiled: bool) -> None:
        self.message = message
        self.compiled = CompiledMessage.compile(message) if compiled else None
        self.payload_crc = _TABLE_CRC8.payload_crc if compiled else payload_crc
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
        signals = (
            self.compiled.decode(data)
            if self.compiled is not None
            else self._decode_reference(arbitration_id, data)
        )
        crc_ok = counter_ok = True
        if self.crc_byte is not None and self.counter is not None:
            crc_ok = self.payload_crc(data, self.crc_byte) == data[self.crc_byte]
            if crc_ok:
                counter_ok = self.counter.update(int(signals[self.counter_signal]))
        return DecodedFrame(message.name, t_s, signals, crc_ok, counter_ok)

    def _decode_reference(self, arbitration_id: int, data: bytes) -> dict[str, SignalValue]:
        message = self.message
        try:
            decoded = message.decode(data, decode_choices=True, scaling=True)
        except Exception as exc:  # cantools raises several types; every one is a bad frame
            raise SignalDecodeError(arbitration_id, f"{message.name}: {exc}") from exc
        if not isinstance(decoded, dict):
            raise SignalDecodeError(
                arbitration_id, f"{message.name}: container messages unsupported"
            )
        return {
            name: value.name if isinstance(value, NamedSignalValue) else value
            for name, value in decoded.items()
            if isinstance(value, (int, float, str, NamedSignalValue))
        }


class FrameDecoder:
    """Decodes frames of the messages in ``database``; checks the protected ones.

    ``compiled=False`` decodes every message with cantools (the reference path).

    >>> decoder = FrameDecoder(database, config.protection)  # doctest: +SKIP
    >>> decoder.decode(0x100, frame_bytes, t_s=1.5).signals["SB1_F1_pPiston"]  # doctest: +SKIP
    12345000
    """

    def __init__(
        self,
        database: Database,
        protection: Mapping[str, Protection],
        *,
        compiled: bool = True,
    ) -> None:
        self._codecs = {
            (message.frame_id, bool(message.is_extended_frame)): _MessageCodec(
                message, protection.get(message.name), compiled
            )
            for message in database.messages
        }

    @property
    def frame_ids(self) -> list[tuple[int, bool]]:
        """(ID, extended) of every known message, e.g. for kernel receive filters."""
        return sorted(self._codecs)

    def decode(
        self,
        arbitration_id: int,
        data: bytes,
        t_s: float,
        is_extended_id: bool = False,
        is_fd: bool = False,
    ) -> DecodedFrame:
        """Decode one frame; raises a :class:`~daq.errors.FrameError` subclass if unusable.

        An FD frame decodes only for a message the DBC defines as FD (else ``fd_frame``).
        """
        codec = self._codecs.get((arbitration_id, is_extended_id))
        if is_fd and (codec is None or not codec.message.is_fd):
            raise FdFrameError(arbitration_id, "CAN FD frame of no FD message in the DBC")
        if codec is None:
            raise UnknownFrameError(arbitration_id, "ID not in the DBC")
        return codec.decode(arbitration_id, bytes(data), t_s)

    def reset_counters(self) -> None:
        """Forget the last counters, e.g. after the bus was down: no false 'counter' faults."""
        for codec in self._codecs.values():
            if codec.counter is not None:
                codec.counter.reset()
