"""Frames built with cantools from the DBC decode back; bad frames are flagged or refused."""

import numpy as np
import pytest
from cantools.database.can import Database, Message, Signal
from hypothesis import given
from hypothesis import strategies as st

from dbc.decoding import FrameDecoder, ReceiveFilter
from dbc.encoding import EncodedFrame, FrameEncoder
from dbc.errors import (
    FdFrameError,
    FrameError,
    FrameLengthError,
    SignalDecodeError,
    UnknownFrameError,
)
from dbc.protection import CounterCheck, crc8_sae_j1850
from dbc.samples import LegSampler
from estimator import foot_force_N
from tests.helpers import LEGS, example_machine

CONFIG, DATABASE = example_machine()


def leg_signals(leg: str, p_piston_Pa: float, p_rod_Pa: float, status: str = "ok") -> dict:
    return {f"{leg}_pPiston": p_piston_Pa, f"{leg}_pRod": p_rod_Pa, f"{leg}_Status": status}


def test_crc8_sae_j1850_check_value() -> None:
    assert crc8_sae_j1850(b"123456789") == 0x4B
    assert crc8_sae_j1850(b"") == 0x00  # init 0xFF, xorout 0xFF


def test_cantools_frame_decodes_to_the_pressures_put_in() -> None:
    decoder = FrameDecoder(DATABASE, CONFIG.protection)
    for i, leg in enumerate(LEGS):
        message = DATABASE.get_message_by_name(f"LEG_{leg}")
        p_piston, p_rod = 12_345_000.0 + i * 1000, 987_000.0 + i * 2000
        values = {**leg_signals(leg, p_piston, p_rod), f"{leg}_Counter": 7, f"{leg}_CRC": 0}
        data = bytearray(message.encode(values))
        data[7] = crc8_sae_j1850(bytes(data[:7]))
        frame = decoder.decode(message.frame_id, bytes(data), t_s=5.0)
        assert frame.message == f"LEG_{leg}"
        assert frame.signals[f"{leg}_pPiston"] == p_piston
        assert frame.signals[f"{leg}_pRod"] == p_rod
        assert frame.signals[f"{leg}_Status"] == "ok"
        assert frame.crc_ok and frame.counter_ok
        samples = LegSampler(CONFIG.legs).samples(frame)
        assert samples is not None
        ((name, sample),) = samples
        assert (name, sample.p_piston_Pa, sample.p_rod_Pa, sample.t_s) == (
            leg,
            p_piston,
            p_rod,
            5.0,
        )


def test_layout_is_as_documented() -> None:
    # Piston 12.000 MPa -> raw (12e6 + 1e6) / 1000 = 13000 = 0x32C8, little endian.
    encoder = FrameEncoder(DATABASE, CONFIG.protection)
    frame = encoder.encode("LEG_SB1_F1", leg_signals("SB1_F1", 12e6, 1e6, "sensor_fault"))
    assert frame.arbitration_id == 0x100 and not frame.is_extended_id
    assert frame.data[0:2] == bytes([0xC8, 0x32])
    assert frame.data[2:4] == (2000).to_bytes(2, "little")
    assert frame.data[4] == (3 << 4) | 0  # status sensor_fault, counter 0
    assert frame.data[7] == crc8_sae_j1850(frame.data[:7])


@given(
    st.sampled_from(LEGS),
    st.floats(min_value=-1e6, max_value=64.535e6),
    st.floats(min_value=-1e6, max_value=64.535e6),
)
def test_quantization_adds_less_than_50_N_to_the_foot_force(
    leg: str, p_piston_Pa: float, p_rod_Pa: float
) -> None:
    decoder = FrameDecoder(DATABASE, CONFIG.protection)
    encoder = FrameEncoder(DATABASE, CONFIG.protection)
    frame = encoder.encode(f"LEG_{leg}", leg_signals(leg, p_piston_Pa, p_rod_Pa))
    decoded = decoder.decode(frame.arbitration_id, frame.data, 0.0)
    geometry = CONFIG.legs[leg].geometry
    exact = foot_force_N(p_piston_Pa, p_rod_Pa, geometry)
    quantized = foot_force_N(
        float(decoded.signals[f"{leg}_pPiston"]), float(decoded.signals[f"{leg}_pRod"]), geometry
    )
    # The DBC comment's bound: 500 Pa * (A_piston + A_rod) * ratio = 4.2 N.
    assert abs(quantized - exact) <= 4.3


