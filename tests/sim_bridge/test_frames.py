"""Frames built from a simulation row decode back to the row's values within quantization."""

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from dbc.decoding import FrameDecoder
from dbc.encoding import FrameEncoder
from dbc.errors import ConfigError
from dbc.machine import load_machine_config, parse_machine_config
from sim_bridge.faults import FaultConfig, FaultWindow
from sim_bridge.frames import FrameBuilder, LegOverride, Timeline
from sim_bridge.result import BASES, LEGS, PHASES, SimulationResult
from sim_bridge.schedule import instants, schedule
from tests.helpers import EXAMPLE_CONFIG, ROOT
from tests.sim_bridge.synthetic import (
    CONFIG,
    DATABASE,
    frames_of,
    make_playout,
    make_result,
    play,
    played_estimates,
    small_machine,
)

#: Half a step of each signal's scale: the most rounding may move a value.
PRESSURE_TOLERANCE_PA = 500.0


def decode_row(result: SimulationResult, row: int, cycle: int = 0) -> dict[str, dict]:
    builder = FrameBuilder(CONFIG, DATABASE)
    encoder = FrameEncoder(DATABASE, CONFIG.protection)
    decoder = FrameDecoder(DATABASE, CONFIG.protection)
    decoded = {}
    for message, signals in builder.frames(result, row, builder.messages, cycle):
        frame = encoder.encode(message, signals)
        out = decoder.decode(frame.arbitration_id, frame.data, 0.0)
        assert out.crc_ok and out.counter_ok
        decoded[message] = dict(out.signals)
    return decoded


@pytest.mark.parametrize("row", [0, 37, 150, 199])
def test_every_message_decodes_back_to_the_row(result: SimulationResult, row: int) -> None:
    decoded = decode_row(result, row, cycle=3)
    for i, leg in enumerate(LEGS):
        signals = decoded[f"LEG_{leg}"]
        assert signals[f"{leg}_pPiston"] == pytest.approx(
            result.p_piston_Pa[row, i], abs=PRESSURE_TOLERANCE_PA
        )
        assert signals[f"{leg}_pRod"] == pytest.approx(
            result.p_rod_Pa[row, i], abs=PRESSURE_TOLERANCE_PA
        )
        assert signals[f"{leg}_Status"] == "ok"
        base = leg[:3]
        assert decoded[f"STROKE_{base}"][f"{leg}_Stroke"] == pytest.approx(
            result.stroke_m[row, i], abs=0.5e-4
        )
    for b, base in enumerate(BASES):
        incl = decoded[f"INCL_{base}"]
        assert incl[f"INCL_{base}_pPiston"] == pytest.approx(
            result.incl_p_piston_Pa[row, b], abs=PRESSURE_TOLERANCE_PA
        )
        assert incl[f"INCL_{base}_pRod"] == pytest.approx(
            result.incl_p_rod_Pa[row, b], abs=PRESSURE_TOLERANCE_PA
        )
        assert incl[f"INCL_{base}_Status"] == "ok"
        assert decoded["BRIDGE_POSE"][f"{base}_InclinationAngle"] == pytest.approx(
            result.inclination_deg[row, b], abs=0.005
        )
    assert decoded["BRIDGE_POSE"]["Bridge_FoldAngle"] == pytest.approx(
        result.fold_deg[row], abs=0.005
    )
    motion = decoded["BRIDGE_MOTION"]
    assert motion["Bridge_RotationAngle"] == pytest.approx(result.rotation_deg[row], abs=0.005)
    assert motion["Carriage_Position"] == pytest.approx(result.carriage_m[row], abs=0.0005)
    state = decoded["MACHINE_STATE"]
    assert state["Machine_Phase"] == PHASES[result.phase[row]]
    assert state["Machine_CycleCount"] == 3
    assert state["Machine_CycleTime"] == pytest.approx(result.t_s[row], abs=0.005)


def test_values_outside_the_dbc_range_are_clipped_into_it(result: SimulationResult) -> None:
    result.p_piston_Pa[5, 0] = 80e6
    result.p_rod_Pa[5, 0] = -5e6
    result.stroke_m[5, 1] = 3.0
    result.fold_deg[5] = -20.0
    result.carriage_m[5] = np.nan
    decoded = decode_row(result, 5)
    assert decoded["LEG_SB1_F1"]["SB1_F1_pPiston"] == 64_535_000
    assert decoded["LEG_SB1_F1"]["SB1_F1_pRod"] == -1_000_000
    assert decoded["STROKE_SB1"]["SB1_F2_Stroke"] == pytest.approx(2.5)
    assert decoded["BRIDGE_POSE"]["Bridge_FoldAngle"] == pytest.approx(-5.0)
    assert decoded["BRIDGE_MOTION"]["Carriage_Position"] == 0.0


