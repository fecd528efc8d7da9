"""PEAK ``.trc`` logs (PCAN-View, PCAN-Explorer): python-can's reader, made to account
for every frame line of the file versions PEAK defines (1.0 to 2.1).

python-can's :class:`can.TRCReader` reads the data and remote frames of versions 1.0,
1.1, 1.3, 2.0 and 2.1. :class:`TrcReader` also

- reads the error frames (``ERROR`` in 1.0's data, type ``Error`` in 1.1 to 1.3, ``ER``
  in 2.x) as error frames, counted by the pipeline as ``error_frame`` as live; python-can
  left them out (1.1 to 2.x) or stopped at them (1.0: ``invalid literal ... 'ERROR'``);
- reads version 1.2 (1.3 without its reserved column; PCAN-Explorer 5), which python-can
  took for 1.0 and stopped at the first line (``invalid literal ... 'Rx'``); a version
  PEAK has not defined is refused by name, not read as 1.0;
- stops at a frame line it cannot parse (too few columns: a line cut in the middle of
  the log), as in every other text log; python-can left it out with a warning of its
  own, a frame lost uncounted.

- reads the controller's status lines (1.x ``Warng`` / 1.0 ``FFFFFFFF`` lines, 2.x
  ``ST``: bus light, bus heavy, bus off, error passive, an overrun) as error frames of
  their channel, as SocketCAN reports such a state (candump logs it so), tallied by
  state in :attr:`TrcReader.controller_events`; python-can left them out: a bus-off
  showed nowhere. A status of 0 (all well again) is no error.

Lines that are no frame are left out, as python-can does: the controller's error
counters (``EC``) and user events (``EV``). A line of a type PEAK does not define (a
line damaged in the middle of the log, text of another program) is left out too, and
counted in :attr:`TrcReader.skipped`: python-can passed over it without a word. A 2.x
frame line with fewer data bytes than its length says (damaged) is a ValueError:
python-can read the bytes it found, a frame of another length (``wrong_dlc``).

>>> import io
>>> log = io.StringIO(
...     ";$FILEVERSION=1.2\\n;$STARTTIME=39878.5\\n"
...     "     1)      1059.900  1  Rx         0300  2  01 02\\n"
...     "     2)      1349.222  1  Error      0008  4  00 19 08 08\\n"
... )
>>> [(m.arbitration_id, bytes(m.data), m.is_error_frame) for m in TrcReader(log)]
[(768, b'\\x01\\x02', False), (0, b'', True)]
"""

from collections import Counter
from collections.abc import Iterator
from typing import Any, TextIO, cast

import can
from can.util import dlc2len

from daq.text_log import SkippedLines, check_data_bytes

#: The file versions PEAK defines: python-can reads all but 1.2, which we read.
_VERSIONS = ("1.0", "1.1", "1.2", "1.3", "2.0", "2.1")

#: The line types that are no frame: the controller's status (of 0: all well; 1.x ``Warng``,
#: 2.x ``ST``), error counters (``EC``) and user events (``EV``).
_NO_FRAME = frozenset(("Warng", "ST", "EC", "EV"))

#: The bits of a PCAN status value (PCAN-Basic's ``PCAN_ERROR_*``) a status line carries.
_STATUS_BITS = {
    0x01: "transmit buffer full",
    0x02: "controller overrun",
    0x04: "bus light",
    0x08: "bus heavy",
    0x10: "bus off",
    0x40: "receive queue overrun",
    0x80: "transmit queue full",
    0x40000: "error passive",
}


