"""A signal sent under several multiplexer values, one input's value on each page
(tests/files/stranger/iom_channels: an I/O module's ``AIN_Druck`` under ``Kanal`` 0..3):
each chamber names its page (``multiplexer = 2`` or ``"AIN3"``) and reads that page's
frames only. Before, two chambers on the signal were refused as one ("is the piston's
signal"), and one alone read all four inputs in turn as its pressure."""

import math
import shutil
from pathlib import Path

import pytest

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from dbc.errors import ConfigError
from dbc.machine import load_machine_config
from tests.helpers import FILES
from tests.sim_bridge.synthetic import small_machine

STRANGER = FILES / "stranger"
FRONT_ID = 0x18FF0A21  # 29 bit, ExtendedCAN: matched by the whole ID, not as J1939
#: The example cylinder and lever of the held-out machines, written out here.
A_PISTON_M2, A_ROD_M2 = 7.854e-3, 4.737e-3
LEVER = (0.90 * math.sin(math.radians(75.0)) - 0.25 * math.cos(math.radians(75.0))) / 1.20
WEIGHT_TERM_N = 0.55 / 1.20 * 4905.0


def _frame(t_s: float, channel: int, p_bar: float, counter: int, diagnosis: int = 0) -> RawFrame:
    """IOM_VORNE_AIN of input ``channel``: Kanal in byte 0, AIN_Druck in bytes 1-2 (10 mbar
    per bit, offset -1000 mbar), AIN_Diagnose in byte 3, the counter in byte 7's low bits."""
    raw = round((p_bar * 1000 + 1000) / 10)
    data = bytes([channel, raw & 0xFF, raw >> 8, diagnosis, 0, 0, 0, counter])
    return RawFrame(t_s, FRONT_ID, True, data)


def test_each_chamber_reads_the_page_it_names() -> None:
    config, database = load_machine_config(STRANGER / "iom_channels.toml")
    assert str(config.legs["VL"].piston) == "IOM_VORNE_AIN.AIN_Druck[Kanal=0]"
    pipeline = Pipeline.from_config(config, database)
    inputs = ((1, 20.0, 0), (0, 100.0, 0), (2, 300.0, 3), (3, 50.0, 0))  # AIN2, AIN1, ...
    estimates = [
        estimate
        for counter, (channel, p_bar, diagnosis) in enumerate(inputs)
        for estimate in pipeline.process(
            _frame(1.0 + 0.001 * counter, channel, p_bar, counter, diagnosis)
        ).estimates
    ]
    assert pipeline.bad == {}
    assert [(e.leg, e.p_piston_Pa, e.p_rod_Pa) for e in estimates] == [
        ("VL", pytest.approx(100e5), pytest.approx(20e5)),
        ("VR", pytest.approx(300e5), pytest.approx(50e5)),  # triggered by its rod, AIN4
    ]
    vl, vr = estimates
    assert vl.valid and vl.force_raw_N == pytest.approx(
        (100e5 * A_PISTON_M2 - 20e5 * A_ROD_M2) * LEVER + WEIGHT_TERM_N
    )
    # AIN3's "Sensorfehler" is VR's piston's, judged with its page's frame only.
    assert not vr.valid and vr.reasons == ("status_Sensorfehler",)


