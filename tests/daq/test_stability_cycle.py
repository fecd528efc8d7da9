"""The stability margin through the pipeline on a simulated cycle, against the truth.

The bridge's frames (legs, bridge pose) go through :class:`daq.pipeline.Pipeline` as
live; a snapshot is taken every 100 ms (the ``/ground`` rate). The truth: the margin of
the simulation's centre of gravity in the polygon of the feet it has on the ground.
"""

import json
import math
import queue
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import orthogonal_procrustes
from scipy.spatial.distance import pdist

from daq.consumer import Consumer
from daq.frames import BusEvent, RawFrame
from daq.mcap_file import GROUND_TOPIC
from daq.mcap_reading import RecordedMessage, RecordingStream
from daq.payloads import machine_ground
from daq.pipeline import FrameResult, Pipeline
from daq.recorder import Recorder
from daq.service_config import PublishSettings, RecordingSettings
from dbc.encoding import FrameEncoder
from dbc.machine import load_machine_config
from estimator.machine import MachineSnapshot
from estimator.stability import signed_margin_m, support_polygon
from sim_bridge.frames import FrameBuilder
from sim_bridge.model import plan_view, simulate
from sim_bridge.playout import Playout
from sim_bridge.result import SimulationResult
from sim_bridge.schedule import instants, schedule
from tests.helpers import EXAMPLE_CONFIG, LEGS

#: Frame time of the cycle's start.
T0_S = 1.8e9
#: Quasi-static: no true foot force changes faster than this.
QUASI_STATIC_RATE_N_S = 5e3
#: Estimated against true margin in the quasi-static phases of either step, at most
#: (measured 5.5 cm in the first step, 5.1 cm in the second, 95 % within 4.0 / 3.7 cm:
#: while the bridge folds, cylinder friction and the folding half's acceleration move
#: the centre of pressure off the centre of gravity).
MARGIN_BOUND_M = 0.06
#: The centre of pressure against the true centre of gravity there (measured 5.5 / 6.6 cm;
#: with six feet down the margin only sees its offset across the bridge, this all of it).
COP_BOUND_M = 0.08
#: The distance between any two estimated feet against the simulator's, at any instant
#: (measured 8.9 mm, while the bridge turns: the pose frames are up to 20 ms old).
FEET_BOUND_M = 0.015
#: The second step starts here (SB2 stands).
STEP_S = 45.0


@pytest.fixture(scope="module")
def result() -> SimulationResult:
    """The full walking cycle: SB1 stands in the first step, SB2 in the second."""
    return simulate(rtol=1e-3, steps=2)


def played(result: SimulationResult, end_s: float) -> Iterator[tuple[int, list[RawFrame]]]:
    """(row of the result, the frames the bridge sends at that instant), up to ``end_s``."""
    config, database = load_machine_config(EXAMPLE_CONFIG)
    playout = Playout(
        result, FrameBuilder(config, database), FrameEncoder(database, config.protection)
    )
    for instant in instants(schedule(playout.cycles, end_sim_ns=round(end_s * 1e9))):
        position, outgoing = playout.frames(instant)
        t_s = T0_S + instant.sim_t_ns / 1e9
        yield (
            position.row,
            [
                RawFrame(t_s, item.frame.arbitration_id, item.frame.is_extended_id, item.frame.data)
                for item in outgoing
            ],
        )


@pytest.fixture(scope="module")
def margins(result: SimulationResult) -> np.ndarray:
    """Rows: (t, estimated margin, true margin, true feet down, estimated feet down,
    largest true force rate, largest error of the distance between two feet, distance
    from the centre of pressure to the true centre of gravity), every 100 ms of both
    steps. The estimator's plan is the standing base's frame, the simulator's SB1's at
    the start: the centre of pressure is compared after the rigid motion that best
    lays the estimated feet onto the true ones."""
    pipeline = Pipeline.from_config(*load_machine_config(EXAMPLE_CONFIG))
    rate_N_s = np.abs(np.gradient(result.force_true_N, result.t_s, axis=0)).max(axis=1)
    rows = []
    next_snapshot_s = 0.0
    for row, frames in played(result, result.t_s[-1]):
        for frame in frames:
            pipeline.process(frame)
        t_s = frames[0].t_s - T0_S if frames else 0.0
        if not frames or t_s < next_snapshot_s:
            continue
        next_snapshot_s += 0.1
        snapshot = pipeline.snapshot(T0_S + t_s)
        payload = machine_ground(snapshot)["stability"]
        feet, cog = plan_view(result.t_s[row], math.radians(result.fold_deg[row]))
        down = result.force_true_N[row] > 0
        polygon = support_polygon([(x, y) for x, y in feet[down]])
        true_m = signed_margin_m((cog[0], cog[1]), polygon) if polygon else math.nan
        estimated_m = payload["margin_m"] if payload else math.nan
        legs = len(payload["legs"]) if payload else 0
        placed = np.array([payload["feet_m"][leg] for leg in LEGS]) if payload else feet * np.nan
        apart_m = np.abs(pdist(placed) - pdist(feet)).max()
        cop_m = np.nan
        if payload:
            turn, _ = orthogonal_procrustes(placed - placed.mean(0), feet - feet.mean(0))
            cop = (np.array(payload["cop_m"]) - placed.mean(0)) @ turn + feet.mean(0)
            cop_m = math.dist(cop, cog)
        rows.append((t_s, estimated_m, true_m, down.sum(), legs, rate_N_s[row], apart_m, cop_m))
    return np.array(rows)


