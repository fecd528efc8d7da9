"""portal-daq export: the raw frames of a recording through python-can's log writers,
read back with python-can's reader into the same frames."""

import subprocess
import sys
from collections.abc import Iterator
from datetime import datetime
from pathlib import Path

import can
import pytest

from daq.cli import main
from daq.errors import RecordingError
from daq.export import FORMATS, export, write_frames
from daq.frames import RawFrame
from daq.mcap_file import McapFile, RecordBatch
from tests.helpers import ROOT, example_machine

T0_S = 1_750_000_000.0
FRAMES = [
    RawFrame(T0_S + 0.001, 0x100, False, bytes(range(8))),
    RawFrame(T0_S + 0.002, 0x18FEF100, True, b"\x01\x02\x03"),
    RawFrame(T0_S + 0.003, 0x7AB, False, b"", is_remote_frame=True),
    RawFrame(T0_S + 0.004, 0x123, False, bytes(range(12)), is_fd=True),
    RawFrame(T0_S + 0.005, 0x100, False, bytes(8)),
]


def recording(path: Path) -> Path:
    _, database = example_machine()
    with open(path, "wb") as stream, McapFile(stream, database) as mcap:
        mcap.start()
        mcap.write_batch(RecordBatch(FRAMES[:2], []))
        mcap.write_batch(RecordBatch(FRAMES[2:], []))
    return path


@pytest.mark.parametrize("fmt", sorted(FORMATS))
def test_exported_frames_read_back_the_same(tmp_path: Path, fmt: str) -> None:
    source = recording(tmp_path / "rec.mcap")
    out = tmp_path / f"out{FORMATS[fmt][1]}"
    assert export([source], out, fmt) == len(FRAMES)
    with can.LogReader(out) as reader:
        back = list(reader)
    assert [(m.arbitration_id, m.is_extended_id, m.is_remote_frame, m.is_fd) for m in back] == [
        (f.arbitration_id, f.is_extended_id, f.is_remote_frame, f.is_fd) for f in FRAMES
    ]
    assert [bytes(m.data) for m in back if not m.is_remote_frame] == [
        f.data for f in FRAMES if not f.is_remote_frame
    ]
    times = [m.timestamp - back[0].timestamp for m in back]
    assert times == pytest.approx([f.t_s - FRAMES[0].t_s for f in FRAMES], abs=1e-5)


def run_export(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "daq", "export", *args],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=cwd,
    )


def test_the_command_line(tmp_path: Path) -> None:
    source = recording(tmp_path / "rec.mcap")
    done = run_export(str(source), "--to", "candump")
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == f"{tmp_path / 'rec.log'}: {len(FRAMES)} frames"
    assert (tmp_path / "rec.log").read_text().count(" can0 ") == len(FRAMES)
    missing = run_export(str(tmp_path / "no.mcap"), "--to", "asc")
    assert missing.returncode == 1 and missing.stderr.count("\n") == 1
    assert missing.stderr.startswith("portal-daq: ")


