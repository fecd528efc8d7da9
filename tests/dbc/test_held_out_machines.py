"""Held-out machines: DBCs and machine configs written as another integrator would
(tests/files/stranger/), driven through the public paths with frames built by hand from
the DBC's layout (not by the project's encoder), forces checked against eq. (4) worked
out here from the config's numbers, in SI."""

import csv
import io
import math
import struct
from dataclasses import replace
from pathlib import Path

import pytest
from cantools.autosar.end_to_end import compute_profile5_crc
from cantools.database.can import Database
from cantools.j1939 import frame_id_pack
from crccheck.crc import Crc8SaeJ1850

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from daq.replay import replay
from dbc.database import load_database_bytes
from dbc.decoding import FrameDecoder
from dbc.errors import ConfigError
from dbc.machine import MachineConfig, load_machine_config
from dbc.units import pressure_factor_to_Pa

STRANGER = Path(__file__).resolve().parent.parent / "files" / "stranger"
PSI_PA = 4.4482216152605 / 0.0254**2

#: The held-out machines' leg: the example cylinder and lever, written out here.
A_PISTON_M2, A_ROD_M2 = 7.854e-3, 4.737e-3
LEVER = (0.90 * math.sin(math.radians(75.0)) - 0.25 * math.cos(math.radians(75.0))) / 1.20
WEIGHT_TERM_N = 0.55 / 1.20 * 4905.0


def eq4_N(p_piston_Pa: float, p_rod_Pa: float) -> float:
    return (p_piston_Pa * A_PISTON_M2 - p_rod_Pa * A_ROD_M2) * LEVER + WEIGHT_TERM_N


def _pipeline(name: str, compiled: bool) -> tuple[Pipeline, MachineConfig, Database]:
    config, database = load_machine_config(STRANGER / name)
    pipeline = Pipeline.from_config(config, database)
    if not compiled:
        pipeline.decoder = FrameDecoder(
            database,
            config.protection,
            config.unit_factors,
            compiled=False,
            sender_to_si=config.sender_unit_factors,
        )
    return pipeline, config, database


def _hub_frame(counter: int, cap_raw: int, rod_raw: int) -> bytes:
    """A HUB_FRONT/HUB_REAR payload: Motorola 16-bit pressures, the counter in the high
    nibble of byte 4, CRC-8 SAE J1850 of bytes 0..4 in byte 5."""
    data = cap_raw.to_bytes(2, "big") + rod_raw.to_bytes(2, "big", signed=True)
    data += bytes([counter << 4])
    return data + bytes([Crc8SaeJ1850.calc(data)])


HUB_FRONT_ID = 0x00FF0001  # 29 bit, not J1939


@pytest.mark.parametrize("compiled", [True, False])
def test_motorola_psi_hub_gives_eq4_in_si(compiled: bool) -> None:
    pipeline, _, _ = _pipeline("motorola_psi.toml", compiled)
    (estimate,) = pipeline.process(
        RawFrame(1.0, HUB_FRONT_ID, True, _hub_frame(0, 15000, 1000))
    ).estimates
    assert estimate.valid and estimate.leg == "FL"
    assert estimate.p_piston_Pa == pytest.approx(1500.0 * PSI_PA, rel=1e-12)
    assert estimate.p_rod_Pa == pytest.approx(100.0 * PSI_PA, rel=1e-12)
    assert estimate.force_raw_N == pytest.approx(eq4_N(1500 * PSI_PA, 100 * PSI_PA), rel=1e-9)
    rear = pipeline.process(RawFrame(1.001, 0x00FF0002, True, _hub_frame(0, 1500, 200)))
    (estimate,) = rear.estimates
    assert estimate.leg == "RL" and estimate.force_raw_N == pytest.approx(eq4_N(150e5, 20e5))
    # A signed rod pressure below the transducer range: -50 psi is -3.4 bar.
    (estimate,) = pipeline.process(
        RawFrame(1.02, HUB_FRONT_ID, True, _hub_frame(1, 15000, -500))
    ).estimates
    assert estimate.p_rod_Pa == pytest.approx(-50.0 * PSI_PA) and estimate.reasons == ("range",)


