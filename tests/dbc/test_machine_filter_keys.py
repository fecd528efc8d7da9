"""The force-filter keys of ``[estimator]``: non-default values load, bad ones are refused."""

from pathlib import Path

import pytest

from dbc.errors import ConfigError
from dbc.machine import load_machine_config
from tests.helpers import EXAMPLE_CONFIG

EXAMPLE = EXAMPLE_CONFIG.read_text()


def test_hampel_filter_keys_load(tmp_path: Path) -> None:
    path = tmp_path / "machine.toml"
    text = EXAMPLE.replace('filter = "median"', 'filter = "hampel"')
    text = text.replace("hampel_window = 7", "hampel_window = 9").replace(
        "hampel_k = 3.0", "hampel_k = 2.5"
    )
    path.write_text(text)
    settings = load_machine_config(path)[0].estimator
    assert (settings.filter, settings.hampel_window, settings.hampel_k) == ("hampel", 9, 2.5)


@pytest.mark.parametrize(
    ("old", "new", "key", "reason"),
    [
        ('filter = "median"', 'filter = "mean"', "estimator.filter", '"median" or "hampel"'),
        ('filter = "median"', "filter = 1", "estimator.filter", "string"),
        ("hampel_window = 7", "hampel_window = 2", "estimator.hampel_window", ">= 3"),
        ("hampel_window = 7", "hampel_window = 7.5", "estimator.hampel_window", "integer"),
        ("hampel_window = 7", "hampel_window = 202", "estimator.hampel_window", "at most 201"),
        ("hampel_k = 3.0", "hampel_k = 0", "estimator.hampel_k", "> 0"),
    ],
)
def test_bad_filter_keys_are_refused(
    tmp_path: Path, old: str, new: str, key: str, reason: str
) -> None:
    path = tmp_path / "machine.toml"
    assert old in EXAMPLE
    path.write_text(EXAMPLE.replace(old, new, 1))
    with pytest.raises(ConfigError) as info:
        load_machine_config(path)
    assert info.value.key == key
    assert reason in str(info.value)


def test_calibration_keys_load_per_leg(tmp_path: Path) -> None:
    path = tmp_path / "machine.toml"
    text = EXAMPLE.replace(
        "[legs.SB1_F2]\n", "[legs.SB1_F2]\nforce_gain = 1.04\nforce_offset_N = -812.5\n"
    )
    path.write_text(text)
    legs = load_machine_config(path)[0].legs
    geometry = legs["SB1_F2"].geometry
    assert (geometry.force_gain, geometry.force_offset_N) == (1.04, -812.5)
    assert geometry.calibrated_ratio == pytest.approx(1.04 * geometry.force_ratio)
    assert (legs["SB1_F1"].geometry.force_gain, legs["SB1_F1"].geometry.force_offset_N) == (1, 0)


@pytest.mark.parametrize(
    ("line", "key", "reason"),
    [
        ("force_gain = 0", "legs.SB1_F2.force_gain", "> 0"),
        ('force_offset_N = "x"', "legs.SB1_F2.force_offset_N", "number"),
    ],
)
def test_bad_calibration_keys_are_refused(tmp_path: Path, line: str, key: str, reason: str) -> None:
    path = tmp_path / "machine.toml"
    path.write_text(EXAMPLE.replace("[legs.SB1_F2]\n", f"[legs.SB1_F2]\n{line}\n"))
    with pytest.raises(ConfigError) as info:
        load_machine_config(path)
    assert info.value.key == key
    assert reason in str(info.value)