def test_a_leg_override_replaces_the_values_and_is_not_clipped_to_the_sensor_range(
    result: SimulationResult,
) -> None:
    builder = FrameBuilder(CONFIG, DATABASE)
    overrides = {"SB1_F2": LegOverride(45e6, 1e6, "sensor_fault")}
    signals = builder.signals("LEG_SB1_F2", result, 10, 0, overrides)
    assert signals == {"SB1_F2_pPiston": 45e6, "SB1_F2_pRod": 1e6, "SB1_F2_Status": "sensor_fault"}
    untouched = builder.signals("LEG_SB1_F1", result, 10, 0, overrides)
    assert untouched["SB1_F1_pPiston"] == result.p_piston_Pa[10, 0]


def test_the_leg_messages_follow_the_config_mapping(result: SimulationResult) -> None:
    # Swap where SB1_F1 and SB1_F2 are on the bus: the frames must swap, not the code.
    data = tomllib.loads(EXAMPLE_CONFIG.read_text())
    legs = data["legs"]
    legs["SB1_F1"], legs["SB1_F2"] = legs["SB1_F2"], legs["SB1_F1"]
    config = parse_machine_config(data, "swapped.toml", DATABASE)
    builder = FrameBuilder(config, DATABASE)
    signals = builder.signals("LEG_SB1_F2", result, 20, 0)
    assert signals["SB1_F2_pPiston"] == result.p_piston_Pa[20, LEGS.index("SB1_F1")]
    assert builder.leg_messages["SB1_F1"] == "LEG_SB1_F2"


def test_a_config_leg_the_simulation_lacks_is_refused() -> None:
    data = tomllib.loads(EXAMPLE_CONFIG.read_text())
    data["legs"]["FRONT"] = data["legs"].pop("SB1_F1")
    del data["stability"]  # it names the feet of the example's legs
    config = parse_machine_config(data, "renamed.toml", DATABASE)
    with pytest.raises(ConfigError, match=r"renamed.toml: legs.FRONT: the simulation has no leg"):
        FrameBuilder(config, DATABASE)


def test_a_config_without_a_leg_does_not_send_its_message(result: SimulationResult) -> None:
    data = tomllib.loads(EXAMPLE_CONFIG.read_text())
    del data["legs"]["SB2_F3"]
    del data["stability"]  # it names the feet of the example's legs
    builder = FrameBuilder(parse_machine_config(data, "five.toml", DATABASE), DATABASE)
    assert "LEG_SB2_F3" not in builder.messages
    assert builder.skipped == ["LEG_SB2_F3"]
    assert "MACHINE_STATE" in builder.messages


def test_timeline_holds_each_row_until_the_next_and_loops() -> None:
    timeline = Timeline(n_rows=100, dt_s=0.02)
    assert timeline.cycle_ns == 2_000_000_000
    assert timeline.position(0) == timeline.position(10_000_000)  # zero-order hold
    assert timeline.position(30_000_000).row == 1
    late = timeline.position(2_000_000_000 * 3 + 40_000_000)
    assert (late.cycle, late.row, late.t_cycle_s) == (3, 2, 0.04)


def test_played_rows_follow_the_simulation_time() -> None:
    result = make_result(duration_s=0.5)
    played = play(result, end_s=1.2)
    legs = frames_of(played, "LEG_SB1_F1")
    assert len(legs) == 120
    rows = [step.row for step in played]
    assert rows[:3] == [0, 1, 2] and rows[50] == 0 and rows[-1] == 19
    cycles = [f.signals["Machine_CycleCount"] for f in frames_of(played, "MACHINE_STATE")]
    assert cycles == [0] * 5 + [1] * 5 + [2] * 2
    assert all(frame.counter_ok and frame.crc_ok for step in played for frame in step.frames)


