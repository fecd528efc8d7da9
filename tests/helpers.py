"""Shared test helpers: the example machine, its DBC, and frame building."""

from pathlib import Path

from dbc.machine import load_machine_config

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE_CONFIG = ROOT / "deploy" / "machine.example.toml"
FILES = Path(__file__).resolve().parent / "files"
LEGS = ("SB1_F1", "SB1_F2", "SB1_F3", "SB2_F1", "SB2_F2", "SB2_F3")


def example_machine():  # type: ignore[no-untyped-def]
    """(MachineConfig, cantools Database) of deploy/machine.example.toml."""
    return load_machine_config(EXAMPLE_CONFIG)
