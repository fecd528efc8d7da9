"""The emitter on python-can's in-process virtual bus, driven by a fake clock."""

import uuid
from collections import Counter
from collections.abc import Iterator

import can
import pytest

from dbc.decoding import FrameDecoder
from sim_bridge.emitter import Emitter, end_of_run_ns
from sim_bridge.result import SimulationResult
from sim_bridge.truth import TruthSample
from tests.sim_bridge.synthetic import CONFIG, DATABASE, make_playout, make_result

UNIX_AT_START_S = 1_750_000_000.0
FEET_M2 = {leg: CONFIG.legs[leg].geometry.A_foot_m2 for leg in CONFIG.legs}


class FakeClock:
    """Monotonic and wall clock in one; ``sleep`` advances it, oversleeping by ``late_s``."""

    def __init__(self, late_s: float = 0.0) -> None:
        self.now_s = 100.0
        self.late_s = late_s
        self.sleeps: list[float] = []

    def clock(self) -> float:
        return self.now_s

    def wall_clock(self) -> float:
        return self.now_s - 100.0 + UNIX_AT_START_S

    def sleep(self, duration_s: float) -> None:
        assert duration_s > 0
        self.sleeps.append(duration_s)
        self.now_s += duration_s + self.late_s


class ListSink:
    def __init__(self) -> None:
        self.samples: list[TruthSample] = []

    def write(self, sample: TruthSample) -> None:
        self.samples.append(sample)


@pytest.fixture()
def buses() -> Iterator[tuple[can.BusABC, can.BusABC]]:
    channel = f"sim-bridge-{uuid.uuid4()}"
    with (
        can.Bus(interface="virtual", channel=channel, preserve_timestamps=True) as tx,
        can.Bus(interface="virtual", channel=channel) as rx,
    ):
        yield tx, rx


def received(rx: can.BusABC) -> list[can.Message]:
    messages = []
    while (message := rx.recv(timeout=0)) is not None:
        messages.append(message)
    return messages


def by_message(messages: list[can.Message]) -> dict[str, list[can.Message]]:
    names = {m.frame_id: m.name for m in DATABASE.messages}
    grouped: dict[str, list[can.Message]] = {}
    for message in messages:
        grouped.setdefault(names[message.arbitration_id], []).append(message)
    return grouped


def emitter(
    tx: can.BusABC, result: SimulationResult, clock: FakeClock, cycles: int = 1, **kwargs
) -> Emitter:
    playout = make_playout(result)
    return Emitter(
        tx,
        playout,
        end_sim_ns=end_of_run_ns(playout.timeline.cycle_ns, cycles),
        clock=clock.clock,
        wall_clock=clock.wall_clock,
        sleep=clock.sleep,
        **kwargs,
    )


@pytest.mark.parametrize("speed", [1.0, 2.0, 10.0])
def test_oversleeping_never_accumulates_into_drift(buses, speed: float) -> None:
    tx, rx = buses
    clock = FakeClock(late_s=0.003)  # every sleep ends 3 ms late
    stats = emitter(tx, make_result(duration_s=1.0), clock, speed=speed).run()
    legs = by_message(received(rx))["LEG_SB1_F1"]
    assert len(legs) == stats.sent["LEG_SB1_F1"] == 100
    for k, message in enumerate(legs):
        due_s = UNIX_AT_START_S + k * 0.01 / speed
        assert due_s - 1e-9 <= message.timestamp <= due_s + 0.003 + 1e-9, k


def test_a_cycle_sends_every_message_at_its_cycle_time(buses) -> None:
    tx, rx = buses
    clock = FakeClock()
    stats = emitter(tx, make_result(duration_s=0.5), clock).run()
    counts = {name: len(messages) for name, messages in by_message(received(rx)).items()}
    assert counts == dict(stats.sent)
    assert counts["LEG_SB1_F1"] == counts["INCL_SB2"] == 50
    assert counts["STROKE_SB1"] == counts["BRIDGE_MOTION"] == 25
    assert counts["MACHINE_STATE"] == 5
    assert len(counts) == 13
    assert clock.now_s == pytest.approx(100.0 + 0.49)
    assert stats.late_instants == 0 and not stats.stopped


def test_as_fast_as_possible_never_sleeps(buses) -> None:
    tx, rx = buses
    clock = FakeClock()
    stats = emitter(tx, make_result(duration_s=0.5), clock, as_fast_as_possible=True).run()
    assert clock.sleeps == []
    assert sum(stats.sent.values()) == len(received(rx)) == 8 * 50 + 4 * 25 + 5


@pytest.mark.parametrize("speed", [1.0, 4.0])
def test_as_fast_as_possible_stamps_frames_and_truth_at_their_due_times(buses, speed) -> None:
    """A frames log or truth of such a run keeps the cycle's timing: stamped when sent,
    the whole cycle took the instant the clock showed, so a replay of the log never saw
    a transducer stale nor a --silent window."""
    tx, rx = buses
    sink = ListSink()
    run = emitter(
        tx, make_result(duration_s=0.3), FakeClock(), as_fast_as_possible=True, speed=speed,
        truth_sinks=[sink], feet_m2=FEET_M2,
    )  # fmt: skip
    run.run()
    grouped = by_message(received(rx))
    legs, state = grouped["LEG_SB1_F1"], grouped["MACHINE_STATE"]
    assert [m.timestamp for m in legs] == [
        round(UNIX_AT_START_S + k * 0.01 / speed, 6) for k in range(30)
    ]
    assert [m.timestamp for m in state] == [UNIX_AT_START_S + k * 0.1 / speed for k in range(3)]
    assert [sample.t_unix_s for sample in sink.samples] == [m.timestamp for m in legs]


