"""The report's pure computations: cycle split, per-cycle metrics, matching, deviation stats.

Hand-made inputs with values chosen so that a plausible wrong implementation (a
signed instead of an absolute quantile, a sample-count instead of a time window,
invalid samples let in, the wrong truth sample picked) gives a different number.
"""

import json
import math
import tomllib
import tracemalloc

import numpy as np
import pytest

from daq.report.content import analyse, with_gaps
from daq.report.cycles import Cycle, cycle_metrics, phase_spans, split_cycles
from daq.report.deviation import (
    DeviationStats,
    LegComparison,
    compare,
    compare_leg,
    deviation_stats,
    match_nearest,
    most_loaded,
    sample_period_s,
)
from daq.report.figures import leg_styles
from daq.report.tracks import LegTrack, RecordingCollector, StateSignals, StateTrack, TruthTrack

NAN = math.nan


def state(rows: list[tuple[float, int, float, str]]) -> StateTrack:
    t, count, time_in_cycle, phase = zip(*rows, strict=True)
    return StateTrack(
        np.array(t, dtype=np.float64),
        np.array(count, dtype=np.int64),
        np.array(time_in_cycle, dtype=np.float64),
        tuple(phase),
    )


def track(
    t_s: list[float], pressure_kPa: list[float], valid: list[bool] | None = None, leg: str = "L"
) -> LegTrack:
    pressure = np.array(pressure_kPa, dtype=np.float64) * 1e3
    return LegTrack(
        leg=leg,
        t_s=np.array(t_s, dtype=np.float64),
        force_N=pressure * 0.33,
        pressure_Pa=pressure,
        valid=np.array(valid if valid is not None else [True] * len(t_s), dtype=np.bool_),
        force_raw_N=pressure * 0.33,
        contact=pressure > 0,
        heard=np.ones(len(t_s), dtype=np.bool_),
    )


# --- cycle split ---------------------------------------------------------------------


def test_without_machine_state_the_recording_is_one_cycle() -> None:
    empty = state([(0.0, 0, 0.0, "")])
    empty = StateTrack(empty.t_s[:0], empty.cycle_count[:0], empty.cycle_time_s[:0], ())
    (cycle,) = split_cycles(empty, 100.0, 145.5)
    assert (cycle.count, cycle.start_s, cycle.end_s, cycle.final) == (None, 100.0, 145.5, True)
    assert cycle.label == "whole recording"


def test_cycles_begin_where_the_cycle_time_says_they_began() -> None:
    rows = [
        (100.25, 7, 30.25, "rotate"),  # recording starts mid-cycle 7
        (100.35, 7, 30.35, "rotate"),
        (115.05, 8, 0.03, "idle"),  # cycle 8 began at 115.02
        (115.15, 8, 0.13, "idle"),
        (160.04, 9, 0.04, "idle"),  # cycle 9 began at 160.00
    ]
    cycles = split_cycles(state(rows), 100.2, 161.0)
    assert [(c.count, c.start_s, c.end_s, c.final) for c in cycles] == [
        (7, 100.2, pytest.approx(115.02), False),
        (8, pytest.approx(115.02), pytest.approx(160.0), False),
        (9, pytest.approx(160.0), 161.0, True),
    ]
    # a frame exactly on a boundary belongs to the cycle it starts; the last takes its end
    t = np.array([115.02 - 1e-9, cycles[1].start_s, 160.5, 161.0])
    assert cycles[0].contains(t).tolist() == [True, False, False, False]
    assert cycles[1].contains(t).tolist() == [False, True, False, False]
    assert cycles[2].contains(t).tolist() == [False, False, True, True]


def test_a_restart_under_the_same_count_starts_a_cycle_and_bad_times_are_clamped() -> None:
    rows = [
        (10.0, 0, 0.0, "idle"),
        (20.0, 0, 10.0, "fold"),
        (30.0, 0, 0.5, "idle"),  # the cycle time ran back by 9.5 s: restarted at 29.5
        (40.0, 1, 99.0, "idle"),  # says it began at -59: taken to begin at 40
    ]
    cycles = split_cycles(state(rows), 10.0, 45.0)
    assert [(c.count, c.start_s, c.end_s) for c in cycles] == [
        (0, 10.0, 29.5),
        (0, 29.5, 40.0),
        (1, 40.0, 45.0),
    ]


