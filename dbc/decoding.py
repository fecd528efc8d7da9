"""Decoding raw CAN frames against the DBC and checking their end-to-end protection.

Pure computation: bytes and a time stamp in, a :class:`DecodedFrame` out, or a
:class:`~dbc.errors.FrameError` the caller counts. The only state is the rolling
counter of each protected message (per source address for J1939).

Frames are found by ID; messages the DBC marks as J1939 (``VFrameFormat``
``J1939PG``) by their PGN, whatever the priority and source address of the frame
(the source address is kept on the decoded frame). Pressure signals come out in
Pa (``to_si``, from :mod:`dbc.units`; a J1939 transducer sending in its own unit by
``sender_to_si``, through a codec of its own); everything else in the DBC's units.

Two paths give the same frames: the precompiled one (:mod:`dbc._compiled_codec`
and table-driven CRCs), used by default, and the reference one (cantools'
``Message.decode`` and the ``crc`` package), ``FrameDecoder(..., compiled=False)``,
which also serves the messages the compiler leaves out (multiplexed, container,
float signals). The tests decode random frames both ways and compare.
"""

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import NamedTuple

from cantools.database.can import Database, Message
from cantools.database.namedsignalvalue import NamedSignalValue
from cantools.j1939 import pgn_from_frame_id

from dbc._compiled_codec import CompiledMessage
from dbc.errors import FdFrameError, FrameLengthError, SignalDecodeError, UnknownFrameError
from dbc.protection import (
    COUNTER_JUMP,
    COUNTER_REPEAT,
    CRC_FAULT,
    CounterCheck,
    CrcCheck,
    Protection,
)
from estimator.records import fast_init

#: A decoded signal: its physical value (Pa for pressures), or its value-table name.
SignalValue = float | int | str

#: Signal name -> factor from its DBC unit to SI, per message name.
UnitFactors = Mapping[str, Mapping[str, float]]
#: The same per message name and J1939 source address: a transducer in its own unit.
SenderUnitFactors = Mapping[tuple[str, int], Mapping[str, float]]

#: Identifier masks of standard and extended frames.
SFF_MASK = 0x7FF
EFF_MASK = 0x1FFFFFFF
#: The PGN bits of a J1939 ID (reserved, data page, PDU format, PDU specific), and of a
#: PDU1 (destination-specific) one, whose PDU specific is the destination address.
J1939_PDU2_MASK = 0x03FFFF00
J1939_PDU1_MASK = 0x03FF0000
#: J1939-81's null address: a node that could not claim an address sends its Cannot
#: Claim from it and nothing else; 0xFF, above it, is the global destination.
J1939_NULL_ADDRESS = 0xFE
J1939_GLOBAL_ADDRESS = 0xFF
#: The proprietary A PGN (peer to peer; A2 is it on data page 1), its low 16 bits.
J1939_PROPRIETARY_A = 0xEF00


class ReceiveFilter(NamedTuple):
    """A kernel receive filter: a frame passes when ``id & can_mask == can_id & can_mask``."""

    can_id: int
    can_mask: int
    extended: bool


@fast_init
@dataclass(frozen=True, slots=True)
class DecodedFrame:
    """One frame, decoded and checked."""

    message: str
    #: Frame time (kernel time stamp), Unix seconds.
    t_s: float
    signals: Mapping[str, SignalValue]
    #: What the protection found wrong: ``crc``, ``counter`` (a jump larger than the
    #: profile allows), ``counter_repeat``; empty when fine or unprotected.
    faults: tuple[str, ...] = ()
    #: Frames lost before this one, by its counter (0 without a counter).
    frames_lost: int = 0
    #: J1939 source address of the sender; None for other messages.
    source_address: int | None = None

    @property
    def crc_ok(self) -> bool:
        return CRC_FAULT not in self.faults

    @property
    def counter_ok(self) -> bool:
        """False for a repeated or too far jumped counter (a CRC failure alone keeps it True)."""
        return COUNTER_JUMP not in self.faults and COUNTER_REPEAT not in self.faults


