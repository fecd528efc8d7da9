"""The soil-metrics tracker against a plain re-statement of its definitions."""

import math

from hypothesis import given
from hypothesis import strategies as st

from estimator.metrics import SoilMetrics, SoilMetricsTracker

LIMIT_PA, WINDOW_S, MAX_GAP_S = 200e3, 0.5, 0.03


def reference(samples: list[tuple[float, float]]) -> SoilMetrics:
    """Peak, best window mean (once a window is covered), capped time above the limit."""
    if not samples:
        return SoilMetrics()
    peak_Pa, peak_t_s = samples[0][1], samples[0][0]
    for t_s, p_Pa in samples:
        if p_Pa > peak_Pa:
            peak_Pa, peak_t_s = p_Pa, t_s
    above_s = sum(
        min(t1 - t0, MAX_GAP_S)
        for (t0, p0), (t1, _) in zip(samples, samples[1:], strict=False)
        if p0 > LIMIT_PA
    )
    near_Pa = near_t_s = math.nan
    first_t_s = samples[0][0]
    for i, (t_s, _) in enumerate(samples):
        if t_s - first_t_s < WINDOW_S:
            continue
        window = [p for u, p in samples[: i + 1] if u > t_s - WINDOW_S]
        mean_Pa = sum(window) / len(window)
        if not mean_Pa <= near_Pa:
            near_Pa, near_t_s = mean_Pa, t_s
    return SoilMetrics(peak_Pa, peak_t_s, near_Pa, near_t_s, above_s, len(samples))


steps = st.lists(
    st.tuples(st.sampled_from([0.01, 0.01, 0.02, 0.1]), st.floats(min_value=0.0, max_value=400e3)),
    max_size=120,
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
