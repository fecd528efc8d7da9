"""Running median: streaming vs brute force (property tests) and vs the batch path."""

import statistics
import tracemalloc

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from estimator import RunningMedian, running_median

finite = st.floats(min_value=-1e9, max_value=1e9, allow_nan=False)
odd_windows = st.integers(min_value=0, max_value=12).map(lambda k: 2 * k + 1)


def brute_force(values: list[float], window: int) -> list[float]:
    return [statistics.median(values[max(0, i - window + 1) : i + 1]) for i in range(len(values))]


@given(st.lists(finite, max_size=200), odd_windows)
def test_streaming_equals_brute_force(values: list[float], window: int) -> None:
    median = RunningMedian(window)
    assert [median.push(v) for v in values] == brute_force(values, window)


@given(st.lists(finite, max_size=200), odd_windows)
def test_batch_is_bit_identical_to_streaming(values: list[float], window: int) -> None:
    median = RunningMedian(window)
    streamed = np.array([median.push(v) for v in values], dtype=np.float64)
    batch = running_median(values, window)
    assert streamed.tobytes() == batch.tobytes()


@pytest.mark.parametrize("window", [1, 3, 7, 203])
def test_a_zero_median_is_positive_zero_in_both_paths(window: int) -> None:
    # Found by the property above: -0.0 == 0.0, and the sorted list and numpy's
    # selection put different ones of them in the middle.
    values = [0.0, 0.0, 1.0, 1.0, 0.0, -0.0, 0.0, -0.0, -0.0, -0.0] * 25
    median = RunningMedian(window)
    streamed = np.array([median.push(v) for v in values], dtype=np.float64)
    batch = running_median(values, window)
    zeros = streamed == 0.0
    assert zeros.any()
    assert not np.signbit(streamed[zeros]).any() and not np.signbit(batch[zeros]).any()
    assert streamed.tobytes() == batch.tobytes()


@given(st.lists(st.integers(min_value=-3, max_value=3).map(float), max_size=100), odd_windows)
def test_many_equal_values_are_removed_one_at_a_time(values: list[float], window: int) -> None:
    median = RunningMedian(window)
    assert [median.push(v) for v in values] == brute_force(values, window)
    assert len(median) == min(len(values), window)


@pytest.mark.parametrize("window", [199, 201, 203, 401])
def test_windows_around_the_sorted_list_switch_equal_brute_force(window: int) -> None:
    # Up to 201 values a plain sorted list, above a SortedList: both exact.
    rng = np.random.default_rng(window)
    values = [float(v) for v in rng.integers(-20, 20, size=3 * window)]
    median = RunningMedian(window)
    streamed = [median.push(v) for v in values]
    assert streamed == brute_force(values, window)
    assert np.array_equal(np.array(streamed), running_median(values, window))
    assert len(median) == window


def test_warm_up_uses_the_samples_so_far() -> None:
    median = RunningMedian(5)
    assert [median.push(v) for v in (10.0, 20.0, 0.0, 40.0, 50.0, 60.0)] == [
        10.0,
        15.0,
        10.0,
        15.0,
        20.0,
        40.0,
    ]


def test_a_single_impulse_is_removed_and_an_edge_kept() -> None:
    signal = np.array([1.0] * 10 + [1e6] + [1.0] * 10 + [5.0] * 10)
    filtered = running_median(signal, 5)
    assert filtered.max() == 5.0  # the impulse is gone
    # The step from 1 to 5 passes unsmoothed, delayed by (N - 1) / 2 = 2 samples.
    assert list(filtered[21:26]) == [1.0, 1.0, 5.0, 5.0, 5.0]


def test_batch_handles_more_rows_than_one_chunk() -> None:
    values = np.random.default_rng(7).normal(size=70_001)
    median = RunningMedian(9)
    streamed = np.array([median.push(float(v)) for v in values])
    assert np.array_equal(streamed, running_median(values, 9))


@pytest.mark.parametrize("window", [29, 31, 33, 35])
def test_batch_around_its_switch_to_the_streaming_path_is_bit_identical(window: int) -> None:
    values = np.random.default_rng(window).normal(size=5 * window)
    median = RunningMedian(window)
    streamed = np.array([median.push(float(v)) for v in values])
    assert streamed.tobytes() == running_median(values, window).tobytes()


def test_a_large_window_holds_no_row_per_value() -> None:
    # A (values x window) matrix of rows selected at once: 6,000 values of window 2,001
    # held 64 MB (10,001 on a recording: gigabytes); the streaming path holds one window.
    values = np.random.default_rng(3).normal(size=6_000)
    tracemalloc.start()
    try:
        filtered = running_median(values, 2_001)
        _, peak_bytes = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak_bytes < 4_000_000
    assert filtered[-1] == np.median(values[-2_001:])


def test_empty_median_is_nan() -> None:
    assert np.isnan(RunningMedian(3).value)
    assert running_median([], 3).size == 0


@pytest.mark.parametrize("window", [0, 2, -1, 4, 2.0, True])
def test_window_must_be_odd_positive_integer(window: object) -> None:
    with pytest.raises(ValueError, match="odd integer"):
        RunningMedian(window)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="odd integer"):
        running_median([1.0], window)  # type: ignore[arg-type]
