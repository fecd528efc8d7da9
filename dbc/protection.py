"""End-to-end protection of a CAN frame: CRC-8 SAE J1850 and a 4-bit rolling counter.

Pure functions and small state machines; used by the decoder to check frames
and by the simulator bridge to build them.

CRC-8 SAE J1850: polynomial 0x1D, initial value 0xFF, final XOR 0xFF, no
reflection (check value 0x4B for ASCII "123456789"), computed over every byte
of the payload except the CRC byte itself.
"""

from crc import Calculator, Crc8

_CRC8_SAE_J1850 = Calculator(Crc8.SAEJ1850.value, optimized=True)


def crc8_sae_j1850(data: bytes) -> int:
    """CRC-8 SAE J1850 of ``data``.

    >>> hex(crc8_sae_j1850(b"123456789"))
    '0x4b'
    """
    return int(_CRC8_SAE_J1850.checksum(data))


def payload_crc(data: bytes, crc_byte: int) -> int:
    """CRC of a frame's payload with the CRC byte at index ``crc_byte`` left out."""
    return crc8_sae_j1850(data[:crc_byte] + data[crc_byte + 1 :])


class CounterCheck:
    """Checks that a message's rolling counter advances by exactly one per frame.

    The counter wraps at ``modulo`` (16 for the DBC's 4-bit counters).

    The first frame (and the first after :meth:`reset`) is always accepted. A
    repeated value (a frozen sender) and any jump (lost frames, or a sender
    that restarted) fail the check; the next frame is judged against the value
    just seen, so one lost frame costs one invalid sample, not many.

    >>> check = CounterCheck()
    >>> [check.update(c) for c in (3, 4, 5, 5, 7, 8, 15, 0)]
    [True, True, True, False, False, True, False, True]
    """

    def __init__(self, modulo: int = 16) -> None:
        if modulo < 2:
            raise ValueError(f"counter modulo must be >= 2, got {modulo}")
        self.modulo = modulo
        self._last: int | None = None

    def reset(self) -> None:
        self._last = None

    def update(self, counter: int) -> bool:
        last, self._last = self._last, counter
        return last is None or counter == (last + 1) % self.modulo
