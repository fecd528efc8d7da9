"""The service's interpreter settings hold inside the context and are undone after it
(the benchmark measures the baseline in the same process with Python's own)."""

import gc
import sys

from daq.interpreter import GC_THRESHOLDS, GIL_SWITCH_INTERVAL_S, tuned_interpreter


def test_settings_hold_inside_and_are_undone_after() -> None:
    switch_s, thresholds = sys.getswitchinterval(), gc.get_threshold()
    assert thresholds != GC_THRESHOLDS
    with tuned_interpreter():
        assert sys.getswitchinterval() == GIL_SWITCH_INTERVAL_S == 0.001
        assert gc.get_threshold() == GC_THRESHOLDS
        assert gc.isenabled()  # rarer, not off: cycles are still collected
    assert (sys.getswitchinterval(), gc.get_threshold()) == (switch_s, thresholds)
