"""Campaign reports: many recordings, one table, computed locally or on a Dask cluster.

The recordings are generated here (:func:`tests.daq.test_report_recordings.record`:
the simulator's playout of a short synthetic cycle through the service's pipeline into
MCAP), different in length, faults and machine state, one of them a run rotated into
two files. The rows are checked against the single report's metrics and a brute-force
weight residual; the same rows come from one process, local processes and a Dask
``LocalCluster`` of two worker processes.
"""

from __future__ import annotations

import csv
import logging
import math
import shutil
import subprocess
import sys
from collections.abc import Callable
from dataclasses import astuple, replace
from pathlib import Path

import numpy as np
import pytest

from daq.errors import RecordingError
from daq.recording_run import run_files, run_metadata, runs
from daq.report.campaign import COLUMNS, CampaignRow, campaign_rows, weight_residuals_N
from daq.report.campaign_run import campaign
from daq.report.content import analyse
from daq.report.loading import load_recording
from sim_bridge.faults import FaultConfig
from tests.daq.test_report_recordings import CYCLE_S, FAULTS, T0_S, record
from tests.helpers import LEGS, ROOT

ROTATE_S = 2.505  # between two 10 ms instants


@pytest.fixture(scope="module")
def recordings(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A campaign directory: four runs, one of them rotated into two files."""
    folder = tmp_path_factory.mktemp("campaign")
    record(folder / "a_plain.mcap", seconds=5.0)
    record(folder / "b_faults.mcap", seconds=4.5, faults=FAULTS)
    record(folder / "c_no_state.mcap", seconds=3.0, machine_state=False)
    noisy = FaultConfig(bad_crc_probability=0.05, seed=3)
    record(folder / "d_run_1.mcap", seconds=ROTATE_S, faults=noisy, run=run_metadata("m", "r", 0))
    record(
        folder / "d_run_2.mcap",
        seconds=5.0,
        faults=noisy,
        run=run_metadata("m", "r", 1),
        after_s=ROTATE_S,
    )
    record(folder / "whole_run.tmp", seconds=5.0, faults=noisy)  # d_run as one file
    return folder


def same(a: list[CampaignRow], b: list[CampaignRow]) -> bool:
    """Equal, NaN equal to NaN (rows of independent runs are compared bit for bit)."""
    return [_key(row) for row in a] == [_key(row) for row in b]


def _key(row: CampaignRow) -> tuple[object, ...]:
    return tuple("nan" if isinstance(v, float) and math.isnan(v) else v for v in astuple(row))


def test_the_runs_of_a_campaign_directory(recordings: Path) -> None:
    found = runs([recordings])
    assert [[p.name for p in files] for _, files in found] == [
        ["a_plain.mcap"],
        ["b_faults.mcap"],
        ["c_no_state.mcap"],
        ["d_run_1.mcap", "d_run_2.mcap"],
    ]


def test_rows_per_recording_cycle_and_foot(recordings: Path) -> None:
    rows = campaign(runs([recordings]), workers=1)
    by_recording: dict[str, list[CampaignRow]] = {}
    for row in rows:
        by_recording.setdefault(row.recording, []).append(row)
    assert list(by_recording) == [
        "a_plain.mcap",
        "b_faults.mcap",
        "c_no_state.mcap",
        "d_run_1.mcap .. d_run_2.mcap (2 files)",
    ]
    # 5 s of a 2 s cycle: cycles 0, 1, 2 (the last one partial); every foot in each.
    plain = by_recording["a_plain.mcap"]
    assert [(r.cycle, r.leg) for r in plain] == [(c, leg) for c in (0, 1, 2) for leg in LEGS]
    assert {r.machine_id for r in rows} == {"pam-proto-1"}
    assert [r.cycle for r in by_recording["c_no_state.mcap"]] == [-1] * len(LEGS)
    assert all(r.invalid_fraction == 0.0 for r in plain)
    # 2 % bad CRC (and the counter fault each leaves behind): some invalid in every foot.
    faulty = by_recording["b_faults.mcap"]
    assert all(0.0 < r.invalid_fraction < 0.25 for r in faulty)
    assert all(r.pressure_limit_Pa == 200e3 for r in rows)

    # The single report's metrics, the same cycles and figures.
    content = analyse(load_recording(recordings / "a_plain.mcap"))
    assert [(m.cycle.start_s, m.leg) for m in content.metrics] == [
        (r.cycle_start_s, r.leg) for r in plain
    ]
    for row, entry in zip(plain, content.metrics, strict=True):
        assert row.peak_pressure_Pa == entry.metrics.peak_pressure_Pa
        assert row.time_above_limit_s == entry.metrics.time_above_limit_s
        assert math.isclose(row.cycle_duration_s, CYCLE_S, abs_tol=0.02) or row.cycle == 2

    # The weight residual, brute force: every 10 ms of cycle 1, each leg's estimate then.
    recording = load_recording(recordings / "a_plain.mcap")
    assert recording.machine is not None
    cycle = content.cycles[1]
    first = recording.legs[LEGS[0]]
    instants = first.t_s[cycle.contains(first.t_s)]
    expected = []
    for t_s in instants.tolist():
        total_N = 0.0
        for track in recording.legs.values():
            i = int(np.flatnonzero(track.t_s <= t_s)[-1])
            total_N += track.force_N[i] if track.contact[i] else 0.0
        expected.append(total_N - recording.machine.weight_N)
    residuals = weight_residuals_N(recording.legs, cycle, {}, recording.machine.weight_N)
    np.testing.assert_allclose(residuals, expected, rtol=0, atol=1e-6)
    row = next(r for r in plain if r.cycle == 1)
    assert row.weight_residual_median_N == float(np.median(expected))
    assert row.weight_residual_max_abs_N == float(np.max(np.abs(expected)))

    # The rotated run is one recording, equal to the same run recorded as one file.
    whole = campaign_rows(load_recording(recordings / "whole_run.tmp"))
    rotated = by_recording["d_run_1.mcap .. d_run_2.mcap (2 files)"]
    assert same(rotated, [replace(r, recording=rotated[0].recording) for r in whole])


def test_local_processes_and_a_dask_cluster_give_the_same_rows(recordings: Path) -> None:
    distributed = pytest.importorskip("distributed")
    found = runs([recordings])
    one = campaign(found, workers=1)
    local = campaign(found, workers=2)
    assert same(local, one)
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        remote = campaign(found, cluster=cluster.scheduler_address)
        workers = len(cluster.scheduler_info["workers"])
    assert workers == 2
    assert same(remote, one) and len(one) > 4 * len(LEGS)


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "daq", "report", *args],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=ROOT,
    )


def test_the_campaign_command_line(recordings: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    result = run_cli("--campaign", str(recordings), "--out", str(out), "--workers", "2")
    assert result.returncode == 0, result.stderr
    assert result.stdout == f"{out / 'campaign.html'}\n"
    with open(out / "campaign.csv", newline="") as table:
        lines = list(csv.reader(table))
    assert tuple(lines[0]) == COLUMNS
    expected = campaign(runs([recordings]), workers=1)
    assert len(lines) - 1 == len(expected)
    assert [float(v) for v in lines[1][6:8]] == [  # full precision
        expected[0].peak_pressure_Pa,
        expected[0].peak_t_s,
    ]
    page = (out / "campaign.html").read_text()
    assert "Campaign report: 4 recordings, 1 machines, 10 cycles" in page
    assert "d_run_1.mcap .. d_run_2.mcap (2 files)" in page
    assert 'src="data:image/png;base64,' in page
    assert (out / "campaign_peaks.png").read_bytes().startswith(b"\x89PNG")


@pytest.mark.parametrize(
    ("args", "status", "message"),
    [
        (["--cluster", "tcp://127.0.0.1:1"], 2, "--cluster and --workers go with --campaign"),
        (["--workers", "0"], 2, "--cluster and --workers go with --campaign"),
        (["--campaign", "--workers", "0"], 2, "--workers: must be >= 1, got 0"),
        (["--campaign", "--cluster", "tcp://x:1", "--workers", "2"], 2, "not with --cluster"),
    ],
)
def test_campaign_usage_errors(
    recordings: Path, args: list[str], status: int, message: str
) -> None:
    result = run_cli(str(recordings), *args)
    assert result.returncode == status
    assert message in result.stderr and "Traceback" not in result.stderr


@pytest.mark.parametrize(
    ("clock", "moved_s"),
    [
        # NTP steps a clock that ran 0.7 s ahead back, in the middle of cycle 1
        (lambda t_s: T0_S + t_s + (0.7 if t_s < 2.9 else 0.0), 0.0),
        # a machine without a real-time clock: 1970 (since boot) until NTP sets it
        (lambda t_s: 60.0 + t_s if t_s < 1.3 else T0_S + t_s, 0.0),
        # a clock 30 s behind, set forward at 1.3 s: a step forward is kept (a gap)
        (lambda t_s: T0_S + t_s - (30.0 if t_s < 1.3 else 0.0), 30.0),
    ],
    ids=["ntp_step_back", "set_from_1970", "step_forward"],
)
def test_a_clock_that_steps_gives_the_rows_of_a_steady_one(
    tmp_path: Path, clock: Callable[[float], float], moved_s: float
) -> None:
    """Sorted by time, a step back interleaved two stretches of the run: cycle 1 was cut
    into hundreds of 10 ms cycles with the wrong peaks and times above the limit; a clock
    set from 1970 made cycle 0 last 56 years. The stretches are joined in the order they
    were recorded (the recorded estimates, and a CAN log's recomputed ones)."""
    from daq.export import write_frames
    from tests.helpers import EXAMPLE_CONFIG, recorded_raw_frames

    steady = campaign_rows(load_recording(record(tmp_path / "steady.mcap", seconds=5.0)))
    stepped = record(tmp_path / "stepped.mcap", seconds=5.0, clock=clock)
    log = tmp_path / "stepped.log"
    write_frames(recorded_raw_frames(stepped), log, "candump")
    for recording in (load_recording(stepped), load_recording(log, EXAMPLE_CONFIG)):
        assert recording.counts.clock_steps == (0 if moved_s else 1)
        rows = campaign_rows(recording)
        assert [(r.cycle, r.leg, r.estimates) for r in rows] == [
            (r.cycle, r.leg, r.estimates) for r in steady
        ]
        for row, expected in zip(rows, steady, strict=True):
            assert row.peak_pressure_Pa == expected.peak_pressure_Pa
            assert row.invalid_fraction == expected.invalid_fraction
            # joined by one period: as steady; a step forward stays, a gap: it adds up to
            # the stale time (30 ms) above the limit where a period added 10 ms
            duration_s = expected.cycle_duration_s + (moved_s if row.cycle == 0 else 0.0)
            assert row.cycle_duration_s == pytest.approx(duration_s, abs=1e-6)
            tolerance_s = 0.021 if moved_s else 1e-6
            assert row.time_above_limit_s == pytest.approx(
                expected.time_above_limit_s, abs=tolerance_s
            )
        # the last stretch keeps its wall-clock times
        assert rows[-1].peak_t_s == pytest.approx(steady[-1].peak_t_s, abs=1e-6)


def test_frames_out_of_order_by_milliseconds_are_no_clock_steps(tmp_path: Path) -> None:
    """Frames of one log out of order by a few ms (two buses merged, a logger's buffers)
    were each joined as a clock step back: a 5 s run was reported as 1,000 steps and
    several times its length, its cycles cut apart."""
    from daq.export import write_frames
    from daq.frames import RawFrame
    from tests.helpers import EXAMPLE_CONFIG, recorded_raw_frames

    recording = record(tmp_path / "steady.mcap", seconds=5.0)
    steady = campaign_rows(load_recording(recording))
    frames = recorded_raw_frames(recording)
    jittered = [  # each frame 2 ms late or early by turns: out of order by up to 4 ms
        RawFrame(f.t_s + (0.002 if i % 2 else -0.002), f.arbitration_id, f.is_extended_id, f.data)
        for i, f in enumerate(frames)
    ]
    log = tmp_path / "jittered.log"
    write_frames(jittered, log, "candump")
    loaded = load_recording(log, EXAMPLE_CONFIG)
    assert loaded.counts.clock_steps == 0
    rows = campaign_rows(loaded)
    assert [(r.cycle, r.leg, r.estimates) for r in rows] == [
        (r.cycle, r.leg, r.estimates) for r in steady
    ]
    for row, expected in zip(rows, steady, strict=True):
        assert row.cycle_duration_s == pytest.approx(expected.cycle_duration_s, abs=0.005)


def test_a_recording_that_holds_nothing_is_left_out_of_the_campaign(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], caplog: pytest.LogCaptureFixture
) -> None:
    """A power cut just after the recorder opened a file leaves (once recovered at the
    next start) a whole file of header and attachments only; one such file among a
    season's stopped the campaign ("nothing to report", exit 1)."""
    from daq.mcap_file import CONFIG_ATTACHMENT, McapFile
    from daq.report.command import report_main
    from tests.helpers import EXAMPLE_CONFIG, example_machine

    season = tmp_path / "season"
    season.mkdir()
    record(season / "a_cycle.mcap", seconds=2.5)
    with (
        open(season / "b_empty.mcap", "wb") as stream,
        McapFile(stream, example_machine()[1]) as mcap,
    ):
        mcap.start({CONFIG_ATTACHMENT: EXAMPLE_CONFIG.read_bytes()}, run=run_metadata("m", "e", 0))
    out = tmp_path / "out"
    assert report_main(["--campaign", str(season), "--workers", "1", "--out", str(out)]) == 0
    with open(out / "campaign.csv") as table:
        assert {row["recording"] for row in csv.DictReader(table)} == {"a_cycle.mcap"}
    page = (out / "campaign.html").read_text()
    assert "Campaign report: 1 recordings" in page
    assert "1 more recordings hold nothing (no frame, no estimate): left out." in page
    assert "b_empty.mcap: holds no CAN frames" in caplog.text and "left out" in caplog.text
    (season / "a_cycle.mcap").unlink()
    assert report_main(["--campaign", str(season), "--workers", "1", "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == f"portal-daq: {season}: none of its 1 recordings holds data", err


def test_copies_and_files_given_twice_count_once(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A backup folder in the campaign's tree, a file named twice (by its directory and
    by itself, through a link): each recording counts once. A copy of a run with run
    metadata stopped everything ("two files claim one index"), one of a recording
    without it (an earlier release) doubled its rows, unsaid."""
    season = tmp_path / "season"
    backup = season / "backup"
    backup.mkdir(parents=True)
    run = record(season / "a_run.mcap", seconds=1.0, run=run_metadata("m", "r", 0))
    old = record(season / "b_old.mcap", seconds=1.5)  # no run metadata
    for original in (run, old):
        shutil.copyfile(original, backup / original.name)
    (tmp_path / "link.mcap").symlink_to(old)
    given = [season, backup, run.resolve(), tmp_path / "link.mcap"]
    with caplog.at_level(logging.WARNING, logger="daq.recording_run"):
        found = runs(given)
    assert [files for _, files in found] == [[run], [old]]
    copies = [r.getMessage() for r in caplog.records if "left out" in r.getMessage()]
    assert sorted(copies) == [
        f"{backup / name}: left out, a copy of {season / name} (the same bytes)"
        for name in ("a_run.mcap", "b_old.mcap")
    ]  # the same file given again (path, link) is no copy: not said
    assert run_files([backup / "a_run.mcap", run]) == [backup / "a_run.mcap"]  # a replay
    # Other bytes under the same run and index (a cut copy): which one is meant is unsaid.
    cut = backup / "a_run.mcap"
    cut.write_bytes(run.read_bytes()[: run.stat().st_size // 2])
    with pytest.raises(RecordingError) as error:
        runs([season, backup])
    assert str(error.value) == (
        f"{cut}: claims file 0 of the run as {run} does, with other bytes "
        "(a recovered copy of a cut file, say): give one of the two"
    )


def test_recordings_of_one_name_in_two_folders_are_two(tmp_path: Path) -> None:
    """Named by their file names alone, ``day1/recording.mcap`` and ``day2/recording.mcap``
    were one recording: the page said "1 recordings" and "1 more recordings hold nothing
    ...: left out", and the table could not tell their rows apart."""
    from daq.report.command import report_main

    for day, seconds in (("day1", 1.0), ("day2", 3.0)):
        (tmp_path / day).mkdir()
        record(tmp_path / day / "recording.mcap", seconds=seconds)
    out = tmp_path / "out"
    given = [str(tmp_path / "day1"), str(tmp_path / "day2")]
    assert report_main(["--campaign", *given, "--workers", "1", "--out", str(out)]) == 0
    with open(out / "campaign.csv") as table:
        rows = list(csv.DictReader(table))
    per_recording = {
        name: [r for r in rows if r["recording"] == name]
        for name in ("day1/recording.mcap", "day2/recording.mcap")
    }
    assert len(rows) == sum(len(found) for found in per_recording.values())
    assert [len(found) for found in per_recording.values()] == [6, 6 * 2]  # 1 and 2 cycles
    page = (out / "campaign.html").read_text()
    assert "Campaign report: 2 recordings" in page and "hold nothing" not in page


def test_a_campaign_directory_is_searched_below_its_top(tmp_path: Path) -> None:
    """A season kept in folders of days (and machines): the recordings below the
    directory given are the campaign's. Only its top was read: a tree of day folders was
    "no .mcap files in this directory" (exit 1), and one with a recording at its top was
    reported without its folders' recordings, unsaid."""
    from daq.report.command import report_main

    season = tmp_path / "season"
    (season / "day2" / "pam-2").mkdir(parents=True)
    (season / "day1").mkdir()
    record(season / "day1" / "a.mcap", seconds=1.0)
    record(season / "day2" / "pam-2" / "a.mcap", seconds=1.5)
    out = tmp_path / "out"
    assert report_main(["--campaign", str(season), "--workers", "1", "--out", str(out)]) == 0
    record(season / "top.mcap", seconds=2.0)  # other bytes than day1/a.mcap: no copy
    assert report_main(["--campaign", str(season), "--workers", "1", "--out", str(out)]) == 0
    with open(out / "campaign.csv") as table:
        names = list(dict.fromkeys(row["recording"] for row in csv.DictReader(table)))
    assert names == ["day1/a.mcap", "day2/pam-2/a.mcap", "top.mcap"]
    assert "Campaign report: 3 recordings" in (out / "campaign.html").read_text()
    # one run's directory (replay, report, export) is its own files only
    assert run_files([season]) == [season / "top.mcap"]


def test_a_recording_cut_short_is_flagged_in_the_table_and_on_the_page(tmp_path: Path) -> None:
    """A file a crash cut short is read up to its last complete chunk: its cycles are
    shorter and its peaks may be missing. The single report's header flags it; the
    campaign's page and table said nothing (a warning on stderr only)."""
    from daq.report.command import report_main

    season = tmp_path / "season"
    season.mkdir()
    whole = record(season / "a_whole.mcap", seconds=2.0)
    cut = record(tmp_path / "b_cut.mcap", seconds=5.0, chunk_size=64 * 1024)
    (season / "b_cut.mcap").write_bytes(cut.read_bytes()[: cut.stat().st_size // 2])
    out = tmp_path / "out"
    assert report_main(["--campaign", str(season), "--workers", "1", "--out", str(out)]) == 0
    with open(out / "campaign.csv") as table:
        flags = {row["recording"]: row["complete"] for row in csv.DictReader(table)}
    assert flags == {whole.name: "True", "b_cut.mcap": "False"}
    page = (out / "campaign.html").read_text()
    assert "b_cut.mcap (cut short: its end is missing)" in page
    assert "a_whole.mcap (cut" not in page
