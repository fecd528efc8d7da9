"""``portal-daq replay ... --out FILE``: the CSV replaces FILE only once the replay is
done; a replay refused or failed leaves FILE as it was, and says why in one line."""

import contextlib
import io
import os
import stat
import threading
from pathlib import Path
from subprocess import CompletedProcess

import pytest

from tests.daq.test_cli import assert_one_line_error, run_cli
from tests.helpers import EXAMPLE_CONFIG

#: Two LEG_SB1_F1 frames as the simulator sends them (counter 0 and 1, CRC-8).
LOG = (
    "(1750000000.000000) can0 100#461208070000001C\n(1750000000.010000) can0 100#4612080701000093\n"
)


@pytest.fixture
def earlier(tmp_path: Path) -> Path:
    """The CSV of an earlier replay, which a failed one must not touch."""
    path = tmp_path / "est.csv"
    path.write_text("leg,t\nSB1_F1,1.0\n")
    return path


def _left_alone(path: Path) -> None:
    assert path.read_text() == "leg,t\nSB1_F1,1.0\n"
    assert sorted(p.name for p in path.parent.iterdir() if p.name.endswith(".part")) == []


def replay_into(log: Path, out: Path, config: Path = EXAMPLE_CONFIG) -> CompletedProcess[str]:
    return run_cli("replay", str(log), "--config", str(config), "--out", str(out))


def test_a_bad_config_leaves_the_output_as_it_was(tmp_path: Path, earlier: Path) -> None:
    """It was emptied: a typo in the config cost the CSV of the run before."""
    (tmp_path / "cycle.log").write_text(LOG)
    (tmp_path / "bad.toml").write_text("x = [\n")
    result = replay_into(tmp_path / "cycle.log", earlier, tmp_path / "bad.toml")
    assert_one_line_error(result, 2, "bad.toml: not valid TOML")
    _left_alone(earlier)


def test_a_missing_log_leaves_the_output_as_it_was(tmp_path: Path, earlier: Path) -> None:
    result = replay_into(tmp_path / "cylce.log", earlier)
    assert_one_line_error(result, 1, "cylce.log: no such file or directory")
    _left_alone(earlier)


@pytest.mark.parametrize("given", [["cylce.log"], ["cycle.log", "cylce.log"], ["cycle.asc"]])
def test_a_replay_to_stdout_that_fails_at_once_writes_nothing(
    tmp_path: Path, given: list[str]
) -> None:
    """It wrote the CSV's header (and the rows of the logs before a missing one), then
    the error: a pipe into another program took a header for an empty replay."""
    from daq.replay_command import replay_main

    (tmp_path / "cycle.log").write_text(LOG)
    (tmp_path / "cycle.asc").write_text(
        "date Wed Dec 02 11:31:04.171 am 2026\n0.0 1 1g0 Rx d 1 00\n"
    )
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = replay_main(
            [*(str(tmp_path / name) for name in given), "--config", str(EXAMPLE_CONFIG)]
        )
    assert (code, out.getvalue()) == (1, "")


def test_a_replay_that_is_done_replaces_the_output(tmp_path: Path, earlier: Path) -> None:
    (tmp_path / "cycle.log").write_text(LOG)
    result = replay_into(tmp_path / "cycle.log", earlier)
    assert result.returncode == 0, result.stderr
    rows = earlier.read_text().splitlines()
    assert rows[0].startswith("leg,t,force_N,") and len(rows) == 3
    assert [row.split(",")[0] for row in rows[1:]] == ["SB1_F1", "SB1_F1"]


@pytest.mark.parametrize(
    ("out", "reason"),
    [
        ("nowhere/est.csv", "nowhere/est.csv: cannot write it: No such file or directory"),
        (".", ": cannot write it: it is a directory"),
    ],
)
def test_an_output_that_cannot_be_written_is_one_line(
    tmp_path: Path, out: str, reason: str
) -> None:
    """It was Python's "[Errno 2] No such file or directory: '...'"."""
    (tmp_path / "cycle.log").write_text(LOG)
    result = replay_into(tmp_path / "cycle.log", tmp_path / out)
    assert_one_line_error(result, 1, reason)
    assert "Errno" not in result.stderr


@pytest.mark.parametrize("suffix", [".blf", ".log", ".trc"])
def test_an_empty_log_of_any_format_is_a_header_and_a_warning(tmp_path: Path, suffix: str) -> None:
    """0 bytes (the logger stopped at once): a BLF was "cannot read it as a CAN log:
    unpack requires a buffer of 72 bytes", exit 1, where the text logs gave the header."""
    log = tmp_path / f"empty{suffix}"
    log.write_bytes(b"")
    result = run_cli("replay", str(log), "--config", str(EXAMPLE_CONFIG))
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("leg,t,force_N,") and len(result.stdout.splitlines()) == 1
    assert "no CAN frame in it" in result.stderr


