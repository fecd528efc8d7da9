"""The paper's equations (3), (4) and (5), for scalars and numpy arrays alike.

The same arithmetic, in the same order, serves the streaming and the batch
path, so both give bit-identical forces on the same input.
"""

from typing import TypeVar

import numpy as np
import numpy.typing as npt

from estimator.geometry import LegGeometry

#: A float or an array of float64 values; the result has the same kind.
Value = TypeVar("Value", float, npt.NDArray[np.float64])


def cylinder_force_N(p_piston_Pa: Value, p_rod_Pa: Value, leg: LegGeometry) -> Value:
    """Eq. (3): F_cyl = p_piston A_piston - p_rod A_rod (positive = pushing)."""
    return p_piston_Pa * leg.A_piston_m2 - p_rod_Pa * leg.A_rod_m2


def foot_force_N(p_piston_Pa: Value, p_rod_Pa: Value, leg: LegGeometry) -> Value:
    """Eq. (4): the vertical ground force of the foot from the chamber pressures.

    F_zFoot = k F_cyl (l_r sin a - l_z cos a) / l_b + (l_gb / l_b) F_gLeg + b

    with the leg's calibrated gain ``k`` (``force_gain``, 1 by default) and offset ``b``
    (``force_offset_N``, 0 by default).
    """
    return (
        cylinder_force_N(p_piston_Pa, p_rod_Pa, leg) * leg.calibrated_ratio + leg.calibrated_term_N
    )


def contact_pressure_Pa(force_N: Value, A_foot_m2: float) -> Value:
    """Eq. (5): the soil contact pressure under a foot, p_ground = F_zFoot / A_foot."""
    return force_N / A_foot_m2
