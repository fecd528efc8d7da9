"""Vector ``.blf`` logs with error objects python-can passes over: ``CAN_ERROR`` (older
CANalyzers), ``CAN_FD_ERROR_64`` (every error frame of a CAN FD channel) and the
driver's error reports (``CAN_DRIVER_ERROR``): read as error frames of their channel and
counted; python-can left them out without a word."""

import io
import struct
from pathlib import Path

import can
import pytest

from daq.replay import can_log_frames, replay
from tests.helpers import EXAMPLE_CONFIG

START_S = 1_796_211_064.0
#: The error objects, by BLF object type: their data (channel 1, the rest zeros but
#: CAN_DRIVER_ERROR's counters: TxErr 132, RxErr 0).
ERRORS = {
    2: struct.pack("<HH4x", 1, 0),
    104: bytes([1]) + bytes(87),
    31: struct.pack("<HBBL", 1, 132, 0, 0),
}
#: A statistic (CAN_STATISTIC, type 4): no frame, passed over.
STATISTIC = (4, struct.pack("<H2xLLLLLLL4x", 1, 0, 100, 0, 0, 0, 0, 0))


def _frame(k: int) -> can.Message:
    return can.Message(
        timestamp=START_S + k / 1000,
        arbitration_id=0x7FF,  # no frame of the DBC: each counted, none an estimate
        is_extended_id=False,
        data=bytes.fromhex("461208070000001C"),
        channel=0,
    )


def _write(path: Path, frames: int, every: int) -> list[tuple[float, bool]]:
    """A BLF of ``frames`` frames (of several containers) with an error object of each
    kind in turn and a statistic after every ``every``-th; (time, error) of what a reader
    should give."""
    expected: list[tuple[float, bool]] = []
    kinds = list(ERRORS)
    with can.BLFWriter(path) as writer:
        for k in range(frames):
            writer.on_message_received(_frame(k))
            expected.append((START_S + k / 1000, False))
            if k % every == every - 1:
                kind = kinds[(k // every) % len(kinds)]
                t_s = START_S + k / 1000 + 0.0005
                writer._add_object(kind, ERRORS[kind], t_s)
                writer._add_object(*STATISTIC, t_s)
                expected.append((t_s, True))
    return expected


def test_error_objects_are_error_frames_in_order_across_containers(tmp_path: Path) -> None:
    log = tmp_path / "fd_bus.blf"
    expected = _write(log, frames=9000, every=997)  # ~430 KB: four containers
    frames = list(can_log_frames(log))
    assert [(f.is_error_frame, f.t_s) for f in frames] == [
        (error, pytest.approx(t_s, abs=2e-6)) for t_s, error in expected
    ]
    assert sum(error for _, error in expected) == 9
    assert {f.arbitration_id for f in frames if not f.is_error_frame} == {0x7FF}


def test_error_objects_are_counted_and_the_drivers_named(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    log = tmp_path / "fd_bus.blf"
    _write(log, frames=40, every=10)
    replay(log, io.StringIO(), EXAMPLE_CONFIG)
    assert "44 frames, 44 of them not used (error_frame 4, unknown_id 40)" in caplog.text
    assert (
        f"{log}: the CAN controller reported driver error (CAN_DRIVER_ERROR) 1: each counted"
        in caplog.text
    )
