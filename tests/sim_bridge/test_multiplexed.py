"""The bridge plays multiplexed messages: held-out hubs sending one leg per multiplexer
page (tests/files/stranger/mux_pages: MPa at 0.001, counter and CRC on page 0 only;
fd_float: 12-byte CAN FD frames, float32 MPa, counter and E2E profile 5 CRC on every
page), played into the service's pipeline: each leg's estimates are eq. (4), worked out
here, of the pressures quantized as the DBC sends them, with no fault and no frame lost."""

import csv
import io
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from crccheck.crc import Crc8SaeJ1850

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from daq.replay import replay
from dbc.encoding import FrameEncoder
from dbc.errors import ConfigError
from dbc.machine import load_machine_config
from estimator.leg import LegEstimate
from sim_bridge.__main__ import cli
from sim_bridge.faults import FaultConfig, FaultWindow
from sim_bridge.frames import FrameBuilder
from sim_bridge.playout import Playout
from sim_bridge.result import SimulationResult
from sim_bridge.schedule import instants, schedule
from tests.dbc.test_held_out_machines import STRANGER, eq4_N
from tests.dbc.test_multiplexed_legs import CONFIG as HUB_CONFIG
from tests.dbc.test_multiplexed_legs import DBC as HUB_DBC
from tests.helpers import dbc_text
from tests.sim_bridge.synthetic import estimates_of, make_playout, make_result, sent_by_the_command

MUX_PAGES = STRANGER / "mux_pages.toml"
FD_FLOAT = STRANGER / "fd_float.toml"
#: Neither config names a simulated leg nor has [stability]: the legs' order plays
#: SB1_F1, SB1_F2 (the result's columns 0 and 1).
COLUMNS = {"bank-0": 0, "bank-1": 1, "A": 0, "B": 1}


def mpa_steps_Pa(p_Pa: float) -> float:
    """mux_pages' pressures: unsigned MPa at 0.001 (1 kPa a step)."""
    return round(p_Pa / 1e3) * 1e3


def float32_MPa_Pa(p_Pa: float) -> float:
    """fd_float's pressures: IEEE single-precision MPa."""
    return float(np.float32(p_Pa / 1e6)) * 1e6


@dataclass
class Run:
    """What one run sent and what the service made of it."""

    legs: list[str]
    pipeline: Pipeline
    playout: Playout
    #: (instant index, arbitration ID, data, is_fd) of every frame sent.
    frames: list[tuple[int, int, bytes, bool]] = field(default_factory=list)
    #: (row, estimate) of every leg estimate.
    estimates: list[tuple[int, LegEstimate]] = field(default_factory=list)


def play(path: Path, result: SimulationResult, duration_s: float, faults: FaultConfig) -> Run:
    """Plays ``duration_s`` of ``result`` onto machine ``path`` into a fresh pipeline."""
    config, database = load_machine_config(path)
    playout = make_playout(result, faults, config, database)
    run = Run(list(config.legs), Pipeline.from_config(config, database), playout)
    end_sim_ns = round(duration_s * 1e9)
    for i, instant in enumerate(instants(schedule(run.playout.cycles, end_sim_ns=end_sim_ns))):
        position, outgoing = run.playout.frames(instant)
        t_s = 1000.0 + instant.sim_t_ns / 1e9
        for item in outgoing:
            frame = item.frame
            run.frames.append((i, frame.arbitration_id, frame.data, frame.is_fd))
            raw = RawFrame(
                t_s, frame.arbitration_id, frame.is_extended_id, frame.data, is_fd=frame.is_fd
            )
            run.estimates += [(position.row, e) for e in run.pipeline.process(raw).estimates]
    return run


@pytest.mark.parametrize(
    ("path", "quantized"), [(MUX_PAGES, mpa_steps_Pa), (FD_FLOAT, float32_MPa_Pa)]
)
def test_every_leg_of_a_hub_gets_eq4_of_the_pressures_its_page_sent(
    path: Path, quantized: Callable[[float], float], result: SimulationResult
) -> None:
    run = play(path, result, 1.0, FaultConfig(seed=1))
    # every 10 ms one frame of each page, in multiplexer value order: one sample per leg
    assert [e.leg for _, e in run.estimates] == run.legs * 100
    for row, estimate in run.estimates:
        column = COLUMNS[estimate.leg]
        p_piston_Pa = quantized(result.p_piston_Pa[row, column])
        p_rod_Pa = quantized(result.p_rod_Pa[row, column])
        assert estimate.valid, estimate
        assert estimate.p_piston_Pa == pytest.approx(p_piston_Pa, abs=1e-6)
        assert estimate.force_raw_N == pytest.approx(eq4_N(p_piston_Pa, p_rod_Pa), abs=1.0)
    assert run.pipeline.bad == {} and run.pipeline.frames_lost == 0
    assert all(is_fd == (path == FD_FLOAT) for *_, is_fd in run.frames)


