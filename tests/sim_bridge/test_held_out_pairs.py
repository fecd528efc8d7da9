"""Held-out DBC and machine-config pairs as other vendors and integrators write them
(tests/files/stranger/, each file says what it is), played by the bridge into the
service's Pipeline: every estimate valid, each chamber pressure within half a step of its
DBC signal of the simulation's (the truth's), each foot force within what that allows.

- ``zyl4_mbar12``: four legs, two per base, German names, 12-bit Motorola pressures
  across byte boundaries in mbar with an offset, cycle time only as the DBC's default;
- ``xdcr_two_rates``: one J1939 transducer per chamber, pistons and rods on two
  proprietary-B PGNs at 10 and 100 ms, one in psi, the controller peer to peer;
- ``fd_be_float``: a 32-byte CAN FD hub of big-endian float32 (Pa, hPa) and signed
  16-bit pressures, E2E profile 5;
- ``eight_legs_mux``: eight legs, four per base, on two multiplexed hubs;
- ``iom_channels``: two I/O modules sending their four inputs in turn in one multiplexed
  signal (each chamber names its page), 29-bit IDs that look J1939 and are not, mbar
  with a large offset, CRLF and Windows-1252, every kind of DBC section CANdb++ writes;
- ``spn_xdcr``: J1939 transducers named by SPN, a PGN per piston, the rods on one PGN
  told apart by source address, no cycle time in the DBC;
- ``split_rates``: each leg's piston and rod in two 11-bit messages at 10 and 50 ms, MPa
  and psi(g), a state byte with a bit per rod transducer;
- ``abs_vehicle``: absolute transmitters ("bar (abs)", "PSIA") in a vehicle DBC that
  cantools reads only without its checks;
- ``iom_j1939``: two J1939 I/O modules on one PGN, eight inputs each in turn, each
  chamber named by source address and page;
- ``e2e_p1_modes``: AUTOSAR E2E profile 1 in each DataIDMode (both, alt, low, nibble),
  counters and CRCs under German and vendor names, a Motorola leg, the machine state
  profile 2 with a DataIDList;
- ``xdcr32_pdu1``: J1939 transducers of 32-bit pressures, the pistons' Motorola and peer
  to peer (PDU1) to the DAQ at priority 3, the rods' unit only in the DBC's comment.
"""

import logging
from collections import defaultdict
from pathlib import Path

import pytest
from cantools.database.can import Database

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from dbc.decoding import FrameDecoder
from dbc.errors import ConfigError, UnknownFrameError
from dbc.machine import ChamberSignal, MachineConfig, load_machine_config
from dbc.units import chamber_unit
from estimator import foot_force_N
from estimator.leg import LegEstimate
from sim_bridge.faults import FaultConfig, FaultWindow
from sim_bridge.leg_map import leg_map
from sim_bridge.schedule import instants, schedule
from tests.helpers import FILES
from tests.sim_bridge.synthetic import (
    estimates_of,
    make_playout,
    make_result,
    played_estimates,
    sent_by_the_command,
    small_machine,
)

STRANGER = FILES / "stranger"
PAIRS = (
    "zyl4_mbar12",
    "xdcr_two_rates",
    "fd_be_float",
    "eight_legs_mux",
    "iom_channels",
    "spn_xdcr",
    "split_rates",
    "abs_vehicle",
    "iom_j1939",
    "e2e_p1_modes",
    "xdcr32_pdu1",
)
PLAYED_S = 0.5


def half_step_Pa(database: Database, chamber: ChamberSignal, p_Pa: float) -> float:
    """The most encoding and decoding may move ``p_Pa`` on ``chamber``'s signal (a float
    signal: its 24-bit mantissa)."""
    signal = database.get_message_by_name(chamber.message).get_signal_by_name(chamber.signal)
    in_Pa = chamber_unit(chamber.unit)
    assert in_Pa is not None
    if signal.is_float:
        return abs(p_Pa) * 2.0**-24 + abs(signal.scale) * in_Pa[0] * 1e-6
    return abs(signal.scale) * in_Pa[0] / 2 * (1 + 1e-9)


