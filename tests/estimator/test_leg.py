"""The streaming leg estimator: validity, filtering, contact, staleness, batch identity."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from estimator import (
    EstimatorSettings,
    LegEstimator,
    LegGeometry,
    LegSample,
    estimate_leg_series,
    foot_force_N,
    running_median,
)
from tests.estimator.test_equations import DEFAULT

LEG = LegGeometry(**DEFAULT)
CYCLE_S = 0.01


def estimator(**overrides: object) -> LegEstimator:
    return LegEstimator("SB1_F1", LEG, EstimatorSettings(**overrides), CYCLE_S)  # type: ignore[arg-type]


def pressures_for(force_N: float, p_rod_Pa: float = 1e6) -> float:
    """Piston pressure that makes eq. (4) give ``force_N`` with the given rod pressure."""
    F_cyl = (force_N - LEG.weight_term_N) / LEG.force_ratio
    return (F_cyl + p_rod_Pa * LEG.A_rod_m2) / LEG.A_piston_m2


def test_valid_sample_gives_eq4_eq5_and_contact() -> None:
    est = estimator(median_window=1)
    pp = pressures_for(61_050.0)
    e = est.update(LegSample(t_s=10.0, p_piston_Pa=pp, p_rod_Pa=1e6))
    assert e.valid and e.reasons == ()
    assert e.force_raw_N == e.force_N == foot_force_N(pp, 1e6, LEG)
    assert e.force_N == pytest.approx(61_050.0)
    assert e.pressure_Pa == pytest.approx(185_000.0)
    assert e.contact is True
    assert (e.leg, e.t_s, e.p_piston_Pa, e.p_rod_Pa) == ("SB1_F1", 10.0, pp, 1e6)


@pytest.mark.parametrize(
    ("sample_kw", "reasons"),
    [
        ({"faults": ("crc",)}, ("crc",)),
        ({"faults": ("counter",)}, ("counter",)),
        ({"faults": ("rod_stale",)}, ("rod_stale",)),
        ({"faults": ("status_sensor_fault",)}, ("status_sensor_fault",)),
        ({"p_piston_Pa": 41e6}, ("range",)),
        ({"p_rod_Pa": -2e5}, ("range",)),
        ({"p_rod_Pa": math.nan}, ("range",)),
        (
            {"faults": ("crc", "status_under_range"), "p_rod_Pa": 50e6},
            ("crc", "status_under_range", "range"),
        ),
    ],
)
def test_each_fault_makes_the_sample_invalid_with_its_reason(
    sample_kw: dict[str, object], reasons: tuple[str, ...]
) -> None:
    est = estimator()
    kw: dict[str, object] = {"t_s": 1.0, "p_piston_Pa": 5e6, "p_rod_Pa": 1e6, **sample_kw}
    e = est.update(LegSample(**kw))  # type: ignore[arg-type]
    assert e.valid is False
    assert e.reasons == reasons


def test_invalid_samples_do_not_enter_the_median() -> None:
    est = estimator(median_window=3)
    good = pressures_for(50_000.0)
    for i in range(3):
        est.update(LegSample(t_s=i * CYCLE_S, p_piston_Pa=good, p_rod_Pa=1e6))
    # Two huge but invalid samples would carry a window of 3 if they entered it (a
    # third would come past the stale time, an outage that restarts the median).
    for i in range(3, 5):
        e = est.update(LegSample(t_s=i * CYCLE_S, p_piston_Pa=30e6, p_rod_Pa=1e6, faults=("crc",)))
        assert e.force_N == pytest.approx(50_000.0)
        assert e.force_raw_N > 150_000.0
    assert est.metrics.samples == 3
    assert est.metrics.peak_pressure_Pa == pytest.approx(50_000.0 / 0.33)


def test_estimate_turns_stale_after_three_cycle_times() -> None:
    est = estimator()
    before = est.snapshot(0.0)
    assert before.valid is False and before.reasons == ("stale",)
    est.update(LegSample(t_s=100.0, p_piston_Pa=5e6, p_rod_Pa=1e6))
    assert est.snapshot(2.9 * CYCLE_S).valid is True
    stale = est.snapshot(3.1 * CYCLE_S)
    assert stale.valid is False and stale.reasons == ("stale",)
    assert stale.force_N == est.snapshot(0.0).force_N
    est.update(LegSample(t_s=100.05, p_piston_Pa=5e6, p_rod_Pa=1e6))
    assert est.snapshot(0.01).valid is True


def test_contact_has_hysteresis_on_the_filtered_force() -> None:
    est = estimator(median_window=1, contact_on_N=8000.0, contact_off_N=4000.0)
    states = []
    for i, force in enumerate((3000.0, 7000.0, 8500.0, 5000.0, 4100.0, 3900.0, 7900.0)):
        states.append(
            est.update(
                LegSample(t_s=i * CYCLE_S, p_piston_Pa=pressures_for(force), p_rod_Pa=1e6)
            ).contact
        )
    assert states == [False, False, True, True, True, False, False]


def test_soil_metrics_peak_near_constant_and_time_above_limit() -> None:
    est = estimator(median_window=1, pressure_limit_Pa=200e3, near_constant_window_s=5.0)
    dt = 0.01
    t = np.arange(0.0, 20.0, dt)
    # 150 kPa for 8 s, 230 kPa for 6 s, then 100 kPa; one 300 kPa sample at t = 3 s.
    pressure = np.where(t < 8.0, 150e3, np.where(t < 14.0, 230e3, 100e3))
    pressure[300] = 300e3
    for ti, p in zip(t, pressure, strict=True):
        est.update(LegSample(t_s=float(ti), p_piston_Pa=pressures_for(p * 0.33), p_rod_Pa=1e6))
    m = est.metrics
    assert m.peak_pressure_Pa == pytest.approx(300e3)
    assert m.peak_t_s == pytest.approx(3.0)
    assert m.near_constant_pressure_Pa == pytest.approx(230e3)
    # The first window holding only plateau samples: (7.99, 12.99].
    assert m.near_constant_t_s == pytest.approx(12.99)
    # Above 200 kPa: the 6 s plateau plus the single 10 ms sample.
    assert m.time_above_limit_s == pytest.approx(6.0 + dt, abs=1.5 * dt)
    assert m.samples == t.size


def test_near_constant_mean_matches_brute_force_on_noise() -> None:
    est = estimator(median_window=1, near_constant_window_s=1.0)
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.005, 0.02, size=800))
    p = rng.uniform(50e3, 250e3, size=t.size)
    for ti, pi in zip(t, p, strict=True):
        est.update(LegSample(t_s=float(ti), p_piston_Pa=pressures_for(pi * 0.33), p_rod_Pa=1e6))
    filtered = np.array([foot_force_N(pressures_for(x * 0.33), 1e6, LEG) / 0.33 for x in p])
    means = [filtered[(t > ti - 1.0) & (t <= ti)].mean() for ti in t if ti - t[0] >= 1.0]
    assert est.metrics.near_constant_pressure_Pa == pytest.approx(max(means), rel=1e-9)


def test_outage_is_not_counted_as_time_above_limit() -> None:
    est = estimator(median_window=1, pressure_limit_Pa=100e3)
    high = pressures_for(200e3 * 0.33)
    est.update(LegSample(t_s=0.0, p_piston_Pa=high, p_rod_Pa=1e6))
    est.update(LegSample(t_s=10.0, p_piston_Pa=high, p_rod_Pa=1e6))
    assert est.metrics.time_above_limit_s == pytest.approx(3 * CYCLE_S)


def test_after_an_outage_the_median_and_contact_restart() -> None:
    est = estimator(pressure_limit_Pa=100e3)
    down, lifted = pressures_for(45_900.0), pressures_for(200.0)
    for i in range(100):  # 1 s on the ground
        est.update(LegSample(t_s=100.0 + i * CYCLE_S, p_piston_Pa=down, p_rod_Pa=1e6))
    peak_Pa = est.metrics.peak_pressure_Pa
    # 30 s without a frame; meanwhile the foot was lifted. A CRC error comes first.
    bad = est.update(LegSample(t_s=131.0, p_piston_Pa=down, p_rod_Pa=1e6, faults=("crc",)))
    assert math.isnan(bad.force_N) and bad.contact is False
    after = [
        est.update(LegSample(t_s=131.0 + i * CYCLE_S, p_piston_Pa=lifted, p_rod_Pa=1e6))
        for i in range(1, 7)
    ]
    assert all(e.valid and e.contact is False for e in after)
    assert [e.force_N for e in after] == pytest.approx([200.0] * 6)
    assert est.metrics.peak_pressure_Pa == peak_Pa  # the old force fed no metrics
    assert est.metrics.samples == 106


def test_a_clock_step_back_does_not_restart_the_median() -> None:
    est = estimator(median_window=5)
    forces = [40_000.0, 41_000.0, 42_000.0, 43_000.0, 44_000.0]
    for i, force in enumerate(forces):
        est.update(
            LegSample(t_s=100.0 + i * CYCLE_S, p_piston_Pa=pressures_for(force), p_rod_Pa=1e6)
        )
    stepped = est.update(LegSample(t_s=95.0, p_piston_Pa=pressures_for(90_000.0), p_rod_Pa=1e6))
    assert stepped.force_N == pytest.approx(43_000.0)  # median of the last five
    assert stepped.contact is True


@settings(max_examples=60, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.floats(min_value=-3e5, max_value=4.2e7),
            st.floats(min_value=0.0, max_value=3e7),
            st.booleans(),
        ),
        max_size=120,
    ),
    st.integers(min_value=0, max_value=5).map(lambda k: 2 * k + 1),
    st.sampled_from(["median", "hampel"]),
    # Mostly the cycle time; outages (> 3 cycles) and clock steps back in between.
    st.lists(st.sampled_from([CYCLE_S] * 4 + [0.05, 1.0, -2.0]), min_size=120, max_size=120),
)
def test_batch_path_is_bit_identical_to_streaming(
    rows: list[tuple[float, float, bool]], window: int, filter_name: str, steps_s: list[float]
) -> None:
    cfg = EstimatorSettings(filter=filter_name, median_window=window, hampel_window=max(window, 3))
    est = LegEstimator("SB1_F1", LEG, cfg, CYCLE_S)
    t = np.cumsum(steps_s[: len(rows)]).tolist()
    streamed = [
        est.update(LegSample(t_s=ti, p_piston_Pa=pp, p_rod_Pa=pr, faults=() if ok else ("crc",)))
        for ti, (pp, pr, ok) in zip(t, rows, strict=True)
    ]
    series = estimate_leg_series(
        t,
        [r[0] for r in rows],
        [r[1] for r in rows],
        LEG,
        cfg,
        checks_ok=[r[2] for r in rows],
        cycle_time_s=CYCLE_S,
    )
    assert series.valid.tolist() == [e.valid for e in streamed]
    assert series.force_raw_N.tobytes() == np.array([e.force_raw_N for e in streamed]).tobytes()
    assert series.force_N.tobytes() == np.array([e.force_N for e in streamed]).tobytes()
    assert series.pressure_Pa.tobytes() == np.array([e.pressure_Pa for e in streamed]).tobytes()


def test_batch_filter_runs_over_valid_samples_only() -> None:
    cfg = EstimatorSettings(median_window=3)
    pp = [5e6, 6e6, 41e6, 7e6, 8e6]  # the third is out of range
    t = [i * CYCLE_S for i in range(5)]
    series = estimate_leg_series(t, pp, [1e6] * 5, LEG, cfg, cycle_time_s=CYCLE_S)
    raw_valid = foot_force_N(np.array([5e6, 6e6, 7e6, 8e6]), 1e6, LEG)
    expected = running_median(raw_valid, 3)
    assert series.valid.tolist() == [True, True, False, True, True]
    assert series.force_N.tolist() == [
        expected[0],
        expected[1],
        expected[1],
        expected[2],
        expected[3],
    ]


def test_batch_rejects_mismatched_shapes() -> None:
    with pytest.raises(ValueError, match="one shape"):
        estimate_leg_series(
            [0.0, 1.0], [1e6], [1e6, 1e6], LEG, EstimatorSettings(), cycle_time_s=CYCLE_S
        )
