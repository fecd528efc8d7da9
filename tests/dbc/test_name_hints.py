"""A signal or message name the DBC does not have is refused with what was probably
meant: another case or a letter off, the message a signal is in, the signals of a
message named alone (tests/files/stranger/zyl4_mbar12: names a user types from a
vendor's sheet). Before, each said only that the name was not there."""

import shutil
from pathlib import Path

import pytest

from dbc.errors import ConfigError
from dbc.machine import load_machine_config
from tests.helpers import FILES

PAIR = FILES / "stranger" / "zyl4_mbar12"
PISTON = 'piston = "HYD_ZYL_VL.HYD_P_ZYL_VL_A"'


@pytest.mark.parametrize(
    ("edit", "key", "reason"),
    [
        (
            (PISTON, 'piston = "HYD_P_ZYL_VL_A"'),
            "legs.VL.piston",
            "'HYD_P_ZYL_VL_A' must be written MESSAGE.SIGNAL: HYD_ZYL_VL.HYD_P_ZYL_VL_A",
        ),
        (
            (PISTON, 'piston = "HYD_ZYL_VL"'),
            "legs.VL.piston",
            "'HYD_ZYL_VL' must be written MESSAGE.SIGNAL; HYD_ZYL_VL's signals are "
            "HYD_P_ZYL_VL_A, HYD_P_ZYL_VL_B, HYD_ZYL_VL_Zustand, HYD_ZYL_VL_Zaehler",
        ),
        (
            (PISTON, 'piston = "HYD_ZYL_VL.hyd_p_zyl_vl_a"'),
            "legs.VL.piston",
            "no signal 'hyd_p_zyl_vl_a' in message HYD_ZYL_VL of the DBC; did you mean "
            "HYD_P_ZYL_VL_A?",
        ),
        (
            (PISTON, 'piston = "HYD_ZYL_VR.HYD_P_ZYL_VL_A"'),
            "legs.VL.piston",
            "no signal 'HYD_P_ZYL_VL_A' in message HYD_ZYL_VR of the DBC; it is in HYD_ZYL_VL",
        ),
        (
            ('cycle_count = "MASCHINE_ZUSTAND.Zyklen"', 'cycle_count = "HYD_ZYL_VL.Zyklen"'),
            "signals.cycle_count",
            "no signal 'Zyklen' in message HYD_ZYL_VL of the DBC; it is in MASCHINE_ZUSTAND",
        ),
        (
            (PISTON, 'piston = "HYD_ZYL_LV.HYD_P_ZYL_VL_A"'),
            "legs.VL.piston",
            "no message 'HYD_ZYL_LV' in the DBC; did you mean HYD_ZYL_VR or "
            "HYD_ZYL_VL or HYD_ZYL_HL?",
        ),
        (
            ('counter = "HYD_ZYL_VL_Zaehler"', 'counter = "HYD_ZYL_VL_Zähler"'),
            "protection.HYD_ZYL_VL.counter",
            "no signal 'HYD_ZYL_VL_Zähler' in message HYD_ZYL_VL of the DBC; did you mean "
            "HYD_ZYL_VL_Zaehler?",
        ),
        (
            (PISTON, 'piston = "HYD_ZYL_VL.Temperatur"'),
            "legs.VL.piston",
            "no signal 'Temperatur' in message HYD_ZYL_VL of the DBC",
        ),
    ],
)
def test_a_name_not_in_the_dbc_is_refused_with_what_was_meant(
    tmp_path: Path, edit: tuple[str, str], key: str, reason: str
) -> None:
    shutil.copy(PAIR.with_suffix(".dbc"), tmp_path)
    text = PAIR.with_suffix(".toml").read_text()
    assert edit[0] in text
    (tmp_path / "m.toml").write_text(text.replace(edit[0], edit[1], 1))
    with pytest.raises(ConfigError) as refused:
        load_machine_config(tmp_path / "m.toml")
    assert (refused.value.key, refused.value.reason) == (key, reason)
