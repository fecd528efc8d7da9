"""The benchmark runs end to end on a few frames and reports in the documented shape.

No timing is asserted: this only checks that the benchmark works (real service
threads, Zenoh on loopback, the probe process, MCAP into a temporary directory).
"""

import json
import logging
from pathlib import Path

import pytest

from bench.report import markdown_table
from bench.run import main, run_benchmark

MODES = ("throughput", "paced", "paced_hog", "nominal")
SYSTEMS = ("pipeline", "pipeline_threads", "pipeline_tuned", "pipeline_coalesced", "baseline")
LATENCY_KEYS = {"count", "median", "p90", "p99", "p99_9", "mean", "max"}


@pytest.fixture(scope="module")
def results() -> dict:
    return run_benchmark(
        throughput_frames=300,
        rounds=2,
        paced_s=0.05,
        nominal_s=0.05,
        rate_hz=2000.0,
        warmup=50,
        pin=False,
    )


def test_every_system_and_mode_is_reported(results: dict) -> None:
    for system in SYSTEMS:
        for mode in MODES:
            r = results[system][mode]
            assert r["mode"] == mode
            assert r["processed"] == r["frames"] > 0
            assert r["frames_per_s"] > 0
            assert r["leg_estimates_received"] == r["leg_estimates_expected"] > 0
            assert set(r["latency_ms"]) == LATENCY_KEYS
            assert r["latency_ms"]["count"] == r["leg_estimates_received"]
            assert r["cpu_us_per_frame"]["total"] > 0 and r["service_cpu_pct"] >= 0
        assert set(results[system]["paced"]["latency_from_due_ms"]) == LATENCY_KEYS
    assert results["pipeline"]["nominal"]["frames"] == round(0.05 * 1010.0)  # the DBC's rate


def test_each_system_reports_its_fastest_round(results: dict) -> None:
    for system in SYSTEMS:
        rounds = results[system]["throughput_rounds"]
        assert len(rounds) == 2
        fastest = max(rounds, key=lambda r: r["frames_per_s"])
        throughput = results[system]["throughput"]
        assert throughput["frames_per_s"] == fastest["frames_per_s"]
        assert throughput["cpu_us_per_frame"]["total"] == fastest["cpu_us_per_frame"]
    assert results["setup"]["throughput_rounds"] == 2


def test_the_service_checked_and_recorded_everything(results: dict) -> None:
    for system in SYSTEMS[:-1]:
        counters = results[system]["counters"]
        assert counters["bad"] == {}  # every simulated frame passes its CRC and counter
        assert not any(counters["dropped"].values())
        frames = 50 + 2 * 300 + 2 * 100 + 50  # warm-up, 2 rounds, paced twice, nominal
        assert counters["frames_processed"] == frames
        recording = results[system]["recording"]
        assert recording["files"] == 1 and recording["bytes"] > 0
        offered = results[system]["offered"]
        assert offered["frames"] == frames
        assert recording["raw_frames"] == frames
        assert recording["messages"]["can"] < frames  # batches
        assert recording["leg_estimates"] == offered["leg_frames"]
        assert recording["messages"]["leg"] < offered["leg_frames"]  # a batch per leg
    # As deployed: signals neither recorded nor published with every frame; the
    # comparison variant: the earlier defaults, every frame's signals.
    assert "signals" not in results["pipeline"]["recording"]["messages"]
    assert results["pipeline_tuned"]["recording"]["messages"]["signals"] == frames
    assert results["pipeline"]["settings"] == {}
    assert results["pipeline_threads"]["settings"] == {"service": "event_loop = false"}
    assert results["pipeline_coalesced"]["settings"] == {"service": "poll_period_ms = 20"}


def test_machine_setup_ratio_and_targets(results: dict) -> None:
    machine = results["machine"]
    assert machine["cpu"] and machine["cores"] >= 1 and machine["python"].startswith("3.")
    assert machine["wakeup_cpu_us"] > 0  # a sleep costs something, on any machine
    assert results["setup"]["pinned_cpu"] is None  # pin=False
    assert results["setup"]["frame_mix"]["LEG_SB1_F1"] > 0
    assert results["ratio_frames_per_s"] > 0 and results["ratio_frames_per_s_tuned"] > 0
    assert results["ratio_cpu_per_frame"] > 0
    assert set(results["targets_coalesced"]) == set(results["targets_tuned"])
    assert set(results["targets_tuned"]) == set(results["targets_threads"])
    assert set(results["targets_threads"]) == set(results["targets"])
    assert set(results["targets"]) == {
        "frames_per_s_at_least_baseline",
        "cpu_per_frame_at_most_baseline",
        "nothing_lost",
        "paced_p99_under_1ms",
        "paced_with_cpu_hog_p99_under_1ms",
        "nominal_rate_cpu_at_most_2pct",
    }
    assert results["targets"]["nothing_lost"] is True
    assert all(isinstance(met, bool) for met in results["targets"].values())
    json.dumps(results)  # what bench/results.json holds


def test_markdown_table_has_a_row_per_system_and_mode(results: dict) -> None:
    table = markdown_table(results)
    rows = [line for line in table.splitlines() if line.startswith("| ") and "---" not in line]
    assert len(rows) == 1 + len(SYSTEMS) * len(MODES)
    assert "| service, wake-ups coalesced (poll_period_ms = 20) |" in table
    assert "Service, wake-ups coalesced: " in table
    assert "Machine: " in table and "x the baseline's frames/s" in table and "load average" in table
    wakeup_us = results["machine"]["wakeup_cpu_us"]
    floor_pct = wakeup_us * 1010.0 / 1e4  # a wake-up per frame at the DBC's rate, % of a CPU
    assert f"costs {wakeup_us:.1f} us of CPU here" in table
    assert f"1,010/s is {floor_pct:.1f} % of a CPU" in table


def test_command_line_writes_the_results_file(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "results.json"
    argv = ["--throughput-frames", "100", "--paced-s", "0.02", "--rate", "2000", "--warmup", "20"]
    argv += ["--nominal-s", "0.02"]
    level = logging.getLogger("daq").level
    assert main([*argv, "--no-pin", "--no-tuned", "--out", str(out)]) == 0
    assert logging.getLogger("daq").level == level  # quiet while measuring only
    written = json.loads(out.read_text())
    assert not any(name in written for name in SYSTEMS[1:-1])
    assert written["pipeline"]["paced"]["frames"] == 40
    assert "| service (as deployed) |" in capsys.readouterr().out
