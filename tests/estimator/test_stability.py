"""Stability margin: a hand-computed case, the sign, undefined cases, the kinematics."""

import math

import numpy as np
import pytest

from dbc.machine import load_machine_config
from estimator.leg import LegEstimate
from estimator.stability import signed_margin_m, stability, support_polygon
from sim_bridge import cycle
from sim_bridge.model import plan_view
from tests.helpers import EXAMPLE_CONFIG, LEGS

RIGHT_TRIANGLE = {"A": (0.0, 0.0), "B": (4.0, 0.0), "C": (0.0, 3.0)}


def estimate(leg: str, force_N: float, contact: bool = True, valid: bool = True) -> LegEstimate:
    return LegEstimate(
        leg=leg,
        t_s=0.0,
        force_N=force_N,
        force_raw_N=force_N,
        pressure_Pa=force_N / 0.33,
        p_piston_Pa=0.0,
        p_rod_Pa=0.0,
        contact=contact,
        valid=valid,
        reasons=() if valid else ("crc",),
    )


def test_three_feet_by_hand() -> None:
    # CoP = (10*0 + 10*4 + 20*0, 10*0 + 10*0 + 20*3) / 40 = (1.0, 1.5). Distances to
    # the edges: AB (y = 0) 1.5, CA (x = 0) 1.0, BC (3x + 4y = 12) (12 - 3 - 6) / 5 = 0.6.
    forces = {"A": 10e3, "B": 10e3, "C": 20e3}
    result = stability([estimate(leg, f) for leg, f in forces.items()], RIGHT_TRIANGLE)
    assert result is not None
    assert result.cop_m == (1.0, 1.5)
    assert result.margin_m == pytest.approx(0.6, abs=1e-12)
    assert result.legs == ("A", "B", "C")
    assert result.polygon_m == ((0.0, 0.0), (4.0, 0.0), (0.0, 3.0))


def test_margin_is_positive_inside_and_negative_outside() -> None:
    square = ((0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0))
    assert signed_margin_m((0.5, 1.0), square) == 0.5
    assert signed_margin_m((1.0, 1.0), square) == 1.0
    assert signed_margin_m((1.0, -0.25), square) == -0.25
    assert signed_margin_m((3.0, 3.0), square) == pytest.approx(-math.sqrt(2.0))
    assert signed_margin_m((2.0, 1.0), square) == 0.0
    # The hull is counter-clockwise whatever the order of the feet.
    assert support_polygon([(0.0, 2.0), (2.0, 2.0), (2.0, 0.0), (0.0, 0.0)]) == square


def test_undefined_with_two_feet_an_invalid_leg_or_feet_on_a_line() -> None:
    forces = {"A": 10e3, "B": 10e3, "C": 20e3}
    lifted = [estimate(leg, f, contact=leg != "C") for leg, f in forces.items()]
    assert stability(lifted, RIGHT_TRIANGLE) is None
    invalid = [estimate(leg, f, valid=leg != "B") for leg, f in forces.items()]
    assert stability(invalid, RIGHT_TRIANGLE) is None
    line = {"A": (0.0, 0.0), "B": (1.0, 1.0), "C": (2.0, 2.0)}
    assert stability([estimate(leg, f) for leg, f in forces.items()], line) is None
    # A fourth foot in the air does not count, but its position is kept for plan views.
    four = RIGHT_TRIANGLE | {"D": (9.0, 9.0)}
    air = [estimate(leg, f) for leg, f in forces.items()] + [estimate("D", 0.0, contact=False)]
    result = stability(air, four)
    assert result is not None and result.legs == ("A", "B", "C")
    assert result.feet_m["D"] == (9.0, 9.0)


@pytest.mark.parametrize(
    ("t_s", "fold_deg"),
    [(0.0, 0.0), (20.0, 30.0), (28.0, 45.0), (40, 10), (45.0, 0.0), (65.0, 30.0), (73.0, 45.0)],
)
def test_the_configured_layout_places_the_feet_as_the_simulator(
    t_s: float, fold_deg: float
) -> None:
    """In either step: the first (SB1 standing) in SB1's frame, which is the simulator's
    plan; the second (SB2 standing, SB1's joint locked at its last rotation) in SB2's,
    which lies in the simulator's plan shifted, not turned (SB2's F1 ends away from SB1)."""
    config = load_machine_config(EXAMPLE_CONFIG)[0]
    assert config.stability is not None
    step = int(t_s // cycle.CYCLE_END_S)
    rotation_rad = float(cycle.rotation_rad(t_s - step * cycle.CYCLE_END_S))
    sb1_joint_rad = float(cycle.rotation_rad(cycle.CYCLE_END_S))  # 0: over SB1_F1
    feet = config.stability.layout.feet_m(
        rotation_rad,
        math.radians(fold_deg),
        standing=step,
        far_bridge_rad=sb1_joint_rad if step else math.pi,
    )
    reference, _ = plan_view(t_s, math.radians(fold_deg))
    placed = np.array([feet[leg] for leg in LEGS])
    origin = 3 * step  # the standing base's F1
    assert np.allclose(placed - placed[origin], reference - reference[origin], atol=1e-5)
    if step == 0:
        assert np.allclose(placed, reference, atol=1e-5)
