"""Each injected fault has the effect it claims, as the project's decoder and estimator see it."""

from pathlib import Path

import pytest

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from dbc.errors import ConfigError
from dbc.samples import LegSampler
from estimator import LegEstimator
from sim_bridge.faults import FaultConfig, FaultInjector, FaultTargets, FaultWindow
from sim_bridge.result import LEGS, SimulationResult
from sim_bridge.schedule import instants, schedule
from tests.sim_bridge.synthetic import (
    CONFIG,
    frames_of,
    make_playout,
    make_result,
    play,
    small_machine,
)

W = FaultWindow.parse


def in_window(t_s: float, start_s: float, duration_s: float) -> bool:
    return start_s <= t_s < start_s + duration_s - 1e-9


@pytest.mark.parametrize(
    ("text", "targeted", "expected"),
    [
        ("SB1_F1@10:2", True, FaultWindow("SB1_F1", 10.0, 2.0)),
        ("LEG_SB1_F1@0.5:0.25", True, FaultWindow("LEG_SB1_F1", 0.5, 0.25)),
        ("30:1", False, FaultWindow("", 30.0, 1.0)),
    ],
)
def test_windows_parse(text: str, targeted: bool, expected: FaultWindow) -> None:
    assert FaultWindow.parse(text, targeted=targeted) == expected
    assert FaultWindow.parse(str(expected), targeted=targeted) == expected


@pytest.mark.parametrize(
    ("text", "targeted"),
    [("SB1_F1", True), ("SB1_F1@10", True), ("@1:2", True), ("SB1_F1@x:2", True),
     ("SB1_F1@1:0", True), ("SB1_F1@-1:2", True), ("SB1_F1@1:2", False), ("10", False)],
)  # fmt: skip
def test_bad_windows_say_the_syntax(text: str, targeted: bool) -> None:
    with pytest.raises(ValueError, match=r"START|seconds"):
        FaultWindow.parse(text, targeted=targeted)


def test_no_faults_means_every_frame_is_good(result: SimulationResult) -> None:
    played = play(result, end_s=1.0)
    assert all(f.crc_ok and f.counter_ok for step in played for f in step.frames)
    assert len(frames_of(played, "LEG_SB1_F1")) == 100


def test_bad_crc_frames_fail_the_decoders_crc_check(result: SimulationResult) -> None:
    everything = play(result, end_s=0.3, faults=FaultConfig(bad_crc_probability=1.0, seed=1))
    assert everything and all(not f.crc_ok for step in everything for f in step.frames)
    some = [
        f for s in play(result, 1.0, FaultConfig(bad_crc_probability=0.1, seed=3)) for f in s.frames
    ]
    bad = sum(not f.crc_ok for f in some)
    assert 0.05 * len(some) < bad < 0.15 * len(some)


def test_dropped_frames_are_missing_and_the_next_counter_jumps(result: SimulationResult) -> None:
    played = play(result, end_s=2.0, faults=FaultConfig(drop_probability=0.2, seed=5))
    legs = frames_of(played, "LEG_SB1_F1")
    assert 130 < len(legs) < 190
    assert any(not f.counter_ok for f in legs)
    assert all(f.crc_ok for f in legs)


def test_seeded_faults_are_reproducible_and_another_seed_differs(result: SimulationResult) -> None:
    def fingerprint(seed: int) -> list[tuple[float, str, bool]]:
        faults = FaultConfig(drop_probability=0.05, bad_crc_probability=0.05, seed=seed)
        return [(f.t_s, f.message, f.crc_ok) for s in play(result, 1.0, faults) for f in s.frames]

    assert fingerprint(7) == fingerprint(7)
    assert fingerprint(7) != fingerprint(8)


def test_the_drop_rate_does_not_move_which_frames_get_a_bad_crc(result: SimulationResult) -> None:
    def bad_crc(drop: float) -> set[tuple[float, str]]:
        faults = FaultConfig(drop_probability=drop, bad_crc_probability=0.05, seed=11)
        frames = [f for s in play(result, 1.0, faults) for f in s.frames]
        return {(f.t_s, f.message) for f in frames if not f.crc_ok}

    assert bad_crc(0.2) <= bad_crc(0.0)


def test_a_frozen_counter_fails_the_counter_check_in_its_window_only(
    result: SimulationResult,
) -> None:
    faults = FaultConfig(freeze_counter=(W("LEG_SB1_F1@0.5:0.2"),))
    legs = frames_of(play(result, end_s=1.0, faults=faults), "LEG_SB1_F1")
    for frame in legs:
        assert frame.counter_ok is not in_window(frame.t_s, 0.5, 0.2), frame.t_s
    assert len(legs) == 100 and all(f.crc_ok for f in legs)
    counters = [f.signals["SB1_F1_Counter"] for f in legs]
    assert counters[50:70] == [counters[49]] * 20
    # Other messages keep counting.
    assert all(f.counter_ok for f in frames_of(play(result, 1.0, faults), "LEG_SB1_F2"))


