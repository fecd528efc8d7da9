"""One time line for a report from frame times that step back: pure.

Frame times follow the machine's wall clock, which may step: NTP correcting a clock that
ran ahead steps it back, and a machine without a real-time clock starts in 1970 (or at the
time it last saved) until NTP sets it. A report sorts everything by time: times that step
back would overlap those before them and interleave two stretches of the run (the cycles
of one movement cut into hundreds, peaks and times above the limit taken from the wrong
samples); a clock set from 1970 makes one cycle last 56 years.

:class:`Timeline` takes one stream's frame times in the order they were processed and
joins the stretches: the first time after a step back, or after the clock was set (from
before :data:`DATED_FROM_S` to after it), follows the last time before it by the stream's
last step forward (its period, for a periodic sender: each stream joins alike); the
report then moves the whole line back by the final :attr:`Timeline.offset_s`, so that the
last stretch keeps its own (corrected) wall-clock times. A forward step within dated time
is kept: a gap and an NTP step forward cannot be told apart. Frame times that never step
back are unchanged, bit for bit; so are times back by at most :data:`OUT_OF_ORDER_S`:
frames out of order (two buses merged into one log, a logger's buffers, an adapter's
time stamps), not a clock step; joined, each made a step (a 45 s log of frames out of
order by 2 ms was reported as 20,355 clock steps and 133 s).
"""

import math

from daq.frames import DATED_FROM_S

#: Frame times at most this much before the latest are frames out of order, not a clock
#: stepping back: NTP (ntpd, chrony's default) slews an offset below 128 ms, never steps it.
OUT_OF_ORDER_S = 0.125


class Timeline:
    """Maps one stream's frame times, in processing order, onto a time line that never
    runs back (see the module docstring).

    >>> line = Timeline()
    >>> [line.advance(t) for t in (100.0, 101.0, 96.0, 97.0, 96.9)]
    [100.0, 101.0, 102.0, 103.0, 102.9]
    >>> line.steps, line.offset_s
    (1, 6.0)
    """

    def __init__(self) -> None:
        #: What is added to the frame times of the current stretch.
        self.offset_s = 0.0
        #: Steps back (and clock settings) joined so far.
        self.steps = 0
        self._last_s = math.nan
        self._step_s = 0.0

    def advance(self, t_s: float) -> float:
        """The time line's time of ``t_s``, the stream's next frame time."""
        last_s = self._last_s
        if t_s < last_s - OUT_OF_ORDER_S or (last_s < DATED_FROM_S <= t_s):  # not with NaN
            # joined by the stream's last step forward: its period, for a periodic sender
            self.offset_s += last_s - t_s + self._step_s
            self.steps += 1
        elif t_s > last_s:
            self._step_s = t_s - last_s
        elif t_s < last_s:  # out of order: the latest time stays the latest
            return t_s + self.offset_s
        if t_s == t_s:
            self._last_s = t_s
        return t_s + self.offset_s

    def at(self, t_s: float) -> float:
        """The time line's time of ``t_s`` in the current stretch (without advancing)."""
        return t_s + self.offset_s
