"""Machine configuration: the example loads; wrong configs are refused naming file and key."""

import logging
import re
from pathlib import Path

import pytest

from dbc.errors import ConfigError, DbcError
from dbc.machine import G_M_S2, load_machine_config
from tests.helpers import EXAMPLE_CONFIG, LEGS

EXAMPLE = EXAMPLE_CONFIG.read_text()


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "machine.toml"
    path.write_text(text)
    return path


def refused(tmp_path: Path, text: str) -> ConfigError:
    path = write(tmp_path, text)
    with pytest.raises(ConfigError) as info:
        load_machine_config(path)
    assert str(path) in str(info.value)
    return info.value


def test_example_config_loads_with_documented_values() -> None:
    config, database = load_machine_config(EXAMPLE_CONFIG)
    assert config.machine_id == "pam-proto-1"
    assert config.weight_N == pytest.approx(18_800.0 * G_M_S2)
    assert tuple(config.legs) == LEGS
    leg = config.legs["SB2_F2"]
    assert leg.geometry.A_foot_m2 == 0.33
    assert leg.geometry.force_ratio == pytest.approx(0.6705, abs=1e-4)
    assert str(leg.piston) == "LEG_SB2_F2.SB2_F2_pPiston"
    assert leg.cycle_time_s == 0.01
    assert config.estimator.median_window == 11
    assert set(config.protection) == {m.name for m in database.messages}


def test_leg_table_overrides_leg_defaults(tmp_path: Path) -> None:
    text = EXAMPLE.replace("[legs.SB1_F3]\n", "[legs.SB1_F3]\nA_foot_m2 = 0.5\n")
    config, _ = load_machine_config(write(tmp_path, text))
    assert config.legs["SB1_F3"].geometry.A_foot_m2 == 0.5
    assert config.legs["SB1_F2"].geometry.A_foot_m2 == 0.33


@pytest.mark.parametrize(
    ("old", "new", "key", "reason"),
    [
        ("l_r_m = 0.90\n", "", "legs.SB1_F1.l_r_m", "missing"),
        ("A_rod_m2 = 4.737e-3", "A_rod_m2 = -4.737e-3", "leg_defaults.A_rod_m2", "must be > 0"),
        ("[legs.SB2_F1]", "[legs.SB2_F1]\nA_piston_m2 = -1.0", "legs.SB2_F1.A_piston_m2", "> 0"),
        ("A_foot_m2 = 0.33", 'A_foot_m2 = "big"', "leg_defaults.A_foot_m2", "must be a number"),
        ("alpha_cyl_deg = 75.0", "alpha_cyl_deg = nan", "leg_defaults.alpha_cyl_deg", "finite"),
        ("[legs.SB1_F2]", "[legs.SB1_F2]\nalpha_cyl_deg = 5.0", "legs.SB1_F2", "cannot carry"),
        # The key named is the one of the table whose value broke the rule: the leg's own
        # piston area below [leg_defaults]' annulus (leg_defaults.A_rod_m2 was blamed),
        # the lever of [leg_defaults] alone (legs.SB1_F1 was: the first leg to use it).
        (
            "[legs.SB2_F1]",
            "[legs.SB2_F1]\nA_piston_m2 = 4.0e-3",
            "legs.SB2_F1.A_piston_m2",
            "A_rod_m2 (0.004737) must be smaller than A_piston_m2 (0.004)",
        ),
        ("[legs.SB2_F1]", "[legs.SB2_F1]\nA_rod_m2 = 9e-3", "legs.SB2_F1.A_rod_m2", "smaller"),
        ("alpha_cyl_deg = 75.0", "alpha_cyl_deg = 5.0", "leg_defaults", "cannot carry"),
        (
            'piston = "LEG_SB1_F2.SB1_F2_pPiston"',
            'piston = "LEG_SB1_F2.SB1_F2_pPistn"',
            "legs.SB1_F2.piston",
            "no signal 'SB1_F2_pPistn' in message LEG_SB1_F2",
        ),
        (
            'rod = "LEG_SB2_F1.SB2_F1_pRod"',
            'rod = "LEG_SB2_F9.SB2_F1_pRod"',
            "legs.SB2_F1.rod",
            "no message 'LEG_SB2_F9'",
        ),
        (
            'status = "LEG_SB1_F1.SB1_F1_Status"',
            'status = "SB1_F1_Status"',
            "legs.SB1_F1.status",
            "MESSAGE.SIGNAL",
        ),
        ("mass_kg = 18800.0", "mass_kg = 0", "machine.mass_kg", "must be > 0"),
        ('id = "pam-proto-1"', 'id = "pam/proto"', "machine.id", "does not match"),
        ("median_window = 11", "median_window = 10", "estimator.median_window", "odd"),
        ("contact_off_N = 4000.0", "contact_off_N = 9000.0", "estimator.contact_off_N", "below"),
        ("median_window = 11", "median_windw = 11", "estimator.median_windw", "unknown key"),
        (
            "stale_after_cycles = 3.0",
            "stale_after_cycles = 1.0",
            "estimator.stale_after_cycles",
            "stale between two of its frames",
        ),
        ("l_gb_m = 0.55", "l_gb = 0.55", "leg_defaults.l_gb", "unknown key"),
        (
            "near_constant_window_s = 5.0",
            "near_constant_window_s = 1e-300",
            "estimator.near_constant_window_s",
            "must be at least 0.01 s",
        ),
        ('crc = "SB1_F1_CRC"', 'crc = "SB1_F1_Status"', "protection.LEG_SB1_F1.crc", "8-bit"),
        ("[legs.SB1_F1]", "[legs.SB1_F1]\nfoot = 1", "legs.SB1_F1.foot", "unknown key"),
    ],
)
def test_wrong_config_is_refused_naming_the_key(
    tmp_path: Path, old: str, new: str, key: str, reason: str
) -> None:
    assert old in EXAMPLE
    error = refused(tmp_path, EXAMPLE.replace(old, new, 1))
    assert error.key == key
    assert reason in str(error)