def test_a_leg_name_freezes_its_message(result: SimulationResult) -> None:
    legs = frames_of(
        play(result, 1.0, FaultConfig(freeze_counter=(W("SB2_F1@0:0.1"),))), "LEG_SB2_F1"
    )
    assert [f.counter_ok for f in legs[:12]] == [True] + [False] * 9 + [True, True]


def test_a_silent_sensor_sends_nothing_in_its_window(result: SimulationResult) -> None:
    played = play(result, end_s=1.5, faults=FaultConfig(silent=(W("SB2_F3@0.5:0.25"),)))
    times = [f.t_s for f in frames_of(played, "LEG_SB2_F3")]
    assert len(times) == 150 - 25
    assert not any(in_window(t, 0.5, 0.25) for t in times)
    assert len(frames_of(played, "LEG_SB2_F2")) == 150
    # Nothing was built in the window, so the counter simply continues afterwards.
    assert all(f.counter_ok for f in frames_of(played, "LEG_SB2_F3"))


def test_a_stuck_sensor_holds_the_pressures_of_its_first_frame(result: SimulationResult) -> None:
    played = play(result, end_s=1.0, faults=FaultConfig(stuck=(W("SB1_F2@0.3:0.4"),)))
    column = LEGS.index("SB1_F2")
    for step in played:
        (frame,) = step.of("LEG_SB1_F2")
        t_s = step.instant.sim_t_ns / 1e9
        row = 30 if in_window(t_s, 0.3, 0.4) else step.row
        assert frame.signals["SB1_F2_pPiston"] == pytest.approx(
            result.p_piston_Pa[row, column], abs=500
        )
        assert frame.signals["SB1_F2_pRod"] == pytest.approx(result.p_rod_Pa[row, column], abs=500)
        assert frame.crc_ok and frame.counter_ok and frame.signals["SB1_F2_Status"] == "ok"


def test_out_of_range_sends_45_MPa_which_the_estimator_flags_as_range(
    result: SimulationResult,
) -> None:
    played = play(result, end_s=1.0, faults=FaultConfig(out_of_range=(W("SB1_F3@0.2:0.1"),)))
    leg = CONFIG.legs["SB1_F3"]
    estimator = LegEstimator("SB1_F3", leg.geometry, CONFIG.estimator, leg.cycle_time_s)
    sampler = LegSampler(CONFIG.legs)
    for frame in frames_of(played, "LEG_SB1_F3"):
        ((_, sample),) = sampler.samples(frame)
        estimate = estimator.update(sample)
        if in_window(frame.t_s, 0.2, 0.1):
            assert sample.p_piston_Pa == 45e6
            assert estimate.reasons == ("range",)
        else:
            assert estimate.valid, (frame.t_s, estimate.reasons)


def test_a_sensor_fault_sets_the_status(result: SimulationResult) -> None:
    played = play(result, end_s=0.5, faults=FaultConfig(sensor_fault=(W("SB2_F2@0.1:0.1"),)))
    statuses = [f.signals["SB2_F2_Status"] for f in frames_of(played, "LEG_SB2_F2")]
    assert statuses == ["ok"] * 10 + ["sensor_fault"] * 10 + ["ok"] * 30


def test_a_bus_pause_sends_nothing_at_all(result: SimulationResult) -> None:
    played = play(result, end_s=1.0, faults=FaultConfig(pause=(W("0.4:0.3", targeted=False),)))
    for step in played:
        t_s = step.instant.sim_t_ns / 1e9
        assert (step.frames == []) is in_window(t_s, 0.4, 0.3), t_s
    assert len(frames_of(played, "MACHINE_STATE")) == 10 - 3


@pytest.mark.parametrize(
    ("faults", "message"),
    [
        (
            FaultConfig(silent=(W("SB9_F1@1:1"),)),
            r"--silent SB9_F1@1:1: no message or leg 'SB9_F1'",
        ),
        (FaultConfig(freeze_counter=(W("NOPE@1:1"),)), r"--freeze-counter NOPE@1:1: no message"),
        (FaultConfig(stuck=(W("LEG_SB1_F1@1:1"),)), r"--stuck LEG_SB1_F1@1:1: no leg"),
        (FaultConfig(out_of_range=(W("X@1:1"),)), r"--out-of-range X@1:1: no leg 'X'"),
    ],
)
def test_unknown_targets_are_refused_by_name(faults: FaultConfig, message: str) -> None:
    targets = FaultTargets(("LEG_SB1_F1", "MACHINE_STATE"), {"SB1_F1": "LEG_SB1_F1"})
    with pytest.raises(ConfigError, match=r"^fault flags: " + message):
        FaultInjector(faults, targets)