@pytest.mark.parametrize("compiled", [True, False])
def test_a_counter_value_the_dbc_names_is_judged_by_its_number(compiled: bool) -> None:
    """FL_Alive's 15 is named "NotAvailable" in the DBC: the counter check takes the
    number (a name in its place once crashed the decoder); the counter counts 0..14,
    its 15 a counter fault (not available, no count: the frame after resynchronises)."""
    pipeline, _, _ = _pipeline("motorola_psi.toml", compiled)
    reasons = []
    for i, counter in enumerate((13, 14, 0, 15, 1, 1)):
        frame = RawFrame(1.0 + 0.02 * i, HUB_FRONT_ID, True, _hub_frame(counter, 15000, 1000))
        result = pipeline.process(frame)
        assert result.decoded is not None
        reasons.append(result.estimates[0].reasons)
    assert reasons == [(), (), (), ("counter",), (), ("counter_repeat",)]
    assert pipeline.frames_lost == 0
    assert dict(pipeline.bad) == {"counter": 1, "counter_repeat": 1}


@pytest.mark.parametrize("encoding", ["utf-8-sig", "utf-16"])
def test_a_dbc_with_a_byte_order_mark_is_read_in_the_encoding_it_declares(
    tmp_path: Path, encoding: str
) -> None:
    """An editor's "UTF-8 with BOM" or Windows' "Unicode" DBC: once "not a valid DBC"."""
    text = (STRANGER / "motorola_psi.dbc").read_text(encoding="cp1252")
    (tmp_path / "motorola_psi.dbc").write_bytes(text.encode(encoding))
    (tmp_path / "machine.toml").write_text((STRANGER / "motorola_psi.toml").read_text())
    config, database = load_machine_config(tmp_path / "machine.toml")
    assert database.get_message_by_name("STATE").get_signal_by_name("OilTemp").unit == "\u00b0C"
    copy = load_database_bytes(text.encode(encoding), "rec.mcap:dbc")  # a recording's copy
    assert copy.get_message_by_name("STATE").get_signal_by_name("OilTemp").unit == "\u00b0C"
    (estimate,) = (
        Pipeline.from_config(config, database)
        .process(RawFrame(1.0, HUB_FRONT_ID, True, _hub_frame(0, 15000, 1000)))
        .estimates
    )
    assert estimate.force_raw_N == pytest.approx(eq4_N(1500 * PSI_PA, 100 * PSI_PA), rel=1e-9)


def test_units_marked_gauge_are_pressure_units_and_come_out_in_pa() -> None:
    """The DBC's "psi(g)" (a chamber) and "PSIG" (a pressure on no leg): once the first
    stopped the config and the second went to Zenoh and MCAP in psi."""
    pipeline, config, _ = _pipeline("motorola_psi.toml", compiled=True)
    assert config.legs["FL"].piston.unit == "psi(g)"
    assert config.unit_factors["ACCU"] == {"pAccu": pytest.approx(PSI_PA, rel=1e-12)}
    accu = pipeline.process(RawFrame(1.0, 0x601, False, (30000).to_bytes(2, "big")))
    assert accu.decoded is not None
    assert accu.decoded.signals["pAccu"] == pytest.approx(3000.0 * PSI_PA, rel=1e-12)


@pytest.mark.parametrize(
    ("unit", "pa"),
    [("psig", PSI_PA), ("bar(g)", 1e5), ("barg", 1e5), ("kPa gauge", 1e3), ("MPa (g)", 1e6)]
    + [("N/mm\u00b2", 1e6), ("n/mm2", 1e6), ("hPa", 100.0), ("kgf/cm\u00b2", 98066.5)]
    + [("KG/CM2 (g)", 9.80665 / 1e-4)]
    + [("N/cm\u00b2", 1e4), ("daN/cm2", 1e5), ("kp/cm\u00b2", 98066.5)]
    + [("bar rel.", 1e5), ("Bar (Relative)", 1e5), ("kPa relative", 1e3)]
    + [("bara", None), ("psia", None), ("kg", None), ("g", None)],
)
def test_gauge_marks_and_absolute_units(unit: str, pa: float | None) -> None:
    factor = pressure_factor_to_Pa(unit)
    assert factor == (None if pa is None else pytest.approx(pa, rel=1e-12))


