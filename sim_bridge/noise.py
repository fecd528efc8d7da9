"""Seeded impulsive noise: the numerical artefacts of a loosely tolerated co-simulation.

The paper's co-simulation at a relative tolerance of 1e-3 shows impulsive jumps in the
ground force (Figure 4) that a running median removes. This model is integrated by an
adaptive solver whose error control does not produce such jumps at any tolerance (a
looser tolerance only makes it less accurate, smoothly), so the artefacts are added
here, explicitly and reproducibly, to exercise the filter.
"""

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class ImpulsiveNoise:
    """Isolated spikes of random sign on a pressure signal."""

    #: Mean number of spikes per second and signal (Poisson).
    rate_per_s: float = 2.0
    #: Largest spike height; heights are uniform in [amplitude/4, amplitude].
    amplitude_Pa: float = 2.0e6
    seed: int = 0

    def __post_init__(self) -> None:
        if self.rate_per_s < 0 or self.amplitude_Pa < 0:
            raise ValueError("rate_per_s and amplitude_Pa must be >= 0")

    def apply(self, values: FloatArray, t_s: FloatArray) -> FloatArray:
        """A copy of ``values`` (samples x signals) with spikes added, one sample wide."""
        rng = np.random.default_rng(self.seed)
        dt_s = float(t_s[1] - t_s[0]) if t_s.size > 1 else 1.0
        hit = rng.random(values.shape) < self.rate_per_s * dt_s
        heights = rng.uniform(self.amplitude_Pa / 4, self.amplitude_Pa, values.shape)
        signs = rng.choice([-1.0, 1.0], values.shape)
        noisy: FloatArray = values + np.where(hit, heights * signs, 0.0)
        return noisy
