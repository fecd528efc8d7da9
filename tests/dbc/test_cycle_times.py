"""Cycle times the DBC does not give: ``[messages.<MESSAGE>] cycle_time_ms`` (vendor DBCs,
J1939 ones especially, often have no ``GenMsgCycleTime``), and that every user of a
message's cycle time (skew, staleness, counter resynchronisation, the bridge's schedule)
takes the same one (tests/files/stranger/j1939_units: a DBC without any)."""

import subprocess
import sys
import tomllib
from dataclasses import replace
from pathlib import Path

import pytest
from cantools.database.can import Database
from cantools.j1939 import frame_id_pack

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from dbc.database import load_database, load_database_string
from dbc.errors import ConfigError
from dbc.machine import MachineConfig, load_machine_config, parse_machine_config
from tests.dbc.test_held_out_machines import PSI_PA, STRANGER, eq4_N, press_a
from tests.dbc.test_transducers import BASE, DATABASE, config_of
from tests.helpers import ROOT

UNITS_TOML = (STRANGER / "j1939_units.toml").read_text()
UNITS_DB = STRANGER / "j1939_units.dbc"
T0_S = 1_700_000_000.0


def units_config(text: str = UNITS_TOML) -> tuple[MachineConfig, Database]:
    database = load_database(UNITS_DB)
    return parse_machine_config(tomllib.loads(text), "m.toml", database, UNITS_DB), database


def units_refused(text: str) -> ConfigError:
    with pytest.raises(ConfigError) as info:
        units_config(text)
    assert "\n" not in str(info.value)
    return info.value


def xdcr(source: int, psi_or_bar: float, t_s: float) -> RawFrame:
    frame_id = int(frame_id_pack(6, 0, 0, 0xFF, 0x50, source))
    data = round(psi_or_bar / 0.001).to_bytes(4, "little", signed=True) + bytes(4)
    return RawFrame(t_s, frame_id, True, data)


def test_the_configs_cycle_times_stand_in_for_the_dbcs() -> None:
    config, database = units_config()
    assert all(message.cycle_time is None for message in database.messages)
    assert config.cycle_times_ms == {"XDCR": 20.0, "MC_STATE": 100.0}
    front = config.legs["front"]
    assert (front.cycle_time_s, front.max_skew_s) == (0.020, 0.020)  # default: one cycle
    assert config.protection["MC_STATE"].cycle_time_s == 0.100


def test_skew_and_staleness_are_judged_on_the_configs_cycle_time() -> None:
    config, database = units_config()
    pipeline = Pipeline.from_config(config, database)
    pipeline.process(xdcr(0x52, 80.0, T0_S))  # rod, bar
    (fresh,) = pipeline.process(xdcr(0x51, 2000.0, T0_S + 0.019)).estimates  # piston, psi
    assert fresh.valid and fresh.force_raw_N == pytest.approx(eq4_N(2000 * PSI_PA, 80e5))
    (late,) = pipeline.process(xdcr(0x51, 2000.0, T0_S + 0.0405)).estimates  # rod 40.5 ms old
    assert late.reasons == ("rod_stale",)
    pipeline.process(xdcr(0x52, 80.0, T0_S + 0.041))
    (fresh,) = pipeline.process(xdcr(0x51, 2000.0, T0_S + 0.041)).estimates
    assert fresh.valid
    # stale_after_cycles (3) x 20 ms after the last sample, on the frames' clock
    assert pipeline.snapshot(T0_S + 0.041 + 0.059).legs["front"].valid
    assert pipeline.snapshot(T0_S + 0.041 + 0.061).legs["front"].reasons[-1] == "stale"


def test_the_counter_resynchronises_after_a_turn_of_the_configs_cycle_time() -> None:
    """MC_STATE.Alive counts 0..15 every 100 ms (the config's): a jump within 1.6 s is a
    counter fault; after a longer silence the check starts anew (no DBC cycle time: never)."""
    config, database = units_config()
    pipeline = Pipeline.from_config(config, database)
    faults = [
        pipeline.process(RawFrame(T0_S + t_s, 0x310, False, bytes([0, alive]))).decoded
        for t_s, alive in ((0.0, 0), (1.0, 5), (3.0, 9), (3.1, 10))
    ]
    assert [frame.faults if frame else None for frame in faults] == [(), ("counter",), (), ()]


