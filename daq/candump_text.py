"""candump's readable output as a CAN log: what ``candump -ta can0 > trace.log`` writes.

python-can reads the ``candump -L`` (``-l``) line, ``(TIME) INTERFACE ID#DATA``; candump
prints frames for people otherwise, and that is what an integrator redirects to a file::

     (1733100000.123456)  can0  100   [8]  46 12 08 07 00 00 00 1C
     (1733100000.123456)  can0  18FF2021   [8]  08 07 00 00 00 00 00 00   '........'
     (2024-12-02 05:44:01.908000)  can0  RX - -  100   [8]  46 12 08 07 00 00 00 1C

:func:`dash_l_line` turns such a line (times ``-ta``, ``-tz``, ``-tA``, also ``-N``'s
nanoseconds; ``-a``'s ASCII column, ``-x``'s direction and ``-c``'s colours ignored;
``-8``'s raw DLC ``{9}`` a classic frame's 8 bytes) into the ``-L`` line python-can
parses; a CAN FD frame, whose length candump prints in two digits (``[08]``), stays one
(with ``-x``'s BRS and ESI flags), as its ``-L`` line ``100##1...`` is. An ``-L`` line
passes as it is, unless its data has an odd number of hex digits (python-can dropped
the last one: ``1C`` cut to ``1`` read as 0x01); :class:`CandumpReader` drops its raw
DLC (``100#1122334455667788_9``: 8 bytes). A line without a time (plain
``candump can0``) cannot be replayed (every rule of the estimator judges frame times):
ValueError saying which option writes one; so do ``-td``'s steps between frames,
which :class:`CandumpReader` tells by times going backwards from a time before 2000 (a
step is no date). A dated time going back is the clock's step (NTP; ``-tA``'s local
time when daylight saving ends), kept as in a ``-L`` log: the estimator's time rules
take it.

>>> dash_l_line(" (1733100000.123456)  can0  100   [8]  46 12 08 07 00 00 00 1C  '........'")
'(1733100000.123456) can0 100#461208070000001C\\n'
>>> dash_l_line("(000.000000)  can1  18FF2021   [0]  remote request")
'(000.000000) can1 18FF2021#R0\\n'
"""

import re
from collections import Counter
from collections.abc import Generator, Iterator
from datetime import datetime
from typing import Any, TextIO, cast

import can
from can.io.canutils import CAN_ERR_BUSERROR, CAN_ERR_FLAG

from daq.frames import DATED_FROM_S, ERROR_CLASSES

#: A readable candump line: time, interface, ``-x``'s direction and CAN FD flag columns
#: (``RX B E``: bit rate switch, error state indicator), ID, length (``[8]`` classic,
#: ``[08]`` CAN FD, ``-8``'s ``{F}`` a classic frame's raw DLC), rest.
_READABLE = re.compile(
    r"\s*\((?P<time>[^)]*)\)\s+(?P<interface>\S+)\s+"
    r"(?:[RT]X\s+(?P<brs>\S+)\s+(?P<esi>\S+)\s+)?(?P<id>[0-9A-Fa-f]{3}|[0-9A-Fa-f]{8})\s+"
    r"(?:\[(?P<length>\d)\]|\[(?P<fd_length>\d\d)\]|\{(?P<dlc>[0-9A-Fa-f])\})\s*(?P<rest>.*)"
)
#: ``-c``'s colours (ANSI escape sequences) around the interface name.
_COLOUR = re.compile(r"\x1b\[[0-9;]*m")
#: The data of an ``-L`` line (after ``#``, or ``##`` and the FD flags), up to its end
#: or `` R`` / `` T`` (``-x``'s direction).
_DASH_L_DATA = re.compile(r"[^#]*#(?:#[0-9A-Fa-f])?(?P<data>[0-9A-Fa-f]*)(?:\s|$)")
#: The same without a time (plain ``candump can0``).
_WITHOUT_TIME = re.compile(
    r"\s*\S+\s+(?:[RT]X\s+\S+\s+\S+\s+)?[0-9A-Fa-f]{3,8}\s+(?:\[\d{1,2}\]|\{[0-9A-Fa-f]\})"
)
#: An ``-L`` line of a classic frame of 8 bytes whose DLC on the bus was 9 to F: candump
#: writes it after the data (``100#1122334455667788_9``) when the interface reports such
#: DLCs (``ip link set can0 type can cc-len8-dlc on``).
_DASH_L_RAW_DLC = re.compile(
    r"(?P<head>[^#]*#[0-9A-Fa-f]{16})_[0-9A-Fa-f](?P<tail>\s.*|)$", re.DOTALL
)
#: ``-tA``'s local date and time (to the second; then 6 digits, or ``-N``'s 9).
_DATE_FORMAT = "%Y-%m-%d %H:%M:%S"
#: The flags of an ``-L`` CAN FD line (``ID##F...``): bit rate switch, error state indicator.
_FD_FLAGS = {"brs": 0x1, "esi": 0x2}
#: The most data a classic CAN frame carries; a longer one is a CAN FD frame.
_CLASSIC_MAX_BYTES = 8

_NEEDS_TIME = "candump -L (or -ta) writes the frame times a replay needs"