def test_missing_machine_table(tmp_path: Path) -> None:
    error = refused(tmp_path, re.sub(r"\[machine\].*?\n\n", "", EXAMPLE, count=1, flags=re.S))
    assert error.key == "machine" and "missing" in error.reason


def test_no_legs(tmp_path: Path) -> None:
    error = refused(tmp_path, EXAMPLE.split("[legs.SB1_F1]")[0] + "[legs]\n")
    assert error.key == "legs" and "no legs" in error.reason


def test_not_toml(tmp_path: Path) -> None:
    error = refused(tmp_path, "[machine\nid = 3")
    assert "not valid TOML" in str(error)


@pytest.mark.parametrize(
    ("old", "new", "key"),
    [
        # float(10**48) is fine, but TOML's integers stop at 64 bits; 10**400 crashed
        # float() with an OverflowError traceback.
        ("mass_kg = 18800.0", f"mass_kg = {10**400}", "machine.mass_kg"),
        ("mass_kg = 18800.0", f"mass_kg = -{10**20}", "machine.mass_kg"),
        ("median_window = 11", f"median_window = {2**64 + 1}", "estimator.median_window"),
    ],
)
def test_an_integer_beyond_64_bits_is_refused_naming_the_key(
    tmp_path: Path, old: str, new: str, key: str
) -> None:
    assert old in EXAMPLE
    error = refused(tmp_path, EXAMPLE.replace(old, new, 1))
    assert error.key == key
    assert "must fit in 64 bits" in error.reason


def test_a_number_too_long_to_read_is_not_valid_toml(tmp_path: Path) -> None:
    # Python's int() refuses more than 4,300 digits with a ValueError: a traceback.
    error = refused(tmp_path, EXAMPLE.replace("mass_kg = 18800.0", "mass_kg = 1" + "0" * 5000))
    assert error.key == "" and "not valid TOML: a number too long to read" in error.reason


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="no such file"):
        load_machine_config(tmp_path / "absent.toml")


def test_bad_dbc_is_a_dbc_error_naming_the_dbc(tmp_path: Path) -> None:
    (tmp_path / "broken.dbc").write_text("BO_ nonsense {")
    text = EXAMPLE.replace('# dbc = "portal_sensors.dbc"', 'dbc = "broken.dbc"')
    with pytest.raises(DbcError, match="broken.dbc: not a valid DBC"):
        load_machine_config(write(tmp_path, text))


def test_missing_dbc(tmp_path: Path) -> None:
    text = EXAMPLE.replace('# dbc = "portal_sensors.dbc"', 'dbc = "nowhere.dbc"')
    with pytest.raises(DbcError, match="nowhere.dbc: no such file"):
        load_machine_config(write(tmp_path, text))