def _page(page: int, cap_raw: int, ann_raw: int, tail: bytes) -> bytes:
    """A MUXHUB payload: page, MPa pressures at 0.001, and bytes 5..7 (counter, CRC)."""
    return bytes([page]) + cap_raw.to_bytes(2, "little") + ann_raw.to_bytes(2, "little") + tail


def _page0(counter: int, cap_raw: int, ann_raw: int) -> bytes:
    data = _page(0, cap_raw, ann_raw, bytes([counter, 0]))
    return data + bytes([Crc8SaeJ1850.calc(data)])


def test_a_counter_and_crc_on_one_multiplexer_page_are_checked_on_its_frames() -> None:
    """Once a page without the counter raised KeyError out of the pipeline, and the CRC
    was checked (failed) on frames that do not carry it."""
    pipeline, _, _ = _pipeline("mux_pages.toml", compiled=True)  # cantools decodes it
    frames = [
        _page0(7, 12500, 1250),
        _page(1, 10000, 2000, bytes([0x12, 0x34, 0x56])),  # no counter, no CRC
        _page0(8, 12500, 1250),
        _page(1, 10000, 2000, bytes([0xAB, 0xCD, 0xEF])),
        _page0(8, 12500, 1250),  # repeated counter
        _page0(9, 12500, 1250)[:7] + b"\x00",  # bad CRC
    ]
    estimates = [
        pipeline.process(RawFrame(1.0 + 0.005 * i, 0x300, False, data)).estimates
        for i, data in enumerate(frames)
    ]
    assert [(e.leg, e.reasons) for (e,) in estimates] == [
        ("bank-0", ()),
        ("bank-1", ()),
        ("bank-0", ()),
        ("bank-1", ()),
        ("bank-0", ("counter_repeat",)),
        ("bank-0", ("crc",)),
    ]
    assert estimates[0][0].force_raw_N == pytest.approx(eq4_N(12.5e6, 1.25e6), rel=1e-12)
    assert estimates[1][0].force_raw_N == pytest.approx(eq4_N(10e6, 2e6), rel=1e-12)
    assert dict(pipeline.bad) == {"counter_repeat": 1, "crc": 1}


STABILITY = """
[stability]
rotation = "POSE.Rot"
fold = "POSE.Fold"
bridge_length_m = 6.0
hinge_m = 3.0
[stability.bases.front]
axis_m = [0.0, 0.0]
feet_m = { FL = [1.5, 0.0] }
[stability.bases.rear]
axis_m = [0.0, 0.0]
feet_m = { RL = [-1.5, 0.0] }
"""


def test_bridge_angles_in_degrees_spelled_as_dbcs_do_are_taken(tmp_path: Path) -> None:
    """ "°" (Vector's) and "Deg": once only "deg" was taken, and the DBC had to change."""
    (tmp_path / "motorola_psi.dbc").write_bytes((STRANGER / "motorola_psi.dbc").read_bytes())
    text = (STRANGER / "motorola_psi.toml").read_text() + STABILITY
    (tmp_path / "machine.toml").write_text(text)
    config, _ = load_machine_config(tmp_path / "machine.toml")
    assert config.stability is not None and str(config.stability.fold) == "POSE.Fold"
    (tmp_path / "machine.toml").write_text(text.replace('"POSE.Fold"', '"HUB_REAR.RL_pRod"'))
    with pytest.raises(ConfigError) as refused:
        load_machine_config(tmp_path / "machine.toml")
    assert str(refused.value) == (
        f"{tmp_path / 'machine.toml'}: stability.fold: HUB_REAR.RL_pRod has unit 'Bar' in the "
        "DBC, not an angle unit; give its unit: "
        'fold = { signal = "HUB_REAR.RL_pRod", unit = "deg" } '
        "(one of deg, \u00b0, degree, rad, mrad)"
    )


