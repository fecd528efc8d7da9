"""Parameters of the co-simulation model: masses, geometry, stiffness, hydraulics, friction.

The paper gives the foot area, the movement cycle and the resulting pressures, not the
machine's drawings; these values are chosen to be physically plausible for an ~18.8 t
machine with 280 bar hydraulics and to reproduce the paper's figures (see the README,
"The co-simulation model"). Leg cylinder and lever geometry come from the machine
configuration, so the model and the estimator share the legs.
"""

import math
from dataclasses import dataclass, field

from estimator.geometry import LegGeometry

#: Standard gravity.
G_M_S2 = 9.80665
#: Angles of a base's feet F1, F2, F3 about the centre of its feet, in the base's frame
#: (x along the bridge at rotation 0; for the hanging base, pointing away from the
#: standing one): the frame of ``[stability.bases.*]`` in the machine configuration.
FOOT_ANGLES_DEG = (0.0, 120.0, 240.0)


def default_leg() -> LegGeometry:
    """The leg of deploy/machine.example.toml (100/63 mm cylinder, lever ratio 0.6705)."""
    return LegGeometry(
        A_piston_m2=7.854e-3,
        A_rod_m2=4.737e-3,
        l_r_m=0.90,
        l_z_m=0.25,
        l_b_m=1.20,
        l_gb_m=0.55,
        alpha_cyl_rad=math.radians(75.0),
        F_gLeg_N=4905.0,
        A_foot_m2=0.33,
    )


@dataclass(frozen=True)
class ModelParams:
    """Everything the model needs; SI units (angles in the cycle schedule are degrees)."""

    leg: LegGeometry = field(default_factory=default_leg)
    #: Each simulated leg's own geometry, in :data:`sim_bridge.result.LEGS` order (the
    #: config leg played on it); None: ``leg`` for every one. Its chamber pressures are
    #: what that leg's cylinder and levers need for the foot force; the dynamics (the oil
    #: column's stiffness) stay ``leg``'s.
    legs: tuple[LegGeometry, ...] | None = None

    # --- geometry -------------------------------------------------------------------
    #: Distance between the two bases' rotation axes with the bridge unfolded.
    bridge_length_m: float = 6.0
    #: Radius of the circle through a base's three feet (feet 120 deg apart, F1 at 0 deg).
    foot_radius_m: float = 1.6
    #: Offset of SB1's bridge rotation axis from the centre of its feet, towards F1.
    axis_offset_m: float = 0.070
    #: Height of the bridge's fold hinge (and of the inclination joints) above ground.
    hinge_height_m: float = 2.5

    # --- masses ---------------------------------------------------------------------
    #: One standing base with its three legs.
    base_kg: float = 2600.0
    #: One half of the bridge.
    bridge_half_kg: float = 1400.0
    #: Upper carriage with engine and crane.
    carriage_kg: float = 10800.0

    # --- carriage positions along the bridge, from SB1's axis towards SB2 -----------
    #: Over SB2 at the start of the cycle.
    carriage_start_m: float = 4.5
    #: Over SB1 after the carriage move (t = 7 s): SB1 carries ~64 % with six feet down;
    #: back here at the end of the step (t = 44.7 s), SB1 carries ~62 %.
    carriage_over_sb1_m: float = 1.5
    #: Counterweight position behind SB1's axis, reached while SB2 is lifted
    #: (t = 8..12 s), so that the centre of gravity lies over SB1's feet.
    carriage_counterweight_m: float = -2.08

    # --- ground contact ---------------------------------------------------------------
    #: Vertical ground spring: the most loaded foot (~100 kN) compresses ~0.2 mm.
    ground_stiffness_N_m: float = 5.0e8
    #: Damping ratio of the foot's vertical support (ground + oil column) modes.
    support_damping_ratio: float = 0.25
    #: Static and sliding friction coefficients of the foot on the ground.
    friction_static: float = 0.6
    friction_sliding: float = 0.5

    # --- hydraulics -------------------------------------------------------------------
    #: Effective bulk modulus of the oil (with hoses and air content).
    bulk_modulus_Pa: float = 1.4e9
    #: Length of the oil column in a leg cylinder's piston chamber (V / A_piston).
    oil_column_m: float = 0.6
    #: Pressure of the rod chamber, held by the valve's return line.
    rod_back_pressure_Pa: float = 0.8e6
    #: Leg cylinder friction: viscous part.
    cylinder_viscous_N_s_m: float = 2.0e4
    #: Leg cylinder friction: static (Coulomb) part, smoothed over ``stribeck_velocity_m_s``.
    cylinder_static_friction_N: float = 1200.0
    stribeck_velocity_m_s: float = 1.0e-3
    #: Inclination cylinder: piston area, rod-side area and lever arm about its joint.
    incl_A_piston_m2: float = 1.2272e-2
    incl_A_rod_m2: float = 7.363e-3
    incl_arm_m: float = 0.8

    # --- bridge fold drive --------------------------------------------------------------
    #: Fold angle at the hard stop of the bridge cylinder.
    fold_stop_deg: float = 45.0
    #: The fold command overshoots the stop so the cylinder presses the bridge against it.
    fold_command_overshoot_deg: float = 3.0
    #: PT1 time constant of the bridge cylinder's input (paper, section 3.2).
    fold_pt1_s: float = 0.35
    #: Closed-loop natural frequency and damping ratio of the fold drive.
    fold_servo_rad_s: float = 4.0
    fold_servo_damping: float = 0.7
    #: Stiffness of the hard stop as a natural frequency of the folded half on it, and damping.
    fold_stop_rad_s: float = 15.0
    fold_stop_damping: float = 0.04

    # --- lifting ----------------------------------------------------------------------
    #: Bridge inclination at SB1 that lifts SB2's feet clear of the ground.
    lift_inclination_deg: float = 3.0
    #: SB2's feet press this far into their springs when set down at the end of the step,
    #: so they carry load from t = 44 s on, before the carriage has come back over SB1.
    set_down_preload_m: float = 3.0e-3
    #: Leg strokes: extended (standing) and retracted (folded up in the air).
    stroke_extended_m: float = 1.0
    stroke_retracted_m: float = 0.3

    @property
    def mass_kg(self) -> float:
        return 2 * self.base_kg + 2 * self.bridge_half_kg + self.carriage_kg

    @property
    def fold_mass_kg(self) -> float:
        """The part that folds: SB2's bridge half and SB2 with its legs."""
        return self.bridge_half_kg + self.base_kg

    @property
    def fold_arm_m(self) -> float:
        """Distance from the fold hinge to the folding part's centre of gravity."""
        half = self.bridge_length_m / 2
        return (self.bridge_half_kg * half / 2 + self.base_kg * half) / self.fold_mass_kg

    @property
    def fold_inertia_kg_m2(self) -> float:
        """Moment of inertia of the folding part about the hinge."""
        half = self.bridge_length_m / 2
        return self.bridge_half_kg * half**2 / 3 + self.base_kg * half**2

    @property
    def hydraulic_stiffness_N_m(self) -> float:
        """Oil column stiffness of a leg cylinder, as seen at the foot (times ratio^2)."""
        k_cylinder = self.bulk_modulus_Pa * self.leg.A_piston_m2 / self.oil_column_m
        return k_cylinder * self.leg.force_ratio**2

    @property
    def support_stiffness_N_m(self) -> float:
        """Ground spring and oil column of one leg in series."""
        return 1.0 / (1.0 / self.ground_stiffness_N_m + 1.0 / self.hydraulic_stiffness_N_m)
