"""AUTOSAR E2E profile 1 as real senders compute it: the CRC (SAE J1850's polynomial with
AUTOSAR's chained start value: init 0x00, no final XOR) in each DataIDMode, the counter
0..14, the data ID nibble; its config keys; a counter or CRC the config leaves unnamed
(tests/files/stranger/e2e_p1_modes)."""

import logging
import tomllib

import pytest
from cantools.autosar.end_to_end import compute_profile2_crc
from crccheck.crc import Crc

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from dbc.errors import ConfigError
from dbc.machine import load_machine_config, machine_from_toml
from dbc.protection import CRC_ALGORITHMS, CrcCheck
from tests.helpers import FILES

STRANGER = FILES / "stranger"
TOML = (STRANGER / "e2e_p1_modes.toml").read_text()
# Profile 1's CRC by an implementation of its own (crccheck's generic engine).
P1_CRC = Crc(8, 0x1D, initvalue=0x00, reflect_input=False, reflect_output=False, xor_output=0)


@pytest.mark.parametrize(
    ("profile", "mode", "crc_counter_0", "crc_counter_1"),
    [
        ("e2e_p1", "both", 0xCC, 0x91),
        ("e2e_p1", "alt", 0xCE, 0x02),
        ("e2e_p1", "low", 0xCE, 0x93),
        ("e2e_p1", "nibble", 0x2A, 0x77),
        ("e2e_p11", "both", 0xCC, 0x91),
        ("e2e_p11", "nibble", 0x2A, 0x77),
    ],
)
def test_each_data_id_mode_gives_the_reference_crcs(
    profile: str, mode: str, crc_counter_0: int, crc_counter_1: int
) -> None:
    """The vectors of the autosar-e2e package's tests (its C implementation of AUTOSAR's
    E2E_P01 and E2E_P11, one CRC): data ID 0x123, 8 bytes, CRC in byte 0, counter in byte
    1's low nibble, the nibble mode's 0x1 in its high nibble. The CRC-8 SAE J1850 with its
    0xFF init and final XOR gave 0xB0 for the first (every frame of a real sender a CRC
    fault)."""
    check = CrcCheck(CRC_ALGORITHMS[profile], 0, data_id=0x123, data_id_mode=mode)
    nibble = 0x10 if mode == "nibble" else 0x00
    first = bytes([crc_counter_0, nibble | 0]) + bytes(6)
    second = bytes([crc_counter_1, nibble | 1]) + bytes(6)
    assert check.compute(first, 0) == crc_counter_0 and check.matches(first, 0)
    assert check.compute(second, 1) == crc_counter_1 and check.matches(second, 1)


def _bar(value: float) -> bytes:
    return round(value / 0.01).to_bytes(2, "little")


def sender_frames(counters: list[int], nibble: int = 0xA) -> list[RawFrame]:
    """Frames of legs VL (mode both) and HR (mode nibble) as a profile-1 sender builds
    them, one per counter value, every 10 ms: 150 bar piston, 20 bar rod, status 0."""
    frames = []
    for i, counter in enumerate(counters):
        t_s = 1.0 + 0.01 * i
        data = bytes([counter]) + _bar(150.0) + _bar(20.0) + bytes(2)
        vl = bytes([P1_CRC.calc(bytes([0x23, 0x01]) + data)]) + data
        data = bytes([nibble << 4 | counter]) + _bar(150.0) + _bar(20.0) + bytes(2)
        hr = bytes([P1_CRC.calc(bytes([0x42, 0x00]) + data)]) + data
        frames += [RawFrame(t_s, 257, False, vl), RawFrame(t_s + 0.001, 260, False, hr)]
    return frames


def estimates(pipeline: Pipeline, frames: list[RawFrame]) -> list[tuple[str, tuple[str, ...]]]:
    return [(e.leg, e.reasons) for frame in frames for e in pipeline.process(frame).estimates]


def test_a_real_senders_frames_are_valid_and_its_wrap_from_14_loses_nothing() -> None:
    """Counters 0..14, 0..14, 0: every sample valid, no frame counted lost, though the DBC
    declares the counters [0|15] (CANdb++'s default): 14 -> 0 is one step of profile 1."""
    config, database = load_machine_config(STRANGER / "e2e_p1_modes.toml")
    pipeline = Pipeline.from_config(config, database)
    got = estimates(pipeline, sender_frames([*range(15), *range(15), 0]))
    assert len(got) == 62 and all(reasons == () for _, reasons in got)
    assert pipeline.bad == {} and pipeline.frames_lost == 0


