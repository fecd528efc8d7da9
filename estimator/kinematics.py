"""Plan positions of all six feet in one frame, from the bridge's rotation and fold angles.

Pure computation, the simulator's kinematics (``sim_bridge/model.py``) in general form.
The plan frame is the *standing* base's own frame (the first base of the config, SB1):
the bridge turns about that base's rotation axis (``axis_m`` in its frame) by the
rotation angle psi (0: along the frame's x axis) and folds about a hinge ``hinge_m``
from that axis; the *far* base (SB2) hangs at the bridge's end, its own frame turned
with the bridge (x along the bridge, away from the standing base):

    u         = (cos psi, sin psi)
    far axis  = axis + (hinge + (length - hinge) cos fold) u
    far foot  = far axis + R(psi) (foot - far base's axis_m)

The bridge's inclination (a few degrees) moves the feet horizontally by less than
0.2 % of the bridge length and is left out, as in the simulator.
"""

import math
from collections.abc import Mapping
from dataclasses import dataclass

from estimator._checks import require_finite, require_positive

#: A point in the plan, metres.
Point = tuple[float, float]


@dataclass(frozen=True)
class BaseLayout:
    """One standing base: its feet and the bridge's rotation axis, in the base's frame."""

    name: str
    #: Where the bridge's rotation axis meets this base, m.
    axis_m: Point
    #: Leg name -> foot position (centre of the foot plate), m.
    feet_m: Mapping[str, Point]


@dataclass(frozen=True)
class MachineLayout:
    """Both bases and the bridge between them."""

    #: The base whose frame is the plan frame; the bridge rotates about its axis.
    standing: BaseLayout
    #: The base at the bridge's far end.
    far: BaseLayout
    #: Distance between the two bases' axes with the bridge unfolded.
    bridge_length_m: float
    #: Distance from the standing base's axis to the fold hinge, along the bridge.
    hinge_m: float

    def __post_init__(self) -> None:
        require_positive("bridge_length_m", self.bridge_length_m)
        require_finite("hinge_m", self.hinge_m)
        if not 0 <= self.hinge_m <= self.bridge_length_m:
            raise ValueError(
                f"hinge_m must lie on the bridge, 0..{self.bridge_length_m}, got {self.hinge_m}"
            )
        shared = set(self.standing.feet_m) & set(self.far.feet_m)
        if shared:
            raise ValueError(f"feet_m of both bases name the legs {sorted(shared)}")

    def feet_m(self, rotation_rad: float, fold_rad: float) -> dict[str, Point]:
        """Every foot's position in the plan frame."""
        ux, uy = math.cos(rotation_rad), math.sin(rotation_rad)
        ax, ay = self.standing.axis_m
        reach_m = self.hinge_m + (self.bridge_length_m - self.hinge_m) * math.cos(fold_rad)
        fx, fy = ax + reach_m * ux, ay + reach_m * uy
        far_ax, far_ay = self.far.axis_m
        feet = dict(self.standing.feet_m)
        for leg, (x, y) in self.far.feet_m.items():
            dx, dy = x - far_ax, y - far_ay
            feet[leg] = (fx + ux * dx - uy * dy, fy + uy * dx + ux * dy)
        return feet
