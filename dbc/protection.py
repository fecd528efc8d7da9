"""End-to-end protection of CAN frames: CRC algorithms and the rolling-counter check.

Pure functions and small state machines; used by the decoder to check frames and
by the simulator bridge to build them. Each protected message has a profile
(``[protection.<MESSAGE>]`` in the config) with a counter, a CRC, or both.

CRC algorithms (all MSB first, no reflection), computed over the frame's payload
with the CRC byte(s) left out, and a data ID where the profile has one:

============== ====== ====== ======== ======== ===================================
name           width  poly   init     xor out  data ID
============== ====== ====== ======== ======== ===================================
crc8_sae_j1850 8      0x1D   0xFF     0xFF     none (the project's own DBC)
e2e_p1         8      0x1D   0x00     0x00     16 bit before, by data ID mode (below)
e2e_p11        8      0x1D   0x00     0x00     as e2e_p1 (modes both, nibble)
e2e_p2         8      0x2F   0xFF     0xFF     8 bit after; or a list of 16, by counter
e2e_p22        8      0x2F   0xFF     0xFF     as e2e_p2
e2e_p5         16     0x1021 0xFFFF   0x0000   16 bit, low then high byte, after
============== ====== ====== ======== ======== ===================================

``e2e_p1`` is AUTOSAR E2E profile 1: the SAE J1850 polynomial, but AUTOSAR's
``Crc_CalculateCRC8`` chained from start value 0xFF and the result XORed with 0xFF
again, which leaves init 0x00 and no final XOR (the J1850 check value 0x4B is not
profile 1's, 0x37). Its data ID goes in by ``DataIDMode``: ``both`` (low byte, then
high), ``low`` (low byte only), ``alt`` (low byte where the counter is even, high
where odd) or ``nibble`` (low byte, then 0; the high byte's low nibble is sent in the
frame, :attr:`Protection.data_id_nibble`); its 4-bit counter counts 0..14.
``e2e_p11`` is profile 11, profile 1's successor for CAN: the same CRC and counter,
data ID modes ``both`` and ``nibble``; ``e2e_p22`` profile 22, profile 2's, the same
CRC over the data and ``DataIDList[counter]``.
``e2e_p2`` profile 2 (CRC-8H2F, DataIDList), ``e2e_p5`` profile 5
(CRC-16/CCITT-FALSE), its CRC written low byte first whatever the DBC declares (AUTOSAR's
E2E library places the bytes, not the signal packing: a Motorola CRC signal of a big-endian
DBC is still low byte first on the bus). The parameter sets come from the ``crc``
package (the reference path); the hot path uses tables built from the same
parameters (:class:`TableCrc`).
"""

import math
import re
from collections.abc import Callable
from dataclasses import dataclass

from cantools.database.can import Message, Signal
from crc import Calculator, Configuration, Crc8, Crc16

from dbc.signal_range import codes_at_the_ends

#: Counter faults, as they appear in an estimate's ``reasons``.
COUNTER_REPEAT = "counter_repeat"
COUNTER_JUMP = "counter"
CRC_FAULT = "crc"


@dataclass(frozen=True, slots=True)
class CrcAlgorithm:
    """A CRC of the protection profiles: its parameters and where the data ID goes."""

    name: str
    configuration: Configuration
    #: "none", "before" (16-bit ID, low byte first), "after8" (one byte, or a list of
    #: 16 by counter) or "after16" (16-bit ID, low byte first).
    data_id_layout: str
    #: The DataIDModes the profile takes ("before" only; the first is the default).
    data_id_modes: tuple[str, ...] = ()
    #: The values a 4-bit counter of the profile takes, where fewer than 16.
    counter_modulo: int | None = None

    @property
    def width_bytes(self) -> int:
        return self.configuration.width // 8


