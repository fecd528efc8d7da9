"""A chamber signal whose DBC factor is 0: every frame decoded to its offset, a
constant pressure published as valid (0 Pa: a foot that carried nothing whatever
the ground did). The config now stops, naming the signal."""

from pathlib import Path

import pytest

from dbc.errors import ConfigError
from dbc.machine import load_machine_config
from tests.dbc.test_held_out_machines import STRANGER


@pytest.mark.parametrize(
    ("layout", "offset"), [("7|16@0+ (0,0)", "0"), ("7|16@0+ (0,-14.5)", "-14.5")]
)
def test_a_chamber_signal_of_factor_0_stops_the_config(
    tmp_path: Path, layout: str, offset: str
) -> None:
    text = (STRANGER / "motorola_psi.dbc").read_text(encoding="cp1252")
    assert "FL_pCap : 7|16@0+ (0.1,0)" in text
    dbc = text.replace("FL_pCap : 7|16@0+ (0.1,0)", f"FL_pCap : {layout}")
    (tmp_path / "motorola_psi.dbc").write_text(dbc, encoding="cp1252")
    (tmp_path / "machine.toml").write_text((STRANGER / "motorola_psi.toml").read_text())
    with pytest.raises(ConfigError) as refused:
        load_machine_config(tmp_path / "machine.toml")
    assert str(refused.value) == (
        f"{tmp_path / 'machine.toml'}: legs.FL.piston: signal HUB_FRONT.FL_pCap has factor 0 "
        f"in the DBC: every value would be its offset, {offset} psi(g)"
    )
