"""Two legs that read the same two chambers (a leg table copied and not edited): the
second leg showed the first one's forces, its own transducers ignored, and the weight
check counted one foot twice. Each leg is its own cylinder; one chamber's transducer
may be shared (a common line), both may not."""

from pathlib import Path

import pytest

from dbc.errors import ConfigError
from dbc.machine import load_machine_config
from tests.dbc.test_held_out_machines import STRANGER


def _config(tmp_path: Path, name: str, old: str, new: str) -> Path:
    text = (STRANGER / f"{name}.toml").read_text()
    assert old in text
    (tmp_path / f"{name}.dbc").write_bytes((STRANGER / f"{name}.dbc").read_bytes())
    (tmp_path / "machine.toml").write_text(text.replace(old, new))
    return tmp_path / "machine.toml"


def test_a_leg_reading_another_legs_two_chambers_stops_the_config(tmp_path: Path) -> None:
    path = _config(
        tmp_path,
        "motorola_psi",
        'piston = "HUB_REAR.RL_pCap"\nrod = "HUB_REAR.RL_pRod"',
        'piston = "HUB_FRONT.FL_pCap"\nrod = "HUB_FRONT.FL_pRod"',
    )
    with pytest.raises(ConfigError) as refused:
        load_machine_config(path)
    assert str(refused.value) == (
        f"{path}: legs.RL: reads the chambers of legs.FL (HUB_FRONT.FL_pCap, "
        "HUB_FRONT.FL_pRod): each leg needs its own"
    )


def test_transducers_of_other_senders_are_other_chambers(tmp_path: Path) -> None:
    """J1939: one signal, the chambers told apart by source address; and one chamber's
    transducer shared by two legs (a common line) is allowed."""
    config, _ = load_machine_config(STRANGER / "j1939_propa.toml")
    assert len(config.legs) == 2
    path = _config(
        tmp_path,
        "j1939_propa",
        'rod = { signal = "PRESS_A.Press", source_address = 0x33, status = "Diag" }',
        'rod = { signal = "PRESS_A.Press", source_address = 0x31, status = "Diag" }',
    )
    shared = load_machine_config(path)[0].legs
    assert shared["right-front"].rod == shared["left-front"].rod
    path = _config(
        tmp_path,
        "j1939_propa",
        'piston = { signal = "PRESS_A.Press", source_address = 0x32, status = "Diag" }\n'
        'rod = { signal = "PRESS_A.Press", source_address = 0x33, status = "Diag" }',
        'piston = { signal = "PRESS_A.Press", source_address = 0x30, status = "Diag" }\n'
        'rod = { signal = "PRESS_A.Press", source_address = 0x31, status = "Diag" }',
    )
    with pytest.raises(ConfigError) as refused:
        load_machine_config(path)
    assert refused.value.key == "legs.right-front"
    assert "reads the chambers of legs.left-front (PRESS_A.Press@0x30, PRESS_A.Press@0x31)" in (
        refused.value.reason
    )
