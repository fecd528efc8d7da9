"""J1939 transducers of 32-bit pressures (tests/files/stranger/xdcr32_pdu1): the codes
of each width and byte order are no pressure, a peer-to-peer piston at another
priority is its chamber's, and what a config gets wrong about them is one line."""

import math
import tomllib
from pathlib import Path

import pytest

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from dbc.errors import ConfigError
from dbc.machine import load_machine_config, machine_from_toml
from tests.helpers import FILES, dbc_text, machine_on

STRANGER = FILES / "stranger"
TOML = (STRANGER / "xdcr32_pdu1.toml").read_text()
PISTON_ID = 0x0CEF8031  # priority 3, proprietary A to the DAQ (0x80), from 0x31
ROD_ID = 0x18FF6041  # proprietary B from 0x41


def piston(raw: int) -> bytes:
    return raw.to_bytes(4, "big") + bytes(4)  # Motorola, 0.001 kPa/bit; status 0 "OK"


def rod(raw: int) -> bytes:
    return raw.to_bytes(4, "little") + bytes(4)  # Intel, 0.00001 bar/bit (the comment's)


@pytest.mark.parametrize(
    ("piston_raw", "rod_raw", "p_piston_Pa", "p_rod_Pa"),
    [
        (20_000_000, 15_000_000, 20e6, 15e6),
        (0xFFFFFFFF, 15_000_000, math.nan, 15e6),  # not available
        (0xFEFFFFFF, 15_000_000, math.nan, 15e6),  # error
        (0xFB000000, 15_000_000, math.nan, 15e6),  # parameter specific
        (20_000_000, 0xFFFFFF00, 20e6, math.nan),
        (20_000_000, 0xFE000000, 20e6, math.nan),
    ],
)
def test_the_codes_of_a_32_bit_pressure_are_no_pressure_in_either_byte_order(
    piston_raw: int, rod_raw: int, p_piston_Pa: float, p_rod_Pa: float
) -> None:
    """0xFB000000 and above of a 4-byte parameter are J1939 indicators, Motorola or
    Intel, declared range or none ([0|0]): at 0.001 kPa/bit 0xFFFFFFFF was 4.3 GPa, at
    0.00001 bar/bit 0xFE000000 a 426 MPa rod, each a number where none was sent."""
    config, database = load_machine_config(STRANGER / "xdcr32_pdu1.toml")
    pipeline = Pipeline.from_config(config, database)
    pipeline.process(RawFrame(1.0, ROD_ID, True, rod(rod_raw)))
    (estimate,) = pipeline.process(RawFrame(1.001, PISTON_ID, True, piston(piston_raw))).estimates
    assert estimate.leg == "VL"
    got = (estimate.p_piston_Pa, estimate.p_rod_Pa)
    assert got == pytest.approx((p_piston_Pa, p_rod_Pa), nan_ok=True, rel=1e-12)
    assert estimate.valid == (not math.isnan(p_piston_Pa + p_rod_Pa))
    assert estimate.reasons == (() if estimate.valid else ("range",))


def test_a_piston_at_another_priority_is_its_chambers_and_another_address_is_counted() -> None:
    """The same PGN at priority 6 from 0x32 is VR's piston; from 0x35, which no chamber
    has, it is counted unmapped_source, not read as another transducer's."""
    config, database = load_machine_config(STRANGER / "xdcr32_pdu1.toml")
    pipeline = Pipeline.from_config(config, database)
    pipeline.process(RawFrame(1.0, 0x18FF6042, True, rod(15_000_000)))
    made = [
        [
            e.leg
            for e in pipeline.process(RawFrame(1.001, frame_id, True, piston(20_000_000))).estimates
        ]
        for frame_id in (0x18EF8032, 0x0CEF8035)
    ]
    assert made == [["VR"], []] and pipeline.bad == {"unmapped_source": 1}


