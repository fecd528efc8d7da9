"""Vector ``.blf`` logs: python-can's reader, made to account for the error objects of
a log as python-can's ASC reader does for their lines.

python-can's :class:`can.BLFReader` reads CAN messages (classic, FD) and the extended
error frame (``CAN_ERROR_EXT``), and passes over every other object without a word.
:class:`BlfReader` also reads, as an error frame of its channel (counted by the
pipeline as ``error_frame``, as live):

- ``CAN_ERROR`` (type 2): the error frame of older CANalyzers and CANoes;
- ``CAN_FD_ERROR_64`` (type 104): the error frame of a CAN FD channel, which CANoe
  writes for every error on an FD bus;
- ``CAN_DRIVER_ERROR`` and ``CAN_DRIVER_ERROR_EXT`` (types 31, 74): the controller's
  driver reporting an error state (its error counters: warning, passive, bus-off), as an
  ASC log's ``Status:`` line; tallied in :attr:`BlfReader.controller_events`.

Everything else (statistics, markers, texts, overload frames, ...) is no frame and is
passed over as python-can does. The objects between those are still parsed by
python-can, a container's run at a time; only the objects' headers are walked here, and
only in a container that holds an error object's header (a search in C).
"""

import re
from collections import Counter
from collections.abc import Iterator
from typing import Any

import can
from can.io.blf import (
    OBJ_HEADER_BASE_STRUCT,
    OBJ_HEADER_V1_STRUCT,
    OBJ_HEADER_V2_STRUCT,
    TIME_ONE_NANS_FACTOR,
    TIME_TEN_MICS,
    TIME_TEN_MICS_FACTOR,
)

#: The error objects read, by BLF object type: their name, and whether the controller's
#: driver reports a state (tallied) rather than an error frame seen on the bus.
ERROR_OBJECTS = {
    2: ("CAN_ERROR", False),
    31: ("CAN_DRIVER_ERROR", True),
    74: ("CAN_DRIVER_ERROR_EXT", True),
    104: ("CAN_FD_ERROR_64", False),
}
#: The header of an error object (signature, header size, version 1 or 2, object size,
#: type): a container without one is python-can's alone.
_ERROR_HEADER = re.compile(
    b"LOBJ..[\x01\x02]\x00....[" + bytes(ERROR_OBJECTS) + b"]\x00\x00\x00", re.DOTALL
)
#: The channel's size in each (a WORD, or a BYTE in CAN_FD_ERROR_64).
_CHANNEL_BYTES = {2: 2, 31: 2, 74: 2, 104: 1}


class BlfReader(can.BLFReader):
    """python-can's BLF reader that also reads the error objects (see the module
    docstring)."""

    def __init__(self, file: Any, **kwargs: Any) -> None:
        super().__init__(file, **kwargs)
        #: The driver's error reports read, by (channel as python-can names it, state).
        self.controller_events: Counter[tuple[str, str]] = Counter()

    def _parse_data(self, data: bytes) -> Iterator[can.Message]:
        """python-can's parsing of ``data`` (a container's objects) between the error
        objects, which are read here; ``self._pos`` ends where python-can's would (the
        start of an object that continues in the next container)."""
        if _ERROR_HEADER.search(data) is None:  # the common case, found in C: python-can's
            yield from super()._parse_data(data)
            return
        run_start = pos = 0
        while True:
            start = data.find(b"LOBJ", pos, pos + 8)  # after the padding python-can skips
            if start < 0 or start + OBJ_HEADER_BASE_STRUCT.size > len(data):
                break  # the end, or what python-can stops at (a damaged object: it raises)
            _, header_size, version, obj_size, obj_type = OBJ_HEADER_BASE_STRUCT.unpack_from(
                data, start
            )
            if start + obj_size > len(data) or obj_size < header_size:
                break  # continues in the next container
            if obj_type in ERROR_OBJECTS and version in (1, 2):
                yield from self._python_cans(data, run_start, start)
                yield self._error_object(data, start, header_size, version, obj_type)
                run_start = start + obj_size
            pos = start + obj_size
        yield from self._python_cans(data, run_start, len(data))
        self._pos += run_start

    def _python_cans(self, data: bytes, start: int, end: int) -> Iterator[can.Message]:
        """python-can's messages of ``data[start:end]``."""
        self._pos = 0
        if start < end:
            yield from super()._parse_data(data[start:end])

    def _error_object(
        self, data: bytes, start: int, header_size: int, version: int, obj_type: int
    ) -> can.Message:
        header = OBJ_HEADER_V1_STRUCT if version == 1 else OBJ_HEADER_V2_STRUCT
        flags, _, _, ticks = header.unpack_from(data, start + OBJ_HEADER_BASE_STRUCT.size)
        factor = TIME_TEN_MICS_FACTOR if flags == TIME_TEN_MICS else TIME_ONE_NANS_FACTOR
        body = start + header_size
        channel = int.from_bytes(data[body : body + _CHANNEL_BYTES[obj_type]], "little") - 1
        name, state = ERROR_OBJECTS[obj_type]
        if state:
            self.controller_events[str(channel), f"driver error ({name})"] += 1
        return can.Message(
            timestamp=float(ticks * factor) + self.start_timestamp,
            is_error_frame=True,
            channel=channel,
        )