#: AUTOSAR E2E profile 1's ways of putting its 16-bit data ID into the CRC (DataIDMode).
P1_DATA_ID_MODES = ("both", "alt", "low", "nibble")
_P1_CRC = Configuration(8, 0x1D, init_value=0x00, final_xor_value=0x00)
CRC_ALGORITHMS: dict[str, CrcAlgorithm] = {
    algorithm.name: algorithm
    for algorithm in (
        CrcAlgorithm("crc8_sae_j1850", Crc8.SAEJ1850.value, "none"),
        # Profile 1's counter takes 0..14 (15 is no counter value); so does 11's.
        CrcAlgorithm("e2e_p1", _P1_CRC, "before", P1_DATA_ID_MODES, counter_modulo=15),
        CrcAlgorithm("e2e_p11", _P1_CRC, "before", ("both", "nibble"), counter_modulo=15),
        CrcAlgorithm("e2e_p2", Crc8.AUTOSAR.value, "after8"),
        CrcAlgorithm("e2e_p22", Crc8.AUTOSAR.value, "after8"),
        CrcAlgorithm("e2e_p5", Crc16.IBM_3740.value, "after16"),
    )
}
DEFAULT_CRC_ALGORITHM = "crc8_sae_j1850"

#: CRC of a byte string, by one implementation or the other.
Checksum = Callable[[bytes], int]


class TableCrc:
    """Table-driven CRC (MSB first, no reflection) of 8 or 16 bits: the hot path.

    >>> TableCrc(Crc8.SAEJ1850.value).checksum(b"123456789")  # SAE J1850 check value
    75
    >>> hex(TableCrc(Crc16.IBM_3740.value).checksum(b"123456789"))  # CCITT-FALSE
    '0x29b1'
    """

    def __init__(self, configuration: Configuration) -> None:
        width = configuration.width
        if width not in (8, 16) or configuration.reverse_input or configuration.reverse_output:
            raise ValueError(f"TableCrc handles unreflected 8/16-bit CRCs, not {configuration}")
        top, mask = 1 << (width - 1), (1 << width) - 1
        table = []
        for byte in range(256):
            register = byte << (width - 8)
            for _ in range(8):
                register = (
                    (register << 1) ^ configuration.polynomial if register & top else register << 1
                )
            table.append(register & mask)
        self._table = tuple(table)
        self._shift = width - 8
        self._mask = mask
        self._init = configuration.init_value
        self._final_xor = configuration.final_xor_value

    def checksum(self, data: bytes) -> int:
        table, shift, mask = self._table, self._shift, self._mask
        register = self._init
        if shift == 0:
            for byte in data:
                register = table[register ^ byte]
        else:
            for byte in data:
                register = ((register << 8) & mask) ^ table[(register >> shift) ^ byte]
        return register ^ self._final_xor


def reference_checksum(configuration: Configuration) -> Checksum:
    """The ``crc`` package's implementation of ``configuration`` (the reference path)."""
    calculator = Calculator(configuration)
    return lambda data: int(calculator.checksum(data))


def crc8_sae_j1850(data: bytes) -> int:
    """CRC-8 SAE J1850 of ``data``.

    >>> hex(crc8_sae_j1850(b"123456789"))
    '0x4b'
    """
    return _J1850_REFERENCE(data)


_J1850_REFERENCE = reference_checksum(Crc8.SAEJ1850.value)


