"""The movement cycle of section 2.1 as actuator set-points over time (Figure 2).

Pure functions of the time ``t_s`` since the step started (scalars or numpy arrays). Every
motion is a cosine-smoothed ramp between two set-points, so velocities start and end at
zero. The schedule is written for the first step, SB1 standing and SB2 lifted; the next
step is the same schedule with the roles swapped (SB2 stands, the bridge turns about its
axis and SB1 is lifted; see sim_bridge.model), so "SB1" below means the standing base and
"SB2" the lifted one:

- move carriage:  t = 2..7 s, over SB2 -> over SB1; then on to the counterweight
  position behind SB1 while SB2 is lifted (t = 7.5..10.5 s); back over SB1 once SB2's
  feet touch down (t = 43.2..44.7 s), so all six feet carry the load again;
- fold:           t = 8..12 s inclination lifts SB2's feet, t = 14..18 s SB2's legs fold
  up (retract), t = 18..23 s the bridge folds (PT1-filtered command, hard stop at 23 s);
- rotate:         t = 23..32 s the bridge turns 180 deg, from between SB1_F2/F3 to over SB1_F1;
- unfold:         t = 32.5..39.5 s the bridge unfolds, t = 38..44 s SB2's legs extend
  while the bridge is lowered; all six feet are down again at t = 44 s and, with the
  carriage back over SB1, share the load as at t = 7 s (paper, section 2.1).
"""

import math

import numpy as np
import numpy.typing as npt

from sim_bridge.params import ModelParams

FloatArray = npt.NDArray[np.float64]

#: Length of one simulated step (the step takes 44 s; one idle second follows).
CYCLE_END_S = 45.0
#: Steps the model can simulate: the step above and the next, with the bases' roles
#: swapped; after the two, each base has been lifted once (a full walking cycle).
MAX_STEPS = 2
#: SB2's feet are pressed onto the ground (the set-down preload) over this time, s.
SET_DOWN_PRELOAD_S = (42.5, 44.0)
#: The carriage comes back over SB1 once SB2's feet are down, over this time, s.
CARRIAGE_BACK_S = (43.2, 44.7)


def ramp(t_s: npt.ArrayLike, start_s: float, end_s: float) -> FloatArray:
    """0 before ``start_s``, 1 after ``end_s``, a half cosine in between."""
    x = np.clip((np.asarray(t_s, dtype=np.float64) - start_s) / (end_s - start_s), 0.0, 1.0)
    return np.asarray(0.5 - 0.5 * np.cos(np.pi * x), dtype=np.float64)


def ramp_rate(t_s: npt.ArrayLike, start_s: float, end_s: float) -> FloatArray:
    """Time derivative of :func:`ramp`, 1/s."""
    t = np.asarray(t_s, dtype=np.float64)
    duration = end_s - start_s
    x = np.clip((t - start_s) / duration, 0.0, 1.0)
    inside = (t > start_s) & (t < end_s)
    return np.where(inside, 0.5 * np.pi / duration * np.sin(np.pi * x), 0.0).astype(np.float64)


def carriage_m(t_s: npt.ArrayLike, p: ModelParams) -> FloatArray:
    """Carriage position from SB1's axis towards SB2.

    It leaves the counterweight position only once SB2's feet touch down (~43.3 s):
    earlier, the centre of gravity would pass SB1_F1 and tip the machine over it.
    """
    return (
        p.carriage_start_m
        + (p.carriage_over_sb1_m - p.carriage_start_m) * ramp(t_s, 2.0, 7.0)
        + (p.carriage_counterweight_m - p.carriage_over_sb1_m)
        * (ramp(t_s, 7.5, 10.5) - ramp(t_s, *CARRIAGE_BACK_S))
    )


def inclination_rad(t_s: npt.ArrayLike, p: ModelParams) -> FloatArray:
    """Bridge inclination at SB1 (positive lifts SB2): lifted at 10..12 s, back at 38..44 s;
    slightly negative at the end so SB2's feet are pressed onto the ground by
    ``set_down_preload_m``. The preload comes on slowly (42.5..44 s) so that the feet touch
    down gently: a steep force kink at touchdown is what a spike filter handles worst."""
    lift = math.radians(p.lift_inclination_deg)
    preload = p.set_down_preload_m / p.bridge_length_m
    return lift * (ramp(t_s, 10.0, 12.0) - ramp(t_s, 38.0, 44.0)) - preload * ramp(
        t_s, *SET_DOWN_PRELOAD_S
    )


def inclination_rate_rad_s(t_s: npt.ArrayLike, p: ModelParams) -> FloatArray:
    lift = math.radians(p.lift_inclination_deg)
    preload = p.set_down_preload_m / p.bridge_length_m
    return lift * (ramp_rate(t_s, 10.0, 12.0) - ramp_rate(t_s, 38.0, 44.0)) - preload * ramp_rate(
        t_s, *SET_DOWN_PRELOAD_S
    )


def lifted_stroke_m(t_s: npt.ArrayLike, p: ModelParams) -> FloatArray:
    """Stroke of the lifted base's legs: retracted in the air (t = 14..18 s), extended
    again (38..43.5 s)."""
    travel = p.stroke_extended_m - p.stroke_retracted_m
    return p.stroke_extended_m - travel * (ramp(t_s, 14.0, 18.0) - ramp(t_s, 38.0, 43.5))


def lifted_stroke_rate_m_s(t_s: npt.ArrayLike, p: ModelParams) -> FloatArray:
    travel = p.stroke_extended_m - p.stroke_retracted_m
    return -travel * (ramp_rate(t_s, 14.0, 18.0) - ramp_rate(t_s, 38.0, 43.5))


def fold_command_rad(t_s: npt.ArrayLike, p: ModelParams) -> FloatArray:
    """Fold command before the PT1 element: up t = 18..22.6 s, past the stop; down 32.5..39.5 s."""
    target = math.radians(p.fold_stop_deg + p.fold_command_overshoot_deg)
    return target * (ramp(t_s, 18.0, 22.6) - ramp(t_s, 32.5, 39.5))


def rotation_rad(t_s: npt.ArrayLike) -> FloatArray:
    """Bridge direction seen from the standing base: pi (between its F2 and F3) turning to
    0 (over its F1)."""
    return np.pi * (1.0 - ramp(t_s, 23.0, 32.0))


def rotation_acceleration_rad_s2(t_s: npt.ArrayLike) -> FloatArray:
    t = np.asarray(t_s, dtype=np.float64)
    duration = 9.0
    x = np.clip((t - 23.0) / duration, 0.0, 1.0)
    inside = (t > 23.0) & (t < 32.0)
    return np.where(inside, -0.5 * np.pi * (np.pi / duration) ** 2 * np.cos(np.pi * x), 0.0)


def phase_index(t_s: npt.ArrayLike) -> npt.NDArray[np.int_]:
    """Index into sim_bridge.result.PHASES: idle, move_carriage, fold, rotate, unfold."""
    t = np.asarray(t_s, dtype=np.float64)
    return np.select(
        [t < 2.0, t < 7.0, t < 8.0, t < 23.0, t < 32.5, t < 44.0, t < CARRIAGE_BACK_S[1]],
        [0, 1, 0, 2, 3, 4, 1],
        default=0,
    )
