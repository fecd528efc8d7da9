"""Shared pytest configuration for portal-daq's tests.

Tests marked ``vcan`` (the marker is declared in pyproject.toml) need a real
SocketCAN ``vcan0``; they are skipped where there is none. ``tests/vcan/with-vcan``
runs pytest inside User-Mode Linux with ``vcan0`` up, and ``./dev test`` uses it.
"""

import logging
import os
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import settings

# Hypothesis's per-example deadline (200 ms) is a timed assert: on a shared, loaded machine
# it fails correct code. Speed is measured in bench/, never in tests.
# The default profile draws the same examples every run (derandomize): a test run, and CI
# above all, passes or fails on the code, not on the draw. HYPOTHESIS_PROFILE=explore draws
# fresh examples, ten times as many, to look for what the fixed draw does not reach.
settings.register_profile("portal-daq", deadline=None, derandomize=True)
settings.register_profile("explore", deadline=None, max_examples=1000)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "portal-daq"))

# --- vcan: skip the real-SocketCAN tests where vcan0 is missing ---------------
# (If another pytest_collection_modifyitems is ever needed in this file, merge
# it with this one: a second definition would silently replace the first.)

VCAN0 = Path("/sys/class/net/vcan0")
VCAN_SKIP_REASON = (
    "needs a real SocketCAN vcan0: run through tests/vcan/with-vcan (./dev test does)"
)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if VCAN0.exists():
        return
    skip_vcan = pytest.mark.skip(reason=VCAN_SKIP_REASON)
    for item in items:
        if item.get_closest_marker("vcan") is not None:
            item.add_marker(skip_vcan)


# --- end vcan -----------------------------------------------------------------


@pytest.fixture(autouse=True)
def _root_logging_restored() -> Iterator[None]:
    """The root logger as it was before each test: a CLI run in-process configures logging
    (``logging.basicConfig``) onto the test's captured stderr, which closes after the test;
    a later test's log line then went to a closed file and its own output had
    ``ValueError: I/O operation on closed file`` in it (seen in one test order only)."""
    root = logging.getLogger()
    handlers, level = root.handlers[:], root.level
    yield
    for handler in root.handlers:
        if handler not in handlers:
            root.removeHandler(handler)
            handler.close()
    root.setLevel(level)