def test_phase_spans_run_to_the_next_phase_and_the_last_to_the_end() -> None:
    rows = [
        (0.0, 0, 0.0, "idle"),
        (0.1, 0, 0.1, "idle"),
        (2.0, 0, 2.0, "fold"),
        (9.0, 0, 9.0, "fold"),
    ]
    spans = phase_spans(state(rows), 12.0)
    assert [(s.phase, s.start_s, s.end_s) for s in spans] == [
        ("idle", 0.0, 2.0),
        ("fold", 2.0, 12.0),
    ]


# --- per-cycle metrics ------------------------------------------------------------------

#: One sample a second; a 5-sample hump 200..400..200 kPa at t = 8..12 s; an invalid
#: 900 kPa sample at 10.5 s; the next cycle begins at 20 s with 1000 kPa.
HUMP_T = [float(t) for t in range(11)] + [10.5] + [float(t) for t in range(11, 21)]
HUMP_KPA = [100.0] * 8 + [200.0, 300.0, 400.0, 900.0, 300.0, 200.0] + [100.0] * 7 + [1000.0]
HUMP_VALID = [True] * 11 + [False] + [True] * 10


def hump() -> LegTrack:
    return track(HUMP_T, HUMP_KPA, HUMP_VALID)


def test_peak_and_near_constant_pressure_per_cycle() -> None:
    cycles = [Cycle(0, 0.0, 20.0), Cycle(1, 20.0, 21.0, final=True)]
    first, second = cycle_metrics({"L": hump()}, cycles, limit_Pa=200e3, window_s=5.0)
    m = first.metrics
    assert (first.cycle, first.leg) == (cycles[0], "L")
    # the invalid 900 kPa and the next cycle's 1000 kPa are left out
    assert (m.peak_pressure_Pa, m.peak_t_s) == (400e3, 10.0)
    # the best 5 s window holds t = 8..12 (the tracker keeps t > end - 5 s):
    # (200 + 300 + 400 + 300 + 200) / 5 = 280 kPa, ending at 12 s
    assert (m.near_constant_pressure_Pa, m.near_constant_t_s) == (280e3, 12.0)
    assert m.time_above_limit_s == 3.0  # after the 300, 400 and 300 kPa samples
    assert m.samples == 20
    # one sample in a 1 s cycle: a peak, but no 5 s window
    assert second.metrics.peak_pressure_Pa == 1000e3
    assert math.isnan(second.metrics.near_constant_pressure_Pa)


def test_a_gap_adds_at_most_the_stale_time_above_the_limit() -> None:
    (row,) = cycle_metrics(
        {"L": hump()},
        [Cycle(None, 0.0, 20.0)],
        limit_Pa=200e3,
        window_s=5.0,
        max_gap_s={"L": 0.25},
    )
    assert row.metrics.time_above_limit_s == 0.75


# --- matching and deviations ---------------------------------------------------------


def test_match_nearest_within_half_a_period() -> None:
    reference = np.array([1.00, 1.01, 1.02, 1.05])
    t = np.array([0.994, 0.996, 1.004, 1.005, 1.006, 1.0151, 1.035, 1.055, 1.0551])
    assert match_nearest(t, reference, 0.005).tolist() == [-1, 0, 0, 0, 1, 2, -1, 3, -1]
    assert match_nearest(t, reference[:0], 0.005).tolist() == [-1] * len(t)
    assert sample_period_s(np.array([0.0, 0.01, 0.01, 0.02, 0.05])) == 0.01