def _fd_page(page: int, counter: int, cap_MPa: float, ann_MPa: float) -> bytes:
    """A HUB_FD payload: page, float32 pressures, counter, then the E2E profile 5 CRC of
    them and data ID 0x1234, low byte first (cantools' CRC is of a payload's bytes 2..)."""
    data = bytes([page]) + struct.pack("<ff", cap_MPa, ann_MPa) + bytes([counter])
    crc = compute_profile5_crc(b"\x00\x00" + data, 0x1234)  # over the bytes after its own
    return data + crc.to_bytes(2, "little")


def test_a_message_longer_than_a_classic_frame_takes_fd_frames() -> None:
    """HUB_FD is 12 bytes and the DBC names no frame format: its frames can only be CAN FD
    (every one was counted fd_frame and dropped)."""
    pipeline, _, database = _pipeline("fd_float.toml", compiled=True)
    assert not database.get_message_by_name("HUB_FD").is_fd  # as cantools reads the DBC
    pages = [(0, 12.5, 1.25), (1, 10.0, 2.0), (0, math.nan, 1.25), (1, 10.0, math.inf)]
    estimates = [
        pipeline.process(
            RawFrame(1.0 + 0.005 * i, 0x300, False, _fd_page(page, i, p, r), is_fd=True)
        ).estimates[0]
        for i, (page, p, r) in enumerate(pages)
    ]
    assert [(e.leg, e.valid) for e in estimates] == [
        ("A", True),
        ("B", True),
        ("A", False),
        ("B", False),
    ]
    assert estimates[0].force_raw_N == pytest.approx(eq4_N(12.5e6, 1.25e6), rel=1e-12)
    assert estimates[1].force_raw_N == pytest.approx(eq4_N(10e6, 2e6), rel=1e-12)
    assert estimates[2].reasons == estimates[3].reasons == ("range",)
    assert not pipeline.bad


def press_a(priority: int, destination: int, source: int, counter: int, raw: int) -> RawFrame:
    """A PRESS_A frame (PGN 0xED00, PDU1) as a transducer sends it: 0.05 kPa/bit, Diag "ok",
    the counter in byte 3, CRC-8 SAE J1850 of bytes 0..6 in byte 7."""
    frame_id = frame_id_pack(priority, 0, 0, 0xED, destination, source)
    data = raw.to_bytes(2, "little") + bytes([0, counter, 0, 0, 0])
    return RawFrame(0.0, frame_id, True, data + bytes([Crc8SaeJ1850.calc(data)]))


def test_j1939_pdu1_transducers_whatever_priority_and_destination() -> None:
    """Held up: PGN 0xED00 from 0x30..0x33 at priority 3 to 0x27 (the DBC: 6, to 0xFE),
    each transducer's own counter, "kPa " with a blank, a value-table code."""
    pipeline, _, _ = _pipeline("j1939_propa.toml", compiled=True)
    filters = pipeline.decoder.receive_filters
    estimates = []
    t_s = 1.0
    for counter in range(3):
        for source, kPa in ((0x31, 800.0), (0x30, 2800.0), (0x32, 2500.0), (0x33, 600.0)):
            frame = press_a(3, 0x27, source, counter, round(kPa / 0.05))
            assert any(frame.arbitration_id & f.can_mask == f.can_id & f.can_mask for f in filters)
            result = pipeline.process(replace(frame, t_s=t_s))
            estimates += [(e.leg, e.force_raw_N, e.reasons) for e in result.estimates]
            t_s += 0.001
        t_s += 0.016
    assert (
        estimates
        == [
            ("left-front", pytest.approx(eq4_N(2.8e6, 0.8e6), rel=1e-12), ()),
            ("right-front", pytest.approx(eq4_N(2.5e6, 0.6e6), rel=1e-12), ()),
        ]
        * 3
    )
    result = pipeline.process(replace(press_a(6, 0xFE, 0x30, 3, 0xFFFF), t_s=t_s))
    (estimate,) = result.estimates
    assert math.isnan(estimate.p_piston_Pa) and estimate.reasons == ("range",)
    result = pipeline.process(replace(press_a(6, 0xFE, 0x34, 0, 100), t_s=t_s))
    assert result.estimates == () and dict(pipeline.bad) == {"unmapped_source": 1}


