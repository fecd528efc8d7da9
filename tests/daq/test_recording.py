"""MCAP recording: rotation by size and time, the files of one run, reading back a file
cut short by a crash."""

import errno
import io
import itertools
import json
import logging
import os
import time
from pathlib import Path

import pytest
from mcap.reader import NonSeekingReader, make_reader

from daq import recorder as recorder_module
from daq.can_batch import recorded_frames
from daq.errors import RecordingError
from daq.frames import BusEvent, RawFrame
from daq.mcap_file import CONFIG_ATTACHMENT, DBC_ATTACHMENT, CountingFile, McapFile, RecordBatch
from daq.mcap_reading import RecordedMessage, RecordingStream, json_items
from daq.pipeline import Pipeline
from daq.recorder import Recorder, cannot_create, file_name
from daq.recorder_process import RecorderProcess
from daq.recording_run import read_run_file, run_files
from daq.replay import replay
from daq.report.loading import load_recording
from daq.service_config import RecordingSettings
from dbc.encoding import FrameEncoder
from tests.daq.service_support import leg_signals
from tests.helpers import EXAMPLE_CONFIG, example_machine, recorded_raw_frames


def results(count: int, t0: float = 1000.0, dt: float = 0.01):  # type: ignore[no-untyped-def]
    config, database = example_machine()
    pipeline = Pipeline.from_config(config, database)
    encoder = FrameEncoder(database, config.protection)
    for i in range(count):
        frame = encoder.encode("LEG_SB1_F1", leg_signals("SB1_F1", 9e6 + 1e3 * i, 1e6))
        yield pipeline.process(RawFrame(t0 + dt * i, frame.arbitration_id, False, frame.data))


def raw_times(path: Path) -> list[float]:
    return [frame.t_s for frame in recorded_raw_frames(path)]


def wait_drained(recorder: Recorder | RecorderProcess) -> None:
    deadline = time.monotonic() + 10
    while recorder.depth and time.monotonic() < deadline:
        time.sleep(0.01)


def test_rotation_by_size_keeps_every_message_in_order(tmp_path: Path) -> None:
    _, database = example_machine()
    settings = RecordingSettings(directory=tmp_path, max_bytes=8192, chunk_size=2048)
    clock = iter(range(10**6))
    with Recorder(settings, database, machine_id="m", now=lambda: float(next(clock))) as recorder:
        for result in results(400):
            recorder.submit(RecordBatch.of([result], signals=True))
        wait_drained(recorder)
    assert len(recorder.paths) > 2 and recorder.dropped == 0 and recorder.errors == 0
    assert sorted(recorder.paths) == recorder.paths  # names sort by start time
    times = []
    for path in recorder.paths:
        with open(path, "rb") as file:
            assert make_reader(file).get_summary() is not None  # each file finished
        times += raw_times(path)
    assert times == [1000.0 + 0.01 * i for i in range(400)]


#: The recorder in a thread of the service's process, and in a process of its own.
KINDS = pytest.mark.parametrize("kind", [Recorder, RecorderProcess], ids=["thread", "process"])


@KINDS
def test_rotation_by_frame_time(tmp_path: Path, kind: type[Recorder | RecorderProcess]) -> None:
    _, database = example_machine()
    settings = RecordingSettings(directory=tmp_path, max_duration_s=1.0)
    with kind(settings, database, machine_id="m") as recorder:
        for result in results(35, dt=0.1):  # 3.4 s of frames
            recorder.submit(RecordBatch.of([result], signals=True))
        recorder.submit(BusEvent(2000.0, "down", "test"))
        wait_drained(recorder)
    assert len(recorder.paths) == 4
    assert [len(raw_times(path)) for path in recorder.paths] == [10, 10, 10, 5]


@KINDS
def test_one_batch_spanning_several_files_is_split_by_frame_time(
    tmp_path: Path, kind: type[Recorder | RecorderProcess]
) -> None:
    _, database = example_machine()
    settings = RecordingSettings(directory=tmp_path, max_duration_s=1.0)
    with kind(settings, database, machine_id="m") as recorder:
        recorder.submit(RecordBatch.of(results(35, dt=0.1), signals=True))  # 3.4 s at once
        wait_drained(recorder)
    assert [len(raw_times(path)) for path in recorder.paths] == [10, 10, 10, 5]
    with open(recorder.paths[1], "rb") as file:
        leg_times = [
            estimate["t"]
            for r in RecordingStream(file)
            if isinstance(r, RecordedMessage) and r.topic.startswith("/leg/")
            for estimate in json_items(r.data)
        ]
    assert leg_times == raw_times(recorder.paths[1])  # the estimates went with their frames