def test_the_calculated_force_is_the_median_centred_on_the_frame() -> None:
    """Median window 5 over the raw forces, centred: the running median 2 valid samples
    later; invalid ones skipped. Published: the recorded (live-filtered) force."""
    t = np.round(np.arange(12) * 0.01 + 100.0, 6)
    t[9] += 0.004  # 4 ms off its truth sample: more than the 3 ms allowed below
    valid = np.ones(12, dtype=np.bool_)
    valid[6] = False
    raw = 2000.0 * np.arange(12)
    raw[[1, 8]] = [50e3, -50e3]  # spikes: the centred median removes them
    raw[6] = 1e9  # invalid: neither matched nor used as a later value
    force = 1000.0 * np.arange(12)  # as published by the live filter
    leg = LegTrack("L", t, force, force / 0.33, valid, raw, force > 0, np.ones(12, bool))
    true_N = 1000.0 * np.arange(12) + 10.0
    true_N[3] = NAN  # unknown truth: left out
    truth = TruthTrack(np.round(np.arange(12) * 0.01 + 100.0, 6), {"L": true_N})

    comparison = compare_leg(leg, truth, 0.003, median_window=5, contact_N=4000.0)
    # usable frames 0..5, 7..11; the last 2 have no centred median; 3 has no truth,
    # 9 no truth sample near enough
    assert comparison.t_s.tolist() == [t[i] for i in (0, 1, 2, 4, 5, 7, 8)]
    # centred window of 5 valid raw forces (6 is invalid): frame 0 (head) -> median of
    # frames 0..2 = 4k, 1 -> 0..3 (even: (4k + 6k) / 2), 2 -> 0..4, 4 -> 2,3,4,5,7,
    # 5 -> 3,4,5,7,8 (the -50k spike at 8 is outvoted), 7 -> 4,5,7,8,9, 8 -> 5,7,8,9,10
    assert comparison.calculated_N.tolist() == [4e3, 5e3, 6e3, 8e3, 8e3, 10e3, 14e3]
    assert comparison.published_N.tolist() == [0.0, 1e3, 2e3, 4e3, 5e3, 7e3, 8e3]
    assert comparison.true_N.tolist() == [10.0, 1010.0, 2010.0, 4010.0, 5010.0, 7010.0, 8010.0]
    assert comparison.deviation_N.tolist() == [3990.0] * 4 + [2990.0] * 2 + [5990.0]
    # stance: true force above the contact threshold (4010 N is, 2010 N is not)
    assert comparison.stance.tolist() == [False] * 3 + [True] * 4

    both = compare({"L": leg, "X": leg}, truth, median_window=5, contact_N=4000.0)
    assert list(both) == ["L"]  # no truth for X
    # half of the 10 ms truth period: frame 9, 4 ms off, is matched now
    assert both["L"].t_s.tolist() == comparison.t_s.tolist() + [t[9]]


def test_sparse_truth_is_compared_with_the_estimates_at_its_instants_only() -> None:
    """Truth once a second (``portal-sim --truth-every 100``), estimates every 10 ms: an
    estimate 0.4 s from a truth sample is not compared with it (half the truth's period
    matched every estimate, each off by the force's change over up to 0.5 s)."""
    t = np.round(100.0 + np.arange(300) * 0.01, 6)
    t[200] += 0.003  # receive latency: still the truth sample's frame
    force = 1000.0 * np.arange(300)  # a ramp: 100 kN a second
    leg = LegTrack(
        "L", t, force, force / 0.33, np.ones(300, bool), force, force > 0, np.ones(300, bool)
    )
    truth_t = np.array([100.0, 101.0, 102.0])
    truth = TruthTrack(truth_t, {"L": np.array([0.0, 100e3, 200e3])})

    comparison = compare({"L": leg}, truth, median_window=1, contact_N=0.0)["L"]
    assert comparison.t_s.tolist() == [t[0], t[100], t[200]]
    assert comparison.deviation_N.tolist() == [0.0, 0.0, 0.0]
    # truth denser than the estimates: half the truth's period, as before
    dense = TruthTrack(np.round(100.0 + np.arange(3000) * 0.001, 6), {"L": np.zeros(3000)})
    assert compare({"L": leg}, dense, 1, 0.0)["L"].t_s.size == 300


