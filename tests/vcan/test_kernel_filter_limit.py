"""``[bus] kernel_filters = true`` with a DBC of more messages than SocketCAN takes
filters (512, ``CAN_RAW_FILTER_MAX``; a whole vehicle's DBC has that many): setting
them failed with EINVAL, so the bus never opened ("absent: Invalid argument", retried
for ever, no frame). Now the frames are filtered in the service, with one warning.

Run through ``tests/vcan/with-vcan`` (User-Mode Linux); no timing is asserted.
"""

import logging

import can
import pytest

from daq.runner import bus_factory
from daq.service_config import BusSettings
from dbc.decoding import ReceiveFilter

pytestmark = pytest.mark.vcan

SETTINGS = BusSettings(interface="socketcan", channel="vcan0", kernel_filters=True)


def _first_id(count: int) -> int:
    """The ID of the first frame the service's socket takes when ``count`` standard IDs
    from 1 are filtered and 0x7FF (not among them), then 0x001 are sent."""
    filters = [ReceiveFilter(frame_id, 0x7FF, False) for frame_id in range(1, count + 1)]
    with bus_factory(SETTINGS, filters)() as source, can.Bus("vcan0", interface="socketcan") as bus:
        bus.send(can.Message(arbitration_id=0x7FF, is_extended_id=False, data=b"\x01"))
        bus.send(can.Message(arbitration_id=0x001, is_extended_id=False, data=b"\x02"))
        frame = source.recv(5.0)
        assert frame is not None
        return frame.arbitration_id


def test_kernel_filters_up_to_socketcans_limit_are_set(caplog: pytest.LogCaptureFixture) -> None:
    assert _first_id(512) == 0x001  # 0x7FF dropped by the kernel
    assert "kernel filters" not in caplog.text


def test_more_kernel_filters_than_socketcan_takes_filter_in_the_service(
    caplog: pytest.LogCaptureFixture,
) -> None:
    with caplog.at_level(logging.WARNING, logger="daq.runner"):
        assert _first_id(600) == 0x7FF
    (line,) = [r.getMessage() for r in caplog.records if "kernel filters" in r.getMessage()]
    assert line == (
        "[bus] kernel_filters: the DBC needs 600 kernel filters, SocketCAN takes 512: "
        "frames are filtered in the service instead (other IDs counted as unknown_id)"
    )
