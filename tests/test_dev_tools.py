"""The developer tools around the tests: ``./dev``'s usage and the JUnit summary line."""

import subprocess
import sys
from pathlib import Path

from tests.helpers import ROOT

JUNIT = """<?xml version="1.0" encoding="utf-8"?><testsuites><testsuite name="pytest" errors="0"
failures="1" skipped="2" tests="5"><testcase classname="t" name="a"><skipped
type="pytest.xfail" message="known defect" /></testcase><testcase classname="t" name="b" />
<testcase classname="t" name="c"><skipped type="pytest.skip" message="no">x</skipped>
</testcase><testcase classname="t" name="d"><failure message="boom">x</failure></testcase>
<testcase classname="t" name="e" /></testsuite></testsuites>"""


def summarize(*paths: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(ROOT / "tests" / "summarize_junit.py"), *map(str, paths)],
        capture_output=True,
        text=True,
        timeout=60,
    )


def test_the_summary_calls_an_xfail_xfailed_not_skipped(tmp_path: Path) -> None:
    report = tmp_path / "host.xml"
    report.write_text(JUNIT)
    result = summarize(report, report)
    assert result.stdout == "4 passed, 2 failed, 2 skipped, 2 xfailed\n"
    assert result.returncode == 1
    clean = tmp_path / "clean.xml"
    clean.write_text(JUNIT.replace('<failure message="boom">x</failure>', ""))
    passing = summarize(clean)
    assert (
        passing.returncode == 0 and passing.stdout == "3 passed, 0 failed, 1 skipped, 1 xfailed\n"
    )


def test_dev_without_arguments_prints_its_usage() -> None:
    result = subprocess.run(
        [str(ROOT / "dev")], capture_output=True, text=True, timeout=60, cwd=ROOT
    )
    assert result.returncode == 2
    lines = result.stderr.splitlines()
    assert lines[0] == "usage: ./dev COMMAND [ARGS...]"
    for command in ("demo", "test", "setup"):
        assert any(line.split()[:1] == [command] for line in lines), result.stderr
    assert "set -" not in result.stderr and "cd " not in result.stderr
    helped = subprocess.run(
        [str(ROOT / "dev"), "--help"], capture_output=True, text=True, timeout=60, cwd=ROOT
    )
    assert helped.returncode == 0 and helped.stdout.startswith("usage: ./dev")