def test_a_contact_threshold_above_the_weight_per_leg_is_warned_of(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    # 1,000 kg on six legs: 1,634 N per foot, never the default 8 kN: every foot "in the
    # air", the weight check 0 N, the report's pressures 0 kPa, nothing said.
    path = write(tmp_path, EXAMPLE.replace("mass_kg = 18800.0", "mass_kg = 1000.0", 1))
    with caplog.at_level(logging.WARNING, logger="dbc.machine"):
        load_machine_config(path)
        load_machine_config(EXAMPLE_CONFIG)  # 30.7 kN per leg: nothing to say
    assert [r.getMessage() for r in caplog.records] == [
        f"{path}: estimator.contact_on_N: 8000 N is at least the machine's weight per leg, "
        "1634 N (1000 kg on 6 legs): with every foot down some would count as in the air; "
        "set contact_on_N and contact_off_N below it"
    ]


@pytest.mark.parametrize(
    ("old", "new", "expected"),
    [
        # The paper's 0.33 m2 foot written in cm2: soil pressures 10,000 times too low.
        (
            "A_foot_m2 = 0.33",
            "A_foot_m2 = 3300",
            "leg_defaults.A_foot_m2: 3300 m2 would carry the weight per leg, 30728 N "
            "(machine.mass_kg 18800 on 6 legs), at 9.311 Pa of soil pressure; areas are in "
            "m2: is it written in cm2 or mm2 (or the mass in t)?",
        ),
        # One leg's 100 mm piston in cm2: its foot force 10,000 times too high.
        (
            "[legs.SB2_F1]\n",
            "[legs.SB2_F1]\nA_piston_m2 = 78.54\nA_rod_m2 = 47.37\n",
            "legs.SB2_F1.A_piston_m2: 78.54 m2 would hold the weight per leg, 30728 N "
            "(machine.mass_kg 18800 on 6 legs), at 540.8 Pa in the piston chamber; areas are "
            "in m2: is it written in cm2 or mm2 (or the mass in t)?",
        ),
        # A 20 mm piston: 1,350 bar to hold the leg, beyond the 400 bar transducers.
        (
            "A_piston_m2 = 7.854e-3\nA_rod_m2 = 4.737e-3",
            "A_piston_m2 = 3.1416e-4\nA_rod_m2 = 1.5e-4",
            "leg_defaults.A_piston_m2: 0.00031416 m2 would hold the weight per leg, 30728 N "
            "(machine.mass_kg 18800 on 6 legs), at 1.352e+08 Pa in the piston chamber, above "
            "[sensors] pressure_max_Pa (4e+07): every sample of the leg standing would be "
            "invalid (range)",
        ),
    ],
)
def test_an_area_no_foot_or_cylinder_stands_on_is_warned_of_once_naming_its_key(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, old: str, new: str, expected: str
) -> None:
    assert old in EXAMPLE
    path = write(tmp_path, EXAMPLE.replace(old, new, 1))
    with caplog.at_level(logging.WARNING, logger="dbc.machine"):
        load_machine_config(path)
    assert [r.getMessage() for r in caplog.records] == [f"{path}: {expected}"]


def test_an_angle_written_in_radians_is_warned_of_naming_its_key(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    # 1.309 (75 deg in radians) with the attachment below the pivot (l_z_m < 0) loads: a
    # lever of 0.225 instead of 0.778, every foot force under a third, silently.
    text = EXAMPLE.replace(
        "[legs.SB1_F2]\n", "[legs.SB1_F2]\nalpha_cyl_deg = 1.309\nl_z_m = -0.25\n"
    )
    with caplog.at_level(logging.WARNING, logger="dbc.machine"):
        config, _ = load_machine_config(write(tmp_path, text))
    assert config.legs["SB1_F2"].geometry.force_ratio == pytest.approx(0.2254, abs=1e-4)
    assert [r.getMessage() for r in caplog.records] == [
        f"{tmp_path / 'machine.toml'}: legs.SB1_F2.alpha_cyl_deg: 1.309 is in degrees, a "
        "cylinder 1.309 deg off the r axis; if it is in radians, write 75 (degrees)"
    ]
    # In [leg_defaults]: one line for the key, then the lever refused as before.
    caplog.clear()
    text = EXAMPLE.replace("alpha_cyl_deg = 75.0", "alpha_cyl_deg = 1.309")
    with caplog.at_level(logging.WARNING, logger="dbc.machine"):
        error = refused(tmp_path, text)
    assert error.key == "leg_defaults" and "cannot carry the foot" in str(error)
    assert [r.getMessage().split(": ")[1] for r in caplog.records] == ["leg_defaults.alpha_cyl_deg"]
