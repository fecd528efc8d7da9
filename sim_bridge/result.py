"""The output of one simulated movement cycle: every DBC signal plus the ground truth."""

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from dbc.machine import SIMULATED_LEGS
from dbc.machine_signals import PHASES as PHASES  # the movement phases, as the DBC numbers them

FloatArray = npt.NDArray[np.float64]

#: Leg order of every per-leg column (defined beside the config key ``simulated_leg``
#: that names them).
LEGS = SIMULATED_LEGS
#: Base order of the per-base columns.
BASES = ("SB1", "SB2")


def leg_column(leg: str, columns: Mapping[str, int] | None = None) -> int:
    """The column of ``leg`` in per-leg arrays: ``columns[leg]`` for a config leg
    (:attr:`sim_bridge.leg_map.LegMap.columns`), else the simulated leg of that name."""
    return columns[leg] if columns is not None else LEGS.index(leg)


@dataclass(frozen=True)
class SimulationResult:
    """Time series of one cycle, sampled every ``t_s[1] - t_s[0]`` seconds.

    Row ``i`` of every array belongs to ``t_s[i]`` (seconds since the cycle started).
    Per-leg arrays have one column per entry of :data:`LEGS`, per-base arrays one per
    entry of :data:`BASES`.
    """

    t_s: FloatArray
    #: Leg cylinder piston / rod chamber pressure, shape (n, 6).
    p_piston_Pa: FloatArray
    p_rod_Pa: FloatArray
    #: True vertical ground force of each foot (the model's contact force), shape (n, 6).
    force_true_N: FloatArray
    #: Compression of the ground spring under each foot, shape (n, 6).
    ground_compression_m: FloatArray
    #: Foot sliding horizontally (stick-slip friction exceeded), shape (n, 6).
    slipping: npt.NDArray[np.bool_]
    #: Inclination cylinder piston / rod chamber pressure per base, shape (n, 2).
    incl_p_piston_Pa: FloatArray
    incl_p_rod_Pa: FloatArray
    #: Leg cylinder strokes, shape (n, 6).
    stroke_m: FloatArray
    #: Bridge inclination at each base, shape (n, 2).
    inclination_deg: FloatArray
    #: Bridge fold angle (0 = unfolded), shape (n,).
    fold_deg: FloatArray
    #: Bridge rotation about the standing base's axis, 0..360, shape (n,).
    rotation_deg: FloatArray
    #: Carriage position along the bridge (0 = bridge middle, + towards SB1), shape (n,).
    carriage_m: FloatArray
    #: Movement phase index into :data:`PHASES`, shape (n,).
    phase: npt.NDArray[np.int_]

    @property
    def dt_s(self) -> float:
        return float(self.t_s[1] - self.t_s[0])

    def __len__(self) -> int:
        return int(self.t_s.size)
