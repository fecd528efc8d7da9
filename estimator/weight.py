"""Weight check: the feet in contact must carry the machine's weight (a sensor-health signal)."""

from collections.abc import Iterable
from dataclasses import dataclass

from estimator.leg import LegEstimate


@dataclass(frozen=True, slots=True)
class WeightCheck:
    """Sum of the foot forces against the machine's weight."""

    #: Sum of the filtered forces of the valid legs in contact.
    total_force_N: float
    #: The machine's weight force (mass times g).
    weight_N: float
    #: total_force_N - weight_N; near zero when the sensors and geometry are right.
    residual_N: float
    #: Valid legs that are on the ground.
    legs_in_contact: int
    #: True when every leg is valid; only then does the residual judge the sensors.
    complete: bool


def weight_check(estimates: Iterable[LegEstimate], weight_N: float) -> WeightCheck:
    """Compare the force carried by the legs in contact with the machine's weight."""
    total_N = 0.0
    in_contact = 0
    complete = True
    for estimate in estimates:
        if not estimate.valid:
            complete = False
        elif estimate.contact:
            total_N += estimate.force_N
            in_contact += 1
    return WeightCheck(
        total_force_N=total_N,
        weight_N=weight_N,
        residual_N=total_N - weight_N,
        legs_in_contact=in_contact,
        complete=complete,
    )
