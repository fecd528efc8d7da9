"""Each shipped example config: the bridge's frames decode through the service's Pipeline
to eq. (4) of the pressures sent, in Pa, with no sample lost or invalid.

The frames come from the bridge's :class:`~sim_bridge.playout.Playout` (a synthetic
cycle); the expected samples from :class:`tests.examples_support.SentFrames`, which reads
the same frames with cantools alone and its own unit table.
"""

from collections import defaultdict
from pathlib import Path

import pytest
from cantools.autosar.end_to_end import check_profile2_crc, check_profile5_crc
from crccheck.crc import Crc

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from daq.service_config import load_service_config
from dbc.errors import ConfigError
from dbc.machine import load_machine_config
from estimator.leg import LegEstimate
from sim_bridge.faults import FaultConfig, FaultWindow
from sim_bridge.frames import FrameBuilder
from sim_bridge.result import LEGS
from sim_bridge.schedule import instants, schedule
from tests.examples_support import EXAMPLE_CONFIGS, ROOT, SentFrames, example_id
from tests.sim_bridge.synthetic import estimates_of, make_playout, make_result, sent_by_the_command

PLAYED_S = 1.0
J1939 = ROOT / "daq" / "examples" / "j1939" / "portal-daq.toml"
E2E = ROOT / "daq" / "examples" / "e2e" / "portal-daq.toml"


def test_both_examples_are_shipped() -> None:
    assert {example_id(path) for path in EXAMPLE_CONFIGS} == {"default", "j1939", "e2e"}


@pytest.mark.parametrize("config_path", [J1939, E2E], ids=example_id)
def test_each_example_loads_as_a_service_config_with_its_dbc_beside_it(config_path: Path) -> None:
    config = load_service_config(config_path)
    assert config.machine.dbc_path.resolve().parent == config_path.parent
    assert config.zenoh.config_file is not None and config.zenoh.config_file.is_file()
    assert config.zenoh.key_prefix == f"portal/{config.machine.machine_id}"
    assert len(config.machine.legs) == 6


@pytest.mark.parametrize("config_path", [J1939, E2E], ids=example_id)
def test_the_bridge_command_plays_each_example(config_path: Path, tmp_path: Path) -> None:
    messages = sent_by_the_command(config_path, tmp_path, make_result(duration_s=0.5))
    pipeline = Pipeline.from_config(*load_machine_config(config_path))
    estimates = estimates_of(pipeline, messages)
    assert pipeline.bad == {} and pipeline.frames_lost == 0
    assert len(estimates) == 6 * 50 and all(estimate.valid for estimate in estimates)


def play_through_pipeline(
    config_path: Path,
) -> tuple[SentFrames, dict[str, list[LegEstimate]], Pipeline, list[RawFrame]]:
    """``PLAYED_S`` of a synthetic cycle with ``config_path``: what was sent and estimated."""
    config, database = load_machine_config(config_path)
    result = make_result()
    playout = make_playout(result, FaultConfig(seed=1), config, database)
    pipeline = Pipeline.from_config(config, database)
    sent = SentFrames(config, database)
    estimates: dict[str, list[LegEstimate]] = defaultdict(list)
    frames = []
    for instant in instants(schedule(playout.cycles, end_sim_ns=round(PLAYED_S * 1e9))):
        position, outgoing = playout.frames(instant)
        t_s = 1000.0 + instant.sim_t_ns / 1e9
        for item in outgoing:
            frame = RawFrame(
                t_s, item.frame.arbitration_id, item.frame.is_extended_id, item.frame.data
            )
            frames.append(frame)
            for sample in sent.add(t_s, frame.arbitration_id, frame.is_extended_id, frame.data):
                # the quantized pressures sent are the simulation's, converted to the DBC unit
                column = LEGS.index(sample.leg)
                for chamber, p_Pa, truth in (
                    ("piston", sample.p_piston_Pa, result.p_piston_Pa),
                    ("rod", sample.p_rod_Pa, result.p_rod_Pa),
                ):
                    bound_Pa = sent.half_step_Pa(sample.leg, chamber) * (1 + 1e-9)
                    assert abs(p_Pa - truth[position.row, column]) <= bound_Pa
            for estimate in pipeline.process(frame).estimates:
                estimates[estimate.leg].append(estimate)
    return sent, estimates, pipeline, frames