class CrcCheck:
    """The CRC of one message: computes, checks and writes it at its place in the frame.

    ``start_byte`` locates the CRC (a 16-bit one low byte first); ``data_id`` is the profile's
    data ID (a tuple of 16 for ``e2e_p2``'s DataIDList, picked by the counter value),
    put in by ``data_id_mode`` for ``e2e_p1`` (:data:`P1_DATA_ID_MODES`).
    ``compiled=False`` uses the ``crc`` package instead of the tables.

    AUTOSAR E2E profile 1, data ID 0x123, the CRC in byte 0 and the counter in byte 1
    (the vectors of the ``autosar-e2e`` package's tests):

    >>> p1 = CrcCheck(CRC_ALGORITHMS["e2e_p1"], 0, data_id=0x123)
    >>> hex(p1.compute(bytes(8), 0)), hex(p1.compute(bytes([0, 1]) + bytes(6), 1))
    ('0xcc', '0x91')
    >>> alt = CrcCheck(CRC_ALGORITHMS["e2e_p1"], 0, data_id=0x123, data_id_mode="alt")
    >>> hex(alt.compute(bytes([0, 1]) + bytes(6), 1))
    '0x2'
    """

    def __init__(
        self,
        algorithm: CrcAlgorithm,
        start_byte: int,
        data_id: int | tuple[int, ...] = 0,
        *,
        data_id_mode: str = "both",
        compiled: bool = True,
    ) -> None:
        self.algorithm = algorithm
        self.start_byte = start_byte
        self.end_byte = start_byte + algorithm.width_bytes
        self.data_id = data_id
        # Profile 1's data ID bytes before the data, for an even and an odd counter.
        self._before = (
            _p1_data_id_bytes(data_id, data_id_mode) if isinstance(data_id, int) else (b"", b"")
        )
        self._checksum: Checksum = (
            TableCrc(algorithm.configuration).checksum
            if compiled
            else reference_checksum(algorithm.configuration)
        )

    def _data_id_for(self, counter: int | None) -> int:
        if isinstance(self.data_id, tuple):
            return self.data_id[(counter or 0) % len(self.data_id)]
        return self.data_id

    def compute(self, data: bytes, counter: int | None = None) -> int:
        """The CRC of ``data`` (a whole frame; its CRC bytes are left out)."""
        payload = data[: self.start_byte] + data[self.end_byte :]
        layout = self.algorithm.data_id_layout
        if layout == "none":
            return self._checksum(payload)
        data_id = self._data_id_for(counter)
        if layout == "before":
            return self._checksum(self._before[(counter or 0) & 1] + payload)
        if layout == "after8":
            return self._checksum(payload + bytes((data_id & 0xFF,)))
        return self._checksum(payload + bytes((data_id & 0xFF, (data_id >> 8) & 0xFF)))

    def received(self, data: bytes) -> int:
        """The CRC value the frame carries."""
        return int.from_bytes(data[self.start_byte : self.end_byte], "little")

    def matches(self, data: bytes, counter: int | None = None) -> bool:
        return self.compute(data, counter) == self.received(data)

    def write(self, frame: bytearray, counter: int | None = None, corrupt: bool = False) -> None:
        """Put the CRC into ``frame`` (inverted when ``corrupt``: fault injection)."""
        value = self.compute(bytes(frame), counter)
        if corrupt:
            value ^= (1 << (8 * self.algorithm.width_bytes)) - 1
        frame[self.start_byte : self.end_byte] = value.to_bytes(
            self.algorithm.width_bytes, "little"
        )


def _p1_data_id_bytes(data_id: int, mode: str) -> tuple[bytes, bytes]:
    """What profile 1's CRC takes of ``data_id`` before the data in ``mode``, for an even
    and for an odd counter value."""
    low, high = data_id & 0xFF, (data_id >> 8) & 0xFF
    if mode == "both":
        return bytes((low, high)), bytes((low, high))
    if mode == "low":
        return bytes((low,)), bytes((low,))
    if mode == "alt":
        return bytes((low,)), bytes((high,))
    if mode == "nibble":  # the high byte's low nibble travels in the frame instead
        return bytes((low, 0)), bytes((low, 0))
    raise ValueError(f"profile 1 data ID mode must be one of {P1_DATA_ID_MODES}, got {mode!r}")


@dataclass(frozen=True, slots=True)
class CounterResult:
    """What one counter value says: a fault (or None) and how many frames were lost."""

    fault: str | None
    lost: int


_OK = CounterResult(None, 0)


