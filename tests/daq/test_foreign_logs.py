"""CAN logs written by other tools, given to ``replay``, ``report``, ``calibrate``,
``export`` and ``recover``: read right, or refused in one line (never a traceback,
never a silent wrong time or an empty output with exit 0)."""

from __future__ import annotations

import io
import logging
import uuid
from collections.abc import Iterator
from pathlib import Path

import can
import pytest

from daq.errors import RecordingError
from daq.replay import can_log_frames, is_can_log, replay
from dbc.machine import load_machine_config
from tests.helpers import EXAMPLE_CONFIG


@pytest.fixture(autouse=True)
def _no_handler_left_behind() -> Iterator[None]:
    """The commands' ``setup_logging`` binds the root logger to this test's captured
    stderr, closed after it: a later test's log line would go there."""
    before = list(logging.getLogger().handlers)
    yield
    for handler in list(logging.getLogger().handlers):
        if handler not in before:
            logging.getLogger().removeHandler(handler)


ASC_RELATIVE = """\
date Tue Dec 01 19:40:44.232 2026
base hex  timestamps relative
internal events logged
Begin Triggerblock Tue Dec 01 19:40:44.232 2026
   0.000000 Start of measurement
   0.010000 2  100             Rx   d 8 00 00 00 00 00 00 00 00
   0.010000 2  18FEF100x       Rx   d 8 00 00 00 00 00 00 00 00
   0.005000 2  100             Rx   d 8 00 00 00 00 00 00 00 00
End TriggerBlock
"""


def test_an_asc_log_with_relative_timestamps_counts_them_from_the_start(tmp_path: Path) -> None:
    # "timestamps relative": each time is the step since the event before (Vector's
    # format); python-can reads them as they stand, which made time jump back and forth.
    log = tmp_path / "relative.asc"
    log.write_text(ASC_RELATIVE)
    frames = list(can_log_frames(log))
    assert [f.t_s for f in frames] == pytest.approx([0.010, 0.020, 0.025], abs=1e-12)
    assert [(f.arbitration_id, f.is_extended_id) for f in frames] == [
        (0x100, False),
        (0x18FEF100, True),
        (0x100, False),
    ]
    absolute = tmp_path / "absolute.asc"
    absolute.write_text(ASC_RELATIVE.replace("relative", "absolute"))
    assert [f.t_s for f in can_log_frames(absolute)] == [0.010, 0.010, 0.005]


def test_an_asc_line_that_is_neither_a_frame_nor_an_event_is_counted_and_said(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """python-can's ASC reader passed over every line it does not take without a word: a
    frame line cut in the middle of the log, a stranger's text; a frame lost uncounted.
    The events of other kinds (comment, statistic, J1939 transport, system variable, LIN,
    the start of measurement) are not counted."""
    lines = ASC_RELATIVE.replace("relative", "absolute").splitlines(keepends=True)
    lines[6:6] = [
        "   0.010000 2  100\n",  # a frame line cut after its ID
        "// a comment\n",
        "   0.011000 2  Statistic: D 100 R 0 XD 0 XR 0 E 0 O 0 B 12.50%\n",
        "   0.012000 2  J1939TP FEE3p        6    0  0   -   Rx   d 23 A0 0F\n",
        "   0.013000 SV: 5 0 1 ::Engine::Speed = 3\n",
        "   0.014000 L1 Rx 12 1 01\n",
        "garbage from another program\n",
    ]
    log = tmp_path / "damaged.asc"
    log.write_text("".join(lines))
    frames = list(can_log_frames(log))
    assert [f.arbitration_id for f in frames] == [0x100, 0x18FEF100, 0x100]
    assert (
        f"{log}: 2 lines left out, neither a frame nor an event of a Vector ASC log "
        "(the first, line 7: '0.010000 2  100')" in caplog.text
    )


def test_an_asc_frame_line_with_fewer_data_bytes_than_its_length_stops_the_replay(
    tmp_path: Path,
) -> None:
    """python-can read the bytes it found: a frame of another length (``wrong_dlc``), not
    the damaged line it is."""
    log = tmp_path / "short.asc"
    log.write_text(
        ASC_RELATIVE.replace("d 8 00 00 00 00 00 00 00 00\n   0.005", "d 8 00 00\n   0.005")
    )
    with pytest.raises(RecordingError) as refused:
        list(can_log_frames(log))
    assert str(refused.value) == (
        f"{log}: unreadable after frame 1 (line 7): a frame line with 2 of its 8 data bytes"
    )


def test_a_relative_asc_logs_times_count_the_steps_of_lines_that_are_no_frame(
    tmp_path: Path,
) -> None:
    """Each time is the step since the line before, a statistic's, a status's, a
    transmit request's too: summing the frames' steps alone put every frame after such a
    line early (here by 0.5 s, 0.25 s and 1 us)."""
    lines = ASC_RELATIVE.splitlines(keepends=True)
    lines[6:6] = [
        "   0.500000 2  Statistic: D 100 R 0 XD 0 XR 0 E 0 O 0 B 12.50%\n",
        "   0.250000 CAN 2 Status:chip status error passive - TxErr: 132 RxErr: 0\n",
        "   0.000001 2  100             TxRq d 8 00 00 00 00 00 00 00 00\n",
    ]
    log = tmp_path / "relative.asc"
    log.write_text("".join(lines))
    frames = list(can_log_frames(log))
    assert [(f.t_s, f.is_error_frame) for f in frames] == [
        (pytest.approx(0.010, abs=1e-9), False),
        (pytest.approx(0.760, abs=1e-9), True),
        (pytest.approx(0.770001, abs=1e-9), False),
        (pytest.approx(0.775001, abs=1e-9), False),
    ]


def test_candump_error_frames_keep_to_the_channel_asked_and_are_counted(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], caplog: pytest.LogCaptureFixture
) -> None:
    # python-can gives a candump error frame no channel: it is not a second bus.
    from daq.replay_command import replay_main

    log = tmp_path / "errors.log"
    log.write_text(
        "(1750000000.000000) can0 100#0000000000000000\n"
        "(1750000000.001000) can0 20000080#0000000000000000\n"
        "(1750000000.002000) can0 7FF#01\n"
        "(1750000000.003000) can0 100#R\n"
    )
    frames = list(can_log_frames(log, "can0"))
    assert [(f.is_error_frame, f.is_remote_frame) for f in frames] == [
        (False, False),
        (True, False),
        (False, False),
        (False, True),
    ]
    assert replay_main([str(log), "--config", str(EXAMPLE_CONFIG), "--out", "/dev/null"]) == 0
    assert "more than one channel" not in caplog.text
    err = capsys.readouterr().err
    assert "4 frames" in err and "error_frame 1" in err and "remote_frame 1" in err, err