def test_bad_crc_is_flagged_and_counter_not_trusted() -> None:
    decoder = FrameDecoder(DATABASE, CONFIG.protection)
    encoder = FrameEncoder(DATABASE, CONFIG.protection)
    signals = leg_signals("SB1_F2", 5e6, 1e6)
    first = encoder.encode("LEG_SB1_F2", signals)
    bad = encoder.encode("LEG_SB1_F2", signals, corrupt_crc=True)
    assert decoder.decode(first.arbitration_id, first.data, 0.0).crc_ok
    frame = decoder.decode(bad.arbitration_id, bad.data, 0.01)
    assert (frame.crc_ok, frame.counter_ok, frame.faults) == (False, True, ("crc",))
    # The next good frame resynchronises the counter check: not flagged, nothing lost.
    nxt = decoder.decode(*_id_data(encoder.encode("LEG_SB1_F2", signals)), 0.02)
    assert (nxt.faults, nxt.frames_lost) == ((), 0)


def _id_data(frame: EncodedFrame) -> tuple[int, bytes]:
    return frame.arbitration_id, frame.data


def test_flipped_payload_bit_fails_the_crc() -> None:
    decoder = FrameDecoder(DATABASE, CONFIG.protection)
    frame = FrameEncoder(DATABASE, CONFIG.protection).encode(
        "LEG_SB2_F1", leg_signals("SB2_F1", 5e6, 1e6)
    )
    data = bytearray(frame.data)
    data[1] ^= 0x04
    assert decoder.decode(frame.arbitration_id, bytes(data), 0.0).crc_ok is False


def test_frozen_counter_is_flagged() -> None:
    decoder = FrameDecoder(DATABASE, CONFIG.protection)
    encoder = FrameEncoder(DATABASE, CONFIG.protection)
    signals = leg_signals("SB1_F1", 5e6, 1e6)
    results = []
    for counter in (3, 4, 4, 4, 5):
        frame = encoder.encode("LEG_SB1_F1", signals, counter=counter)
        results.append(decoder.decode(frame.arbitration_id, frame.data, 0.0).faults)
    assert results == [(), (), ("counter_repeat",), ("counter_repeat",), ()]


def test_counter_wraps_and_reset_forgets() -> None:
    check = CounterCheck(16, max_delta=2)
    assert [check.update(c).fault for c in (14, 15, 0, 1)] == [None] * 4
    assert (check.update(9).fault, check.update(10).fault) == ("counter", None)
    check.reset()
    assert check.update(2).fault is None


def test_unknown_id_and_wrong_dlc_raise_frame_errors_with_kinds() -> None:
    decoder = FrameDecoder(DATABASE, CONFIG.protection)
    with pytest.raises(UnknownFrameError, match="0x7FF") as unknown:
        decoder.decode(0x7FF, bytes(8), 0.0)
    assert unknown.value.kind == "unknown_id"
    with pytest.raises(UnknownFrameError):
        decoder.decode(0x100, bytes(8), 0.0, is_extended_id=True)
    with pytest.raises(FrameLengthError, match="DLC 6, the DBC says 8") as short:
        decoder.decode(0x100, bytes(6), 0.0)
    assert short.value.kind == "wrong_dlc"
    with pytest.raises(FrameLengthError):
        decoder.decode(0x100, bytes(9), 0.0)
    assert issubclass(SignalDecodeError, FrameError)


@pytest.mark.parametrize("compiled", [True, False])
def test_fd_frames_decode_only_for_messages_the_dbc_defines_as_fd(compiled: bool) -> None:
    def message(frame_id: int, name: str, length: int, is_fd: bool) -> Message:
        signal = Signal(f"{name}_value", start=8 * (length - 2), length=16)
        return Message(frame_id, name, length, [signal], is_fd=is_fd)

    database = Database([message(0x200, "FD", 12, True), message(0x201, "CLASSIC", 2, False)])
    decoder = FrameDecoder(database, {}, compiled=compiled)
    data = bytes(10) + (0x1234).to_bytes(2, "little")
    assert decoder.decode(0x200, data, 1.0, is_fd=True).signals == {"FD_value": 0x1234}
    with pytest.raises(FdFrameError, match="0x201") as classic:
        decoder.decode(0x201, b"\x01\x02", 1.0, is_fd=True)
    assert classic.value.kind == "fd_frame"
    with pytest.raises(FdFrameError):  # an FD frame of no message at all: fd_frame too
        decoder.decode(0x7AA, bytes(12), 1.0, is_fd=True)
    assert decoder.decode(0x201, b"\x01\x02", 1.0).signals == {"CLASSIC_value": 0x0201}