def test_the_config_wins_over_the_dbcs_cycle_time() -> None:
    config = config_of(BASE + "\n[messages.HYD_PRESS]\ncycle_time_ms = 25.5\n")
    assert DATABASE.get_message_by_name("HYD_PRESS").cycle_time == 10
    assert config.cycle_times_ms["HYD_PRESS"] == 25.5
    assert config.legs["J1"].cycle_time_s == 0.0255 and config.legs["J1"].max_skew_s == 0.0255
    assert config.legs["J2"].max_skew_s == 0.004  # a leg's own max_skew_s still wins
    assert config_of().cycle_times_ms["HYD_PRESS"] == 10.0


def test_a_message_without_a_cycle_time_names_the_key_to_add() -> None:
    error = units_refused(UNITS_TOML.replace("[messages.XDCR]\ncycle_time_ms = 20\n", ""))
    assert error.key == "legs.front.piston.signal"
    assert str(error) == (
        "m.toml: legs.front.piston.signal: message XDCR has no GenMsgCycleTime in the DBC: "
        "set [messages.XDCR] cycle_time_ms (staleness and skew are judged on it)"
    )


def refused_without_config_cycle_time(database: Database) -> ConfigError:
    """What the units machine is refused with when its config gives XDCR no cycle time."""
    with pytest.raises(ConfigError) as refused:
        parse_machine_config(
            tomllib.loads(UNITS_TOML.replace("[messages.XDCR]\ncycle_time_ms = 20\n", "")),
            "m.toml",
            database,
            UNITS_DB,
        )
    return refused.value


def test_a_dbc_cycle_time_that_is_no_period_is_none() -> None:
    """BA_ "GenMsgCycleTime" BO_ ... -5; (a typo; cantools does not check the attribute's
    range): it was taken, and the config stopped at the leg's max_skew_s, a key the user
    never set ("legs.front.max_skew_s: must be >= 0, got -0.005"). The DBC's -5 is told
    as what it is; the config's cycle time stands in for it."""
    text = UNITS_DB.read_text() + '\nBA_ "GenMsgCycleTime" BO_ 2566869246 -5;\n'
    database = load_database_string(text, "vendor.dbc")
    assert database.get_message_by_name("XDCR").cycle_time == -5
    config = parse_machine_config(tomllib.loads(UNITS_TOML), "m.toml", database, UNITS_DB)
    assert config.cycle_times_ms["XDCR"] == 20.0 and config.legs["front"].max_skew_s == 0.020
    refused = refused_without_config_cycle_time(database)
    assert str(refused) == (
        "m.toml: legs.front.piston.signal: message XDCR has GenMsgCycleTime -5, no period, "
        "in the DBC: set [messages.XDCR] cycle_time_ms (staleness and skew are judged on it)"
    )


def test_a_cycle_time_under_another_attribute_name_is_shown() -> None:
    """Some tools write a message's period as "CycleTime" (cantools reads GenMsgCycleTime
    only): the refusal shows it, so the user need not open the DBC to find the number."""
    text = UNITS_DB.read_text() + (
        '\nBA_DEF_ BO_ "CycleTime" INT 0 10000;\nBA_DEF_DEF_ "CycleTime" 0;\n'
        'BA_ "CycleTime" BO_ 2566869246 20;\n'
    )
    database = load_database_string(text, "vendor.dbc")
    refused = refused_without_config_cycle_time(database)
    assert str(refused) == (
        "m.toml: legs.front.piston.signal: message XDCR has no GenMsgCycleTime in the DBC "
        "(it has CycleTime 20: its period?): set [messages.XDCR] cycle_time_ms (staleness "
        "and skew are judged on it)"
    )


