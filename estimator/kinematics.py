"""Plan positions of all six feet in one frame, from the bridge's rotation and fold angles.

Pure computation, the simulator's kinematics (``sim_bridge/model.py``) in general form,
for either base standing. The plan frame is the *standing* base's own frame: the bridge
turns about that base's rotation axis (``axis_m`` in its frame) by the rotation angle
psi (the bridge's direction seen from the standing base, in its frame) and folds about
a hinge ``hinge_m`` from the *first* base's axis (``length - hinge`` from the second's).
The *far* base hangs at the bridge's end; its frame is fixed to the bridge by its own
joint, locked while it hangs at the angle theta it had when it last stood (the bridge's
direction seen from it, towards the standing base; pi: its x axis along the bridge,
away from the standing base):

    u         = (cos psi, sin psi)
    far axis  = axis + (hinge + (length - hinge) cos fold) u
    far foot  = far axis + R(psi + pi - theta) (foot - far base's axis_m)

Which base stands, and theta, follow the walking cycle (:mod:`estimator.stance`).
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
    """One base: its feet and the bridge's rotation axis, in the base's frame."""

    name: str
    #: Where the bridge's rotation axis meets this base, m.
    axis_m: Point
    #: Leg name -> foot position (centre of the foot plate), m.
    feet_m: Mapping[str, Point]


@dataclass(frozen=True)
class MachineLayout:
    """Both bases and the bridge between them."""

    #: The two bases; the first stands when the service starts.
    bases: tuple[BaseLayout, BaseLayout]
    #: Distance between the two bases' axes with the bridge unfolded.
    bridge_length_m: float
    #: Distance from the first base's axis to the fold hinge, along the bridge.
    hinge_m: float

    def __post_init__(self) -> None:
        require_positive("bridge_length_m", self.bridge_length_m)
        require_finite("hinge_m", self.hinge_m)
        if not 0 <= self.hinge_m <= self.bridge_length_m:
            raise ValueError(
                f"hinge_m must lie on the bridge, 0..{self.bridge_length_m}, got {self.hinge_m}"
            )
        shared = set(self.bases[0].feet_m) & set(self.bases[1].feet_m)
        if shared:
            raise ValueError(f"feet_m of both bases name the legs {sorted(shared)}")

    def feet_m(
        self,
        rotation_rad: float,
        fold_rad: float,
        standing: int = 0,
        far_bridge_rad: float = math.pi,
    ) -> dict[str, Point]:
        """Every foot's position in the frame of the base ``standing`` (0 or 1), the
        other hanging with its joint at ``far_bridge_rad`` (theta above)."""
        base, far = self.bases[standing], self.bases[1 - standing]
        ux, uy = math.cos(rotation_rad), math.sin(rotation_rad)
        hinge_m = self.hinge_m if standing == 0 else self.bridge_length_m - self.hinge_m
        reach_m = hinge_m + (self.bridge_length_m - hinge_m) * math.cos(fold_rad)
        ax, ay = base.axis_m
        fx, fy = ax + reach_m * ux, ay + reach_m * uy
        turn_rad = rotation_rad + math.pi - far_bridge_rad
        cos_turn, sin_turn = math.cos(turn_rad), math.sin(turn_rad)
        far_ax, far_ay = far.axis_m
        feet = dict(base.feet_m)
        for leg, (x, y) in far.feet_m.items():
            dx, dy = x - far_ax, y - far_ay
            feet[leg] = (fx + cos_turn * dx - sin_turn * dy, fy + sin_turn * dx + cos_turn * dy)
        return feet
