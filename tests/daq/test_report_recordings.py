"""Reports of real MCAP recordings of different shapes, and the ``report`` command line.

The recordings are made here the fast way: the simulator bridge's playout of a short
synthetic cycle goes frame by frame through the service's :class:`Pipeline` into an
:class:`McapFile` (the live path, threads and Zenoh aside, which
``test_report_end_to_end.py`` covers), the truth written with the recorder's own
``write_truth``.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.writer import Writer

from daq.frames import RawFrame
from daq.mcap_file import CONFIG_ATTACHMENT, DBC_ATTACHMENT, McapFile
from daq.pipeline import Pipeline
from daq.report import ReportOptions, report
from daq.report.content import analyse
from daq.report.figures import png_bytes, time_series_figure
from daq.report.loading import load_recording
from dbc.errors import ConfigError
from sim_bridge.faults import FaultConfig, FaultWindow
from sim_bridge.schedule import instants, schedule
from sim_bridge.truth import truth_sample
from tests.helpers import EXAMPLE_CONFIG, LEGS, ROOT, example_machine
from tests.sim_bridge.synthetic import make_playout, make_result

T0_S = 1_750_000_000.0
CYCLE_S = 2.0  # the synthetic cycle
FAULTS = FaultConfig(
    bad_crc_probability=0.02,
    silent=(FaultWindow("SB1_F2", 0.5, 0.3),),  # 300 ms without frames: a gap
    seed=7,
)


def record(
    path: Path,
    *,
    seconds: float = 5.0,
    truth: bool = False,
    machine_state: bool = True,
    embed_config: bool = True,
    faults: FaultConfig | None = None,
    chunk_size: int = 1024 * 1024,
    run: dict[str, str] | None = None,
    after_s: float = 0.0,
    clock: Callable[[float], float] | None = None,
) -> Path:
    """A service recording of ``seconds`` of the synthetic cycle, looping; with ``run``
    metadata, and only the frames from ``after_s`` on (a later file of a run); ``clock``:
    the frame time of each time since the start (default ``T0_S`` + it)."""
    config, database = example_machine()
    result = make_result(duration_s=CYCLE_S)
    playout = make_playout(result, faults)
    pipeline = Pipeline.from_config(config, database)
    feet_m2 = {leg: config.legs[leg].geometry.A_foot_m2 for leg in LEGS}
    attachments = {
        CONFIG_ATTACHMENT: EXAMPLE_CONFIG.read_bytes(),
        DBC_ATTACHMENT: config.dbc_path.read_bytes(),
    }
    with open(path, "wb") as stream, McapFile(stream, database, chunk_size=chunk_size) as mcap:
        mcap.start(attachments if embed_config else {}, T0_S, run)
        last_row = None
        for instant in instants(schedule(playout.cycles, end_sim_ns=round(seconds * 1e9))):
            t_s = T0_S + instant.sim_t_ns / 1e9 if clock is None else clock(instant.sim_t_ns / 1e9)
            position, outgoing = playout.frames(instant)
            for item in outgoing:
                if item.message == "MACHINE_STATE" and not machine_state:
                    continue
                frame = RawFrame(t_s, item.frame.arbitration_id, False, item.frame.data)
                processed = pipeline.process(frame)  # before after_s: as in an earlier file
                if instant.sim_t_ns >= after_s * 1e9:
                    mcap.write_result(processed)
            if truth and (position.cycle, position.row) != last_row:
                last_row = (position.cycle, position.row)
                mcap.write_truth(truth_sample(result, position, t_s, feet_m2).as_json())
    return path


def strip(source: Path, target: Path, *, keep: tuple[str, ...], attachments: bool) -> Path:
    """A copy of ``source`` with only the topics starting with one of ``keep``."""
    with open(source, "rb") as file, open(target, "wb") as out:
        reader = make_reader(file)
        writer = Writer(out)
        writer.start()
        if attachments:
            for attachment in reader.iter_attachments():
                writer.add_attachment(
                    attachment.create_time, attachment.log_time, attachment.name,
                    attachment.media_type, attachment.data,
                )  # fmt: skip
        channels: dict[int, int] = {}
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            if not channel.topic.startswith(keep):
                continue
            if channel.id not in channels:
                schema_id = writer.register_schema(schema.name, schema.encoding, schema.data)  # type: ignore[union-attr]
                channels[channel.id] = writer.register_channel(
                    channel.topic, channel.message_encoding, schema_id
                )
            writer.add_message(
                channels[channel.id], message.log_time, message.data, message.log_time
            )
        writer.finish()
    return target


def test_a_recording_without_truth_gets_the_time_and_cycle_pictures(tmp_path: Path) -> None:
    path = record(tmp_path / "run.mcap", seconds=5.0, faults=FAULTS)
    written = report(ReportOptions(path, tmp_path / "out"))
    assert [p.name for p in written] == [
        "pressure.png",
        "force.png",
        "cycle_pressures.png",
        "report.html",
    ]
    page = (tmp_path / "out" / "report.html").read_text()
    assert "No simulation truth (/sim/truth) in this recording." in page
    assert "pam-proto-1" in page and "run.mcap" in page

    recording = load_recording(path)
    assert recording.machine_id == "pam-proto-1" and recording.machine is not None
    assert not recording.recomputed and recording.complete
    assert recording.counts.bad["crc"] > 0 and "stale" not in recording.counts.invalid
    assert recording.counts.invalid["crc"] > 0
    content = analyse(recording)
    # MACHINE_STATE's cycle count steps every 2 s: three cycles, the last one partial
    assert [(c.count, c.start_s - T0_S, c.end_s - T0_S) for c in content.cycles] == [
        (0, 0.0, pytest.approx(2.0)),
        (1, pytest.approx(2.0), pytest.approx(4.0)),
        (2, pytest.approx(4.0), pytest.approx(recording.duration_s)),
    ]
    # each cycle's peak is the highest valid recorded pressure within it (independently)
    for row in content.metrics:
        track = recording.legs[row.leg]
        inside = (track.t_s >= row.cycle.start_s) & (track.t_s <= row.cycle.end_s)
        if not row.cycle.final:
            inside &= track.t_s < row.cycle.end_s
        expected = np.max(track.pressure_Pa[inside & track.valid])
        assert row.metrics.peak_pressure_Pa == expected
        assert row.metrics.samples == np.count_nonzero(inside & track.valid)
        assert np.isnan(row.metrics.near_constant_pressure_Pa)  # cycles < 5 s
    # the silent window of SB1_F2 is a gap wider than the staleness time (30 ms)
    track = recording.legs["SB1_F2"]
    assert np.max(np.diff(track.t_s)) == pytest.approx(0.31)
    assert content.gap_after_s["SB1_F2"] == pytest.approx(0.03)


def test_without_machine_state_the_whole_recording_is_one_cycle(tmp_path: Path) -> None:
    path = record(tmp_path / "run.mcap", seconds=3.0, machine_state=False)
    content = analyse(load_recording(path))
    assert [c.label for c in content.cycles] == ["whole recording"]
    assert content.phases == []
    report(ReportOptions(path, tmp_path / "out"))
    assert "whole recording" in (tmp_path / "out" / "report.html").read_text()


def test_truth_in_the_recording_adds_the_comparison(tmp_path: Path) -> None:
    path = record(tmp_path / "run.mcap", seconds=2.0, truth=True)
    written = report(ReportOptions(path, tmp_path / "out"))
    assert {"truth_comparison.png", "truth_deviation.png"} <= {p.name for p in written}
    content = analyse(load_recording(path))
    # the synthetic truth is eq. (4) of the sent pressures: only the DBC's 1000 Pa
    # resolution (<= 4.2 N) and the median (its start-up, the sine's curvature) separate
    # them; the published values lag by 5 samples, which costs kN on this fast sine
    for leg, stats in content.deviations.items():
        assert stats.samples == 200 - 5, leg  # 200 frames, the last 5 without a centred median
        assert stats.abs50_N < 5.0 and stats.abs95_N < 100.0, leg
        assert stats.published_abs95_N > 2000.0, leg
    assert content.most_loaded == "SB2_F3"  # the synthetic pressures grow with the leg


def test_estimates_are_recomputed_from_the_raw_frames_when_none_were_recorded(
    tmp_path: Path,
) -> None:
    full = record(tmp_path / "full.mcap", seconds=3.0, faults=FAULTS)
    raw = strip(full, tmp_path / "raw.mcap", keep=("/can/raw", "/daq/bus"), attachments=True)
    recorded, recomputed = load_recording(full), load_recording(raw)
    assert recomputed.recomputed and not recorded.recomputed
    assert recomputed.counts.estimates == recorded.counts.estimates
    for leg in LEGS:
        for name in ("t_s", "force_N", "pressure_Pa", "valid"):
            np.testing.assert_array_equal(
                getattr(recomputed.legs[leg], name), getattr(recorded.legs[leg], name)
            )
    assert recomputed.counts.invalid == recorded.counts.invalid

    bare = strip(full, tmp_path / "bare.mcap", keep=("/can/raw",), attachments=False)
    with pytest.raises(ConfigError, match="recomputing them needs --config"):
        load_recording(bare)
    with_config = load_recording(bare, EXAMPLE_CONFIG)
    np.testing.assert_array_equal(
        with_config.legs["SB1_F1"].force_N, recorded.legs["SB1_F1"].force_N
    )
    # no configuration at all, but estimates recorded: drawn with the default settings
    legs_only = strip(full, tmp_path / "pam-9_20250101T000000.000Z.mcap", keep=("/leg/",),
                      attachments=False)  # fmt: skip
    bare_recording = load_recording(legs_only)
    assert bare_recording.machine is None and bare_recording.machine_id == "pam-9"
    assert list(bare_recording.legs) == sorted(LEGS)
    report(ReportOptions(legs_only, tmp_path / "legs-only"))


def test_a_recording_cut_short_is_reported_up_to_its_last_chunk(tmp_path: Path) -> None:
    path = record(tmp_path / "run.mcap", seconds=3.0, chunk_size=256 * 1024)
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) * 2 // 3])
    recording = load_recording(cut)
    assert not recording.complete and 0 < recording.counts.frames
    report(ReportOptions(cut, tmp_path / "out"))
    assert "cut short" in (tmp_path / "out" / "report.html").read_text()


def test_the_time_axis_ends_with_the_longest_cycle(tmp_path: Path) -> None:
    """A cycle's end is the next one's start: "just before it" must stay in the cycle at
    Unix times (1e-9 s below it is the same float), else a second, shorter cycle's end
    sets the axis and the phase names fall outside it (a collapsed figure)."""
    content = analyse(load_recording(record(tmp_path / "r.mcap", seconds=2.5)))
    assert content.time.in_cycle and len(content.cycles) == 2
    ends = [content.time.before(cycle.end_s) for cycle in content.cycles]
    assert ends == pytest.approx([2.0, 0.49], abs=1e-3)
    figure = time_series_figure(content, "pressure")
    png_bytes(figure)  # warnings are errors: the layout holds
    assert figure.axes[0].get_xlim()[1] == pytest.approx(2.0, abs=1e-3)


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "daq", "report", *args],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
    )


def test_the_command_line(tmp_path: Path) -> None:
    path = record(tmp_path / "run.mcap", seconds=1.0)
    done = run_cli(str(path))
    assert done.returncode == 0, done.stderr
    default_out = tmp_path / "run_report"
    assert done.stdout.strip() == str(default_out / "report.html")
    assert (default_out / "pressure.png").stat().st_size > 10_000

    missing = run_cli(str(tmp_path / "nope.mcap"))
    assert missing.returncode == 1
    assert missing.stderr.strip().splitlines() == [
        f"portal-daq: {tmp_path / 'nope.mcap'}: no such file or directory"
    ]
    bare = strip(path, tmp_path / "bare.mcap", keep=("/can/raw",), attachments=False)
    unconfigured = run_cli(str(bare), "--out", str(tmp_path / "x"))
    assert unconfigured.returncode == 2 and "needs --config" in unconfigured.stderr
    assert "Traceback" not in unconfigured.stderr
    configured = run_cli(str(bare), "--config", str(EXAMPLE_CONFIG), "--out", str(tmp_path / "x"))
    assert configured.returncode == 0, configured.stderr
    page = (tmp_path / "x" / "report.html").read_text()
    assert "recomputed from /can/raw" in page

    help_text = run_cli("--help")
    assert help_text.returncode == 0 and "--config" in help_text.stdout


@pytest.mark.parametrize("campaign", [[], ["--campaign"]])
def test_an_out_that_is_a_file_is_one_line_before_reading(
    tmp_path: Path, campaign: list[str]
) -> None:
    """``--out`` naming a file (the recording itself, say) read the whole recording, then
    said ``portal-daq: run.mcap: File exists``."""
    path = tmp_path / "run.mcap"
    path.write_bytes(b"not read")
    done = run_cli(str(tmp_path / "nope.mcap"), *campaign, "--out", str(path))
    assert done.returncode == 1
    assert done.stderr.splitlines() == [
        f"portal-daq: {path}: it is a file; --out names the directory the report goes into"
    ]
    assert path.read_bytes() == b"not read"


def test_a_log_of_another_machine_says_why_the_pictures_are_empty(tmp_path: Path) -> None:
    """The default machine's frames reported with the J1939 machine's config: exit 0 and
    not a word, while every picture was empty (replay says what it did not use)."""
    log = tmp_path / "cycle.log"
    log.write_text(
        "(1750000000.000000) can0 100#461208070000001C\n"
        "(1750000000.010000) can0 100#4612080701000093\n"
    )
    j1939 = ROOT / "deploy" / "examples" / "j1939" / "portal-daq.toml"
    done = run_cli(str(log), "--config", str(j1939), "--out", str(tmp_path / "out"))
    assert done.returncode == 0, done.stderr
    assert done.stderr.splitlines() == [
        "WARNING daq.report.command: cycle.log: no leg estimate in it (2 frames; not used: "
        "unknown_id 2): the pictures are empty; is the machine config (--config, or the one "
        "embedded) this machine's?"
    ]
    right = run_cli(str(log), "--config", str(EXAMPLE_CONFIG), "--out", str(tmp_path / "out"))
    assert right.returncode == 0 and right.stderr == "", right.stderr


def test_a_cut_recording_is_said_once(tmp_path: Path) -> None:
    """Report read the cut file twice (its records, then its frames again to derive the
    signals) and said "ends without its summary" twice, as if two files were cut."""
    path = record(tmp_path / "run.mcap", seconds=2.0, chunk_size=16 * 1024)
    with open(path, "r+b") as file:
        file.truncate(path.stat().st_size * 2 // 3)
    done = run_cli(str(path), "--out", str(tmp_path / "out"))
    assert done.returncode == 0, done.stderr
    assert done.stderr.count("ends without its summary") == 1, done.stderr


def test_input_without_frames_or_estimates_exits_1_with_one_line(tmp_path: Path) -> None:
    """A TOML file, or an MCAP file with only the simulator's truth: nothing to report."""
    toml = run_cli(str(EXAMPLE_CONFIG), "--out", str(tmp_path / "toml"))
    assert toml.returncode == 1
    assert toml.stderr.splitlines() == [
        f"portal-daq: {EXAMPLE_CONFIG}: not an MCAP file (a service recording is .mcap)"
    ]
    full = record(tmp_path / "full.mcap", seconds=0.5, truth=True)
    truth_only = strip(full, tmp_path / "truth.mcap", keep=("/sim/truth",), attachments=True)
    result = run_cli(str(truth_only), "--out", str(tmp_path / "truth"))
    assert result.returncode == 1
    assert result.stderr.splitlines() == [
        f"portal-daq: {truth_only}: holds no CAN frames (/can/raw) and no leg estimates: "
        "nothing to report (50 simulation truth samples only)"
    ]
    assert not (tmp_path / "toml").exists() and not (tmp_path / "truth").exists()