@pytest.mark.parametrize("config_path", EXAMPLE_CONFIGS, ids=example_id)
def test_each_example_decodes_to_eq_4_of_the_pressures_sent_in_Pa(config_path: Path) -> None:
    assert_eq_4_of_the_pressures_sent(config_path)


def test_transducers_in_their_own_units_on_a_cycle_time_from_the_config_round_trip(
    tmp_path: Path,
) -> None:
    """The j1939 example with SB1_F1's transducers set to MPa (piston) and psi (rod), and
    HYD_PRESS's cycle time given by the config, not the DBC (10 ms; SB1_F1's rod 20 ms):
    the bridge sends each transducer in its own unit on its own cycle, the service
    decodes eq. (4) of them in Pa."""
    dbc = J1939.parent / "transducers_j1939.dbc"
    text = dbc.read_text(encoding="cp1252")
    cycle_line = 'BA_ "GenMsgCycleTime" BO_ 2566856737 10;\n'
    assert cycle_line in text
    (tmp_path / dbc.name).write_text(text.replace(cycle_line, ""), encoding="cp1252")
    config = J1939.read_text()
    for address, keys in ((0x21, 'unit = "MPa"'), (0x22, 'unit = "psi", cycle_time_ms = 20')):
        where = f"source_address = 0x{address:02X}, "
        assert config.count(where) == 1
        config = config.replace(where, f"{where}{keys}, ")
    config_path = tmp_path / "portal-daq.toml"
    config_path.write_text(config + "\n[messages.HYD_PRESS]\ncycle_time_ms = 10\n")
    machine, database = load_machine_config(config_path)
    assert database.get_message_by_name("HYD_PRESS").cycle_time is None
    assert (machine.legs["SB1_F1"].piston.unit, machine.legs["SB1_F1"].rod.unit) == ("MPa", "psi")
    cycles = {cycle.message: cycle.cycle_ns for cycle in FrameBuilder(machine, database).cycles}
    assert cycles["HYD_PRESS@0x21"] == cycles["HYD_PRESS@0x2C"] == 10_000_000
    assert cycles["HYD_PRESS@0x22"] == 20_000_000
    assert_eq_4_of_the_pressures_sent(config_path)


def assert_eq_4_of_the_pressures_sent(config_path: Path) -> None:
    sent, estimates, pipeline, _ = play_through_pipeline(config_path)
    assert pipeline.bad == {} and pipeline.frames_lost == 0
    assert sorted(estimates) == sorted(LEGS)
    for leg, expected in sent.samples.items():
        got = estimates[leg]
        # one estimate per trigger frame sent (100 Hz): none lost, none invented
        assert len(got) == len(expected) == round(PLAYED_S / 0.01)
        for estimate, sample in zip(got, expected, strict=True):
            assert sample.complete
            assert estimate.valid and estimate.reasons == (), estimate
            assert estimate.t_s == sample.t_s
            assert estimate.p_piston_Pa == pytest.approx(sample.p_piston_Pa, rel=1e-12)
            assert estimate.p_rod_Pa == pytest.approx(sample.p_rod_Pa, rel=1e-12)
            assert abs(estimate.force_raw_N - sample.force_raw_N) <= 1.0
            # Pa, not the DBC's bar or kPa: a loaded leg is at several MPa
            assert 1e6 < estimate.p_piston_Pa < 5e7
            assert 1e5 < estimate.p_rod_Pa < 5e7