def test_a_piston_transducers_frames_to_another_destination_are_no_pressure() -> None:
    """The DBC has the pistons' proprietary A to the DAQ (0x80) only; the same PGN from
    VR's transducer to a display at 0x28 (its own content) was read as VR's piston: a
    valid, wrong force. It is no message of the DBC, counted ``unknown_id``; to all
    (0xFF), which is to the DAQ too, it is VR's piston."""
    config, database = load_machine_config(STRANGER / "xdcr32_pdu1.toml")
    pipeline = Pipeline.from_config(config, database)
    pipeline.process(RawFrame(1.0, 0x18FF6042, True, rod(15_000_000)))
    to_display = pipeline.process(RawFrame(1.001, 0x18EF2832, True, piston(3_000_000)))
    (estimate,) = pipeline.process(RawFrame(1.002, 0x18EF8032, True, piston(20_000_000))).estimates
    assert to_display.estimates == () and pipeline.bad == {"unknown_id": 1}
    assert (estimate.leg, estimate.p_piston_Pa, estimate.valid) == ("VR", 20e6, True)
    (to_all,) = pipeline.process(RawFrame(1.003, 0x18EFFF32, True, piston(21_000_000))).estimates
    assert (to_all.leg, to_all.p_piston_Pa, to_all.valid) == ("VR", 21e6, True)


def test_a_standard_peer_to_peer_pgn_is_read_to_any_destination(tmp_path: Path) -> None:
    """A standard PGN has one layout whatever node it goes to: TSC1 (PGN 0) that the DBC
    gives to the engine (0x00) is TSC1 to a retarder (0x0F) too; proprietary A is not."""
    messages = (
        'BO_ 2364506161 PRESS: 8 Hub\n SG_ pPiston : 0|16@1+ (0.01,0) [0|0] "bar" DAQ\n'
        ' SG_ pRod : 16|16@1+ (0.01,0) [0|0] "bar" DAQ\n'
        'BO_ 2348810243 TSC1: 8 Hub\n SG_ ReqSpeed : 8|16@1+ (0.125,0) [0|0] "rpm" DAQ\n'
    )
    attributes = "".join(
        f'BA_ "GenMsgCycleTime" BO_ {i} 10;\nBA_ "VFrameFormat" BO_ {i} 3;\n'
        for i in (2364506161, 2348810243)
    )
    legs = '[legs.A]\npiston = "PRESS.pPiston"\nrod = "PRESS.pRod"\n'
    pipeline = Pipeline.from_config(*machine_on(tmp_path, dbc_text(messages, attributes), legs))
    data = (1000).to_bytes(2, "little") * 2 + bytes(4)
    assert pipeline.decoder.decode(0x0C000F03, data, 1.0, True).message == "TSC1"
    assert [e.leg for e in pipeline.process(RawFrame(1.0, 0x0CEF8031, True, data)).estimates] == [
        "A"
    ]
    assert pipeline.process(RawFrame(1.01, 0x0CEF2831, True, data)).estimates == ()
    assert pipeline.bad == {"unknown_id": 1}


@pytest.mark.parametrize(
    ("old", "new", "key", "reason"),
    [
        (
            'source_address = 0x41, unit = "bar", ',
            "source_address = 0x41, ",
            "legs.VL.rod.signal",
            "not a pressure unit; set unit = one of Pa, kPa, MPa, bar, mbar, psi, hPa, N/mm2, "
            "N/cm2, daN/cm2, kgf/cm2 (the DBC's comment on it: 'Stangendruck in bar, "
            "0.00001 bar/bit')",
        ),
        (
            "source_address = 0x31,",
            "source_address = 0xFE,",
            "legs.VL.piston.source_address",
            "must be a J1939 address 0..253, got 254 (0xFE: the null address, a node "
            "without a claimed one)",
        ),
        (
            "source_address = 0x31,",
            "source_address = 0xFF,",
            "legs.VL.piston.source_address",
            "got 255 (0xFF: the global address, a destination, no sender)",
        ),
    ],
)
def test_what_a_config_gets_wrong_is_one_line(old: str, new: str, key: str, reason: str) -> None:
    """A rod whose unit is only in the DBC's comment (the vendor's way) is refused with
    that comment, so a user of the wheel alone needs not open the DBC to find it; the
    null and global addresses are told as such."""
    assert old in TOML
    with pytest.raises(ConfigError) as info:
        machine_from_toml(tomllib.loads(TOML.replace(old, new, 1)), "m.toml", STRANGER)
    assert info.value.key == key and reason in str(info.value)
    assert "\n" not in str(info.value)
