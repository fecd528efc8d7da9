"""``portal-daq router``: its default config ships in the package (a wheel has no
``deploy/``), and a file it cannot use is one line naming it, exit 2."""

import json
from pathlib import Path

import pytest

import daq
from daq.router import DEFAULT_CONFIG, listen_endpoints, router_config, router_main
from tests.helpers import ROOT, assert_links_to


def test_the_default_config_is_the_packaged_site_router() -> None:
    """``portal-daq router --config deploy/zenoh-router.json5`` was the only way: the
    README's fleet commands did not run from an installed wheel."""
    assert DEFAULT_CONFIG.is_relative_to(Path(daq.__file__).parent)
    assert_links_to(ROOT / "deploy" / "zenoh-router.json5", DEFAULT_CONFIG)
    config = router_config(DEFAULT_CONFIG)
    assert json.loads(config.get_json("mode")) == "router"
    assert listen_endpoints(config) == ["tcp/0.0.0.0:7447"]


@pytest.mark.parametrize(
    ("name", "text", "reason"),
    [
        ("missing.json5", None, "missing.json5: no such file; give --config a Zenoh JSON5 file"),
        ("folder", "", "folder: it is a directory; give --config a Zenoh JSON5 file"),
        ("peer.json5", '{ mode: "peer" }', "peer.json5: mode: must be 'router' for a router"),
        # A service config given instead: the TOML error carried the whole file.
        ("portal-daq.toml", "[machine\n" + "# a long comment\n" * 500, "not a valid Zenoh"),
    ],
)
def test_a_config_it_cannot_use_is_one_short_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str, text: str | None, reason: str
) -> None:
    path = tmp_path / name
    if name == "folder":
        path.mkdir()
    elif text is not None:
        path.write_text(text)
    assert router_main(["--config", str(path)]) == 2
    stderr = capsys.readouterr().err
    assert stderr.startswith(f"portal-daq: {path}") and stderr.count("\n") == 1
    assert reason in stderr and "a long comment" not in stderr and len(stderr) < 300


def test_an_access_control_zenoh_refuses_is_the_files_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Zenoh checks a policy's rules and subjects only when the session opens: it was
    exit 1 with the hint of a taken port ("check listen in the router's config")."""
    text = DEFAULT_CONFIG.read_text()
    rules = 'policies: [{ rules: ["no-sim-truth-through-the-router"]'
    assert rules in text
    path = tmp_path / "zenoh-router.json5"
    path.write_text(text.replace(rules, 'policies: [{ rules: ["no-sim-truth"]'))
    assert router_main(["--config", str(path)]) == 2
    assert capsys.readouterr().err == (
        f"portal-daq: {path}: access_control: "
        "Rule 'no-sim-truth' in policy #0 does not exist in rules list\n"
    )


@pytest.mark.parametrize("config_file", [None, ROOT / "deploy" / "zenoh.json5"])
def test_a_machine_announces_the_routers_lease(config_file: Path | None) -> None:
    """The router drops a machine that vanishes (power, cable, a frozen process) after the
    lease the machine's session announces, not its own: with Zenoh's default of 10 s a
    SIGSTOPped client's token went after 8 s, where the router's file promised 2 s (1.5 s
    with the machine announcing 2 s; measured through a ``portal-daq router``)."""
    from daq.service_config import ZenohSettings
    from daq.zenoh_session import config_value, zenoh_config

    router = router_config(DEFAULT_CONFIG)
    machine = zenoh_config(
        ZenohSettings(config_file=config_file, mode="client", connect=("tcp/127.0.0.1:7447",))
    )
    for key in ("transport/link/tx/lease", "transport/link/tx/keep_alive"):
        assert config_value(machine, key) == config_value(router, key), key
    assert config_value(machine, "transport/link/tx/lease") == 2000
