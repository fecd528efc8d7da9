"""The with-vcan harness itself (runs on the host): exit statuses cross the UML boundary,
so a failing vcan test fails ``./dev test`` and CI."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.helpers import ROOT

WITH_VCAN = ROOT / "tests" / "vcan" / "with-vcan"

pytestmark = pytest.mark.skipif(
    os.environ.get("PORTAL_VCAN_GUEST") == "1", reason="already inside the UML guest"
)


def run(*command: str, cwd: Path = ROOT) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "PORTAL_FORCE_UML": "1"}
    return subprocess.run(
        [str(WITH_VCAN), *command], cwd=cwd, env=env, capture_output=True, text=True, timeout=300
    )


def test_exit_status_of_the_guest_command_is_returned() -> None:
    assert run("sh", "-c", "exit 3").returncode == 3
    done = run("sh", "-c", "ip -o link show vcan0; echo guest=$PORTAL_VCAN_GUEST")
    assert done.returncode == 0
    assert ",UP" in done.stdout  # the interface flags, e.g. <NOARP,UP,LOWER_UP>
    assert "guest=1" in done.stdout


def test_a_failing_vcan_test_fails_the_run(tmp_path: Path) -> None:
    failing = tmp_path / "test_fails_on_vcan.py"
    failing.write_text(
        "import pathlib, pytest\n"
        "@pytest.mark.vcan\n"
        "def test_vcan0_is_there_but_this_fails():\n"
        "    assert pathlib.Path('/sys/class/net/vcan0').exists()\n"
        "    assert 1 + 1 == 3\n"
    )
    result = run(
        sys.executable,
        "-m",
        "pytest",
        "-p",
        "no:cacheprovider",
        "-q",
        "-m",
        "vcan",
        "--rootdir",
        str(tmp_path),
        "-c",
        os.devnull,
        str(failing),
    )
    assert result.returncode == 1, result.stdout
    lines = [line for line in result.stdout.splitlines() if line.strip()]
    assert "1 failed" in lines[-1]
