"""Text CAN logs as python-can's readers take them: the lines of the file up to a cut
(:class:`LogLines`), and Vector's ASC read as Vector writes it (:class:`AscReader`)."""

import gzip
import re
import zlib
from collections import Counter
from collections.abc import Generator, Iterable, Iterator
from typing import IO, Any, TextIO, cast

import can
from can.io.asc import ASC_MESSAGE_REGEX

#: EDL in the flags of an ASC ``CANFD`` line (and of a BLF CAN FD message): an FD frame.
_EDL = 1 << 12

#: The header line of python-can's CSV log.
_CSV_HEADER = "timestamp,arbitration_id,extended,remote,error,dlc,data\n"

#: The header's last line in an ASC log (python-can's pattern).
_EVENTS_LINE = re.compile(r"(no)?\s*internal\s+events\s+logged", re.IGNORECASE)

#: A CAN controller's status line in an ASC log: its time, channel (from 1) and state
#: (``0.5 CAN 1 Status:chip status error passive - TxErr: 132 RxErr: 0``).
_ASC_STATUS = re.compile(
    r"\s*(?P<time>\d+\.\d+)\s+CAN\s+(?P<channel>\d+)\s+Status:\s*(?P<state>[^-\n]*[^-\s])"
)
#: The time an ASC line begins with (not a header's or a comment's).
_ASC_TIME = re.compile(r"(?P<indent>\s*)(?P<time>\d+\.\d+)(?=\s)")
#: A transmit request in an ASC log (classic: ``TIME CH ID TxRq``, FD: ``TIME CANFD CH TxRq``).
_ASC_TX_REQUEST = re.compile(r"\s*\d+\.\d+\s+(?:\d+\s+\S+|CANFD\s+\d+)\s+TxRq\s", re.IGNORECASE)


#: The lines of an ASC log after its header that are no frame but known to be something:
#: a comment, a header's line again (logs joined), the trigger block's bounds, an event of
#: another kind (a time, then a word where the channel is: ``Start of measurement``,
#: ``SV:``, ``CAN 1 Status:``, LIN, FlexRay, ...; or a channel, then a word where the ID
#: is: ``Statistic:``, ``J1939TP``, ...).
_ASC_NO_FRAME = re.compile(
    r"\s*(?:$|//|date\s|base\s|(?:no\s+)?internal\s+events|(?:begin|end)\s+triggerblock"
    r"|\d+\.\d+\s+(?:(?!\d+\s)\S|\d+\s+(?![0-9A-Fa-f]+x?\s)\S))",
    re.IGNORECASE,
)


def _asc_line_unknown(line: str) -> bool:
    """``line`` (after an ASC log's header) is neither a frame python-can reads nor a
    line of another kind :data:`_ASC_NO_FRAME` knows."""
    return ASC_MESSAGE_REGEX.match(line.strip()) is None and _ASC_NO_FRAME.match(line) is None


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
        #: The line read last (None before the first).
        self.last: str | None = None
        #: The number of the line read last, from 1 (0 before the first).
        self.number = 0
        self._again: list[str] = []
        self._started = False

    def __iter__(self) -> "LogLines":
        return self

    def read_again(self, line: str | None = None) -> None:
        """The next line is ``line``, by default the one read last once more (a header
        reader that read a line too far)."""
        line = self.last if line is None else line
        if line is not None:
            self._again.append(line)

    def __next__(self) -> str:
        if self._again:
            return self._again.pop()
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
        self.number += 1
        if not line.endswith("\n"):
            self.cut = f"its last line has no line end: {line.strip()[:60]!r}, left out"
            raise StopIteration
        self.last = line
        return line

    def close(self) -> None:
        self._file.close()


def check_data_bytes(data: bytes | bytearray, length: int) -> None:
    """Raises ValueError when a frame line's ``data`` has fewer bytes than its ``length``
    (or DLC) says: a line damaged in the middle of a log, whose frame is not known."""
    if len(data) < length:
        raise ValueError(f"a frame line with {len(data)} of its {length} data bytes")


class SkippedLines:
    """The lines of a text log a reader leaves out that are neither a frame nor an event
    of the format it knows (a frame line damaged in the middle of the log, text of
    another program): counted, the first kept with its number, for one warning line.
    python-can's ASC and TRC readers passed over them without a word, a frame lost
    uncounted."""

    def __init__(self, lines: object) -> None:
        self._lines = lines
        #: How many were left out.
        self.count = 0
        #: The first one left out: its number in the file (0 if not known) and its text.
        self.first: tuple[int, str] | None = None

    def add(self, line: str) -> None:
        self.count += 1
        if self.first is None:
            number = self._lines.number if isinstance(self._lines, LogLines) else 0
            self.first = (number, line.strip()[:60])


