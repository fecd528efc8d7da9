"""A DBC refused says what to change where cantools' words alone do not."""

from pathlib import Path

import pytest

from dbc.database import load_database_string
from dbc.errors import ConfigError, DbcError
from tests.helpers import dbc_text, machine_on


def test_a_29_bit_id_without_the_extended_flag_names_the_id_to_write() -> None:
    """A hand-written J1939 DBC with BO_ 0x18FF2021 in decimal, bit 31 left out: the
    reason was cantools' alone ("Standard frame id ... is more than 11 bits")."""
    text = dbc_text('BO_ 419373089 XDCR: 8 Xdcr\n SG_ P : 0|16@1+ (0.01,0) [0|0] "bar" DAQ\n', "")
    with pytest.raises(DbcError) as refused:
        load_database_string(text, "vendor.dbc")
    assert str(refused.value).endswith(
        'is more than 11 bits in message XDCR." (a 29-bit ID is written with bit 31 set '
        "in a DBC: BO_ 2566856737, not BO_ 419373089)"
    )


def test_statements_naming_a_29_bit_message_without_its_flag_are_that_messages(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """BO_ 2566856737 (0x18FF2021 with bit 31) and its cycle time, value tables, comment
    and float type written with 419373089 (a script writing the ID both ways): cantools
    ignored the cycle time (the config said the DBC had none) and refused the value
    table (left out: the status had no names). A 11-bit message's statements stay."""
    messages = (
        'BO_ 2566856737 XDCR: 8 Xdcr\n SG_ P : 0|32@1- (1,0) [0|4e7] "Pa" DAQ\n'
        ' SG_ Status : 32|2@1+ (1,0) [0|3] "" DAQ\n'
        'BO_ 1024 STATE: 1 Ctrl\n SG_ Phase : 0|8@1+ (1,0) [0|4] "" DAQ\n'
    )
    attributes = (
        'BA_ "GenMsgCycleTime" BO_ 419373089 20;\nBA_ "GenMsgCycleTime" BO_ 1024 100;\n'
        'VAL_ 419373089 Status 0 "ok" 1 "fault" ;\nVAL_ 1024 Phase 0 "idle" ;\n'
        'CM_ SG_ 419373089 P "Pressure";\nSIG_VALTYPE_ 419373089 P : 1;\n'
    )
    with caplog.at_level("WARNING", logger="dbc.database"):
        database = load_database_string(dbc_text(messages, attributes), "vendor.dbc")
    xdcr = database.get_message_by_name("XDCR")
    assert xdcr.cycle_time == 20 and xdcr.get_signal_by_name("Status").choices == {
        0: "ok",
        1: "fault",
    }
    assert xdcr.get_signal_by_name("P").is_float and xdcr.get_signal_by_name("P").comment
    state = database.get_message_by_name("STATE")
    assert state.cycle_time == 100 and state.get_signal_by_name("Phase").choices == {0: "idle"}
    assert [r.getMessage() for r in caplog.records] == [
        "vendor.dbc: read as the 29-bit messages they are: the statements naming 419373089 "
        "(BO_ 2566856737) without the extended flag (bit 31)"
    ]


def test_attributes_given_without_a_definition_are_defined_by_their_values(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """A DBC written by a script gives the cycle time, the frame format and the network's
    protocol (BA_) without defining them (BA_DEF_): cantools refused it whole, 'not a
    valid DBC: DBC: "'GenMsgCycleTime'"'. Each is defined by its values, so the message
    is J1939 every 20 ms."""
    text = (
        'VERSION ""\nNS_ :\nBS_:\nBU_: Xdcr\n'
        'BO_ 2566856737 XDCR: 8 Xdcr\n SG_ P : 0|16@1+ (0.01,0) [0|600] "bar" DAQ\n'
        'BA_DEF_DEF_ "GenMsgCycleTime" 0;\nBA_ "ProtocolType" "J1939";\n'
        'BA_ "GenMsgCycleTime" BO_ 2566856737 20;\nBA_ "VFrameFormat" BO_ 2566856737 3;\n'
        'BA_ "GenSigStartValue" SG_ 2566856737 P 1.5;\nBA_ "NodeId" BU_ Xdcr 33;\n'
    )
    with caplog.at_level("WARNING", logger="dbc.database"):
        database = load_database_string(text, "script.dbc")
    (xdcr,) = database.messages
    assert (xdcr.cycle_time, xdcr.protocol) == (20, "j1939")
    assert xdcr.get_signal_by_name("P").dbc.attributes["GenSigStartValue"].value == 1.5
    assert [r.getMessage() for r in caplog.records] == [
        "script.dbc: attributes given without a definition (BA_DEF_), defined by their "
        "values: ProtocolType, GenMsgCycleTime, VFrameFormat, GenSigStartValue, NodeId"
    ]


def test_a_statement_without_its_semicolon_is_pointed_at() -> None:
    """A value table written by hand without its ';': cantools' reason names the next
    line, column 1, which is right as it is."""
    text = dbc_text(
        'BO_ 256 HUB: 8 Hub\n SG_ Status : 0|2@1+ (1,0) [0|3] "" DAQ\n',
        'VAL_ 256 Status 0 "ok" 1 "fault"\nBA_ "GenMsgCycleTime" BO_ 256 10;\n',
    )
    with pytest.raises(DbcError) as refused:
        load_database_string(text, "hand.dbc")
    assert str(refused.value).endswith(
        'column 1: ">>!<<BA_ "GenMsgCycleTime" BO_ 256 10;"" (does the statement before '
        "line 13 end with its ';'?)"
    )
    with pytest.raises(DbcError) as refused:
        load_database_string("leg,t,force_N\nA,1.0,2.0\n", "estimates.csv")
    assert "statement before" not in str(refused.value)


def test_an_empty_file_says_so() -> None:
    """It was cantools' 'Invalid syntax at line 1, column 1: ">>!<<"'."""
    for text in ("", "\n  \r\n"):
        with pytest.raises(DbcError) as refused:
            load_database_string(text, "empty.dbc")
        assert str(refused.value) == "empty.dbc: is empty: no CAN messages"


def test_a_quote_left_open_is_pointed_at() -> None:
    """A unit written without its closing '"': cantools reads on to the next '"', lines
    later, and names where it stopped (line 13, a BA_ the user never touched)."""
    text = dbc_text(
        'BO_ 256 HUB: 8 Hub\n SG_ pA : 0|16@1+ (0.01,0) [0|600] "bar DAQ\n'
        ' SG_ pB : 16|16@1+ (0.01,0) [0|600] "bar" DAQ\n',
        'BA_ "GenMsgCycleTime" BO_ 256 10;\n',
    )
    with pytest.raises(DbcError) as refused:
        load_database_string(text, "hand.dbc")
    assert str(refused.value).startswith(
        'hand.dbc: not a valid DBC: DBC: "Invalid syntax at line 13, column 21:'
    )
    assert str(refused.value).endswith(" (line 6 opens a '\"' it does not close)")


@pytest.mark.parametrize(
    ("attributes", "hint"),
    [
        (
            'BA_DEF_ BO_ "GenMsgSendType" ENUM "Cyclic","Event";\n'
            'BA_ "GenMsgSendType" BO_ 256 "Event";\n',
            '(line 15: BA_ "GenMsgSendType" BO_ 256 "Event"; gives a string to the ENUM '
            'attribute: write its value\'s index, 1 for "Event")',
        ),
        (
            'BA_DEF_ BO_ "GenMsgSendType" ENUM "Cyclic","Event";\n'
            'BA_ "GenMsgSendType" BO_ 256 "cyclic";\n',
            '(line 15: BA_ "GenMsgSendType" BO_ 256 "cyclic"; gives a string to the ENUM '
            'attribute: write its value\'s index; "cyclic" is none of them)',
        ),
        (  # a number in quotes is read as that number; the word after it is the problem
            'BA_ "GenMsgCycleTime" BO_ 256 "20";\nBA_ "GenMsgCycleTime" BO_ 257 "fast";\n',
            '(line 15: BA_ "GenMsgCycleTime" BO_ 257 "fast"; gives a string to the INT '
            "attribute: write a number)",
        ),
    ],
)
def test_a_string_given_to_a_number_attribute_is_pointed_at(attributes: str, hint: str) -> None:
    """cantools' reason was '[<class 'decimal.ConversionSyntax'>]' alone: no line, no name."""
    text = dbc_text(
        'BO_ 256 HUB: 8 Hub\n SG_ pA : 0|16@1+ (0.01,0) [0|600] "bar" DAQ\n'
        'BO_ 257 HUB2: 8 Hub\n SG_ pB : 0|16@1+ (0.01,0) [0|600] "bar" DAQ\n',
        attributes,
    )
    with pytest.raises(DbcError) as refused:
        load_database_string(text, "script.dbc")
    assert str(refused.value) == (
        "script.dbc: not a valid DBC: DBC: \"[<class 'decimal.ConversionSyntax'>]\" " + hint
    )


def test_a_message_longer_than_a_can_fd_frame_stops_the_config(tmp_path: Path) -> None:
    """cantools takes a 65-byte message (a typo for 64, or 8): no frame on the bus can be
    it, every one was wrong_dlc, and `check` passed it."""
    text = dbc_text(
        'BO_ 256 HUB: 65 Hub\n SG_ pA : 0|16@1+ (0.01,0) [0|600] "bar" DAQ\n'
        ' SG_ pB : 16|16@1+ (0.01,0) [0|600] "bar" DAQ\n',
        'BA_ "GenMsgCycleTime" BO_ 256 10;\n',
    )
    with pytest.raises(ConfigError) as refused:
        machine_on(tmp_path, text, '[legs.A]\npiston = "HUB.pA"\nrod = "HUB.pB"\n')
    assert str(refused.value) == (
        f"{tmp_path / 'm.toml'}: legs.A.piston: message HUB of the DBC: HUB is 65 bytes "
        "long: a CAN frame carries 64 at most (CAN FD)"
    )
    config, _ = machine_on(
        tmp_path,
        text.replace("HUB: 65", "HUB: 64"),
        '[legs.A]\npiston = "HUB.pA"\nrod = "HUB.pB"\n',
    )
    assert config.legs["A"].piston.message == "HUB"


def test_two_signals_of_one_name_are_told_as_such(tmp_path: Path) -> None:
    """Two signals named pB at bits 16 and 32 (a copy-paste left unrenamed): cantools
    said 'The signals pB and pB are overlapping', which they are not."""
    text = dbc_text(
        'BO_ 256 HUB: 8 Hub\n SG_ pA : 0|16@1+ (0.01,0) [0|600] "bar" DAQ\n'
        ' SG_ pB : 16|16@1+ (0.01,0) [0|600] "bar" DAQ\n'
        ' SG_ pB : 32|16@1+ (0.01,0) [0|600] "bar" DAQ\n',
        'BA_ "GenMsgCycleTime" BO_ 256 10;\n',
    )
    with pytest.raises(ConfigError) as refused:
        machine_on(tmp_path, text, '[legs.A]\npiston = "HUB.pA"\nrod = "HUB.pB"\n')
    assert str(refused.value) == (
        f"{tmp_path / 'm.toml'}: legs.A.piston: message HUB of the DBC: HUB has two signals "
        "named pB (start bits 16, 32): rename one"
    )
