"""Service configuration: the example loads; wrong service tables are refused naming the key."""

from pathlib import Path

import pytest

from daq.service_config import ZenohSettings, load_service_config
from daq.zenoh_session import zenoh_config
from dbc import DEFAULT_DBC_PATH
from dbc.errors import ConfigError
from dbc.machine import load_machine_config
from tests.helpers import ROOT

EXAMPLE = ROOT / "deploy" / "portal-daq.example.toml"
MACHINE_ONLY = ROOT / "deploy" / "machine.example.toml"


def test_example_loads_with_documented_values() -> None:
    config = load_service_config(EXAMPLE)
    assert config.machine.machine_id == "pam-proto-1"
    assert (config.bus.interface, config.bus.channel) == ("socketcan", "can0")
    assert config.bus.kernel_filters is False and config.bus.receive_own_messages is False
    assert config.bus.receive_buffer_bytes == 4 * 1024 * 1024
    assert config.zenoh.key_prefix == "portal/pam-proto-1"
    assert config.zenoh.config_file == EXAMPLE.parent / "zenoh.json5"
    assert config.publish.ground_rate_hz == 10.0 and config.publish.signals is True
    assert config.recording.compression == "zstd" and config.recording.signals is False
    assert config.service.event_loop is True and config.publish.signals_max_rate_hz == 10.0
    assert config.recording.directory == Path("/var/lib/portal-daq/recordings")
    zenoh_config(config.zenoh)  # the JSON5 file is valid for Zenoh


def test_machine_loader_accepts_the_service_file() -> None:
    machine, _ = load_machine_config(EXAMPLE)
    assert machine == load_service_config(EXAMPLE).machine


def test_machine_file_alone_gives_service_defaults() -> None:
    config = load_service_config(MACHINE_ONLY)
    assert config.bus.channel == "can0" and config.recording.directory is None
    assert config.zenoh.config_file is None and config.zenoh.connect == ()
    assert config.publish.status_period_s == 1.0


def refused(tmp_path: Path, text: str) -> ConfigError:
    path = tmp_path / "portal-daq.toml"
    path.write_text(text + "\n" + MACHINE_ONLY.read_text())
    with pytest.raises(ConfigError) as info:
        load_service_config(path)
    assert str(path) in str(info.value)
    return info.value


