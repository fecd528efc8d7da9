"""Crash-cut recordings: SIGKILL the service; `recover` and the restart complete the file.

SIGKILL of the service's main process alone leaves the recorder's process, which finishes
the file; SIGKILL of the whole group (systemd's last resort after TimeoutStopSec) cuts it.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import zenoh
from mcap.exceptions import McapError
from mcap.reader import make_reader

from daq.cli import main
from daq.mcap_reading import RecordedMessage, RecordingStream
from daq.recorder import Recorder
from daq.recover import is_cut_short
from daq.service_config import RecordingSettings
from tests.daq.service_support import WAIT_S, free_port, peer_config, write_service_config
from tests.helpers import ROOT, example_machine

SAMPLES = 200


def truth(i: int) -> bytes:
    sample = {"t_unix_s": 1_750_000_000.0 + 0.01 * i, "legs": {"SB1_F1": {"force_true_N": i}}}
    return json.dumps(sample).encode()


def truth_in(path: Path) -> list[int]:
    with open(path, "rb") as file:
        return [
            json.loads(record.data)["legs"]["SB1_F1"]["force_true_N"]
            for record in RecordingStream(file)
            if isinstance(record, RecordedMessage) and record.topic == "/sim/truth"
        ]


def start_service(config: Path) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "daq", "--config", str(config)],
        cwd=ROOT,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # a process group of its own: the service and its recorder
    )


def record_truth_then_kill(tmp_path: Path, *, group: bool) -> tuple[Path, Path]:
    """Run the service until SAMPLES truth samples are on disk, then SIGKILL its main
    process (``group``: and its recorder's process); the config and the file."""
    port = free_port()
    rec = tmp_path / "rec"
    config = write_service_config(
        tmp_path, channel="recover-test", port=port, recording=rec, truth=True
    )
    process = start_service(config)
    try:
        with zenoh.open(peer_config(connect=f"tcp/127.0.0.1:{port}")) as session:
            deadline = time.monotonic() + WAIT_S
            while not list(rec.glob("*.mcap")) or not session.info.peers_zid():
                assert time.monotonic() < deadline and process.poll() is None
                time.sleep(0.05)
            (cut,) = rec.glob("*.mcap")
            publisher = session.declare_publisher(
                "portal/pam-proto-1/sim/truth", congestion_control=zenoh.CongestionControl.BLOCK
            )
            # The file exists once the recorder's process opened it, a moment before the
            # service subscribes to the truth: put once somebody listens.
            while not publisher.matching_status.matching:
                assert time.monotonic() < deadline and process.poll() is None
                time.sleep(0.05)
            for i in range(SAMPLES):
                publisher.put(truth(i))
            # Wait until all of them are on disk (the chunk is written every 0.2 s).
            while truth_in(cut) != list(range(SAMPLES)):
                assert time.monotonic() < deadline, truth_in(cut)
                time.sleep(0.05)
        if group:
            os.killpg(process.pid, signal.SIGKILL)
        else:
            process.send_signal(signal.SIGKILL)
        process.wait(timeout=WAIT_S)
    finally:
        if process.poll() is None:
            process.kill()
        process.communicate()
    return config, cut


def test_recorder_process_finishes_the_file_when_the_service_is_sigkilled(
    tmp_path: Path,
) -> None:
    _, path = record_truth_then_kill(tmp_path, group=False)
    deadline = time.monotonic() + WAIT_S
    while is_cut_short(path):  # the recorder's process notices within 0.25 s
        assert time.monotonic() < deadline, "the recorder's process did not finish the file"
        time.sleep(0.05)
    with open(path, "rb") as file:
        assert make_reader(file).get_summary() is not None
    assert truth_in(path) == list(range(SAMPLES))


def test_sigkilled_recording_is_recovered_by_the_cli_and_at_restart(tmp_path: Path) -> None:
    config, cut = record_truth_then_kill(tmp_path, group=True)
    rec = cut.parent
    assert is_cut_short(cut)
    with open(cut, "rb") as file, pytest.raises(McapError):
        list(make_reader(file).iter_messages())

    out = tmp_path / "recovered.mcap"
    result = subprocess.run(
        [sys.executable, "-m", "daq", "recover", str(cut), "-o", str(out)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 3, result.stderr  # the end was cut: reported as a loss
    assert "stopped at the cut" in result.stderr and "Traceback" not in result.stderr
    with open(out, "rb") as file:
        reader = make_reader(file)
        assert reader.get_summary() is not None
        forces = [
            json.loads(message.data)["legs"]["SB1_F1"]["force_true_N"]
            for _, channel, message in reader.iter_messages(topics=["/sim/truth"])
        ]
        names = {attachment.name for attachment in reader.iter_attachments()}
    assert forces == list(range(SAMPLES))
    assert names == {"portal-daq.toml", "portal_sensors.dbc"}
    assert not is_cut_short(out) and is_cut_short(cut)

    # The service completes the cut file in place when it starts again.
    process = start_service(config)
    try:
        deadline = time.monotonic() + WAIT_S
        while len(list(rec.glob("*.mcap"))) < 2:
            assert time.monotonic() < deadline and process.poll() is None
            time.sleep(0.05)
        process.send_signal(signal.SIGTERM)
        assert process.wait(timeout=WAIT_S) == 0
    finally:
        if process.poll() is None:
            process.kill()
        stderr = process.communicate()[1]
    assert not is_cut_short(cut) and f"recovered {cut}" in stderr
    with open(cut, "rb") as file:
        reader = make_reader(file)
        messages = list(reader.iter_messages(topics=["/sim/truth"]))
        assert len(messages) == SAMPLES and len(list(reader.iter_attachments())) == 2


def _chunks(data: bytes) -> list[tuple[int, int]]:
    """(offset, length) of each chunk record of an MCAP file (opcode 0x06)."""
    import struct

    found, at = [], 8
    while data[at] != 0x02:  # up to the footer
        length = struct.unpack_from("<Q", data, at + 1)[0]
        if data[at] == 0x06:
            found.append((at, length))
        at += 9 + length
    return found


def test_a_damaged_chunk_costs_its_own_messages_only(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A flipped bit on the storage in the first chunk (which holds the channels) and in
    one in the middle: reading stopped at the first one, so replay, report and export
    saw nothing of the file and `recover` in place threw away all that came after it."""
    from daq.cli import main
    from tests.daq.test_report_recordings import record
    from tests.helpers import recorded_raw_frames

    whole = record(tmp_path / "whole.mcap", seconds=3.0, chunk_size=16 * 1024)
    data = bytearray(whole.read_bytes())
    chunks = _chunks(bytes(data))
    assert len(chunks) > 6
    for at, length in (chunks[0], chunks[len(chunks) // 2]):
        data[at + 9 + length - 40] ^= 0xFF  # inside the compressed records
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(bytes(data))
    frames = recorded_raw_frames(whole)
    left = recorded_raw_frames(damaged)
    assert len(frames) * 0.6 < len(left) < len(frames)
    assert set(left) < set(frames) and left == sorted(left, key=frames.index)
    assert main(["recover", str(damaged)]) == 3
    err = capsys.readouterr().err
    assert "damaged chunk skipped" in err and err.rstrip().endswith("2 damaged chunks skipped")
    with open(damaged, "rb") as file:  # now whole: indexes and summary
        summary = make_reader(file).get_summary()
        assert summary is not None and summary.statistics is not None
        assert summary.statistics.message_count > 0
    assert recorded_raw_frames(damaged) == left


def test_what_out_named_before_is_never_removed(tmp_path: Path) -> None:
    """``recover NOT_MCAP -o /dev/null`` removed /dev/null (a failed recovery unlinked its
    output), and ``-o FILE`` left the user's file emptied: a failed recovery leaves what
    was there as it was. A named pipe stands in for /dev/null, which a regression must not
    break on the test machine."""
    import stat
    import threading

    from daq.errors import RecordingError
    from daq.recover import recover_file

    not_mcap = tmp_path / "notes.txt"
    not_mcap.write_text("not a recording\n")
    pipe = tmp_path / "sink"
    os.mkfifo(pipe)
    drained = threading.Thread(target=pipe.read_bytes, daemon=True)
    drained.start()
    with pytest.raises(RecordingError, match="notes.txt"):
        recover_file(not_mcap, pipe)
    drained.join(timeout=WAIT_S)
    assert stat.S_ISFIFO(pipe.stat().st_mode)
    fresh = tmp_path / "out.mcap"
    with pytest.raises(RecordingError):
        recover_file(not_mcap, fresh)
    assert not fresh.exists()  # what it made, it removes
    earlier = tmp_path / "earlier.mcap"
    earlier.write_bytes(b"the user's file")
    with pytest.raises(RecordingError):
        recover_file(not_mcap, earlier)
    assert earlier.read_bytes() == b"the user's file"  # was left emptied
    assert sorted(p.name for p in tmp_path.iterdir()) == ["earlier.mcap", "notes.txt", "sink"]


def test_an_output_that_cannot_be_written_is_named_as_given(tmp_path: Path) -> None:
    """``recover CUT.mcap -o nowhere/out.mcap`` named ``nowhere/.out.mcap.part``, a file
    the user never heard of; a missing input is still named as the input."""
    from daq.errors import RecordingError
    from daq.recover import recover_file

    cut = tmp_path / "cut.mcap"
    cut.write_bytes(b"\x89MCAP0\r\n")
    out = tmp_path / "nowhere" / "out.mcap"
    with pytest.raises(RecordingError) as raised:
        recover_file(cut, out)
    assert str(raised.value) == f"{out}: cannot recover: No such file or directory"
    with pytest.raises(RecordingError) as raised:
        recover_file(tmp_path / "gone.mcap", out)
    assert (
        str(raised.value) == f"{tmp_path / 'gone.mcap'}: cannot recover: No such file or directory"
    )


@pytest.mark.parametrize("content", [b"", b"\x89MCAP0\r\n", b"\x89MCAP0\r\n\x01\x19\x00"])
def test_a_file_that_holds_no_record_is_refused_as_it_is(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: bytes
) -> None:
    """A file the recorder had just opened (0 bytes, or cut in its header) was rewritten
    as an empty MCAP file of 303 bytes, exit 3 ('recovered 0 messages'): nothing was
    there to recover, and the evidence of what the file was went."""
    from daq.cli import main

    cut = tmp_path / "pam_20261202T113100Z.mcap"
    cut.write_bytes(content)
    assert main(["recover", str(cut)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"portal-daq: {cut}: holds no MCAP record ("), err
    assert err[0].endswith("nothing to recover"), err
    assert cut.read_bytes() == content
    assert [p.name for p in tmp_path.iterdir()] == [cut.name]


def test_every_cut_file_of_the_machine_is_recovered_at_start_not_the_newest_name_only(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A machine without a real-time clock starts in 1970 until NTP sets it: a power cut
    before the clock was set left a cut file named before the complete files of earlier
    days, and the start recovered only the newest by name. A file the recorder had just
    opened (0 bytes) is removed; another machine's files are left alone."""
    import io

    from mcap.writer import Writer

    from daq.recover import hold_while_writing, recover_cut_files

    def mcap_bytes() -> bytes:
        buffer = io.BytesIO()
        writer = Writer(buffer, chunk_size=256)
        writer.start()
        schema = writer.register_schema("s", "jsonschema", b"{}")
        channel = writer.register_channel("/t", "json", schema)
        for k in range(200):
            writer.add_message(channel, log_time=k, data=b'{"k": %d}' % k, publish_time=k)
        writer.finish()  # type: ignore[no-untyped-call]
        return buffer.getvalue()

    whole = mcap_bytes()
    complete = tmp_path / "pam_20261201T100000.000Z.mcap"
    complete.write_bytes(whole)
    cut = tmp_path / "pam_19700101T000012.000Z.mcap"
    cut.write_bytes(whole[: len(whole) // 2])
    opened = tmp_path / "pam_19700101T004512.000Z.mcap"
    opened.write_bytes(b"")
    foreign = tmp_path / "other_19700101T000001.000Z.mcap"
    foreign.write_bytes(whole[: len(whole) // 2])
    writing = tmp_path / "pam_19700101T004513.000Z.mcap"  # another service's, just opened
    with open(writing, "wb") as held:
        hold_while_writing(held, writing)
        recover_cut_files(tmp_path, "pam")
    assert writing.exists()
    assert not is_cut_short(cut) and complete.read_bytes() == whole
    with open(cut, "rb") as stream:
        assert 0 < len(list(make_reader(stream).iter_messages())) < 200
    assert not opened.exists() and foreign.read_bytes() == whole[: len(whole) // 2]
    assert f"recovered {cut} (cut short by a crash)" in caplog.text
    assert f"removed {opened}: it holds no MCAP record" in caplog.text


def test_a_file_a_running_service_writes_is_not_recovered_in_place(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # Replay and report warn that the file being written "ends without its summary"; a
    # recover in place then replaced it with a copy, and everything the service wrote
    # after went into the old file, unlinked: lost, while /status said healthy.
    _, database = example_machine()
    settings = RecordingSettings(directory=tmp_path / "rec", flush_period_s=0.1)
    with Recorder(settings, database, machine_id="m") as recorder:
        (live,) = recorder.paths
        assert is_cut_short(live)
        assert main(["recover", str(live)]) == 1
        (line,) = capsys.readouterr().err.strip().splitlines()
        assert line.startswith(f"portal-daq: {live}: a running service is writing it"), line
        assert main(["recover", str(live), "-o", str(tmp_path / "copy.mcap")]) == 3
        inode = live.stat().st_ino
    assert live.stat().st_ino == inode and not is_cut_short(live)  # finished, in place
    assert main(["recover", str(live)]) == 0  # its writer gone, it may be