def test_deviation_statistics_are_of_the_absolute_deviation() -> None:
    deviation = np.array([-10.0, -4.0, -2.0, 0.0, 1.0, 3.0])
    true_N = np.array([100.0, 200.0, 300.0, 400.0, 500.0, 600.0])
    comparison = LegComparison(
        "L", np.arange(6.0), true_N + deviation, true_N, true_N + 2 * deviation, true_N > 0
    )
    stats = deviation_stats(comparison)
    # |deviation| sorted: 0 1 2 3 4 10; linear quantiles at 2.5 and 4.75 of 5
    assert stats == DeviationStats(
        leg="L",
        samples=6,
        median_N=-1.0,
        mean_N=-2.0,
        abs50_N=2.5,
        abs95_N=8.5,
        max_abs_N=10.0,
        mean_true_N=350.0,
        published_abs95_N=17.0,
    )
    assert deviation_stats(comparison, stance=False).samples == 0
    empty = deviation_stats(LegComparison("E", *(np.zeros(0),) * 4, np.zeros(0, dtype=bool)))
    assert empty.samples == 0 and math.isnan(empty.abs95_N)


def test_stance_and_swing_samples_are_counted_and_judged_apart() -> None:
    """A lifted leg's big deviations (true force 0) do not enter the stance figures."""
    true_N = np.array([50e3, 52e3, 54e3, 0.0, 0.0, 0.0, 0.0, 9e3])
    deviation = np.array([100.0, -200.0, 300.0, -4500.0, 3500.0, 4000.0, -100.0, 50.0])
    comparison = LegComparison(
        "L", np.arange(8.0), true_N + deviation, true_N, true_N, true_N > 8000.0
    )
    stance, swing = deviation_stats(comparison), deviation_stats(comparison, stance=False)
    assert (stance.samples, swing.samples) == (4, 4)
    assert stance.max_abs_N == 300.0 and stance.abs95_N == pytest.approx(285.0)
    assert stance.mean_true_N == pytest.approx((50e3 + 52e3 + 54e3 + 9e3) / 4)
    assert swing.max_abs_N == 4500.0 and swing.mean_true_N == 0.0


def test_the_most_loaded_leg_has_the_highest_mean_true_force_not_peak() -> None:
    def stats(leg: str, mean_true_N: float, samples: int = 10) -> DeviationStats:
        return DeviationStats(leg, samples, 0, 0, 0, 0, 0, mean_true_N, 0)

    assert most_loaded({"A": stats("A", 40e3), "B": stats("B", 55e3), "C": stats("C", 9e3)}) == "B"
    assert most_loaded({"A": stats("A", 40e3, samples=0)}) is None


# --- drawing helpers and collecting ------------------------------------------------------


def test_invalid_samples_and_missing_frames_become_gaps() -> None:
    t, values = with_gaps(
        np.array([0.0, 0.01, 0.02, 0.10, 0.11]),
        np.array([1.0, 2.0, 3.0, 4.0, 5.0]),
        np.array([True, False, True, True, True]),
        0.03,
    )
    assert t.tolist() == pytest.approx([0.0, 0.01, 0.02, 0.06, 0.10, 0.11])
    assert np.isnan(values).tolist() == [False, True, False, True, False, False]
    assert values[~np.isnan(values)].tolist() == [1.0, 3.0, 4.0, 5.0]


def test_leg_styles_colour_and_marker_by_foot_dash_by_base_all_distinct() -> None:
    legs = ["SB1_F1", "SB1_F2", "SB1_F3", "SB2_F1", "SB2_F2", "SB2_F3"]
    styles = leg_styles(legs)
    assert (styles["SB1_F2"]["color"], styles["SB1_F2"]["linestyle"]) == ("tab:orange", "-")
    assert (styles["SB2_F2"]["color"], styles["SB2_F2"]["linestyle"]) == ("tab:orange", "--")
    # SB1_F2 and SB1_F3 carry equal loads for long stretches: besides the colour, marker,
    # marker positions and line width tell them apart, so neither hides the other
    f2, f3 = styles["SB1_F2"], styles["SB1_F3"]
    assert f2["marker"] != f3["marker"] and f2["markevery"] != f3["markevery"]
    assert f2["linewidth"] > f3["linewidth"]
    assert len({(s["color"], s["linestyle"], s["marker"]) for s in styles.values()}) == 6
    assert len({s["markevery"] for s in styles.values()}) == 6
    other = leg_styles(["front", "rear"])
    assert other["front"]["color"] != other["rear"]["color"]
    assert other["front"]["marker"] != other["rear"]["marker"]