def test_a_recording_without_frames_is_a_header_and_a_warning(tmp_path: Path) -> None:
    """A service recording of no frame (the recorder had just opened it; or a truth file
    of ``portal-sim --truth-mcap``) gave the header alone and not a word, where a CAN log
    of none says so."""
    from daq.mcap_file import McapFile
    from tests.helpers import example_machine

    path = tmp_path / "opened.mcap"
    with open(path, "wb") as stream, McapFile(stream, example_machine()[1]) as mcap:
        mcap.start()
    result = run_cli("replay", str(path))
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("leg,t,force_N,") and len(result.stdout.splitlines()) == 1
    assert f"{path}: no CAN frame in it: the CSV has its header only" in result.stderr


def test_a_named_pipe_is_written_to_not_replaced(tmp_path: Path) -> None:
    """``--out /dev/null`` had /dev/null replaced by a regular file (the CSV written beside
    it, then renamed onto it): a device or pipe is written as it is. A named pipe stands
    in for /dev/null here, which a regression must not break on the test machine."""
    (tmp_path / "cycle.log").write_text(LOG)
    pipe = tmp_path / "estimates"
    os.mkfifo(pipe)
    read: list[str] = []
    reader = threading.Thread(target=lambda: read.append(pipe.read_text()), daemon=True)
    reader.start()
    result = replay_into(tmp_path / "cycle.log", pipe)
    reader.join(timeout=60)
    assert result.returncode == 0, result.stderr
    assert stat.S_ISFIFO(pipe.stat().st_mode)
    assert read[0].startswith("leg,") and read[0].count("\nSB1_F1,") == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cycle.log", "estimates"]


def test_a_symbolic_link_keeps_pointing_at_the_csv_it_names(tmp_path: Path) -> None:
    """``--out latest.csv`` a link to ``runs/42.csv``: the link was replaced by a regular
    file and ``42.csv`` kept the earlier estimates."""
    (tmp_path / "cycle.log").write_text(LOG)
    (tmp_path / "runs").mkdir()
    (tmp_path / "runs" / "42.csv").write_text("leg,t\n")
    link = tmp_path / "latest.csv"
    link.symlink_to(Path("runs") / "42.csv")
    result = replay_into(tmp_path / "cycle.log", link)
    assert result.returncode == 0, result.stderr
    assert link.is_symlink() and link.readlink() == Path("runs") / "42.csv"
    assert (tmp_path / "runs" / "42.csv").read_text().count("\nSB1_F1,") == 2
    assert sorted(p.name for p in (tmp_path / "runs").iterdir()) == ["42.csv"]


def test_a_replaced_output_keeps_its_permissions(tmp_path: Path, earlier: Path) -> None:
    """A results file made group-readable and read-only for others stays so."""
    (tmp_path / "cycle.log").write_text(LOG)
    earlier.chmod(0o640)
    result = replay_into(tmp_path / "cycle.log", earlier)
    assert result.returncode == 0, result.stderr
    assert earlier.read_text().count("\nSB1_F1,") == 2
    assert stat.S_IMODE(earlier.stat().st_mode) == 0o640


@pytest.mark.parametrize("name", ["cycle.log", "again.log"])
def test_an_output_that_names_the_log_replayed_is_refused(tmp_path: Path, name: str) -> None:
    """``replay cycle.log --out cycle.log`` replaced the log with its own CSV (exit 0): the
    recording was gone. Also under another name (a hard link) it is refused."""
    log = tmp_path / "cycle.log"
    log.write_text(LOG)
    if name != log.name:
        os.link(log, tmp_path / name)
    result = replay_into(log, tmp_path / name)
    assert_one_line_error(result, 1, f"{name}: --out names {log}, which this reads")
    assert log.read_text() == LOG
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.endswith(".part")) == []


@pytest.mark.parametrize("command", ["replay", "report"])
def test_a_log_mixed_with_a_service_recording_is_one_line(tmp_path: Path, command: str) -> None:
    """``replay cycle.log REC.mcap`` wrote the log's rows, then stopped at
    ``REC.mcap: cannot read it as a CAN log`` (exit 1); ``report REC.mcap cycle.log``
    said ``cycle.log: not an MCAP file``, while report takes CAN logs. Now one line
    before anything is read or written."""
    from tests.daq.test_export import recording

    (tmp_path / "cycle.log").write_text(LOG)
    rec = recording(tmp_path / "rec.mcap")
    for order in ((tmp_path / "cycle.log", rec), (rec, tmp_path / "cycle.log")):
        result = run_cli(command, *map(str, order), "--config", str(EXAMPLE_CONFIG),
                         "--out", str(tmp_path / "out"))  # fmt: skip
        assert_one_line_error(
            result, 1, f"cycle.log: a CAN log given with service recordings ({rec}): they "
            "are not one run; give one kind at a time"
        )  # fmt: skip
        assert result.stdout == "" and not (tmp_path / "out").exists()