def is_j1939(message: Message) -> bool:
    """The DBC marks ``message`` as a J1939 parameter group (matched by PGN). J1939 IDs have
    29 bits: a standard-ID message is none, even where J1939PG is the DBC's default."""
    return message.protocol == "j1939" and bool(message.is_extended_frame)


#: The most data a classic CAN frame carries.
CLASSIC_MAX_BYTES = 8
#: What a J1939 frame of a parameter group of up to 8 bytes carries (padded with 0xFF).
J1939_FRAME_BYTES = 8


#: The data lengths a CAN FD frame may have beyond 8 bytes (DLC 9..15).
FD_LENGTHS = (12, 16, 20, 24, 32, 48, 64)


def frame_length(message: Message) -> int:
    """How many bytes a frame of ``message`` carries on the bus: its DBC length, but a
    CAN FD message's of a length no FD frame has (a DBC's 30 bytes) the next FD length
    (32: the controller pads), a J1939 parameter group's shorter than 8 bytes 8
    (J1939-21 pads with 0xFF). The frames of either length are ``message``'s."""
    if is_j1939(message) and message.length < J1939_FRAME_BYTES:
        return J1939_FRAME_BYTES
    if message.length > CLASSIC_MAX_BYTES and is_fd_message(message):
        return next((n for n in FD_LENGTHS if n >= message.length), message.length)
    return message.length


def is_fd_message(message: Message) -> bool:
    """``message`` is sent as CAN FD frames: the DBC says so (``VFrameFormat``
    ``StandardCAN_FD``/``ExtendedCAN_FD``), or it is longer than a classic frame can be
    (a DBC that leaves the frame format out, or names a classic one)."""
    return bool(message.is_fd) or message.length > CLASSIC_MAX_BYTES


def j1939_pgn(frame_id: int) -> int:
    """The PGN of a 29-bit J1939 frame ID (PDU1: the destination address is not part of it)."""
    return int(pgn_from_frame_id(frame_id))  # type: ignore[no-untyped-call]


def j1939_destination(frame_id: int) -> int | None:
    """The destination address of a 29-bit J1939 frame ID: PDU1 (PDU format below 240,
    peer to peer, e.g. proprietary A 0xEF00) has one in its PDU specific byte; PDU2
    (broadcast) none."""
    return (frame_id >> 8) & 0xFF if (frame_id >> 16) & 0xFF < 240 else None