def test_the_help_says_where_the_log_goes_for_a_directory(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--help`` said "default: beside the recording"; of a run's directory the log is
    written inside it (``rec/rec.asc``), where a user following the help did not look."""
    run = tmp_path / "rec"
    run.mkdir()
    recording(run / "a.mcap")
    assert main(["export", str(run), "--to", "asc"]) == 0
    assert capsys.readouterr().out == f"{run / 'rec.asc'}: {len(FRAMES)} frames\n"
    with pytest.raises(SystemExit):
        main(["export", "--help"])
    assert "a directory's name, inside the directory" in " ".join(capsys.readouterr().out.split())


def test_an_output_that_names_the_recording_is_refused(tmp_path: Path) -> None:
    """``export REC.mcap --out REC.mcap`` emptied the recording (the writer opened it
    before it was read) and said ``0 frames``, exit 0."""
    source = recording(tmp_path / "rec.mcap")
    before = source.read_bytes()
    with pytest.raises(RecordingError, match="--out names .*rec.mcap, which this reads"):
        export([tmp_path], source, "candump")
    assert source.read_bytes() == before


def test_an_export_that_fails_leaves_the_earlier_file(tmp_path: Path) -> None:
    """The writer wrote into the output as it went: a recording unreadable half way left
    an earlier export of that name emptied or cut."""
    out = tmp_path / "rec.log"
    out.write_text("earlier\n")

    def failing() -> Iterator[RawFrame]:
        yield FRAMES[0]
        raise RecordingError(tmp_path / "rec.mcap", "unreadable")

    with pytest.raises(RecordingError, match="unreadable"):
        write_frames(failing(), out, "candump")
    assert out.read_text() == "earlier\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec.log"]
    assert write_frames(FRAMES, out, "candump") == len(FRAMES)
    assert out.read_text().count(" can0 ") == len(FRAMES)


def test_outputs_of_a_directory_given_as_dot_are_named_after_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Run in a run's directory, ``export . --to asc`` wrote a hidden ``./.asc`` and
    ``report .`` (also ``--campaign``) stopped with a ValueError traceback ('.' has an
    empty name): the default outputs are named after the directory '.' stands for."""
    from daq.report.command import ReportOptions

    run = tmp_path / "run1"
    run.mkdir()
    recording(run / "rec.mcap")
    done = run_export(".", "--to", "asc", cwd=run)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == f"{run / 'run1.asc'}: {len(FRAMES)} frames"
    assert sorted(p.name for p in run.iterdir()) == ["rec.mcap", "run1.asc"]
    monkeypatch.chdir(run)
    assert ReportOptions(Path(".")).directory == tmp_path / "run1_report"
    assert ReportOptions((Path("."),), campaign=True).directory == tmp_path / "run1_campaign"
    assert ReportOptions(Path("..")).directory == tmp_path.parent / f"{tmp_path.name}_report"


def test_frames_the_recording_says_were_lost_are_said_by_the_export(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A CAN log has no place for the recording's loss events (``/daq/bus``): the export
    said only ``N frames``, and a replay of the log no longer told the 37 frames the
    kernel dropped, which the recording's own replay counts."""
    from daq.frames import BusEvent

    _, database = example_machine()
    source = tmp_path / "rec.mcap"
    with open(source, "wb") as stream, McapFile(stream, database) as mcap:
        mcap.start()
        mcap.write_batch(RecordBatch(FRAMES[:2], []))
        mcap.write_event(BusEvent(T0_S + 0.0025, "up", "", kernel_dropped=37, rx_dropped=2))
        mcap.write_batch(RecordBatch(FRAMES[2:], []))
    with caplog.at_level("WARNING", logger="daq.export"):
        assert export([source], tmp_path / "rec.log", "candump") == len(FRAMES)
    assert caplog.messages == [
        "39 frames lost before they were recorded or logged, not in rec.log, a CAN log: "
        "only rec.mcap counts them (37 by the kernel: receive buffer full; 2 by the "
        "service's queue)"
    ]
    caplog.clear()
    with caplog.at_level("WARNING", logger="daq.export"):
        export([recording(tmp_path / "whole.mcap")], tmp_path / "whole.log", "candump")
    assert caplog.messages == []


@pytest.mark.parametrize("fmt", ["asc", "blf"])
def test_frames_after_a_clock_step_back_keep_their_times(tmp_path: Path, fmt: str) -> None:
    """ASC and BLF store offsets from the log's start, which python-can took from the
    first frame: after NTP stepped the clock back an hour, ASC wrote the later frames
    with their Unix time as the offset (read back 56 years late) and BLF at offset 0
    (every one at the first frame's time)."""
    stepped = [
        RawFrame(T0_S + 0.0123, 0x100, False, bytes(8)),
        RawFrame(T0_S + 0.0223, 0x101, False, bytes(8)),
        RawFrame(T0_S - 3600.0 + 0.0323, 0x100, False, bytes(8)),
        RawFrame(T0_S - 3600.0 + 0.0423, 0x101, False, bytes(8)),
    ]
    _, database = example_machine()
    source = tmp_path / "rec.mcap"
    with open(source, "wb") as stream, McapFile(stream, database) as mcap:
        mcap.start()
        mcap.write_batch(RecordBatch(stepped, []))
    out = tmp_path / f"out{FORMATS[fmt][1]}"
    assert export([source], out, fmt) == len(stepped)
    with can.LogReader(out) as reader:
        back = [m.timestamp for m in reader]
    earliest_s = min(f.t_s for f in stepped)
    assert [t - min(back) for t in back] == pytest.approx(
        [f.t_s - earliest_s for f in stepped], abs=2e-6
    )
    if fmt == "asc":  # its date is the log's start (it was the time of the export)
        absolute = [m.timestamp for m in can.ASCReader(out, relative_timestamp=False)]
        assert absolute == pytest.approx([f.t_s for f in stepped], abs=2e-6)
        lines = out.read_text().splitlines()
        start = datetime.fromtimestamp(earliest_s).strftime("%a %b %d %H:%M:%S.%f")[:-3]
        assert lines[0] == f"date {start} {datetime.fromtimestamp(earliest_s).year}"
        assert lines[3] == f"Begin Triggerblock {lines[0].removeprefix('date ')}"
