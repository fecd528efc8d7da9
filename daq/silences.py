"""When legs had no estimate for longer than their stale time: pure, for the report's
header and replay's summary line.

A transducer that falls silent (a loose connector, a reboot) makes no frame, so no
invalid estimate and no bad frame either: only the estimates' times tell it.

>>> import numpy as np
>>> leg_silences({"F1": np.array([0.0, 0.01, 0.5, 0.51])}, ["F1", "F2"], 0.0, 0.51,
...              {"F1": 0.03, "F2": 0.03})
{'F1': (1, 0.49), 'F2': (1, 0.51)}
"""

from collections.abc import Iterable, Mapping

import numpy as np
import numpy.typing as npt

from dbc.machine import MachineConfig


def leg_silences(
    times: Mapping[str, npt.NDArray[np.float64]],
    legs: Iterable[str],
    start_s: float,
    end_s: float,
    gaps_s: Mapping[str, float],
) -> dict[str, tuple[int, float]]:
    """Per leg of ``legs`` and ``times`` (its estimates' frame times, in order): how many
    times, and for how many seconds in all, it had no estimate for longer than
    ``gaps_s[leg]`` between ``start_s`` and ``end_s`` (the recording's first and last
    frame: not yet or no more heard counts; a leg never heard: once, the whole span).
    Only legs that had one. A forward step of the clock shows as one too: it cannot be
    told from a silence of the bus."""
    found: dict[str, tuple[int, float]] = {}
    for leg in dict.fromkeys([*legs, *times]):
        t_s = times.get(leg)
        if t_s is None or t_s.size == 0:
            found[leg] = (1, round(max(0.0, end_s - start_s), 9))
            continue
        steps = np.diff(np.concatenate(([start_s], t_s, [end_s])))
        silent = steps[steps > gaps_s.get(leg, np.inf)]
        if silent.size:
            found[leg] = (int(silent.size), round(float(silent.sum()), 9))
    return found


def stale_times_s(machine: MachineConfig) -> dict[str, float]:
    """Per leg of ``machine``: its stale time (``stale_after_cycles`` of its cycle time)."""
    settings = machine.estimator
    return {
        leg: settings.stale_after_s(config.cycle_time_s) for leg, config in machine.legs.items()
    }