def test_a_sensor_fault_needs_a_status_value_naming_a_fault() -> None:
    names = frozenset({"ok", "busy"})
    targets = FaultTargets(("LEG_SB1_F1",), {"SB1_F1": "LEG_SB1_F1"}, {"SB1_F1": names})
    with pytest.raises(ConfigError) as refused:
        FaultInjector(FaultConfig(sensor_fault=(W("SB1_F1@1:1"),)), targets)
    assert refused.value.reason == (
        "leg SB1_F1 has no status value naming a fault in the DBC ('sensor_fault', or one "
        "with fault, error, fail, short, open, broken, fehler, defekt, st\u00f6rung, "
        "kurzschluss, bruch, d\u00e9faut, erreur in its name); its status values: busy, ok"
    )


def test_a_sensor_fault_sends_the_value_a_held_out_dbc_names_a_fault_with(
    result: SimulationResult, tmp_path: Path
) -> None:
    """A status table of Ok, Warning, Error, NotAvailable (J1939 transducers'): the flag
    was refused for want of 'sensor_fault'; now it sends Error, which the service flags."""
    config, database = small_machine(
        tmp_path,
        """
BO_ 768 HYD: 5 Hub
 SG_ pCap : 0|16@1+ (0.01,0) [0|600] "bar" DAQ
 SG_ pRod : 16|16@1+ (0.01,0) [0|600] "bar" DAQ
 SG_ Stat : 32|2@1+ (1,0) [0|3] "" DAQ
""",
        'BA_ "GenMsgCycleTime" BO_ 768 10;\n'
        'VAL_ 768 Stat 0 "Ok" 1 "Warning" 2 "Error" 3 "NotAvailable" ;\n',
        '[legs.front]\npiston = "HYD.pCap"\nrod = "HYD.pRod"\nstatus = "HYD.Stat"\n',
        '[sensors]\nstatus_ok = "Ok"\n',
    )
    faults = FaultConfig(seed=1, sensor_fault=(W("front@0.05:0.05"),))
    playout = make_playout(result, faults, config=config, database=database)
    pipeline = Pipeline.from_config(config, database)
    reasons = []
    for instant in instants(schedule(playout.cycles, end_sim_ns=200_000_000)):
        for item in playout.frames(instant)[1]:
            frame = item.frame
            raw = RawFrame(instant.sim_t_ns / 1e9, frame.arbitration_id, False, frame.data)
            reasons += [e.reasons for e in pipeline.process(raw).estimates]
    assert reasons == [()] * 5 + [("status_Error",)] * 5 + [()] * 10


@pytest.mark.parametrize("probability", [-0.1, 1.5])
def test_probabilities_must_be_probabilities(probability: float) -> None:
    with pytest.raises(ValueError, match="drop_probability must be within 0..1"):
        FaultConfig(drop_probability=probability)


def test_without_a_seed_one_is_drawn_and_reported() -> None:
    targets = FaultTargets(("LEG_SB1_F1",), {"SB1_F1": "LEG_SB1_F1"})
    injector = FaultInjector(FaultConfig(drop_probability=0.5), targets)
    rerun = FaultInjector(FaultConfig(drop_probability=0.5, seed=injector.seed), targets)
    fates = [injector.fate("LEG_SB1_F1", k) for k in range(50)]
    assert fates == [rerun.fate("LEG_SB1_F1", k) for k in range(50)]


def test_faults_apply_in_simulated_time_across_cycles() -> None:
    # A 0.5 s cycle looped: a window at 0.7 s hits the second cycle only.
    played = play(make_result(duration_s=0.5), 1.0, FaultConfig(silent=(W("SB1_F1@0.7:0.1"),)))
    missing = [s.row for s in played if not s.of("LEG_SB1_F1")]
    assert missing == list(range(20, 30))


def test_the_playout_counts_what_each_fault_touched(result: SimulationResult) -> None:
    faults = FaultConfig(
        freeze_counter=(W("LEG_SB1_F1@0.2:0.1"),),
        silent=(W("SB1_F2@0.5:0.05"),),
        pause=(W("0.9:0.1", targeted=False),),
        drop_probability=0.1,
        bad_crc_probability=0.1,
        seed=2,
    )
    playout = make_playout(result, faults)
    for instant in instants(schedule(playout.cycles, end_sim_ns=1_000_000_000)):
        playout.frames(instant)
    counts = playout.counts
    assert counts.frozen_counter == {"LEG_SB1_F1": 10}
    assert counts.silent == {"LEG_SB1_F2": 5}
    assert counts.paused["LEG_SB1_F1"] == 10 and counts.paused["MACHINE_STATE"] == 1
    assert counts.built["LEG_SB1_F1"] == 90 and counts.built["LEG_SB1_F2"] == 85
    built = sum(counts.built.values())
    assert 0.05 * built < sum(counts.dropped.values()) < 0.15 * built
    assert 0.05 * built < sum(counts.bad_crc.values()) < 0.15 * built
