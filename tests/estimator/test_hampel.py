"""The causal Hampel filter: no lag, spikes removed, also on the simulated cycle."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from estimator import EstimatorSettings, foot_force_N, running_median
from estimator.filters import filter_series, make_filter
from estimator.hampel import RunningHampel
from sim_bridge.model import simulate
from sim_bridge.noise import ImpulsiveNoise
from sim_bridge.params import ModelParams

#: The live target of issue 13: 95 % of |published - true| on feet in contact within this.
LIVE_95_TARGET_N = 1800.0
#: What is left of an injected spike (2.6..10.5 kN) at its sample after the Hampel filter:
#: the filtered noisy minus the filtered clean force. Measured: 99 % within 0.52 kN, all
#: within 3.8 kN (the worst at SB2's touchdown, t = 43.3 s, where the force bends sharply
#: and a causal filter cannot tell a spike from the edge). The plain trailing-median
#: Hampel filter leaves up to 10 kN of a spike on a ramp or swing, 7 kN at 99 %.
SPIKE_LEFT_BOUND_N = 4000.0
SPIKE_LEFT_99_BOUND_N = 1000.0


def test_clean_oscillation_is_followed_closer_than_by_the_lagging_median() -> None:
    t = np.arange(0.0, 3.0, 0.01)
    force = 50e3 + 20e3 * np.exp(-t) * np.sin(2 * math.pi * 2.4 * t)  # the fold stop's swing
    filtered = filter_series(force, EstimatorSettings(filter="hampel"))
    lagging = np.abs(running_median(force, 11) - force).max()
    # Where the curvature is high the projection flags a few samples, and replaces
    # them with a prediction a little off; the median's lag costs far more.
    assert lagging > 8e3
    assert np.abs(filtered - force).max() < 0.3 * lagging
    assert np.array_equal(filtered[:7], force[:7])  # warm-up: passes unchanged


def test_spike_on_a_ramp_is_replaced_by_the_projected_median() -> None:
    ramp = [1000.0 * i for i in range(10)]
    hampel = RunningHampel(window=5, k=3.0)
    out = [hampel.push(v) for v in [*ramp[:7], 50_000.0, *ramp[8:]]]
    assert out == [*ramp[:7], 7000.0, *ramp[8:]]
    assert hampel.replaced == 1


def test_a_step_is_followed_once_the_window_holds_it() -> None:
    hampel = RunningHampel(window=5, k=3.0)
    out = [hampel.push(v) for v in [0.0] * 6 + [10.0] * 6]
    # Outliers until three of five window samples lie on the new level.
    assert out == [0.0] * 6 + [0.0, 0.0, 0.0, 10.0, 10.0, 10.0]


@given(st.lists(st.floats(min_value=-1e6, max_value=1e6), max_size=60), st.integers(3, 9))
def test_batch_equals_streaming(values: list[float], window: int) -> None:
    settings = EstimatorSettings(filter="hampel", hampel_window=window)
    streaming = make_filter(settings)
    streamed = np.array([streaming.push(v) for v in values], dtype=np.float64)
    assert streamed.tobytes() == filter_series(values, settings).tobytes()


@pytest.mark.parametrize(
    ("window", "k"), [(2, 3.0), (202, 3.0), (7, 0.0), (7, math.inf), (True, 3.0)]
)
def test_bad_parameters_are_refused(window: int, k: float) -> None:
    with pytest.raises(ValueError, match="hampel_"):
        RunningHampel(window, k)


@pytest.fixture(scope="module")
def noisy_cycle() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(raw eq. 4 force with the --noise spikes, the same without, true force); 6 columns."""
    leg = ModelParams().leg
    noisy = simulate(noise=ImpulsiveNoise())  # what `python -m sim_bridge --noise` plays
    clean = simulate()
    raw = foot_force_N(noisy.p_piston_Pa, noisy.p_rod_Pa, leg)
    raw_clean = foot_force_N(clean.p_piston_Pa, clean.p_rod_Pa, leg)
    return raw, raw_clean, noisy.force_true_N


def test_hampel_meets_the_live_target_and_removes_every_spike(
    noisy_cycle: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> None:
    raw, raw_clean, truth = noisy_cycle
    hampel = EstimatorSettings(filter="hampel")
    median = EstimatorSettings()
    spikes = np.abs(raw - raw_clean) > 100.0
    assert spikes.sum() > 300 and np.abs(raw - raw_clean).max() > 9e3
    lefts = []
    for leg in range(6):
        contact = truth[:, leg] > 0
        live = filter_series(raw[:, leg], hampel)
        live_clean = filter_series(raw_clean[:, leg], hampel)
        lagging = filter_series(raw[:, leg], median)
        live95 = np.quantile(np.abs(live - truth[:, leg])[contact], 0.95)
        assert live95 < LIVE_95_TARGET_N, (leg, live95)
        # The first window of samples passes unchanged (warm-up): spikes there stay.
        judged = spikes[:, leg] & (np.arange(len(live)) >= hampel.hampel_window)
        left = np.abs(live - live_clean)[judged]
        assert left.max() < SPIKE_LEFT_BOUND_N, (leg, left.max())
        lefts.append(left)
        if leg == 0:
            # The running median as published misses the target on the most loaded leg.
            assert np.quantile(np.abs(lagging - truth[:, 0])[contact], 0.95) > 3e3
    assert np.quantile(np.concatenate(lefts), 0.99) < SPIKE_LEFT_99_BOUND_N
