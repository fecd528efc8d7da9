"""A status that no frame can make "fine": ``status_ok`` numbers that the status signal
cannot take (7 of a 2-bit signal) made every sample of the leg invalid
(``status_0``, ``status_1``, ...), with nothing said at start."""

from pathlib import Path

import pytest

from dbc.errors import ConfigError
from dbc.machine import load_machine_config
from tests.dbc.test_held_out_machines import STRANGER
from tests.helpers import dbc_text, machine_on


def _load(tmp_path: Path, status_ok: str) -> None:
    (tmp_path / "j1939_propa.dbc").write_bytes((STRANGER / "j1939_propa.dbc").read_bytes())
    text = (STRANGER / "j1939_propa.toml").read_text()
    old = 'status_ok = ["ok", "warn"]'
    assert old in text
    (tmp_path / "machine.toml").write_text(text.replace(old, f"status_ok = {status_ok}"))
    load_machine_config(tmp_path / "machine.toml")


@pytest.mark.parametrize(
    ("status_ok", "expected"), [("4", "[4]"), ("[4, -1]", "[4, -1]"), ("[7]", "[7]")]
)
def test_status_ok_numbers_the_status_signal_cannot_take_stop_the_config(
    tmp_path: Path, status_ok: str, expected: str
) -> None:
    with pytest.raises(ConfigError) as refused:
        _load(tmp_path, status_ok)
    assert refused.value.key == "legs.left-front.piston.status_ok"  # [sensors]' value here
    assert refused.value.reason == (
        f"PRESS_A.Diag takes 0..3: none of {expected} is one of them (every sample would be "
        "invalid) (no status_ok in legs.left-front.piston: the leg's status_ok, or [sensors] "
        "status_ok, ['ok'] by default; set status_ok in legs.left-front.piston)"
    )


@pytest.mark.parametrize("status_ok", ["[0, 7]", "3", '["ok", 1]'])
def test_one_value_the_status_can_take_is_enough(tmp_path: Path, status_ok: str) -> None:
    _load(tmp_path, status_ok)


def test_a_status_in_a_message_of_its_own_is_refused_saying_why(tmp_path: Path) -> None:
    """A sensor state in a diagnostic message of its own: the refusal said to give it as
    the chamber's status instead, which stops the config the same way."""
    text = dbc_text(
        'BO_ 256 PRESS: 4 Hub\n SG_ pA : 0|16@1+ (0.01,0) [0|400] "bar" DAQ\n'
        ' SG_ pB : 16|16@1+ (0.01,0) [0|400] "bar" DAQ\n'
        'BO_ 257 DIAG: 1 Hub\n SG_ SensorState : 0|2@1+ (1,0) [0|3] "" DAQ\n',
        'BA_ "GenMsgCycleTime" BO_ 256 10;\nVAL_ 257 SensorState 0 "OK" 1 "Fault" ;\n',
    )
    legs = '[legs.S]\npiston = "PRESS.pA"\nrod = "PRESS.pB"\nstatus = "DIAG.SensorState"\n'
    with pytest.raises(ConfigError) as refused:
        machine_on(tmp_path, text, legs + 'status_ok = "OK"\n')
    assert str(refused.value) == (
        f"{tmp_path / 'm.toml'}: legs.S.status: DIAG.SensorState is not in the chambers' "
        "message (PRESS): a status is judged with the frame that carries it and the "
        "pressures; one sent in a message of its own cannot be (leave status out: the leg "
        "is not judged by status)"
    )


def test_a_status_ok_the_config_does_not_set_is_told_where_it_comes_from(
    tmp_path: Path,
) -> None:
    """A foreign DBC's status names its fine value "i.O.": the default "ok" is no value
    of it, and the refusal named legs.VL.status_ok, a key the config does not have."""
    text = dbc_text(
        'BO_ 256 PRESS: 5 Hub\n SG_ pA : 0|16@1+ (0.01,0) [0|400] "bar" DAQ\n'
        ' SG_ pB : 16|16@1+ (0.01,0) [0|400] "bar" DAQ\n'
        ' SG_ Zustand : 32|2@1+ (1,0) [0|3] "" DAQ\n',
        'BA_ "GenMsgCycleTime" BO_ 256 10;\nVAL_ 256 Zustand 0 "i.O." 1 "Kabelbruch" ;\n',
    )
    leg = '[legs.VL]\npiston = "PRESS.pA"\nrod = "PRESS.pB"\nstatus = "PRESS.Zustand"\n'
    with pytest.raises(ConfigError) as refused:
        machine_on(tmp_path, text, leg)
    assert refused.value.key == "legs.VL.status_ok"
    assert refused.value.reason == (
        "'ok' is not a value of PRESS.Zustand: its value table has ['Kabelbruch', 'i.O.'] "
        "(no status_ok in legs.VL: [sensors] status_ok, ['ok'] by default; set status_ok "
        "in legs.VL)"
    )
    config, _ = machine_on(tmp_path, text, leg + 'status_ok = "i.O."\n')
    assert config.legs["VL"].piston.status is not None