@pytest.mark.parametrize(
    ("text", "key", "reason"),
    [
        ('[bus]\nchanel = "can0"', "bus.chanel", "unknown key"),
        ('[bus]\ninterface = "socketcam"', "bus.interface", "unknown python-can interface"),
        ("[bus]\nreceive_own_messages = 1", "bus.receive_own_messages", "true or false"),
        ("[bus]\nqueue_size = 0", "bus.queue_size", "between 1 and 1000000, got 0"),
        ("[bus]\nreceive_buffer_bytes = 100", "bus.receive_buffer_bytes", "between 1024 and"),
        ('[bus]\nreceive_buffer_bytes = "4M"', "bus.receive_buffer_bytes", "integer"),
        ('[zenoh]\nmode = "peers"', "zenoh.mode", "must be one of"),
        ('[zenoh]\nconnect = "tcp/1.2.3.4:7447"', "zenoh.connect", "list of non-empty strings"),
        ('[zenoh]\nkey_prefix = "portal/*"', "zenoh.key_prefix", "has '*' (wildcards,"),
        ('[zenoh]\nkey_prefix = "/portal"', "zenoh.key_prefix", "has an empty chunk"),
        ('[zenoh]\nkey_prefix = "portal/pam 1"', "zenoh.key_prefix", "has ' ' (wildcards,"),
        # A verbatim chunk: neither the access control's portal/** nor portal/* matched it.
        ('[zenoh]\nkey_prefix = "portal/@pam"', "zenoh.key_prefix", "starts with '@'"),
        ('[zenoh]\nconfig_file = "absent.json5"', "zenoh.config_file", "no such file"),
        ("[publish]\nground_rate_hz = -1", "publish.ground_rate_hz", "between 0.01 and 100"),
        ('[publish]\nsignals = "yes"', "publish.signals", "true or false"),
        ("[publish]\nstatus_period_s = 0", "publish.status_period_s", "between 0.01 and 3600"),
        ('[recording]\ncompression = "gzip"', "recording.compression", "must be one of"),
        ("[recording]\nmax_bytes = 100", "recording.max_bytes", ">= chunk_size"),
        ('[recording]\nmax_duration_s = "1h"', "recording.max_duration_s", "must be a number"),
        ("[recordings]\nx = 1", "recordings", "unknown key"),
        ('[service]\nevent_loop = "yes"', "service.event_loop", "true or false"),
        ("[service]\nthreads = 4", "service.threads", "unknown key"),
        ("[publish]\nsignals_max_rate_hz = -1", "publish.signals_max_rate_hz", ">= 0"),
        ('[publish]\nsignals_max_rate_hz = "10 Hz"', "publish.signals_max_rate_hz", "a number"),
        ("[recording]\nsignals = 1", "recording.signals", "true or false"),
        ('[recording]\nprocess = "no"', "recording.process", "true or false"),
        ("[service]\npoll_period_ms = -1", "service.poll_period_ms", "between 0 and 250"),
        ("[service]\npoll_period_ms = 1000", "service.poll_period_ms", "between 0 and 250"),
        ('[service]\npoll_period_ms = "20 ms"', "service.poll_period_ms", "a number"),
        # Periods and rates that spun a loop or overflowed a wait (no frame coming in: a
        # third of a core or all of one; status_period_s = 1e300 an OverflowError).
        ("[publish]\nground_rate_hz = 1e6", "publish.ground_rate_hz", "got 1e+06 (the legs'"),
        ("[publish]\nground_rate_hz = 1e-300", "publish.ground_rate_hz", "between 0.01 and"),
        ("[publish]\nground_rate_hz = nan", "publish.ground_rate_hz", "finite"),
        ("[publish]\nstatus_period_s = 1e-300", "publish.status_period_s", "between 0.01 and"),
        ("[publish]\nstatus_period_s = 1e300", "publish.status_period_s", "and 3600, got 1e+300"),
        ("[publish]\nstatus_period_s = inf", "publish.status_period_s", "finite"),
        ("[recording]\nflush_period_s = 1e-300", "recording.flush_period_s", "at least 0.01"),
        ("[recording]\nflush_period_s = 0", "recording.flush_period_s", "at least 0.01"),
        ("[recording]\nmax_duration_s = 0.001", "recording.max_duration_s", "at least 1, got"),
        ("[recording]\nmax_duration_s = -1", "recording.max_duration_s", "at least 1, got"),
        # A queue bounds memory; the recorder process's took 2**31 - 1 at most (a traceback).
        ("[recording]\nqueue_size = 4611686018427387904", "recording.queue_size", "and 1000000"),
        ("[publish]\nqueue_size = 1000001", "publish.queue_size", "between 1 and 1000000"),
        ("[bus]\nqueue_size = 2.5", "bus.queue_size", "must be an integer"),
        ("[bus]\nqueue_size = -1", "bus.queue_size", "between 1 and 1000000, got -1"),
    ],
)
def test_wrong_service_table_is_refused_naming_the_key(
    tmp_path: Path, text: str, key: str, reason: str
) -> None:
    error = refused(tmp_path, text)
    assert error.key == key
    assert reason in str(error)


def test_performance_keys_default_and_set(tmp_path: Path) -> None:
    defaults = load_service_config(MACHINE_ONLY)
    assert defaults.service.event_loop is True and defaults.service.poll_period_s == 0.0
    assert defaults.publish.signals_max_rate_hz == 10.0 and defaults.recording.signals is False
    assert defaults.recording.process is True
    path = tmp_path / "portal-daq.toml"
    text = (
        "[service]\nevent_loop = false\npoll_period_ms = 20\n[publish]\nsignals_max_rate_hz = 0\n"
        "[recording]\nsignals = true\nprocess = false\n"
    )
    path.write_text(text + MACHINE_ONLY.read_text())
    config = load_service_config(path)
    assert config.service.event_loop is False
    assert config.service.poll_period_ms == 20.0 and config.service.poll_period_s == 0.02
    assert config.publish.signals_max_rate_hz == 0.0 and config.recording.signals is True
    assert config.recording.process is False


def test_receive_buffer_size_is_read(tmp_path: Path) -> None:
    path = tmp_path / "portal-daq.toml"
    path.write_text("[bus]\nreceive_buffer_bytes = 65536\n" + MACHINE_ONLY.read_text())
    assert load_service_config(path).bus.receive_buffer_bytes == 65536


