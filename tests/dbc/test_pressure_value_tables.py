"""A pressure signal with a value table (J1939 transducers name their "not available" and
"error" codes): a frame carrying such a code makes an invalid sample (``range``), never
an exception and never a number; an entry naming a pressure inside the signal's range
(``0 "Zero"``) is that pressure."""

import math
from pathlib import Path

import pytest
from cantools.database.can import Database

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from dbc.machine import MachineConfig, load_machine_config
from estimator import foot_force_N
from tests.helpers import LEG_DEFAULTS_TOML, dbc_text

DBC = dbc_text(
    """
BO_ 2364538657 PRESS: 8 Tx
 SG_ P : 0|16@1+ (0.05,0) [0|3212.75] "kPa" DAQ

BO_ 768 HUB: 4 Tx
 SG_ pPiston : 0|16@1+ (0.01,0) [0|642.55] "bar" DAQ
 SG_ pRod : 16|16@1+ (0.01,0) [0|642.55] "bar" DAQ

BO_ 769 BARE: 4 Tx
 SG_ pPiston : 0|16@1+ (0.01,0) [0|0] "bar" DAQ
 SG_ pRod : 16|16@1+ (0.01,0) [0|0] "bar" DAQ
""",
    """
BA_ "GenMsgCycleTime" BO_ 2364538657 20;
BA_ "GenMsgCycleTime" BO_ 768 10;
BA_ "VFrameFormat" BO_ 2364538657 3;
VAL_ 2364538657 P 65535 "NotAvailable" 65024 "Error";
VAL_ 768 pRod 65535 "SNA" 0 "Zero";
BA_ "GenMsgCycleTime" BO_ 769 10;
VAL_ 769 pRod 0 "Zero";
""",
    nodes="Tx DAQ",
)

CONFIG = f"""
[machine]
id = "valtab"
mass_kg = 5000.0
dbc = "valtab.dbc"
{LEG_DEFAULTS_TOML}
[legs.J]
piston = {{ signal = "PRESS.P", source_address = 0x47 }}
rod = {{ signal = "PRESS.P", source_address = 0x05 }}

[legs.HUB]
piston = "HUB.pPiston"
rod = "HUB.pRod"

[legs.BARE]
piston = "BARE.pPiston"
rod = "BARE.pRod"
"""


def _load(tmp_path: Path) -> tuple[MachineConfig, Database]:
    (tmp_path / "valtab.dbc").write_text(DBC)
    (tmp_path / "machine.toml").write_text(CONFIG)
    return load_machine_config(tmp_path / "machine.toml")


def _press(t_s: float, source_address: int, raw: int) -> RawFrame:
    frame_id = (0x0CEFFF00 | source_address) & 0x1FFFFFFF
    return RawFrame(t_s, frame_id, True, raw.to_bytes(2, "little") + bytes(6))


def test_a_named_code_in_place_of_a_pressure_makes_an_invalid_sample(tmp_path: Path) -> None:
    config, database = _load(tmp_path)
    for compiled in (True, False):
        pipeline = Pipeline.from_config(config, database)
        if not compiled:
            pipeline.decoder = type(pipeline.decoder)(
                database, config.protection, config.unit_factors, compiled=False
            )
        pipeline.process(_press(1.0, 0x05, 0xFFFF))  # rod: not available
        (estimate,) = pipeline.process(_press(1.001, 0x47, 3000)).estimates
        assert not estimate.valid and estimate.reasons == ("range",)
        assert estimate.p_piston_Pa == 150e3 and math.isnan(estimate.p_rod_Pa)
        pipeline.process(_press(1.002, 0x05, 400))
        (estimate,) = pipeline.process(_press(1.003, 0x47, 3000)).estimates
        geometry = config.legs["J"].geometry
        assert estimate.valid and estimate.force_raw_N == foot_force_N(150e3, 20e3, geometry)
        hub = pipeline.process(RawFrame(1.004, 768, False, bytes([0x10, 0x27, 0xFF, 0xFF])))
        (estimate,) = hub.estimates
        assert estimate.reasons == ("range",) and estimate.p_piston_Pa == 100e5
        assert not pipeline.bad


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "reference"])
def test_a_value_table_name_inside_the_range_is_that_pressure(
    tmp_path: Path, compiled: bool
) -> None:
    config, database = _load(tmp_path)
    pipeline = Pipeline.from_config(config, database)
    if not compiled:
        pipeline.decoder = type(pipeline.decoder)(
            database, config.protection, config.unit_factors, compiled=False
        )
    # HUB.pRod [0|642.55] bar: raw 0 is named "Zero" and inside the range, a pressure;
    # raw 65535 "SNA" lies above the range: a code.
    result = pipeline.process(RawFrame(1.0, 768, False, bytes([0x10, 0x27, 0x00, 0x00])))
    assert result.decoded is not None and result.decoded.signals["pRod"] == "Zero"  # as named
    (estimate,) = result.estimates
    assert estimate.valid and estimate.reasons == ()
    assert (estimate.p_piston_Pa, estimate.p_rod_Pa) == (100e5, 0.0)
    (estimate,) = pipeline.process(RawFrame(1.01, 768, False, b"\x10\x27\xff\xff")).estimates
    assert estimate.reasons == ("range",) and math.isnan(estimate.p_rod_Pa)
    # BARE declares no range ([0|0]): nothing tells a code from a value, so "Zero" is a code.
    (estimate,) = pipeline.process(RawFrame(1.02, 769, False, bytes([0x10, 0x27, 0, 0]))).estimates
    assert estimate.reasons == ("range",) and math.isnan(estimate.p_rod_Pa)
    assert not pipeline.bad


def test_named_pressures_are_those_inside_the_declared_range(tmp_path: Path) -> None:
    config, _ = _load(tmp_path)
    legs = config.legs
    assert legs["HUB"].rod.named_Pa == {"Zero": 0.0}  # not "SNA", 655.35 bar > 642.55 bar
    assert legs["J"].piston.named_Pa == {}  # both codes above [0|3212.75] kPa
    assert legs["BARE"].rod.named_Pa == {}  # no declared range
