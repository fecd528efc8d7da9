"""A whole vehicle's DBC with a message the legs do not use whose signals overlap or
do not fit (CANdb++ warns and saves it; real vehicle DBCs have such messages): the
whole DBC was refused ("not a valid DBC: The signals Gear and GearAlt are
overlapping in message CAB_1"), so the machine could not be configured at all. Now
such messages are read as cantools reads them, with one warning line; a message the
config uses must still be sound."""

import logging
from pathlib import Path

import pytest

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from dbc.database import load_database_bytes
from dbc.errors import ConfigError, DbcError
from dbc.machine import load_machine_config
from tests.dbc.test_held_out_machines import HUB_FRONT_ID, STRANGER, _hub_frame, eq4_N

#: An unrelated cab message: Gear and GearAlt over the same byte; Spare beyond its end.
CAB = (
    'BO_ 1600 CAB_1: 2 Hub\n SG_ Gear : 0|8@1+ (1,0) [0|15] "" DAQ\n'
    ' SG_ GearAlt : 0|4@1+ (1,0) [0|15] "" DAQ\n SG_ Lamp : 8|1@1+ (1,0) [0|1] "" DAQ\n\n'
)


def _machine(tmp_path: Path, dbc: str) -> Path:
    (tmp_path / "motorola_psi.dbc").write_text(dbc, encoding="cp1252")
    (tmp_path / "machine.toml").write_text((STRANGER / "motorola_psi.toml").read_text())
    return tmp_path / "machine.toml"


def _dbc(extra: str) -> str:
    text = (STRANGER / "motorola_psi.dbc").read_text(encoding="cp1252")
    return text.replace("BO_ 1536 STATE", extra + "BO_ 1536 STATE")