def test_the_pose_signals_of_the_stability_config_carry_the_bridge_pose(
    result: SimulationResult,
) -> None:
    """A DBC naming the bridge angles its own way: the bridge finds them through
    ``[stability]`` (not by the project's names), so the service's margin sees the pose."""
    from dbc.database import load_database_string
    from dbc.machine import DEFAULT_DBC_PATH

    text = DEFAULT_DBC_PATH.read_text(encoding="cp1252")
    renamed = text.replace("Bridge_RotationAngle", "RotAngle").replace("Bridge_FoldAngle", "Fold")
    database = load_database_string(renamed, "renamed.dbc")
    data = tomllib.loads(EXAMPLE_CONFIG.read_text())
    data["stability"]["rotation"] = "BRIDGE_MOTION.RotAngle"
    data["stability"]["fold"] = "BRIDGE_POSE.Fold"
    builder = FrameBuilder(parse_machine_config(data, "renamed.toml", database), database)
    row = 150  # the bridge rotated and folded
    motion = builder.signals("BRIDGE_MOTION", result, row, 0)
    pose = builder.signals("BRIDGE_POSE", result, row, 0)
    assert motion["RotAngle"] == pytest.approx(result.rotation_deg[row])
    assert pose["Fold"] == pytest.approx(result.fold_deg[row])
    assert not {"BRIDGE_MOTION.RotAngle", "BRIDGE_POSE.Fold"} & set(builder.defaulted)


def test_the_bridge_angles_go_out_in_the_unit_of_their_signal(result: SimulationResult) -> None:
    """A DBC (or config) whose bridge angles are in radians gets radians, not degrees."""
    data = tomllib.loads(EXAMPLE_CONFIG.read_text())
    data["stability"]["rotation"] = {
        "signal": "BRIDGE_MOTION.Bridge_RotationAngle",
        "unit": "rad",
    }
    builder = FrameBuilder(parse_machine_config(data, "rad.toml", DATABASE), DATABASE)
    row = 150  # the bridge rotated and folded
    motion = builder.signals("BRIDGE_MOTION", result, row, 0)
    pose = builder.signals("BRIDGE_POSE", result, row, 0)
    assert result.rotation_deg[row] > 10.0
    assert motion["Bridge_RotationAngle"] == pytest.approx(math.radians(result.rotation_deg[row]))
    assert pose["Bridge_FoldAngle"] == pytest.approx(result.fold_deg[row])


def test_pressures_found_by_name_go_out_in_the_unit_of_their_signal(
    result: SimulationResult, tmp_path: Path
) -> None:
    """The e2e example's inclination cylinders are in MPa ([-0.1|65.435]): their Pa were
    clipped against that range as if it were Pa (65.435 Pa at most), so the bridge sent
    ~0 MPa for every row. A pressure nobody supplies (here one in bar, [1|400]) is
    clipped in its unit too: 1 bar, not 1 Pa (below the range: cantools refused it)."""
    example = ROOT / "daq" / "examples" / "e2e"
    extra = ' SG_ INCL_SB1_pAccu : 48|16@1+ (0.01,0) [1|400] "bar" PortalDAQ\n'
    text = (example / "e2e_sensors.dbc").read_text(encoding="cp1252")
    after = text.index("\n", text.index(" SG_ INCL_SB1_pRod ")) + 1
    (tmp_path / "e2e_sensors.dbc").write_text(text[:after] + extra + text[after:], "cp1252")
    (tmp_path / "portal-daq.toml").write_text((example / "portal-daq.toml").read_text())
    config, database = load_machine_config(tmp_path / "portal-daq.toml")
    builder = FrameBuilder(config, database)
    encoder = FrameEncoder.from_config(config, database)
    decoder = FrameDecoder(database, config.protection, config.unit_factors)
    row = 37
    decoded = {}
    for b, base in enumerate(BASES):
        frame = encoder.encode(f"INCL_{base}", builder.signals(f"INCL_{base}", result, row, 0))
        signals = decoded[base] = decoder.decode(frame.arbitration_id, frame.data, 0.0).signals
        assert signals[f"INCL_{base}_pPiston"] == pytest.approx(
            result.incl_p_piston_Pa[row, b], abs=PRESSURE_TOLERANCE_PA
        )
        assert signals[f"INCL_{base}_pRod"] == pytest.approx(
            result.incl_p_rod_Pa[row, b], abs=PRESSURE_TOLERANCE_PA
        )
    assert decoded["SB1"]["INCL_SB1_pAccu"] == pytest.approx(1e5)
    assert "INCL_SB1.INCL_SB1_pAccu" in builder.defaulted


