"""A CAN database in another format than DBC (KCD, ARXML, SYM: cantools reads them,
the machine config does not) is named as what it is, with the way to a DBC."""

from pathlib import Path

import cantools
import pytest

from dbc.errors import DbcError
from dbc.machine import load_machine_config
from tests.dbc.test_held_out_machines import STRANGER

DATABASE = STRANGER / "j1939_slots.dbc"


def _texts() -> dict[str, str]:
    database = cantools.database.load_file(DATABASE)
    return {
        "kcd": database.as_kcd_string(),
        "sym": database.as_sym_string(),
        "arxml": '<?xml version="1.0" encoding="UTF-8"?>\n'
        '<AUTOSAR xmlns="http://autosar.org/schema/r4.0">\n</AUTOSAR>\n',
    }


@pytest.mark.parametrize(
    ("suffix", "kind"), [("kcd", "a KCD"), ("sym", "a SYM"), ("arxml", "an ARXML")]
)
def test_a_database_in_another_format_is_named_with_how_to_convert_it(
    tmp_path: Path, suffix: str, kind: str
) -> None:
    """It was 'not a valid DBC: DBC: "Invalid syntax at line 1, column 1: ">>!<<<Network..."'."""
    (tmp_path / f"machine.{suffix}").write_text(_texts()[suffix])
    config = (STRANGER / "j1939_slots.toml").read_text()
    (tmp_path / "machine.toml").write_text(config.replace("j1939_slots.dbc", f"machine.{suffix}"))
    with pytest.raises(DbcError) as refused:
        load_machine_config(tmp_path / "machine.toml")
    path = tmp_path / f"machine.{suffix}"
    assert str(refused.value) == (
        f"{path}: {kind} file, not a DBC: portal-daq reads DBC only; convert it with "
        f"`cantools convert {path} {path.with_suffix('.dbc')}`"
    )
