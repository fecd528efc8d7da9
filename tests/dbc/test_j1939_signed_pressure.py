"""A J1939 pressure a DBC declares signed (``@1-``): the transducer's J1939 indicator
codes are no pressure.

J1939 has no two's complement (its SLOTs give negative values by an offset), so a
transducer sends "not available" as 0xFFFF and "error" as 0xFE00.. whatever its DBC
says; read two's complement they were -0.01 and -5.12 bar at 0.01 bar/bit, the first a
valid gauge pressure near 0 for a transducer that had no value."""

import math
from pathlib import Path

import pytest

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from dbc.machine import load_machine_config
from tests.dbc.test_held_out_machines import eq4_N
from tests.helpers import LEG_DEFAULTS_TOML

DBC = """VERSION ""

NS_ :
	BA_DEF_
	BA_
	BA_DEF_DEF_

BS_:

BU_: Xdcr DAQ

BO_ 2566856737 XDCR_J1939: 8 Xdcr
 SG_ Pressure : 0|16@1- (0.01,0) [-327.68|327.67] "bar" DAQ

BO_ 512 XDCR_11BIT: 8 Xdcr
 SG_ Piston : 0|16@1- (0.01,0) [-327.68|327.67] "bar" DAQ
 SG_ Rod : 16|16@1- (0.01,0) [-327.68|327.67] "bar" DAQ

BA_DEF_ BO_ "GenMsgCycleTime" INT 0 65535;
BA_DEF_ BO_ "VFrameFormat" ENUM "StandardCAN","ExtendedCAN","reserved","J1939PG";
BA_DEF_DEF_ "GenMsgCycleTime" 10;
BA_DEF_DEF_ "VFrameFormat" "StandardCAN";
BA_ "VFrameFormat" BO_ 2566856737 3;
"""

CONFIG = (
    """[machine]
id = "signed"
mass_kg = 3000.0
dbc = "signed.dbc"

[sensors]
# Room below 0 for the test: the two's complement values beyond J1939's codes.
pressure_min_Pa = -2.0e6

"""
    + LEG_DEFAULTS_TOML
    + """
[legs.J1939]
piston = { signal = "XDCR_J1939.Pressure", source_address = 0x21 }
rod = { signal = "XDCR_J1939.Pressure", source_address = 0x22 }
max_skew_s = 0.015

[legs.PLAIN]
piston = "XDCR_11BIT.Piston"
rod = "XDCR_11BIT.Rod"
"""
)

ROD_RAW = 3000  # 30 bar


@pytest.fixture
def pipeline(tmp_path: Path) -> Pipeline:
    (tmp_path / "signed.dbc").write_text(DBC)
    (tmp_path / "machine.toml").write_text(CONFIG)
    return Pipeline.from_config(*load_machine_config(tmp_path / "machine.toml"))


def _int16(raw: int) -> bytes:
    return (raw & 0xFFFF).to_bytes(2, "little")


@pytest.mark.parametrize(
    ("raw", "bar"),
    [
        (0xFFFF, None),  # not available
        (0xFF00, None),  # not available
        (0xFE00, None),  # error
        (0xFEFF, None),  # error
        (0xFB00, None),  # parameter specific
        (0xFAFF, -12.81),  # -1281 steps: J1939's last valid raw value, a pressure
        (0x0000, 0.0),
        (15000, 150.0),
    ],
)
def test_a_j1939_indicator_of_a_signed_pressure_is_no_pressure(
    pipeline: Pipeline, raw: int, bar: float | None
) -> None:
    pipeline.process(RawFrame(1.0, 0x18FF2022, True, _int16(ROD_RAW) + b"\xff" * 6))
    result = pipeline.process(RawFrame(1.001, 0x18FF2021, True, _int16(raw) + b"\xff" * 6))
    (estimate,) = result.estimates
    assert estimate.p_rod_Pa == 30e5
    if bar is None:
        assert math.isnan(estimate.p_piston_Pa)
        assert not estimate.valid and estimate.reasons == ("range",)
    else:
        assert estimate.valid and estimate.reasons == ()
        assert estimate.p_piston_Pa == pytest.approx(bar * 1e5, abs=1e-6)
        assert estimate.force_raw_N == pytest.approx(eq4_N(bar * 1e5, 30e5), rel=1e-12)


def test_a_signed_pressure_outside_j1939_is_read_twos_complement(pipeline: Pipeline) -> None:
    """An 11-bit message is no J1939 one: its -1 step is -0.01 bar, its -512 -5.12 bar."""
    frame = RawFrame(1.0, 0x200, False, _int16(-1) + _int16(-512) + bytes(4))
    (first,) = pipeline.process(frame).estimates
    assert first.valid
    assert (first.p_piston_Pa, first.p_rod_Pa) == pytest.approx((-1e3, -512e3), abs=1e-6)
    assert first.force_raw_N == pytest.approx(eq4_N(-1e3, -512e3), rel=1e-12)