@pytest.mark.parametrize("step", [0, 1])
def test_margin_matches_the_centre_of_gravity_in_quasi_static_phases(
    margins: np.ndarray, step: int
) -> None:
    t, estimated, true, down, legs, rate, apart, cop = margins.T
    in_step = (t >= STEP_S * step) & (t < STEP_S * (step + 1))
    assert np.isfinite(estimated[in_step]).all()  # three feet or more all the step
    quasi_static = in_step & (rate < QUASI_STATIC_RATE_N_S) & (down == legs)
    assert quasi_static.sum() > 250  # of 450 snapshots
    assert np.abs(estimated - true)[quasi_static].max() < MARGIN_BOUND_M
    assert cop[quasi_static].max() < COP_BOUND_M
    # The plan follows the standing base: every foot where the simulator has it.
    assert apart[in_step].max() < FEET_BOUND_M


@pytest.mark.parametrize("step", [0, 1])
def test_margin_is_smallest_with_three_feet(margins: np.ndarray, step: int) -> None:
    t, estimated, true, down, legs, rate, apart, cop = margins.T
    in_step = (t >= STEP_S * step) & (t < STEP_S * (step + 1))
    three = in_step & (legs == 3)
    six = in_step & (legs == 6)
    assert three.sum() > 200 and six.sum() > 50
    assert estimated[three].max() < estimated[six].min()
    # Six feet at rest: the CoP lies on the bridge's axis, 1.386 m from the long edges.
    at_rest = six & (t - STEP_S * step < 8.0)
    assert at_rest.sum() > 50
    assert estimated[at_rest] == pytest.approx(1.3856, abs=2e-3)
    # Three feet: at most the triangle's inradius (0.8 m); lowest in the fold stop's
    # swing (0.39 m at t = 23 s with SB1 standing, 0.32 m at 68 s with SB2).
    assert 0.25 < estimated[three].min() and estimated[three].max() < 0.8


class SignallingRecorder:
    """The real recorder, with an event set once a ``/ground`` snapshot went to it."""

    def __init__(self, recorder: Recorder) -> None:
        self.recorder = recorder
        self.snapshots = 0
        self.enough = threading.Event()

    def submit(self, item: FrameResult | BusEvent | MachineSnapshot) -> None:
        self.recorder.submit(item)
        if isinstance(item, MachineSnapshot) and item.stability is not None:
            self.snapshots += 1
            if self.snapshots >= 3:
                self.enough.set()


def test_ground_with_the_margin_is_recorded(result: SimulationResult, tmp_path: Path) -> None:
    config, database = load_machine_config(EXAMPLE_CONFIG)
    inbox: queue.Queue[RawFrame | BusEvent] = queue.Queue()
    with Recorder(RecordingSettings(directory=tmp_path), database, machine_id="m") as recorder:
        signalling = SignallingRecorder(recorder)
        with Consumer(
            Pipeline.from_config(config, database),
            inbox,
            PublishSettings(ground_rate_hz=50.0),
            recorder=signalling,
        ):
            for _, frames in played(result, 0.5):
                for frame in frames:
                    inbox.put(frame)
            assert signalling.enough.wait(timeout=30.0)
    grounds = []
    for path in recorder.paths:
        with open(path, "rb") as file:
            grounds += [
                json.loads(record.data)
                for record in RecordingStream(file)
                if isinstance(record, RecordedMessage) and record.topic == GROUND_TOPIC
            ]
    margins = [g["stability"]["margin_m"] for g in grounds if g["stability"] is not None]
    assert len(margins) >= 3
    # Six feet down, the centre of pressure on the bridge's axis: 1.386 m to the long edges.
    assert margins[-1] == pytest.approx(1.3856, abs=2e-3)
    assert grounds[-1]["stability"]["legs"] == list(config.legs)
