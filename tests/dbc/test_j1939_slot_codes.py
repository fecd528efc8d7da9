"""J1939 "error" and "not available" codes where the DBC declares no range
(tests/files/stranger/j1939_slots: ``[0|0]``, as cantools and many tools write it).

J1939-71 reserves the top of a parameter's raw range: of 1, 2 and 4 bytes, values
above 0xFA, 0xFAFF, 0xFAFFFFFF are indicators (0xFB.. parameter specific, 0xFE.. error,
0xFF.. not available), never a measurement. A transducer sends 0xFFFF when it has no
value; at 0.05 kPa/bit that is 3.28 MPa, a plausible chamber pressure."""

import math

import pytest

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from dbc.machine import load_machine_config
from tests.dbc.test_held_out_machines import STRANGER, eq4_N

#: (leg, piston and rod source addresses, byte offset, length, Pa per bit)
LEGS = [
    ("two-bytes", 0x30, 0x31, 0, 2, 50.0),
    ("four-bytes", 0x32, 0x33, 2, 4, 1.0),
    ("one-byte", 0x34, 0x35, 6, 1, 1e5),
]


def xdcr(t_s: float, source: int, offset: int, length: int, raw: int) -> RawFrame:
    """An XDCR frame (PGN 0xFF50) of one transducer: its own pressure, the others'
    bytes 0xFF (not available) as a transducer that measures one pressure sends them."""
    data = bytearray(b"\xff" * 8)
    data[offset : offset + length] = raw.to_bytes(length, "little")
    return RawFrame(t_s, 0x18FF5000 | source, True, bytes(data))


def pose(t_s: float, rot_raw: int, fold_raw: int) -> RawFrame:
    data = rot_raw.to_bytes(2, "little") + fold_raw.to_bytes(2, "little") + b"\xff" * 4
    return RawFrame(t_s, 0x18FF6080, True, data)


def _pipeline() -> Pipeline:
    return Pipeline.from_config(*load_machine_config(STRANGER / "j1939_slots.toml"))


@pytest.mark.parametrize(("leg", "piston_sa", "rod_sa", "offset", "length", "pa_per_bit"), LEGS)
def test_a_j1939_indicator_code_is_no_pressure_without_a_range_in_the_dbc(
    leg: str, piston_sa: int, rod_sa: int, offset: int, length: int, pa_per_bit: float
) -> None:
    """0xFB.., 0xFE.. and 0xFF.. of the pressure's length: the chamber is NaN and the
    sample invalid (``range``); the largest valid code, 0xFA.., is a pressure."""
    pipeline = _pipeline()
    step = 1 << (8 * length - 8)  # of the top byte
    rod_raw = round(0.8e6 / pa_per_bit)
    # A pressure; not available (0xFF..FF), error (0xFE00..), parameter specific (0xFB00..);
    # the largest valid value (0xFA, 0xFAFF, 0xFAFFFFFF).
    codes = [round(2.8e6 / pa_per_bit), 0x100 * step - 1, 0xFE * step, 0xFB * step, 0xFB * step - 1]
    estimates = []
    for i, code in enumerate(codes):
        t_s = 1.0 + 0.01 * i
        pipeline.process(xdcr(t_s, rod_sa, offset, length, rod_raw))
        (estimate,) = pipeline.process(xdcr(t_s + 0.001, piston_sa, offset, length, code)).estimates
        estimates.append(estimate)
    assert [e.leg for e in estimates] == [leg] * 5
    assert estimates[0].valid
    assert estimates[0].force_raw_N == pytest.approx(eq4_N(2.8e6, 0.8e6), rel=1e-9)
    for estimate in estimates[1:4]:
        assert math.isnan(estimate.p_piston_Pa) and estimate.reasons == ("range",)
        assert estimate.p_rod_Pa == pytest.approx(0.8e6)
    assert estimates[4].p_piston_Pa == pytest.approx(codes[4] * pa_per_bit)


def test_a_j1939_indicator_code_of_a_bridge_angle_makes_the_pose_unknown() -> None:
    """Fold 0xFFFF at 0.01 deg/bit, -100 deg offset, was a fold of 555.35 deg: the
    stability margin was computed from it. Now the pose is unknown (margin undefined)
    until a frame brings an angle again; the old angle is not kept."""
    pipeline = _pipeline()
    t_s = 1.0

    def step(rot_raw: int, fold_raw: int) -> bool:
        """Send a pose and every chamber; True when the snapshot has a margin."""
        nonlocal t_s
        pipeline.process(pose(t_s, rot_raw, fold_raw))
        for _, piston_sa, rod_sa, offset, length, pa_per_bit in LEGS:
            pipeline.process(xdcr(t_s, rod_sa, offset, length, round(0.8e6 / pa_per_bit)))
            pipeline.process(xdcr(t_s, piston_sa, offset, length, round(2.8e6 / pa_per_bit)))
        pipeline.process(xdcr(t_s, 0x37, 0, 2, 0))  # the rear foot in the air
        pipeline.process(xdcr(t_s, 0x36, 0, 2, 0))
        snapshot = pipeline.snapshot(t_s)
        assert all(leg.valid for leg in snapshot.legs.values()), snapshot.legs
        t_s += 0.01
        return snapshot.stability is not None

    folded_0_deg = 100 * 100
    assert step(0, folded_0_deg)
    assert not step(0, 0xFFFF)
    assert not step(0xFE00, folded_0_deg)
    assert step(0xFAFF, 0xFAFF - 1)  # 642.55 deg: J1939 allows it, the DBC bounds nothing