def test_truth_json_written_by_the_recorder_reads_back(tmp_path: Path) -> None:
    path = record(tmp_path / "run.mcap", seconds=0.05, truth=True)
    with open(path, "rb") as file:
        reader = make_reader(file)
        payloads = [json.loads(m.data) for _, _, m in reader.iter_messages(topics=["/sim/truth"])]
    assert [p["t_unix_s"] for p in payloads] == [T0_S + 0.01 * i for i in range(5)]
    assert load_recording(path).truth.t_s.tolist() == [p["t_unix_s"] for p in payloads]


def test_a_leg_invalid_throughout_is_drawn_as_one_gap(tmp_path: Path) -> None:
    """A transducer broken for the whole recording leaves its leg without a valid sample:
    its line is all gap (matplotlib cannot place staggered markers on it), the report is
    still written."""
    faults = FaultConfig(sensor_fault=(FaultWindow("SB1_F2", 0.0, 10.0),), seed=1)
    path = record(tmp_path / "run.mcap", seconds=1.0, faults=faults)
    content = analyse(load_recording(path))
    assert not content.recording.legs["SB1_F2"].valid.any()
    assert content.recording.legs["SB1_F1"].valid.all()
    report(ReportOptions(path, tmp_path / "out"))
    assert (tmp_path / "out" / "pressure.png").stat().st_size > 10_000
