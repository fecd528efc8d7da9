"""A held-out-style machine (tests/files/renamed: the default DBC with every message,
signal, frame ID and leg renamed, legs and feet listed out of order) played by the
bridge: each config leg carries its simulated leg's pressures, bit for bit what the
DBC's quantization allows, the faults take the config's leg names, and the truth
names the config's legs."""

import csv
import tomllib
import uuid
from collections import defaultdict
from pathlib import Path

import can
import numpy as np
import pytest
from cantools.database.can import Database

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from dbc.decoding import FrameDecoder
from dbc.errors import ConfigError
from dbc.machine import MachineConfig, load_machine_config, parse_machine_config
from sim_bridge.__main__ import cli
from sim_bridge.faults import FaultConfig, FaultWindow
from sim_bridge.leg_map import leg_map
from sim_bridge.plot import cycle_figure
from sim_bridge.result import LEGS, SimulationResult
from sim_bridge.schedule import instants, schedule
from tests.helpers import ROOT
from tests.sim_bridge.synthetic import make_playout, make_result, write_export
from tests.sim_bridge.test_leg_map import RENAMED, RENAMED_LEGS

CONFIG, DATABASE = load_machine_config(RENAMED)
J1939_EXAMPLE = ROOT / "daq" / "examples" / "j1939" / "portal-daq.toml"
#: The renamed DBC's pressure signals: 1000 Pa per bit, offset -1 MPa (the default's).
SCALE_PA, OFFSET_PA = 1000.0, -1.0e6


def quantized_Pa(p_Pa: float) -> float:
    """What a pressure is after encoding and decoding with the DBC's scale and offset."""
    return round((p_Pa - OFFSET_PA) / SCALE_PA) * SCALE_PA + OFFSET_PA


def camel(leg: str) -> str:
    return "".join(part.capitalize() for part in leg.split("_"))


def test_the_fixture_is_the_default_dbc_renamed() -> None:
    pressure = DATABASE.get_message_by_name("HYD_NEAR_TIP").get_signal_by_name("NearTip_pCap")
    assert (pressure.scale, pressure.offset) == (SCALE_PA, OFFSET_PA)
    names = {m.name for m in DATABASE.messages} | {
        s.name for m in DATABASE.messages for s in m.signals
    }
    assert not any("SB1" in name or "SB2" in name for name in names)


def test_each_config_leg_carries_its_simulated_legs_pressures_exactly() -> None:
    result = make_result(duration_s=1.0)
    playout = make_playout(result, FaultConfig(seed=1), CONFIG, DATABASE)
    decoder = FrameDecoder(DATABASE, CONFIG.protection)
    pipeline = Pipeline.from_config(CONFIG, DATABASE)
    seen = {leg: 0 for leg in CONFIG.legs}
    for instant in instants(schedule(playout.cycles, end_sim_ns=round(1e9))):
        position, outgoing = playout.frames(instant)
        row = position.row
        for item in outgoing:
            frame = item.frame
            t_s = 1000.0 + instant.sim_t_ns / 1e9
            decoded = decoder.decode(frame.arbitration_id, frame.data, t_s)
            assert decoded.crc_ok and decoded.counter_ok
            if decoded.message.startswith("STROKES_"):
                for leg, value in decoded.signals.items():
                    if leg.endswith("_Stroke"):  # named after the config leg
                        column = LEGS.index(RENAMED_LEGS[leg.removesuffix("_Stroke")])
                        assert value == pytest.approx(result.stroke_m[row, column], abs=0.5e-4)
            raw = RawFrame(t_s, frame.arbitration_id, frame.is_extended_id, frame.data)
            for estimate in pipeline.process(raw).estimates:
                column = LEGS.index(RENAMED_LEGS[estimate.leg])
                assert estimate.valid, estimate
                assert estimate.p_piston_Pa == quantized_Pa(result.p_piston_Pa[row, column])
                assert estimate.p_rod_Pa == quantized_Pa(result.p_rod_Pa[row, column])
                assert decoded.message == f"HYD_{estimate.leg.upper()}"
                assert decoded.signals[f"{camel(estimate.leg)}_Health"] == "ok"
                seen[estimate.leg] += 1
    assert seen == {leg: 100 for leg in CONFIG.legs}
    assert pipeline.bad == {} and pipeline.frames_lost == 0