@pytest.mark.parametrize(
    ("name", "content", "reason"),
    [
        pytest.param(  # python-can's BLFReader leaves its file open when the header fails
            "garbage.blf",
            b"garbage",
            "cannot read it as a CAN log",
            marks=pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning"),
        ),
        ("garbage.db", b"garbage\n" * 100, "unreadable after frame 0: file is not a database"),
        ("missing.db", None, "missing.db: no such file or directory"),
        (  # python-can's 'No read support for unknown log format ".txt"' named no other
            "cycle.txt",
            b"(1.0) can0 100#00\n",
            "cannot read it as a CAN log: no log format for its suffix; replay reads .asc, "
            ".blf, .csv, .db, .log, .mf4, .trc (each also .gz) and service recordings (.mcap)",
        ),
        ("empty.txt", b"", "no log format for its suffix"),  # was a header and exit 0
        ("plain.log.gz", b"(1.0) can0 100#00\n", "unreadable after frame 0: Not a gzipped file"),
        (  # a CSV of other columns (our own replay's, say)
            "estimates.csv",
            b"leg,t,force_N,force_raw_N,pressure_Pa,p_piston_Pa,p_rod_Pa,contact,valid\n"
            b"SB1_F1,0.0,1.0,1.0,1.0,1.0,1.0,1,1,\n",
            "unreadable after frame 0 (line 1): too many values to unpack (expected 7) "
            "(python-can's CSV: timestamp,arbitration_id,extended,remote,error,dlc,data)",
        ),
        (  # candump -L always names the interface; some tools leave it out
            "no_interface.log",
            b"(1750000000.000000) 100#0000000000000000\n",
            "unreadable after frame 0 (line 1): not enough values to unpack (expected 3, got 2) "
            "(a candump -L line is '(TIME) INTERFACE ID#DATA', candump -ta's "
            "'(TIME)  INTERFACE  ID   [LENGTH]  DATA')",
        ),
    ],
)
def test_an_unreadable_or_unknown_log_is_one_line(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    name: str,
    content: bytes | None,
    reason: str,
) -> None:
    from daq.replay_command import replay_main

    log = tmp_path / name
    if content is not None:
        log.write_bytes(content)
    assert replay_main([str(log), "--config", str(EXAMPLE_CONFIG)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"portal-daq: {log}: ") and reason in err[0], err
    assert content is not None or not log.exists()  # reading created no file


def test_an_mf4_log_without_asammdf_says_what_to_install(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    pytest.importorskip("can.io.mf4")
    from can.io import mf4

    if mf4.asammdf is not None:  # type: ignore[attr-defined]
        pytest.skip("asammdf is installed")
    from daq.replay_command import replay_main

    log = tmp_path / "trace.mf4"
    log.write_bytes(b"MDF     4.10    ")
    assert replay_main([str(log), "--config", str(EXAMPLE_CONFIG)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "asammdf" in err[0], err


def candump_log(path: Path, start_s: float = 1_750_000_000.0) -> Path:
    with can.Logger(path) as writer:
        for k in range(3):
            writer.on_message_received(
                can.Message(timestamp=start_s + k / 100, arbitration_id=0x100, data=bytes(8))
            )
    return path


@pytest.mark.parametrize(
    "command",
    [
        ["report", "--campaign", "--workers", "1", "--out", "{tmp}/camp"],
        ["export", "--to", "asc", "--out", "{tmp}/out.asc"],
        ["recover", "-o", "{tmp}/out.mcap"],
    ],
)
def test_a_can_log_given_where_a_recording_is_needed_is_refused_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: list[str]
) -> None:
    from daq.cli import main

    log = candump_log(tmp_path / "cycle.log")
    name, *options = command
    args = [name, str(log), *(o.replace("{tmp}", str(tmp_path)) for o in options)]
    assert main(args) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"portal-daq: {log}: not an MCAP file (a service recording is .mcap)"], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cycle.log"]  # nothing written


def test_logs_given_out_of_order_are_chained_as_given_with_a_warning(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    # The median and contact carry over from one log to the next: a log that begins
    # before the one before it ended (wrong order, two loggers, times from 0) says so.
    morning = candump_log(tmp_path / "morning.log", start_s=1_750_000_000.0)
    noon = candump_log(tmp_path / "noon.log", start_s=1_750_007_200.0)
    assert replay([morning, noon], io.StringIO(), EXAMPLE_CONFIG) == 0
    assert "out of order" not in caplog.text
    assert replay([noon, morning], io.StringIO(), EXAMPLE_CONFIG) == 0
    (line,) = [r.getMessage() for r in caplog.records if "out of order" in r.getMessage()]
    assert line == (
        f"{morning} begins 7200.020 s before {noon} ends: logs out of order or overlapping? "
        "chained in the order given"
    )


def sim_log(tmp_path: Path, name: str = "cycle.log", seconds: float = 1.0) -> Path:
    from sim_bridge.__main__ import cli

    log = tmp_path / name
    args = ["--interface", "virtual", "--channel", f"log-{uuid.uuid4()}", "--as-fast-as-possible"]
    assert cli([*args, "-q", "--duration", str(seconds), "--frames-log", str(log)]) == 0
    return log


def test_a_can_log_is_reported_with_config_as_its_replay_gives(tmp_path: Path) -> None:
    from daq.report.command import report_main
    from daq.report.loading import load_recording

    log = sim_log(tmp_path)
    lines = log.read_text().splitlines()
    # a foreign node and an error frame among the machine's frames
    stamp = lines[5].split()[0]
    lines[5:5] = [f"{stamp} can0 7FF#01", f"{stamp} can0 20000080#00"]
    log.write_text("\n".join(lines) + "\n")
    out = io.StringIO()
    rows = replay(log, out, EXAMPLE_CONFIG)
    recording = load_recording(log, EXAMPLE_CONFIG)
    assert recording.recomputed and recording.machine_id == "pam-proto-1"
    assert recording.counts.frames == len(lines)
    assert recording.counts.estimates == rows == 6 * 100
    assert recording.counts.bad == {"unknown_id": 1, "error_frame": 1}
    assert recording.counts.messages["LEG_SB1_F1"] == 100
    first = float(lines[0][1 : lines[0].index(")")])
    assert recording.start_t_s == first
    assert (
        report_main([str(log), "--config", str(EXAMPLE_CONFIG), "--out", str(tmp_path / "r")]) == 0
    )
    assert (tmp_path / "r" / "report.html").is_file()
    # without a config: what it needs, exit 2
    assert report_main([str(log), "--out", str(tmp_path / "r2")]) == 2


def test_a_log_with_times_from_0_is_reported_without_a_1970_date(tmp_path: Path) -> None:
    from daq.report.command import report_main

    log = sim_log(tmp_path)
    lines = log.read_text().splitlines()
    t0 = float(lines[0][1 : lines[0].index(")")])
    relative = tmp_path / "relative.log"
    relative.write_text(
        "".join(f"({float(l[1 : l.index(')')]) - t0:.6f}){l[l.index(')') + 1 :]}\n" for l in lines)
    )
    out = tmp_path / "r"
    assert report_main([str(relative), "--config", str(EXAMPLE_CONFIG), "--out", str(out)]) == 0
    page = (out / "report.html").read_text()
    assert "1970" not in page
    assert "log time, no date" in page


@pytest.mark.parametrize(
    ("name", "expected"),
    [("a.log", True), ("a.ASC", True), ("a.blf", True), ("a.trc", True), ("a.log.gz", True),
     ("a.mcap", False), ("a.toml", False), ("a.gz", False), ("a", False), ("a.tar.gz", False)],
)  # fmt: skip
def test_which_files_are_can_logs(name: str, expected: bool) -> None:
    assert is_can_log(Path(name)) is expected


def test_calibrate_takes_the_movement_phase_from_the_frames_of_a_log_or_a_recording(
    tmp_path: Path,
) -> None:
    """The phase decides which instants are quasi-static: it is decoded from the
    MACHINE_STATE frames, also of a CAN log and of a recording made without
    ``[recording] signals`` (the default), where it was ignored before."""
    from daq.calibrate.data import machine_for, read_instants
    from daq.mcap_file import CONFIG_ATTACHMENT, DBC_ATTACHMENT, McapFile
    from daq.pipeline import Pipeline
    from dbc import DEFAULT_DBC_PATH
    from dbc.errors import ConfigError

    fast = sim_log(tmp_path, "fast.log", seconds=45.0)
    # frame times of a real-time run: instant k (frames of one time stamp) at k * 10 ms
    stamps: dict[str, int] = {}
    log = tmp_path / "cycle.log"
    with open(fast) as lines, open(log, "w") as out:
        for line in lines:
            stamp, rest = line.split(" ", 1)
            out.write(f"({1_796_150_000 + stamps.setdefault(stamp, len(stamps)) / 100:.6f}) {rest}")
    machine = load_machine_config(EXAMPLE_CONFIG)
    recordings = {}
    for signals in (True, False):
        path = recordings[signals] = tmp_path / f"signals_{signals}.mcap"
        pipeline = Pipeline.from_config(*machine)
        with open(path, "wb") as stream, McapFile(stream, machine[1]) as mcap:
            mcap.start(
                {
                    CONFIG_ATTACHMENT: EXAMPLE_CONFIG.read_bytes(),
                    DBC_ATTACHMENT: DEFAULT_DBC_PATH.read_bytes(),
                }
            )
            for frame in can_log_frames(log):
                mcap.write_result(pipeline.process(frame), signals=signals)
    recorded = read_instants([recordings[True]], machine)
    assert 50 < len(recorded.t_s) < recorded.total - 200  # moving phases left out
    for path in (recordings[False], log):
        instants = read_instants([path], machine)
        assert instants.total == recorded.total
        assert list(instants.t_s) == list(recorded.t_s)
        assert (instants.force_N == recorded.force_N).all()
    with pytest.raises(ConfigError, match="needs --config"):
        machine_for([log], None)


ASC_FD_CHANNEL = """\
date Tue Dec 01 19:40:44.232 2026
base hex  timestamps absolute
internal events logged
Begin Triggerblock Tue Dec 01 19:40:44.232 2026
   0.010000 CANFD 1 Rx 100 LEG_SB1_F1 0 0 8 8 01 02 03 04 05 06 07 08 130000 130 2000 0 0 0 0 0
   0.020000 CANFD 1 Rx 123 1 0 9 12 01 02 03 04 05 06 07 08 09 0A 0B 0C 130000 130 323000 0 0 0 0 0
   0.030000 CANFD 1 Rx 100 0 0 8 8 01 02 03 04 05 06 07 08 130000 130 0 0 0 0 0 0
End TriggerBlock
"""


def test_a_classic_frame_on_a_can_fd_channel_of_an_asc_log_is_no_fd_frame(tmp_path: Path) -> None:
    # Vector logs every frame of a CAN FD channel as a CANFD line; bit 12 of its flags
    # (EDL) tells an FD frame. python-can made every such line FD: refused as fd_frame.
    log = tmp_path / "fd_channel.asc"
    log.write_text(ASC_FD_CHANNEL)
    frames = list(can_log_frames(log))
    assert [(f.arbitration_id, f.is_fd, len(f.data)) for f in frames] == [
        (0x100, False, 8),
        (0x123, True, 12),
        (0x100, False, 8),
    ]


def _written_log(path: Path, count: int = 5) -> list[can.Message]:
    """``count`` frames of ID 0x100 (data ending in 0x1C) written by python-can's writer
    for ``path``'s suffix; the messages."""
    messages = [
        can.Message(
            timestamp=1_750_000_000.0 + k / 100,
            arbitration_id=0x100,
            is_extended_id=False,
            data=bytes([k % 256, 0x12, 8, 7, 0, 0, 0, 0x1C]),
            channel="can0",
        )
        for k in range(count)
    ]
    with can.Logger(path) as writer:
        for message in messages:
            writer.on_message_received(message)
    return messages


@pytest.mark.parametrize("suffix", [".log", ".asc", ".csv", ".trc", ".log.gz"])
def test_a_text_log_cut_short_is_read_up_to_its_last_whole_line(
    tmp_path: Path, suffix: str, caplog: pytest.LogCaptureFixture
) -> None:
    # A logger killed by a power cut leaves a last line without its line end, cut
    # anywhere: in an ASC line after "1" of the last byte "1C", python-can read a whole
    # frame with 0x01; a candump or CSV line was an error (replay exit 1, report none).
    import gzip

    whole = tmp_path / f"whole{suffix}"
    messages = _written_log(whole, 400 if suffix.endswith(".gz") else 5)
    text = whole.read_bytes()
    if suffix.endswith(".gz"):
        cut = tmp_path / "cut.log.gz"
        cut.write_bytes(text[: len(text) // 2])  # inside the compressed stream
        assert gzip.decompress(text).endswith(b"\n")
    else:
        lines = text.decode().replace("\r\n", "\n").splitlines(keepends=True)
        # the last frame's line (CSV: its data in base64)
        last = max(i for i, line in enumerate(lines) if "1C" in line or "ABw=" in line)
        cut_at = lines[last].rfind("1C") + 1 or len(lines[last]) // 2  # "... 00 1"
        cut = tmp_path / f"cut{suffix}"
        cut.write_text("".join(lines[:last]) + lines[last][:cut_at], newline="")
    frames = list(can_log_frames(cut))
    expected = len(messages) - 1 if not suffix.endswith(".gz") else len(frames)
    assert len(frames) == expected and 0 < len(frames) < len(messages)
    assert [f.data for f in frames] == [bytes(m.data) for m in messages[: len(frames)]]
    (line,) = [r.getMessage() for r in caplog.records if "cut short" in r.getMessage()]
    assert line.startswith(f"{cut} is cut short (") and f"read up to frame {len(frames)}" in line
    assert replay(cut, io.StringIO(), EXAMPLE_CONFIG) == len(frames)  # LEG_SB1_F1: one each


def test_a_log_in_a_windows_code_page_or_with_a_bom_reads(tmp_path: Path) -> None:
    # A German CANoe writes its ASC header in Windows-1252 ("Mär"), a comment may hold
    # "°C"; Windows editors put a BOM before a CSV. The frames are ASCII: read them.
    whole = tmp_path / "whole.asc"
    messages = _written_log(whole)
    body = whole.read_text().split("Start of measurement\n", 1)[1]
    german = tmp_path / "german.asc"
    german.write_bytes(
        "date Mo Mär 02 09:15:01.000 vorm. 2026\nbase hex  timestamps absolute\n"
        "// Öltemperatur in °C\ninternal events logged\n"
        "Begin Triggerblock Mo Mär 02 09:15:01.000 vorm. 2026\n"
        "   0.000000 Start of measurement\n".encode("cp1252")
        + body.encode()
    )
    assert [f.data for f in can_log_frames(german)] == [bytes(m.data) for m in messages]
    csv_log = tmp_path / "whole.csv"
    _written_log(csv_log)
    bom = tmp_path / "bom.csv"
    bom.write_bytes(b"\xef\xbb\xbf" + csv_log.read_bytes())
    assert [f.data for f in can_log_frames(bom)] == [bytes(m.data) for m in messages]


def test_a_stray_byte_in_a_candump_line_names_the_frame_before_it(tmp_path: Path) -> None:
    # Decoding failed for the whole 8 KiB block around the byte: "after frame 0".
    log = tmp_path / "stray.log"
    good = "".join(f"({1_750_000_000 + k / 100:.6f}) can0 100#00\n" for k in range(400))
    log.write_bytes(good.encode() + b"(1750000004.000000) can0 100#00\xff\xfe\n" + good.encode())
    with pytest.raises(RecordingError, match=r"unreadable after frame 400 \(line 401\): "):
        list(can_log_frames(log))


def test_the_report_counts_j1939_frames_from_an_unmapped_source_address(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    # Transducers replaced by ones of other source addresses: replay said "unmapped_source
    # 4", the report "bad frames by kind: none" beside "leg estimates 0".
    from daq.mcap_file import CONFIG_ATTACHMENT, DBC_ATTACHMENT, McapFile, RecordBatch
    from daq.pipeline import Pipeline
    from daq.report.loading import load_recording
    from tests.helpers import ROOT

    config_path = ROOT / "deploy/examples/j1939/portal-daq.toml"
    log = tmp_path / "new_transducers.log"
    log.write_text(
        "".join(
            f"({1_796_150_000 + k / 100:.6f}) can0 18FF20{source:02X}#0807002800000000\n"
            for k in range(4)
            for source in (0x21, 0x22, 0x31)  # SB1_F1's piston and rod; 0x31 mapped nowhere
        )
    )
    machine = load_machine_config(config_path)
    recording = tmp_path / "new_transducers.mcap"
    pipeline = Pipeline.from_config(*machine)
    with open(recording, "wb") as stream, McapFile(stream, machine[1]) as mcap:
        mcap.start(
            {
                CONFIG_ATTACHMENT: config_path.read_bytes(),
                DBC_ATTACHMENT: machine[0].dbc_path.read_bytes(),
            }
        )
        batch = [pipeline.process(frame) for frame in can_log_frames(log)]
        mcap.write_batch(RecordBatch.of(batch, signals=False))
    assert pipeline.bad == {"unmapped_source": 4}
    for loaded in (load_recording(log, config_path), load_recording(recording)):
        assert loaded.counts.bad == {"unmapped_source": 4}
        assert loaded.counts.estimates == 4  # SB1_F1, one per piston frame
    # replay of the recording counts them too, as replay of a CAN log did (it said nothing)
    assert replay(recording, io.StringIO()) == 4
    assert "12 frames, 4 of them not used (unmapped_source 4)" in caplog.text


def test_a_leg_whose_rod_transducer_fell_silent_is_named_by_replay_and_report(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """SB1_F1's rod transducer (0x22) stops after 0.2 s, its piston one (0x21) goes on:
    every SB1_F1 estimate after it is ``rod_stale``. The live status names the leg silent;
    replay and the report named only legs without any estimate, so not this one. SB1_F2
    sends both chambers throughout and is not named."""
    from daq.report.content import analyse
    from daq.report.loading import load_recording
    from daq.report.page import header_rows
    from tests.helpers import ROOT

    config_path = ROOT / "deploy/examples/j1939/portal-daq.toml"
    log = tmp_path / "rod_silent.log"
    log.write_text(
        "".join(
            f"({1_796_150_000 + k / 100 + source / 1e5:.6f}) can0 18FF20{source:02X}"
            "#0807002800000000\n"
            for k in range(100)
            for source in (0x22, 0x24, 0x21, 0x23)  # rods first, then pistons
            if source != 0x22 or k < 20
        )
    )
    rows = dict(header_rows(analyse(load_recording(log, config_path))))
    silent = rows["legs silent (no estimate for longer than the stale time)"]
    assert silent.startswith("SB1_F1 1x, 0.79 s, SB1_F3 1x, 0.99 s"), silent
    assert "SB1_F2" not in silent, silent
    assert replay(log, io.StringIO(), config_path) == 200  # SB1_F1's, invalid, included
    assert f"legs silent (no estimate for longer than their stale time): {silent}" in caplog.text


def two_container_blf(tmp_path: Path) -> tuple[Path, bytes, int]:
    """A BLF of 4,000 frames in two containers (of 128 KiB before zlib): its path, its
    bytes and where the second container begins."""
    whole = tmp_path / "whole.blf"
    with can.BLFWriter(whole) as writer:
        for k in range(4000):
            writer.on_message_received(
                can.Message(timestamp=1_750_000_000 + k / 100, arbitration_id=0x7F0, data=bytes(8))
            )
    data = whole.read_bytes()
    return whole, data, data.index(b"LOBJ", data.index(b"LOBJ") + 4)


def test_a_blf_log_not_closed_or_cut_is_read_to_its_last_object_with_a_warning(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, capsys: pytest.CaptureFixture[str]
) -> None:
    # python-can read a BLF whose logger died (header never filled in) or that was cut
    # silently, or stopped with exit 1 where the cut fell in an object's header; a
    # damaged object was a BLFParseError traceback.
    from daq.replay_command import replay_main

    whole, data, second = two_container_blf(tmp_path)
    assert len(list(can_log_frames(whole))) == 4000 and "cut short" not in caplog.text
    counts = []
    for name, content in (("cut_in_header.blf", data[: second + 8]), ("cut.blf", data[:-100])):
        cut = tmp_path / name
        cut.write_bytes(content)
        counts.append(count := len(list(can_log_frames(cut))))
        assert 0 < count < 4000
        assert caplog.records[-1].getMessage() == (
            f"{cut} is cut short (its header gives {len(data)} bytes, the file has "
            f"{len(content)}: not closed): read up to frame {count}"
        )
    damaged = tmp_path / "damaged.blf"
    damaged.write_bytes(data[:second] + b"XXXX" + data[second + 4 :])
    assert replay_main([str(damaged), "--config", str(EXAMPLE_CONFIG), "--out", "/dev/null"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"portal-daq: {damaged}: unreadable after frame {counts[0]}: "
        "BLFParseError (no BLF object begins where one should: a damaged file)"
    ], err


def test_a_damaged_or_cut_compressed_blf_is_one_line_or_read_to_its_cut(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, capsys: pytest.CaptureFixture[str]
) -> None:
    """zlib's error on a BLF container damaged inside its compressed bytes was a
    traceback; a gzipped BLF cut short (gzip's EOFError) too, and one whose gzip check
    fails was 'portal-daq: CRC check failed ...' (no file named) after its rows, exit 1.
    A gzipped BLF is read as a gzipped text log is: up to its cut, with a warning."""
    import gzip

    from daq.replay_command import replay_main

    whole, data, second = two_container_blf(tmp_path)
    packed = gzip.compress(data)
    cut = tmp_path / "cut.blf.gz"
    cut.write_bytes(packed[: len(packed) * 3 // 4])
    checked = tmp_path / "checked.blf.gz"  # its CRC-32 zeroed
    checked.write_bytes(packed[:-8] + bytes(4) + packed[-4:])
    for path, reason, whole_read in (
        (cut, "Compressed file ended before the end-of-stream marker was reached", False),
        (checked, "CRC check failed 0x0 != ", True),
    ):
        count = len(list(can_log_frames(path)))
        assert (count == 4000) == whole_read and count > 0
        message = caplog.records[-1].getMessage()
        assert message.startswith(f"{path} is cut short ({reason}"), message
        assert message.endswith(f"): read up to frame {count}"), message
    # (replay_main's logging last: its handler takes the log lines from caplog)
    damaged = tmp_path / "damaged.blf"  # zeros in the second container's zlib stream
    damaged.write_bytes(data[: second + 200] + bytes(40) + data[second + 240 :])
    assert replay_main([str(damaged), "--config", str(EXAMPLE_CONFIG), "--out", "/dev/null"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"portal-daq: {damaged}: unreadable after frame ")
    assert "while decompressing data" in err[0], err
    assert err[0].endswith("(a compressed container of the BLF is damaged)"), err


def test_a_log_whose_frames_all_have_one_time_stamp_is_reported(tmp_path: Path) -> None:
    # A logger that stamps nothing (one time for every frame): the cycle has no duration,
    # no time just before its end; the time axis' NaN limit was a ValueError traceback.
    from daq.report.command import report_main

    log = sim_log(tmp_path)
    lines = log.read_text().splitlines()
    stamped = tmp_path / "one_stamp.log"
    stamped.write_text("".join(f"(1796150000.000000){l[l.index(')') + 1 :]}\n" for l in lines))
    out = tmp_path / "r"
    assert report_main([str(stamped), "--config", str(EXAMPLE_CONFIG), "--out", str(out)]) == 0
    assert "duration</td><td class=text>0.00 s" in (out / "report.html").read_text()


def test_the_report_of_a_log_of_two_buses_takes_one_channel(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    # The warning said "pick one with --channel", which only replay had.
    from daq.report.command import report_main
    from daq.report.loading import load_recording

    log = sim_log(tmp_path)
    lines = log.read_text().splitlines()
    two = tmp_path / "two_buses.log"
    other = [l.replace(" vcan0 ", " vcan1 ").replace("#", "#FF", 1) for l in lines[:50]]
    two.write_text("\n".join(lines + other) + "\n")  # can1: the same IDs, other lengths
    both = load_recording(two, EXAMPLE_CONFIG)
    assert both.counts.frames == len(lines) + 50 and both.counts.bad == {"wrong_dlc": 50}
    assert "pick one with --channel" in caplog.text
    one = load_recording(two, EXAMPLE_CONFIG, "vcan0")
    assert one.counts.frames == len(lines) and one.counts.bad == {}
    assert one.counts.estimates == both.counts.estimates
    out = tmp_path / "r"
    args = [str(two), "--config", str(EXAMPLE_CONFIG), "--out", str(out), "--channel"]
    assert report_main([*args, "vcan0"]) == 0
    assert report_main([*args, "can9"]) == 1


def test_an_empty_log_replays_to_a_header_with_a_warning(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    log = tmp_path / "empty.log"
    log.write_text("")
    out = io.StringIO()
    assert replay(log, out, EXAMPLE_CONFIG) == 0
    assert out.getvalue().count("\n") == 1
    assert f"{log}: no CAN frame in it: the CSV has its header only" in caplog.text


def test_candumps_dropcount_lines_are_counted_as_frames_the_kernel_dropped(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """``candump -d`` writes a line into its log when the kernel dropped frames before it
    read them (the socket's receive buffer was full); python-can stopped at it (exit 1).
    The loss is counted where the service counts its own: replay's warning line and the
    report's "frames lost before processing"."""
    from daq.report.loading import load_recording

    log = sim_log(tmp_path, seconds=0.3)
    lines = log.read_text().splitlines()
    del lines[100:137]  # the 37 frames the kernel dropped
    lines.insert(100, "DROPCOUNT: dropped 37 CAN frames on 'vcan0' socket (total drops 37)")
    lines.append("DROPCOUNT: dropped 1 CAN frame on 'vcan0' socket (total drops 38)")
    log.write_text("\n".join(lines) + "\n")
    with caplog.at_level(logging.WARNING):
        replay(log, io.StringIO(), EXAMPLE_CONFIG)
    assert (
        "38 frames lost before they were recorded or logged, not in the file (38 by the kernel"
        in caplog.text
    )
    assert f"{len(lines) - 2} frames, " in caplog.text  # the frames' count line
    counts = load_recording(log, EXAMPLE_CONFIG).counts
    assert (counts.frames, counts.kernel_dropped, counts.rx_dropped) == (len(lines) - 2, 38, 0)


@pytest.mark.parametrize(
    "header",
    [
        "",  # frame lines only (a tool that writes no header)
        "date Wed Dec 02 08:17:26.477 2026\n",
        "date Wed Dec 02 08:17:26.477 2026\nbase hex  timestamps absolute\n",  # CANalyzer 5
        "date Wed Dec 02 08:17:26.477 2026\nbase hex  timestamps absolute\n"
        "no internal events logged\n",
    ],
    ids=["none", "date", "date_base", "whole"],
)
def test_an_asc_header_without_its_events_line_costs_no_frame(tmp_path: Path, header: str) -> None:
    """python-can's header reading stops one line past a header that lacks its last line
    (``internal events logged``) and dropped that line: the log's first frame, uncounted."""
    log = tmp_path / "old.asc"
    frames = "".join(
        f"   0.0{i}0000 1  10{i}             Rx   d 8 00 00 00 00 00 00 00 0{i}\n" for i in (1, 2)
    )
    log.write_text(header + frames)
    assert [(f.arbitration_id, f.t_s) for f in can_log_frames(log)] == [
        (0x101, 0.01),
        (0x102, 0.02),
    ]


@pytest.mark.parametrize(
    "header", ["timestamp,arbitration_id,extended,remote,error,dlc,data\n", ""]
)
def test_a_csv_log_without_its_header_line_costs_no_frame(tmp_path: Path, header: str) -> None:
    """python-can's CSV reader skips the first line as the header: of a CSV written
    without one, the first frame was lost uncounted."""
    log = tmp_path / "frames.csv"
    log.write_text(header + "1.0,0x101,0,0,0,1,AQ==\n2.0,0x102,0,0,0,1,Ag==\n")
    assert [(f.arbitration_id, f.data) for f in can_log_frames(log)] == [
        (0x101, b"\1"),
        (0x102, b"\2"),
    ]


@pytest.mark.parametrize("stamp", ["inf", "nan", "1e300"])
def test_a_frame_time_that_is_no_time_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], stamp: str
) -> None:
    """A corrupted time (1e300, inf) raised an IndexError out of the estimator (replay,
    report), and calibrate sampled towards it forever."""
    from daq.cli import main

    log = tmp_path / "cycle.log"
    log.write_text(
        f"(1.0) can0 7FF#00\n(2.0) can0 7FF#00\n({stamp}) can0 7FF#00\n(3.0) can0 7FF#00\n"
    )
    for command in ("replay", "report", "calibrate"):
        assert main([command, str(log), "--config", str(EXAMPLE_CONFIG)]) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert err[-1].startswith(
            f"portal-daq: {log}: unreadable after frame 2 (line 3): frame time "
        )
        assert "is no time" in err[-1] and "Traceback" not in "\n".join(err)


CANOE_TWO_CHANNELS = """\
date Wed Dec 02 11:31:04.171 am 2026
base hex  timestamps absolute
internal events logged
// version 13.0.0
Begin Triggerblock Wed Dec 02 11:31:04.171 am 2026
   0.000000 Start of measurement
   0.000000 CAN 1 Status:chip status error active
   0.000000 CAN 2 Status:chip status error active
   0.001000 1  18FEF100x       Rx   d 8 FF FF FF FF FF FF FF FF  Length = 280000 BitCount = 144
   0.009990 2  100             TxRq d 8 46 12 08 07 00 00 00 1C
   0.010000 2  100             Tx   d 8 46 12 08 07 00 00 00 1C  Length = 228000 BitCount = 118
   0.015000 CAN 2 Status:chip status warning level - TxErr: 96 RxErr: 0
   0.016000 CAN 2 Status:chip status error passive - TxErr: 132 RxErr: 0
   0.017000 CAN 2 Status:chip status busoff - TxErr: 256 RxErr: 0
   0.018000 CAN 1 Status:receive queue overrun
   0.019990 CANFD 2 TxRq 100 0 0 8 8 46 12 08 07 01 00 00 93 0 0 0 0 0 0 0 0
   0.020000 CANFD 2 Tx 100 0 0 8 8 46 12 08 07 01 00 00 93 130000 130 0 0 0 0 0 0
   0.120000 CAN 2 Status:chip status error active
End TriggerBlock
"""


def test_an_asc_logs_controller_states_are_error_frames_and_its_tx_requests_no_frames(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """python-can skipped the controller's status lines (a bus-off showed nowhere) and read
    each transmit request (TxRq: the logging node asked for a frame; the frame is its Tx
    line) as a frame: every frame the node sent came twice, counter_repeat and an
    invalid estimate more."""
    log = tmp_path / "canoe.asc"
    log.write_text(CANOE_TWO_CHANNELS)
    frames = list(can_log_frames(log, "1"))  # CANalyzer's channel 2
    assert [(f.is_error_frame, f.t_s) for f in frames] == [
        (False, 0.010),
        (True, 0.015),
        (True, 0.016),
        (True, 0.017),
        (False, 0.020),
    ]
    assert (
        f"{log}: the CAN controller reported warning level 1, error passive 1, busoff 1: "
        "each counted as an error frame" in caplog.text
    )
    out = io.StringIO()
    assert replay(log, out, EXAMPLE_CONFIG, "1") == 2
    assert [row.split(",")[-2] for row in out.getvalue().splitlines()[1:]] == ["1", "1"]  # valid
    assert "error_frame 3)" in caplog.text and "counter_repeat" not in caplog.text
    caplog.clear()
    assert [f.is_error_frame for f in can_log_frames(log, "0")] == [False, True]
    assert "reported receive queue overrun 1: each" in caplog.text


def test_a_sensor_silent_for_a_while_or_never_heard_is_in_the_report_and_the_replay(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A transducer silent for 0.4 s (a loose connector, a reboot) left no estimate, and
    the header said "invalid estimates by reason: none", "frames lost: 0": only a gap in
    a picture told it; replay said nothing. One that never spoke was not named at all."""
    from daq.report.content import analyse
    from daq.report.loading import load_recording
    from daq.report.page import header_rows

    log = sim_log(tmp_path)
    lines = log.read_text().splitlines()
    t0 = float(lines[0][1 : lines[0].index(")")])

    def kept(line: str) -> bool:
        t_s = float(line[1 : line.index(")")]) - t0
        frame_id = line.split()[2].split("#")[0]
        # mid-step bounds: a log's stamps are wall-clock seconds, 0.30 may read 0.2999999
        return not (frame_id == "102" and 0.295 < t_s < 0.705) and frame_id != "105"

    log.write_text("".join(f"{line}\n" for line in lines if kept(line)))
    rows = dict(header_rows(analyse(load_recording(log, EXAMPLE_CONFIG))))
    silent = rows["legs silent (no estimate for longer than the stale time)"]
    f3, never = silent.split(", SB2_F3 ")
    assert f3.startswith("SB1_F3 1x, ") and f3.endswith(" s"), silent
    assert f3.split(", ")[1] == "0.42 s", silent  # from the kept step at 0.29 s to 0.71 s
    assert never == "1x, 0.99 s", silent  # the whole log
    replay(log, io.StringIO(), EXAMPLE_CONFIG)
    assert f"legs silent (no estimate for longer than their stale time): {silent}" in caplog.text
    whole = load_recording(sim_log(tmp_path, "whole.log"), EXAMPLE_CONFIG)
    whole_rows = dict(header_rows(analyse(whole)))
    assert whole_rows["legs silent (no estimate for longer than the stale time)"] == "none"
    caplog.clear()
    replay(tmp_path / "whole.log", io.StringIO(), EXAMPLE_CONFIG)
    assert "legs silent" not in caplog.text


@pytest.mark.parametrize("glitch", ["step back", "stamped 0"])
def test_replay_names_the_legs_silent_as_the_report_does_across_clock_steps(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, glitch: str
) -> None:
    """The clock steps back an hour while SB1_F3 is silent for 0.4 s; or one frame of
    SB1_F1 is stamped 0 (a logger's glitch). Replay judged the silences on frame times:
    it named nothing in the first case (SB1_F3's frames came back "before" they went) and
    SB1_F1 silent for 56 years in the second. It now says what the report's header says,
    on the time line that joins such steps."""
    from daq.report.content import analyse
    from daq.report.loading import load_recording
    from daq.report.page import header_rows

    log = sim_log(tmp_path)
    lines = log.read_text().splitlines()
    t0 = float(lines[0][1 : lines[0].index(")")])
    kept = []
    for line in lines:
        t_s = float(line[1 : line.index(")")]) - t0
        frame_id = line.split()[2].split("#")[0]
        if frame_id == "102" and 0.295 < t_s < 0.705:
            continue
        if glitch == "step back" and t_s > 0.5:
            t_s -= 3600.0
        if glitch == "stamped 0" and frame_id == "100" and 0.795 < t_s < 0.805:
            t_s = -t0
        kept.append(f"({t0 + t_s:.6f}){line[line.index(')') + 1 :]}\n")
    log.write_text("".join(kept))
    rows = dict(header_rows(analyse(load_recording(log, EXAMPLE_CONFIG))))
    silent = rows["legs silent (no estimate for longer than the stale time)"]
    assert silent.startswith("SB1_F3 1x, 0.4"), silent
    caplog.clear()
    replay(log, io.StringIO(), EXAMPLE_CONFIG)
    assert f"legs silent (no estimate for longer than their stale time): {silent}" in caplog.text


def test_a_block_of_zero_bytes_inside_a_text_log_is_said_in_a_short_line(
    tmp_path: Path,
) -> None:
    """A block the file system left zeroed (a power cut as the logger wrote it) in the
    middle of a candump log: the error quoted the line, a single line of 16 KB of
    ``\\x00``; it says how many zero bytes, on which line."""
    log = sim_log(tmp_path, seconds=0.1)
    text = log.read_bytes()
    middle = text.index(b"\n", len(text) // 2) + 8  # inside the time of a line
    log.write_bytes(text[:middle] + bytes(4096) + text[middle:])
    line_number = text[:middle].count(b"\n") + 1
    with pytest.raises(RecordingError) as refused:
        list(can_log_frames(log))
    reason = str(refused.value)
    assert reason.startswith(
        f"{log}: unreadable after frame {line_number - 1} (line {line_number}): 4096 zero bytes "
        "(a block of the file left zeroed"
    )
    assert len(reason) < 400


def test_the_channels_of_an_asc_log_are_said_numbered_from_0(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """python-can numbers ASC and BLF channels from 0, CANalyzer from 1: the warning and
    the error listed `0, 1` of a log of CANalyzer's channels 1 and 2, and `--channel 2`
    (CANalyzer's second bus) was refused without saying why."""
    log = tmp_path / "canoe.asc"
    log.write_text(CANOE_TWO_CHANNELS)
    list(can_log_frames(log))
    assert (
        f"{log}: frames of more than one channel (0, 1; numbered from 0: CANalyzer's and "
        "CANoe's channel 1 is 0): replayed as one bus" in caplog.text
    )
    with pytest.raises(RecordingError) as refused:
        list(can_log_frames(log, "2"))
    assert str(refused.value) == (
        f"{log}: no frame on channel '2'; its channels: 0, 1; numbered from 0: CANalyzer's "
        "and CANoe's channel 1 is 0"
    )