def test_relative_paths_are_relative_to_the_config_file(tmp_path: Path) -> None:
    (tmp_path / "z.json5").write_text("{ mode: 'peer' }")
    path = tmp_path / "portal-daq.toml"
    text = '[zenoh]\nconfig_file = "z.json5"\n[recording]\ndirectory = "rec"\n'
    path.write_text(text + MACHINE_ONLY.read_text())
    config = load_service_config(path)
    assert config.zenoh.config_file == tmp_path / "z.json5"
    assert config.recording.directory == tmp_path / "rec"


def test_a_path_that_starts_with_a_tilde_is_in_the_home_directory(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``~/recordings`` was a directory named ``~`` beside the config file, as the DBC's
    ``~/dbc/machine.dbc`` ("cannot read it: no such file")."""
    home = tmp_path / "home"
    (home / "dbc").mkdir(parents=True)
    monkeypatch.setenv("HOME", str(home))
    (home / "dbc" / "machine.dbc").write_bytes(DEFAULT_DBC_PATH.read_bytes())
    (home / "z.json5").write_text("{ mode: 'peer' }")
    path = tmp_path / "etc" / "portal-daq.toml"
    path.parent.mkdir()
    machine = MACHINE_ONLY.read_text().replace(
        "[machine]\n", '[machine]\ndbc = "~/dbc/machine.dbc"\n', 1
    )
    text = '[zenoh]\nconfig_file = "~/z.json5"\n[recording]\ndirectory = "~/rec"\n'
    path.write_text(text + machine)
    config = load_service_config(path)
    assert config.machine.dbc_path == home / "dbc" / "machine.dbc"
    assert config.zenoh.config_file == home / "z.json5"
    assert config.recording.directory == home / "rec"


def test_bad_zenoh_file_is_a_config_error(tmp_path: Path) -> None:
    (tmp_path / "z.json5").write_text("{ mode: ")
    path = tmp_path / "portal-daq.toml"
    path.write_text('[zenoh]\nconfig_file = "z.json5"\n' + MACHINE_ONLY.read_text())
    config = load_service_config(path)
    with pytest.raises(ConfigError, match="z.json5: not a valid Zenoh config"):
        zenoh_config(config.zenoh)


@pytest.mark.parametrize(
    ("line", "reason"),
    [
        # Taken by Zenoh: a peer retried it for ever ("not reached"), never could it work.
        (
            'connect = ["tcp/192.168.10.1"]',
            "zenoh.connect: 'tcp/192.168.10.1' names no port "
            "(tcp/HOST:PORT, e.g. tcp/192.168.10.1:7447)",
        ),
        ('connect = ["tcp/10.0.0.1:99999"]', "zenoh.connect: 'tcp/10.0.0.1:99999': port 99999"),
        ('connect = ["tcp/10.0.0.1:0"]', "zenoh.connect: 'tcp/10.0.0.1:0': port 0 is for listen"),
        ('connect = ["tcp/:7447"]', "zenoh.connect: 'tcp/:7447' names no host"),
        # A listener said "invalid socket address", blamed on a taken port.
        ('listen = ["udp/127.0.0.1"]', "zenoh.listen: 'udp/127.0.0.1' names no port"),
    ],
)
def test_an_endpoint_no_session_can_use_is_a_config_error(
    tmp_path: Path, line: str, reason: str
) -> None:
    path = tmp_path / "portal-daq.toml"
    path.write_text(f"[zenoh]\n{line}\n" + MACHINE_ONLY.read_text())
    config = load_service_config(path)
    with pytest.raises(ConfigError) as error:
        zenoh_config(config.zenoh, config.source)
    assert str(error.value).startswith(f"{path}: {reason}")
    # The same in the Zenoh file, named by its key; listening on port 0 (any) is fine.
    key, _, value = line.partition(" = ")
    (tmp_path / "z.json5").write_text(f"{{ {key}: {{ endpoints: {value} }} }}")
    path.write_text('[zenoh]\nconfig_file = "z.json5"\n' + MACHINE_ONLY.read_text())
    config = load_service_config(path)
    with pytest.raises(ConfigError) as error:
        zenoh_config(config.zenoh, config.source)
    assert str(error.value).startswith(f"{tmp_path / 'z.json5'}: {key}/endpoints: ")
    fine = ZenohSettings(listen=("tcp/127.0.0.1:0", "tcp/[::1]:7447", "unixsock-stream//x"))
    assert zenoh_config(fine) is not None
