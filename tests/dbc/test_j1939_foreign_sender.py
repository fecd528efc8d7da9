"""A foreign J1939 node sending a transducer's PGN from another source address, where the
chamber pins no ``source_address`` (one PGN per transducer, each DBC ID with its sender:
tests/files/stranger/spn_xdcr): its frames are counted ``unmapped_source``, never the
chamber's. They were read as the chamber's: a plausible pressure of another node made a
valid, wrong foot force."""

from pathlib import Path

import pytest

from daq.check_command import describe
from daq.frames import RawFrame
from daq.pipeline import Pipeline
from dbc.machine import load_machine_config
from tests.dbc.test_held_out_machines import STRANGER, eq4_N

PISTON_1 = 0x18FF6100  # HPT_PISTON_1, PGN 0xFF61; its DBC ID's sender is 0x31
ROD = 0x18FF7000  # HPT_ROD, PGN 0xFF70 (DBC ID from 0xFE), pinned to 0x41..0x44


def _piston(bar: float) -> bytes:
    return round(bar / 0.05).to_bytes(2, "little") + b"\x00" + b"\xff" * 5


def _rod(bar: float) -> bytes:
    return round(bar * 100.0 / 0.001).to_bytes(4, "little") + b"\x00" + b"\xff" * 3


def _pipeline(config: Path) -> Pipeline:
    return Pipeline.from_config(*load_machine_config(config))


def test_a_foreign_sender_of_an_unpinned_chambers_pgn_is_counted_not_used() -> None:
    pipeline = _pipeline(STRANGER / "spn_xdcr.toml")
    pipeline.process(RawFrame(1.000, ROD | 0x41, True, _rod(20.0)))
    (estimate,) = pipeline.process(RawFrame(1.001, PISTON_1 | 0x31, True, _piston(150.0))).estimates
    assert estimate.leg == "front-left" and estimate.valid
    assert estimate.force_raw_N == pytest.approx(eq4_N(150e5, 20e5), rel=1e-12)
    # Another node (0x55) sends the PGN, a plausible 100 bar, at another priority.
    foreign = pipeline.process(
        RawFrame(1.002, (PISTON_1 & ~(7 << 26)) | (3 << 26) | 0x55, True, _piston(100.0))
    )
    assert foreign.estimates == () and foreign.decoded is not None
    assert dict(pipeline.bad) == {"unmapped_source": 1}
    (again,) = pipeline.process(RawFrame(1.021, PISTON_1 | 0x31, True, _piston(150.0))).estimates
    assert again.force_raw_N == pytest.approx(eq4_N(150e5, 20e5), rel=1e-12)


def test_check_says_which_sender_an_unpinned_chamber_reads() -> None:
    lines = describe(*load_machine_config(STRANGER / "spn_xdcr.toml")).splitlines()
    assert lines[2] == (
        "  piston: HPT_PISTON_1.SPN_520448 from 0x31 (its DBC ID's) in 'bar', every 20 ms, "
        "status SPN_520449 (fine: OK)"
    )
    assert lines[3].startswith("  rod: HPT_ROD.SPN_520464@0x41 in 'kPa'")


def test_an_unpinned_chamber_whose_dbc_id_has_the_null_address_takes_any_sender(
    tmp_path: Path,
) -> None:
    """A DBC written with 0xFE (or 0xFF) as the sender, a placeholder no transducer sends
    from: the chamber takes the PGN from whichever address its transducer has."""
    text = (STRANGER / "spn_xdcr.dbc").read_text()
    placeholder = str(0x98FF61FE)  # HPT_PISTON_1 with the null address
    (tmp_path / "spn_xdcr.dbc").write_text(text.replace("2566873393", placeholder))
    (tmp_path / "machine.toml").write_text((STRANGER / "spn_xdcr.toml").read_text())
    pipeline = _pipeline(tmp_path / "machine.toml")
    pipeline.process(RawFrame(1.000, ROD | 0x41, True, _rod(20.0)))
    (estimate,) = pipeline.process(RawFrame(1.001, PISTON_1 | 0x5B, True, _piston(150.0))).estimates
    assert estimate.leg == "front-left" and estimate.valid
    assert estimate.force_raw_N == pytest.approx(eq4_N(150e5, 20e5), rel=1e-12)
    assert dict(pipeline.bad) == {}
