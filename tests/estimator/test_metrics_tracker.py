"""The soil-metrics tracker against a plain re-statement of its definitions."""

import math

from hypothesis import given
from hypothesis import strategies as st

from estimator.metrics import SoilMetrics, SoilMetricsTracker

LIMIT_PA, WINDOW_S, MAX_GAP_S = 200e3, 0.5, 0.03


def runs(samples: list[tuple[float, float]]) -> list[list[tuple[float, float]]]:
    """The samples cut wherever time steps back or jumps by more than the max gap."""
    cut: list[list[tuple[float, float]]] = []
    for i, sample in enumerate(samples):
        if i == 0 or not 0.0 <= sample[0] - samples[i - 1][0] <= MAX_GAP_S:
            cut.append([])
        cut[-1].append(sample)
    return cut


def reference(samples: list[tuple[float, float]]) -> SoilMetrics:
    """Peak, best window mean within a run that spans the window, time above the limit
    over forward steps only (each capped at the max gap)."""
    if not samples:
        return SoilMetrics()
    peak_Pa, peak_t_s = samples[0][1], samples[0][0]
    for t_s, p_Pa in samples:
        if p_Pa > peak_Pa:
            peak_Pa, peak_t_s = p_Pa, t_s
    above_s = sum(
        min(t1 - t0, MAX_GAP_S)
        for (t0, p0), (t1, _) in zip(samples, samples[1:], strict=False)
        if p0 > LIMIT_PA and t1 > t0
    )
    near_Pa = near_t_s = math.nan
    for run in runs(samples):
        for i, (t_s, _) in enumerate(run):
            if t_s - run[0][0] < WINDOW_S:
                continue
            window = [p for u, p in run[: i + 1] if u > t_s - WINDOW_S]
            mean_Pa = sum(window) / len(window)
            if not mean_Pa <= near_Pa:
                near_Pa, near_t_s = mean_Pa, t_s
    return SoilMetrics(peak_Pa, peak_t_s, near_Pa, near_t_s, above_s, len(samples))


# Mostly the 10 ms cycle, with gaps (0.1 s > MAX_GAP_S) and clock steps back.
steps = st.lists(
    st.tuples(
        st.sampled_from([0.01, 0.01, 0.01, 0.02, 0.1, -0.3]),
        st.floats(min_value=0.0, max_value=400e3),
    ),
    max_size=160,
)


def close(a: float, b: float, rel_tol: float = 1e-9) -> bool:
    return (math.isnan(a) and math.isnan(b)) or math.isclose(a, b, rel_tol=rel_tol, abs_tol=1e-9)


@given(steps)
def test_tracker_matches_the_definitions(increments: list[tuple[float, float]]) -> None:
    tracker = SoilMetricsTracker(LIMIT_PA, WINDOW_S, MAX_GAP_S)
    samples, t_s = [], 100.0
    for dt_s, p_Pa in increments:
        t_s += dt_s
        samples.append((t_s, p_Pa))
        returned = tracker.update(t_s, p_Pa)
        assert returned is tracker.metrics
    got, want = tracker.metrics, reference(samples)
    assert got.samples == want.samples
    for field in ("peak_pressure_Pa", "peak_t_s", "near_constant_t_s", "time_above_limit_s"):
        assert close(getattr(got, field), getattr(want, field)), field
    # The tracker's running sum and the fresh sum here may differ in the last bits.
    assert close(got.near_constant_pressure_Pa, want.near_constant_pressure_Pa, rel_tol=1e-6)


def test_add_and_update_agree_and_reset_starts_afresh() -> None:
    a, b = SoilMetricsTracker(LIMIT_PA, WINDOW_S), SoilMetricsTracker(LIMIT_PA, WINDOW_S)
    for i in range(100):
        a.add(i * 0.01, 150e3 + 1e3 * i)
        b.update(i * 0.01, 150e3 + 1e3 * i)
    assert a.metrics == b.metrics
    assert a.metrics.samples == 100 and a.metrics.peak_pressure_Pa == 249e3
    a.reset()
    assert a.metrics.samples == 0 and math.isnan(a.metrics.peak_pressure_Pa)


def steady(tracker: SoilMetricsTracker, t0_s: float, duration_s: float, p_Pa: float) -> float:
    """Feed ``p_Pa`` every 10 ms from ``t0_s`` for ``duration_s``; returns the next time."""
    count = round(duration_s / 0.01)
    for i in range(count):
        tracker.add(t0_s + 0.01 * i, p_Pa)
    return t0_s + 0.01 * count


def test_a_clock_step_back_adds_no_negative_time_and_restarts_the_window() -> None:
    tracker = SoilMetricsTracker(LIMIT_PA, 5.0, MAX_GAP_S)
    end_s = steady(tracker, 1000.0, 2.0, 250e3)  # above the limit for 2 s
    steady(tracker, end_s - 60.0, 6.0, 330e3)  # the clock steps back 60 s, 6 s more
    metrics = tracker.metrics
    # 2 s + 6 s above the limit; the step itself adds nothing (not -60 s).
    assert math.isclose(metrics.time_above_limit_s, 8.0 - 2 * 0.01, abs_tol=1e-6)
    # The 6 s after the step are one run spanning the 5 s window: its mean counts.
    assert metrics.near_constant_pressure_Pa == 330e3
    assert math.isclose(metrics.near_constant_t_s, end_s - 60.0 + 5.0, abs_tol=1e-6)


def test_after_a_gap_one_sample_is_not_a_near_constant_mean() -> None:
    tracker = SoilMetricsTracker(LIMIT_PA, 5.0, MAX_GAP_S)
    end_s = steady(tracker, 1000.0, 6.0, 120e3)
    tracker.add(end_s + 10.0, 330e3)  # one sample after a 10 s gap
    assert tracker.metrics.near_constant_pressure_Pa == 120e3
    steady(tracker, end_s + 10.01, 4.0, 330e3)  # 4 s of the new run: still under 5 s
    assert tracker.metrics.near_constant_pressure_Pa == 120e3
    assert tracker.metrics.peak_pressure_Pa == 330e3


def test_a_time_too_large_for_its_window_raises_nothing() -> None:
    """At 1e300 (a corrupted frame time) the window's start is the time itself: the
    window was emptied and read, an IndexError out of the estimator."""
    tracker = SoilMetricsTracker(LIMIT_PA, WINDOW_S, MAX_GAP_S)
    end_s = steady(tracker, 1000.0, 1.0, 250e3)
    for t_s in (1e300, math.inf, end_s):
        tracker.add(t_s, 300e3)
    assert tracker.metrics.peak_pressure_Pa == 300e3