def test_a_chamber_of_any_sender_is_in_the_frames_of_the_pinned_one(
    result: SimulationResult, tmp_path: Path
) -> None:
    """A J1939 message of two pressures whose piston is pinned to 0x21 and whose rod reads
    any sender: the bridge sent the rod from the DBC's ID (source address 0x21 too) with
    the piston 0, and from 0x21 with the rod 0, so both chambers read 0 every other
    frame. One sender now carries both."""
    config, database = small_machine(
        tmp_path,
        """
BO_ 2566856737 HYD: 8 Hub
 SG_ P1 : 0|16@1+ (1000,0) [0|65535000] "Pa" DAQ
 SG_ P2 : 16|16@1+ (1000,0) [0|65535000] "Pa" DAQ
""",
        'BA_ "GenMsgCycleTime" BO_ 2566856737 10;\nBA_ "VFrameFormat" BO_ 2566856737 3;\n',
        '[legs.SB1_F1]\npiston = { signal = "HYD.P1", source_address = 0x21 }\nrod = "HYD.P2"\n',
    )
    builder = FrameBuilder(config, database)
    pipeline = Pipeline.from_config(config, database)
    encoder = FrameEncoder.from_config(config, database)
    estimates = []
    for row in range(20):
        for sender, signals in builder.frames(result, row, builder.messages, 0):
            message, address = builder.target(sender)
            frame = encoder.encode(message, signals, source_address=address)
            raw = RawFrame(0.01 * row, frame.arbitration_id, True, frame.data)
            estimates += pipeline.process(raw).estimates
    assert [(e.p_piston_Pa, e.p_rod_Pa) for e in estimates] == [
        (pytest.approx(p, abs=500), pytest.approx(r, abs=500))
        for p, r in zip(result.p_piston_Pa[:20, 0], result.p_rod_Pa[:20, 0], strict=True)
    ]
    assert builder.messages == ["HYD@0x21"]  # no frame of the DBC's ID besides


def test_angles_found_by_name_go_out_in_the_unit_of_their_signal(
    result: SimulationResult,
) -> None:
    """Without [stability] the bridge finds the angles by name; a DBC with them in radians
    got degrees (the service's /signals and recordings then showed 57x the angle)."""
    from dbc.database import load_database_string
    from dbc.machine import DEFAULT_DBC_PATH

    text = DEFAULT_DBC_PATH.read_text(encoding="cp1252")
    text = text.replace(
        'Bridge_FoldAngle : 32|16@1- (0.01,0) [-5|95] "deg"',
        'Bridge_FoldAngle : 32|16@1- (0.0001,0) [-0.1|1.7] "rad"',
    )
    text = text.replace(
        'SB1_InclinationAngle : 0|16@1- (0.01,0) [-12|12] "deg"',
        'SB1_InclinationAngle : 0|16@1- (0.01,0) [-210|210] "mrad"',
    )
    assert text.count('"rad"') == 1 and text.count('"mrad"') == 1
    database = load_database_string(text, "radians.dbc")
    data = tomllib.loads(EXAMPLE_CONFIG.read_text())
    del data["stability"]
    builder = FrameBuilder(parse_machine_config(data, "radians.toml", database), database)
    row = 150  # the bridge folded, SB2 lifted by its inclination
    pose = builder.signals("BRIDGE_POSE", result, row, 0)
    assert result.fold_deg[row] > 10.0
    assert pose["Bridge_FoldAngle"] == pytest.approx(math.radians(result.fold_deg[row]), abs=1e-4)
    assert pose["SB1_InclinationAngle"] == pytest.approx(
        1000 * math.radians(result.inclination_deg[row, 0]), abs=0.01
    )
    assert pose["SB2_InclinationAngle"] == pytest.approx(result.inclination_deg[row, 1], abs=0.01)
    assert abs(result.inclination_deg[row, 0]) > 1.0  # 1.25 deg: 21.8 mrad


