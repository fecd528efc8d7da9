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
from dbc.database import load_database_string
from dbc.machine import MachineConfig, load_machine_config
from dbc.signal_range import named_values, value_range
from estimator import foot_force_N
from tests.helpers import LEG_DEFAULTS_TOML, dbc_text, machine_on

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


#: A 250 bar transducer's 12-bit pressures (0.05 bar/bit, Motorola) and a signed one, each
#: declared over all its bits (CANdb++'s default range), with codes named at the ends.
ENDS_DBC = dbc_text(
    """
BO_ 2148532496 HYD_P_ZYL1: 8 Tx
 SG_ HYD_P_ZYL1_A : 7|12@0+ (0.05,0) [0|204.75] "bar" DAQ
 SG_ HYD_P_ZYL1_B : 11|12@0+ (0.05,0) [0|204.75] "bar" DAQ
 SG_ HYD_P_ZYL1_DIFF : 31|16@0- (0.01,0) [-327.68|327.67] "bar" DAQ
""",
    """
BA_ "GenMsgCycleTime" BO_ 2148532496 10;
VAL_ 2148532496 HYD_P_ZYL1_A 4095 "SNA" 4094 "Fehler" 0 "Null" ;
VAL_ 2148532496 HYD_P_ZYL1_B 4095 "SNA" 4093 "Init" ;
VAL_ 2148532496 HYD_P_ZYL1_DIFF -32768 "Invalid" 32767 "SNA" 0 "Null" ;
""",
    nodes="Tx DAQ",
)


def _zyl1(a_raw: int, b_raw: int) -> RawFrame:
    packed = (a_raw << 12 | b_raw).to_bytes(3, "big") + bytes(5)
    return RawFrame(1.0, 0x00100110, True, packed)


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "reference"])
def test_a_code_named_at_the_top_of_the_bits_is_no_pressure_in_a_range_reaching_it(
    tmp_path: Path, compiled: bool
) -> None:
    """``4095 "SNA"`` of a 12-bit [0|204.75] bar signal was a valid 204.75 bar sample
    (inside the declared range, so taken for a named measurement, below the 400 bar
    sensor range)."""
    config, database = machine_on(
        tmp_path,
        ENDS_DBC,
        '[legs.ZYL1]\npiston = "HYD_P_ZYL1.HYD_P_ZYL1_A"\nrod = "HYD_P_ZYL1.HYD_P_ZYL1_B"\n',
    )
    diff = database.get_message_by_name("HYD_P_ZYL1").get_signal_by_name("HYD_P_ZYL1_DIFF")
    assert named_values(diff, j1939=False) == {"Null": 0.0}  # not -327.68 nor 327.67 bar
    assert config.legs["ZYL1"].piston.named_Pa == {"Null": 0.0}
    assert config.legs["ZYL1"].rod.named_Pa == {"Init": 4093 * 0.05e5}  # not next to the SNA
    pipeline = Pipeline.from_config(config, database)
    if not compiled:
        pipeline.decoder = type(pipeline.decoder)(
            database, config.protection, config.unit_factors, compiled=False
        )
    estimates = [pipeline.process(_zyl1(a, 400)).estimates[0] for a in (4095, 4094, 0, 2000)]
    assert [(e.valid, e.reasons) for e in estimates] == [
        (False, ("range",)),
        (False, ("range",)),
        (True, ()),
        (True, ()),
    ]
    assert math.isnan(estimates[0].p_piston_Pa) and math.isnan(estimates[1].p_piston_Pa)
    assert [e.p_piston_Pa for e in estimates[2:]] == [0.0, pytest.approx(100e5)]
    (estimate,) = pipeline.process(_zyl1(2000, 4095)).estimates
    assert estimate.reasons == ("range",) and math.isnan(estimate.p_rod_Pa)


def test_the_last_raw_values_of_the_bits_are_outside_the_value_range() -> None:
    """All ones (a signed signal's least value too) is a code or a saturated transducer,
    never a measurement, whatever range the DBC declares (here all the bits hold)."""
    message = load_database_string(ENDS_DBC, "ends.dbc").get_message_by_name("HYD_P_ZYL1")
    low, high = value_range(message.get_signal_by_name("HYD_P_ZYL1_A"), j1939=False)
    assert low <= 0.0 and 4094 * 0.05 <= high < 4095 * 0.05
    low, high = value_range(message.get_signal_by_name("HYD_P_ZYL1_DIFF"), j1939=False)
    assert -32768 * 0.01 < low <= -32767 * 0.01 and 32766 * 0.01 <= high < 32767 * 0.01