class _MessageCodec:
    """Decoding and protection of one DBC message (precompiled unless ``compiled`` is off)."""

    def __init__(
        self,
        message: Message,
        protection: Protection | None,
        to_si: Mapping[str, float],
        compiled: bool,
    ) -> None:
        self.message = message
        # cantools' properties, read once: the per-frame path reads plain attributes.
        self.name: str = message.name
        self.length: int = message.length
        self.is_fd = is_fd_message(message)
        # A frame padded to what the bus carries (a short J1939 parameter group to 8
        # bytes, an FD message of 30 bytes to 32) is the DBC's bytes and the padding.
        self.padded_length = frame_length(message)
        self.to_si = dict(to_si)
        self.compiled = CompiledMessage.compile(message, to_si) if compiled else None
        self.protection = protection
        self.crc: CrcCheck | None = None
        self.counter_signal: str | None = None
        # One counter state per sender: J1939 transducers sharing a PGN count on their own.
        self._counters: dict[int | None, CounterCheck] = {}
        # A counter with a value table (e.g. 15 "NotAvailable") decodes to a name for some
        # values; the check judges its number.
        self._counter_codes: dict[str, int] = {}
        # A counter the DBC scales ((1,1): 1..16 for raw 0..15) or declares signed (@1-:
        # -8..7 for raw 0..15) is judged by its raw bits, as sent: (scale, offset, 2**bits).
        self._counter_scaling: tuple[float, float, int] | None = None
        # A CRC under a multiplexer value is in (and checked on) those frames only; so is a
        # counter, which then counts them.
        self._multiplexed_crc: str | None = None
        # Profile 1 in data ID mode nibble: (the nibble's signal, the value it must carry).
        self._nibble: tuple[str, int] | None = None
        if protection is not None:
            if protection.data_id_nibble is not None:
                self._nibble = (protection.data_id_nibble, protection.nibble_value)
            self.crc = protection.crc_check(message, compiled=compiled)
            self.counter_signal = protection.counter
            if protection.crc is not None:
                if message.get_signal_by_name(protection.crc).multiplexer_ids:
                    self._multiplexed_crc = protection.crc
            if protection.counter is not None:
                choices: Mapping[int, object] = (
                    message.get_signal_by_name(protection.counter).choices or {}
                )
                counter_signal = message.get_signal_by_name(protection.counter)
                bits = 2**counter_signal.length
                self._counter_codes = {str(name): int(raw) % bits for raw, name in choices.items()}
                if (counter_signal.scale, counter_signal.offset) != (1, 0) or (
                    counter_signal.is_signed
                ):
                    self._counter_scaling = (counter_signal.scale, counter_signal.offset, bits)

    def decode(
        self,
        arbitration_id: int,
        data: bytes,
        t_s: float,
        source_address: int | None,
        bus_s: float,
    ) -> DecodedFrame:
        name = self.name
        if len(data) != self.length:
            if len(data) != self.padded_length:
                raise FrameLengthError(
                    arbitration_id, f"{name} has DLC {len(data)}, the DBC says {self.length}"
                )
            data = data[: self.length]
        signals = (
            self.compiled.decode(data)
            if self.compiled is not None
            else self._decode_reference(arbitration_id, data)
        )
        if self.protection is None:
            return DecodedFrame(name, t_s, signals, (), 0, source_address)
        counter_value = None
        counter = None
        if self.counter_signal is not None:
            value = signals.get(self.counter_signal)
            if value is not None:
                if isinstance(value, str):
                    counter_value = self._counter_codes[value]
                elif self._counter_scaling is None:
                    counter_value = int(value)
                else:  # judged by what the sender counts: its raw bits
                    scale, offset, bits = self._counter_scaling
                    counter_value = round((value - offset) / scale) % bits
                counter = self._counters.get(source_address) or self._counter(source_address)
        crc = self.crc
        if (
            crc is not None
            and (self._multiplexed_crc is None or self._multiplexed_crc in signals)
            and (
                not crc.matches(data, counter_value)
                or (self._nibble is not None and signals.get(self._nibble[0]) != self._nibble[1])
            )
        ):
            # The counter of a corrupted frame is not trusted: the next good frame is not
            # flagged (one bad CRC costs exactly one sample), the frames missing counted.
            if counter is not None:
                counter.skip()
            return DecodedFrame(name, t_s, signals, (CRC_FAULT,), 0, source_address)
        if counter is None or counter_value is None:
            return DecodedFrame(name, t_s, signals, (), 0, source_address)
        result = counter.update(counter_value, bus_s)
        faults = (result.fault,) if result.fault is not None else ()
        return DecodedFrame(name, t_s, signals, faults, result.lost, source_address)

    def _counter(self, source_address: int | None) -> CounterCheck | None:
        if self.protection is None or self.protection.counter is None:
            return None
        counter = self._counters.get(source_address)
        if counter is None:
            counter = self.protection.counter_check(self.message, source_address)
            assert counter is not None
            self._counters[source_address] = counter
        return counter

    def reset_counters(self) -> None:
        for counter in self._counters.values():
            counter.reset()

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
        values: dict[str, SignalValue] = {}
        for name, value in decoded.items():
            if isinstance(value, NamedSignalValue):
                values[name] = value.name
            elif isinstance(value, (int, float)):
                factor = self.to_si.get(name)
                values[name] = value if factor is None else value * factor
            elif isinstance(value, str):
                values[name] = value
        return values


