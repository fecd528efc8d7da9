"""A rolling counter the DBC scales (``(1,1)``: the sender's raw 0..15 shown as 1..16) or
declares signed (``@1-``: raw 8..15 shown as -8..-1) is judged by what the sender counts,
its raw bits, and encoded so."""

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


def test_a_counter_the_dbc_declares_signed_counts_its_bits(tmp_path: Path) -> None:
    """A 4-bit counter declared ``@1-`` and an 8-bit one ``[-128|127]`` (a DBC tool that
    marks every signal signed): the sender's counts 8..15 (128..255) decoded as -8..-1 were
    below the counter's values, a ``counter`` fault each (15 of 40 samples of a profile 1
    sender invalid), and the simulator bridge stopped with cantools' OverflowError
    ('Signed integer value 8 out of range')."""
    dbc = DBC.replace("BZ : 32|4@1+ (1,1) [1|16]", "BZ : 32|4@1- (1,0) [-8|7]").replace(
        "BO_ 256 LEG: 8 H",
        'BO_ 257 AUX: 8 H\n SG_ SQC : 0|8@1- (1,0) [-128|127] "" DAQ\n\nBO_ 256 LEG: 8 H',
    )
    protection = '[protection.LEG]\ncounter = "BZ"\n[protection.AUX]\ncounter = "SQC"\n'
    config, database = machine_on(tmp_path, dbc, LEGS, protection)
    pipeline = Pipeline.from_config(config, database)
    reasons = []
    for i in range(34):
        data = (15000).to_bytes(2, "little") + (2000).to_bytes(2, "little") + bytes([i % 16])
        data += bytes(3)
        reasons += [
            e.reasons for e in pipeline.process(RawFrame(1 + 0.01 * i, 256, False, data)).estimates
        ]
    for i in range(300):
        pipeline.process(RawFrame(1 + 0.01 * i, 257, False, bytes([i % 256]) + bytes(7)))
    assert reasons == [()] * 34 and pipeline.bad == {} and pipeline.frames_lost == 0
    encoder = FrameEncoder(database, config.protection)
    sent = [encoder.encode("LEG", {"P": 150.0, "R": 20.0}).data[4] for _ in range(17)]
    aux = [encoder.encode("AUX", {}).data[0] for _ in range(257)]
    assert sent == [*range(16), 0] and aux == [*range(256), 0]