def test_a_29_bit_message_pinned_to_senders_is_matched_as_j1939_without_the_dbc_saying_so() -> None:
    """cantools writes a J1939 message without VFrameFormat J1939PG: a chamber's
    source_address was refused ("not a J1939 message"); it now makes the message J1939."""
    pipeline, config, database = _pipeline("cantools_j1939.toml", compiled=True)
    assert config.legs["two"].rod.source_address == 0x43
    estimates = []
    for i, source in enumerate((0x41, 0x40, 0x43, 0x42)):
        frame_id = frame_id_pack(3, 0, 0, 0xFF, 0x3A, source)  # the DBC's ID: priority 6
        data = (12500 if source % 2 == 0 else 1250).to_bytes(2, "little") + bytes(6)
        result = pipeline.process(RawFrame(1.0 + 0.001 * i, frame_id, True, data))
        estimates += [(e.leg, e.force_raw_N, e.reasons) for e in result.estimates]
    expected = pytest.approx(eq4_N(12.5e6, 1.25e6), rel=1e-12)
    assert estimates == [("one", expected, ()), ("two", expected, ())]
    assert not pipeline.bad


def test_a_j1939_code_above_the_dbcs_range_is_no_pressure() -> None:
    """PRESS_A.Press is [0|3212.75] kPa (J1939: 0..0xFAFF); 0xFE00, J1939's "error", is
    named by no value table: once it was a valid 3.2512 MPa, now the chamber is NaN."""
    pipeline, _, _ = _pipeline("j1939_propa.toml", compiled=True)
    rod_at_max = pipeline.process(replace(press_a(6, 0xFE, 0x31, 0, 0xFAFF), t_s=1.0))
    (estimate,) = pipeline.process(replace(press_a(6, 0xFE, 0x30, 0, 0xFE00), t_s=1.001)).estimates
    assert rod_at_max.decoded is not None  # the decoded signal stays the DBC's number
    assert rod_at_max.decoded.signals["Press"] == pytest.approx(3212.75e3)
    assert math.isnan(estimate.p_piston_Pa) and estimate.reasons == ("range",)
    assert estimate.p_rod_Pa == pytest.approx(3212.75e3)  # the range's end is inside it


def test_frames_the_held_out_dbc_cannot_use_are_counted_by_kind() -> None:
    """Held up: a 6-byte message padded to 8, a short one, an 11-bit frame with a 29-bit
    message's number, an unknown ID, an FD frame of a classic message."""
    pipeline, _, _ = _pipeline("motorola_psi.toml", compiled=True)
    good = _hub_frame(0, 15000, 1000)
    frames = [
        RawFrame(1.0, HUB_FRONT_ID, True, good + b"\x00\x00"),
        RawFrame(1.0, HUB_FRONT_ID, True, good[:5]),
        RawFrame(1.0, HUB_FRONT_ID & 0x7FF, False, good),
        RawFrame(1.0, 0x1FFFFFFF, True, good),
        RawFrame(1.0, HUB_FRONT_ID, True, good, is_fd=True),
    ]
    kinds = [pipeline.process(frame).error_kind for frame in frames]
    assert kinds == ["wrong_dlc", "wrong_dlc", "unknown_id", "unknown_id", "fd_frame"]
    assert pipeline.frames == 5 and sum(pipeline.bad.values()) == 5