def test_a_leg_whose_rod_is_in_a_message_of_its_own_pairs_from_its_first_sample(
    result: SimulationResult, tmp_path: Path
) -> None:
    """Pistons at 10 ms in CAP, rods at 50 ms in ROD (after CAP in the DBC): the bridge
    sent CAP first in an instant, so the first sample had no rod (rod_stale), and every
    fifth one paired the rod of 50 ms before, stale by any jitter of a live run."""
    config, database = small_machine(
        tmp_path,
        """
BO_ 768 CAP: 2 Hub
 SG_ pCap : 0|16@1+ (1000,0) [0|65535000] "Pa" DAQ

BO_ 769 ROD: 2 Hub
 SG_ pRod : 0|16@1+ (1000,0) [0|65535000] "Pa" DAQ
""",
        'BA_ "GenMsgCycleTime" BO_ 768 10;\nBA_ "GenMsgCycleTime" BO_ 769 50;\n',
        '[legs.front]\npiston = "CAP.pCap"\nrod = "ROD.pRod"\n',
    )
    playout = make_playout(result, config=config, database=database)
    assert [cycle.message for cycle in playout.cycles] == ["ROD", "CAP"]
    pipeline = Pipeline.from_config(config, database)
    estimates = played_estimates(playout, pipeline, 200_000_000)
    assert len(estimates) == 20 and all(e.valid for e, _ in estimates)
    assert [e.p_rod_Pa for e, _ in estimates] == [
        pytest.approx(result.p_rod_Pa[row - row % 5, 0], abs=500) for _, row in estimates
    ]


def test_out_of_range_goes_beyond_a_dbc_range_that_ends_below_it(
    result: SimulationResult, tmp_path: Path
) -> None:
    """A 250 bar transducer's DBC ([0|250] in 16 bits at 0.01 bar): --out-of-range's
    45 MPa was clipped to 250 bar, a valid sample; now it goes out as 450 bar (what the
    bits hold), beyond the DBC's range, and the service flags it."""
    config, database = small_machine(
        tmp_path,
        """
BO_ 768 HYD: 4 Hub
 SG_ pCap : 0|16@1+ (0.01,0) [0|250] "bar" DAQ
 SG_ pRod : 16|16@1+ (0.01,0) [0|250] "bar" DAQ
""",
        'BA_ "GenMsgCycleTime" BO_ 768 10;\n',
        '[legs.front]\npiston = "HYD.pCap"\nrod = "HYD.pRod"\n',
    )
    faults = FaultConfig(seed=1, out_of_range=(FaultWindow("front", 0.05, 0.05),))
    playout = make_playout(result, faults, config=config, database=database)
    pipeline = Pipeline.from_config(config, database)
    estimates, sent_Pa = [], []
    for instant in instants(schedule(playout.cycles, end_sim_ns=200_000_000)):
        _, outgoing = playout.frames(instant)
        for item in outgoing:
            frame = item.frame
            processed = pipeline.process(
                RawFrame(instant.sim_t_ns / 1e9, frame.arbitration_id, False, frame.data)
            )
            estimates += processed.estimates
            assert processed.decoded is not None
            sent_Pa.append(processed.decoded.signals["pCap"])
    assert [e.reasons for e in estimates] == [()] * 5 + [("range",)] * 5 + [()] * 10
    assert sent_Pa[5:10] == [pytest.approx(45e6)] * 5  # on /signals; the estimate's is NaN


@pytest.mark.parametrize(
    ("piston", "top_Pa"),
    [
        ('0|16@1+ (0.1,0) [0|3000] "psi"', 3000 * 6894.757293168361),  # a 3000 psi transducer
        ('0|12@1+ (0.05,0) [0|204.75] "bar"', 204.75e5),  # 12 bits, the range all they hold
    ],
    ids=["range-below-the-bits", "range-of-all-the-bits"],
)
def test_a_simulated_pressure_beyond_the_transducer_is_flagged_not_sent_as_its_top(
    result: SimulationResult, tmp_path: Path, piston: str, top_Pa: float
) -> None:
    """The simulation's piston pressure above a transducer's range (216 bar on a 3000
    psi, 206.8 bar, one): it was sent as the range's top, a valid sample 10 bar short of
    the truth; now it goes out beyond the range, or as the last value the bits hold
    (saturated), and the service flags it ``range``."""
    config, database = small_machine(
        tmp_path,
        f"""
BO_ 768 HYD: 4 Hub
 SG_ pCap : {piston} DAQ
 SG_ pRod : 16|16@1+ (0.1,0) [0|6000] "bar" DAQ
""",
        'BA_ "GenMsgCycleTime" BO_ 768 10;\n',
        '[legs.front]\npiston = "HYD.pCap"\nrod = "HYD.pRod"\n',
    )
    result.p_piston_Pa[5:10, 0] = top_Pa + 10e5
    playout = make_playout(result, config=config, database=database)
    pipeline = Pipeline.from_config(config, database)
    estimates = played_estimates(playout, pipeline, 200_000_000)
    assert [e.reasons for e, _ in estimates] == [()] * 5 + [("range",)] * 5 + [()] * 10
    for estimate, row in estimates:
        if estimate.valid:
            assert estimate.p_piston_Pa == pytest.approx(result.p_piston_Pa[row, 0], abs=3500)
        else:
            assert math.isnan(estimate.p_piston_Pa)


