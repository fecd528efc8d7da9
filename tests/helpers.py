"""Shared test helpers: the example machine, its DBC, and frame building."""

from collections.abc import Mapping
from pathlib import Path

from cantools.database.can import Database

from daq.can_batch import recorded_frames
from daq.frames import RawFrame
from daq.mcap_file import RAW_TOPIC
from daq.mcap_reading import RecordedMessage, RecordingStream
from dbc.machine import MachineConfig, load_machine_config

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE_CONFIG = ROOT / "deploy" / "machine.example.toml"
#: The service config of the default machine (what `portal-daq init` writes).
EXAMPLE_SERVICE_CONFIG = ROOT / "deploy" / "portal-daq.example.toml"
FILES = Path(__file__).resolve().parent / "files"
LEGS = ("SB1_F1", "SB1_F2", "SB1_F3", "SB2_F1", "SB2_F2", "SB2_F3")
#: Vector's frame formats: ``BA_ "VFrameFormat" BO_ <id> 3;`` is J1939, 14 and 15 CAN FD.
FRAME_FORMATS = ("StandardCAN", "ExtendedCAN", "reserved", "J1939PG", *["reserved"] * 10)
#: The example machine's ``[leg_defaults]`` table, for machine configs written in tests.
LEG_DEFAULTS_TOML = """
[leg_defaults]
A_piston_m2 = 7.854e-3
A_rod_m2 = 4.737e-3
l_r_m = 0.90
l_z_m = 0.25
l_b_m = 1.20
l_gb_m = 0.55
alpha_cyl_deg = 75.0
F_gLeg_N = 4905.0
A_foot_m2 = 0.33
"""


def assert_links_to(link: Path, packaged: Path) -> None:
    """``link`` (under ``deploy/``) is ``packaged``: a symbolic link to it in a checkout
    (one copy of each file), the same files in an sdist, where setuptools copies what a
    link names."""
    if link.is_symlink() or (ROOT / ".git").exists():
        assert link.resolve() == packaged.resolve(), link
    else:
        assert _contents(link) == _contents(packaged), link


def _contents(path: Path) -> dict[Path, bytes]:
    """Every file at or under ``path`` by its path relative to ``path``, with its bytes."""
    files = sorted(path.rglob("*")) if path.is_dir() else [path]
    return {f.relative_to(path): f.read_bytes() for f in files if f.is_file()}


def example_machine():  # type: ignore[no-untyped-def]
    """(MachineConfig, cantools Database) of deploy/machine.example.toml."""
    return load_machine_config(EXAMPLE_CONFIG)


def with_leg_keys(config_text: str, keys: Mapping[str, Mapping[str, float]]) -> str:
    """``config_text`` (a machine config) with ``keys`` added to each ``[legs.<LEG>]`` table."""
    for leg, values in keys.items():
        header = f"[legs.{leg}]\n"
        assert header in config_text, header
        body = "".join(f"{key} = {value!r}\n" for key, value in values.items())
        config_text = config_text.replace(header, header + body)
    return config_text


def machine_on(
    directory: Path, dbc: str, legs: str, tables: str = ""
) -> tuple[MachineConfig, Database]:
    """A machine of ``legs`` (TOML of ``[legs.*]`` tables, after the defaults, and other
    ``tables`` before them) on the DBC text ``dbc``, written into ``directory`` and loaded."""
    (directory / "m.dbc").write_text(dbc)
    (directory / "m.toml").write_text(
        '[machine]\nid = "m"\nmass_kg = 1000.0\ndbc = "m.dbc"\n' + tables + LEG_DEFAULTS_TOML + legs
    )
    return load_machine_config(directory / "m.toml")


def dbc_text(messages: str, attributes: str, nodes: str = "Hub DAQ") -> str:
    """A DBC of ``messages`` (``BO_``/``SG_`` lines) and ``attributes`` (``BA_``, ``VAL_``
    lines), with the definitions of ``GenMsgCycleTime`` and ``VFrameFormat``
    (:data:`FRAME_FORMATS`; default: none, i.e. standard CAN)."""
    formats = ",".join(f'"{name}"' for name in (*FRAME_FORMATS, "StandardCAN_FD", "ExtendedCAN_FD"))
    return (
        f'VERSION ""\nNS_ :\nBS_:\nBU_: {nodes}\n{messages}\n'
        'BA_DEF_ BO_ "GenMsgCycleTime" INT 0 65535;\n'
        f'BA_DEF_ BO_ "VFrameFormat" ENUM {formats};\n'
        'BA_DEF_DEF_ "GenMsgCycleTime" 0;\n'
        'BA_DEF_DEF_ "VFrameFormat" "StandardCAN";\n'
        f"{attributes}"
    )


def recorded_raw_frames(path: Path) -> list[RawFrame]:
    """Every frame on ``/can/raw`` of an MCAP recording (batches or JSON), in file order."""
    with open(path, "rb") as file:
        return [
            frame
            for record in RecordingStream(file)
            if isinstance(record, RecordedMessage) and record.topic == RAW_TOPIC
            for frame in recorded_frames(record.encoding, record.data)
        ]
