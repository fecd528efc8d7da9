"""Text CAN logs as python-can's readers take them: the lines of the file up to a cut
(:class:`LogLines`), and Vector's ASC read as Vector writes it (:class:`AscReader`)."""

import gzip
import zlib
from typing import IO, Any

import can

#: EDL in the flags of an ASC ``CANFD`` line (and of a BLF CAN FD message): an FD frame.
_EDL = 1 << 12


class LogLines:
    """The lines of a text CAN log, as python-can's readers take a file, up to a cut.

    A logger killed while writing (a power cut) leaves a last line without its line end:
    it is left out, as its data may end inside a byte (``1C`` cut to ``1`` would read as
    0x01), and :attr:`cut` says so; a gzipped log cut short ends the same way.
    """

    def __init__(self, file: IO[str]) -> None:
        self._file = file
        #: Why reading stopped before the end of the file (None: it did not).
        self.cut: str | None = None
        self._started = False

    def __iter__(self) -> "LogLines":
        return self

    def __next__(self) -> str:
        if self.cut is not None:
            raise StopIteration
        try:
            line = next(self._file)
        except (EOFError, zlib.error, gzip.BadGzipFile) as exc:  # a gzipped log cut short
            if not self._started:  # none at all: not gzip ("Not a gzipped file")
                raise ValueError(str(exc)) from exc
            self.cut = str(exc)
            raise StopIteration from exc
        self._started = True
        if not line.endswith("\n"):
            self.cut = f"its last line has no line end: {line.strip()[:60]!r}, left out"
            raise StopIteration
        return line

    def close(self) -> None:
        self._file.close()


class AscReader(can.ASCReader):
    """python-can's ASC reader, except that a ``CANFD`` line is an FD frame only when its
    flags have EDL (bit 12) set, as python-can's BLF reader has it: Vector's tools log
    the classic frames of a CAN FD channel as ``CANFD`` lines too, which python-can made
    FD frames (refused as ``fd_frame``)."""

    def _process_fd_can_frame(self, line: str, msg_kwargs: dict[str, Any]) -> can.Message:
        message = super()._process_fd_can_frame(line, msg_kwargs)
        if message.is_error_frame:
            return message
        # CHANNEL DIR ID [NAME] BRS ESI DLC LENGTH DATA... DURATION BITS FLAGS ...
        fields = line.split()
        length_at = 6 if fields[3].isdigit() else 7
        try:
            flags = int(fields[length_at + int(fields[length_at]) + 3], 16)
        except (IndexError, ValueError):  # a line of an older format: python-can's way
            return message
        message.is_fd = bool(flags & _EDL)
        return message