@pytest.mark.parametrize(
    ("edit", "key", "reason"),
    [
        (
            ('multiplexer = "AIN1", ', ""),
            "legs.VL.piston.signal",
            "IOM_VORNE_AIN.AIN_Druck is sent under Kanal = 0 (AIN1), 1 (AIN2), 2 (AIN3), 3 "
            "(AIN4), a value on each page: set multiplexer = the page of this chamber's",
        ),
        (
            ('multiplexer = "AIN1"', 'multiplexer = "AIN5"'),
            "legs.VL.piston.multiplexer",
            "'AIN5' is no page of IOM_VORNE_AIN.AIN_Druck: it is sent under Kanal = 0 (AIN1), "
            "1 (AIN2), 2 (AIN3), 3 (AIN4)",
        ),
        (
            ("multiplexer = 2,", "multiplexer = true,"),
            "legs.VR.piston.multiplexer",
            "True is no page of IOM_VORNE_AIN.AIN_Druck: it is sent under Kanal = 0 (AIN1), "
            "1 (AIN2), 2 (AIN3), 3 (AIN4)",
        ),
        (
            (
                '"IOM_VORNE_AIN.AIN_Druck", multiplexer = "AIN1"',
                '"IOM_VORNE_AIN.IOM_Zaehler", multiplexer = 1, unit = "bar"',
            ),
            "legs.VL.piston.multiplexer",
            "IOM_VORNE_AIN.IOM_Zaehler is not under a multiplexer",
        ),
        (
            ('multiplexer = "AIN2",', 'multiplexer = "AIN2", unit = "psi",'),
            "legs.VL.rod",
            "IOM_VORNE_AIN.AIN_Druck[Kanal=1] is in 'psi' here and in 'mbar' for legs.VL.piston "
            "(pages of one signal); a signal's pages have one unit",
        ),
        (
            ('multiplexer = "AIN2"', 'multiplexer = "AIN1"'),
            "legs.VL.rod",
            "is the piston's signal IOM_VORNE_AIN.AIN_Druck[Kanal=0]; each chamber has its own",
        ),
    ],
)
def test_a_chamber_on_a_signal_of_several_pages_names_one_of_them(
    tmp_path: Path, edit: tuple[str, str], key: str, reason: str
) -> None:
    shutil.copy(STRANGER / "iom_channels.dbc", tmp_path)
    text = (STRANGER / "iom_channels.toml").read_text()
    assert edit[0] in text
    (tmp_path / "m.toml").write_text(text.replace(edit[0], edit[1], 1))
    with pytest.raises(ConfigError) as refused:
        load_machine_config(tmp_path / "m.toml")
    assert (refused.value.key, refused.value.reason) == (key, reason)


#: An I/O module counting its channels from 1: the multiplexer is (1,1), page 0 of the
#: DBC (``m0``, ``SG_MUL_VAL_ ... 0-3``) reads channel 1.
FROM_ONE = """
BO_ 1792 AIN: 8 IOM
 SG_ Channel M : 0|8@1+ (1,1) [1|4] "" DAQ
 SG_ Pressure m0 : 8|16@1+ (0.01,0) [0|600] "bar" DAQ
"""
FROM_ONE_ATTRIBUTES = 'BA_ "GenMsgCycleTime" BO_ 1792 10;\nSG_MUL_VAL_ 1792 Pressure Channel 0-3;\n'
FROM_ONE_LEGS = (
    '[legs.A]\npiston = { signal = "AIN.Pressure", multiplexer = 0 }\n'
    'rod = { signal = "AIN.Pressure", multiplexer = 1 }\n'
    '[legs.B]\npiston = { signal = "AIN.Pressure", multiplexer = 2 }\n'
    'rod = { signal = "AIN.Pressure", multiplexer = 3 }\n'
)


def test_the_pages_of_a_chamber_without_one_are_named_in_runs(tmp_path: Path) -> None:
    """iom_j1939's Channel 0..7 without a value table: the refusal names the run."""
    shutil.copy(STRANGER / "iom_j1939.dbc", tmp_path)
    text = (STRANGER / "iom_j1939.toml").read_text()
    (tmp_path / "m.toml").write_text(text.replace("multiplexer = 0, ", "", 1))
    with pytest.raises(ConfigError) as refused:
        load_machine_config(tmp_path / "m.toml")
    assert (refused.value.key, refused.value.reason) == (
        "legs.SB1_F1.piston.signal",
        "IOM_AIN.AIN_Pressure is sent under Channel = 0..7, a value on each page: set "
        "multiplexer = the page of this chamber's",
    )


def test_a_scaled_multiplexer_is_refused(tmp_path: Path) -> None:
    """cantools picks a frame's signals by the multiplexer's scaled value, the DBC's pages
    are raw: page 2's frames (Channel reads 3) were read as page 3's, and page 3's frames
    failed to decode; a leg on such a message stops the config."""
    with pytest.raises(ConfigError) as refused:
        small_machine(tmp_path, FROM_ONE, FROM_ONE_ATTRIBUTES, FROM_ONE_LEGS)
    assert (refused.value.key, refused.value.reason) == (
        "legs.A.piston.signal",
        "AIN's multiplexer Channel has factor 1 and offset 1: its frames' pages would be "
        "taken by the scaled value, not the raw one the DBC's pages are; give it (1,0) in "
        "the DBC",
    )
