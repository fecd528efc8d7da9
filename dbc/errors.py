"""The one exception tree of portal-daq, rooted here in the CAN interface layer.

Every error the project raises on purpose derives from :class:`PortalDaqError`,
so a caller can catch them all at once, and each formats its own message naming
the object and value at fault. The CAN layer (this package) defines the root and
what reading a configuration, a DBC or a frame can raise; the service adds its
own branches in :mod:`daq.errors`::

    PortalDaqError
    ├── ConfigError        a machine/service configuration is unusable (fatal at start)
    ├── DbcError           the CAN database cannot be loaded or lacks what is needed (fatal)
    ├── FrameError         one received frame cannot be used (counted, never fatal)
    │   ├── UnknownFrameError   its ID is not in the DBC
    │   ├── FrameLengthError    its DLC differs from the DBC's length
    │   ├── SignalDecodeError   cantools could not decode it
    │   ├── FdFrameError        it is a CAN FD frame of a message the DBC does not define as FD
    │   ├── ErrorFrameError     it is a CAN error frame (bus fault report)
    │   └── RemoteFrameError    it is a remote (RTR) frame, which carries no data
    ├── BusError           (daq.errors) the CAN bus cannot be opened or read (retried)
    ├── ZenohError         (daq.errors) the Zenoh session cannot be opened (fatal at start)
    └── RecordingError     (daq.errors) an MCAP recording cannot be written or read

Configuration and DBC errors are also ``ValueError`` so that generic callers
treating bad input as a value problem keep working.
"""

from pathlib import Path


class PortalDaqError(Exception):
    """Base of every error raised on purpose by portal-daq."""


class ConfigError(PortalDaqError, ValueError):
    """A configuration file is missing, malformed or inconsistent.

    The message names the file, the key (dotted TOML path) and the reason.
    """

    def __init__(self, source: str | Path, key: str, reason: str) -> None:
        self.source = str(source)
        self.key = key
        self.reason = reason
        where = f"{self.source}: {key}: " if key else f"{self.source}: "
        super().__init__(where + reason)


class DbcError(PortalDaqError, ValueError):
    """The CAN database (DBC) cannot be loaded or does not hold what is needed."""

    def __init__(self, source: str | Path, reason: str) -> None:
        self.source = str(source)
        self.reason = reason
        super().__init__(f"{self.source}: {reason}")


class FrameError(PortalDaqError):
    """A received CAN frame cannot be used; the service counts it and records it raw."""

    #: Short, stable name of the fault, used as a counter key on the status topic.
    kind = "bad_frame"

    def __init__(self, arbitration_id: int, reason: str) -> None:
        self.arbitration_id = arbitration_id
        self.reason = reason
        super().__init__(f"frame 0x{arbitration_id:03X}: {reason}")


class UnknownFrameError(FrameError):
    """The frame's ID is not defined in the DBC."""

    kind = "unknown_id"


class FrameLengthError(FrameError):
    """The frame's DLC differs from the length the DBC defines for its message."""

    kind = "wrong_dlc"


class SignalDecodeError(FrameError):
    """cantools could not decode the frame's payload."""

    kind = "decode_error"


class FdFrameError(FrameError):
    """A CAN FD frame whose ID the DBC does not define as an FD message."""

    kind = "fd_frame"


class ErrorFrameError(FrameError):
    """The frame is a CAN error frame: the controller reports a bus fault, no data."""

    kind = "error_frame"


class RemoteFrameError(FrameError):
    """The frame is a remote (RTR) frame: a request, no data to decode."""

    kind = "remote_frame"