def test_faults_act_on_the_pages(result: SimulationResult) -> None:
    """A leg's fault silences its page only; a bad CRC hits the page carrying the CRC (the
    other goes out as it is, uncounted); a message name freezes the counter of its pages."""
    W = FaultWindow.parse
    faults = FaultConfig(bad_crc_probability=1.0, silent=(W("bank-1@0.2:0.1"),), seed=1)
    run = play(MUX_PAGES, result, 0.5, faults)
    assert run.playout.counts.silent == {"MUXHUB#1": 10}
    assert run.playout.counts.bad_crc == {"MUXHUB#0": 50}
    reasons = {leg: [e.reasons for _, e in run.estimates if e.leg == leg] for leg in run.legs}
    assert reasons == {"bank-0": [("crc",)] * 50, "bank-1": [()] * 40}
    frozen = play(FD_FLOAT, result, 0.2, FaultConfig(freeze_counter=(W("HUB_FD@0.1:0.05"),)))
    assert frozen.playout.counts.frozen_counter == {"HUB_FD#0": 5, "HUB_FD#1": 5}
    assert frozen.pipeline.bad == {"counter_repeat": 10}


NESTED_DBC = dbc_text(
    """
BO_ 512 NESTED: 8 Hub
 SG_ Outer M : 0|4@1+ (1,0) [0|15] "" DAQ
 SG_ Inner m0M : 4|4@1+ (1,0) [0|15] "" DAQ
 SG_ A_pPiston m1 : 8|16@1+ (0.01,0) [0|655.35] "bar" DAQ
 SG_ A_pRod m1 : 24|16@1+ (0.01,0) [0|655.35] "bar" DAQ

BO_ 513 PLAIN: 4 Hub
 SG_ B_pPiston : 0|16@1+ (0.01,0) [0|655.35] "bar" DAQ
 SG_ B_pRod : 16|16@1+ (0.01,0) [0|655.35] "bar" DAQ
""",
    """
BA_ "GenMsgCycleTime" BO_ 512 10;
BA_ "GenMsgCycleTime" BO_ 513 10;
SG_MUL_VAL_ 512 Inner Outer 0-0;
SG_MUL_VAL_ 512 A_pPiston Inner 1-1;
SG_MUL_VAL_ 512 A_pRod Inner 1-1;
""",
)


@pytest.mark.parametrize("message", ["NESTED", "PLAIN"])
def test_nested_multiplexing_is_refused_for_a_leg_and_left_unsent_otherwise(
    tmp_path: Path, message: str
) -> None:
    (tmp_path / "nested.dbc").write_text(NESTED_DBC)
    leg = "A" if message == "NESTED" else "B"
    (tmp_path / "machine.toml").write_text(
        MUX_PAGES.read_text().split("[legs.bank-0]")[0].replace("mux_pages.dbc", "nested.dbc")
        + f'[legs.SB1_F1]\npiston = "{message}.{leg}_pPiston"\nrod = "{message}.{leg}_pRod"\n'
    )
    config, database = load_machine_config(tmp_path / "machine.toml")
    if message == "NESTED":
        with pytest.raises(ConfigError) as refused:
            FrameBuilder(config, database)
        assert str(refused.value) == (
            f"{tmp_path / 'machine.toml'}: legs.SB1_F1.piston: message NESTED has nested "
            "multiplexing: the bridge plays one multiplexer signal only (the service decodes it)"
        )
    else:
        builder = FrameBuilder(config, database)
        assert (builder.messages, builder.skipped) == (["PLAIN"], ["NESTED"])


def test_a_leg_split_over_two_pages_pairs_one_row_from_the_first_sample(
    tmp_path: Path, result: SimulationResult
) -> None:
    """tests/dbc/test_multiplexed_legs.py's hub: SB1_F3's piston (its trigger) on page 2,
    its rod on page 3: page 2 goes after the others, so each SB1_F3 sample pairs the
    values of one row, valid from the first. Pages in value order otherwise; a page
    nothing supplies (5) goes out with its constants; DIAG's pages carry named signals."""
    (tmp_path / "hub.dbc").write_text(HUB_DBC)
    (tmp_path / "machine.toml").write_text(HUB_CONFIG)
    config, database = load_machine_config(tmp_path / "machine.toml")
    builder = FrameBuilder(config, database)
    pages = ["HUB_PRESS#0", "HUB_PRESS#1", "HUB_PRESS#3", "HUB_PRESS#5"]
    assert builder.messages == [*pages, "DIAG#0", "DIAG#1", "HUB_PRESS#2"]  # 2 after all
    assert builder.skipped == ["LEG_PLAIN"] and "HUB_PRESS.HubTemp" in builder.defaulted
    run = play(tmp_path / "machine.toml", result, 0.2, FaultConfig(seed=1))
    split = [(row, e) for row, e in run.estimates if e.leg == "SB1_F3"]
    assert len(split) == 20
    for row, estimate in split:  # column 2: SB1_F3 plays itself; 0.01 bar a step
        assert estimate.valid, estimate
        assert estimate.p_piston_Pa == pytest.approx(round(result.p_piston_Pa[row, 2] / 1e3) * 1e3)
        assert estimate.p_rod_Pa == pytest.approx(round(result.p_rod_Pa[row, 2] / 1e3) * 1e3)
    assert run.pipeline.bad == {}


