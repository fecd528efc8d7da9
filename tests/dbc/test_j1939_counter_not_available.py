"""A J1939 transducer's 4-bit rolling counter whose 15 means "not available" (``VAL_ ...
15 "NotAvailable"``, CANdb++'s ``[0|15]``): it counts 0..14, so 14 -> 0 is one step.

Taken as a counter of 16 values, every wrap counted one frame lost (``frames_lost``, and
with ``max_delta_counter = 1`` a ``counter`` fault every 15th frame)."""

from pathlib import Path

import pytest

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from dbc.machine import load_machine_config
from tests.helpers import LEG_DEFAULTS_TOML

DBC = """VERSION ""

NS_ :
	BA_DEF_
	BA_
	VAL_
	BA_DEF_DEF_

BS_:

BU_: Xdcr DAQ

BO_ 2566856737 XDCR: 8 Xdcr
 SG_ Pressure : 0|16@1+ (0.01,0) [0|642.55] "bar" DAQ
 SG_ MsgCounter : 16|4@1+ (1,0) [0|15] "" DAQ

BA_DEF_ BO_ "GenMsgCycleTime" INT 0 65535;
BA_DEF_ BO_ "VFrameFormat" ENUM "StandardCAN","ExtendedCAN","reserved","J1939PG";
BA_DEF_DEF_ "GenMsgCycleTime" 10;
BA_DEF_DEF_ "VFrameFormat" "J1939PG";
BA_ "VFrameFormat" BO_ 2566856737 3;
VAL_ 2566856737 MsgCounter 15 "NotAvailable" ;
"""

CONFIG = (
    """[machine]
id = "counter-na"
mass_kg = 3000.0
dbc = "xdcr.dbc"

"""
    + LEG_DEFAULTS_TOML
    + """
[legs.A]
piston = { signal = "XDCR.Pressure", source_address = 0x21 }
rod = { signal = "XDCR.Pressure", source_address = 0x22 }
max_skew_s = 0.015

[protection.XDCR]
counter = "MsgCounter"
max_delta_counter = 1
"""
)


@pytest.fixture
def pipeline(tmp_path: Path) -> Pipeline:
    (tmp_path / "xdcr.dbc").write_text(DBC)
    (tmp_path / "machine.toml").write_text(CONFIG)
    return Pipeline.from_config(*load_machine_config(tmp_path / "machine.toml"))


def _frame(t_s: float, source: int, counter: int) -> RawFrame:
    data = (15000).to_bytes(2, "little") + bytes([0xF0 | counter]) + b"\xff" * 5
    return RawFrame(t_s, 0x18FF2000 | source, True, data)


def _piston(pipeline: Pipeline, t_s: float, counter: int) -> list[tuple[str, ...]]:
    return [e.reasons for e in pipeline.process(_frame(t_s, 0x21, counter)).estimates]


def test_a_counter_that_names_15_not_available_counts_0_to_14(pipeline: Pipeline) -> None:
    """Two transducers, each counting 0..14 on its own (started apart), 40 frames each:
    two wraps each, no frame lost, every sample valid; then the piston's "not available"
    is a counter fault, and its next count is taken as it comes."""
    reasons = []
    for i in range(40):
        t_s = 1.0 + 0.01 * i
        pipeline.process(_frame(t_s, 0x22, (i + 7) % 15))
        reasons += _piston(pipeline, t_s + 0.001, i % 15)
    assert reasons == [()] * 40
    assert pipeline.frames_lost == 0 and dict(pipeline.bad) == {}
    for i, counter in enumerate((15, 9, 10)):
        t_s = 1.4 + 0.01 * i
        pipeline.process(_frame(t_s, 0x22, (40 + i + 7) % 15))
        reasons += _piston(pipeline, t_s + 0.001, counter)
    assert reasons[40:] == [("counter",), (), ()]
    assert pipeline.frames_lost == 0 and dict(pipeline.bad) == {"counter": 1}