def test_the_bridge_angles_go_where_stability_says(result: SimulationResult) -> None:
    playout = make_playout(result, FaultConfig(seed=1), CONFIG, DATABASE)
    decoder = FrameDecoder(DATABASE, CONFIG.protection)
    for instant in instants(schedule(playout.cycles, end_sim_ns=round(0.2e9))):
        position, outgoing = playout.frames(instant)
        for item in outgoing:
            decoded = decoder.decode(item.frame.arbitration_id, item.frame.data, 0.0)
            if decoded.message == "BRIDGE_DRIVE":
                assert decoded.signals["BridgeYaw_deg"] == pytest.approx(
                    result.rotation_deg[position.row], abs=0.005
                )
            if decoded.message == "BRIDGE_GEOMETRY":
                assert decoded.signals["BridgeFold_deg"] == pytest.approx(
                    result.fold_deg[position.row], abs=0.005
                )


def test_faults_name_the_config_legs(result: SimulationResult) -> None:
    W = FaultWindow.parse
    faults = FaultConfig(
        stuck=(W("near_left@0.3:0.4"),),
        silent=(W("far_tip@0.5:0.25"),),
        sensor_fault=(W("far_right@0.1:0.1"),),
        seed=1,
    )
    playout = make_playout(result, faults, CONFIG, DATABASE)
    decoder = FrameDecoder(DATABASE, CONFIG.protection)
    column = LEGS.index("SB1_F2")  # near_left's simulated leg
    health = []
    for instant in instants(schedule(playout.cycles, end_sim_ns=round(1e9))):
        position, outgoing = playout.frames(instant)
        t_s = instant.sim_t_ns / 1e9
        for item in outgoing:
            decoded = decoder.decode(item.frame.arbitration_id, item.frame.data, t_s)
            if decoded.message == "HYD_NEAR_LEFT":
                row = 30 if 0.3 <= t_s < 0.7 - 1e-9 else position.row
                assert decoded.signals["NearLeft_pCap"] == quantized_Pa(
                    result.p_piston_Pa[row, column]
                )
            if decoded.message == "HYD_FAR_RIGHT":
                health.append(decoded.signals["FarRight_Health"])
    assert playout.counts.silent == {"HYD_FAR_TIP": 25}
    assert health == ["ok"] * 10 + ["sensor_fault"] * 10 + ["ok"] * 80


def test_the_bridge_command_plays_it_and_the_truth_names_its_legs(tmp_path: Path) -> None:
    result = make_result(duration_s=0.5)
    data, mapping = write_export(tmp_path, result)
    # the export's mapping may name the config's legs (SB1's here) or the simulation's
    text = mapping.read_text()
    for leg in ("near_tip", "near_left", "near_right"):
        text = text.replace(f"[legs.{RENAMED_LEGS[leg]}]", f"[legs.{leg}]")
    mapping.write_text(text)
    channel, truth_csv = f"renamed-{uuid.uuid4()}", tmp_path / "truth.csv"
    args = ["--config", str(RENAMED), "--interface", "virtual", "--channel", channel]
    args += ["--input", str(data), "--mapping", str(mapping), "--as-fast-as-possible"]
    args += ["--truth-csv", str(truth_csv), "--out-of-range", "near_tip@0.2:0.1"]
    with can.Bus(interface="virtual", channel=channel) as rx:
        assert cli(args) == 0
        messages = []
        while (message := rx.recv(timeout=0)) is not None:
            messages.append(message)
    with open(truth_csv, newline="") as stream:
        rows = list(csv.DictReader(stream))
    assert len(rows) == 50
    assert [name for name in rows[0] if name.startswith("force_true_N_")] == [
        f"force_true_N_{leg}" for leg in CONFIG.legs
    ]
    for leg, simulated in RENAMED_LEGS.items():
        column = LEGS.index(simulated)
        forces = np.array([float(row[f"force_true_N_{leg}"]) for row in rows])
        assert np.array_equal(forces, result.force_true_N[:50, column])  # repr round-trips
        # the truth holds the model's pressures, before faults
        assert float(rows[25][f"p_piston_Pa_{leg}"]) == result.p_piston_Pa[25, column]
    pipeline = Pipeline.from_config(CONFIG, DATABASE)
    ranges = []
    for m in messages:
        raw = RawFrame(m.timestamp, m.arbitration_id, m.is_extended_id, bytes(m.data))
        ranges += [e.t_s for e in pipeline.process(raw).estimates if "range" in e.reasons]
    assert len(ranges) == 10 and pipeline.bad == {}


