"""The co-simulation model: the machine on six ground springs through the movement cycle.

Pure computation (numpy + scipy's ``solve_ivp``), no I/O. The machine is one body that
moves vertically (heave, roll, pitch; small angles) on the six feet. Its mass is a set of
point masses placed by the cycle's kinematics (bases, bridge halves, carriage), so the
support is statically indeterminate and solved through the springs, not split by hand.
Each foot is a unilateral support: the ground spring (~0.2 mm at the highest load) in
series with the leg cylinder's oil column (hydraulic compressibility), with damping.

The folding half of the bridge (with SB2) is a second body: it turns about the fold
hinge, driven by a position-controlled bridge cylinder whose input passes a PT1 element,
and is stopped by a stiff hard stop at the end of the fold (t = 23 s). Its inertial
forces (vertical, and horizontal at hinge height) act on the body, which gives the
oscillation and pressure peak of the paper.

The leg cylinder pressures follow from the true foot force through the leg's lever
(eq. 4 backwards) plus the cylinder friction (viscous + smoothed static), so that eq. (4)
applied to the pressures deviates from the true force the way the paper explains.
"""

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.integrate import solve_ivp

from sim_bridge import cycle
from sim_bridge.noise import ImpulsiveNoise
from sim_bridge.params import G_M_S2, ModelParams
from sim_bridge.result import SimulationResult

FloatArray = npt.NDArray[np.float64]

#: Angles of a base's feet F1, F2, F3 about its centre.
FOOT_ANGLES_RAD = np.radians([0.0, 120.0, 240.0])


@dataclass(frozen=True)
class _Pose:
    """Where everything is at one instant, for given cycle time and fold angle."""

    feet_xy: FloatArray  # (6, 2)
    clearance_m: FloatArray  # (6,) foot height above its free contact point
    clearance_rate_m_s: FloatArray  # (6,)
    masses_kg: FloatArray  # (k,)
    masses_xy: FloatArray  # (k, 2)
    fold_cog_xy: FloatArray  # (2,)
    bridge_dir: FloatArray  # (2,) unit vector from SB1's axis along the bridge
    axis_xy: FloatArray  # (2,) SB1's rotation axis


def _pose(t_s: float, fold_rad: float, p: ModelParams) -> _Pose:
    psi = float(cycle.rotation_rad(t_s))
    u = np.array([np.cos(psi), np.sin(psi)])
    axis = np.array([p.axis_offset_m, 0.0])
    half = p.bridge_length_m / 2
    cos_fold = np.cos(fold_rad)
    circle = np.stack([np.cos(FOOT_ANGLES_RAD), np.sin(FOOT_ANGLES_RAD)], axis=1)
    sb1_feet = p.foot_radius_m * circle
    sb2_centre = axis + (half + half * cos_fold) * u
    sb2_angles = psi + FOOT_ANGLES_RAD
    sb2_feet = sb2_centre + p.foot_radius_m * np.stack(
        [np.cos(sb2_angles), np.sin(sb2_angles)], axis=1
    )
    feet = np.vstack([sb1_feet, sb2_feet])

    # SB2's feet rise with the inclination (about SB1's joint), the fold and the legs' retraction.
    along_m = (sb2_feet - axis) @ u
    gamma = float(cycle.inclination_rad(t_s, p))
    gamma_rate = float(cycle.inclination_rate_rad_s(t_s, p))
    retracted = p.stroke_extended_m - float(cycle.sb2_stroke_m(t_s, p))
    clearance = np.zeros(6)
    clearance[3:] = along_m * np.sin(gamma) + half * np.sin(fold_rad) + retracted
    clearance_rate = np.zeros(6)
    clearance_rate[3:] = along_m * np.cos(gamma) * gamma_rate - float(
        cycle.sb2_stroke_rate_m_s(t_s, p)
    )

    s = float(cycle.carriage_m(t_s, p))
    third = p.base_kg / 3
    masses = np.array([third] * 6 + [p.bridge_half_kg, p.bridge_half_kg, p.carriage_kg])
    positions = np.vstack(
        [
            sb1_feet,
            sb2_feet,
            axis + half / 2 * u,
            axis + (half + half / 2 * cos_fold) * u,
            axis + s * u,
        ]
    )
    fold_cog = axis + (half + p.fold_arm_m * cos_fold) * u
    return _Pose(feet, clearance, clearance_rate, masses, positions, fold_cog, u, axis)