def played(
    name: str, drop_source_address: int | None = None, faults: FaultConfig | None = None
) -> tuple[MachineConfig, Database, dict[str, list[tuple[LegEstimate, int]]], Pipeline]:
    """``PLAYED_S`` of a synthetic cycle on pair ``name`` (with the bridge's ``faults``):
    each leg's estimates with the simulation row their frames were built from."""
    config, database = load_machine_config(STRANGER / f"{name}.toml")
    playout = make_playout(make_result(), faults or FaultConfig(seed=1), config, database)
    pipeline = Pipeline.from_config(config, database)
    estimates: dict[str, list[tuple[LegEstimate, int]]] = defaultdict(list)
    for instant in instants(schedule(playout.cycles, end_sim_ns=round(PLAYED_S * 1e9))):
        position, outgoing = playout.frames(instant)
        for item in outgoing:
            frame = item.frame
            if frame.is_extended_id and frame.arbitration_id & 0xFF == drop_source_address:
                continue
            raw = RawFrame(
                1000.0 + instant.sim_t_ns / 1e9,
                frame.arbitration_id,
                frame.is_extended_id,
                bytes(frame.data),
            )
            for estimate in pipeline.process(raw).estimates:
                estimates[estimate.leg].append((estimate, position.row))
    return config, database, estimates, pipeline


@pytest.mark.parametrize("name", PAIRS)
def test_each_pair_estimates_the_simulated_pressures_and_forces(name: str) -> None:
    config, database, estimates, pipeline = played(name)
    assert pipeline.bad == {} and pipeline.frames_lost == 0
    result = make_result()
    columns = leg_map(config).columns
    assert sorted(estimates) == sorted(config.legs)
    for leg_name, leg in config.legs.items():
        cycle_s = (leg.piston if leg.trigger == "piston" else leg.rod).cycle_time_s
        assert cycle_s is not None
        assert len(estimates[leg_name]) == round(PLAYED_S / cycle_s)
        column = columns[leg_name]
        for estimate, row in estimates[leg_name]:
            assert estimate.valid, (leg_name, estimate.reasons)
            p_Pa, r_Pa = result.p_piston_Pa[row, column], result.p_rod_Pa[row, column]
            p_step_Pa = half_step_Pa(database, leg.piston, p_Pa)
            r_step_Pa = half_step_Pa(database, leg.rod, r_Pa)
            assert abs(estimate.p_piston_Pa - p_Pa) <= p_step_Pa
            assert abs(estimate.p_rod_Pa - r_Pa) <= r_step_Pa
            force_step_N = foot_force_N(p_step_Pa, -r_step_Pa, leg.geometry) - foot_force_N(
                0.0, 0.0, leg.geometry
            )
            truth_N = result.force_true_N[row, column]
            assert abs(estimate.force_raw_N - truth_N) <= force_step_N + 1e-6


@pytest.mark.parametrize("name", PAIRS)
def test_the_bridge_command_plays_each_pair(name: str, tmp_path: Path) -> None:
    config_path = STRANGER / f"{name}.toml"
    config, database = load_machine_config(config_path)
    fd = any(message.is_fd for message in database.messages)
    sent = sent_by_the_command(config_path, tmp_path, make_result(duration_s=0.3), fd=fd)
    pipeline = Pipeline.from_config(config, database)
    estimates = estimates_of(pipeline, sent)
    assert pipeline.bad == {} and pipeline.frames_lost == 0
    assert {e.leg for e in estimates} == set(config.legs) and all(e.valid for e in estimates)


def test_a_transducer_that_never_speaks_makes_its_legs_samples_invalid() -> None:
    """B3's rod transducer (0x55) named in the config, silent on the bus: B3's samples are
    invalid (``rod_stale``, no rod value), the other legs' untouched."""
    _, _, estimates, pipeline = played("xdcr_two_rates", drop_source_address=0x55)
    assert {e.reasons for e, _ in estimates["B3"]} == {("rod_stale", "range")}
    assert all(e.valid for leg in ("A1", "A2", "A3", "B1", "B2") for e, _ in estimates[leg])
    assert pipeline.bad == {}


