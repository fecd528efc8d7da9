"""The recorder in a process of its own: what the service hands it is written as the
recorder in a thread writes it, losses are counted, signals do not stop it."""

import json
import os
import resource
import signal
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from mcap.reader import make_reader

from daq import recorder_process
from daq.errors import RecordingError
from daq.frames import BusEvent
from daq.mcap_file import RecordBatch
from daq.recorder import Recorder
from daq.recorder_process import RecorderProcess
from daq.service_config import RecordingSettings
from tests.daq.test_recording import raw_times, results, wait_drained
from tests.helpers import example_machine


def messages(path: Path) -> list[tuple[str, int, bytes]]:
    with open(path, "rb") as file:
        reader = make_reader(file)
        assert reader.get_summary() is not None  # finished: summary and index
        return [(c.topic, m.log_time, m.data) for _, c, m in reader.iter_messages()]


def test_writes_what_the_recorder_in_a_thread_writes(tmp_path: Path) -> None:
    _, database = example_machine()
    batches = [RecordBatch.of(results(40, t0=1000.0 + i), signals=True) for i in range(5)]
    written = {}
    for kind in (Recorder, RecorderProcess):
        settings = RecordingSettings(directory=tmp_path / kind.__name__)
        with kind(settings, database, machine_id="m") as recorder:
            for batch in batches:
                recorder.submit(batch)
            recorder.submit(BusEvent(1010.0, "down", "test"))
            wait_drained(recorder)
        assert recorder.dropped == 0 and recorder.errors == 0 and len(recorder.paths) == 1
        written[kind] = messages(recorder.paths[0])
    assert len(written[Recorder]) == 5 * 2 + 5 * 40 + 1  # raw and leg per batch, signals, event
    assert written[RecorderProcess] == written[Recorder]


def test_a_directory_it_cannot_create_is_a_recording_error(tmp_path: Path) -> None:
    _, database = example_machine()
    (tmp_path / "file").write_text("")
    settings = RecordingSettings(directory=tmp_path / "file" / "rec")
    with pytest.raises(RecordingError, match="cannot create it"):
        RecorderProcess(settings, database, machine_id="m").start()


@contextmanager
def child_stopped(recorder: RecorderProcess) -> Iterator[None]:
    """The recorder's child takes nothing meanwhile (SIGSTOP): a queue fills, whatever the
    machine's load."""
    assert recorder.pid is not None
    os.kill(recorder.pid, signal.SIGSTOP)
    try:
        yield
    finally:
        os.kill(recorder.pid, signal.SIGCONT)


def test_a_full_queue_drops_and_counts_frames_and_the_rest_is_written(tmp_path: Path) -> None:
    _, database = example_machine()
    settings = RecordingSettings(directory=tmp_path, queue_size=5)
    recorder = RecorderProcess(settings, database, machine_id="m")
    with recorder:
        with child_stopped(recorder):
            for i in range(10):
                recorder.submit(RecordBatch.of(results(3, t0=1000.0 + i), signals=False))
            assert recorder.depth == 5 and recorder.dropped == 5 * 3
    assert recorder.dropped == 15 and recorder.depth == 0
    assert len(raw_times(recorder.paths[0])) == 15


def test_what_a_full_queue_dropped_is_a_gap_in_the_file_before_the_next_item(
    tmp_path: Path,
) -> None:
    """A recorder behind (a slow disk, a busy CPU) left a hole in the file that nothing in
    it explained (replayed: every leg silent, as if the sensors were); the status alone
    counted the drops."""
    _, database = example_machine()
    recorder = RecorderProcess(
        RecordingSettings(directory=tmp_path, queue_size=5), database, machine_id="m"
    )
    with recorder:
        with child_stopped(recorder):
            for i in range(10):
                recorder.submit(RecordBatch.of(results(3, t0=1000.0 + i), signals=False))
        wait_drained(recorder)
        recorder.submit(RecordBatch.of(results(3, t0=1010.0), signals=False))
        wait_drained(recorder)
    with open(recorder.paths[0], "rb") as file:  # in file order (the gap's time is wall time)
        written = [
            (c.topic, m.data) for _, c, m in make_reader(file).iter_messages(log_time_order=False)
        ]
    topics = [topic for topic, _ in written]
    assert topics.count("/daq/recording") == 1
    at = topics.index("/daq/recording")
    assert at == 5 * 2 and topics[at + 1] == "/can/raw"  # after the 5 batches taken
    gap = json.loads(written[at][1])
    assert gap["dropped"] == 5 * 3 and gap["reason"] == "recorder's queue full"
    assert gap["t"] - gap["stopped_t"] == pytest.approx(gap["lost_s"]) and gap["lost_s"] >= 0
    assert recorder.dropped == 15 and len(recorder.gaps) == 1
    assert len(raw_times(recorder.paths[0])) == 6 * 3


