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
from sim_bridge.params import FOOT_ANGLES_DEG, G_M_S2, ModelParams
from sim_bridge.result import LEGS, SimulationResult

FloatArray = npt.NDArray[np.float64]

#: Angles of a base's feet F1, F2, F3 about its centre.
FOOT_ANGLES_RAD = np.radians(FOOT_ANGLES_DEG)


@dataclass(frozen=True)
class _Pose:
    """Where everything is at one instant, for given cycle time and fold angle."""

    feet_xy: FloatArray  # (6, 2)
    clearance_m: FloatArray  # (6,) foot height above its free contact point
    clearance_rate_m_s: FloatArray  # (6,)
    masses_kg: FloatArray  # (k,)
    masses_xy: FloatArray  # (k, 2)
    fold_cog_xy: FloatArray  # (2,)
    bridge_dir: FloatArray  # (2,) unit vector from the standing base's axis along the bridge
    axis_xy: FloatArray  # (2,) the standing base's rotation axis


@dataclass(frozen=True)
class _Stance:
    """One step: which base stands, and where, in the world frame (SB1's frame at t = 0).

    The cycle's set-points (sim_bridge.cycle) are written for the standing base; the
    lifted base hangs at the bridge's far end, turned with the bridge.
    """

    #: When the step starts, s since the simulation started.
    start_s: float
    #: The standing base: 0 (SB1) or 1 (SB2), index into result.BASES.
    base: int
    #: The standing base's feet (3, 2) and the bridge's rotation axis on it (2,).
    standing_feet_xy: FloatArray
    axis_xy: FloatArray
    #: How far the standing base's feet were pressed in when it was set down (3,), m
    #: (negative clearance; zero for SB1, which stood from the start).
    standing_clearance_m: FloatArray
    #: The lifted base's feet centre lies this far beyond the bridge's end (its own
    #: rotation axis), along the bridge, m.
    lifted_beyond_m: float
    #: The lifted base's F1 points this far (rad) from the bridge's direction.
    lifted_turn_rad: float
    #: Inclination at the standing base when the step starts, rad (the previous
    #: set-down's preload, seen from this base).
    inclination_start_rad: float

    @property
    def standing(self) -> slice:
        return slice(3 * self.base, 3 * self.base + 3)

    @property
    def lifted(self) -> slice:
        return slice(3 - 3 * self.base, 6 - 3 * self.base)


def _stances(p: ModelParams) -> tuple[_Stance, ...]:
    """The steps the model can play (cycle.MAX_STEPS): SB1 standing, then SB2.

    The second starts where the first ends: SB2 stands where it was set down (pressed in
    by the preload), turned with the bridge; the bridge now turns about SB2's axis (at
    its feet's centre, as the first step hangs it), and SB1 hangs at the far end with its
    F1 towards SB2 (the bridge lay over SB1_F1) and its axis ``axis_offset_m`` nearer
    than its feet's centre.
    """
    circle = np.stack([np.cos(FOOT_ANGLES_RAD), np.sin(FOOT_ANGLES_RAD)], axis=1)
    first = _Stance(
        start_s=0.0,
        base=0,
        standing_feet_xy=p.foot_radius_m * circle,
        axis_xy=np.array([p.axis_offset_m, 0.0]),
        standing_clearance_m=np.zeros(3),
        lifted_beyond_m=0.0,
        lifted_turn_rad=0.0,
        inclination_start_rad=0.0,
    )
    end = _pose(cycle.CYCLE_END_S, 0.0, p, first)
    sb2_feet = end.feet_xy[first.lifted]
    second = _Stance(
        start_s=cycle.CYCLE_END_S,
        base=1,
        standing_feet_xy=sb2_feet,
        axis_xy=sb2_feet.mean(axis=0),
        standing_clearance_m=end.clearance_m[first.lifted],
        lifted_beyond_m=p.axis_offset_m,
        lifted_turn_rad=np.pi,
        inclination_start_rad=-float(cycle.inclination_rad(cycle.CYCLE_END_S, p)),
    )
    return first, second