@pytest.mark.parametrize(
    ("old", "new", "reason"),
    [
        (
            "BO_ 2164195330 HUB_REAR",
            "BO_ 2164195329 HUB_REAR",
            "HUB_FRONT has the frame ID of HUB_REAR too in the DBC (0xFF0001, 0xFF0001): "
            "their frames cannot be told apart",
        ),
        (
            "BO_ 2164195330 HUB_REAR",
            "BO_ 2164195330 HUB_FRONT",
            "the DBC has two messages named HUB_FRONT: rename one",
        ),
    ],
)
def test_a_message_whose_id_or_name_another_has_too_stops_the_config(
    tmp_path: Path, old: str, new: str, reason: str
) -> None:
    """cantools keeps the last of two such messages: HUB_REAR's legs read HUB_FRONT's
    frames (a silently wrong force), or FL's signals were "not in" HUB_FRONT."""
    text = (STRANGER / "motorola_psi.dbc").read_text(encoding="cp1252")
    assert old in text
    (tmp_path / "motorola_psi.dbc").write_text(text.replace(old, new), encoding="cp1252")
    (tmp_path / "machine.toml").write_text((STRANGER / "motorola_psi.toml").read_text())
    with pytest.raises(ConfigError) as refused:
        load_machine_config(tmp_path / "machine.toml")
    assert refused.value.key == "legs.FL.piston" and refused.value.reason == reason


def test_two_j1939_messages_of_one_pgn_and_sender_stop_the_config(tmp_path: Path) -> None:
    """One group twice for one sender, at two priorities (two DBCs merged): the decoder
    kept the last for that sender's frames."""
    text = (STRANGER / "j1939_propa.dbc").read_text()
    twin = 'BO_ 2364407806 PRESS_A_P3: 8 Xdcr\n SG_ P3 : 0|16@1+ (0.01,0) [0|0] "bar" DAQ\n'
    (tmp_path / "j1939_propa.dbc").write_text(text.replace("BA_DEF_ ", twin + "\nBA_DEF_ ", 1))
    (tmp_path / "machine.toml").write_text((STRANGER / "j1939_propa.toml").read_text())
    with pytest.raises(ConfigError) as refused:
        load_machine_config(tmp_path / "machine.toml")
    assert refused.value.reason == (
        "PRESS_A has the PGN, source and destination address of PRESS_A_P3 too in the DBC "
        "(0x18EDFFFE, "
        "0xCEDFFFE): their frames cannot be told apart"
    )


def test_a_j1939_group_shorter_than_8_bytes_takes_its_frames_padded_to_8(tmp_path: Path) -> None:
    """XDCR_PRESSURE written as the 3 bytes it uses: J1939 transducers pad it to 8 with
    0xFF (J1939-21), and each such frame was counted wrong_dlc."""
    text = (STRANGER / "cantools_j1939.dbc").read_text()
    assert "XDCR_PRESSURE: 8 Xdcr" in text
    (tmp_path / "cantools_j1939.dbc").write_text(
        text.replace("XDCR_PRESSURE: 8", "XDCR_PRESSURE: 3")
    )
    (tmp_path / "machine.toml").write_text((STRANGER / "cantools_j1939.toml").read_text())
    config, database = load_machine_config(tmp_path / "machine.toml")
    pipeline = Pipeline.from_config(config, database)
    rod = (1250).to_bytes(2, "little") + b"\x19"
    piston = (12500).to_bytes(2, "little") + b"\x19"
    pipeline.process(RawFrame(1.0, 0x18FF3A41, True, rod + b"\xff" * 5))
    result = pipeline.process(RawFrame(1.001, 0x18FF3A40, True, piston))  # unpadded too
    assert result.estimates[0].force_raw_N == pytest.approx(eq4_N(12.5e6, 1.25e6), rel=1e-12)
    assert result.decoded is not None and result.decoded.signals["Temp"] == 25
    short = pipeline.process(RawFrame(1.002, 0x18FF3A41, True, rod + b"\xff" * 4))
    assert short.error_kind == "wrong_dlc" and dict(pipeline.bad) == {"wrong_dlc": 1}


