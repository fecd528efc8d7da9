"""deploy/: the systemd unit passes systemd-analyze, the install script installs into a root."""

import configparser
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from daq.cli import main
from daq.service_config import BusSettings
from tests.helpers import ROOT, assert_links_to

DEPLOY = ROOT / "deploy"
UNIT = DEPLOY / "systemd" / "portal-daq.service"

needs_systemd = pytest.mark.skipif(
    shutil.which("systemd-analyze") is None, reason="needs systemd-analyze (Debian: systemd)"
)


def unit_sections(path: Path) -> configparser.ConfigParser:
    parser = configparser.ConfigParser(strict=False, interpolation=None)
    parser.optionxform = str  # type: ignore[assignment,method-assign]
    parser.read(path)
    return parser


def test_unit_has_notify_watchdog_restart_user_state_and_hardening() -> None:
    unit = unit_sections(UNIT)
    service = unit["Service"]
    assert service["Type"] == "notify"
    assert service["WatchdogSec"] == "10s"
    assert service["Restart"] == "on-failure"
    assert service["RestartPreventExitStatus"] == "2"  # a bad config: no restart loop
    assert service["User"] == "portal-daq"
    assert service["StateDirectory"] == "portal-daq"
    assert service["ProtectSystem"] == "strict"
    assert service["NoNewPrivileges"] == "yes"
    assert set(service["RestrictAddressFamilies"].split()) == {
        "AF_CAN",
        "AF_NETLINK",
        "AF_UNIX",
        "AF_INET",
        "AF_INET6",
    }
    assert unit["Unit"]["BindsTo"] == "sys-subsystem-net-devices-can0.device"
    assert "sys-subsystem-net-devices-can0.device" in unit["Unit"]["After"].split()