def test_status_outside_value_table_reaches_the_estimator_as_a_number() -> None:
    decoder = FrameDecoder(DATABASE, CONFIG.protection)
    data = bytearray(
        FrameEncoder(DATABASE, CONFIG.protection)
        .encode("LEG_SB1_F1", leg_signals("SB1_F1", 5e6, 1e6))
        .data
    )
    data[4] = (9 << 4) | (data[4] & 0x0F)
    crc = CONFIG.protection["LEG_SB1_F1"].crc_check(DATABASE.get_message_by_name("LEG_SB1_F1"))
    assert crc is not None
    crc.write(data)
    frame = decoder.decode(0x100, bytes(data), 0.0)
    samples = LegSampler(CONFIG.legs).samples(frame)
    assert samples is not None
    ((_, sample),) = samples
    assert sample.faults == ("status_9",)


def test_non_leg_messages_decode_without_leg_samples() -> None:
    decoder = FrameDecoder(DATABASE, CONFIG.protection)
    frame = FrameEncoder(DATABASE, CONFIG.protection).encode(
        "MACHINE_STATE",
        {"Machine_Phase": "fold", "Machine_CycleCount": 3, "Machine_CycleTime": 12.5},
    )
    decoded = decoder.decode(frame.arbitration_id, frame.data, 1.0)
    assert decoded.signals["Machine_Phase"] == "fold"
    assert decoded.signals["Machine_CycleTime"] == pytest.approx(12.5)
    assert LegSampler(CONFIG.legs).samples(decoded) == []


def test_every_message_has_cycle_time_units_and_ranges() -> None:
    for message in DATABASE.messages:
        assert message.cycle_time and message.cycle_time > 0, message.name
        assert message.length == 8
        for signal in message.signals:
            assert signal.minimum is not None and signal.maximum is not None, signal.name
            if signal.name.endswith(("pPiston", "pRod")):
                assert signal.unit == "Pa"
                assert signal.scale == 1000  # 0.01 bar
    statuses = DATABASE.get_message_by_name("LEG_SB1_F1").get_signal_by_name("SB1_F1_Status")
    assert {str(v) for v in statuses.choices.values()} == {
        "ok",
        "over_range",
        "under_range",
        "sensor_fault",
    }
    phase = DATABASE.get_message_by_name("MACHINE_STATE").get_signal_by_name("Machine_Phase")
    assert [str(v) for v in phase.choices.values()] == [
        "idle",
        "move_carriage",
        "fold",
        "rotate",
        "unfold",
    ]


def test_receive_filters_pass_the_dbc_ids_exactly() -> None:
    filters = FrameDecoder(DATABASE, CONFIG.protection).receive_filters
    assert (0x100, 0x7FF, False) in filters and (0x130, 0x7FF, False) in filters
    assert len(filters) == len(DATABASE.messages)
    assert np.all(np.diff([f.can_id for f in filters]) > 0)


def _passes(filters: list[ReceiveFilter], frame_id: int, extended: bool) -> bool:
    return any(
        f.extended == extended and frame_id & f.can_mask == f.can_id & f.can_mask for f in filters
    )


def test_receive_filters_pass_a_j1939_pgn_from_any_priority_and_source() -> None:
    from tests.dbc.test_transducers import DATABASE as TRANSDUCERS

    filters = FrameDecoder(TRANSDUCERS, {}).receive_filters
    assert ReceiveFilter(0xFF2000, 0x3FFFF00, True) in filters
    for frame_id in (0x18FF2021, 0x0CFF2099, 0x1CFF20FE):  # priorities 6, 3, 7
        assert _passes(filters, frame_id, True)
    for frame_id in (0x18FF2121, 0x18FE2021, 0x19FF2021):  # other PS, PF, data page
        assert not _passes(filters, frame_id, True)
    assert not _passes(filters, 0x100 | 0x18FF0000, True) and _passes(filters, 0x100, False)
