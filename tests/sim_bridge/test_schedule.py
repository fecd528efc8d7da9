"""The absolute schedule: due times from k, never from summed sleeps; merged in time order."""

import itertools
from collections import Counter

import pytest

from sim_bridge.result import SimulationResult
from sim_bridge.schedule import MessageCycle, ScheduledFrame, instants, schedule
from tests.sim_bridge.synthetic import make_playout, make_result

CYCLES = [
    MessageCycle("LEG", 10_000_000),
    MessageCycle("STROKE", 20_000_000),
    MessageCycle("STATE", 100_000_000),
]


@pytest.mark.parametrize("speed", [1.0, 3.0, 10.0, 0.25])
def test_frame_k_is_due_at_exactly_start_plus_k_cycles_over_speed(speed: float) -> None:
    start_s = 1_700_000_000.123
    frames = schedule(CYCLES, start_s=start_s, speed=speed)
    legs = (f for f in frames if f.message == "LEG")
    for frame in itertools.islice(legs, 0, 200_000, 997):
        assert frame.due_s == start_s + frame.k * 0.01 / speed
        assert frame.sim_t_ns == frame.k * 10_000_000


def test_frames_come_in_time_order_with_ties_in_message_order() -> None:
    frames = list(schedule(CYCLES, end_sim_ns=1_000_000_000))
    keys = [(f.sim_t_ns, [c.message for c in CYCLES].index(f.message)) for f in frames]
    assert keys == sorted(keys)
    assert Counter(f.message for f in frames) == {"LEG": 100, "STROKE": 50, "STATE": 10}
    assert [f.message for f in frames[:3]] == ["LEG", "STROKE", "STATE"]


def test_instants_group_the_frames_of_one_simulation_time() -> None:
    grouped = list(instants(schedule(CYCLES, start_s=5.0, speed=2.0, end_sim_ns=200_000_000)))
    assert [g.sim_t_ns for g in grouped] == [k * 10_000_000 for k in range(20)]
    assert grouped[0].messages == ("LEG", "STROKE", "STATE")
    assert grouped[1].messages == ("LEG",)
    assert grouped[10].due_s == 5.0 + 10 * 0.01 / 2.0


def test_the_dbc_cycle_times_are_used(result: SimulationResult) -> None:
    cycles = {c.message: c.cycle_s for c in make_playout(result).cycles}
    assert cycles["LEG_SB1_F1"] == cycles["INCL_SB2"] == 0.01
    assert cycles["STROKE_SB1"] == cycles["BRIDGE_POSE"] == cycles["BRIDGE_MOTION"] == 0.02
    assert cycles["MACHINE_STATE"] == 0.1
    assert len(cycles) == 13


@pytest.mark.parametrize("speed", [0.0, -1.0, float("inf"), float("nan")])
def test_a_bad_speed_is_refused(speed: float) -> None:
    with pytest.raises(ValueError, match="speed"):
        next(schedule(CYCLES, speed=speed))


def test_end_is_exclusive() -> None:
    frames: list[ScheduledFrame] = list(schedule(CYCLES[:1], end_sim_ns=30_000_000))
    assert [f.k for f in frames] == [0, 1, 2]


def test_a_result_shorter_than_a_message_cycle_still_loops() -> None:
    playout = make_playout(make_result(duration_s=0.05))
    rows = [playout.timeline.position(k * 10_000_000) for k in range(12)]
    assert [(p.cycle, p.row) for p in rows[:7]] == [
        (0, 0),
        (0, 1),
        (0, 2),
        (0, 3),
        (0, 4),
        (1, 0),
        (1, 1),
    ]
