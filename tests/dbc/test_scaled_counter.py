"""A rolling counter the DBC scales (``(1,1)``: the sender's raw 0..15 shown as 1..16) is
judged by what the sender counts, its raw value, and encoded so."""

from pathlib import Path

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from dbc.encoding import FrameEncoder
from tests.helpers import machine_on

DBC = """VERSION ""

NS_ :

BS_:

BU_: H DAQ

BO_ 256 LEG: 8 H
 SG_ P : 0|16@1+ (0.01,0) [0|655.34] "bar" DAQ
 SG_ R : 16|16@1+ (0.01,0) [0|655.34] "bar" DAQ
 SG_ BZ : 32|4@1+ (1,1) [1|16] "" DAQ

BA_DEF_ BO_ "GenMsgCycleTime" INT 0 10000;
BA_ "GenMsgCycleTime" BO_ 256 10;
"""
LEGS = '[legs.A]\npiston = "LEG.P"\nrod = "LEG.R"\n'


def test_a_counter_shown_from_1_wraps_as_sent(tmp_path: Path) -> None:
    """Raw 0..15, 0..15: no fault and nothing lost; before, its 16 (raw 15) was above the
    counter's values, a ``counter`` fault every 16th frame."""
    config, database = machine_on(tmp_path, DBC, LEGS, '[protection.LEG]\ncounter = "BZ"\n')
    pipeline = Pipeline.from_config(config, database)
    reasons = []
    for i in range(34):
        data = (15000).to_bytes(2, "little") + (2000).to_bytes(2, "little") + bytes([i % 16])
        data += bytes(3)
        frame = RawFrame(1.0 + 0.01 * i, 256, False, data)
        reasons += [e.reasons for e in pipeline.process(frame).estimates]
    assert reasons == [()] * 34 and pipeline.bad == {} and pipeline.frames_lost == 0
    encoder = FrameEncoder(database, config.protection)
    sent = [encoder.encode("LEG", {"P": 150.0, "R": 20.0}).data[4] for _ in range(17)]
    assert sent == [*range(16), 0]  # the encoder counts the raw bits alike