def test_a_clock_stepped_back_in_a_batch_at_a_rotation_keeps_every_frame_in_its_place(
    tmp_path: Path,
) -> None:
    # 1.4 s of frames, then the clock stepped back two hours: in one batch across the
    # rotation at 1001.0 s. Split by time, the 5 frames after the step (earlier by their
    # stamps) went into the first file, before the frames they followed: replay read the
    # run out of order.
    config, database = example_machine()
    pipeline = Pipeline.from_config(config, database)
    encoder = FrameEncoder(database, config.protection)
    # None at the rotation's very time (1001.0 s, from the file's first log time in ns).
    times = [1000.0] + [1000.05 + 0.1 * i for i in range(1, 15)]
    times += [1001.5 - 7200.0 + 0.1 * i for i in range(5)]
    batch = []
    for i, t_s in enumerate(times):
        frame = encoder.encode("LEG_SB1_F1", leg_signals("SB1_F1", 9e6 + 1e3 * i, 1e6))
        batch.append(pipeline.process(RawFrame(t_s, frame.arbitration_id, False, frame.data)))
    settings = RecordingSettings(directory=tmp_path, max_duration_s=1.0)
    with Recorder(settings, database, machine_id="m") as recorder:
        recorder.submit(RecordBatch.of(batch, signals=True))
        wait_drained(recorder)
    assert [raw_times(path) for path in recorder.paths] == [times[:10], times[10:]]


def record_run(directory: Path, run_id: str, t0: float) -> list[Path]:
    _, database = example_machine()
    settings = RecordingSettings(directory=directory, max_duration_s=1.0)
    with Recorder(settings, database, machine_id="m", run_id=run_id) as recorder:
        for result in results(35, t0=t0, dt=0.1):
            recorder.submit(RecordBatch.of([result], signals=True))
        wait_drained(recorder)
    return recorder.paths


def test_the_files_of_a_run_carry_its_id_and_their_order(tmp_path: Path) -> None:
    paths = record_run(tmp_path / "a", "run-a", 1000.0)
    assert [(f.run, f.index) for f in map(read_run_file, paths)] == [
        (("m", "run-a"), i) for i in range(4)
    ]
    # Given in any order (or as their directory), they come back in the order of the run.
    assert run_files(paths[::-1]) == paths
    assert run_files([tmp_path / "a"]) == paths