def test_the_bridge_command_plays_a_can_fd_hub(tmp_path: Path) -> None:
    result = make_result(duration_s=0.5)
    messages = sent_by_the_command(FD_FLOAT, tmp_path, result, fd=True)
    assert len(messages) == 100 and all(m.is_fd and len(m.data) == 12 for m in messages)
    assert [m.data[0] for m in messages] == [0, 1] * 50  # the page, in value order
    config, database = load_machine_config(FD_FLOAT)
    pipeline = Pipeline.from_config(config, database)
    estimates = estimates_of(pipeline, messages)
    assert [e.leg for e in estimates] == ["A", "B"] * 50 and all(e.valid for e in estimates)
    assert pipeline.bad == {} and pipeline.frames_lost == 0


def test_the_encoder_puts_counter_and_crc_on_the_page_that_has_them() -> None:
    """Page 0 frames count 0, 1, ... with their CRC; page 1 frames (by number or by the
    multiplexer's value-table name) carry neither and advance nothing."""
    config, database = load_machine_config(MUX_PAGES)
    encoder = FrameEncoder.from_config(config, database)
    page0 = {"Page": 0, "pCap0": 12.5e6, "pAnn0": 1.25e6}
    page1 = {"pCap1": 10e6, "pAnn1": 2e6, "Spare1": 0}
    frames = [
        encoder.encode("MUXHUB", page0).data,
        encoder.encode("MUXHUB", {"Page": 1} | page1).data,
        encoder.encode("MUXHUB", {"Page": "bank_1"} | page1).data,
        encoder.encode("MUXHUB", page0).data,
    ]
    head0 = bytes([0]) + (12500).to_bytes(2, "little") + (1250).to_bytes(2, "little")
    expected0 = [head0 + bytes([counter, 0]) for counter in (0, 1)]
    page1_bytes = bytes([1]) + (10000).to_bytes(2, "little") + (2000).to_bytes(2, "little")
    assert frames == [
        expected0[0] + bytes([Crc8SaeJ1850.calc(expected0[0])]),
        page1_bytes + bytes(3),
        page1_bytes + bytes(3),
        expected0[1] + bytes([Crc8SaeJ1850.calc(expected0[1])]),
    ]


def test_the_movement_cycle_played_onto_a_hub_replays_to_eq4_of_the_truth(
    tmp_path: Path,
) -> None:
    """The model's cycle (its first second) through ``portal-sim`` into a frame log,
    replayed by the service: each estimate is eq. (4) of the truth's pressures of its
    instant, as the hub's page quantized them."""
    log, truth = tmp_path / "hub.log", tmp_path / "truth.csv"
    args = ["--config", str(MUX_PAGES), "--interface", "virtual", "--channel", str(uuid.uuid4())]
    args += ["--as-fast-as-possible", "--duration", "1", "--frames-log", str(log)]
    assert cli([*args, "--truth-csv", str(truth)]) == 0
    out = io.StringIO()
    assert replay(log, out, MUX_PAGES) == 200
    rows = list(csv.DictReader(io.StringIO(out.getvalue())))
    with open(truth, newline="") as stream:
        samples = list(csv.DictReader(stream))
    assert len(samples) == 100 and [row["leg"] for row in rows] == ["bank-0", "bank-1"] * 100
    for i, row in enumerate(rows):
        sample = samples[i // 2]  # one instant: page 0, page 1
        assert float(row["t"]) == pytest.approx(float(sample["t_unix_s"]), abs=1e-3)
        p_piston_Pa, p_rod_Pa = (
            mpa_steps_Pa(max(0.0, float(sample[f"{chamber}_Pa_{row['leg']}"])))
            for chamber in ("p_piston", "p_rod")
        )
        assert row["valid"] == "1" and row["reasons"] == ""
        assert float(row["force_raw_N"]) == pytest.approx(eq4_N(p_piston_Pa, p_rod_Pa), abs=1.0)
