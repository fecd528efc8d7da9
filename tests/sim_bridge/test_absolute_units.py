"""Transducers sending absolute pressure (DBC unit ``Pa abs``): the bridge sends the
simulation's gauge pressures plus the standard atmosphere, and the service, reading them
less it, gets the simulated pressures back (eq. (4) takes gauge pressures)."""

import re
from pathlib import Path

import pytest

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from dbc import DEFAULT_DBC_PATH
from dbc.machine import load_machine_config
from dbc.units import STANDARD_ATMOSPHERE_PA
from tests.sim_bridge.synthetic import LEGS, make_result, sent_by_the_command

EXAMPLE_CONFIG = Path(DEFAULT_DBC_PATH).parent / "machine.example.toml"
#: The default DBC's pressure step: 1 kPa per bit.
STEP_PA = 1000.0


def test_absolute_chambers_round_trip_to_the_simulated_gauge_pressures(tmp_path: Path) -> None:
    chamber = re.compile(r'(SG_ SB[12]_F[123]_p(?:Piston|Rod) [^"]*)"Pa"')
    dbc, changed = chamber.subn(r'\1"Pa abs"', DEFAULT_DBC_PATH.read_text(encoding="cp1252"))
    assert changed == 12
    (tmp_path / "absolute.dbc").write_text(dbc, encoding="cp1252")
    config_text = EXAMPLE_CONFIG.read_text().replace(
        '# dbc = "portal_sensors.dbc"', 'dbc = "absolute.dbc"'
    )
    (tmp_path / "machine.toml").write_text(config_text)
    result = make_result(duration_s=0.3)
    frames = [
        RawFrame(message.timestamp, message.arbitration_id, False, bytes(message.data))
        for message in sent_by_the_command(tmp_path / "machine.toml", tmp_path, result)
    ]
    config, database = load_machine_config(tmp_path / "machine.toml")
    assert config.legs["SB1_F1"].piston.atmosphere_Pa == STANDARD_ATMOSPHERE_PA
    pipeline = Pipeline.from_config(config, database)
    estimates = [e for frame in frames for e in pipeline.process(frame).estimates]
    first = {leg: next(e for e in estimates if e.leg == leg) for leg in LEGS}
    for column, leg in enumerate(LEGS):
        estimate = first[leg]
        assert estimate.valid, (leg, estimate.reasons)
        simulated_Pa = (result.p_piston_Pa[0, column], result.p_rod_Pa[0, column])
        # 1 kPa steps: read as absolute, every pressure would be ~101 kPa off.
        assert (estimate.p_piston_Pa, estimate.p_rod_Pa) == pytest.approx(
            simulated_Pa, abs=STEP_PA / 2 + 1e-6
        )
