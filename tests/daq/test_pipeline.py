"""The pure pipeline: frames in, estimates out, faults counted by kind, never raised."""

import json
import math

from daq.frames import RawFrame
from daq.payloads import json_bytes, leg_ground
from daq.pipeline import Pipeline
from dbc.encoding import FrameEncoder
from estimator.equations import foot_force_N
from tests.daq.service_support import leg_signals
from tests.helpers import LEGS, example_machine


def make() -> tuple[Pipeline, FrameEncoder]:
    config, database = example_machine()
    return Pipeline.from_config(config, database), FrameEncoder(database, config.protection)


def raw(frame, t_s: float) -> RawFrame:  # type: ignore[no-untyped-def]
    return RawFrame(t_s, frame.arbitration_id, frame.is_extended_id, frame.data)


def test_leg_frame_gives_its_estimate() -> None:
    pipeline, encoder = make()
    result = pipeline.process(raw(encoder.encode("LEG_SB1_F3", leg_signals("SB1_F3", 9e6, 1e6)), 5))
    (estimate,) = result.estimates
    geometry = pipeline.estimator.legs["SB1_F3"].leg
    assert estimate.leg == "SB1_F3" and estimate.t_s == 5 and estimate.valid
    assert estimate.force_raw_N == foot_force_N(9e6, 1e6, geometry)
    assert result.decoded is not None and result.error is None
    assert pipeline.frames == 1 and not pipeline.bad


def test_bad_frames_are_counted_by_kind_never_raised() -> None:
    pipeline, encoder = make()
    good = encoder.encode("LEG_SB1_F1", leg_signals("SB1_F1", 9e6, 1e6))
    frames = [
        RawFrame(0, 0x7FF, False, b""),
        RawFrame(0, 0x100, False, good.data[:5]),
        RawFrame(0, 0x100, True, good.data),  # extended 0x100 is not the DBC's 0x100
        RawFrame(0, 0x100, False, b"", is_remote_frame=True),
        RawFrame(0, 0x4, False, bytes(8), is_error_frame=True),
        RawFrame(0, 0x100, False, good.data, is_fd=True),  # the leg's message is classic
    ]
    kinds = [pipeline.process(frame).error_kind for frame in frames]
    assert kinds == [
        "unknown_id",
        "wrong_dlc",
        "unknown_id",
        "remote_frame",
        "error_frame",
        "fd_frame",
    ]
    assert pipeline.bad == {
        "unknown_id": 2,
        "wrong_dlc": 1,
        "remote_frame": 1,
        "error_frame": 1,
        "fd_frame": 1,
    }
    assert pipeline.frames == 6


def test_reset_counters_forgives_the_jump_after_a_gap() -> None:
    pipeline, encoder = make()
    signals = leg_signals("SB1_F1", 9e6, 1e6)
    pipeline.process(raw(encoder.encode("LEG_SB1_F1", signals, counter=1), 0))
    pipeline.reset_counters()
    after_gap = pipeline.process(raw(encoder.encode("LEG_SB1_F1", signals, counter=9), 0.01))
    assert after_gap.estimates[0].valid
    jump = pipeline.process(raw(encoder.encode("LEG_SB1_F1", signals, counter=3), 0.02))
    assert jump.estimates[0].reasons == ("counter",)
    assert pipeline.bad == {"counter": 1}


def test_a_silence_longer_than_a_turn_of_the_counter_restarts_its_check() -> None:
    """LEG_SB1_F1: 4-bit counter, 10 ms cycle: a turn is 160 ms. A shorter gap still shows
    the jump (frames lost); after a longer one (the sender switched off, a log's gap) the
    counter cannot tell what was lost, and the first frame is taken as it comes."""
    pipeline, encoder = make()
    signals = leg_signals("SB1_F1", 9e6, 1e6)
    pipeline.process(raw(encoder.encode("LEG_SB1_F1", signals, counter=1), 100.0))
    short = pipeline.process(raw(encoder.encode("LEG_SB1_F1", signals, counter=9), 100.15))
    assert short.estimates[0].reasons == ("counter",) and short.decoded is not None
    assert short.decoded.frames_lost == 7
    after_an_hour = pipeline.process(raw(encoder.encode("LEG_SB1_F1", signals, counter=4), 3700))
    assert after_an_hour.estimates[0].valid and after_an_hour.decoded is not None
    assert after_an_hour.decoded.frames_lost == 0
    assert pipeline.bad == {"counter": 1} and pipeline.frames_lost == 7


def test_a_silence_across_a_clock_step_back_restarts_the_counters_check() -> None:
    """LEG_SB1_F1 is lost for 0.5 s (three turns of its counter) while SB1_F2 goes on,
    and NTP steps the clock back an hour meanwhile: its frame times say it came back
    before it went, and its first frame was a ``counter`` fault (a sample invalid, a
    fault counted, where the sender was fine). On bus time the silence is 0.5 s."""
    pipeline, encoder = make()
    results = []
    for i in range(100):  # 10 ms apart; SB1_F1 silent for 0.5 s from 0.2 s
        t_s = 1000.0 + 0.01 * i - (3600.0 if i >= 40 else 0.0)
        for leg in ("SB1_F1", "SB1_F2"):
            frame = encoder.encode(f"LEG_{leg}", leg_signals(leg, 9e6, 1e6))  # counts on
            if leg == "SB1_F2" or not 20 <= i < 70:  # a loose connector: none arrives
                results.append(pipeline.process(raw(frame, t_s)))
    assert all(estimate.valid for result in results for estimate in result.estimates)
    assert not pipeline.bad and pipeline.frames_lost == 0


def test_json_payload_writes_nan_as_null() -> None:
    pipeline, _ = make()
    snapshot = pipeline.snapshot(100.0)
    payload = json.loads(json_bytes(leg_ground(snapshot.legs["SB1_F1"])))
    assert payload["force_N"] is None and payload["t"] is None
    assert payload["reasons"] == ["stale"] and payload["valid"] is False
    assert json.loads(json_bytes({"x": [math.inf, -math.inf, 1.5]})) == {"x": [None, None, 1.5]}


def test_a_pose_silent_across_a_clock_step_back_is_old() -> None:
    """The bridge's controller falls silent while the legs go on, and NTP steps the clock
    back an hour meanwhile: on frame times its last pose looked an hour younger than
    the legs' frames, fresh, and the stability margin was computed from it for that
    hour. On bus time it is as old as the silence: the margin is undefined."""
    pipeline, encoder = make()
    pose = {
        "BRIDGE_POSE": {
            "SB1_InclinationAngle": 0.0,
            "SB2_InclinationAngle": 0.0,
            "Bridge_FoldAngle": 0.0,
        },
        "BRIDGE_MOTION": {"Bridge_RotationAngle": 0.0, "Carriage_Position": 0.0},
    }
    margins = []
    for i in range(100):  # 10 ms apart; the pose every 20 ms for 0.5 s, then nothing
        t_s = 1000.0 + 0.01 * i - (3600.0 if i >= 60 else 0.0)
        if i < 50 and i % 2 == 0:
            for message, signals in pose.items():
                pipeline.process(raw(encoder.encode(message, signals), t_s))
        for leg in LEGS:
            pipeline.process(raw(encoder.encode(f"LEG_{leg}", leg_signals(leg, 9e6, 1e6)), t_s))
        snapshot = pipeline.snapshot(t_s)
        assert all(estimate.valid for estimate in snapshot.legs.values())
        margins.append(None if snapshot.stability is None else snapshot.stability.margin_m)
    assert all(margin is not None for margin in margins[:50])
    assert margins[99] is None and margins[60] is None
