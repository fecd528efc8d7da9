"""What to do about a CAN bus that cannot be opened or read, by the OS's error number.

One wording for the service (``daq``: ``[bus] channel``) and the simulator bridge
(``sim_bridge``: ``--channel``), which opens its bus through python-can too and may not
import the service. python-can gives the number as ``errno`` (an ``OSError``) or as
``error_code`` (its ``CanOperationError``).
"""

import errno

_NO_INTERFACE = (
    "no such CAN interface; check {channel_option} and `ip link show {channel}` (a virtual "
    "one: sudo ip link add dev {channel} type vcan && sudo ip link set {channel} up)"
)
_NO_SOCKETCAN = (
    "this kernel has no SocketCAN: load it (sudo modprobe can-raw; vcan too for a virtual bus), "
    "or set {interface_option} to another python-can interface"
)
_NOT_PERMITTED = "not permitted; run as a user allowed to open CAN sockets"
_HINTS = {
    errno.ENETDOWN: "the CAN interface is down; bring it up: ip link set {channel} up",
    errno.ENODEV: _NO_INTERFACE,
    errno.ENXIO: _NO_INTERFACE,
    errno.EPERM: _NOT_PERMITTED,
    errno.EACCES: _NOT_PERMITTED,
    # A kernel without CAN (a laptop's, a container's): retrying will not bring it.
    errno.EAFNOSUPPORT: _NO_SOCKETCAN,
    errno.EPROTONOSUPPORT: _NO_SOCKETCAN,
}


def error_code(exc: BaseException) -> int | None:
    """The OS error number of ``exc``, from python-can's ``error_code`` or ``errno``."""
    code = getattr(exc, "error_code", None) or getattr(exc, "errno", None)
    return code if isinstance(code, int) else None


def bus_hint(
    exc: BaseException,
    channel: str,
    *,
    channel_option: str = "[bus] channel",
    interface_option: str = "[bus] interface",
) -> str:
    """What to do about ``exc`` on ``channel``, naming where the channel and the interface
    are set; ``""`` when its error number says nothing to act on.

    >>> bus_hint(OSError(errno.EAFNOSUPPORT, "Address family not supported"), "vcan0",
    ...          interface_option="--interface")  # doctest: +ELLIPSIS
    'this kernel has no SocketCAN: ..., or set --interface to another python-can interface'
    """
    code = error_code(exc)
    hint = _HINTS.get(code, "") if code is not None else ""
    return hint.format(
        channel=channel, channel_option=channel_option, interface_option=interface_option
    )