def test_files_of_two_runs_are_refused_and_a_missing_file_is_logged(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    first = record_run(tmp_path, "run-a", 1000.0)
    second = record_run(tmp_path, "run-b", 5000.0)
    with pytest.raises(RecordingError, match=r"2 runs .*run run-a of m: .*run run-b of m"):
        run_files([tmp_path])
    assert run_files(second) == second
    with caplog.at_level(logging.WARNING):
        assert run_files([first[0], first[2], first[3]]) == [first[0], first[2], first[3]]
    assert "run run-a: file(s) 1 of the run missing" in caplog.text


def test_file_names() -> None:
    assert file_name("pam-proto-1", 1_700_000_000.25) == "pam-proto-1_20231114T221320.250Z.mcap"


def test_a_file_cut_short_reads_back_to_its_last_complete_chunk(tmp_path: Path) -> None:
    _, database = example_machine()
    path = tmp_path / "cut.mcap"
    sizes = []
    with open(path, "wb", buffering=0) as raw:
        stream = CountingFile(raw)
        mcap = McapFile(stream, database, chunk_size=1024)
        mcap.start({"a.txt": b"hello"})
        for i, result in enumerate(results(300)):
            mcap.write_result(result)
            if i % 50 == 49:
                mcap.flush()
                sizes.append((stream.count, i + 1))
        # no close(): as if the process were killed here
    data = path.read_bytes()
    for size, frames in sizes:
        for cut in (size, size + 1, size + 37):
            (tmp_path / "part.mcap").write_bytes(data[:cut])
            with open(tmp_path / "part.mcap", "rb") as file:
                stream_reader = RecordingStream(file)
                records = list(stream_reader)
            times = [
                frame.t_s
                for r in records
                if isinstance(r, RecordedMessage) and r.topic == "/can/raw"
                for frame in recorded_frames(r.encoding, r.data)
            ]
            assert times[:frames] == [1000.0 + 0.01 * i for i in range(frames)]
            assert not stream_reader.complete and stream_reader.stopped_by
    # mcap's own non-seeking reader sees the same up to the cut (the seeking one,
    # which make_reader picks for a file, needs the summary and gives nothing)
    (tmp_path / "part.mcap").write_bytes(data[: sizes[0][0]])
    with open(tmp_path / "part.mcap", "rb") as file:
        reader = NonSeekingReader(file)
        count = 0
        try:
            for _ in reader.iter_messages(log_time_order=False):
                count += 1
        except Exception:  # noqa: BLE001 -- the cut end
            pass
    assert count >= 50


def test_leg_messages_of_this_and_earlier_releases_read_alike() -> None:
    one = {"leg": "SB1_F1", "t": 1.5, "force_N": 1000.0}
    two = {"leg": "SB1_F1", "t": 1.6, "force_N": None}
    batch = json.dumps({"leg": "SB1_F1", "estimates": [one, two]}).encode()
    assert json_items(batch) == [one, two]
    assert json_items(json.dumps(one).encode()) == [one]  # one estimate per message, before
    assert json_items(b'{"t":2.0,"legs":{}}') == [{"t": 2.0, "legs": {}}]  # other topics


def test_the_writer_pauses_after_every_message() -> None:
    """The recorder's thread lets the GIL go after each message (``pause``), so a batch
    never holds up the frames' thread for longer than one message."""
    _, database = example_machine()
    written: list[int] = []
    with McapFile(io.BytesIO(), database, pause=lambda: written.append(mcap.message_count)) as mcap:
        mcap.start()
        mcap.write_batch(RecordBatch.of(results(30), signals=True))
    assert written == list(range(1, 1 + 1 + 30 + 1))  # raw batch, leg batch, 30 signals


def test_the_recorder_lets_the_gil_go_once_a_quarter_millisecond_of_writing(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    slept: list[float] = []
    ticks = iter([0.0, 0.0001, 0.0002, 0.0003, 0.00031, 0.0004, 0.0006, 0.0007])
    monkeypatch.setattr(recorder_module.time, "perf_counter", lambda: next(ticks))
    monkeypatch.setattr(recorder_module.time, "sleep", slept.append)
    pause = recorder_module.GilYield(every_s=0.00025)  # starts at 0.0
    for _ in range(4):  # at 0.0001, 0.0002, 0.0003 (sleeps, restarts at 0.00031), 0.0004
        pause()
    assert slept == [0]
    pause()  # 0.0006: more than 0.25 ms since 0.00031
    assert slept == [0, 0]


def test_an_empty_or_cut_file_is_warned_about_once_by_replay(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Replay looks for the run's metadata first and then reads the file: one warning, and
    an empty file (the recorder stopped as it opened it) is not called a cut chunk."""
    from daq.cli import main

    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    cut = tmp_path / "cut.mcap"
    with open(cut, "wb") as raw:
        mcap = McapFile(CountingFile(raw), example_machine()[1], chunk_size=1024)
        mcap.start({})
        for result in results(200):
            mcap.write_result(result)
        mcap.flush()  # no close(): as if the process were killed here
    warnings = []
    for path in (empty, cut):
        assert main(["replay", str(path), "--config", str(EXAMPLE_CONFIG)]) == 0
        out, err = capsys.readouterr()
        warnings.append([line for line in err.splitlines() if "daq.mcap_reading" in line])
        assert out.startswith("leg,t,")
    (empty_warning,), (cut_warning,) = warnings
    assert f"{empty} holds no MCAP record (" in empty_warning
    assert f"{cut} ends without its summary (" in cut_warning


def test_replay_of_a_recording_counts_the_frames_lost_before_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The service's loss events (/daq/bus: kernel_dropped, rx_dropped) were read for the
    counters' resets only: a replay of a recording that lost frames said nothing of it."""
    from daq.cli import main

    path = tmp_path / "lossy.mcap"
    with open(path, "wb") as raw, McapFile(CountingFile(raw), example_machine()[1]) as mcap:
        mcap.start({})
        for i, result in enumerate(results(20)):
            if i in (5, 12):
                mcap.write_event(BusEvent(1000.0 + i / 100, "up", "loss", False, 40, i))
            mcap.write_result(result)
    assert main(["replay", str(path), "--config", str(EXAMPLE_CONFIG)]) == 0
    err = capsys.readouterr().err
    assert "97 frames lost before they were recorded or logged, not in the file (80 by the " in err
    assert "kernel: receive buffer full; 17 by the service's queue)" in err


def recorded_with_a_full_queue(tmp_path: Path) -> Recorder:
    """A recording of 4 batches of 3 frames whose queue (2 items) dropped 2 batches before
    the recorder started, then one more batch: its file holds 9 frames and the gap."""
    config, database = example_machine()
    clock = iter(range(10**6))
    recorder = Recorder(
        RecordingSettings(directory=tmp_path, queue_size=2),
        database,
        machine_id="m",
        attachments={
            CONFIG_ATTACHMENT: EXAMPLE_CONFIG.read_bytes(),
            DBC_ATTACHMENT: config.dbc_path.read_bytes(),
        },
        now=lambda: float(next(clock)),
    )
    frames = results(5 * 3)  # one leg's frames, its rolling counter going up by one each
    for _ in range(4):  # not started: nothing takes from the queue
        recorder.submit(RecordBatch.of(itertools.islice(frames, 3), signals=False))
    assert recorder.dropped == 2 * 3
    with recorder:  # opens its file at clock 1
        wait_drained(recorder)
        recorder.submit(RecordBatch.of(frames, signals=False))
        wait_drained(recorder)
    return recorder


def test_what_a_full_queue_dropped_is_a_gap_in_the_file_in_a_thread_too(tmp_path: Path) -> None:
    recorder = recorded_with_a_full_queue(tmp_path)
    with open(recorder.paths[0], "rb") as file:
        written = [
            (c.topic, json.loads(m.data) if c.topic == "/daq/recording" else None)
            for _, c, m in make_reader(file).iter_messages(log_time_order=False)
        ]
    gaps = [payload for topic, payload in written if topic == "/daq/recording"]
    # since the first drop (clock 0, before the start) until the next item, put after it
    assert [(gap["stopped_t"], gap["dropped"], gap["reason"]) for gap in gaps] == [
        (0.0, 6, "recorder's queue full")
    ]
    assert gaps[0]["t"] == gaps[0]["lost_s"] > 1.0
    assert [topic for topic, _ in written].index("/daq/recording") == 2 * 2
    assert (
        recorder.gaps == [(0.0, gaps[0]["lost_s"])] and len(raw_times(recorder.paths[0])) == 3 * 3
    )


def test_a_gap_restarts_the_rolling_counters_in_replay_and_report_and_is_said(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """The frames the recorder dropped were counted as lost on the bus by the counters'
    jump (live saw them all: none lost), and replay said nothing of the gap."""
    path = recorded_with_a_full_queue(tmp_path).paths[0]
    report = load_recording(path)
    assert report.counts.frames == 9 and report.counts.frames_lost == 0 and report.counts.bad == {}
    assert report.counts.recording_gaps == 1
    caplog.set_level(logging.WARNING, logger="daq.replay")
    with_gap = io.StringIO()
    assert replay([path], with_gap) == 9
    said = f"{path}: {report.counts.recording_lost_s:.1f} s not recorded (recorder's queue full: 6"
    assert said in caplog.text
    assert ",counter" not in with_gap.getvalue()  # no estimate invalid for its counter


@pytest.mark.parametrize("kind", [Recorder, RecorderProcess])
def test_a_directory_it_cannot_create_names_the_key(
    tmp_path: Path, kind: type[Recorder] | type[RecorderProcess]
) -> None:
    _, database = example_machine()
    (tmp_path / "file").write_text("")
    directory = tmp_path / "file" / "rec"
    with pytest.raises(RecordingError) as raised:
        kind(RecordingSettings(directory=directory), database, machine_id="m").start()
    assert (
        str(raised.value)
        == f"{directory}: cannot create it ([recording] directory): Not a directory"
    )


@pytest.mark.parametrize("code", [errno.EROFS, errno.EACCES, errno.EPERM])
def test_a_directory_it_may_not_create_says_where_the_unit_lets_it_write(code: int) -> None:
    # Under the systemd unit (ProtectSystem=strict) a directory outside /var/lib/portal-daq
    # is read-only: the service said '/data/rec: cannot create it: Read-only file system'.
    reason = cannot_create(OSError(code, os.strerror(code)))
    assert reason.startswith(f"cannot create it ([recording] directory): {os.strerror(code)} (")
    assert "only /var/lib/portal-daq is writable" in reason and "ReadWritePaths=" in reason
    assert "systemd" not in cannot_create(OSError(errno.ENOTDIR, "Not a directory"))
