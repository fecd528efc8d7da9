"""Foot contact detection: on the ground or in the air, with hysteresis on the force."""

import math


class ContactDetector:
    """Switches to contact at ``on_N`` and back to air at ``off_N`` (``off_N < on_N``).

    The gap keeps noise around one threshold from toggling the state.

    >>> c = ContactDetector(on_N=8000.0, off_N=4000.0)
    >>> [c.update(f) for f in (0.0, 7000.0, 9000.0, 5000.0, 3000.0)]
    [False, False, True, True, False]
    """

    def __init__(self, on_N: float, off_N: float) -> None:
        if not off_N < on_N:
            raise ValueError(f"off_N ({off_N}) must be below on_N ({on_N})")
        self.on_N = on_N
        self.off_N = off_N
        self.in_contact = False

    def reset(self) -> None:
        """Back to the initial state, in the air (e.g. after an outage)."""
        self.in_contact = False

    def update(self, force_N: float) -> bool:
        """Feed a filtered foot force; return whether the foot is on the ground."""
        if math.isnan(force_N):
            return self.in_contact
        if self.in_contact:
            self.in_contact = force_N > self.off_N
        else:
            self.in_contact = force_N >= self.on_N
        return self.in_contact