def test_every_gap_is_counted_beyond_the_latest_it_shares(tmp_path: Path) -> None:
    """The status counted the gaps the child shares as text, the latest 200: after more,
    ``recording.gaps`` stayed at 200 and ``lost_s`` summed the latest 200 alone."""
    _, database = example_machine()
    recorder = RecorderProcess(
        RecordingSettings(directory=tmp_path, queue_size=1), database, machine_id="m"
    )
    with recorder:
        for i in range(recorder_process._KEPT + 20):
            # On an idle machine the child took each at once and nothing was dropped:
            # stopped, the gap before fills the queue, both batches are dropped.
            with child_stopped(recorder):
                recorder.submit(RecordBatch.of(results(1, t0=1000.0 + i), signals=False))
                recorder.submit(RecordBatch.of(results(1, t0=1000.5 + i), signals=False))
            wait_drained(recorder)
    gaps = []
    for path in recorder.paths:
        with open(path, "rb") as file:
            gaps += [
                json.loads(m.data)["lost_s"]
                for _, c, m in make_reader(file).iter_messages(topics=["/daq/recording"])
            ]
    assert len(gaps) > recorder_process._KEPT and len(recorder.gaps) == recorder_process._KEPT
    assert recorder.gap_count == len(gaps) and recorder.lost_s == pytest.approx(sum(gaps))


def test_it_runs_at_sched_idle_and_only_close_stops_it(tmp_path: Path) -> None:
    _, database = example_machine()
    recorder = RecorderProcess(RecordingSettings(directory=tmp_path), database, machine_id="m")
    with recorder:
        assert recorder.pid is not None
        assert os.sched_getscheduler(recorder.pid) == os.SCHED_IDLE  # the service goes first
        for signum in (signal.SIGTERM, signal.SIGINT):
            os.kill(recorder.pid, signum)  # systemd and a terminal signal the whole group
        recorder.submit(RecordBatch.of(results(7), signals=False))
        wait_drained(recorder)
        time.sleep(0.3)  # long enough for a signal to have ended it
        assert recorder.alive
    assert not recorder.alive and recorder.dropped == 0
    assert len(raw_times(recorder.paths[0])) == 7


def test_a_dead_child_is_not_alive_and_what_it_never_took_is_counted(tmp_path: Path) -> None:
    _, database = example_machine()
    recorder = RecorderProcess(RecordingSettings(directory=tmp_path), database, machine_id="m")
    with recorder:
        assert recorder.alive and recorder.pid is not None
        os.kill(recorder.pid, signal.SIGKILL)
        deadline = time.monotonic() + 10
        while recorder.alive:  # the watchdog's condition: the service is not alive now
            assert time.monotonic() < deadline
            time.sleep(0.01)
        recorder.submit(RecordBatch.of(results(4), signals=False))
        recorder.submit(BusEvent(1010.0, "down", "test"))
    assert recorder.dropped == 4 + 1  # the batch's frames and the event, never written


def policies(pid: int) -> set[int]:
    """The scheduling policies of the threads of process ``pid``."""
    return {os.sched_getscheduler(int(tid)) for tid in os.listdir(f"/proc/{pid}/task")}


@pytest.mark.skipif(
    os.geteuid() != 0 and resource.getrlimit(resource.RLIMIT_NICE)[0] < 20,
    reason="leaving SCHED_IDLE needs CAP_SYS_NICE or an RLIMIT_NICE of 20 (LimitNICE=+0)",
)
def test_on_close_the_child_leaves_sched_idle_to_finish_its_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # At SCHED_IDLE on a CPU that other work saturated (two CPU hogs), the child got ~1 %
    # of a core: it was killed after JOIN_S with its file cut and what was queued lost.
    _, database = example_machine()
    leave_idle = recorder_process._leave_idle
    seen: list[tuple[set[int], set[int]]] = []

    def watched(pid: int) -> None:
        before = policies(pid)
        leave_idle(pid)
        seen.append((before, policies(pid)))

    monkeypatch.setattr(recorder_process, "_leave_idle", watched)
    recorder = RecorderProcess(RecordingSettings(directory=tmp_path), database, machine_id="m")
    with recorder:
        recorder.submit(RecordBatch.of(results(7), signals=False))
    [(before, after)] = seen  # once, the child still running
    assert os.SCHED_IDLE in before and after == {os.SCHED_OTHER}  # every thread
    assert recorder.dropped == 0 and len(raw_times(recorder.paths[0])) == 7