@needs_systemd
def test_unit_passes_systemd_analyze_verify(tmp_path: Path) -> None:
    # verify checks that ExecStart exists: point it at this checkout's console script.
    executable = str(Path(sys.executable).with_name("portal-daq"))
    text = UNIT.read_text().replace("/opt/portal-daq/venv/bin/portal-daq", executable)
    unit = tmp_path / "portal-daq.service"
    unit.write_text(text)
    result = subprocess.run(
        ["systemd-analyze", "verify", "--man=no", str(unit)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 0, result.stderr
    # verify exits 0 on ignored lines too; any complaint about our file is a failure.
    complaints = [line for line in result.stderr.splitlines() if "portal-daq.service" in line]
    assert complaints == []


@needs_systemd
def test_systemd_analyze_catches_a_broken_unit(tmp_path: Path) -> None:
    unit = tmp_path / "portal-daq.service"
    unit.write_text(UNIT.read_text().replace("ProtectSystem=strict", "ProtectSystem=sometimes"))
    result = subprocess.run(
        ["systemd-analyze", "verify", "--man=no", str(unit)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert "ProtectSystem" in result.stderr or "protect system" in result.stderr


def test_sysctl_drop_in_allows_the_default_can_receive_buffer() -> None:
    lines = (DEPLOY / "sysctl" / "90-portal-daq.conf").read_text().splitlines()
    pairs = [line.split("=", 1) for line in lines if line.strip() and not line.startswith("#")]
    settings = {key.strip(): value.strip() for key, value in pairs}
    rmem_max = int(settings["net.core.rmem_max"])
    # SO_RCVBUF without CAP_NET_ADMIN is clamped to rmem_max: it must not clamp the default.
    assert rmem_max >= BusSettings().receive_buffer_bytes


def test_networkd_brings_can0_up_with_bitrate_and_bus_off_restart() -> None:
    can0 = unit_sections(DEPLOY / "network" / "80-can0.network")
    assert can0["Match"]["Name"] == "can0"
    assert can0["CAN"]["BitRate"] == "500000"
    assert can0["CAN"]["RestartSec"] == "100ms"
    vcan = unit_sections(DEPLOY / "network" / "80-vcan0.netdev")
    assert (vcan["NetDev"]["Name"], vcan["NetDev"]["Kind"]) == ("vcan0", "vcan")


@needs_systemd
def test_install_script_into_a_temporary_root(tmp_path: Path) -> None:
    root = tmp_path / "root"
    subprocess.run(
        [str(DEPLOY / "install.sh"), "--root", str(root), "--with-vcan"],
        check=True,
        capture_output=True,
        text=True,
        timeout=600,
    )
    venv = root / "opt/portal-daq/venv"
    help_text = subprocess.run(
        [str(venv / "bin/portal-daq"), "--help"], check=True, capture_output=True, text=True
    ).stdout
    assert "--config" in help_text
    config = root / "etc/portal-daq/portal-daq.toml"
    assert config.is_file() and (root / "etc/portal-daq/zenoh.json5").is_file()
    # The installed example configuration loads with the installed package.
    subprocess.run(
        [
            str(venv / "bin/python"),
            "-c",
            "import sys; from daq.service_config import load_service_config;"
            " load_service_config(sys.argv[1])",
            str(config),
        ],
        check=True,
        timeout=60,
    )
    unit = root / "etc/systemd/system/portal-daq.service"
    assert unit.read_text() == UNIT.read_text()
    enabled = root / "etc/systemd/system/multi-user.target.wants/portal-daq.service"
    assert enabled.is_symlink()
    assert (root / "etc/systemd/network/80-can0.network").is_file()
    assert (root / "etc/systemd/network/80-vcan0.netdev").is_file()
    assert (root / "etc/sysctl.d/90-portal-daq.conf").is_file()
    passwd = (root / "etc/passwd").read_text()
    assert any(line.startswith("portal-daq:") for line in passwd.splitlines())

    assert (root / "etc/portal-daq/portal_sensors.dbc").is_file()
    assert (root / "opt/portal-daq/README.md").read_text() == (ROOT / "README.md").read_text()

    # A second install keeps the operator's configuration; this time from the kit an
    # installed package writes (`portal-daq init DIR --deploy`: a wheel has no deploy/).
    config.write_text(config.read_text() + "\n# edited by the operator\n")
    kit = tmp_path / "kit"
    subprocess.run([str(venv / "bin/portal-daq"), "init", str(kit), "--deploy"], check=True)
    subprocess.run(
        [str(kit / "deploy/install.sh"), "--root", str(root), "--package", str(ROOT),
         "--pip-args", "--no-deps"],
        check=True,
        capture_output=True,
        timeout=600,
    )  # fmt: skip
    assert config.read_text().endswith("# edited by the operator\n")
    assert unit.read_text() == UNIT.read_text()


def test_install_help_is_the_whole_header() -> None:
    helped = subprocess.run(
        [str(DEPLOY / "install.sh"), "--help"], capture_output=True, text=True, check=True
    ).stdout
    assert helped.startswith("# install.sh: install portal-daq")
    assert helped.rstrip().endswith("(extra arguments for pip install, e.g. --no-deps).")


@needs_systemd
@pytest.mark.parametrize(
    ("interface", "channel", "bound_to", "network"),
    [
        ("socketcan", "can-1", r"sys-subsystem-net-devices-can\x2d1.device", "80-can-1.network"),
        ("socketcan", "vcan0", "sys-subsystem-net-devices-vcan0.device", None),
        ("virtual", "can1", None, None),
    ],
    ids=["can_1", "vcan0", "not_socketcan"],
)
def test_the_installed_unit_is_bound_to_the_configured_channel(
    tmp_path: Path, interface: str, channel: str, bound_to: str | None, network: str | None
) -> None:
    # The unit waited for can0 whatever [bus] channel said: on a machine whose sensors are
    # on another interface, or a bench on vcan0, its start never came.
    kit = tmp_path / "kit"
    assert main(["init", str(kit), "--deploy"]) == 0
    config = kit / "portal-daq.toml"
    text = config.read_text()
    edited = text.replace('interface = "socketcan"', f'interface = "{interface}"', 1)
    config.write_text(edited.replace('channel = "can0"', f'channel = "{channel}"', 1))
    root = tmp_path / "root"
    said = subprocess.run(
        [str(kit / "deploy/install.sh"), "--root", str(root), "--package", str(ROOT),
         "--pip-args", "--no-deps"],
        check=True, capture_output=True, text=True, timeout=600,
    ).stdout  # fmt: skip
    # networkd, off in a Debian of ifupdown, brings the link up: said where it is not on
    # (the root here has none), as the link stayed down after a reboot, unsaid.
    assert ("warning: systemd-networkd is not installed here" in said) == (network is not None)
    if network is not None:
        assert f"nothing reads {network} at boot, and {channel} is not brought up" in said
    installed = root / "etc/systemd/system/portal-daq.service"
    unit, install = unit_sections(installed)["Unit"], unit_sections(installed)["Install"]
    assert "devices-can0" not in installed.read_text()
    if bound_to is None:
        assert "BindsTo" not in unit
        assert unit["After"].split() == ["network-online.target"]
        assert install["WantedBy"].split() == ["multi-user.target"]
    else:
        assert unit["BindsTo"] == bound_to
        assert unit["After"].split() == [bound_to, "network-online.target"]
        assert install["WantedBy"].split() == ["multi-user.target", bound_to]
        assert (root / f"etc/systemd/system/{bound_to}.wants/portal-daq.service").is_symlink()
    networks = sorted(path.name for path in (root / "etc/systemd/network").iterdir())
    assert networks == ([] if network is None else [network])
    if network is not None:
        assert unit_sections(root / "etc/systemd/network" / network)["Match"]["Name"] == channel
        # Another channel in the installed configuration, installed again: the unit is
        # wanted by the new device alone (the old device's link started it as well).
        installed_config = root / "etc/portal-daq/portal-daq.toml"
        text = installed_config.read_text()
        installed_config.write_text(text.replace(f'channel = "{channel}"', 'channel = "can2"'))
        subprocess.run(
            [str(kit / "deploy/install.sh"), "--root", str(root), "--package", str(ROOT),
             "--pip-args", "--no-deps"],
            check=True, capture_output=True, timeout=600,
        )  # fmt: skip
        wants = sorted(path.name for path in (root / "etc/systemd/system").glob("*.wants"))
        assert wants == ["multi-user.target.wants", "sys-subsystem-net-devices-can2.device.wants"]


@pytest.mark.parametrize(
    ("top", "bus"),
    [("bus = 3\n", "[bux]"), ("", '[bus]\ninterface = "socketcan"\nchannel = 0\n[bux]')],
)
def test_a_bus_that_is_no_table_of_names_stops_the_install_in_one_line(
    tmp_path: Path, top: str, bus: str
) -> None:
    # `bus = 3` was a traceback of install.sh's Python (AttributeError: 'int' object has no
    # attribute 'get'); `channel = 0` installed a unit bound to a device named 0.
    kit = tmp_path / "kit"
    assert main(["init", str(kit), "--deploy"]) == 0
    config = kit / "portal-daq.toml"
    config.write_text(top + config.read_text().replace("\n[bus]\n", f"\n{bus}\n", 1))
    result = subprocess.run(
        [str(kit / "deploy/install.sh"), "--root", str(tmp_path / "root"), "--package",
         str(ROOT), "--pip-args", "--no-deps"],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert result.returncode != 0 and "Traceback" not in result.stderr
    assert result.stderr.strip().splitlines()[-1] == (
        f"install.sh: {tmp_path}/root/etc/portal-daq/portal-daq.toml: [bus] must be a table "
        'whose interface and channel are names (interface = "socketcan", channel = "can0"); '
        "fix it and run install.sh again"
    )
    assert not (tmp_path / "root/etc/systemd/system/portal-daq.service").exists()


def test_init_writes_the_deployment_kit_of_the_repository(tmp_path: Path) -> None:
    # A user with the wheel alone had no install.sh, no unit: no way to deploy.
    assert main(["init", str(tmp_path), "--deploy"]) == 0
    kit = tmp_path / "deploy"
    packaged = ROOT / "daq" / "deploy"  # deploy/ links to it: one copy of each file
    for name in ("install.sh", "systemd", "network", "sysctl"):
        assert_links_to(DEPLOY / name, packaged / name)
    expected = {path.relative_to(packaged) for path in packaged.rglob("*") if path.is_file()}
    assert {path.relative_to(kit) for path in kit.rglob("*") if path.is_file()} == expected
    assert Path("systemd/portal-daq.service") in expected
    for path in expected:
        assert (kit / path).read_bytes() == (packaged / path).read_bytes(), path
    assert os.access(kit / "install.sh", os.X_OK)
    # Without a source tree around it, install.sh needs to be told what to install.
    root = tmp_path / "root"
    refused = subprocess.run(
        [str(kit / "install.sh"), "--root", str(root)], capture_output=True, text=True
    )
    assert refused.returncode == 2 and not root.exists()
    assert refused.stderr.startswith("install.sh: no source tree around ")
    assert "give --package, the portal-daq wheel" in refused.stderr