def test_a_counter_of_15_and_another_senders_nibble_are_faults() -> None:
    """15 is no profile-1 counter value (`counter`); a frame whose CRC is right over its
    bytes but whose data ID nibble is another's (0xB42) is another sender's (`crc`)."""
    config, database = load_machine_config(STRANGER / "e2e_p1_modes.toml")
    pipeline = Pipeline.from_config(config, database)
    got = estimates(pipeline, sender_frames([13, 14, 15, 0]))
    assert [r for leg, r in got if leg == "VL"] == [(), (), ("counter",), ()]
    pipeline = Pipeline.from_config(config, database)
    got = estimates(pipeline, sender_frames([1, 2], nibble=0xB))
    assert [r for leg, r in got if leg == "HR"] == [("crc",), ("crc",)]
    assert pipeline.bad == {"crc": 2}


@pytest.mark.parametrize("written", ["alt", "ALT", "E2E_P01_DATAID_ALT", "DATAID_ALT"])
def test_a_data_id_mode_is_taken_as_autosar_tools_write_it(written: str) -> None:
    """VR's mode as the profile's DataIDMode is named in an ARXML or a tool's export: its
    frames' CRCs then use the high byte of the data ID on odd counters (a wrong mode taken
    silently would make every other frame a crc fault)."""
    text = TOML.replace('data_id_mode = "alt"', f'data_id_mode = "{written}"')
    config, _ = machine_from_toml(tomllib.loads(text), "m.toml", STRANGER)
    assert config.protection["ZYL_VR"].data_id_mode == "alt"


def test_profiles_11_and_22_read_what_their_senders_send() -> None:
    """HR as profile 11 (nibble) and the machine state as profile 22 (DataIDList): the
    frames of a real sender valid, the 14 -> 0 wrap one step; the state's CRC as
    cantools.autosar computes profile 2's with the list's ID for the counter."""
    text = TOML.replace(
        'crc = "ZYL_HR_CRC"\ncrc_algorithm = "e2e_p1"',
        'crc = "ZYL_HR_CRC"\ncrc_algorithm = "e2e_p11"',
    ).replace('crc_algorithm = "e2e_p2"', 'crc_algorithm = "e2e_p22"')
    assert text.count("e2e_p11") == 1 and text.count("e2e_p22") == 1
    config, database = machine_from_toml(tomllib.loads(text), "m.toml", STRANGER)
    pipeline = Pipeline.from_config(config, database)
    got = estimates(pipeline, sender_frames([*range(15), 0]))
    assert len(got) == 32 and all(reasons == () for _, reasons in got)
    for counter in (3, 15):
        data = bytearray([0, counter, 2, 7, 0, 40, 0, 0])
        data[0] = compute_profile2_crc(bytes(data), 0x60 + counter)
        pipeline.process(RawFrame(2.0 + counter, 0x200, False, bytes(data)))
    assert pipeline.bad == {} and pipeline.frames_lost == 0
    with pytest.raises(ConfigError, match="unknown 'alt' for e2e_p11; one of both, nibble"):
        machine_from_toml(
            tomllib.loads(text.replace('data_id_mode = "nibble"', 'data_id_mode = "alt"')),
            "m.toml",
            STRANGER,
        )