#: What ``candump -d`` writes, into its log and its readable output, when the kernel
#: dropped frames before candump read them (the socket's receive buffer was full).
_DROPCOUNT = re.compile(r"\s*DROPCOUNT: dropped (?P<frames>\d+) CAN frames? on ")
#: ``candump -e``'s description of an error frame, on tab-indented lines after it
#: (``\tcontroller-problem{rx-error-warning}``, ``\terror-counter-tx-rx{{0}{96}}``).
_ERROR_DETAIL = re.compile(r"\t[a-z][a-z-]*(?:[{,]|\s*$)")
#: A ``-L`` line of an error frame: its ID has CAN_ERR_FLAG (bit 29), which no data
#: frame's 29-bit ID has, and the class bits (bus-off 0x040, controller 0x004, ...).
_ERROR_ID = re.compile(r"(?P<head>\s*\(\S+\)\s+\S+\s+)(?P<id>[2-9A-Fa-f][0-9A-Fa-f]{7})#")


def dash_l_line(line: str) -> str:
    """``line`` as a ``candump -L`` line (unchanged if it is one, or blank)."""
    if "\x1b" in line:
        line = _COLOUR.sub("", line)
    match = _READABLE.match(line)
    if match is None:
        if "#" not in line and _WITHOUT_TIME.match(line):
            raise ValueError(f"a candump line without a time: {_NEEDS_TIME}")
        dash_l = _DASH_L_DATA.match(line)
        if dash_l is not None and len(dash_l["data"]) % 2:
            raise ValueError(f"an odd number of hex digits in its data: {line.strip()!r}")
        return line  # a -L line, or python-can's word on it
    time = match["time"]
    if "-" in time:  # -tA: local date and time
        date, _, fraction = time.strip().rpartition(".")
        time = f"{datetime.strptime(date, _DATE_FORMAT).timestamp():.0f}.{fraction}"
    fd_length = match["fd_length"]
    if match["dlc"] is not None:  # -8: a classic frame's DLC, 9 to F meaning 8 bytes
        length = min(int(match["dlc"], 16), _CLASSIC_MAX_BYTES)
    else:
        length = int(fd_length or match["length"])
    rest = match["rest"]
    if rest.startswith("remote request"):
        data = f"R{length}"
    else:
        octets = rest.split()[:length]
        if len(octets) != length or not all(re.fullmatch("[0-9A-Fa-f]{2}", o) for o in octets):
            raise ValueError(f"[{length}] and its data bytes differ: {line.strip()!r}")
        data = "".join(octets)
        if fd_length is not None:
            flags = sum(bit for name, bit in _FD_FLAGS.items() if match[name] not in (None, "-"))
            data = f"#{flags:X}{data}"
    return f"({time}) {match['interface']} {match['id']}#{data}\n"


class CandumpReader(can.CanutilsLogReader):
    """python-can's candump reader that also reads candump's readable lines
    (:func:`dash_l_line`); frame times going backwards in those from a time that is no
    date are ``-td``'s steps. ``candump -d``'s ``DROPCOUNT`` lines (python-can stopped
    at them) are summed in :attr:`dropped_frames`. An error frame of any class is an
    error frame: python-can read only the bus-error class (0x080) as one, any other
    (bus-off, controller problems, ...) as a data frame of the class's 29-bit ID; its
    classes are tallied in :attr:`controller_events`, and it keeps its interface
    (python-can gave it no channel, so it was kept whatever channel was replayed); the
    lines ``candump -e`` describes it in are left out (python-can stopped at them)."""

    def __init__(self, file: Any, **kwargs: Any) -> None:
        super().__init__(file, **kwargs)
        #: Frames the kernel dropped before candump read them, as its ``DROPCOUNT``
        #: lines read so far say.
        self.dropped_frames = 0
        #: The error frames read, by (interface, class: bus off, controller problems, ...).
        self.controller_events: Counter[tuple[str, str]] = Counter()
        self._error_interface = ""

    def __iter__(self) -> Generator[can.Message, None, None]:
        original = self.file
        self.file = cast(TextIO, self._dash_l_lines(original))
        try:
            for message in super().__iter__():
                if message.is_error_frame:  # python-can gives it no channel: its line's
                    message.channel = self._error_interface
                yield message
        finally:
            self.file = original

    def _dash_l_lines(self, lines: Any) -> Iterator[str]:
        latest_s = None
        for line in lines:
            dropped = _DROPCOUNT.match(line)
            if dropped is not None:
                self.dropped_frames += int(dropped["frames"])
                continue
            if _ERROR_DETAIL.match(line):  # the error frame's line before says it all
                continue
            raw_dlc = _DASH_L_RAW_DLC.match(line)
            if raw_dlc is not None:  # python-can stopped at it: a classic frame's 8 bytes
                line = raw_dlc["head"] + raw_dlc["tail"]
            converted = dash_l_line(line)
            if converted is not line:  # a readable line: undated times must not go back
                t_s = float(converted[1 : converted.index(")")])
                if latest_s is not None and t_s < latest_s < DATED_FROM_S:
                    raise ValueError(
                        f"frame times go backwards ({latest_s:.6f} then {t_s:.6f}): "
                        f"candump -td's steps between frames? {_NEEDS_TIME}"
                    )
                latest_s = t_s
            error = _ERROR_ID.match(converted)
            if error is not None and int(error["id"], 16) & CAN_ERR_FLAG:
                # python-can keeps neither the class nor the data of an error frame
                error_class = int(error["id"], 16) & ~CAN_ERR_FLAG
                self._error_interface = error["head"].split()[1]
                for state in [name for bit, name in ERROR_CLASSES.items() if error_class & bit]:
                    self.controller_events[self._error_interface, state] += 1
                error_id = int(error["id"], 16) | CAN_ERR_BUSERROR
                converted = f"{error['head']}{error_id:08X}{converted[error.end() - 1 :]}"
            yield converted