def test_a_rod_message_that_stops_makes_its_legs_samples_invalid() -> None:
    """split_rates: base 2's rods (STANGE_SB2, every 50 ms) fall silent at 0.2 s while its
    pistons (every 10 ms) go on: beyond one rod cycle after the last rod frame, each sample
    of its legs is invalid (``rod_stale``), not a force from the last rod value; base 1's
    stay valid."""
    silent = FaultWindow("STANGE_SB2", 0.2, 1.0)
    _, _, estimates, _ = played("split_rates", faults=FaultConfig(seed=1, silent=(silent,)))
    for leg in ("SB2_F1", "SB2_F2", "SB2_F3"):
        times_s = [(estimate.t_s - 1000.0, estimate) for estimate, _ in estimates[leg]]
        # The last rod frame went at 0.15 s: its value pairs until 0.2 s.
        assert all(e.valid for t_s, e in times_s if t_s < 0.15 + 0.05 + 1e-6)
        late = [e for t_s, e in times_s if t_s > 0.15 + 0.05 + 1e-6]
        assert len(late) == 29 and all(e.reasons == ("rod_stale",) for e in late)
    assert all(e.valid for leg in ("SB1_F1", "SB1_F2", "SB1_F3") for e, _ in estimates[leg])


@pytest.mark.parametrize(
    ("name", "leg", "status"),
    [
        ("iom_channels", "VL", "Sensorfehler"),
        ("xdcr_two_rates", "A1", "ShortCircuit"),
        ("split_rates", "SB1_F1", "SENSOR_FAULT_F1"),
        ("split_rates", "SB1_F3", "SENSOR_FAULT_F3"),
        ("split_rates", "SB2_F2", "SENSOR_FAULT_F2"),
    ],
)
def test_a_sensor_fault_sends_what_the_dbc_names_a_fault(name: str, leg: str, status: str) -> None:
    """--sensor-fault on held-out status tables without 'fault', 'error' or 'fail' in a
    name (a German I/O module's Sensorfehler, Drahtbruch, Kurzschluss; a J1939
    transducer's OpenCircuit, ShortCircuit): portal-sim refused the flag; now the leg's
    samples in the window carry the fault, the other legs' none. split_rates' three legs
    of a base share one state byte, each fine with the others' bits: a fault on F1 or F2
    was overwritten by F3's "OK" (nothing sent), and one on F3 sent SENSOR_FAULT_F1,
    F1's fault, fine for F3."""
    window = FaultWindow(leg, 0.2, 0.1)
    _, _, estimates, _ = played(name, faults=FaultConfig(seed=1, sensor_fault=(window,)))
    for other, of_leg in estimates.items():
        faulty = [e for e, _ in of_leg if not e.valid]
        if other != leg:
            assert faulty == []
            continue
        assert faulty and {e.reasons for e in faulty} == {(f"status_{status}",)}
        assert all(0.2 - 1e-6 <= e.t_s - 1000.0 < 0.3 + 0.1 for e in faulty)


def test_a_transducer_at_an_address_no_chamber_has_is_named_once(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """B3's rod transducer set to 0x56 instead of the config's 0x55: its frames were
    counted ``unmapped_source`` with nothing saying which address sent them."""
    config, database = load_machine_config(STRANGER / "xdcr_two_rates.toml")
    pipeline = Pipeline.from_config(config, database)
    data = bytes([0x10, 0x27]) + bytes(6)
    with caplog.at_level(logging.WARNING, logger="daq.pipeline"):
        for i in range(3):
            pipeline.process(RawFrame(1.0 + 0.1 * i, 0x18FF3256, True, data))
    assert pipeline.bad == {"unmapped_source": 3}
    assert [r.getMessage() for r in caplog.records] == [
        "XDCR_ROD from source address 0x56: no chamber has this source_address; its frames "
        "are counted unmapped_source and not used"
    ]


def test_a_message_sent_at_another_length_than_the_dbcs_is_named_once(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """split_rates' PLC sends STANGE_SB1 in 8 bytes where the DBC says 7 (a DBC of an
    older PLC program): its legs had no rod, and only the count wrong_dlc said so."""
    config, database = load_machine_config(STRANGER / "split_rates.toml")
    pipeline = Pipeline.from_config(config, database)
    with caplog.at_level(logging.WARNING, logger="daq.pipeline"):
        for i, length in enumerate((8, 8, 8, 6)):
            pipeline.process(RawFrame(1.0 + 0.05 * i, 0x211, False, bytes(length)))
    assert pipeline.bad == {"wrong_dlc": 4}
    assert [r.getMessage() for r in caplog.records] == [
        f"frame 0x211: STANGE_SB1 has DLC {length}, the DBC says 7: its frames are counted "
        "wrong_dlc and not used"
        for length in (8, 6)
    ]


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "reference"])
def test_peer_to_peer_messages_are_told_apart_by_their_destination(compiled: bool) -> None:
    """The controller (0x27) sends proprietary A 0xEF00 to the DAQ (0x80: the machine
    state) and to the valve block (0x81): the config naming MCU_TO_DAQ was refused ("their
    frames cannot be told apart"), and frames to the valves were read as the machine
    state. A frame to a destination neither message has is no message of the DBC."""
    config, database = load_machine_config(STRANGER / "xdcr_two_rates.toml")
    decoder = FrameDecoder(database, config.protection, compiled=compiled)
    data = bytes([2, 7, 0, 0, 0, 0, 0, 0])
    to_daq = decoder.decode(0x18EF8027, data, 1.0, True)
    assert (to_daq.message, to_daq.signals["Phase"], to_daq.source_address) == (
        "MCU_TO_DAQ",
        "fold",
        0x27,
    )
    assert decoder.decode(0x0CEF8127, data, 1.0, True).message == "MCU_TO_VALVES"
    with pytest.raises(UnknownFrameError):
        decoder.decode(0x18EF8227, data, 1.0, True)
    assert decoder.decode(0x18EF8027, data, 1.1, True).message == "MCU_TO_DAQ"  # cached