def test_the_end_codes_of_an_inverted_signal_are_no_pressure(tmp_path: Path) -> None:
    """A signal of negative factor (-0.01 bar/bit from 655.35 bar: raw 0 is the top) has
    its all-ones code at the bottom: 0xFFFF was a valid 0 bar (the checks at the ends of
    the bits were skipped for a factor below 0), and so was J1939's 0xFE00 error code."""
    messages = """
BO_ 256 INV: 4 Hub
 SG_ pCap : 0|16@1+ (-0.01,655.35) [0|655.35] "bar" DAQ
 SG_ pRod : 16|16@1+ (-0.01,655.35) [0|655.35] "bar" DAQ

BO_ 2566856704 XDCR: 8 Hub
 SG_ P : 0|16@1+ (-0.05,3276.75) [0|3276.75] "kPa" DAQ
"""
    attributes = (
        'BA_ "GenMsgCycleTime" BO_ 256 10;\nBA_ "GenMsgCycleTime" BO_ 2566856704 10;\n'
        'BA_ "VFrameFormat" BO_ 2566856704 3;\n'
    )
    legs = (
        '[legs.A]\npiston = "INV.pCap"\nrod = "INV.pRod"\n'
        '[legs.B]\npiston = { signal = "XDCR.P", source_address = 0x21 }\n'
        'rod = { signal = "XDCR.P", source_address = 0x22 }\n'
    )
    config, database = machine_on(tmp_path, dbc_text(messages, attributes), legs)
    pipeline = Pipeline.from_config(config, database)

    def inverted(cap_raw: int, rod_raw: int) -> RawFrame:
        return RawFrame(
            1.0, 256, False, cap_raw.to_bytes(2, "little") + rod_raw.to_bytes(2, "little")
        )

    (estimate,) = pipeline.process(inverted(55535, 60535)).estimates
    assert estimate.valid and estimate.p_piston_Pa == pytest.approx(100e5)
    assert estimate.p_rod_Pa == pytest.approx(50e5)
    (estimate,) = pipeline.process(inverted(55535, 0xFFFF)).estimates
    assert estimate.reasons == ("range",) and math.isnan(estimate.p_rod_Pa)
    low_Pa, high_Pa = config.legs["B"].piston.range_Pa
    # J1939's valid raw range ends at 0xFAFF: 0xFE00 (error) is 25.6 kPa here, below it.
    assert (0xFAFF + 0.5) * -50 + 3276.75e3 == pytest.approx(low_Pa)
    assert high_Pa == pytest.approx(3276.75e3 + 25, rel=1e-9)


#: Two hubs of signed 16-bit pressures (0.01 bar/bit, [-10|400] bar) whose value tables
#: name the transducer's 0xFFFF "not available" and 0xFFFE "error": as the bits decode
#: (-1, -2) and as a vendor's sheet lists them (65535, 65534).
SIGNED_DBC = dbc_text(
    """
BO_ 400 DRUCK_A: 4 Tx
 SG_ A_pK : 0|16@1- (0.01,0) [-10|400] "bar" DAQ
 SG_ A_pS : 16|16@1- (0.01,0) [-10|400] "bar" DAQ

BO_ 401 DRUCK_B: 4 Tx
 SG_ B_pK : 0|16@1- (0.01,0) [-10|400] "bar" DAQ
 SG_ B_pS : 16|16@1- (0.01,0) [-10|400] "bar" DAQ
""",
    """
BA_ "GenMsgCycleTime" BO_ 400 10;
BA_ "GenMsgCycleTime" BO_ 401 10;
VAL_ 400 A_pK -1 "SNA" -2 "Error" 0 "Null" ;
VAL_ 401 B_pK 65535 "SNA" 65534 "Error" ;
""",
    nodes="Tx DAQ",
)


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "reference"])
def test_a_signed_pressure_named_at_all_ones_is_no_pressure(tmp_path: Path, compiled: bool) -> None:
    """A non-J1939 signed pressure's 0xFFFF named "SNA" was a valid -0.01 bar (inside the
    declared range, so taken for a named measurement; keyed 65535 the name was never
    found), and the piston's "not available" made a valid foot force of -933 N. Unnamed,
    -1 step is a measurement."""
    legs = (
        '[legs.A]\npiston = "DRUCK_A.A_pK"\nrod = "DRUCK_A.A_pS"\n'
        '[legs.B]\npiston = "DRUCK_B.B_pK"\nrod = "DRUCK_B.B_pS"\n'
    )
    config, database = machine_on(tmp_path, SIGNED_DBC, legs)
    assert config.legs["A"].piston.named_Pa == {"Null": 0.0}
    pipeline = Pipeline.from_config(config, database)
    if not compiled:
        pipeline.decoder = type(pipeline.decoder)(
            database, config.protection, config.unit_factors, compiled=False
        )
    for frame_id in (400, 401):
        samples = []
        for t_s, piston_raw in ((1.0, 0xFFFF), (1.01, 0xFFFE), (1.02, 4000)):
            data = piston_raw.to_bytes(2, "little") + (0xFFFF).to_bytes(2, "little")
            samples += pipeline.process(RawFrame(t_s, frame_id, False, data)).estimates
        assert [(e.valid, e.reasons) for e in samples] == [(False, ("range",))] * 2 + [(True, ())]
        assert math.isnan(samples[0].p_piston_Pa) and math.isnan(samples[1].p_piston_Pa)
        # The rod's 0xFFFF is named in neither table: -1 step, a measurement.
        assert (samples[2].p_piston_Pa, samples[2].p_rod_Pa) == (40e5, pytest.approx(-1e3))
    decoded = pipeline.process(RawFrame(1.03, 401, False, bytes(4 * [0xFF]))).decoded
    assert decoded is not None and decoded.signals["B_pK"] == "SNA"
    assert not pipeline.bad
