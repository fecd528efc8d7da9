"""Leg geometry of Figure 3: cylinder areas, lever arms, leg weight and foot area."""

import math
from dataclasses import dataclass, field

from estimator._checks import require_finite, require_non_negative, require_positive


@dataclass(frozen=True, slots=True)
class LegGeometry:
    """One leg as eq. (4) sees it; SI units throughout.

    The lever distances are measured from the leg's pivot A (Figure 3):
    ``l_r_m``/``l_z_m`` locate the cylinder's attachment on the leg along the
    r and z axes, ``l_b_m`` is the horizontal distance to the foot and
    ``l_gb_m`` the horizontal distance to the leg's centre of gravity.

    >>> leg = LegGeometry(A_piston_m2=7.854e-3, A_rod_m2=4.737e-3, l_r_m=0.9,
    ...                   l_z_m=0.25, l_b_m=1.2, l_gb_m=0.55,
    ...                   alpha_cyl_rad=math.radians(75), F_gLeg_N=4905.0, A_foot_m2=0.33)
    >>> round(leg.force_ratio, 4)
    0.6705
    """

    #: Piston (cap-end) area of the leg cylinder.
    A_piston_m2: float
    #: Rod-side annulus area (piston area minus rod cross section).
    A_rod_m2: float
    #: Cylinder attachment on the leg, along the r axis from pivot A.
    l_r_m: float
    #: Cylinder attachment on the leg, along the z axis from pivot A.
    l_z_m: float
    #: Horizontal distance from pivot A to the foot's contact point.
    l_b_m: float
    #: Horizontal distance from pivot A to the leg's centre of gravity.
    l_gb_m: float
    #: Angle of the cylinder axis against the r axis.
    alpha_cyl_rad: float
    #: Weight force of the leg.
    F_gLeg_N: float
    #: Contact area of the foot (0.33 m2 in the paper).
    A_foot_m2: float
    #: Calibrated gain on the lever term (``portal-daq calibrate``); 1: the design geometry.
    force_gain: float = 1.0
    #: Calibrated offset added to the foot force (transducer zero offsets, leg weight).
    force_offset_N: float = 0.0
    #: (l_r sin a - l_z cos a) / l_b: foot force per newton of cylinder force.
    force_ratio: float = field(init=False)
    #: (l_gb / l_b) F_gLeg: the leg's own weight as seen at the foot.
    weight_term_N: float = field(init=False)
    #: force_gain x force_ratio: what eq. (4) multiplies the cylinder force by.
    calibrated_ratio: float = field(init=False)
    #: weight_term_N + force_offset_N: what eq. (4) adds.
    calibrated_term_N: float = field(init=False)

    def __post_init__(self) -> None:
        for name in ("A_piston_m2", "A_rod_m2", "l_b_m", "A_foot_m2"):
            require_positive(name, getattr(self, name))
        for name in ("l_r_m", "l_z_m", "l_gb_m", "alpha_cyl_rad"):
            require_finite(name, getattr(self, name))
        require_non_negative("F_gLeg_N", self.F_gLeg_N)
        require_positive("force_gain", self.force_gain)
        require_finite("force_offset_N", self.force_offset_N)
        if self.A_rod_m2 >= self.A_piston_m2:
            raise ValueError(
                f"A_rod_m2 ({self.A_rod_m2}) must be smaller than A_piston_m2 "
                f"({self.A_piston_m2}): the annulus is the piston area minus the rod"
            )
        lever_arm_m = self.l_r_m * math.sin(self.alpha_cyl_rad) - self.l_z_m * math.cos(
            self.alpha_cyl_rad
        )
        if lever_arm_m <= 0:
            raise ValueError(
                f"the lever arm l_r_m*sin(alpha_cyl) - l_z_m*cos(alpha_cyl) = {lever_arm_m:.4g} m "
                "must be > 0: "
                "with this geometry a pushing cylinder cannot carry the foot"
            )
        # Precomputed once so that the per-frame path is two multiplies and an add,
        # identical for scalars and numpy arrays.
        object.__setattr__(self, "force_ratio", lever_arm_m / self.l_b_m)
        object.__setattr__(self, "weight_term_N", self.l_gb_m / self.l_b_m * self.F_gLeg_N)
        object.__setattr__(self, "calibrated_ratio", self.force_gain * self.force_ratio)
        object.__setattr__(self, "calibrated_term_N", self.weight_term_N + self.force_offset_N)