class CounterCheck:
    """Checks a message's rolling counter as AUTOSAR E2E does.

    The counter wraps at ``modulo`` (16 for a 4-bit counter). With ``delta`` the
    step from the last value seen: 0 is a repeat (``counter_repeat``: a frozen
    sender, the sample is invalid); 1..``max_delta`` is fine, ``delta - 1`` frames
    were lost on the way (counted, the data of this frame is good); a larger jump
    is ``counter`` (invalid; the sender restarted or many frames were lost). The
    first frame, and the first after :meth:`reset`, is accepted as it comes; the
    next frame is always judged against the value just seen. A frame whose CRC failed
    is :meth:`skip`-ped (its counter is not trusted): the next good frame is not
    flagged, and the frames missing between the last good one and it, less those that
    came corrupted, are counted lost (a burst of interference corrupts some frames and
    loses others; those lost went uncounted). So is a frame that comes
    more than ``resync_after_s`` after the one before (the times given: the pipeline's
    bus time, :class:`estimator.machine.BusClock`, on which a clock stepped back during
    the silence hides none of it): after a silence as long as a whole turn of the
    counter (the sender switched off, a log's gap), the counter can no longer tell how
    many frames went missing, and the check starts anew, as AUTOSAR's receivers
    resynchronise after a timeout.

    >>> check = CounterCheck(modulo=16, max_delta=2)
    >>> [(r.fault, r.lost) for r in map(check.update, (3, 4, 6, 6, 10, 11))]
    [(None, 0), (None, 0), (None, 1), ('counter_repeat', 0), ('counter', 3), (None, 0)]
    >>> check = CounterCheck(modulo=16, max_delta=2)
    >>> check.update(3), check.skip(), check.update(7)  # 4 corrupted, 5 and 6 lost
    (CounterResult(fault=None, lost=0), None, CounterResult(fault=None, lost=2))
    >>> check = CounterCheck(modulo=16, max_delta=2, resync_after_s=0.16)
    >>> [check.update(c, t).fault for c, t in ((3, 0.0), (9, 0.05), (5, 3600.0))]
    [None, 'counter', None]
    """

    def __init__(
        self, modulo: int = 16, max_delta: int = 2, resync_after_s: float = math.inf
    ) -> None:
        if modulo < 2:
            raise ValueError(f"counter modulo must be >= 2, got {modulo}")
        if not 1 <= max_delta < modulo:
            raise ValueError(f"max_delta_counter must be 1..{modulo - 1}, got {max_delta}")
        self.modulo = modulo
        self.max_delta = max_delta
        self.resync_after_s = resync_after_s
        self._last: int | None = None
        self._last_t_s = math.nan
        # Frames since the last value whose counter was not trusted (their CRC failed).
        self._skipped = 0

    def reset(self) -> None:
        """Forget the last value (after a gap in reception)."""
        self._last = None
        self._skipped = 0

    def skip(self) -> None:
        """A frame came whose counter is not trusted (its CRC failed): the next good frame
        is judged against the last good one, never flagged, its frames lost counted."""
        if self._last is not None:
            self._skipped += 1

    def update(self, counter: int, t_s: float = math.nan) -> CounterResult:
        """Judge ``counter`` of a frame at time ``t_s`` (NaN: time not judged)."""
        if not 0 <= counter < self.modulo:  # a value it never takes (profile 1's 15)
            self.reset()
            return CounterResult(COUNTER_JUMP, 0)
        last, self._last = self._last, counter
        last_t_s, self._last_t_s = self._last_t_s, t_s
        if last is None or t_s - last_t_s > self.resync_after_s:
            self._skipped = 0
            return _OK
        delta = (counter - last) % self.modulo
        if self._skipped:  # after corrupted frames: resynchronised, what is missing lost
            skipped, self._skipped = self._skipped, 0
            return CounterResult(None, max(0, delta - 1 - skipped))
        if delta == 1:
            return _OK
        if delta == 0:
            return CounterResult(COUNTER_REPEAT, 0)
        if delta <= self.max_delta:
            return CounterResult(None, delta - 1)
        return CounterResult(COUNTER_JUMP, delta - 1)


