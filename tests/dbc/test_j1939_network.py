"""A DBC of a J1939 network that marks it so (``BA_ "ProtocolType" "J1939"``, Vector's
J1939 template) but gives its messages no ``VFrameFormat``: its 29-bit messages are
J1939 parameter groups, matched by PGN."""

from pathlib import Path

import pytest
from cantools.j1939 import frame_id_pack

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from dbc.database import load_database_string
from dbc.decoding import is_j1939
from dbc.errors import ConfigError
from tests.dbc.test_held_out_machines import eq4_N
from tests.helpers import machine_on

#: PGN 0x1FF30 (data page 1) from 0x30 at priority 6, in the DBC; an 11-bit controller frame.
DBC = """VERSION ""
NS_ :
BS_:
BU_: Dual Vcu DAQ
BO_ 2583638064 DUAL_P: 8 Dual
 SG_ P1 : 0|16@1+ (0.5,0) [0|32127.5] "kPa" DAQ
 SG_ P2 : 16|16@1+ (0.5,0) [0|32127.5] "kPa" DAQ

BO_ 784 VCU: 1 Vcu
 SG_ Phase : 0|8@1+ (1,0) [0|250] "" DAQ

BA_DEF_  "ProtocolType" STRING ;
BA_DEF_ BO_ "GenMsgCycleTime" INT 0 3600000;
BA_DEF_DEF_  "ProtocolType" "";
BA_DEF_DEF_ "GenMsgCycleTime" 0;
BA_ "ProtocolType" "J1939";
BA_ "GenMsgCycleTime" BO_ 2583638064 10;
"""
LEG = '[legs.front]\npiston = "DUAL_P.P1"\nrod = "DUAL_P.P2"\n'


def test_the_29_bit_messages_of_a_j1939_network_are_parameter_groups() -> None:
    database = load_database_string(DBC, "j1939.dbc")
    assert is_j1939(database.get_message_by_name("DUAL_P"))
    assert not is_j1939(database.get_message_by_name("VCU"))
    plain = load_database_string(DBC.replace('BA_ "ProtocolType" "J1939";\n', ""), "can.dbc")
    assert not is_j1939(plain.get_message_by_name("DUAL_P"))


def test_a_transducer_at_another_priority_than_the_dbcs_feeds_its_leg(tmp_path: Path) -> None:
    """Matched by the whole ID, its frames were unknown_id and the leg stale."""
    config, database = machine_on(tmp_path, DBC, LEG)
    pipeline = Pipeline.from_config(config, database)
    frame_id = frame_id_pack(3, 0, 1, 0xFF, 0x30, 0x30)  # priority 3, not the DBC's 6
    data = (25000).to_bytes(2, "little") + (2000).to_bytes(2, "little") + b"\xff" * 4
    result = pipeline.process(RawFrame(1.0, frame_id, True, data))
    assert result.error_kind is None
    (estimate,) = result.estimates
    assert estimate.valid and estimate.force_raw_N == pytest.approx(eq4_N(12.5e6, 1e6))


def test_a_chamber_in_a_parameter_group_longer_than_a_frame_is_refused(tmp_path: Path) -> None:
    """J1939 sends a 12-byte group in TP.CM/TP.DT packets, never as a frame of its PGN:
    the config was taken and the leg silent for ever, nothing saying why."""
    with pytest.raises(ConfigError) as refused:
        machine_on(tmp_path, DBC.replace("DUAL_P: 8", "DUAL_P: 12"), LEG)
    assert str(refused.value) == (
        f"{tmp_path / 'm.toml'}: legs.front.piston: DUAL_P is a J1939 parameter group "
        "of 12 bytes: J1939 sends one of more than 8 in transport-protocol packets (TP.CM/TP.DT, "
        "PGN 0xEC00/0xEB00), which are not reassembled, so no frame of it would come; a chamber "
        "needs one of up to 8 bytes (or a CAN FD message: VFrameFormat ExtendedCAN_FD)"
    )