def test_frames_decode_with_good_crc_and_counters_across_cycles(buses) -> None:
    tx, rx = buses
    stats = emitter(tx, make_result(duration_s=0.3), FakeClock(), cycles=3).run()
    decoder = FrameDecoder(DATABASE, CONFIG.protection)
    frames = [decoder.decode(m.arbitration_id, bytes(m.data), m.timestamp) for m in received(rx)]
    assert all(f.crc_ok and f.counter_ok for f in frames)
    state = [f.signals["Machine_CycleCount"] for f in frames if f.message == "MACHINE_STATE"]
    assert state == [0, 0, 0, 1, 1, 1, 2, 2, 2]
    assert stats.cycles_started == 3
    assert stats.sim_time_s == pytest.approx(0.89)


def test_truth_is_stamped_with_the_frame_time_of_its_row(buses) -> None:
    tx, rx = buses
    sink = ListSink()
    result = make_result(duration_s=0.2)
    run = emitter(tx, result, FakeClock(), cycles=2, speed=4.0, truth_sinks=[sink], feet_m2=FEET_M2)
    stats = run.run()
    legs = by_message(received(rx))["LEG_SB2_F2"]
    assert stats.truth_samples == len(sink.samples) == 40 == len(legs)
    for sample, frame in zip(sink.samples, legs, strict=True):
        assert sample.t_unix_s == frame.timestamp
    sample = sink.samples[25]
    assert (sample.cycle, sample.t_cycle_s) == (1, pytest.approx(0.05))
    truth = sample.legs["SB1_F3"]
    assert truth.force_true_N == result.force_true_N[5, 2]
    assert truth.pressure_true_Pa == pytest.approx(result.force_true_N[5, 2] / 0.33)
    assert truth.p_piston_Pa == result.p_piston_Pa[5, 2]


def test_truth_decimation_writes_every_nth_sample(buses) -> None:
    tx, _ = buses
    sink = ListSink()
    run = emitter(
        tx, make_result(0.5), FakeClock(), truth_sinks=[sink], feet_m2=FEET_M2, truth_every=5
    )
    run.run()
    assert [s.t_cycle_s for s in sink.samples] == pytest.approx([k * 0.05 for k in range(10)])


def test_stop_ends_the_run_after_the_current_instant(buses) -> None:
    tx, rx = buses
    clock = FakeClock()
    run = emitter(tx, make_result(duration_s=1.0), clock, cycles=0)

    def sleep(duration_s: float) -> None:
        clock.sleep(duration_s)
        if len(clock.sleeps) == 20:
            run.stop()

    run._sleep = sleep  # the stop arrives while waiting, as a signal would
    stats = run.run()
    assert stats.stopped
    assert by_message(received(rx))["LEG_SB1_F1"].__len__() == 21


def test_a_late_frame_delays_only_itself(buses) -> None:
    tx, rx = buses
    clock = FakeClock()
    run = emitter(tx, make_result(duration_s=0.5), clock)

    def sleep(duration_s: float) -> None:
        clock.sleep(duration_s)
        if len(clock.sleeps) == 10:
            clock.now_s += 0.0355  # a hiccup of 35.5 ms

    run._sleep = sleep
    stats = run.run()
    times = [m.timestamp - UNIX_AT_START_S for m in by_message(received(rx))["LEG_SB1_F1"]]
    assert times[10:14] == pytest.approx([0.1355] * 4)  # sent as soon as possible
    assert times[14] == pytest.approx(0.14) and times[-1] == pytest.approx(0.49)
    assert stats.late_instants == 3  # 110, 120, 130 ms were > 5 ms late; 100 ms was on time
    assert stats.max_lateness_s == pytest.approx(0.0255)


class RefusingBus(can.BusABC):
    def __init__(self) -> None:
        super().__init__(channel="refusing")

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if msg.arbitration_id == 0x130:
            raise can.CanOperationError("Transmit buffer full")

    def _recv_internal(self, timeout):  # type: ignore[no-untyped-def]
        return None, False


def test_refused_sends_are_counted_not_fatal() -> None:
    with RefusingBus() as bus:
        stats = emitter(bus, make_result(duration_s=0.5), FakeClock()).run()
    assert stats.send_errors == Counter({"MACHINE_STATE": 5})
    assert stats.sent["MACHINE_STATE"] == 0 and stats.sent["LEG_SB1_F1"] == 50


def test_end_of_run() -> None:
    assert end_of_run_ns(2_000_000_000, cycles=3) == 6_000_000_000
    assert end_of_run_ns(2_000_000_000, cycles=0) is None
    assert end_of_run_ns(2_000_000_000, cycles=0, duration_s=1.5) == 1_500_000_000
    with pytest.raises(ValueError, match="cycles"):
        end_of_run_ns(2_000_000_000, cycles=-1)
