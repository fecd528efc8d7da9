"""The standing base through a walking cycle: chosen by the feet, the pose held with
both bases down, the far base's joint carried over at the switch."""

import itertools
import math

import numpy as np
import pytest

from dbc.machine import load_machine_config
from estimator.kinematics import MachineLayout, Point
from estimator.leg import LegEstimate
from estimator.stance import BridgePose, StanceTracker
from tests.estimator.test_stability import estimate
from tests.helpers import EXAMPLE_CONFIG, LEGS


@pytest.fixture
def layout() -> MachineLayout:
    config = load_machine_config(EXAMPLE_CONFIG)[0]
    assert config.stability is not None
    return config.stability.layout


def legs(down: str = "SB1 SB2", invalid: str = "") -> dict[str, LegEstimate]:
    """Every leg; those of the bases named in ``down`` in contact."""
    return {leg: estimate(leg, 50e3, contact=leg[:3] in down, valid=leg != invalid) for leg in LEGS}


def distances(feet: dict[str, Point]) -> list[float]:
    """Between every two feet: what no choice of plan frame changes."""
    return [math.dist(feet[a], feet[b]) for a, b in itertools.combinations(LEGS, 2)]


def test_the_step_s_end_switches_the_frame_and_keeps_the_feet(layout: MachineLayout) -> None:
    tracker = StanceTracker(layout)
    # First step: SB2 lifted, the bridge turns about SB1 to over SB1_F1 (rotation 0).
    tracker.observe(legs("SB1"), BridgePose(math.pi / 2, 0.0))
    assert tracker.standing == 0 and tracker.held is None
    tracker.observe(legs("SB1"), BridgePose(0.0, 0.0))
    # SB2 set down: six feet on the ground, the pose held.
    down = BridgePose(0.0, 0.0)
    tracker.observe(legs(), down)
    assert tracker.held == down
    before = tracker.feet_m(down)
    assert before == layout.feet_m(0.0, 0.0)
    # The controller now reports the rotation about SB2 (pi: towards SB1): no foot moves.
    switched = BridgePose(math.pi, 0.0)
    tracker.observe(legs(), switched)
    assert tracker.feet_m(switched) == before
    # An invalid leg changes nothing.
    tracker.observe(legs(invalid="SB1_F2"), switched)
    assert tracker.standing == 0 and tracker.held == down
    # SB1 lifted: SB2 stands, its frame is the plan's; SB1's joint locked at 0.
    tracker.observe(legs("SB2"), switched)
    assert tracker.standing == 1 and tracker.held is None and tracker.far_bridge_rad == 0.0
    after = tracker.feet_m(switched)
    assert after["SB2_F1"] == layout.bases[1].feet_m["SB2_F1"]
    assert np.allclose(distances(after), distances(before), atol=1e-9)
    # Without the carried-over joint SB1 would be turned round: a wrong implementation.
    wrong = layout.feet_m(math.pi, 0.0, standing=1)
    assert not np.allclose(distances(wrong), distances(before), atol=0.1)
    # Second step: the bridge turns about SB2 and SB1's feet go with it.
    turned = tracker.feet_m(BridgePose(0.0, 0.0))
    sb2_axis = layout.bases[1].axis_m
    assert math.dist(turned["SB1_F1"], sb2_axis) == pytest.approx(
        math.dist(after["SB1_F1"], sb2_axis)
    )
    assert turned["SB1_F1"][0] > 0 > after["SB1_F1"][0]


def test_a_base_set_down_and_lifted_again_keeps_the_standing_one(
    layout: MachineLayout,
) -> None:
    tracker = StanceTracker(layout)
    tracker.observe(legs(), BridgePose(math.pi, 0.0))  # at rest, as the cycle starts
    assert tracker.feet_m(BridgePose(0.5, 0.0)) == layout.feet_m(math.pi, 0.0)
    tracker.observe(legs("SB1"), BridgePose(0.5, 0.0))
    assert tracker.standing == 0 and tracker.far_bridge_rad == math.pi
    assert tracker.feet_m(BridgePose(0.5, 0.0)) == layout.feet_m(0.5, 0.0)
    # Feet of both bases down, none of a base fully: the pose is held too.
    partly = legs("SB1") | {"SB2_F1": estimate("SB2_F1", 9e3)}
    tracker.observe(partly, BridgePose(0.4, 0.0))
    assert tracker.held == BridgePose(0.4, 0.0)
