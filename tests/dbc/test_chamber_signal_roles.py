"""A chamber naming a signal that is no pressure whatever unit it is given: the message's
multiplexer (the bridge crashed on it, "Expected multiplexer id in {0, 1, 2 or 3}"), its
rolling counter or its CRC (0..15 read as a valid pressure in bar, the bridge's counter
written over the simulated pressure), the leg's status, or a signal whose value table names
every value it takes (a 2-bit sensor state in kPa was a valid 0..3 kPa). Each stops the
config naming the leg's key."""

import shutil
from pathlib import Path

import pytest

from dbc.errors import ConfigError
from dbc.machine import load_machine_config
from tests.helpers import FILES

STRANGER = FILES / "stranger"


@pytest.mark.parametrize(
    ("pair", "old", "new", "key", "reason"),
    [
        (
            "eight_legs_mux",
            'piston = "HUB_VORNE.HYD_P_VL1_A"',
            'piston = { signal = "HUB_VORNE.HUB_VORNE_Seite", unit = "bar" }',
            "legs.VL1.piston.signal",
            "signal HUB_VORNE.HUB_VORNE_Seite is the message's multiplexer (which page a "
            "frame is), not a pressure",
        ),
        (
            "zyl4_mbar12",
            'piston = "HYD_ZYL_VL.HYD_P_ZYL_VL_A"',
            'piston = { signal = "HYD_ZYL_VL.HYD_ZYL_VL_Zaehler", unit = "bar" }',
            "legs.VL.piston",
            "HYD_ZYL_VL.HYD_ZYL_VL_Zaehler is [protection.HYD_ZYL_VL] counter, not a pressure",
        ),
        (
            "eight_legs_mux",
            'rod = "HUB_HINTEN.HYD_P_HR2_B"',
            'rod = { signal = "HUB_HINTEN.HUB_HINTEN_CRC", unit = "kPa" }',
            "legs.HR2.rod",
            "HUB_HINTEN.HUB_HINTEN_CRC is [protection.HUB_HINTEN] crc, not a pressure",
        ),
        (
            "zyl4_mbar12",
            'rod = "HYD_ZYL_VL.HYD_P_ZYL_VL_B"',
            'rod = { signal = "HYD_ZYL_VL.HYD_ZYL_VL_Zustand", unit = "bar" }',
            "legs.VL.rod",
            "HYD_ZYL_VL.HYD_ZYL_VL_Zustand is this leg's status, not a pressure",
        ),
        (
            "xdcr_two_rates",
            'rod = { signal = "XDCR_ROD.HydPress", source_address = 0x50',
            'rod = { signal = "XDCR_ROD.SensorState", unit = "kPa", source_address = 0x50',
            "legs.A1.rod.signal",
            'signal XDCR_ROD.SensorState names every value it takes (0 "Ok", 1 "OpenCircuit", '
            '2 "ShortCircuit", 3 "NotAvailable"): a status, not a pressure',
        ),
    ],
)
def test_a_chamber_on_a_signal_that_is_no_pressure_is_refused(
    tmp_path: Path, pair: str, old: str, new: str, key: str, reason: str
) -> None:
    shutil.copy(STRANGER / f"{pair}.dbc", tmp_path)
    text = (STRANGER / f"{pair}.toml").read_text()
    assert text.count(old) == 1
    (tmp_path / "machine.toml").write_text(text.replace(old, new))
    with pytest.raises(ConfigError) as refused:
        load_machine_config(tmp_path / "machine.toml")
    assert (refused.value.key, refused.value.reason) == (key, reason)