def counter_modulo(
    message: Message, counter: str, crc_algorithm: str = DEFAULT_CRC_ALGORITHM
) -> int:
    """How many values the rolling counter ``counter`` of ``message`` takes: all its bits
    can hold, or fewer where the DBC declares a range ``[0|max]`` below that, so the wrap
    from max to 0 is one step. AUTOSAR E2E profile 1's 4-bit counter counts 0..14 whatever
    the DBC declares (CANdb++ fills in ``[0|15]``), as profile 11's does: a real
    sender's wrap 14 -> 0 was a lost frame, and its 15 a valid value. So does a counter
    whose value table names the top of its bits (``15 "NotAvailable"``, J1939's way, and
    the named values right below it: :func:`dbc.signal_range.codes_at_the_ends`): the
    sender never counts through its code, so its wrap 14 -> 0 counted a frame lost each
    turn, and its 15 was a count.

    >>> from cantools.database import load_string
    >>> db = load_string('BO_ 1 M: 1 A\\n SG_ C : 0|4@1+ (1,0) [0|14] "" A\\n', "dbc")
    >>> counter_modulo(db.get_message_by_name("M"), "C")
    15
    >>> db = load_string('BO_ 1 M: 1 A\\n SG_ C : 0|4@1+ (1,0) [0|15] "" A\\n', "dbc")
    >>> counter_modulo(db.get_message_by_name("M"), "C"), counter_modulo(
    ...     db.get_message_by_name("M"), "C", "e2e_p1")
    (16, 15)
    >>> db = load_string('BO_ 1 M: 1 A\\n SG_ C : 0|4@1+ (1,0) [0|15] "" A\\n'
    ...                  'VAL_ 1 C 15 "NotAvailable" 14 "Error" ;\\n', "dbc")
    >>> counter_modulo(db.get_message_by_name("M"), "C")
    14
    """
    signal = message.get_signal_by_name(counter)
    modulo: int = 2**signal.length
    profile_modulo = CRC_ALGORITHMS[crc_algorithm].counter_modulo
    if profile_modulo is not None and signal.length == 4:
        return profile_modulo
    # The codes named at the top; a table naming most values names counts, not codes.
    codes = codes_at_the_ends(signal) & set(range(modulo // 2, modulo))
    if len(codes) < modulo // 4:
        modulo -= len(codes)
    low, high = signal.minimum, signal.maximum
    if (
        low == 0
        and high is not None
        and float(high).is_integer()
        and 1 <= high < modulo - 1
        and (signal.scale, signal.offset) == (1, 0)
    ):
        return int(high) + 1
    return modulo


#: Words of a signal name that call it a rolling counter or a CRC, as vendors write them
#: (English, German, abbreviated): ``AliveCounter``, ``MsgCntr``, ``Zaehler``, ``BZ``
#: (Botschaftszaehler), ``SQC``; ``Checksum``, ``CHK``, ``Pruefsumme``, ``CRC8``.
_ROLE_WORDS = {
    "counter": frozenset(
        "counter cntr cnt ctr zaehler zähler alive rollingcounter msgcntr msgcnt bz sqc seq".split()
    ),
    "crc": frozenset("crc checksum chksum chks chk pruefsumme prüfsumme".split()),
}
_WORD_BREAKS = re.compile(
    r"[^0-9A-Za-zÄÖÜäöüß]+|(?<=[a-zäöüß])(?=[A-ZÄÖÜ])|(?<=\D)(?=\d)|(?<=\d)(?=\D)"
)


def protection_role(signal: Signal) -> str | None:
    """``"counter"`` or ``"crc"`` where ``signal``'s name calls it one (a word of it, by
    ``_`` and case: ``ZYL_VL_Zaehler``, ``MsgCntr``, ``HUB_CRC8``) and its bits fit one
    (an unscaled integer of 2..16 bits; a CRC of 8 or 16); else None.

    >>> from cantools.database.can import Signal
    >>> [protection_role(Signal(n, 0, 8)) for n in ("MsgCntr", "Pruefsumme", "CycleCount")]
    ['counter', 'crc', None]
    """
    if signal.is_float or (signal.scale, signal.offset) != (1, 0):
        return None
    words = {word.lower() for word in _WORD_BREAKS.split(signal.name) if word}
    if words & _ROLE_WORDS["crc"] and signal.length in (8, 16):
        return "crc"
    if words & _ROLE_WORDS["counter"] and 2 <= signal.length <= 16:
        return "counter"
    return None


@dataclass(frozen=True, slots=True)
class Protection:
    """The end-to-end protection profile of one message (``[protection.<MESSAGE>]``).

    Either part is optional: a counter alone, a CRC alone, or both.
    """

    message: str
    #: The rolling counter signal; None: no counter check.
    counter: str | None = None
    #: The CRC signal (8 or 16 bits on byte boundaries); None: no CRC check.
    crc: str | None = None
    #: A name of :data:`CRC_ALGORITHMS`.
    crc_algorithm: str = DEFAULT_CRC_ALGORITHM
    #: The profile's data ID; a tuple of 16 is e2e_p2's DataIDList (by counter value).
    data_id: int | tuple[int, ...] = 0
    #: How ``e2e_p1`` (``e2e_p11``) puts the data ID into the CRC: one of
    #: :data:`P1_DATA_ID_MODES` (``both``, ``nibble``).
    data_id_mode: str = "both"
    #: ``e2e_p1`` in data ID mode ``nibble``: the 4-bit signal that carries the data
    #: ID's high byte's low nibble (a frame with another is a CRC fault: another sender's).
    data_id_nibble: str | None = None
    #: Largest counter step still accepted (1 + frames that may be lost in a row).
    max_delta_counter: int = 2
    #: The message's cycle time (:attr:`dbc.machine.MachineConfig.cycle_times_ms`), s;
    #: None: none known, the counter check then never resynchronises on a silence.
    cycle_time_s: float | None = None
    #: (J1939 source address, cycle time s) of the transducers that send at their own
    #: (a chamber's ``cycle_time_ms``): their counters resynchronise on that.
    sender_cycle_times_s: tuple[tuple[int, float], ...] = ()

    def crc_check(self, message: Message, *, compiled: bool = True) -> CrcCheck | None:
        """The CRC check of this profile on ``message``'s layout; None without a CRC."""
        if self.crc is None:
            return None
        signal = message.get_signal_by_name(self.crc)
        # A Motorola signal's start bit is its MSB, in the lowest byte it occupies; its
        # bytes are low byte first all the same (profile 5's CRC: AUTOSAR places them).
        start_byte = signal.start // 8
        return CrcCheck(
            CRC_ALGORITHMS[self.crc_algorithm],
            start_byte,
            self.data_id,
            data_id_mode=self.data_id_mode,
            compiled=compiled,
        )

    @property
    def nibble_value(self) -> int:
        """What :attr:`data_id_nibble` carries: the data ID's high byte's low nibble."""
        assert isinstance(self.data_id, int)
        return (self.data_id >> 8) & 0x0F

    @property
    def signals(self) -> tuple[str, ...]:
        """The signals of the profile (counter, CRC, data ID nibble): no measurement."""
        return tuple(s for s in (self.counter, self.crc, self.data_id_nibble) if s is not None)

    def counter_check(
        self, message: Message, source_address: int | None = None
    ) -> CounterCheck | None:
        """A fresh counter check for ``message`` (from the J1939 sender ``source_address``);
        None without a counter."""
        if self.counter is None:
            return None
        modulo = counter_modulo(message, self.counter, self.crc_algorithm)
        own = [
            cycle_s for address, cycle_s in self.sender_cycle_times_s if address == source_address
        ]
        cycle_time_s = own[0] if own else self.cycle_time_s
        # A whole turn of the counter: longer silent, it cannot count what was lost.
        resync_after_s = modulo * cycle_time_s if cycle_time_s else math.inf
        return CounterCheck(modulo, self.max_delta_counter, resync_after_s)
