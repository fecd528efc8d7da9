"""The installed wheel works outside the repository: ``portal-sim`` (with the packaged
example machine config as its default), ``portal-sim plot`` and ``portal-daq``.

The wheel is built with ``pip wheel --no-deps`` from a copy of the source tree (so the
checkout gets no ``build/``), installed into a fresh venv with its dependencies from the
same package index this machine's pip uses, and run from a directory that is not the
repository, with nothing of the repository on ``sys.path``.
"""

from __future__ import annotations

import ast
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tarfile
import tomllib
from importlib import metadata
from pathlib import Path

import pytest

from tests.daq.service_support import WAIT_S, free_port, write_service_config
from tests.helpers import ROOT

IGNORE = shutil.ignore_patterns(
    ".git", ".venv", "build", "dist", "*.egg-info", "__pycache__", ".*_cache", ".hypothesis"
)


def run(*args: str | Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    return subprocess.run(
        [str(a) for a in args], capture_output=True, text=True, timeout=900, cwd=cwd, env=env
    )


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    work = tmp_path_factory.mktemp("wheel")
    source = work / "source"
    shutil.copytree(ROOT, source, symlinks=True, ignore=IGNORE)
    built = run(sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", work / "dist",
                source, cwd=work)  # fmt: skip
    assert built.returncode == 0, built.stderr
    (built_wheel,) = (work / "dist").glob("portal_daq-*.whl")
    return built_wheel


def fresh_venv(where: Path, *requirements: str | Path) -> Path:
    """A venv at ``where`` with ``requirements`` pip-installed into it."""
    assert run(sys.executable, "-m", "venv", where, cwd=where.parent).returncode == 0
    installed = run(where / "bin" / "python", "-m", "pip", "install", "-q", *requirements,
                    cwd=where.parent)  # fmt: skip
    assert installed.returncode == 0, installed.stderr
    return where


@pytest.fixture(scope="module")
def venv(wheel: Path) -> Path:
    return fresh_venv(wheel.parent.parent / "venv", wheel)


def oldest_requirements() -> list[str]:
    """Each dependency of pyproject.toml at the version its lower bound names:
    ``numpy>=1.26,<3`` gives ``numpy==1.26``."""
    dependencies = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    return [re.sub(r">=([\d.]+),<[\d.]+$", r"==\1", d) for d in dependencies]


def installed_default_config(venv: Path, cwd: Path, module: str = "sim_bridge._args") -> Path:
    """``module.DEFAULT_CONFIG`` as the installed package has it."""
    code = f"import {module} as a; print(a.DEFAULT_CONFIG)"
    where = run(venv / "bin" / "python", "-c", code, cwd=cwd)
    assert where.returncode == 0, where.stderr
    return Path(where.stdout.strip())


def test_the_wheel_ships_the_example_config_as_the_simulators_default(venv: Path) -> None:
    elsewhere = venv.parent / "elsewhere"
    elsewhere.mkdir(exist_ok=True)
    default = installed_default_config(venv, elsewhere)
    assert default.is_file() and default.is_relative_to(venv), default
    assert not default.is_relative_to(ROOT)
    # `portal-daq router`'s default, the site router's config (deploy/ is not in a wheel)
    router = installed_default_config(venv, elsewhere, "daq.router")
    assert router.is_file() and router.is_relative_to(venv), router
    assert "tcp/0.0.0.0:7447" in router.read_text()
    # every package is typed for the programs that import it (mypy strict on all four)
    site = next(venv.glob("lib/python*/site-packages"))
    for package in ("daq", "dbc", "estimator", "sim_bridge"):
        assert (site / package / "py.typed").is_file(), package
    # license = "MIT" in pyproject.toml, and its text ships with the wheel
    (license_file,) = venv.glob("lib/python*/site-packages/portal_daq-*.dist-info/licenses/LICENSE")
    assert license_file.read_text().startswith("MIT License")


def test_portal_sim_and_plot_run_from_another_directory(venv: Path) -> None:
    elsewhere = venv.parent / "elsewhere"
    elsewhere.mkdir(exist_ok=True)
    sim = run(venv / "bin" / "portal-sim", "--interface", "virtual", "--as-fast-as-possible",
              "--rtol", "1e-3", "--duration", "0.3", "--frames-log", "cycle.log",
              "--truth-csv", "truth.csv", cwd=elsewhere)  # fmt: skip
    assert sim.returncode == 0, sim.stderr
    assert len((elsewhere / "truth.csv").read_text().splitlines()) == 1 + 30
    plot = run(venv / "bin" / "portal-sim", "plot", "--rtol", "1e-3", "--out", "cycle.png",
               cwd=elsewhere)  # fmt: skip
    assert plot.returncode == 0, plot.stderr
    assert (elsewhere / "cycle.png").read_bytes().startswith(b"\x89PNG")
    default = installed_default_config(venv, elsewhere)
    replayed = run(venv / "bin" / "portal-daq", "replay", "cycle.log", "--config", default,
                   cwd=elsewhere)  # fmt: skip
    assert replayed.returncode == 0, replayed.stderr
    assert len(replayed.stdout.splitlines()) == 1 + 6 * 30
    listed = run(venv / "bin" / "portal-daq", "--help", cwd=elsewhere)
    assert listed.returncode == 0
    assert all(f"  {name} " in listed.stdout for name in ("run", "replay", "report"))


def test_init_writes_an_example_the_installed_service_takes(venv: Path) -> None:
    """A user with the wheel alone gets the J1939 machine's config, DBC and Zenoh file,
    and the simulator and replay take them from there (the estimates of every leg)."""
    elsewhere = venv.parent / "elsewhere-init"
    elsewhere.mkdir(exist_ok=True)
    init = run(venv / "bin" / "portal-daq", "init", "j1939", "--example", "j1939", cwd=elsewhere)
    assert init.returncode == 0, init.stderr
    written = sorted(p.name for p in (elsewhere / "j1939").iterdir())
    assert written == ["portal-daq.toml", "transducers_j1939.dbc", "zenoh.json5"]
    config = Path("j1939") / "portal-daq.toml"
    sim = run(venv / "bin" / "portal-sim", "--config", config, "--interface", "virtual",
              "--as-fast-as-possible", "--rtol", "1e-3", "--duration", "0.3",
              "--frames-log", "j1939.log", cwd=elsewhere)  # fmt: skip
    assert sim.returncode == 0, sim.stderr
    replayed = run(venv / "bin" / "portal-daq", "replay", "j1939.log", "--config", config,
                   cwd=elsewhere)  # fmt: skip
    assert replayed.returncode == 0, replayed.stderr
    legs = {line.split(",")[0] for line in replayed.stdout.splitlines()[1:]}
    assert legs == {"SB1_F1", "SB1_F2", "SB1_F3", "SB2_F1", "SB2_F2", "SB2_F3"}


def test_the_wheel_carries_the_deployment_kit(venv: Path) -> None:
    """A user with the wheel alone had no install.sh, unit or drop-ins (deploy/ is not in a
    wheel): `portal-daq init DIR --deploy` writes them, the script executable."""
    elsewhere = venv.parent / "elsewhere-deploy"
    elsewhere.mkdir(exist_ok=True)
    init = run(venv / "bin" / "portal-daq", "init", "machine", "--deploy", cwd=elsewhere)
    assert init.returncode == 0, init.stderr
    kit = elsewhere / "machine" / "deploy"
    unit = kit / "systemd" / "portal-daq.service"
    assert unit.read_bytes() == (ROOT / "deploy" / "systemd" / "portal-daq.service").read_bytes()
    assert (kit / "sysctl" / "90-portal-daq.conf").is_file()
    helped = run(kit / "install.sh", "--help", cwd=elsewhere)
    assert helped.returncode == 0 and "--package SPEC" in helped.stdout
    assert "deploy/install.sh --package WHEEL" in init.stderr


def test_the_oldest_dependencies_it_admits_run_it(wheel: Path) -> None:
    """pip keeps an installed dependency that meets the bound: the wheel must run on the
    oldest of each. ``cantools>=40``, ``eclipse-zenoh>=1.0``, ``python-can>=4.4`` and
    ``mcap>=1.2`` were admitted, and every command was an ImportError or AttributeError
    traceback (cantools' UnsupportedDatabaseFormatError, zenoh.ext's HistoryConfig, can.io.blf's
    TIME_ONE_NANS_FACTOR), or the service exited 1 at start (mcap's Writer.flush)."""
    oldest = fresh_venv(wheel.parent.parent / "oldest", *oldest_requirements())
    installed = run(oldest / "bin" / "python", "-m", "pip", "install", "-q", "--no-deps",
                    wheel, cwd=oldest.parent)  # fmt: skip
    assert installed.returncode == 0, installed.stderr
    elsewhere = oldest.parent / "elsewhere-oldest"
    elsewhere.mkdir()
    listed = run(oldest / "bin" / "portal-daq", "--help", cwd=elsewhere)  # imports every command
    assert listed.returncode == 0, listed.stderr
    sim = run(oldest / "bin" / "portal-sim", "--interface", "virtual", "--as-fast-as-possible",
              "--rtol", "1e-3", "--duration", "0.3", "--frames-log", "cycle.log",
              "--truth-mcap", "truth.mcap", cwd=elsewhere)  # fmt: skip
    assert sim.returncode == 0, sim.stderr
    config = write_service_config(elsewhere, port=free_port(), recording=elsewhere / "rec")
    replayed = run(oldest / "bin" / "portal-daq", "replay", "cycle.log", "--config", config,
                   cwd=elsewhere)  # fmt: skip
    assert replayed.returncode == 0, replayed.stderr
    assert len(replayed.stdout.splitlines()) == 1 + 6 * 30
    reported = run(oldest / "bin" / "portal-daq", "report", "cycle.log", "--config", config,
                   "--out", "report", cwd=elsewhere)  # fmt: skip
    assert reported.returncode == 0, reported.stderr
    assert (elsewhere / "report" / "pressure.png").read_bytes().startswith(b"\x89PNG")
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as notify:
        notify.bind(str(elsewhere / "notify.sock"))
        notify.settimeout(WAIT_S)
        service = subprocess.Popen(
            [oldest / "bin" / "portal-daq", "run", "--config", config], cwd=elsewhere,
            env=dict(os.environ, NOTIFY_SOCKET=str(elsewhere / "notify.sock")),
            stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        try:
            ready = notify.recv(4096)
        except TimeoutError:
            ready = b""
        service.send_signal(signal.SIGTERM)
        stderr = service.communicate(timeout=WAIT_S)[1]
    assert (ready, service.returncode) == (b"READY=1", 0), stderr
    (recording,) = (elsewhere / "rec").glob("*.mcap")
    recovered = run(oldest / "bin" / "portal-daq", "export", recording, "--to", "candump",
                    cwd=elsewhere)  # fmt: skip
    assert recovered.returncode == 0, recovered.stderr


def test_the_sdist_holds_the_repository_and_its_tests_run(wheel: Path) -> None:
    """The sdist held the packages and two test modules: no tests/files, deploy/, bench/
    or ./dev, which the tests read, so its tests could not run (MANIFEST.in)."""
    if not (ROOT / ".git").exists():
        pytest.skip("compares the sdist with the files git tracks")
    tracked = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True,
                             text=True, check=True).stdout.strip("\0").split("\0")  # fmt: skip
    work = wheel.parent.parent
    builder = fresh_venv(work / "sdist-builder", "setuptools>=77")
    code = "import sys, setuptools.build_meta as b; print(b.build_sdist(sys.argv[1]))"
    built = run(builder / "bin" / "python", "-c", code, work / "sdist", cwd=work / "source")
    assert built.returncode == 0, built.stderr
    with tarfile.open(work / "sdist" / built.stdout.split()[-1]) as sdist:
        sdist.extractall(work / "sdist", filter="data")
        top, *_ = sdist.getnames()
    unpacked = work / "sdist" / top
    assert [name for name in tracked if not (unpacked / name).exists()] == []
    # deploy/'s links are copies in an sdist; the tests of the packaged kit take them
    tests = run(sys.executable, "-m", "pytest", "-q", "-p", "no:randomly", "-p", "no:cacheprovider",
                "tests/deploy/test_deploy.py::test_init_writes_the_deployment_kit_of_the_repository",
                "tests/daq/test_router_command.py::test_the_default_config_is_the_packaged_site_router",
                "tests/daq/test_init_command.py", cwd=unpacked)  # fmt: skip
    assert tests.returncode == 0, tests.stdout


PACKAGES = ("daq", "dbc", "estimator", "sim_bridge")


def imported_modules() -> set[str]:
    """The top-level modules the packages import (absolute imports, any depth)."""
    found = set()
    for path in (path for package in PACKAGES for path in (ROOT / package).rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                found |= {alias.name.partition(".")[0] for alias in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                found.add(node.module.partition(".")[0])
    return found


def test_every_module_it_imports_is_a_declared_dependency() -> None:
    """``zstandard`` (daq/mcap_reading.py) was imported but not declared: it came with
    mcap, which may stop requiring it, and the lower-bound test could not pin it."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    declared = set()
    for requirement in [
        *project["dependencies"],
        *sum(project["optional-dependencies"].values(), []),
    ]:
        name, extras = re.match(r"([\w.-]+)(?:\[([\w,.-]+)\])?", requirement).groups()
        declared |= {name.lower(), *(extras or "").split(",")}
    distributions = metadata.packages_distributions()
    undeclared = {
        module: distributions.get(module)
        for module in imported_modules() - set(PACKAGES) - sys.stdlib_module_names
        if not {d.lower() for d in distributions.get(module, [module])} & declared
    }
    assert undeclared == {}
