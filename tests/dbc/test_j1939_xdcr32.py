"""J1939 transducers of 32-bit pressures (tests/files/stranger/xdcr32_pdu1): the codes
of each width and byte order are no pressure, a peer-to-peer piston at another
priority is its chamber's, and what a config gets wrong about them is one line."""

import math
import tomllib

import pytest

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from dbc.errors import ConfigError
from dbc.machine import load_machine_config, machine_from_toml
from tests.helpers import FILES

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