def test_the_plot_draws_each_config_leg_from_its_simulated_leg(result: SimulationResult) -> None:
    geometries = {leg: CONFIG.legs[leg].geometry for leg in CONFIG.legs}
    figure = cycle_figure(result, geometries, columns=leg_map(CONFIG).columns)
    lines = {str(line.get_label()): line for line in figure.axes[1].get_lines()}
    assert list(lines) == list(CONFIG.legs)
    for leg, simulated in RENAMED_LEGS.items():
        force_kN = result.force_true_N[:, LEGS.index(simulated)] / 1e3
        assert np.array_equal(lines[leg].get_ydata(), force_kN)
        # SB1's feet solid, SB2's dashed, as the simulated leg's base
        assert lines[leg].get_linestyle() == ("-" if simulated < "SB2" else "--")


def estimates_by_leg(config: MachineConfig, database: Database, result: SimulationResult):  # type: ignore[no-untyped-def]
    """(t, p_piston, p_rod, force_raw) of each leg's estimates, 0.5 s of ``result`` played."""
    playout = make_playout(result, FaultConfig(seed=1), config, database)
    pipeline = Pipeline.from_config(config, database)
    by_leg = defaultdict(list)
    for instant in instants(schedule(playout.cycles, end_sim_ns=round(0.5e9))):
        for item in playout.frames(instant)[1]:
            frame = item.frame
            raw = RawFrame(instant.sim_t_ns / 1e9, frame.arbitration_id, True, frame.data)
            for e in pipeline.process(raw).estimates:
                assert e.valid, e
                by_leg[e.leg].append((e.t_s, e.p_piston_Pa, e.p_rod_Pa, e.force_raw_N))
    assert pipeline.bad == {}
    return by_leg


def test_j1939_transducers_under_other_leg_names_go_by_the_legs_order(
    result: SimulationResult,
) -> None:
    """The J1939 example (one transducer per chamber, no [stability]) with its legs renamed
    and their tables shuffled: the n-th leg plays the n-th simulated leg, whichever
    transducers it has, and gets what the example's leg of that name gets."""
    data = tomllib.loads(J1939_EXAMPLE.read_text())
    tables = data["legs"]
    renamed = ("right_rear", "left_mid", "left_front", "right_front", "left_rear", "right_mid")
    shuffled = ("SB2_F3", "SB1_F2", "SB2_F1", "SB1_F1", "SB1_F3", "SB2_F2")
    data["legs"] = {name: tables[old] for name, old in zip(renamed, shuffled, strict=True)}
    example, database = load_machine_config(J1939_EXAMPLE)
    config = parse_machine_config(data, "renamed-j1939.toml", database, example.dbc_path)
    assert dict(leg_map(config).simulated) == dict(zip(renamed, LEGS, strict=True))
    got = estimates_by_leg(config, database, result)
    expected = estimates_by_leg(example, database, result)
    assert len(got) == 6 and all(len(values) == 50 for values in got.values())
    for leg, simulated in zip(renamed, LEGS, strict=True):
        assert got[leg] == expected[simulated], leg


def test_an_export_mapping_may_not_map_a_leg_twice(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data, mapping = write_export(tmp_path, make_result(duration_s=0.2))
    mapping.write_text(mapping.read_text() + "[legs.far_tip]\npiston = 0.0\nrod = 0.0\n")
    args = ["plot", "--config", str(RENAMED), "--input", str(data), "--mapping", str(mapping)]
    assert cli([*args, "--out", str(tmp_path / "x.png")]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.endswith("mapping.toml: legs.far_tip: maps SB2_F1 again (legs.SB2_F1 does)")


@pytest.mark.parametrize(
    ("flag", "hint"),
    [
        ("stuck", "no leg 'SB1_F1'; the legs are {legs} (the config's names: "
         "simulated leg SB1_F1 is near_tip's)"),
        ("silent", "no message or leg 'SB2_F2'; the legs are {legs} (the config's names: "
         "simulated leg SB2_F2 is far_left's); the messages are HYD_NEAR_TIP, "),
        ("sensor_fault", "no leg 'SB1_F9'; the legs are {legs}"),
    ],
)  # fmt: skip
def test_faults_refuse_a_simulated_legs_name_naming_its_config_leg(
    result: SimulationResult, flag: str, hint: str
) -> None:
    """A simulated leg's name is no leg where the config calls its legs otherwise (one
    may be called like another simulated leg than it plays): the error names the legs,
    and the config leg that plays the named one."""
    target = hint.split("'")[1]
    faults = FaultConfig(**{flag: (FaultWindow.parse(f"{target}@0.1:0.1"),)}, seed=1)  # type: ignore[arg-type]
    with pytest.raises(ConfigError) as info:
        make_playout(result, faults, CONFIG, DATABASE)
    assert info.value.reason.startswith(hint.format(legs=", ".join(CONFIG.legs)))
