"""The last minute of every leg's contact pressure, for the dashboard's plot. Pure.

Points are keyed by the service's snapshot time ``t`` (Unix seconds, the
service's clock) of each ``<prefix>/ground``; an invalid leg is a gap
(``None``). A point not newer than the last is dropped (a repeat, or the late
joiner's cached value); a jump back in time by more than :data:`CLOCK_JUMP_S`
(the service restarted with a clock set back) starts a new history and a new
:attr:`PressureHistory.generation`, so that clients holding the old one reload.
"""

from collections import deque
from collections.abc import Sequence

from daq.live.state import GroundReading

#: The plot's time span.
WINDOW_S = 60.0
#: A snapshot this much older than the last point means the service's clock went back.
CLOCK_JUMP_S = 5.0

Point = tuple[float, tuple[float | None, ...]]


class PressureHistory:
    """``(t_s, pressures_Pa)`` of the last ``window_s``; pressures in the order of ``legs``.

    >>> from daq.live.state import parse_ground
    >>> history = PressureHistory(["A"])
    >>> history.add(parse_ground({"t": 10.0, "legs": {"A": {"pressure_Pa": 1e5, "valid": True}}}))
    True
    >>> history.since(None)
    [(10.0, (100000.0,))]
    """

    def __init__(self, legs: Sequence[str], window_s: float = WINDOW_S) -> None:
        self.legs = tuple(legs)
        self.window_s = window_s
        self._points: deque[Point] = deque()
        #: Incremented whenever the history restarts (see the module docstring).
        self.generation = 0

    def with_legs(self, legs: Sequence[str]) -> "PressureHistory":
        """This history, or an empty one of the next generation when ``legs`` are others
        (a machine of the fleet restarted with another config): the fleet page plotted
        the first legs it saw for ever, the new ones never.

        >>> history = PressureHistory(["A"])
        >>> history.with_legs(["A"]) is history
        True
        >>> renewed = history.with_legs(["B", "C"])
        >>> renewed.legs, renewed.generation
        (('B', 'C'), 1)
        """
        if tuple(legs) == self.legs:
            return self
        renewed = PressureHistory(legs, self.window_s)
        renewed.generation = self.generation + 1
        return renewed

    def __len__(self) -> int:
        return len(self._points)

    def add(self, ground: GroundReading) -> bool:
        """Append the snapshot's pressures; False if it was not newer than the last point."""
        t_s = ground.t_s
        if t_s is None:
            return False
        if self._points:
            last_s = self._points[-1][0]
            if t_s < last_s - CLOCK_JUMP_S:
                self._points.clear()
                self.generation += 1
            elif t_s <= last_s:
                return False
        pressures = []
        for leg in self.legs:
            reading = ground.legs.get(leg)
            valid = reading is not None and reading.valid
            pressures.append(reading.pressure_Pa if valid and reading else None)
        self._points.append((t_s, tuple(pressures)))
        while self._points and self._points[0][0] < t_s - self.window_s:
            self._points.popleft()
        return True

    def since(self, t_s: float | None) -> list[Point]:
        """The points after ``t_s`` (all for None), oldest first."""
        if t_s is None:
            return list(self._points)
        newer: list[Point] = []
        for point in reversed(self._points):
            if point[0] <= t_s:
                break
            newer.append(point)
        return newer[::-1]
