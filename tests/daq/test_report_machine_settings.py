"""The report and replay of a machine configured unlike the example: the filter named as
configured, a leg whose cycle time is shorter than the period it is sent at told as such."""

from __future__ import annotations

import io
import logging
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from daq.report.command import report_main
from tests.helpers import EXAMPLE_CONFIG


@pytest.fixture(autouse=True)
def _no_handler_left_behind() -> Iterator[None]:
    """``report_main`` binds the root logger to this test's captured stderr."""
    before = list(logging.getLogger().handlers)
    yield
    for handler in list(logging.getLogger().handlers):
        if handler not in before:
            logging.getLogger().removeHandler(handler)


@pytest.fixture(scope="module")
def cycle_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One simulated second of the example machine (every leg each 10 ms) as a candump log."""
    from sim_bridge.__main__ import cli

    log = tmp_path_factory.mktemp("log") / "cycle.log"
    args = ["--interface", "virtual", "--channel", f"log-{uuid.uuid4()}", "--as-fast-as-possible"]
    assert cli([*args, "-q", "--duration", "1", "--frames-log", str(log)]) == 0
    return log


def page(tmp_path: Path, log: Path, config_text: str) -> str:
    config = tmp_path / "machine.toml"
    config.write_text(config_text)
    out = tmp_path / "r"
    assert report_main([str(log), "--config", str(config), "--out", str(out)]) == 0
    return (out / "report.html").read_text()


def test_the_filter_is_named_as_configured(tmp_path: Path, cycle_log: Path) -> None:
    text = EXAMPLE_CONFIG.read_text().replace('filter = "median"', 'filter = "hampel"', 1)
    shown = page(tmp_path, cycle_log, text)
    # It said "running median of eq. 4" whatever the filter.
    assert "Filtered estimates (eq. 4 through the causal Hampel filter, window 7" in shown
    assert "running median" not in shown


def test_a_leg_sent_slower_than_its_cycle_time_is_told_so(tmp_path: Path, cycle_log: Path) -> None:
    # LEG_SB1_F1 comes every 10 ms; a cycle time of 3 ms makes its stale time 9 ms, so
    # every step was a "silence" and nothing said why.
    text = EXAMPLE_CONFIG.read_text() + "\n[messages.LEG_SB1_F1]\ncycle_time_ms = 3\n"
    shown = page(tmp_path, cycle_log, text)
    silent = shown.split("legs silent")[1].split("</tr>")[0]
    assert "SB1_F1 " in silent and "SB1_F2" not in silent
    assert (
        "(at every step: it is sent every 10 ms, over its stale time of 9 ms, 3 x the cycle "
        "time of LEG_SB1_F1, 3 ms: the median, contact and near-constant window restarted "
        "at each sample; set [messages.LEG_SB1_F1] cycle_time_ms)"
    ) in silent
    assert "at every step" not in page(tmp_path, cycle_log, EXAMPLE_CONFIG.read_text())


def test_replay_says_which_legs_restarted_at_every_sample(
    tmp_path: Path, cycle_log: Path, caplog: pytest.LogCaptureFixture
) -> None:
    from daq.replay import replay

    config = tmp_path / "machine.toml"
    config.write_text(EXAMPLE_CONFIG.read_text() + "\n[messages.LEG_SB1_F1]\ncycle_time_ms = 3\n")
    with caplog.at_level(logging.WARNING, logger="daq.leg_restarts"):
        assert replay(cycle_log, io.StringIO(), config) == 600
    # Its rows look valid; only this line tells the median never filtered anything.
    assert [r.getMessage() for r in caplog.records] == [
        "legs.SB1_F1: 99 of its 100 valid samples came more than its stale time (9 ms: 3 x "
        "its cycle time, 3 ms) after the one before, so the filter, contact and "
        "near-constant window restarted at each (force_N is force_raw_N): is it sent less "
        "often? set its cycle time ([messages.LEG_SB1_F1] cycle_time_ms)"
    ]
