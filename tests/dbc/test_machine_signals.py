"""The ``[signals]`` table: defaults found by name, non-default names apply, bad ones refused."""

import math
import shutil
from pathlib import Path

import pytest

from dbc.errors import ConfigError
from dbc.machine import MachineConfig, SignalRef, load_machine_config
from tests.helpers import EXAMPLE_CONFIG, FILES

RENAMED = FILES / "renamed" / "machine.toml"
TEXT = RENAMED.read_text()


def load(tmp_path: Path, text: str) -> MachineConfig:
    shutil.copy(RENAMED.parent / "renamed_sensors.dbc", tmp_path)
    path = tmp_path / "machine.toml"
    path.write_text(text)
    return load_machine_config(path)[0]


def test_left_out_they_are_the_default_names_wherever_the_dbc_has_them() -> None:
    signals = load_machine_config(EXAMPLE_CONFIG)[0].signals
    assert signals.phase == SignalRef("MACHINE_STATE", "Machine_Phase")
    assert signals.state_message == "MACHINE_STATE"
    assert signals.carriage == SignalRef("BRIDGE_MOTION", "Carriage_Position")
    assert signals.bases[1].inclination == SignalRef("BRIDGE_POSE", "SB2_InclinationAngle")
    assert signals.bases[0].rod == SignalRef("INCL_SB1", "INCL_SB1_pRod")
    assert signals.base_names == ("SB1", "SB2") and signals.absent() == []


def test_non_default_names_and_an_angle_unit(tmp_path: Path) -> None:
    config = load(tmp_path, TEXT)
    signals = config.signals
    assert signals.base_names == ("near", "far")  # [stability.bases]' order
    assert signals.state_message == "VEHICLE_STATE"
    assert signals.cycle_time == SignalRef("VEHICLE_STATE", "StepTime_s")
    assert signals.carriage == SignalRef("BRIDGE_DRIVE", "Trolley_m")
    far = signals.bases[1]
    assert far.status == SignalRef("TILT_FAR", "TILT_FAR_Status")
    assert far.inclination_rad_per_unit == pytest.approx(math.pi / 180)
    changed = load(
        tmp_path,
        TEXT.replace(
            'inclination = "BRIDGE_GEOMETRY.TiltFar_deg"',
            'inclination = { signal = "BRIDGE_GEOMETRY.TiltFar_deg", unit = "mrad" }',
        ),
    )
    assert changed.signals.bases[1].inclination_rad_per_unit == pytest.approx(1e-3)
    # a base left out of [signals.bases]: the default names, which this DBC has not
    start = TEXT.index("[signals.bases.far]")
    without_far = load(tmp_path, TEXT[:start] + TEXT[TEXT.index("[protection.", start) :])
    assert without_far.signals.absent() == [
        f"bases.far.{key}" for key in ("inclination", "piston", "rod", "status")
    ]


#: (what the renamed config says, what it says instead, the key refused, the reason).
BAD = [
    ('"VEHICLE_STATE.StepPhase"', '"VEHICLE_STATE.Phase"', "signals.phase",
     "no signal 'Phase' in message VEHICLE_STATE"),
    ('"VEHICLE_STATE.StepTime_s"', '"BRIDGE_DRIVE.Trolley_m"', "signals.cycle_time",
     "the machine state is one message's"),
    ('carriage = "BRIDGE_DRIVE.Trolley_m"', "carriage = 3", "signals.carriage", "string"),
    ("[signals.bases.far]", "[signals.bases.SB2]", "signals.bases.SB2", "no base 'SB2'"),
    ('"BRIDGE_GEOMETRY.TiltNear_deg"', '"BRIDGE_DRIVE.Trolley_m"',
     "signals.bases.near.inclination", "not an angle unit"),
    ("rod = \"TILT_FAR", "annulus = \"TILT_FAR", "signals.bases.far.annulus", "unknown key"),
    ('carriage = "BRIDGE_DRIVE.Trolley_m"', 'trolley = "x"', "signals.trolley", "unknown"),
]  # fmt: skip


@pytest.mark.parametrize(("old", "new", "key", "reason"), BAD)
def test_bad_signals_are_refused(tmp_path: Path, old: str, new: str, key: str, reason: str) -> None:
    assert old in TEXT
    with pytest.raises(ConfigError) as info:
        load(tmp_path, TEXT.replace(old, new, 1))
    assert info.value.key == key
    assert reason in str(info.value)


def test_without_stability_the_bases_are_the_simulations(tmp_path: Path) -> None:
    start = TEXT.index("[stability]")
    text = TEXT[:start] + TEXT[TEXT.index("[signals]") :]
    with pytest.raises(ConfigError) as info:
        load(tmp_path, text)
    assert info.value.key == "signals.bases.near"
    assert "the bases are SB1, SB2 (the simulation's)" in str(info.value)
    text = text.replace("[signals.bases.near]", "[signals.bases.SB1]")
    config = load(tmp_path, text.replace("[signals.bases.far]", "[signals.bases.SB2]"))
    assert config.signals.bases[0].piston == SignalRef("TILT_NEAR", "TILT_NEAR_pPiston")