@pytest.mark.parametrize(
    ("old", "new", "key", "reason"),
    [
        (
            'data_id = 0x0056\ndata_id_mode = "low"',
            'data_id = 0x0056\ndata_id_mode = "lo"',
            "ZYL_HL.data_id_mode",
            "unknown 'lo' for e2e_p1; one of both, alt, low, nibble",
        ),
        ('counter = "ZYL_VR_AliveCounter"\n', "", "ZYL_VR.data_id_mode", "name the counter"),
        ('data_id_nibble = "ZYL_HR_DataIDNibble"\n', "", "ZYL_HR.data_id_nibble", "missing"),
        (
            'data_id_nibble = "ZYL_HR_DataIDNibble"',
            'data_id_nibble = "ZYL_HR_Cnt"',
            "ZYL_HR.data_id_nibble",
            "must be a 4-bit signal of its own",
        ),
        (
            'data_id_nibble = "ZYL_HR_DataIDNibble"',
            'data_id_nibble = "ZYL_HR_pKolben"',
            "ZYL_HR.data_id_nibble",
            "must be a 4-bit signal of its own",
        ),
        (
            'data_id_mode = "low"',
            'data_id_mode = "low"\ndata_id_nibble = "ZYL_HL_Zustand"',
            "ZYL_HL.data_id_nibble",
            'only with data_id_mode = "nibble"',
        ),
        (
            'crc_algorithm = "e2e_p2"',
            'crc_algorithm = "e2e_p2"\ndata_id_mode = "alt"',
            "MASCHINE_ZUSTAND.data_id_mode",
            "only e2e_p1 and e2e_p11 have a data ID mode",
        ),
        ('counter = "MZ_Zaehler"\n', "", "MASCHINE_ZUSTAND.data_id", "name the counter too"),
        (
            'counter = "ZYL_VL_Zaehler"',
            'counter = "ZYL_VL_Pruefsumme"',
            "ZYL_VL.counter",
            "ZYL_VL_Pruefsumme is the crc too: the rolling counter is a signal of its own",
        ),
        # A profile's config without its crc_algorithm: the default's name alone did not
        # say that it was the default, nor which profile has a data ID or a 16-bit CRC.
        (
            'crc = "ZYL_VL_Pruefsumme"\ncrc_algorithm = "e2e_p1"\n',
            'crc = "ZYL_VL_Pruefsumme"\n',
            "ZYL_VL.data_id",
            "crc8_sae_j1850 (the default: no crc_algorithm given) has no data ID (the E2E "
            "profiles have: e2e_p1, e2e_p11, e2e_p2, e2e_p22, e2e_p5)",
        ),
        (
            'crc = "ZYL_VL_Pruefsumme"\ncrc_algorithm = "e2e_p1"\n',
            'crc = "ZYL_VL_Pruefsumme"\ncrc_algorithm = "e2e_p5"\n',
            "ZYL_VL.crc",
            "ZYL_VL_Pruefsumme must be a 16-bit signal on byte boundaries for e2e_p5, is 8 "
            "bits from bit 0",
        ),
        (
            'crc = "ZYL_HL_CRC8"\ncrc_algorithm = "e2e_p1"\n',
            'crc = "ZYL_HL_Zustand"\ncrc_algorithm = "e2e_p1"\n',
            "ZYL_HL.crc",
            "ZYL_HL_Zustand must be an 8-bit signal on byte boundaries for e2e_p1, is 4 bits "
            "from bit 15",
        ),
    ],
)
def test_bad_profile_1_and_2_keys_are_one_line(old: str, new: str, key: str, reason: str) -> None:
    assert old in TOML
    text = TOML.replace(old, new)
    with pytest.raises(ConfigError) as info:
        machine_from_toml(tomllib.loads(text), "m.toml", STRANGER)
    assert info.value.key == f"protection.{key}" and reason in str(info.value)
    assert "\n" not in str(info.value)


def test_a_counter_or_crc_the_config_leaves_unnamed_is_one_warning_line(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """Without [protection.ZYL_VL], and with ZYL_HL's crc left out, those frames were
    taken unchecked (a frozen sender's pressures valid) and nothing said so; the full
    config warns of nothing."""
    without = TOML.replace(
        '[protection.ZYL_VL]\ncounter = "ZYL_VL_Zaehler"\ncrc = "ZYL_VL_Pruefsumme"\n'
        'crc_algorithm = "e2e_p1"\ndata_id = 0x0123\n',
        "",
    ).replace('crc = "ZYL_HL_CRC8"\n', "")
    with caplog.at_level(logging.WARNING, logger="dbc"):
        machine_from_toml(tomllib.loads(TOML), "m.toml", STRANGER)
        assert caplog.messages == []
        machine_from_toml(tomllib.loads(without), "m.toml", STRANGER)
    assert caplog.messages == [
        "m.toml: protection.ZYL_VL: ZYL_VL_Pruefsumme (a CRC by its name), ZYL_VL_Zaehler (a "
        "rolling counter by its name) are not checked: the config has no [protection.ZYL_VL]; "
        "name them there (counter, crc, crc_algorithm as the sender computes it) to judge its "
        "frames",
        "m.toml: protection.ZYL_HL: ZYL_HL_CRC8 (a CRC by its name) is not checked: "
        "[protection.ZYL_HL] names no crc; name it there (counter, crc, crc_algorithm as the "
        "sender computes it) to judge its frames",
    ]