def test_a_counter_the_dbc_declares_0_to_14_wraps_from_14_to_0() -> None:
    """RL_Alive is [0|14] (AUTOSAR E2E profile 1 counts so): 14 -> 0 is one step (it was
    a lost frame at every wrap), and 15, a value it never takes, is a counter fault."""
    pipeline, _, _ = _pipeline("motorola_psi.toml", compiled=True)
    reasons = []
    for i, counter in enumerate((13, 14, 0, 1, 15, 3)):
        frame = RawFrame(1.0 + 0.02 * i, 0x00FF0002, True, _hub_frame(counter, 1500, 200))
        reasons += [e.reasons for e in pipeline.process(frame).estimates]
    assert reasons == [(), (), (), (), ("counter",), ()]
    assert pipeline.frames_lost == 0 and dict(pipeline.bad) == {"counter": 1}


def test_candump_logs_of_held_out_machines_replay_to_eq4(tmp_path: Path) -> None:
    """Held up: a candump log of the J1939 transducers (29-bit IDs, priority 3) and one of
    the FD hub (``##`` lines) replayed with their configs give eq. (4) of the frames."""
    lines = []
    for i, (source, kPa) in enumerate(((0x31, 800.0), (0x30, 2800.0), (0x33, 600.0))):
        frame = press_a(3, 0x27, source, 0, round(kPa / 0.05))
        lines.append(f"(1700000000.{i:06d}) can0 {frame.arbitration_id:08X}#{frame.data.hex()}")
    lines.append(f"(1700000000.000009) can0 {frame.arbitration_id:08X}#{frame.data.hex()[:6]}")
    (tmp_path / "j1939.log").write_text("\n".join(lines) + "\n")
    out = io.StringIO()
    assert replay(tmp_path / "j1939.log", out, STRANGER / "j1939_propa.toml") == 2
    left, right = csv.DictReader(io.StringIO(out.getvalue()))
    assert left["leg"] == "left-front" and left["valid"] == "1"
    assert float(left["force_raw_N"]) == pytest.approx(eq4_N(2.8e6, 0.8e6), rel=1e-12)
    assert right["leg"] == "right-front" and right["reasons"] == "piston_stale|range"  # no 0x32
    fd = _fd_page(1, 0, 10.0, 2.0).hex()
    (tmp_path / "fd.log").write_text(f"(1700000000.000000) can0 300##0{fd}\n")
    out = io.StringIO()
    assert replay(tmp_path / "fd.log", out, STRANGER / "fd_float.toml") == 1
    (row,) = csv.DictReader(io.StringIO(out.getvalue()))
    assert row["leg"] == "B" and float(row["force_raw_N"]) == pytest.approx(eq4_N(10e6, 2e6))


# --- j1939_units: a unit per transducer, cycle times from the config ---------------------------

BAR_PA, MPA_PA = 1e5, 1e6
#: What the j1939_units machine's transducers send, in the order sent: (source address,
#: value in the transducer's own unit, Pa per that unit); 0x5F is mapped to no chamber.
UNITS_SENT = ((0x52, 80.0, BAR_PA), (0x51, 2000.0, PSI_PA), (0x53, 1500.0, PSI_PA))
UNITS_SENT += ((0x54, 4.5, MPA_PA), (0x5F, 12.5, BAR_PA))
#: eq. (4) of those pressures: front (piston 0x51, rod 0x52), rear (rod 0x54 triggers).
UNITS_FORCES_N = {
    "front": eq4_N(2000.0 * PSI_PA, 80.0 * BAR_PA),
    "rear": eq4_N(1500.0 * PSI_PA, 4.5 * MPA_PA),
}


def xdcr(source: int, value: float, t_s: float, priority: int = 6) -> RawFrame:
    """An XDCR frame (PGN 0xFF50) from ``source``: ``value`` in the transducer's own unit,
    32-bit signed little-endian at 0.001 per bit, 25 degC, padded with 0xFF."""
    data = round(value / 0.001).to_bytes(4, "little", signed=True) + bytes([65]) + b"\xff" * 3
    return RawFrame(t_s, int(frame_id_pack(priority, 0, 0, 0xFF, 0x50, source)), True, data)


