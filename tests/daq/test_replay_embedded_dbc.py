"""A recording replays with the DBC embedded in it as the service loaded the file: a
Windows-1252 DBC (Vector's tools write "°C" so) must not stop the replay."""

import io
from pathlib import Path

from daq.frames import RawFrame
from daq.mcap_file import CONFIG_ATTACHMENT, DBC_ATTACHMENT, McapFile
from daq.pipeline import Pipeline
from daq.replay import replay
from dbc.machine import load_machine_config
from tests.helpers import LEG_DEFAULTS_TOML, dbc_text

DBC = dbc_text(
    'BO_ 768 LEG: 5 Hub\n SG_ pP : 0|16@1+ (0.01,0) [0|655.35] "bar" DAQ\n'
    ' SG_ pR : 16|16@1+ (0.01,0) [0|655.35] "bar" DAQ\n'
    ' SG_ Temp : 32|8@1+ (1,-40) [-40|215] "°C" DAQ\n',
    'BA_ "GenMsgCycleTime" BO_ 768 10;\nCM_ SG_ 768 Temp "Öltemperatur";\n',
)
CONFIG = f"""[machine]
id = "cp1252"
mass_kg = 5000.0
dbc = "legs.dbc"
{LEG_DEFAULTS_TOML}
[legs.L]
piston = "LEG.pP"
rod = "LEG.pR"
"""


def test_a_windows_1252_dbc_replays_from_the_recording(tmp_path: Path) -> None:
    (tmp_path / "legs.dbc").write_bytes(DBC.encode("cp1252"))
    (tmp_path / "machine.toml").write_text(CONFIG)
    config, database = load_machine_config(tmp_path / "machine.toml")
    assert database.get_message_by_name("LEG").get_signal_by_name("Temp").unit == "°C"
    pipeline = Pipeline.from_config(config, database)
    path = tmp_path / "run.mcap"
    attachments = {
        CONFIG_ATTACHMENT: CONFIG.encode(),
        DBC_ATTACHMENT: (tmp_path / "legs.dbc").read_bytes(),
    }
    with open(path, "wb") as stream, McapFile(stream, database) as mcap:
        mcap.start(attachments, 1_750_000_000.0)
        for k in range(3):
            frame = RawFrame(1_750_000_000.0 + k / 100, 768, False, bytes([16, 39, 232, 3, 60]))
            mcap.write_result(pipeline.process(frame))
    embedded, configured = io.StringIO(), io.StringIO()
    assert replay(path, embedded) == 3
    assert replay(path, configured, tmp_path / "machine.toml") == 3
    assert embedded.getvalue() == configured.getvalue()