def _stance_at(stances: tuple[_Stance, ...], t_s: float) -> _Stance:
    return stances[min(int(t_s // cycle.CYCLE_END_S), len(stances) - 1)]


def _pose(t_s: float, fold_rad: float, p: ModelParams, stance: _Stance) -> _Pose:
    step_t_s = t_s - stance.start_s
    psi = float(cycle.rotation_rad(step_t_s))
    u = np.array([np.cos(psi), np.sin(psi)])
    axis = stance.axis_xy
    half = p.bridge_length_m / 2
    cos_fold = np.cos(fold_rad)
    lifted_centre = axis + (half + half * cos_fold + stance.lifted_beyond_m) * u
    lifted_angles = psi + stance.lifted_turn_rad + FOOT_ANGLES_RAD
    lifted_feet = lifted_centre + p.foot_radius_m * np.stack(
        [np.cos(lifted_angles), np.sin(lifted_angles)], axis=1
    )
    feet = np.empty((6, 2))
    feet[stance.standing] = stance.standing_feet_xy
    feet[stance.lifted] = lifted_feet

    # The lifted base's feet rise with the inclination (about the standing base's joint),
    # the fold and the legs' retraction.
    along_m = (lifted_feet - axis) @ u
    gamma = float(cycle.inclination_rad(step_t_s, p))
    gamma_rate = float(cycle.inclination_rate_rad_s(step_t_s, p))
    retracted = p.stroke_extended_m - float(cycle.lifted_stroke_m(step_t_s, p))
    clearance = np.zeros(6)
    clearance[stance.standing] = stance.standing_clearance_m
    clearance[stance.lifted] = along_m * np.sin(gamma) + half * np.sin(fold_rad) + retracted
    clearance_rate = np.zeros(6)
    clearance_rate[stance.lifted] = along_m * np.cos(gamma) * gamma_rate - float(
        cycle.lifted_stroke_rate_m_s(step_t_s, p)
    )

    s = float(cycle.carriage_m(step_t_s, p))
    third = p.base_kg / 3
    masses = np.array([third] * 6 + [p.bridge_half_kg, p.bridge_half_kg, p.carriage_kg])
    positions = np.vstack(
        [
            feet,
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
    """(the six feet (6, 2), the centre of gravity (2,)) in the plan at time ``t_s`` and
    fold angle ``fold_rad``, in the world frame (SB1's frame; from the second step on,
    ``t_s >= cycle.CYCLE_END_S``, SB1 has moved in it), m: the reference for the
    estimator's foot layout and stability margin."""
    p = params or ModelParams()
    pose = _pose(t_s, fold_rad, p, _stance_at(_stances(p), t_s))
    cog = pose.masses_kg @ pose.masses_xy / pose.masses_kg.sum()
    return pose.feet_xy, np.asarray(cog, dtype=np.float64)


def _lever_rows(xy: FloatArray) -> FloatArray:
    """Rows [1, y, -x]: how heave, roll and pitch move a point vertically."""
    xy = np.atleast_2d(xy)
    return np.column_stack([np.ones(len(xy)), xy[:, 1], -xy[:, 0]])


class _Model:
    """The right-hand side of the ODE and the forces at a state."""

    def __init__(self, p: ModelParams, steps: int = 1) -> None:
        self.p = p
        self.stances = _stances(p)[:steps]
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
        stance = _stance_at(self.stances, t_s)
        pose = _pose(t_s, fold, p, stance)
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
        command_rad = float(cycle.fold_command_rad(t_s - stance.start_s, p))
        command_rate = (command_rad - command) / p.fold_pt1_s
        return np.concatenate([q_rate, q_acc, [fold_rate, fold_acc, command_rate]])

    def static_state(self) -> FloatArray:
        """The body at rest on its springs at t = 0 (active set: feet that push)."""
        p = self.p
        pose = _pose(0.0, 0.0, p, self.stances[0])
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
    t_end_s: float | None = None,
    noise: ImpulsiveNoise | None = None,
    steps: int = 1,
) -> SimulationResult:
    """Simulate ``steps`` steps (1: SB2 lifted; 2: then SB1 lifted, a full walking
    cycle) and sample every output each ``dt_s`` seconds, until ``t_end_s`` (default:
    the steps' end, ``steps * cycle.CYCLE_END_S``)."""
    p = params or ModelParams()
    if not 0 < rtol < 1:
        raise ValueError(f"rtol must be in (0, 1), got {rtol}")
    if not 1 <= steps <= cycle.MAX_STEPS:
        raise ValueError(f"steps must be 1..{cycle.MAX_STEPS}, got {steps}")
    if t_end_s is None:
        t_end_s = steps * cycle.CYCLE_END_S
    model = _Model(p, steps)
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
    # Per row: its step, the time since that step started, and the lifted legs.
    step = np.minimum((t_s // cycle.CYCLE_END_S).astype(np.int_), len(model.stances) - 1)
    stances = [model.stances[k] for k in step]
    step_t_s = t_s - np.array([stance.start_s for stance in model.stances])[step]
    lifted = np.zeros((n, 6), dtype=bool)
    for i, (t, y, stance) in enumerate(zip(t_s, states, stances, strict=True)):
        pose = _pose(float(t), y[6], p, stance)
        force[i], deflection_rate[i] = model.foot_forces(pose, y[0:3], y[3:6])
        lifted[i, stance.lifted] = True
        along = (pose.masses_xy - pose.axis_xy) @ pose.bridge_dir
        along_feet = (pose.feet_xy[stance.lifted] - pose.axis_xy) @ pose.bridge_dir
        # The standing base's inclination cylinder holds the bridge's side: the lifted
        # base, both halves and the carriage, less what the lifted feet carry.
        bridge_side = np.r_[lifted[i], np.ones(3)].astype(bool)
        incl_moment[i, stance.base] = G_M_S2 * (
            pose.masses_kg[bridge_side] @ along[bridge_side]
        ) - (force[i, stance.lifted] @ along_feet)
        incl_moment[i, 1 - stance.base] = max(
            force[i, stance.lifted].sum() - p.base_kg * G_M_S2, 0.0
        ) * (p.bridge_length_m / 4)

    stroke = np.where(lifted, cycle.lifted_stroke_m(step_t_s, p)[:, None], p.stroke_extended_m)
    stroke_rate = np.where(lifted, cycle.lifted_stroke_rate_m_s(step_t_s, p)[:, None], 0.0)

    # Cylinder velocity: the oil column compresses as the foot force rises, plus the
    # commanded stroke motion. Friction opposes it and shows up in the pressures.
    in_contact = force > 0
    column_rate = np.where(in_contact, -p.hydraulic_stiffness_N_m * deflection_rate, 0.0)
    # Each leg's own cylinder and levers (per column), so that eq. (4) with the config's
    # geometry of the leg played there reads its foot force.
    legs = p.legs or (leg,) * len(LEGS)
    force_ratio = np.array([g.force_ratio for g in legs])
    cylinder_rate = column_rate / p.hydraulic_stiffness_N_m * force_ratio + stroke_rate
    friction_N = p.cylinder_viscous_N_s_m * cylinder_rate + p.cylinder_static_friction_N * np.tanh(
        cylinder_rate / p.stribeck_velocity_m_s
    )
    weight_term_N = np.array([g.weight_term_N for g in legs])
    cylinder_force_N = (force - weight_term_N) / force_ratio + friction_N
    p_piston, p_rod = _chamber_pressures(
        cylinder_force_N,
        np.array([g.A_piston_m2 for g in legs]),
        np.array([g.A_rod_m2 for g in legs]),
        p.rod_back_pressure_Pa,
    )
    if noise is not None:
        p_piston = noise.apply(p_piston, t_s)

    incl_p_piston, incl_p_rod = _chamber_pressures(
        incl_moment / p.incl_arm_m, p.incl_A_piston_m2, p.incl_A_rod_m2, p.rod_back_pressure_Pa
    )

    tangential = _tangential_forces(model, step_t_s, states, force)
    slipping = in_contact & (tangential > p.friction_static * force)
    # Inclination at each base: the standing one's joint lifts, the other sees it negated.
    first = np.array([stance.base == 0 for stance in stances])
    standing_rad = cycle.inclination_rad(step_t_s, p) + np.array(
        [stance.inclination_start_rad for stance in stances]
    )
    inclination = np.degrees(np.where(first, standing_rad, -standing_rad))
    # The carriage from the bridge's middle towards SB1, which stands in the first step
    # (cycle.carriage_m is measured from the standing base's axis).
    from_middle_m = p.bridge_length_m / 2 - cycle.carriage_m(step_t_s, p)
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
        rotation_deg=np.degrees(cycle.rotation_rad(step_t_s)) % 360.0,
        carriage_m=np.where(first, from_middle_m, -from_middle_m),
        phase=cycle.phase_index(step_t_s),
    )


def _chamber_pressures(
    force_N: FloatArray,
    A_piston_m2: float | FloatArray,
    A_rod_m2: float | FloatArray,
    back_pressure_Pa: float,
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
    model: _Model, step_t_s: FloatArray, states: FloatArray, force: FloatArray
) -> FloatArray:
    """Horizontal force each foot must hold: the folding part's inertia along the bridge
    and the torque that turns the bridge, shared by the feet in contact (``step_t_s``:
    time since each row's step started)."""
    p = model.p
    fold, fold_rate = states[:, 6], states[:, 7]
    command = states[:, 8]
    fold_acc = np.array(
        [model.fold_acceleration(a, b, c) for a, b, c in zip(fold, fold_rate, command, strict=True)]
    )
    along_N = (
        p.fold_mass_kg
        * p.fold_arm_m
        * np.abs(fold_acc * np.sin(fold) + fold_rate**2 * np.cos(fold))
    )
    # Rotating parts: carriage, bridge halves and the folded part, about the standing axis.
    half = p.bridge_length_m / 2
    carriage = cycle.carriage_m(step_t_s, p)
    inertia = (
        p.carriage_kg * carriage**2
        + p.bridge_half_kg * (half / 2) ** 2
        + p.fold_mass_kg * (half + p.fold_arm_m * np.cos(fold)) ** 2
    )
    torque = inertia * np.abs(cycle.rotation_acceleration_rad_s2(step_t_s))
    total = force.sum(axis=1, keepdims=True)
    contact_count = np.maximum((force > 0).sum(axis=1, keepdims=True), 1)
    share = np.divide(force, total, out=np.zeros_like(force), where=total > 0)
    tangential: FloatArray = share * along_N[:, None] + (force > 0) * (
        torque[:, None] / (contact_count * p.foot_radius_m)
    )
    return tangential