def units_frames() -> list[RawFrame]:
    return [
        xdcr(source, value, 1_700_000_000.0 + 0.001 * i, priority=3 + i % 4)
        for i, (source, value, _) in enumerate(UNITS_SENT)
    ]


@pytest.mark.parametrize("compiled", [True, False])
def test_each_j1939_transducer_is_converted_by_its_own_unit(compiled: bool) -> None:
    """One signal, XDCR.Pressure, from four transducers in psi, bar (the DBC's) and MPa:
    each frame in Pa by its sender's unit (the decoded signal too: /signals is SI), an
    unmapped sender by the DBC's unit; eq. (4) of the Pa values, on both decoding paths."""
    pipeline, _, _ = _pipeline("j1939_units.toml", compiled)
    decoded, forces = [], {}
    for frame in units_frames():
        result = pipeline.process(frame)
        assert result.decoded is not None
        decoded.append(result.decoded.signals["Pressure"])
        forces |= {e.leg: (e.force_raw_N, e.reasons) for e in result.estimates}
    assert decoded == [pytest.approx(v * unit, rel=1e-12) for _, v, unit in UNITS_SENT]
    assert forces == {
        leg: (pytest.approx(force_N, rel=1e-12), ()) for leg, force_N in UNITS_FORCES_N.items()
    }
    assert dict(pipeline.bad) == {"unmapped_source": 1}


def test_a_candump_log_of_transducers_in_their_own_units_replays_to_eq4(tmp_path: Path) -> None:
    """``portal-daq replay`` of the frames, as a candump log, gives what the live path gives."""
    log = "".join(
        f"({f.t_s:.6f}) can0 {f.arbitration_id:08X}#{f.data.hex().upper()}\n"
        for f in units_frames()
    )
    (tmp_path / "units.log").write_text(log)
    out = io.StringIO()
    assert replay(tmp_path / "units.log", out, STRANGER / "j1939_units.toml") == 2
    rows = {row["leg"]: row for row in csv.DictReader(io.StringIO(out.getvalue()))}
    assert {leg: float(row["force_raw_N"]) for leg, row in rows.items()} == {
        leg: pytest.approx(force_N, rel=1e-9) for leg, force_N in UNITS_FORCES_N.items()
    }
    assert all(row["valid"] == "1" for row in rows.values())


@pytest.mark.parametrize(
    ("all_in_bar", "unmapped"),
    [(True, pytest.approx(12.5e5, rel=1e-12)), (False, pytest.approx(12.5, rel=1e-12))],
)
def test_an_unmapped_sender_of_a_signal_without_a_dbc_unit_takes_the_agreed_one(
    tmp_path: Path, all_in_bar: bool, unmapped: object
) -> None:
    """The vendor DBC gives XDCR.Pressure no unit, each chamber one: an unmapped sender's
    frames are in the unit all chambers agree on (bar), else left in the DBC's number."""
    dbc = (STRANGER / "j1939_units.dbc").read_text()
    (tmp_path / "j1939_units.dbc").write_text(dbc.replace('100000] "bar"', '100000] ""'))
    toml = (STRANGER / "j1939_units.toml").read_text()
    toml = toml.replace("source_address = 0x52 }", 'source_address = 0x52, unit = "bar" }')
    if all_in_bar:
        toml = toml.replace('"psi"', '"bar"').replace('"MPa"', '"bar"')
    (tmp_path / "machine.toml").write_text(toml)
    config, database = load_machine_config(tmp_path / "machine.toml")
    pipeline = Pipeline.from_config(config, database)
    values = {}
    for frame in units_frames():
        decoded = pipeline.process(frame).decoded
        assert decoded is not None and decoded.source_address is not None
        values[decoded.source_address] = decoded.signals["Pressure"]
    assert values[0x5F] == unmapped
    expected_0x51 = 2000.0 * (1e5 if all_in_bar else PSI_PA)
    assert (values[0x52], values[0x51]) == (pytest.approx(80e5), pytest.approx(expected_0x51))