#: A vendor's proprietary PGN 0xFF1F for all its transducers: an oil temperature one at
#: 0x30 (first in the DBC), pressure ones whose DBC ID says 0xFE.
SHARED_PGN = """
BO_ 2566856496 OIL_TEMP: 8 Xdcr
 SG_ Temperature : 0|16@1+ (0.03125,-273) [-273|1735] "degC" DAQ

BO_ 2566856702 HYD_PRESS: 8 Xdcr
 SG_ Pressure : 0|16@1+ (0.01,-10) [-10|632.55] "bar" DAQ
"""
SHARED_PGN_ATTRIBUTES = "".join(
    f'BA_ "GenMsgCycleTime" BO_ {frame_id} {ms};\nBA_ "VFrameFormat" BO_ {frame_id} 3;\n'
    for frame_id, ms in ((2566856496, 100), (2566856702, 10))
)


def test_transducers_pinned_on_a_message_are_its_where_another_of_its_pgn_comes_first(
    tmp_path: Path,
) -> None:
    """Frames of PGN 0xFF1F from 0x21 and 0x22 (the chambers' transducers) were read as
    OIL_TEMP, the DBC's first message of the PGN: the leg never had a sample."""
    legs = (
        '[legs.SB1_F1]\npiston = { signal = "HYD_PRESS.Pressure", source_address = 0x21 }\n'
        'rod = { signal = "HYD_PRESS.Pressure", source_address = 0x22 }\n'
    )
    config, database = small_machine(tmp_path, SHARED_PGN, SHARED_PGN_ATTRIBUTES, legs)
    assert config.pinned_senders == {("HYD_PRESS", 0x21), ("HYD_PRESS", 0x22)}
    result = make_result()
    playout = make_playout(result, config=config, database=database)
    pipeline = Pipeline.from_config(config, database)
    estimates = played_estimates(playout, pipeline, 100_000_000, extended=True)
    assert len(estimates) == 10 and pipeline.bad == {}
    for estimate, row in estimates:
        assert estimate.valid
        assert estimate.p_piston_Pa == pytest.approx(result.p_piston_Pa[row, 0], abs=500)
    temperature = pipeline.process(RawFrame(1.0, 0x18FF1F30, True, bytes(8))).decoded
    assert temperature is not None and temperature.message == "OIL_TEMP"  # 0x30 still is
    with pytest.raises(ConfigError) as refused:
        small_machine(tmp_path, SHARED_PGN, SHARED_PGN_ATTRIBUTES, legs.replace("0x22", "0x30"))
    assert (refused.value.key, refused.value.reason) == (
        "legs.SB1_F1.rod.source_address",
        "0x30 sends OIL_TEMP in the DBC (0x18FF1F30, the PGN of HYD_PRESS): its frames are "
        "that message's",
    )
