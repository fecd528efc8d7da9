"""The campaign benchmark runs end to end on two tiny recordings (no timing asserted)."""

from pathlib import Path

from bench.campaign import main, run_benchmark


def test_the_campaign_benchmark_reports_every_executor(tmp_path: Path) -> None:
    results = run_benchmark(2, 0.5, dask=True)
    assert results["recordings"] == 2 and results["rows"] == 2 * 6  # one cycle, six feet
    assert results["rows_equal"] is True and results["dask_rows_equal"] is True
    for key in ("one_process_s", "local_processes_s", "dask_local_cluster_s"):
        assert results[key] > 0
    assert results["local_speedup"] == results["one_process_s"] / results["local_processes_s"]
    out = tmp_path / "results.json"
    assert main(["--recordings", "1", "--seconds", "0.3", "--no-dask", "--out", str(out)]) == 0
    assert '"local_speedup"' in out.read_text()
