"""The interpreter settings the service runs with: the CLI's and the benchmark's.

Two settings of CPython are process-wide, so they are made where the service runs
(``portal-daq run``), not in the library, and the benchmark applies the same
settings around its measurements of the service only (:func:`tuned_interpreter`).

- The GIL switch interval: the reader, consumer, publisher and recorder threads hand
  frames on within about a millisecond; CPython's default 5 ms would add up to 5 ms of
  latency whenever a busy thread holds the GIL.
- The cyclic garbage collector's thresholds: every frame makes a few short-lived
  objects that reference counting frees, but with the default first threshold (700
  allocations) the collector also ran every hundred frames or so and took about a
  tenth of the service's CPU per frame (bench/, as fast as taken). Collections stay,
  a hundred times rarer; the per-frame path makes no reference cycles, so nothing
  piles up meanwhile.
"""

import gc
import sys
from collections.abc import Iterator
from contextlib import contextmanager

GIL_SWITCH_INTERVAL_S = 0.001
#: Allocations before a first-generation collection, then the usual ratios above it.
GC_THRESHOLDS = (70_000, 10, 10)


@contextmanager
def tuned_interpreter() -> Iterator[None]:
    """The service's GIL switch interval and collector thresholds meanwhile."""
    switch_s, thresholds = sys.getswitchinterval(), gc.get_threshold()
    sys.setswitchinterval(GIL_SWITCH_INTERVAL_S)
    gc.set_threshold(*GC_THRESHOLDS)
    try:
        yield
    finally:
        sys.setswitchinterval(switch_s)
        gc.set_threshold(*thresholds)
