"""The precompiled decoder and the table CRCs agree with the reference path (cantools, crc)."""

import cantools
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dbc._compiled_codec import CompiledMessage
from dbc.decoding import FrameDecoder
from dbc.protection import CRC_ALGORITHMS, TableCrc, reference_checksum
from tests.helpers import example_machine

CONFIG, DATABASE = example_machine()
MESSAGES = DATABASE.messages

# Layouts the example DBC does not have: Motorola byte order, signed values with and
# without scaling, a value table on a signed signal, odd positions and lengths, a
# 5-byte message; and two messages the compiler must leave to cantools.
OTHER_DBC = """VERSION ""

BS_:

BU_: A

BO_ 1 MOTOROLA: 8 A
 SG_ be_unsigned : 7|12@0+ (0.5,-100) [-100|1947.5] "" A
 SG_ be_signed : 11|13@0- (1,0) [-4096|4095] "" A
 SG_ be_int_scaled : 30|7@0- (3,2) [-190|191] "" A
 SG_ le_odd : 41|11@1- (0.25,0) [-256|255.75] "" A
 SG_ le_choice : 52|4@1- (1,0) [-8|7] "" A
 SG_ le_top : 56|8@1+ (1,0) [0|255] "" A

BO_ 2 SHORT: 5 A
 SG_ a : 3|17@1+ (1,0) [0|131071] "" A
 SG_ b : 39|8@0- (10,5) [-1275|1275] "" A

BO_ 3 MUXED: 8 A
 SG_ mux M : 0|8@1+ (1,0) [0|255] "" A
 SG_ x m1 : 8|16@1+ (1,0) [0|65535] "" A
 SG_ y m2 : 8|16@1- (1,0) [-32768|32767] "" A

BO_ 4 FLOATING: 8 A
 SG_ f : 0|32@1- (1,0) [0|0] "" A

VAL_ 1 le_choice -8 "lowest" -1 "minus_one" 0 "zero" 7 "highest" ;
SIG_VALTYPE_ 4 f : 1;
"""
OTHER = cantools.database.load_string(OTHER_DBC, database_format="dbc", strict=True)


def typed(signals: dict) -> list[tuple[str, type, object]]:
    """Names, in order, with the type and value of each: 1000 and 1000.0 differ here."""
    return [(name, type(value), value) for name, value in signals.items()]


@settings(max_examples=400)
@given(
    st.sampled_from(MESSAGES),
    st.lists(st.tuples(st.binary(min_size=8, max_size=8), st.booleans()), min_size=1, max_size=20),
)
def test_random_frames_of_the_dbc_decode_alike_both_ways(message, frames) -> None:  # type: ignore[no-untyped-def]
    """Every signal (values, types, order), the CRC and the rolling-counter verdicts."""
    compiled = FrameDecoder(DATABASE, CONFIG.protection)
    reference = FrameDecoder(DATABASE, CONFIG.protection, compiled=False)
    for t_s, (payload, fix_crc) in enumerate(frames):
        data = bytearray(payload)
        if fix_crc:  # mostly good frames, so that the counters are judged too
            crc = CONFIG.protection[message.name].crc_check(message)
            assert crc is not None
            crc.write(data)
        a = compiled.decode(message.frame_id, bytes(data), float(t_s))
        b = reference.decode(message.frame_id, bytes(data), float(t_s))
        assert (a.message, a.t_s, a.faults, a.frames_lost) == (
            b.message,
            b.t_s,
            b.faults,
            b.frames_lost,
        )
        assert typed(dict(a.signals)) == typed(dict(b.signals))


def test_every_message_of_the_dbc_is_compiled() -> None:
    assert all(CompiledMessage.compile(message) is not None for message in MESSAGES)


@pytest.mark.parametrize("name", ["MOTOROLA", "SHORT"])
@given(data=st.binary(min_size=8, max_size=8))
def test_other_layouts_decode_like_cantools(name: str, data: bytes) -> None:
    message = OTHER.get_message_by_name(name)
    payload = data[: message.length]
    compiled = CompiledMessage.compile(message)
    assert compiled is not None
    reference = message.decode(payload, decode_choices=True, scaling=True)
    expected = {key: getattr(value, "name", value) for key, value in reference.items()}
    assert typed(compiled.decode(payload)) == typed(expected)


def test_value_table_and_sign_of_motorola_frame() -> None:
    message = OTHER.get_message_by_name("MOTOROLA")
    values = {
        "be_unsigned": 12.5,
        "be_signed": -1234,
        "be_int_scaled": -97,
        "le_odd": -3.25,
        "le_choice": "minus_one",
        "le_top": 200,
    }
    data = message.encode(values)
    compiled = CompiledMessage.compile(message)
    assert compiled is not None
    assert compiled.decode(data) == values


def test_multiplexed_and_float_messages_are_left_to_cantools() -> None:
    assert CompiledMessage.compile(OTHER.get_message_by_name("MUXED")) is None
    assert CompiledMessage.compile(OTHER.get_message_by_name("FLOATING")) is None
    decoder = FrameDecoder(OTHER, {})
    frame = decoder.decode(3, bytes([1, 0x34, 0x12, 0, 0, 0, 0, 0]), 0.0)
    assert dict(frame.signals) == {"mux": 1, "x": 0x1234}


@pytest.mark.parametrize("algorithm", sorted(CRC_ALGORITHMS))
@given(data=st.binary(max_size=64))
def test_table_crcs_match_the_crc_package(algorithm: str, data: bytes) -> None:
    configuration = CRC_ALGORITHMS[algorithm].configuration
    assert TableCrc(configuration).checksum(data) == reference_checksum(configuration)(data)


def test_pressures_in_bar_decode_to_pa_alike_both_ways() -> None:
    """Unit factors apply after the DBC's scale and offset on both paths."""
    message = OTHER.get_message_by_name("MOTOROLA")
    to_si = {"MOTOROLA": {"be_unsigned": 1e5, "le_odd": 6894.757293168361}}
    data = bytes(range(8))
    a = FrameDecoder(OTHER, {}, to_si).decode(1, data, 0.0).signals
    b = FrameDecoder(OTHER, {}, to_si, compiled=False).decode(1, data, 0.0).signals
    plain = message.decode(data, decode_choices=False)
    assert typed(dict(a)) == typed(dict(b))
    assert a["be_unsigned"] == plain["be_unsigned"] * 1e5
    assert a["le_odd"] == plain["le_odd"] * 6894.757293168361
    assert a["be_signed"] == plain["be_signed"]  # not a pressure: untouched