@pytest.mark.parametrize(
    ("value", "key", "reason"),
    [
        ("cycle_time_ms = 0", "messages.XDCR.cycle_time_ms", "must be at least 0.1 ms"),
        ("cycle_time_ms = -20", "messages.XDCR.cycle_time_ms", "must be at least 0.1 ms"),
        # Shorter than a frame on the bus: it also rounded to 0 ns in the simulator's
        # schedule, and portal-sim stopped with a traceback.
        ("cycle_time_ms = 1e-9", "messages.XDCR.cycle_time_ms", "must be at least 0.1 ms"),
        ("cycle_time_ms = nan", "messages.XDCR.cycle_time_ms", "must be"),
        ('cycle_time_ms = "20"', "messages.XDCR.cycle_time_ms", "must be a number"),
        ("cycle_time_ms = true", "messages.XDCR.cycle_time_ms", "must be a number"),
        ("cycle_time_ms = inf", "messages.XDCR.cycle_time_ms", "must be finite"),
        # A leg whose transducer died would never be stale (a slip: 10e6 for 10).
        ("cycle_time_ms = 10e6", "messages.XDCR.cycle_time_ms", "at most 3600000 ms (an hour"),
        ("cycle_time_ms = 1e300", "messages.XDCR.cycle_time_ms", "got 1e+300"),
        ("cycle_ms = 20", "messages.XDCR.cycle_ms", "unknown key"),
    ],
)
def test_a_bad_cycle_time_stops_the_config(value: str, key: str, reason: str) -> None:
    error = units_refused(UNITS_TOML.replace("cycle_time_ms = 20", value))
    assert error.key == key and reason in error.reason


def test_a_cycle_time_of_a_message_the_dbc_lacks_stops_the_config() -> None:
    error = units_refused(UNITS_TOML + "\n[messages.XDCR2]\ncycle_time_ms = 20\n")
    assert error.key == "messages.XDCR2" and "no message 'XDCR2' in the DBC" in error.reason


def test_a_bad_cycle_time_exits_2_with_one_line(tmp_path: Path) -> None:
    (tmp_path / "j1939_units.dbc").write_bytes(UNITS_DB.read_bytes())
    config = tmp_path / "machine.toml"
    config.write_text(UNITS_TOML.replace("cycle_time_ms = 100", "cycle_time_ms = 0"))
    (tmp_path / "x.log").write_text("")
    result = subprocess.run(
        [sys.executable, "-m", "daq", "replay", str(tmp_path / "x.log"), "--config", str(config)],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
    )
    assert result.returncode == 2, result.stderr
    assert result.stderr.strip() == (
        f"portal-daq: {config}: messages.MC_STATE.cycle_time_ms: "
        "must be at least 0.1 ms (the message's period; one frame takes about that long on "
        "the bus), got 0"
    )


def test_load_machine_config_reads_the_table_from_a_file() -> None:
    config, _ = load_machine_config(STRANGER / "j1939_units.toml")
    assert config.cycle_times_ms["MC_STATE"] == 100.0


FRONT_ROD = 'rod = { signal = "XDCR.Pressure", source_address = 0x52 }'


def test_a_transducer_may_have_its_own_cycle_time() -> None:
    """front's rod transducer (0x52) sends every 50 ms: the default skew of front's piston
    samples is 50 ms; rear's rod trigger (0x54, every 10 ms) is stale after 30 ms."""
    text = UNITS_TOML.replace(FRONT_ROD, FRONT_ROD.replace(" }", ", cycle_time_ms = 50 }"))
    text = text.replace(
        'source_address = 0x54, unit = "MPa" }',
        'source_address = 0x54, unit = "MPa", cycle_time_ms = 10 }',
    )
    config, database = units_config(text)
    assert config.sender_cycle_times_ms == {("XDCR", 0x52): 50.0, ("XDCR", 0x54): 10.0}
    assert (config.cycle_time_ms("XDCR", 0x52), config.cycle_time_ms("XDCR", 0x51)) == (50, 20)
    front, rear = config.legs["front"], config.legs["rear"]
    assert (front.cycle_time_s, front.max_skew_s) == (0.020, 0.050)
    assert (rear.cycle_time_s, rear.max_skew_s) == (0.010, 0.020)
    pipeline = Pipeline.from_config(config, database)
    pipeline.process(xdcr(0x52, 80.0, T0_S))
    (estimate,) = pipeline.process(xdcr(0x51, 2000.0, T0_S + 0.045)).estimates
    assert estimate.valid
    pipeline.process(xdcr(0x53, 1500.0, T0_S + 0.045))
    pipeline.process(xdcr(0x54, 4.5, T0_S + 0.046))
    assert pipeline.snapshot(T0_S + 0.046 + 0.029).legs["rear"].valid
    assert not pipeline.snapshot(T0_S + 0.046 + 0.031).legs["rear"].valid


