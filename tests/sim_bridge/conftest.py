"""Fixtures of the bridge tests (the helpers are in :mod:`tests.sim_bridge.synthetic`)."""

import pytest

from sim_bridge.result import SimulationResult
from tests.sim_bridge.synthetic import make_result


@pytest.fixture()
def result() -> SimulationResult:
    """A 2 s synthetic cycle sampled every 10 ms."""
    return make_result()