class AscReader(can.ASCReader):
    """python-can's ASC reader, except that

    - a ``CANFD`` line is an FD frame only when its flags have EDL (bit 12) set, as
      python-can's BLF reader has it: Vector's tools log the classic frames of a CAN FD
      channel as ``CANFD`` lines too, which python-can made FD frames (``fd_frame``);
    - a header without its last line, ``internal events logged`` (older CANalyzers, other
      tools), does not cost the log's first line: python-can's header reading took it and
      dropped it, a frame lost uncounted where a frame came next (of a :class:`LogLines`
      file);
    - a CAN controller's status line (``CAN 2 Status:chip status busoff``, ``error
      passive``, ``warning level``, ``receive queue overrun``; not ``error active``, the
      state of a controller that is well) is an error frame of its channel, as SocketCAN
      reports one (candump logs it so), and tallied in :attr:`controller_events`;
      python-can skipped them: a bus-off showed nowhere;
    - with ``timestamps relative`` (each line's time the step since the line before), a
      line's time is the sum of the steps of every line up to it: python-can read the
      steps as times (the log ran back and forth), and summing the frames' alone lost
      the steps of the lines it skips (a comment, a statistic, a status);
    - a transmit request (``TxRq``: the logging node asked for a frame to be sent; the
      frame itself is its ``Tx`` line) is no frame: python-can read it as one, so every
      frame the logger's node sent came twice (``counter_repeat``, a second estimate);
    - a line after the header that is neither a CAN frame nor an event of another kind
      (a comment, a statistic, a J1939 transport message, a system variable, ...: a time
      and a word where the channel or the ID would be) is counted in :attr:`skipped`: a
      frame line cut in the middle of the log (``0.190000 1  1``), text of another
      program; python-can passed over them without a word;
    - a frame line with fewer data bytes than its length says (a line damaged in the
      middle of the log) is a ValueError: python-can read the bytes it found, a frame
      of another length (``wrong_dlc``).
    """

    def __init__(self, file: Any, **kwargs: Any) -> None:
        super().__init__(file, **kwargs)
        #: The controller status changes read, by (channel as python-can names it, state).
        self.controller_events: Counter[tuple[str, str]] = Counter()
        self._lines: object = file
        self._in_header = True  # a line read past the header is read again (and counted once)
        self._relative = False  # "timestamps relative": summed here (of every line, not
        self._elapsed_s = 0.0  # of the frames alone: a comment's step counts too)
        #: The lines left out as neither a frame nor an event of an ASC log.
        self.skipped = SkippedLines(file)

    def __iter__(self) -> Generator[can.Message, None, None]:
        self._lines = lines = self.file
        self.file = cast(TextIO, self._event_lines(lines))
        try:
            yield from super().__iter__()
        finally:
            self.file = lines

    def _event_lines(self, lines: Iterable[str]) -> Iterator[str]:
        """The lines, a status line as an error frame's line, without transmit requests;
        with relative timestamps, each line's time the sum of the steps up to it."""
        for line in lines:
            if self._relative and (timed := _ASC_TIME.match(line)) is not None:
                self._elapsed_s += float(timed["time"])
                line = f"{timed['indent']}{self._elapsed_s:.9f}{line[timed.end() :]}"
            if "TxRq" in line and _ASC_TX_REQUEST.match(line):
                continue
            status = None if self._in_header or "Status:" not in line else _ASC_STATUS.match(line)
            if status is not None:
                state = status["state"].removeprefix("chip status ")
                if state == "error active":
                    continue
                self.controller_events[str(int(status["channel"]) - 1), state] += 1
                line = f"{status['time']} {status['channel']} ErrorFrame\n"
            elif not self._in_header and _asc_line_unknown(line):
                self.skipped.add(line)
                continue
            yield line

    def _extract_header(self) -> None:
        super()._extract_header()  # reads up to the events line, or one line past the header
        self._in_header = False
        self._relative = self.timestamps_format == "relative"
        lines = self._lines
        if isinstance(lines, LogLines) and not _EVENTS_LINE.match((lines.last or "").strip()):
            lines.read_again()

    def _process_data_string(
        self, data_str: str, data_length: int, msg_kwargs: dict[str, Any]
    ) -> None:
        super()._process_data_string(data_str, data_length, msg_kwargs)
        check_data_bytes(msg_kwargs["data"], data_length)

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


class CsvReader(can.CSVReader):
    """python-can's CSV reader, except that a file without the header line (the columns
    written by another program) costs no frame: python-can skipped its first line as the
    header, a frame lost uncounted (of a :class:`LogLines` file)."""

    def __iter__(self) -> Generator[can.Message, None, None]:
        lines: object = self.file
        if isinstance(lines, LogLines):
            first = next(lines, None)
            lines.read_again()
            if first is not None and not first.lstrip().lower().startswith("timestamp"):
                lines.read_again(_CSV_HEADER)  # for python-can to skip
        yield from super().__iter__()
