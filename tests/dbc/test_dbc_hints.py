"""A DBC refused says what to change where cantools' words alone do not."""

import pytest

from dbc.database import load_database_string
from dbc.errors import DbcError
from tests.helpers import dbc_text


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
