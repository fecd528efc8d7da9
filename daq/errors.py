"""The service's branches of the one exception tree (rooted in :mod:`dbc.errors`).

PortalDaqError (dbc.errors)
├── BusError           the CAN bus cannot be opened or read (retried, never fatal)
├── ZenohError         the Zenoh session cannot be opened (fatal at start)
└── RecordingError     an MCAP recording cannot be written or read
    └── EmptyRecordingError   it holds no CAN frame and no leg estimate: nothing to report
"""

from pathlib import Path

from dbc.errors import PortalDaqError


class BusError(PortalDaqError):
    """The CAN bus cannot be opened or read; the service retries and reports the state."""

    def __init__(self, channel: str, reason: str, hint: str = "") -> None:
        self.channel = channel
        self.reason = reason
        self.hint = hint
        super().__init__(f"CAN bus {channel!r}: {reason}" + (f" ({hint})" if hint else ""))


class ZenohError(PortalDaqError):
    """The Zenoh session cannot be opened with the configured endpoints."""

    def __init__(self, reason: str, hint: str = "") -> None:
        self.reason = reason
        self.hint = hint
        super().__init__(f"Zenoh: {reason}" + (f" ({hint})" if hint else ""))


class RecordingError(PortalDaqError):
    """An MCAP recording cannot be written (directory, disk) or read back."""

    def __init__(self, path: str | Path, reason: str) -> None:
        self.path = str(path)
        self.reason = reason
        super().__init__(f"{self.path}: {reason}")


class EmptyRecordingError(RecordingError):
    """A recording (or CAN log) that holds no CAN frame and no leg estimate, e.g. a file
    the recorder had just opened when the power went: nothing to report."""
