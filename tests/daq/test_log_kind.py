"""A CAN log saved under another format's suffix: said what it looks like, in one line.

A candump log named ``.asc`` replayed to no frame and exit 0 (python-can's ASC reader
skips every line it does not take); every other mix stopped with the reader's own
words (``could not convert string to float: 'vcan0'``), none saying what the file was.
"""

from pathlib import Path

import can
import pytest

from daq.log_kind import FORMATS
from tests.helpers import EXAMPLE_CONFIG

FORMATS_WRITTEN = [".log", ".asc", ".blf", ".trc", ".csv"]


def _written(path: Path) -> Path:
    """Three LEG_SB1_F1 frames in ``path``'s format, as python-can writes it."""
    with can.Logger(path) as writer:
        for k in range(3):
            data = bytes.fromhex("461208070000001C")
            writer.on_message_received(
                can.Message(
                    timestamp=1_796_211_064.0 + k / 100,
                    arbitration_id=0x100,
                    is_extended_id=False,
                    data=data,
                )
            )
    return path


@pytest.mark.parametrize("written", FORMATS_WRITTEN)
@pytest.mark.parametrize("named", FORMATS_WRITTEN)
def test_a_log_named_as_another_format_says_what_it_looks_like(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], written: str, named: str
) -> None:
    from daq.replay_command import replay_main

    log = _written(tmp_path / f"cycle{written}").rename(tmp_path / f"trace{named}")
    code = replay_main([str(log), "--config", str(EXAMPLE_CONFIG), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    if written == named:
        assert code == 0 and not any("looks like" in line for line in err), err
        return
    assert code == 1 and len(err) == 1, err
    assert err[0].startswith(f"portal-daq: {log}: ")
    assert err[0].endswith(f"; it looks like {FORMATS[written]}: name it {written}"), err


def test_a_gzipped_log_without_gz_is_told_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import gzip

    from daq.replay_command import replay_main

    text = _written(tmp_path / "cycle.log").read_bytes()
    log = tmp_path / "trace.log"
    log.write_bytes(gzip.compress(text))
    assert replay_main([str(log), "--config", str(EXAMPLE_CONFIG)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.endswith("; it is a candump log compressed by gzip: name it .log.gz"), err
    log.rename(asc := tmp_path / "trace.asc.gz")
    assert replay_main([str(asc), "--config", str(EXAMPLE_CONFIG)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.endswith(
        "no frame of a Vector ASC log in it; it looks like a candump log: name it .log.gz"
    ), err


def test_an_asc_log_of_a_header_only_is_still_an_empty_log(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    import io

    from daq.replay import replay

    log = tmp_path / "stopped.asc"
    log.write_text(
        "date Wed Dec 02 11:31:04.171 am 2026\nbase hex  timestamps absolute\n"
        "internal events logged\nBegin Triggerblock Wed Dec 02 11:31:04.171 am 2026\n"
        "   0.000000 Start of measurement\nEnd TriggerBlock\n"
    )
    assert replay(log, io.StringIO(), EXAMPLE_CONFIG) == 0
    assert f"{log}: no CAN frame in it: the CSV has its header only" in caplog.text


@pytest.mark.parametrize(
    ("suffix", "content", "reason"),
    [
        *(
            (suffix, content, "nothing in its first lines looks like a line of a CAN log")
            for suffix in (".asc", ".trc")
            for content in (b"meeting notes\nnothing here\n", b"\x00" * 512)
        ),
        *(
            (suffix, "(1.0) can0 100#00\n".encode("utf-16"), "it is UTF-16 text: a CAN log is")
            for suffix in (".log", ".asc", ".trc", ".csv")
        ),
    ],
)
def test_a_file_that_is_no_can_log_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], suffix: str, content: bytes, reason: str
) -> None:
    """python-can's ASC reader skips every line it does not take: a text file of anything
    named .asc (or a log saved as UTF-16, a file of zeros left by a crash) replayed to the
    CSV's header and exit 0; the other readers stopped in their own words (a candump or
    CSV line says what its line should be: test_foreign_logs)."""
    from daq.replay_command import replay_main

    log = tmp_path / f"notes{suffix}"
    log.write_bytes(content)
    code = replay_main([str(log), "--config", str(EXAMPLE_CONFIG), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1, err
    assert err[0].startswith(f"portal-daq: {log}: ") and reason in err[0], err


@pytest.mark.parametrize(
    ("name", "text"),
    [
        ("header.asc", "date Wed Dec 02 11:31:04.171 am 2026\nbase hex  timestamps absolute\n"),
        (
            "comments.trc",
            ";$FILEVERSION=2.1\n;$STARTTIME=46358.1\n;$COLUMNS=N,O,T,B,I,d,R,L,D\n;\n"
            ";   Generated by PCAN-View\n",
        ),
        ("blank.log", "\n\n"),
    ],
)
def test_a_log_without_a_frame_is_still_an_empty_log(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str, text: str
) -> None:
    from daq.replay_command import replay_main

    log = tmp_path / name
    log.write_text(text)
    code = replay_main([str(log), "--config", str(EXAMPLE_CONFIG), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 0 and f"{log}: no CAN frame in it: the CSV has its header only" in err, err