def test_one_transducer_has_one_cycle_time() -> None:
    text = UNITS_TOML.replace(FRONT_ROD, FRONT_ROD.replace(" }", ", cycle_time_ms = 50 }"))
    text = text.replace('source_address = 0x54, unit = "MPa"', "source_address = 0x52")
    error = units_refused(text)
    assert error.key == "legs.rear.rod"
    assert "XDCR@0x52 is sent every 20 ms here and every 50 ms for legs.front.rod" in error.reason


@pytest.mark.parametrize(
    ("chamber", "key", "reason"),
    [
        (
            '{ signal = "XDCR.Pressure", source_address = 0x52, cycle_time_ms = 0 }',
            "rod.cycle_time_ms",
            "must be at least 0.1 ms",
        ),
        (
            '{ signal = "XDCR.Pressure", source_address = 0x52, cycle_time_ms = "50" }',
            "rod.cycle_time_ms",
            "must be a number",
        ),
    ],
)
def test_a_bad_transducer_cycle_time_stops_the_config(chamber: str, key: str, reason: str) -> None:
    error = units_refused(UNITS_TOML.replace(FRONT_ROD, f"rod = {chamber}"))
    assert error.key == f"legs.front.{key}" and reason in error.reason


def test_a_cycle_time_on_a_chamber_reading_every_sender_is_refused() -> None:
    text = BASE.replace(
        'rod = "LEG_PSI.pRod"', 'rod = { signal = "LEG_PSI.pRod", cycle_time_ms = 5 }'
    )
    with pytest.raises(ConfigError) as info:
        config_of(text)
    assert info.value.key == "legs.PSI.rod.cycle_time_ms"
    assert "for the message: [messages.LEG_PSI] cycle_time_ms" in info.value.reason


def test_a_transducers_counter_resynchronises_on_its_own_cycle_time() -> None:
    """PRESS_A (20 ms in the DBC, a 4-bit counter per sender): 0x31 sends every 100 ms, so
    a jump 1 s after its last frame is within a counter turn (1.6 s): a counter fault;
    0x30's turn is 0.32 s, after which its check starts anew."""
    text = (STRANGER / "j1939_propa.toml").read_text()
    rod = 'source_address = 0x31, status = "Diag" }'
    assert rod in text
    database = load_database(STRANGER / "j1939_propa.dbc")
    config = parse_machine_config(
        tomllib.loads(text.replace(rod, rod.replace(" }", ", cycle_time_ms = 100 }"))),
        "m.toml",
        database,
    )
    assert config.protection["PRESS_A"].sender_cycle_times_s == ((0x31, 0.1),)
    pipeline = Pipeline.from_config(config, database)
    faults = {}
    for source in (0x30, 0x31):
        for t_s, counter in ((0.0, 0), (1.0, 5)):
            frame = replace(press_a(6, 0xFE, source, counter, 1000), t_s=T0_S + t_s)
            decoded = pipeline.process(frame).decoded
            assert decoded is not None
            faults[(source, t_s)] = decoded.faults
    assert faults[(0x30, 1.0)] == () and faults[(0x31, 1.0)] == ("counter",)


def test_a_legs_cycle_time_is_set_where_its_trigger_chamber_takes_it() -> None:
    """What the report and the restart warning tell the user to set: a message's cycle
    time, or a J1939 transducer's own (one sender of a shared PGN)."""
    example, _ = load_machine_config(ROOT / "dbc" / "machine.example.toml")
    assert example.legs["SB1_F1"].cycle_time_key == "[messages.LEG_SB1_F1] cycle_time_ms"
    j1939, _ = load_machine_config(STRANGER / "xdcr_two_rates.toml")
    assert j1939.legs["A1"].cycle_time_key == "legs.A1.piston.cycle_time_ms"