def test_an_unsound_message_the_legs_do_not_use_is_read_with_a_warning(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    with caplog.at_level(logging.WARNING, logger="dbc.database"):
        config, database = load_machine_config(_machine(tmp_path, _dbc(CAB)))
    (line,) = [r.getMessage() for r in caplog.records]
    assert line == (
        f"{tmp_path / 'motorola_psi.dbc'}: read as cantools reads it, without its checks: "
        "The signals GearAlt and Gear are overlapping in message CAB_1."
    )
    pipeline = Pipeline.from_config(config, database)
    (estimate,) = pipeline.process(
        RawFrame(1.0, HUB_FRONT_ID, True, _hub_frame(0, 15000, 1000))
    ).estimates
    psi_Pa = 4.4482216152605 / 0.0254**2
    assert estimate.valid
    assert estimate.force_raw_N == pytest.approx(eq4_N(1500 * psi_Pa, 100 * psi_Pa), rel=1e-9)
    cab = pipeline.process(RawFrame(1.0, 1600, False, bytes([0x35, 0x01]))).decoded
    assert cab is not None and dict(cab.signals) == {"Gear": 0x35, "GearAlt": 5, "Lamp": 1}


def test_an_unsound_message_a_leg_uses_stops_the_config(tmp_path: Path) -> None:
    alive = ' SG_ FL_Alive : 39|4@0+ (1,0) [0|15] "" DAQ\n'
    spare = ' SG_ FL_Spare : 39|8@0+ (1,0) [0|255] "" DAQ\n'
    dbc = _dbc("").replace(alive, alive + spare)
    with pytest.raises(ConfigError) as refused:
        load_machine_config(_machine(tmp_path, dbc))
    assert refused.value.key == "legs.FL.piston"
    assert refused.value.reason == (
        "message HUB_FRONT of the DBC: The signals FL_Spare and FL_Alive are overlapping in "
        "message HUB_FRONT."
    )


def test_a_dbc_that_is_no_dbc_is_still_refused() -> None:
    with pytest.raises(DbcError, match="x.dbc: not a valid DBC: "):
        load_database_bytes(b"BO_ nonsense {", "x.dbc")


def test_value_tables_and_float_types_of_signals_the_dbc_lacks_are_left_out(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A value table and a float type left behind by a signal deleted or renamed by hand
    (FL_Status was once in HUB_FRONT; a message 0x700 is gone): cantools refused the whole
    DBC ("unused VAL_ entries in DBC:", and the error showed that first line only)."""
    stale = (
        'VAL_ 2164195329 FL_Status 0 "ok" 1 "fault" ;\n'
        'VAL_ 1792 Gone 0 "no" 1 "yes" ;\n'
        "SIG_VALTYPE_ 2164195329 FL_pOld : 1;\n"
    )
    dbc = _dbc("") + stale
    with caplog.at_level(logging.WARNING, logger="dbc.database"):
        config, database = load_machine_config(_machine(tmp_path, dbc))
    assert [r.getMessage() for r in caplog.records] == [
        f"{tmp_path / 'motorola_psi.dbc'}: left out, naming no signal of the DBC: " + entries
        for entries in (
            "VAL_ 2164195329 FL_Status, VAL_ 1792 Gone",
            "SIG_VALTYPE_ 2164195329 FL_pOld",
        )
    ]
    alive = database.get_message_by_name("HUB_FRONT").get_signal_by_name("FL_Alive")
    assert alive.choices == {15: "NotAvailable"}  # the DBC's other value tables are kept
    (estimate,) = (
        Pipeline.from_config(config, database)
        .process(RawFrame(1.0, HUB_FRONT_ID, True, _hub_frame(0, 15000, 1000)))
        .estimates
    )
    assert estimate.valid


#: A float type (SIG_VALTYPE_ 1) on the cab's 4-bit GearAlt: a hand edit that put it on
#: the wrong signal. cantools' checks take it and then unpack no frame of CAB_1.
FLOAT_GEAR = (
    'BO_ 1600 CAB_1: 2 Hub\n SG_ Gear : 0|4@1+ (1,0) [0|15] "" DAQ\n'
    ' SG_ GearAlt : 4|4@1+ (1,0) [0|15] "" DAQ\n\n'
)


def test_a_float_signal_no_frame_can_be_decoded_is_warned_of(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A message the legs do not use: one warning line at load (every frame of it was
    decode_error, and nothing said why)."""
    dbc = _dbc(FLOAT_GEAR) + "SIG_VALTYPE_ 1600 GearAlt : 1;\n"
    with caplog.at_level(logging.WARNING, logger="dbc.database"):
        config, database = load_machine_config(_machine(tmp_path, dbc))
    assert [r.getMessage() for r in caplog.records] == [
        f"{tmp_path / 'motorola_psi.dbc'}: CAB_1.GearAlt is an IEEE float by its "
        "SIG_VALTYPE_ but 4 bits long (a float is 16, 32 or 64): no frame of CAB_1 can be "
        "decoded (remove the SIG_VALTYPE_ or fix the length)"
    ]
    (estimate,) = (
        Pipeline.from_config(config, database)
        .process(RawFrame(1.0, HUB_FRONT_ID, True, _hub_frame(0, 15000, 1000)))
        .estimates
    )
    assert estimate.valid


def test_a_float_signal_no_frame_can_be_decoded_in_a_leg_message_stops_the_config(
    tmp_path: Path,
) -> None:
    """SIG_VALTYPE_ 1 on a leg's 4-bit rolling counter: `check` said fine, and the
    service counted every frame of the legs' message decode_error, the legs silent."""
    dbc = _dbc("") + "SIG_VALTYPE_ 2164195329 FL_Alive : 1;\n"
    with pytest.raises(ConfigError) as refused:
        load_machine_config(_machine(tmp_path, dbc))
    assert refused.value.key == "legs.FL.piston"
    assert refused.value.reason == (
        "message HUB_FRONT of the DBC: HUB_FRONT.FL_Alive is an IEEE float by its "
        "SIG_VALTYPE_ but 4 bits long (a float is 16, 32 or 64): no frame of HUB_FRONT can "
        "be decoded (remove the SIG_VALTYPE_ or fix the length)"
    )
