"""The recorder on a full disk (a 64 KiB tmpfs) or without its directory: one log line, no
empty files, the gap recorded, every item lost counted."""

from __future__ import annotations

import errno
import io
import json
import logging
import shutil
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from mcap.reader import make_reader

import daq.recorder
from daq.mcap_file import RecordBatch
from daq.recorder import Recorder
from daq.replay import replay
from daq.report.loading import load_recording
from daq.runner import recording_attachments
from daq.service_config import RecordingSettings, load_service_config
from tests.daq.service_support import free_port, write_service_config
from tests.daq.test_recording import results, wait_drained
from tests.helpers import example_machine, recorded_raw_frames

WAIT_S = 20.0


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    """A 64 KiB tmpfs (needs root, as in the test container and UML guest)."""
    disk = tmp_path / "disk"
    disk.mkdir()
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(disk)], capture_output=True
    )
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs: {mounted.stderr.decode().strip()}")
    try:
        yield disk
    finally:
        subprocess.run(["umount", "-l", str(disk)], check=True)


def fill(disk: Path) -> Path:
    """Fill ``disk`` up to the last byte with one file; returns it."""
    filler = disk / "filler"
    with open(filler, "wb", buffering=0) as file:
        try:
            while True:
                file.write(b"\0" * 1024)
        except OSError as exc:
            assert exc.errno == errno.ENOSPC
        try:
            while True:
                file.write(b"\0")
        except OSError:
            pass
    return filler


def recorder_on(disk: Path, tmp_path: Path, flush_period_s: float = 0.02) -> Recorder:
    config, database = example_machine()
    path = write_service_config(tmp_path, port=free_port())
    settings = RecordingSettings(directory=disk, chunk_size=4096, flush_period_s=flush_period_s)
    return Recorder(
        settings,
        database,
        machine_id=config.machine_id,
        attachments=recording_attachments(load_service_config(path)),
    )


def wait_until(condition, recorder: Recorder, feed: Iterator) -> int:  # type: ignore[no-untyped-def]
    """Keep submitting results until ``condition()`` holds (the recorder retries on items);
    how many were submitted."""
    deadline = time.monotonic() + WAIT_S
    submitted = 0
    while not condition():
        assert time.monotonic() < deadline, "condition not reached"
        recorder.submit(RecordBatch.of([next(feed)], signals=False))
        submitted += 1
        time.sleep(0.005)
    return submitted


def mcap_files(disk: Path) -> list[Path]:
    return sorted(disk.glob("*.mcap"))


def one_line_logs(caplog: pytest.LogCaptureFixture, text: str) -> list[str]:
    found = [r for r in caplog.records if text in r.getMessage()]
    assert all(r.exc_info is None and "\n" not in r.getMessage() for r in found)
    return [r.getMessage() for r in found]