def message(payload: dict) -> bytes:  # type: ignore[type-arg]
    return json.dumps(payload).encode()


def leg_payload(t: float, force: float | None, valid: bool = True, reasons=()) -> bytes:  # type: ignore[no-untyped-def]
    return message(
        {"leg": "SB1_F1", "t": t, "force_N": force, "force_raw_N": force,
         "pressure_Pa": None if force is None else force / 0.33, "p_piston_Pa": 1.0,
         "p_rod_Pa": 1.0, "contact": True, "valid": valid, "reasons": list(reasons)}
    )  # fmt: skip


def test_the_collector_counts_like_the_service() -> None:
    collector = RecordingCollector()
    raw = {"id": 256, "extended": False, "dlc": 8, "data": "00", "error_frame": False,
           "remote_frame": False, "reason": None}  # fmt: skip
    for t, error in ((5.0, None), (5.1, "unknown_id"), (5.2, "wrong_dlc"), (5.3, "unknown_id")):
        collector.add("/can/raw", message(raw | {"t": t, "error": error}))
    state_signals = {"Machine_Phase": "fold", "Machine_CycleCount": 2, "Machine_CycleTime": 3.5}
    for t, crc_ok, counter_ok in ((5.0, True, True), (5.1, False, True), (5.2, True, False)):
        collector.add(
            "/signals/MACHINE_STATE",
            message({"t": t, "crc_ok": crc_ok, "counter_ok": counter_ok, "signals": state_signals}),
        )
    leg_frame = {"t": 5.3, "crc_ok": True, "counter_ok": False, "signals": {}}
    collector.add(
        "/signals/LEG_SB1_F1",
        message(leg_frame | {"faults": ["counter_repeat"], "frames_lost": 0}),
    )
    collector.add("/signals/LEG_SB1_F1", message(leg_frame | {"faults": [], "frames_lost": 2}))
    collector.add("/leg/SB1_F1/ground", leg_payload(5.1, None, False, ("crc",)))
    collector.add("/leg/SB1_F1/ground", leg_payload(5.2, 33.0, False, ("counter", "range")))
    collector.add("/leg/SB1_F1/ground", leg_payload(5.3, 3300.0))
    collector.add(
        "/daq/bus", message({"t": 1.0, "state": "up", "reason": "", "reset_counters": False})
    )
    loss = {"t": 5.2, "state": "up", "reason": "lost", "reset_counters": False}
    collector.add("/daq/bus", message(loss | {"kernel_dropped": 40, "rx_dropped": 0}))
    collector.add("/daq/bus", message(loss | {"kernel_dropped": 2, "rx_dropped": 3}))
    collector.add(
        "/sim/truth", message({"t_unix_s": 5.1, "legs": {"SB1_F1": {"force_true_N": 7.0}}})
    )
    collector.add(
        "/sim/truth", message({"t_unix_s": 5.2, "legs": {"SB1_F1": {"force_true_N": None}}})
    )
    collector.add("/other", b"not even json")
    recording = collector.recording("x.mcap", None, machine_id="m")

    counts = recording.counts
    assert counts.frames == 4 and counts.messages == {"LEG_SB1_F1": 2, "MACHINE_STATE": 3}
    assert counts.bad == {
        "unknown_id": 2,
        "wrong_dlc": 1,
        "crc": 1,
        "counter": 1,
        "counter_repeat": 1,
    }
    assert counts.frames_lost == 2
    assert counts.estimates == 3 and counts.invalid == {"crc": 1, "counter": 1, "range": 1}
    assert (counts.bus_events, counts.truth_samples) == (1, 2)
    assert (counts.kernel_dropped, counts.rx_dropped) == (42, 3)
    assert (recording.start_t_s, recording.end_t_s) == (5.0, 5.3)
    leg = recording.legs["SB1_F1"]
    assert leg.t_s.tolist() == [5.1, 5.2, 5.3] and leg.valid.tolist() == [False, False, True]
    assert math.isnan(leg.force_N[0]) and leg.pressure_Pa[2] == pytest.approx(10000.0)
    assert recording.state.t_s.tolist() == [5.0, 5.2]  # the frame with a bad CRC is left out
    assert recording.state.cycle_count.tolist() == [2, 2] and recording.state.phase[0] == "fold"
    assert recording.truth.t_s.tolist() == [5.1, 5.2]
    assert recording.truth.force_true_N["SB1_F1"][0] == 7.0
    assert math.isnan(recording.truth.force_true_N["SB1_F1"][1])

    content = analyse(recording)
    assert [c.count for c in content.cycles] == [2]
    assert content.cycles[0].start_s == 5.0  # 5.0 - 3.5 is before the recording: clamped
    assert content.gap_after_s["SB1_F1"] == pytest.approx(0.3)  # 3 sample periods
    # the one valid estimate has no centred median (11-sample window): nothing compared
    assert content.deviations["SB1_F1"].samples == 0 and content.most_loaded is None


