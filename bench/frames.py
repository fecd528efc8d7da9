"""The benchmark's input: simulated CAN frames, generated once before anything is timed.

The co-simulation model (:func:`sim_bridge.model.simulate`) gives one movement cycle;
the simulator bridge's :class:`~sim_bridge.playout.Playout` turns it into the DBC's
periodic messages in schedule order (legs and inclination every 10 ms, strokes and
bridge every 20 ms, machine state every 100 ms: 101 frames per 100 ms), each encoded
with its rolling counter and CRC-8, exactly as ``python -m sim_bridge`` sends them.
The playout loops over the cycle, so any number of frames can be had; counters keep
running across the loop, so every frame passes its checks.
"""

import functools
from pathlib import Path

import can

from dbc.encoding import FrameEncoder
from dbc.machine import load_machine_config
from estimator.geometry import LegGeometry
from sim_bridge.frames import FrameBuilder
from sim_bridge.model import simulate
from sim_bridge.params import ModelParams
from sim_bridge.playout import Playout
from sim_bridge.result import SimulationResult
from sim_bridge.schedule import instants, schedule

ROOT = Path(__file__).resolve().parent.parent
#: The machine the benchmark runs: the example configuration.
EXAMPLE_CONFIG = ROOT / "deploy" / "machine.example.toml"


@functools.lru_cache(maxsize=2)
def _simulation(leg: LegGeometry, rtol: float) -> SimulationResult:
    return simulate(ModelParams(leg=leg), rtol=rtol)


def simulated_frames(count: int, *, rtol: float = 1e-3) -> list[can.Message]:
    """The first ``count`` frames the bridge would send for the example machine (time
    stamps left 0: the sender stamps each frame as it sends it)."""
    config, database = load_machine_config(EXAMPLE_CONFIG)
    result = _simulation(next(iter(config.legs.values())).geometry, rtol)
    playout = Playout(
        result, FrameBuilder(config, database), FrameEncoder(database, config.protection)
    )
    frames: list[can.Message] = []
    for instant in instants(schedule(playout.cycles)):
        for item in playout.frames(instant)[1]:
            frame = item.frame
            frames.append(
                can.Message(
                    arbitration_id=frame.arbitration_id,
                    is_extended_id=frame.is_extended_id,
                    data=frame.data,
                )
            )
        if len(frames) >= count:
            break
    return frames[:count]