def test_the_j1939_example_sends_one_pgn_from_twelve_transducers() -> None:
    _, _, pipeline, frames = play_through_pipeline(J1939)
    transducers = [f for f in frames if (f.arbitration_id >> 8) & 0xFFFF == 0xFF20]
    assert all(f.is_extended_id for f in frames)
    assert {f.arbitration_id & 0xFF for f in transducers} == set(range(0x21, 0x2D))
    # priority 6, PGN 0xFF20
    assert {f.arbitration_id >> 8 for f in transducers} == {0x18FF20}
    # each transducer at 100 Hz, none of them more
    assert len(transducers) == 12 * round(PLAYED_S / 0.01)
    # the same PGN at priority 3 from SB1_F1's piston transducer makes a sample; from an
    # address no chamber maps (0x2D) it is counted, not used
    last = transducers[-1]
    made = [
        [e.leg for e in pipeline.process(RawFrame(last.t_s, frame_id, True, last.data)).estimates]
        for frame_id in (0x0CFF2021, 0x18FF202D)
    ]
    assert made == [["SB1_F1"], []]
    assert pipeline.bad == {"unmapped_source": 1}


def test_the_e2e_example_frames_carry_crcs_a_reference_implementation_accepts() -> None:
    """Profiles 2 and 5 by cantools.autosar, profile 1 by crccheck's CRC-8 of the SAE J1850
    polynomial from 0x00 without final XOR (AUTOSAR's chained Crc_CalculateCRC8), its
    counter 0..14."""
    _, _, pipeline, frames = play_through_pipeline(E2E)
    checked = defaultdict(int)
    list_p2 = [0x40 + i for i in range(16)]
    for frame in frames:
        data, frame_id = frame.data, frame.arbitration_id
        if 0x210 <= frame_id <= 0x215:  # legs: profile 5, data ID = frame ID
            assert check_profile5_crc(data, frame_id), frame
            checked["p5"] += 1
        elif frame_id in (0x220, 0x221):  # inclination: profile 1, data ID low then high byte
            crc = Crc(8, 0x1D).calc(bytes((frame_id & 0xFF, frame_id >> 8)) + data[1:])
            assert data[0] == crc and data[1] & 0x0F < 15, frame
            checked["p1"] += 1
        elif frame_id == 0x240:  # machine state: profile 2 with a DataIDList
            assert check_profile2_crc(data, list_p2[data[1] & 0x0F]), frame
            checked["p2 list"] += 1
        else:  # strokes and bridge: profile 2, data ID = low byte of the frame ID
            assert check_profile2_crc(data, frame_id & 0xFF), frame
            checked["p2"] += 1
    assert checked == {"p5": 600, "p1": 200, "p2 list": 10, "p2": 200}
    assert pipeline.bad == {}


def test_a_j1939_fault_names_one_transducer_or_every_sender_of_the_message() -> None:
    config, database = load_machine_config(J1939)
    silent = (FaultWindow.parse("HYD_PRESS@0x22@0.2:0.1"), FaultWindow.parse("HYD_PRESS@0.5:0.1"))
    playout = make_playout(make_result(), FaultConfig(silent=silent, seed=1), config, database)
    for instant in instants(schedule(playout.cycles, end_sim_ns=round(PLAYED_S * 1e9))):
        playout.frames(instant)
    assert playout.counts.silent["HYD_PRESS@0x22"] == 10 + 10
    assert all(playout.counts.silent[f"HYD_PRESS@0x{a:02X}"] == 10 for a in range(0x23, 0x2D))
    assert playout.counts.silent["STROKE_SB1"] == 0
    with pytest.raises(ConfigError, match="HYD_PRESS@0x21"):  # the error lists the senders
        make_playout(
            make_result(), FaultConfig(silent=(FaultWindow.parse("HYD@0:1"),)), config, database
        )


def test_bad_crc_touches_only_messages_that_have_a_crc() -> None:
    config, database = load_machine_config(J1939)  # no CRC anywhere
    playout = make_playout(
        make_result(), FaultConfig(bad_crc_probability=1.0, seed=1), config, database
    )
    pipeline = Pipeline.from_config(config, database)
    for instant in instants(schedule(playout.cycles, end_sim_ns=round(0.1 * 1e9))):
        for item in playout.frames(instant)[1]:
            frame = item.frame
            pipeline.process(RawFrame(0.0, frame.arbitration_id, frame.is_extended_id, frame.data))
    assert sum(playout.counts.built.values()) > 0 and not playout.counts.bad_crc
    assert pipeline.bad == {}