def test_a_leg_track_is_kept_in_typed_columns() -> None:
    """Every column intact, equal times in arrival order; a row costs tens of bytes, not a
    tuple of Python objects (~190), so that the report of an 8-hour recording fits in
    memory."""
    collector = RecordingCollector()
    arrivals = [(5.0, 0.0, False, True), (5.1, 1.0, True, False), (5.2, 2.0, True, False),
                (5.2, 3.0, True, True)]  # fmt: skip
    for t_s, force_N, valid, contact in arrivals:
        collector.add_estimate(
            {"leg": "SB1_F1", "t": t_s, "force_N": force_N, "pressure_Pa": force_N / 2,
             "valid": valid, "force_raw_N": -force_N, "contact": contact, "reasons": []}
        )  # fmt: skip
    track = collector.recording("x", None, machine_id="m").legs["SB1_F1"]
    assert track.t_s.tolist() == [5.0, 5.1, 5.2, 5.2]
    assert track.force_N.tolist() == [0.0, 1.0, 2.0, 3.0]
    assert track.pressure_Pa.tolist() == [0.0, 0.5, 1.0, 1.5]
    assert track.force_raw_N.tolist() == [-0.0, -1.0, -2.0, -3.0]
    assert track.valid.tolist() == [False, True, True, True]
    assert track.contact.tolist() == [True, False, False, True]
    assert track.valid.dtype == np.bool_ and track.t_s.dtype == np.float64

    rows = 20_000
    collector = RecordingCollector()
    payloads = [
        {"leg": "SB1_F1", "t": 5.0 + i, "force_N": float(i), "pressure_Pa": float(i),
         "valid": True, "force_raw_N": float(i), "contact": True, "reasons": []}
        for i in range(rows)
    ]  # fmt: skip
    tracemalloc.start()
    try:
        for payload in payloads:
            collector.add_estimate(payload)
        kept_bytes, _ = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert kept_bytes / rows < 64


def test_a_time_in_cycle_in_ms_is_read_in_seconds() -> None:
    """A DBC whose time in cycle is in ms ([signals] cycle_time): its 22,500 was read as
    22,500 s, the cycles' clocks 1000 times too fast."""
    from dbc.database import load_database_string
    from dbc.machine import DEFAULT_DBC_PATH, parse_machine_config
    from tests.helpers import EXAMPLE_CONFIG

    text = DEFAULT_DBC_PATH.read_text(encoding="cp1252").replace(
        'Machine_CycleTime : 24|16@1+ (0.01,0) [0|655.35] "s"',
        'Machine_CycleTime : 24|16@1+ (10,0) [0|655350] "ms"',
    )
    database = load_database_string(text, "ms.dbc")
    machine = parse_machine_config(tomllib.loads(EXAMPLE_CONFIG.read_text()), "ms.toml", database)
    names = StateSignals.of(machine)
    assert names is not None and names.cycle_time_s_per_unit == 0.001
    payload = {"t": 5.0, "signals": {"Machine_CycleCount": 2, "Machine_CycleTime": 22500}}
    assert StateTrack.row(payload, names) == (5.0, 2, 22.5, "")
    assert StateTrack.row(payload, StateSignals()) == (5.0, 2, 22500.0, "")