class TrcReader(can.TRCReader):
    """python-can's TRC reader that reads error frames and version 1.2, and stops at a
    frame line it cannot parse (see the module docstring)."""

    def __init__(self, file: Any, **kwargs: Any) -> None:
        super().__init__(file, **kwargs)
        #: The controller status changes read, by (channel as python-can names it, state).
        self.controller_events: Counter[tuple[str, str]] = Counter()
        #: The lines left out as of a type PEAK does not define.
        self.skipped = SkippedLines(file)
        self._type_at: int | None = None  # the column of a line's type (1.0 has none)

    def _extract_header(self) -> str:
        declared: list[str] = []
        lines = self.file

        def header_lines() -> Iterator[str]:
            for line in lines:
                if line.strip().startswith(";$FILEVERSION="):
                    declared.append(line.split("=", 1)[1].strip())
                yield line

        self.file = cast(TextIO, header_lines())
        try:
            first_line = super()._extract_header()
        finally:
            self.file = lines
        version = declared[-1] if declared else None
        self._type_at = {"1.1": 2, "1.2": 3, "1.3": 3}.get(version or "1.0", self.columns.get("T"))
        if version == "1.2":
            if self._start_time is None:  # as python-can's check for 1.1 and later
                raise ValueError("File has no start time information")
            self._parse_cols = self._parse_cols_v1_2
        elif version is not None and version not in _VERSIONS:
            raise ValueError(f"TRC file version {version}: not one PEAK defines (1.0 to 2.1)")
        return first_line

    def _parse_line(self, line: str) -> can.Message | None:
        if not line.strip():  # python-can's header reading hands on an empty file's ''
            return None
        cols = tuple(line.split(maxsplit=self._num_columns))
        try:
            message = self._parse_cols(cols)
        except IndexError as exc:
            raise ValueError(f"a frame line with too few columns: {line.strip()!r}") from exc
        if message is None and self._type_at is not None and cols[self._type_at] not in _NO_FRAME:
            self.skipped.add(line)
        return message

    def _error_frame(self, offset_ms: str, channel: int, dated: bool = True) -> can.Message:
        """An error frame at ``offset_ms`` from the start time (1.0 has none: ``dated``
        False, its times count from 0 as python-can reads its frames)."""
        start_s = (self._start_time or 0.0) if dated else 0.0
        return can.Message(
            timestamp=float(offset_ms) / 1000 + start_s,
            is_error_frame=True,
            channel=channel,
        )

    def _status(
        self, cols: tuple[str, ...], value_at: int, offset_ms: str, channel: int, dated: bool = True
    ) -> can.Message | None:
        """The error frame of a status line whose four status bytes begin at word
        ``value_at`` of ``cols``; None for a status of 0 (all well)."""
        words = " ".join(cols).split()
        value = int("".join(words[value_at : value_at + 4]), 16)
        if value == 0:
            return None
        states = [name for bit, name in _STATUS_BITS.items() if value & bit]
        for state in states or [f"status 0x{value:X}"]:
            self.controller_events[str(channel), state] += 1
        return self._error_frame(offset_ms, channel, dated)

    def _parse_msg_v1_0(self, cols: tuple[str, ...]) -> can.Message | None:
        # NUMBER) OFFSET ID LENGTH (DATA... | RTR | ERROR DATA...); status: ID FFFFFFFF
        if len(cols) > 4 and cols[4] == "ERROR":
            return self._error_frame(cols[1], 1, dated=False)
        if cols[2] == "FFFFFFFF":
            return self._status(cols, 4, cols[1], 1, dated=False)
        return super()._parse_msg_v1_0(cols)

    def _parse_cols_v1_1(self, cols: tuple[str, ...]) -> can.Message | None:
        # NUMBER) OFFSET TYPE ID LENGTH DATA...
        if cols[2] == "Error":
            return self._error_frame(cols[1], 1)
        if cols[2] == "Warng":
            return self._status(cols, 5, cols[1], 1)
        return super()._parse_cols_v1_1(cols)

    def _parse_cols_v1_2(self, cols: tuple[str, ...]) -> can.Message | None:
        # NUMBER) OFFSET BUS TYPE ID LENGTH DATA...: 1.3 without its reserved column
        return self._parse_cols_v1_3((*cols[:5], "-", *cols[5:]))

    def _parse_cols_v1_3(self, cols: tuple[str, ...]) -> can.Message | None:
        # NUMBER) OFFSET BUS TYPE ID - LENGTH DATA...
        if cols[3] == "Error":
            return self._error_frame(cols[1], int(cols[2]))
        if cols[3] == "Warng":
            return self._status(cols, 7, cols[1], int(cols[2]))
        return super()._parse_cols_v1_3(cols)

    def _parse_msg_v2_x(self, cols: tuple[str, ...]) -> can.Message | None:
        message = super()._parse_msg_v2_x(cols)
        if message is not None and not message.is_remote_frame:
            check_data_bytes(message.data, dlc2len(message.dlc))
        return message

    def _parse_cols_v2_x(self, cols: tuple[str, ...]) -> can.Message | None:
        kind = cols[self.columns["T"]]
        if kind in ("ER", "ST"):
            bus = self.columns.get("B")
            channel = int(cols[bus]) if bus is not None else 1
            if kind == "ST":  # its four status bytes end the line
                words = len(" ".join(cols).split())
                return self._status(cols, words - 4, cols[self.columns["O"]], channel)
            return self._error_frame(cols[self.columns["O"]], channel)
        return super()._parse_cols_v2_x(cols)
