"""Helpers of the bridge tests: small synthetic simulation results and playing them.

The synthetic result is not physics: every column is a distinct, smooth, in-range
function of time (so a mix-up of legs or rows shows), and the true force is eq. (4) of
the pressures, so the truth and the frames agree.
"""

import math
import uuid
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import can
import numpy as np
from cantools.database.can import Database

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from dbc.decoding import DecodedFrame, FrameDecoder
from dbc.encoding import FrameEncoder
from dbc.machine import MachineConfig
from estimator import foot_force_N
from estimator.leg import LegEstimate
from sim_bridge.__main__ import cli
from sim_bridge.faults import FaultConfig, FaultInjector
from sim_bridge.frames import FrameBuilder
from sim_bridge.playout import Playout, fault_targets
from sim_bridge.result import LEGS, PHASES, SimulationResult
from sim_bridge.schedule import Instant, instants, schedule
from tests.helpers import dbc_text, example_machine, machine_on

CONFIG, DATABASE = example_machine()


def make_result(duration_s: float = 2.0, dt_s: float = 0.01) -> SimulationResult:
    """A synthetic cycle of ``duration_s`` sampled every ``dt_s``."""
    n = round(duration_s / dt_s)
    t_s = np.arange(n) * dt_s
    legs = np.arange(len(LEGS))
    wave = np.sin(2 * math.pi * t_s[:, None] / duration_s + legs[None, :])
    p_piston = 8e6 + 1e6 * legs[None, :] + 3e6 * wave
    p_rod = np.full_like(p_piston, 0.8e6) + 1e4 * legs[None, :]
    geometry = CONFIG.legs["SB1_F1"].geometry
    force = np.asarray(foot_force_N(p_piston, p_rod, geometry), dtype=np.float64)
    return SimulationResult(
        t_s=t_s,
        p_piston_Pa=p_piston,
        p_rod_Pa=p_rod,
        force_true_N=force,
        ground_compression_m=force / 5e8,
        slipping=np.zeros((n, 6), dtype=np.bool_),
        incl_p_piston_Pa=np.column_stack([5e6 + 1e6 * wave[:, 0], 6e6 + 1e6 * wave[:, 1]]),
        incl_p_rod_Pa=np.column_stack([1e6 + 0 * t_s, 1.2e6 + 0 * t_s]),
        stroke_m=0.3 + 0.1 * legs[None, :] + 0.05 * (1 + wave),
        inclination_deg=np.column_stack([3 * wave[:, 2], -3 * wave[:, 3]]),
        fold_deg=45 * (1 + wave[:, 4]) / 2,
        rotation_deg=180 * t_s / duration_s,
        carriage_m=4.5 * wave[:, 5],
        phase=(np.arange(n) * len(PHASES) // n).astype(np.int_),
    )


def make_playout(
    result: SimulationResult,
    faults: FaultConfig | None = None,
    config: MachineConfig = CONFIG,
    database: Database = DATABASE,
) -> Playout:
    builder = FrameBuilder(config, database)
    injector = FaultInjector(faults or FaultConfig(seed=1), fault_targets(builder))
    return Playout(result, builder, FrameEncoder.from_config(config, database), injector)


@dataclass(frozen=True)
class Played:
    """One instant of a played result: its frames as a receiver decodes them, and its row."""

    instant: Instant
    frames: list[DecodedFrame]
    row: int
    cycle: int

    def of(self, message: str) -> list[DecodedFrame]:
        return [frame for frame in self.frames if frame.message == message]


def play(result: SimulationResult, end_s: float, faults: FaultConfig | None = None) -> list[Played]:
    """Every instant before ``end_s`` (simulated), decoded by one fresh decoder."""
    playout = make_playout(result, faults)
    decoder = FrameDecoder(DATABASE, CONFIG.protection)
    played = []
    for instant in instants(schedule(playout.cycles, end_sim_ns=round(end_s * 1e9))):
        position, outgoing = playout.frames(instant)
        decoded = [
            decoder.decode(item.frame.arbitration_id, item.frame.data, instant.sim_t_ns / 1e9)
            for item in outgoing
        ]
        played.append(Played(instant, decoded, position.row, position.cycle))
    return played


def frames_of(played: list[Played], message: str) -> list[DecodedFrame]:
    return [frame for step in played for frame in step.of(message)]


def write_export(directory: Path, result: SimulationResult) -> tuple[Path, Path]:
    """``result`` as an external CSV export with its mapping (SI units): (data, mapping)."""
    columns: dict[str, np.ndarray] = {"t": result.t_s, "phase": result.phase.astype(float)}
    mapping = ['[input]\ntime = "t"\n', "[signals]", 'phase = "phase"\n']
    for i, leg in enumerate(LEGS):
        columns[f"p_{leg}"] = result.p_piston_Pa[:, i]
        columns[f"r_{leg}"] = result.p_rod_Pa[:, i]
        columns[f"F_{leg}"] = result.force_true_N[:, i]
        mapping.append(f'[legs.{leg}]\npiston = "p_{leg}"\nrod = "r_{leg}"\nforce = "F_{leg}"\n')
    names = list(columns)
    rows = [",".join(names)] + [
        ",".join(repr(float(columns[name][row])) for name in names) for row in range(len(result))
    ]
    data = directory / "export.csv"
    data.write_text("\n".join(rows) + "\n")
    mapping_path = directory / "mapping.toml"
    mapping_path.write_text("\n".join(mapping))
    return data, mapping_path


def sent_by_the_command(
    config: Path, directory: Path, result: SimulationResult, *options: str, fd: bool = False
) -> list[can.Message]:
    """The frames ``portal-sim --config CONFIG`` sends, as fast as possible on a virtual
    bus of its own, playing ``result`` (written as an export into ``directory``), at the
    times the bridge gave them (its schedule's, from its ``--frames-log``): the virtual bus
    stamps a frame with the wall clock as it passes, and a pause of a loaded machine
    between a leg's rod and piston frames made that sample ``rod_stale`` (the J1939
    example failed so, by the test order)."""
    data, mapping = write_export(directory, result)
    channel = f"bridge-{uuid.uuid4()}"
    log = directory / f"{channel}.log"
    args = ["--config", str(config), "--interface", "virtual", "--channel", channel]
    args += ["--input", str(data), "--mapping", str(mapping), "--as-fast-as-possible"]
    args += ["--frames-log", str(log)]
    with can.Bus(interface="virtual", channel=channel, fd=fd) as rx:
        assert cli([*args, *options]) == 0
        sent = []
        while (message := rx.recv(timeout=0)) is not None:
            sent.append(message)
    with can.LogReader(log) as logged:
        stamped = list(logged)
    assert [(m.arbitration_id, bytes(m.data)) for m in stamped] == [
        (m.arbitration_id, bytes(m.data)) for m in sent
    ]
    for message, as_sent in zip(sent, stamped, strict=True):
        message.timestamp = as_sent.timestamp
    return sent


def estimates_of(pipeline: Pipeline, messages: Iterable[can.Message]) -> list[LegEstimate]:
    """The leg estimates ``pipeline`` makes of ``messages`` (e.g. what the bridge sent)."""
    return [
        estimate
        for m in messages
        for estimate in pipeline.process(
            RawFrame(m.timestamp, m.arbitration_id, m.is_extended_id, bytes(m.data), is_fd=m.is_fd)
        ).estimates
    ]


def played_estimates(
    playout: Playout, pipeline: Pipeline, end_sim_ns: int, *, extended: bool = False
) -> list[tuple[LegEstimate, int]]:
    """Each leg estimate ``pipeline`` makes of the frames ``playout`` sends until
    ``end_sim_ns`` (at their simulation times), with the result's row they were sent from."""
    estimates = []
    for instant in instants(schedule(playout.cycles, end_sim_ns=end_sim_ns)):
        position, outgoing = playout.frames(instant)
        for item in outgoing:
            frame = item.frame
            raw = RawFrame(instant.sim_t_ns / 1e9, frame.arbitration_id, extended, frame.data)
            estimates += [(e, position.row) for e in pipeline.process(raw).estimates]
    return estimates


def small_machine(
    directory: Path, messages: str, attributes: str, legs: str, tables: str = ""
) -> tuple[MachineConfig, Database]:
    """A machine of ``legs`` (TOML of ``[legs.*]`` tables, after the defaults, and other
    ``tables`` before them) on a DBC of ``messages`` and ``attributes``
    (:func:`~tests.helpers.dbc_text`), written into ``directory`` and loaded."""
    return machine_on(directory, dbc_text(messages, attributes), legs, tables)
