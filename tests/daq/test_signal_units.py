"""The units the recorded ``/signals`` schemas name are those the decoder converted to: a
pressure signal with no unit in the DBC and a chamber's ``unit`` is labelled Pa, as its
values are; the label comes from the machine config (``decoded_units``)."""

import json
from pathlib import Path

import pytest
from mcap.reader import make_reader

from daq.frames import RawFrame
from daq.mcap_file import RecordBatch
from daq.pipeline import Pipeline
from daq.runner import build_recorder
from daq.service_config import load_service_config
from dbc.machine import load_machine_config
from tests.daq.test_recording import wait_drained
from tests.helpers import LEG_DEFAULTS_TOML, dbc_text

DBC = dbc_text(
    'BO_ 768 LEG: 5 Hub\n SG_ pP : 0|16@1+ (0.01,0) [0|655.35] "" DAQ\n'
    ' SG_ pR : 16|16@1+ (1,0) [0|65535] "kPa" DAQ\n'
    ' SG_ Temp : 32|8@1+ (1,-40) [-40|215] "degC" DAQ\n'
    'BO_ 2566856737 HYD: 8 Hub\n SG_ Pressure : 0|16@1+ (0.01,0) [0|655.35] "" DAQ\n',
    'BA_ "GenMsgCycleTime" BO_ 768 10;\nBA_ "GenMsgCycleTime" BO_ 2566856737 10;\n'
    'BA_ "VFrameFormat" BO_ 2566856737 3;\n',
)
MACHINE = f"""[machine]
id = "units"
mass_kg = 5000.0
dbc = "legs.dbc"
{LEG_DEFAULTS_TOML}
[legs.L]
piston = {{ signal = "LEG.pP", unit = "bar" }}
rod = "LEG.pR"

[legs.J]
piston = {{ signal = "HYD.Pressure", source_address = 0x21, unit = "psi" }}
rod = {{ signal = "HYD.Pressure", source_address = 0x22, unit = "bar" }}
"""


def service_config(tmp_path: Path, process: bool) -> Path:
    (tmp_path / "legs.dbc").write_text(DBC)
    path = tmp_path / "portal-daq.toml"
    path.write_text(
        f'[bus]\ninterface = "virtual"\nchannel = "test"\n\n'
        f'[recording]\ndirectory = "rec"\nsignals = true\nprocess = {str(process).lower()}\n\n'
        + MACHINE
    )
    return path


def test_decoded_units_name_pa_where_the_decoder_converts(tmp_path: Path) -> None:
    config = load_service_config(service_config(tmp_path, process=False)).machine
    assert config.decoded_units == {
        "LEG": {"pP": "Pa", "pR": "Pa"},  # the chamber's bar, the DBC's kPa
        # Each transducer in its own unit, no unit in the DBC: other senders stay as sent.
        "HYD": {"Pressure": "Pa from 0x21, 0x22; other senders as sent (no unit in the DBC)"},
    }


@pytest.mark.parametrize("process", [False, True], ids=["thread", "process"])
def test_recorded_signals_schema_says_pa_for_a_chamber_unit(tmp_path: Path, process: bool) -> None:
    config = load_service_config(service_config(tmp_path, process))
    pipeline = Pipeline.from_config(config.machine, config.database)
    recorder = build_recorder(config)
    assert recorder is not None
    with recorder:
        # pP raw 250 at 0.01 bar/bit: 2.5 bar; pR 800 kPa; Temp 60 - 40 = 20 degC.
        data = (250).to_bytes(2, "little") + (800).to_bytes(2, "little") + bytes([60])
        result = pipeline.process(RawFrame(1_750_000_000.0, 768, False, data))
        recorder.submit(RecordBatch.of([result], signals=True))
        wait_drained(recorder)
    with open(recorder.paths[0], "rb") as file:
        reader = make_reader(file)
        summary = reader.get_summary()
        assert summary is not None
        (channel,) = (c for c in summary.channels.values() if c.topic == "/signals/LEG")
        schema = json.loads(summary.schemas[channel.schema_id].data)
        (_, _, message) = next(iter(reader.iter_messages(topics=["/signals/LEG"])))
    units = {
        name: entry["description"]
        for name, entry in schema["properties"]["signals"]["properties"].items()
    }
    assert units == {"pP": "Pa", "pR": "Pa", "Temp": "degC"}
    signals = json.loads(message.data)["signals"]
    assert (signals["pP"], signals["pR"], signals["Temp"]) == pytest.approx((2.5e5, 8e5, 20.0))


def test_decoded_units_say_which_transducers_send_absolute_pressure(tmp_path: Path) -> None:
    """Their values on /signals are what they sent, in Pa: absolute, where the estimator
    reads them less the atmosphere."""
    (tmp_path / "legs.dbc").write_text(
        DBC.replace('(0.01,0) [0|655.35] "" DAQ\n', '(0.01,0) [0|655.35] "bar" DAQ\n')
    )
    machine = MACHINE.replace('unit = "psi"', 'unit = "psia"').replace(
        'source_address = 0x22, unit = "bar"', "source_address = 0x22"
    )
    (tmp_path / "machine.toml").write_text(machine)
    config, _ = load_machine_config(tmp_path / "machine.toml")
    assert config.decoded_units["HYD"] == {"Pressure": "Pa; absolute from 0x21"}
    assert config.decoded_units["LEG"] == {"pP": "Pa", "pR": "Pa"}


def test_decoded_units_name_absolute_senders_where_others_stay_as_sent(tmp_path: Path) -> None:
    """No unit in the DBC, each transducer its own: the label still says which of the
    converted senders are absolute."""
    (tmp_path / "legs.dbc").write_text(DBC)
    (tmp_path / "machine.toml").write_text(MACHINE.replace('unit = "psi"', 'unit = "psia"'))
    config, _ = load_machine_config(tmp_path / "machine.toml")
    assert config.decoded_units["HYD"] == {
        "Pressure": "Pa from 0x21, 0x22; absolute from 0x21; other senders as sent "
        "(no unit in the DBC)"
    }