@pytest.fixture(autouse=True)
def quick_retry(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(daq.recorder, "RETRY_AFTER_S", 0.05)


def test_disk_full_while_running_stops_and_resumes_with_the_gap_recorded(
    small_disk: Path, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.INFO, logger="daq.recorder")
    feed = results(100_000, t0=1_750_000_000.0)
    recorder = recorder_on(small_disk, tmp_path)
    with recorder:
        wait_until(lambda: recorder.current_bytes > 4096, recorder, feed)
        (first,) = mcap_files(small_disk)
        filler = fill(small_disk)
        wait_until(lambda: recorder.failing, recorder, feed)
        dropped_at_stop = recorder.dropped
        # Many retries while the disk stays full: no new (empty) file, items counted.
        wait_until(lambda: recorder.dropped > dropped_at_stop + 200, recorder, feed)
        assert mcap_files(small_disk) == [first] and recorder.errors >= 2
        filler.unlink()
        wait_until(lambda: not recorder.failing, recorder, feed)
        wait_until(lambda: recorder.current_bytes > 4096, recorder, feed)
    stopped = one_line_logs(caplog, "recording stopped")
    resumed = one_line_logs(caplog, "recording resumed")
    assert len(stopped) == 1 and "No space left on device" in stopped[0]
    assert f"recording stopped: {first}: No space left on device; " in stopped[0]
    assert len(resumed) == 1 and " s lost (" in resumed[0]
    first_again, second = mcap_files(small_disk)
    assert first_again == first and recorder.gaps and recorder.gaps[0][1] > 0
    with open(second, "rb") as file:
        reader = make_reader(file)
        messages = list(reader.iter_messages(log_time_order=False))
        assert {a.name for a in reader.iter_attachments()} >= {"portal-daq.toml"}
    _, channel, message = messages[0]
    gap = json.loads(message.data)
    assert channel.topic == "/daq/recording"
    assert gap["lost_s"] == pytest.approx(recorder.gaps[0][1])
    assert gap["dropped"] >= 200
    report = load_recording(second)
    assert report.counts.recording_gaps == 1
    assert report.counts.recording_lost_s == pytest.approx(gap["lost_s"])


def test_disk_full_at_start_leaves_no_file_and_recovers(
    small_disk: Path, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.INFO, logger="daq.recorder")
    filler = fill(small_disk)
    feed = results(100_000, t0=1_750_000_000.0)
    recorder = recorder_on(small_disk, tmp_path)
    with recorder:  # starts: no exception, recording is "failing"
        assert recorder.failing and recorder.current_path is None
        wait_until(lambda: recorder.errors >= 5, recorder, feed)
        assert mcap_files(small_disk) == []
        filler.unlink()
        wait_until(lambda: recorder.current_path is not None, recorder, feed)
    assert len(one_line_logs(caplog, "recording stopped")) == 1
    (path,) = mcap_files(small_disk)
    with open(path, "rb") as file:
        assert make_reader(file).get_summary() is not None


def test_the_chunk_a_full_disk_cut_is_counted_as_dropped(
    small_disk: Path, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    # The messages of the chunk being written when the disk filled (up to chunk_size or
    # flush_period_s of frames) were lost from the file, which reads back to its last
    # complete chunk, and counted nowhere: /status said every other frame was recorded.
    # Chunks go out when full (4 KiB), never by time: the disk fills under a chunk of
    # messages for certain.
    feed = results(100_000, t0=1_750_000_000.0)
    recorder = recorder_on(small_disk, tmp_path, flush_period_s=3600.0)
    with recorder:
        filler = fill(small_disk)
        submitted = wait_until(lambda: recorder.failing, recorder, feed)
        filler.unlink()
        submitted += wait_until(lambda: not recorder.failing, recorder, feed)
        wait_drained(recorder)
    recorded = sum(len(recorded_raw_frames(path)) for path in mcap_files(small_disk))
    (stopped,) = one_line_logs(caplog, "recording stopped")
    lost = int(stopped.split("; ")[1].split()[0])  # "; 17 items lost from the file; ..."
    assert lost > 0 and recorded + recorder.dropped == submitted
    # What was recorded, the cut file's complete chunks too, is replayed as one run.
    out = io.StringIO()
    assert replay([small_disk], out) == recorded


def test_a_recording_directory_removed_while_recording_is_counted_and_made_again(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    # A cleanup that removed the recording directory unlinked the file being written: the
    # recorder wrote on into it, lost, until the file rotated (an hour, by default) while
    # /status said healthy; and the retries never found the directory again.
    directory = tmp_path / "rec"
    feed = results(100_000, t0=1_750_000_000.0)
    recorder = recorder_on(directory, tmp_path)
    with recorder:
        submitted = wait_until(lambda: recorder.current_bytes > 20_000, recorder, feed)
        shutil.rmtree(directory)
        submitted += wait_until(lambda: recorder.failing, recorder, feed)
        submitted += wait_until(lambda: not recorder.failing, recorder, feed)
        wait_drained(recorder)
    (path,) = mcap_files(directory)  # the directory made again, the file resumed in
    recorded = len(recorded_raw_frames(path))
    assert recorded > 0 and recorded + recorder.dropped == submitted
    (stopped,) = one_line_logs(caplog, "recording stopped")
    assert f"{recorder.paths[0]}: deleted while it was being written; " in stopped