class FrameDecoder:
    """Decodes frames of the messages in ``database``; checks the protected ones.

    ``protection`` holds the profiles by message name; ``to_si`` the unit factors
    of the signals to convert (by message, then signal); ``sender_to_si`` those of a
    J1939 message's frames from one source address, where that transducer sends in
    its own unit (each such sender gets a codec of its own, compiled with its factors:
    no per-frame cost). ``senders``: the (message, source address) the config pins
    (:attr:`~dbc.machine.MachineConfig.pinned_senders`): their frames are that message's,
    where another DBC message of its PGN would take them. ``compiled=False`` decodes
    every message with cantools (the reference path).

    >>> decoder = FrameDecoder(database, config.protection)  # doctest: +SKIP
    >>> decoder.decode(0x100, frame_bytes, t_s=1.5).signals["SB1_F1_pPiston"]  # doctest: +SKIP
    12345000
    """

    def __init__(
        self,
        database: Database,
        protection: Mapping[str, Protection],
        to_si: UnitFactors | None = None,
        *,
        compiled: bool = True,
        sender_to_si: SenderUnitFactors | None = None,
        senders: Iterable[tuple[str, int]] = (),
    ) -> None:
        self._codecs: dict[tuple[int, bool], _MessageCodec] = {}
        #: The multiplexer signals of each multiplexed message, by message name: a frame's
        #: page is their values.
        self.multiplexers: dict[str, tuple[str, ...]] = {
            message.name: tuple(s.name for s in message.signals if s.is_multiplexer)
            for message in database.messages
            if message.is_multiplexed()
        }
        # PGN -> source address -> codec; None: any address (one message of the PGN).
        self._by_pgn: dict[int, dict[int | None, _MessageCodec]] = {}
        # (PGN, source address) -> destination address -> codec, for the peer-to-peer
        # messages that only their destination tells apart (a controller's proprietary A
        # to the DAQ and to a valve block); a frame to another destination is unknown.
        self._by_destination: dict[tuple[int, int], dict[int | None, _MessageCodec]] = {}
        j1939: dict[str, _MessageCodec] = {}
        for message in database.messages:
            codec = _MessageCodec(
                message,
                protection.get(message.name),
                (to_si or {}).get(message.name, {}),
                compiled,
            )
            if is_j1939(message):
                j1939[message.name] = codec
                pgn, address = j1939_pgn(message.frame_id), message.frame_id & 0xFF
                by_address = self._by_pgn.setdefault(pgn, {})
                other = by_address.get(address)
                destination = j1939_destination(message.frame_id)
                if other is not None and j1939_destination(other.message.frame_id) != destination:
                    self._by_destination.setdefault(
                        (pgn, address), {j1939_destination(other.message.frame_id): other}
                    )[destination] = codec
                by_address[address] = codec
            else:
                self._codecs[(message.frame_id, bool(message.is_extended_frame))] = codec
        for by_address in self._by_pgn.values():
            # One message of a PGN takes it from any source address (transducers sharing a
            # PGN); several (one per sender) each take their own, others go to the first.
            by_address[None] = next(iter(by_address.values()))
        for name, address in senders:
            # A sender the config pins on a message is that message's, where another DBC
            # message of its PGN came first (OIL_TEMP from 0x30, HYD_PRESS from 0x21, 0x22).
            if name in j1939:
                by_address = self._by_pgn[j1939_pgn(j1939[name].message.frame_id)]
                by_address.setdefault(address, j1939[name])
        for (name, address), factors in (sender_to_si or {}).items():
            message = database.get_message_by_name(name)
            by_address = self._by_pgn[j1939_pgn(message.frame_id)]
            taken = by_address.get(address)
            # A sender another DBC message of the PGN is for (one message per sender) keeps it.
            if taken is None or taken.message is message:
                codec = _MessageCodec(message, protection.get(name), factors, compiled)
                by_address[address] = codec
                destinations = self._by_destination.get((j1939_pgn(message.frame_id), address))
                if destinations is not None:
                    destinations[j1939_destination(message.frame_id)] = codec
        # 29-bit IDs of J1939 frames seen, with their message: bounded by the known PGNs
        # times priorities, source (and destination) addresses, so it cannot grow forever.
        self._j1939_ids: dict[int, _MessageCodec] = {}

    @property
    def receive_filters(self) -> list[ReceiveFilter]:
        """Kernel receive filters passing the DBC's frames and nothing else: each message's
        exact ID, and each J1939 PGN from any priority and source address."""
        filters = [
            ReceiveFilter(frame_id, EFF_MASK if extended else SFF_MASK, extended)
            for frame_id, extended in sorted(self._codecs)
        ]
        for pgn in sorted(self._by_pgn):
            pdu1 = (pgn >> 8) & 0xFF < 240
            filters.append(
                ReceiveFilter(pgn << 8, J1939_PDU1_MASK if pdu1 else J1939_PDU2_MASK, True)
            )
        return filters

    def decode(
        self,
        arbitration_id: int,
        data: bytes,
        t_s: float,
        is_extended_id: bool = False,
        is_fd: bool = False,
        bus_s: float | None = None,
    ) -> DecodedFrame:
        """Decode one frame; raises a :class:`~dbc.errors.FrameError` subclass if unusable.

        An FD frame decodes only for a message the DBC defines as FD (else ``fd_frame``).
        ``bus_s``: the bus time at the frame (:class:`estimator.machine.BusClock`), on which
        a silence that restarts the rolling counter's check is judged; its frame time when
        not given (then a message silent across a clock step back came back with a
        ``counter`` fault).
        """
        codec = self._codecs.get((arbitration_id, is_extended_id))
        source_address = None
        if codec is None and is_extended_id and self._by_pgn:
            codec = self._j1939_ids.get(arbitration_id)
            if codec is None:
                codec = self._j1939_codec(arbitration_id)
                if codec is not None:
                    self._j1939_ids[arbitration_id] = codec
            source_address = arbitration_id & 0xFF if codec is not None else None
        if is_fd and (codec is None or not codec.is_fd):
            raise FdFrameError(arbitration_id, "CAN FD frame of no FD message in the DBC")
        if codec is None:
            raise UnknownFrameError(arbitration_id, "ID not in the DBC")
        return codec.decode(
            arbitration_id, bytes(data), t_s, source_address, t_s if bus_s is None else bus_s
        )

    def _j1939_codec(self, frame_id: int) -> _MessageCodec | None:
        """The codec of a 29-bit frame ID by its PGN, source and (where only that tells
        the DBC's messages apart) destination address; None: none of the DBC's."""
        pgn = j1939_pgn(frame_id)
        by_address = self._by_pgn.get(pgn)
        if by_address is None:
            return None
        destinations = self._by_destination.get((pgn, frame_id & 0xFF))
        if destinations is not None:
            return destinations.get(j1939_destination(frame_id))
        codec = by_address.get(frame_id & 0xFF, by_address[None])
        # A proprietary A message the DBC gives a destination is the frames to it (and to
        # all, 0xFF): its content is the manufacturer's for each pair of nodes, so the PGN
        # to another node (a controller's to a valve block, where the DBC has its frames to
        # the DAQ only) is another message. A DBC's 0xFE, 0xFF: any. A standard PGN has
        # one layout to any node.
        wanted = j1939_destination(codec.message.frame_id)
        if (
            pgn & 0xFFFF == J1939_PROPRIETARY_A
            and wanted is not None
            and wanted < J1939_NULL_ADDRESS
            and j1939_destination(frame_id) not in (wanted, J1939_GLOBAL_ADDRESS)
        ):
            return None
        return codec

    def reset_counters(self) -> None:
        """Forget the last counters, e.g. after the bus was down: no false counter faults."""
        j1939 = {id(c): c for by_address in self._by_pgn.values() for c in by_address.values()}
        for destinations in self._by_destination.values():
            j1939 |= {id(c): c for c in destinations.values()}
        for codec in (*self._codecs.values(), *j1939.values()):
            codec.reset_counters()