def test_strokes_carriage_and_time_in_cycle_go_out_in_the_unit_of_their_signal(
    result: SimulationResult, caplog: pytest.LogCaptureFixture
) -> None:
    """A DBC with the strokes and the carriage in mm and the time in cycle in ms got
    metres and seconds (a 1.2 m stroke went out as 1.2 mm, the service's /signals and
    recordings showed it, and the report read a time in cycle of 22,500 ms as 22.5 ms).
    A unit that is no length (here "%") is named once at load, its values taken in m."""
    from dbc.database import load_database_string
    from dbc.machine import DEFAULT_DBC_PATH

    text = DEFAULT_DBC_PATH.read_text(encoding="cp1252")
    for old, new in (
        (
            'SB1_F1_Stroke : 0|16@1+ (0.0001,0) [0|2.5] "m"',
            'SB1_F1_Stroke : 0|16@1+ (0.1,0) [0|2500] "mm"',
        ),
        (
            'SB1_F2_Stroke : 16|16@1+ (0.0001,0) [0|2.5] "m"',
            'SB1_F2_Stroke : 16|16@1+ (0.01,0) [0|250] "cm"',
        ),
        (
            'Carriage_Position : 16|16@1- (0.001,0) [-10|10] "m"',
            'Carriage_Position : 16|16@1- (1,0) [-10000|10000] "mm"',
        ),
        (
            'Machine_CycleTime : 24|16@1+ (0.01,0) [0|655.35] "s"',
            'Machine_CycleTime : 24|16@1+ (10,0) [0|655350] "ms"',
        ),
    ):
        assert text.count(old) == 1
        text = text.replace(old, new)
    database = load_database_string(text, "millimetres.dbc")
    data = tomllib.loads(EXAMPLE_CONFIG.read_text())
    config = parse_machine_config(data, "mm.toml", database)
    assert (config.signals.carriage_m_per_unit, config.signals.cycle_time_s_per_unit) == (
        0.001,
        0.001,
    )
    builder = FrameBuilder(config, database)
    row = 150
    strokes = builder.signals("STROKE_SB1", result, row, 0)
    assert result.stroke_m[row, 0] > 0.1 and result.stroke_m[row, 1] > 0.1
    assert strokes["SB1_F1_Stroke"] == pytest.approx(1000 * result.stroke_m[row, 0], abs=0.05)
    assert strokes["SB1_F2_Stroke"] == pytest.approx(100 * result.stroke_m[row, 1], abs=0.005)
    assert strokes["SB1_F3_Stroke"] == pytest.approx(result.stroke_m[row, 2], abs=1e-4)
    assert abs(result.carriage_m[row]) > 0.1
    motion = builder.signals("BRIDGE_MOTION", result, row, 0)
    assert motion["Carriage_Position"] == pytest.approx(1000 * result.carriage_m[row], abs=0.5)
    state = builder.signals("MACHINE_STATE", result, row, 0)
    assert result.t_s[row] > 1.0
    assert state["Machine_CycleTime"] == pytest.approx(1000 * result.t_s[row], abs=5)
    assert not caplog.records
    percent = text.replace('[-10000|10000] "mm"', '[-10000|10000] "%"')
    config = parse_machine_config(data, "mm.toml", load_database_string(percent, "p.dbc"))
    assert config.signals.carriage_m_per_unit == 1.0
    assert [r.getMessage() for r in caplog.records] == [
        "mm.toml: signals.carriage: BRIDGE_MOTION.Carriage_Position has unit '%', none of "
        "m, cm, mm: its values are taken in m"
    ]
