"""Which base stands through the walking cycle, and the bridge pose the plan uses.

Pure: fed each snapshot's leg estimates and the bridge's latest angles (rotation and
fold, from the bus). The bus says how far the bridge has turned about the standing
base's axis, not which base that is; the feet say it:

- **One base lifted** (all its legs valid, none in contact): the other base stands, and
  the plan is its frame with the pose as read. When that is the other base than before,
  the base that stood becomes the far one, its joint locked at the rotation it last had
  (the bridge's direction seen from it: the held pose's), so the feet keep their places
  on the ground. (Had no pose been read while both were down, the joint stays as it was.)
- **Feet of both bases on the ground** (all legs valid, no base lifted): the bridge can
  neither turn nor fold, so the pose is *held* at its value when this began, and the
  standing base stays the one that stood last. The rotation signal is not used meanwhile:
  the controller may switch its reference to the next step's standing base while both
  are down (the simulator does, at the step's end) and the feet would seem to jump.
- **An invalid leg**: nothing changes (and the margin is undefined anyway).

At start the first base of the layout stands and the second hangs with the bridge along
its x axis (theta = pi, :mod:`estimator.kinematics`), as the simulated cycle begins.
"""

import math
from collections.abc import Mapping
from dataclasses import dataclass

from estimator.kinematics import MachineLayout, Point
from estimator.leg import LegEstimate


@dataclass(frozen=True, slots=True)
class BridgePose:
    """The bridge's angles: rotation about the standing base's axis, and fold."""

    rotation_rad: float
    fold_rad: float


class StanceTracker:
    """The walking cycle's state: the standing base, the far base's joint, a held pose."""

    def __init__(self, layout: MachineLayout) -> None:
        self.layout = layout
        #: Index of the standing base in ``layout.bases``.
        self.standing = 0
        #: The far base's joint: the bridge's direction seen from it, rad.
        self.far_bridge_rad = math.pi
        #: The pose held while feet of both bases are on the ground; None otherwise
        #: (or while no pose was known since).
        self.held: BridgePose | None = None
        self._legs = tuple(tuple(base.feet_m) for base in layout.bases)

    def _lifted(self, legs: Mapping[str, LegEstimate], base: int) -> bool | None:
        """Whether every foot of ``base`` is in the air; None when a leg is invalid or
        unknown."""
        estimates = [legs.get(leg) for leg in self._legs[base]]
        if any(estimate is None or not estimate.valid for estimate in estimates):
            return None
        return not any(estimate.contact for estimate in estimates if estimate is not None)

    def observe(self, legs: Mapping[str, LegEstimate], pose: BridgePose | None) -> None:
        """Judge the legs' contact (``pose``: the angles as read now, None if unknown)."""
        lifted = (self._lifted(legs, 0), self._lifted(legs, 1))
        if lifted == (False, False):
            if self.held is None:
                self.held = pose
        elif lifted in ((True, False), (False, True)):
            standing = lifted.index(False)
            if standing != self.standing:
                if self.held is not None:
                    self.far_bridge_rad = self.held.rotation_rad
                self.standing = standing
            self.held = None

    def feet_m(self, pose: BridgePose) -> dict[str, Point]:
        """Every foot's plan position, in the standing base's frame (``pose`` as read)."""
        used = self.held or pose
        return self.layout.feet_m(
            used.rotation_rad, used.fold_rad, self.standing, self.far_bridge_rad
        )