def plan_view(
    t_s: float, fold_rad: float, params: ModelParams | None = None
) -> tuple[FloatArray, FloatArray]:
    """(the six feet (6, 2), the centre of gravity (2,)) in the plan at cycle time ``t_s``
    and fold angle ``fold_rad``, in SB1's frame (m): the reference for the estimator's
    foot layout and stability margin."""
    p = params or ModelParams()
    pose = _pose(t_s, fold_rad, p)
    cog = pose.masses_kg @ pose.masses_xy / pose.masses_kg.sum()
    return pose.feet_xy, np.asarray(cog, dtype=np.float64)


def _lever_rows(xy: FloatArray) -> FloatArray:
    """Rows [1, y, -x]: how heave, roll and pitch move a point vertically."""
    xy = np.atleast_2d(xy)
    return np.column_stack([np.ones(len(xy)), xy[:, 1], -xy[:, 0]])


class _Model:
    """The right-hand side of the ODE and the forces at a state."""

    def __init__(self, p: ModelParams) -> None:
        self.p = p
        self.k_N_m = p.support_stiffness_N_m
        # Damping of one foot's support against a third of the machine.
        self.c_N_s_m = 2 * p.support_damping_ratio * np.sqrt(self.k_N_m * p.mass_kg / 3)
        inertia = p.fold_inertia_kg_m2
        self.fold_inertia = inertia
        self.servo_k = inertia * p.fold_servo_rad_s**2
        self.servo_d = 2 * p.fold_servo_damping * p.fold_servo_rad_s * inertia
        self.stop_k = inertia * p.fold_stop_rad_s**2
        self.stop_d = 2 * p.fold_stop_damping * p.fold_stop_rad_s * inertia
        self.stop_rad = np.radians(p.fold_stop_deg)

    def foot_forces(
        self, pose: _Pose, q: FloatArray, q_rate: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """(force, deflection rate) of each foot; zero force where it is off the ground."""
        rows = _lever_rows(pose.feet_xy)
        deflection = -(rows @ q) - pose.clearance_m
        rate = -(rows @ q_rate) - pose.clearance_rate_m_s
        force = np.where(deflection > 0, self.k_N_m * deflection + self.c_N_s_m * rate, 0.0)
        return np.maximum(force, 0.0), rate

    def fold_acceleration(self, fold: float, fold_rate: float, command: float) -> float:
        torque = self.servo_k * (command - fold) - self.servo_d * fold_rate
        if fold > self.stop_rad:
            # The stop pushes, never pulls.
            torque += min(0.0, -self.stop_k * (fold - self.stop_rad) - self.stop_d * fold_rate)
        return torque / self.fold_inertia

    def rhs(self, t_s: float, y: FloatArray) -> FloatArray:
        p = self.p
        q, q_rate = y[0:3], y[3:6]
        fold, fold_rate, command = y[6], y[7], y[8]
        pose = _pose(t_s, fold, p)
        forces, _ = self.foot_forces(pose, q, q_rate)
        fold_acc = self.fold_acceleration(fold, fold_rate, command)

        mass_rows = _lever_rows(pose.masses_xy)
        generalized = _lever_rows(pose.feet_xy).T @ forces - G_M_S2 * (mass_rows.T @ pose.masses_kg)
        # Inertial reaction of the folding part on the body: vertical at its centre of
        # gravity, horizontal (along the bridge) at hinge height.
        arm = p.fold_arm_m
        acc_vertical = arm * (fold_acc * np.cos(fold) - fold_rate**2 * np.sin(fold))
        acc_along = -arm * (fold_acc * np.sin(fold) + fold_rate**2 * np.cos(fold))
        generalized += -p.fold_mass_kg * acc_vertical * _lever_rows(pose.fold_cog_xy)[0]
        along_N = -p.fold_mass_kg * acc_along
        u = pose.bridge_dir
        generalized[1] += -p.hinge_height_m * along_N * u[1]
        generalized[2] += p.hinge_height_m * along_N * u[0]

        mass_matrix = mass_rows.T @ (pose.masses_kg[:, None] * mass_rows)
        q_acc = np.linalg.solve(mass_matrix, generalized)
        command_rate = (float(cycle.fold_command_rad(t_s, p)) - command) / p.fold_pt1_s
        return np.concatenate([q_rate, q_acc, [fold_rate, fold_acc, command_rate]])

    def static_state(self) -> FloatArray:
        """The body at rest on its springs at t = 0 (active set: feet that push)."""
        p = self.p
        pose = _pose(0.0, 0.0, p)
        rows = _lever_rows(pose.feet_xy)
        load = G_M_S2 * (_lever_rows(pose.masses_xy).T @ pose.masses_kg)
        active = np.ones(6, dtype=bool)
        for _ in range(6):
            a = rows[active]
            stiffness = self.k_N_m * a.T @ a
            q = -np.linalg.solve(stiffness, load + self.k_N_m * a.T @ pose.clearance_m[active])
            deflection = -(rows @ q) - pose.clearance_m
            now_active = deflection > 0
            if np.array_equal(now_active, active):
                break
            active = now_active
        return np.concatenate([q, np.zeros(3)])


def simulate(
    params: ModelParams | None = None,
    *,
    rtol: float = 1e-5,
    dt_s: float = 0.01,
    t_end_s: float = cycle.CYCLE_END_S,
    noise: ImpulsiveNoise | None = None,
) -> SimulationResult:
    """Simulate one movement cycle and sample every output each ``dt_s`` seconds."""
    p = params or ModelParams()
    if not 0 < rtol < 1:
        raise ValueError(f"rtol must be in (0, 1), got {rtol}")
    model = _Model(p)
    y0 = np.concatenate([model.static_state(), [0.0, 0.0, 0.0]])
    t_eval = np.arange(0.0, t_end_s + dt_s / 2, dt_s)
    # Position states in metres/radians are tiny (mm, mrad): absolute tolerances per state.
    atol = np.array([1e-9, 1e-9, 1e-9, 1e-7, 1e-7, 1e-7, 1e-8, 1e-7, 1e-8]) * (rtol / 1e-5)
    solution = solve_ivp(
        model.rhs, (0.0, t_end_s), y0, method="LSODA", t_eval=t_eval, rtol=rtol, atol=atol
    )
    if not solution.success:
        raise RuntimeError(f"the simulation failed at rtol={rtol}: {solution.message}")
    return _outputs(model, solution.t, solution.y.T, noise)


def _outputs(
    model: _Model, t_s: FloatArray, states: FloatArray, noise: ImpulsiveNoise | None
) -> SimulationResult:
    p = model.p
    leg = p.leg
    n = t_s.size
    force = np.zeros((n, 6))
    deflection_rate = np.zeros((n, 6))
    incl_moment = np.zeros((n, 2))
    for i, (t, y) in enumerate(zip(t_s, states, strict=True)):
        pose = _pose(float(t), y[6], p)
        force[i], deflection_rate[i] = model.foot_forces(pose, y[0:3], y[3:6])
        along = (pose.masses_xy - pose.axis_xy) @ pose.bridge_dir
        along_feet = (pose.feet_xy[3:] - pose.axis_xy) @ pose.bridge_dir
        bridge_side = np.r_[np.zeros(3), np.ones(6)].astype(bool)  # SB2 base, halves, carriage
        incl_moment[i, 0] = G_M_S2 * (pose.masses_kg[bridge_side] @ along[bridge_side]) - (
            force[i, 3:] @ along_feet
        )
        incl_moment[i, 1] = max(force[i, 3:].sum() - p.base_kg * G_M_S2, 0.0) * (
            p.bridge_length_m / 4
        )

    stroke = np.full((n, 6), p.stroke_extended_m)
    stroke[:, 3:] = cycle.sb2_stroke_m(t_s, p)[:, None]
    stroke_rate = np.zeros((n, 6))
    stroke_rate[:, 3:] = cycle.sb2_stroke_rate_m_s(t_s, p)[:, None]

    # Cylinder velocity: the oil column compresses as the foot force rises, plus the
    # commanded stroke motion. Friction opposes it and shows up in the pressures.
    in_contact = force > 0
    column_rate = np.where(in_contact, -p.hydraulic_stiffness_N_m * deflection_rate, 0.0)
    cylinder_rate = column_rate / p.hydraulic_stiffness_N_m * leg.force_ratio + stroke_rate
    friction_N = p.cylinder_viscous_N_s_m * cylinder_rate + p.cylinder_static_friction_N * np.tanh(
        cylinder_rate / p.stribeck_velocity_m_s
    )
    cylinder_force_N = (force - leg.weight_term_N) / leg.force_ratio + friction_N
    p_piston, p_rod = _chamber_pressures(
        cylinder_force_N, leg.A_piston_m2, leg.A_rod_m2, p.rod_back_pressure_Pa
    )
    if noise is not None:
        p_piston = noise.apply(p_piston, t_s)

    incl_p_piston, incl_p_rod = _chamber_pressures(
        incl_moment / p.incl_arm_m, p.incl_A_piston_m2, p.incl_A_rod_m2, p.rod_back_pressure_Pa
    )

    tangential = _tangential_forces(p, t_s, states, force)
    slipping = in_contact & (tangential > p.friction_static * force)
    inclination = np.degrees(cycle.inclination_rad(t_s, p))
    return SimulationResult(
        t_s=t_s,
        p_piston_Pa=p_piston,
        p_rod_Pa=p_rod,
        force_true_N=force,
        ground_compression_m=force / p.ground_stiffness_N_m,
        slipping=slipping,
        incl_p_piston_Pa=incl_p_piston,
        incl_p_rod_Pa=incl_p_rod,
        stroke_m=stroke,
        inclination_deg=np.column_stack([inclination, -inclination]),
        fold_deg=np.degrees(states[:, 6]),
        rotation_deg=np.degrees(cycle.rotation_rad(t_s)) % 360.0,
        carriage_m=p.bridge_length_m / 2 - cycle.carriage_m(t_s, p),
        phase=cycle.phase_index(t_s),
    )


def _chamber_pressures(
    force_N: FloatArray, A_piston_m2: float, A_rod_m2: float, back_pressure_Pa: float
) -> tuple[FloatArray, FloatArray]:
    """(piston, rod) chamber pressures of a cylinder pushing with ``force_N`` (pulling
    when negative): the loaded chamber carries the force, the other one sits at the
    valve's back pressure."""
    pushing = force_N + back_pressure_Pa * A_rod_m2 >= back_pressure_Pa * A_piston_m2
    p_piston = np.where(
        pushing, (force_N + back_pressure_Pa * A_rod_m2) / A_piston_m2, back_pressure_Pa
    )
    p_rod = np.where(
        pushing, back_pressure_Pa, (back_pressure_Pa * A_piston_m2 - force_N) / A_rod_m2
    )
    return p_piston, p_rod


def _tangential_forces(
    p: ModelParams, t_s: FloatArray, states: FloatArray, force: FloatArray
) -> FloatArray:
    """Horizontal force each foot must hold: the folding part's inertia along the bridge
    and the torque that turns the bridge, shared by the feet in contact."""
    fold, fold_rate = states[:, 6], states[:, 7]
    model = _Model(p)
    command = states[:, 8]
    fold_acc = np.array(
        [model.fold_acceleration(a, b, c) for a, b, c in zip(fold, fold_rate, command, strict=True)]
    )
    along_N = (
        p.fold_mass_kg
        * p.fold_arm_m
        * np.abs(fold_acc * np.sin(fold) + fold_rate**2 * np.cos(fold))
    )
    # Rotating parts: carriage, bridge halves and the folded part, about SB1's axis.
    half = p.bridge_length_m / 2
    carriage = cycle.carriage_m(t_s, p)
    inertia = (
        p.carriage_kg * carriage**2
        + p.bridge_half_kg * (half / 2) ** 2
        + p.fold_mass_kg * (half + p.fold_arm_m * np.cos(fold)) ** 2
    )
    torque = inertia * np.abs(cycle.rotation_acceleration_rad_s2(t_s))
    total = force.sum(axis=1, keepdims=True)
    contact_count = np.maximum((force > 0).sum(axis=1, keepdims=True), 1)
    share = np.divide(force, total, out=np.zeros_like(force), where=total > 0)
    tangential: FloatArray = share * along_N[:, None] + (force > 0) * (
        torque[:, None] / (contact_count * p.foot_radius_m)
    )
    return tangential
