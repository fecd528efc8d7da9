"""Real transducers by configuration: units, J1939 by PGN and source address, one transducer
per chamber, protection profiles and status per leg (tests/files/transducers.dbc)."""

import math
import subprocess
import sys
import tomllib
from pathlib import Path
from typing import Any

import pytest
from cantools.autosar.end_to_end import compute_profile2_crc, compute_profile5_crc
from cantools.j1939 import frame_id_pack
from crccheck.crc import Crc

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from dbc.database import load_database
from dbc.decoding import FrameDecoder
from dbc.encoding import FrameEncoder
from dbc.errors import ConfigError
from dbc.machine import MachineConfig, load_machine_config, parse_machine_config
from dbc.protection import CRC_ALGORITHMS, CrcCheck, TableCrc, reference_checksum
from dbc.units import PRESSURE_UNITS_TO_PA
from estimator import foot_force_N
from tests.helpers import FILES, LEG_DEFAULTS_TOML, ROOT, dbc_text

DBC_PATH = ROOT / "tests" / "files" / "transducers.dbc"
DATABASE = load_database(DBC_PATH)
PGN_ID = 0x18FF2021  # priority 6, PGN 0xFF20 (proprietary B), source address 0x21

BASE = (
    """
[machine]
id = "hyd"
mass_kg = 18800.0

"""
    + LEG_DEFAULTS_TOML
    + """
[legs.J1]
piston = { signal = "HYD_PRESS.Pressure", source_address = 0x21, status = "Status" }
rod = { signal = "HYD_PRESS.Pressure", source_address = 0x22, status = "Status" }

[legs.J2]
piston = { signal = "HYD_PRESS.Pressure", source_address = 0x23 }
rod = { signal = "HYD_PRESS.Pressure", source_address = 0x24 }
max_skew_s = 0.004

[legs.HUB]
piston = "LEG_HUB.pPiston"
rod = "LEG_HUB.pRod"
status = "LEG_HUB.Status"
status_ok = ["ok", 1]

[legs.E2E]
piston = "LEG_E2E5.pPiston"
rod = { signal = "LEG_E2E5.pRod", unit = "bar" }

[legs.PSI]
piston = "LEG_PSI.pPiston"
rod = "LEG_PSI.pRod"

[protection.LEG_HUB]
counter = "Counter"
crc = "Crc"

[protection.LEG_E2E5]
counter = "Counter"
crc = "Crc16"
crc_algorithm = "e2e_p5"
data_id = 0x1234
max_delta_counter = 3

[protection.LEG_PSI]
counter = "Counter"
"""
)


def config_of(text: str = BASE) -> MachineConfig:
    return parse_machine_config(tomllib.loads(text), "machine.toml", DATABASE, DBC_PATH)


def refused(text: str) -> ConfigError:
    with pytest.raises(ConfigError) as info:
        config_of(text)
    assert "\n" not in str(info.value)
    return info.value


class Bench:
    """A pipeline on the test DBC and an encoder making its frames."""

    def __init__(self, text: str = BASE) -> None:
        self.config = config_of(text)
        self.pipeline = Pipeline.from_config(self.config, DATABASE)
        self.encoder = FrameEncoder.from_config(self.config, DATABASE)

    def send(self, message: str, signals: dict[str, Any], t_s: float, **kw: Any) -> list[Any]:
        frame = self.encoder.encode(message, signals, **kw)
        return self.raw(frame.arbitration_id, frame.data, t_s, frame.is_extended_id)

    def raw(self, frame_id: int, data: bytes, t_s: float, extended: bool = False) -> list[Any]:
        result = self.pipeline.process(RawFrame(t_s, frame_id, extended, bytes(data)))
        return list(result.estimates)


# --- units ----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("unit", "pa_per_unit"),
    [
        ("Pa", 1.0),
        ("kPa", 1e3),
        ("MPa", 1e6),
        ("bar", 1e5),
        ("mbar", 100.0),
        ("psi", 6894.757293168361),
    ],
)
def test_each_unit_converts_to_pa(unit: str, pa_per_unit: float) -> None:
    assert PRESSURE_UNITS_TO_PA[unit.lower()] == pytest.approx(pa_per_unit, rel=1e-6)
    text = BASE.replace(
        'rod = { signal = "LEG_E2E5.pRod", unit = "bar" }',
        f'rod = {{ signal = "LEG_E2E5.pRod", unit = "{unit.upper()}" }}',
    )
    bench = Bench(text)
    # raw 123 at the DBC's 0.1 per bit: 12.3 of the configured unit.
    data = bytearray(8)
    data[3:5] = (20000).to_bytes(2, "little")  # piston 20.000 MPa
    data[5:7] = (123).to_bytes(2, "little")
    data[2] = 0
    crc = CrcCheck(CRC_ALGORITHMS["e2e_p5"], 0, data_id=0x1234)
    crc.write(data)
    (estimate,) = bench.raw(0x101, bytes(data), 1.0)
    assert estimate.p_piston_Pa == pytest.approx(20e6)
    assert estimate.p_rod_Pa == pytest.approx(12.3 * pa_per_unit, rel=1e-12)
    assert estimate.valid


def test_dbc_units_kpa_psi_and_mbar_are_read_from_the_dbc() -> None:
    bench = Bench()
    (hub,) = bench.send("LEG_HUB", {"pPiston": 12.5e6, "pRod": 0.8e6, "Status": "ok"}, 1.0)
    assert (hub.p_piston_Pa, hub.p_rod_Pa) == (12.5e6, 0.8e6)  # kPa in the DBC
    data = bytearray(8)
    data[0:2] = (14504).to_bytes(2, "little")  # 1450.4 psi
    data[2:4] = (123).to_bytes(2, "little")  # 12300 mbar
    (psi,) = bench.raw(0x102, bytes(data), 1.0)
    assert psi.p_piston_Pa == pytest.approx(1450.4 * 6894.757293168361, rel=1e-12)
    assert psi.p_rod_Pa == pytest.approx(12300 * 100.0, rel=1e-12)
    # The published force is eq. (4) of the Pa values, not of the DBC numbers.
    geometry = bench.config.legs["PSI"].geometry
    assert psi.force_raw_N == pytest.approx(
        foot_force_N(1450.4 * 6894.757293168361, 1.23e6, geometry), abs=1e-6
    )


def test_unknown_unit_stops_the_config_naming_signal_and_units() -> None:
    error = refused(BASE.replace(', unit = "bar" }', " }"))
    assert error.key == "legs.E2E.rod.signal"
    assert "LEG_E2E5.pRod has unit ''" in str(error)
    assert "Pa, kPa, MPa, bar, mbar, psi" in str(error)
    error = refused(BASE.replace('unit = "bar"', 'unit = "atm"'))
    assert error.key == "legs.E2E.rod.unit" and "'atm'" in str(error)


def test_unknown_unit_exits_2_with_one_line(tmp_path: Path) -> None:
    config = tmp_path / "machine.toml"
    text = BASE.replace(', unit = "bar" }', " }")
    config.write_text(text.replace("mass_kg = 18800.0", f'mass_kg = 18800.0\ndbc = "{DBC_PATH}"'))
    result = subprocess.run(
        [sys.executable, "-m", "daq", "replay", str(DBC_PATH), "--config", str(config)],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
    )
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "legs.E2E.rod.signal" in lines[0] and "psi" in lines[0]


PSI_PA = 6894.757293168361


def psi_rod_text(extra: str = "") -> str:
    """BASE with J2's rod transducer (0x24) in psi: the DBC's bar for the others."""
    return BASE.replace(
        'rod = { signal = "HYD_PRESS.Pressure", source_address = 0x24 }',
        f'rod = {{ signal = "HYD_PRESS.Pressure", source_address = 0x24, unit = "psi"{extra} }}',
    )


@pytest.mark.parametrize("compiled", [True, False])
def test_each_transducer_of_a_shared_signal_is_read_in_its_own_unit(compiled: bool) -> None:
    """HYD_PRESS.Pressure from 0x24 is psi (its chamber says so), from every other sender
    the DBC's bar: the same raw number is 12.34 psi from 0x24 and 12.34 bar from 0x23."""
    config = config_of(psi_rod_text())
    assert config.unit_factors["HYD_PRESS"] == {"Pressure": 1e5}
    assert config.sender_unit_factors == {("HYD_PRESS", 0x24): {"Pressure": PSI_PA}}
    bench = Bench(psi_rod_text())
    if not compiled:
        bench.pipeline.decoder = FrameDecoder(
            DATABASE,
            config.protection,
            config.unit_factors,
            compiled=False,
            sender_to_si=config.sender_unit_factors,
        )
    decoder = bench.pipeline.decoder
    raw = pressure_bytes(12.34)  # raw 1234 at 0.01 per bit
    assert decoder.decode(j1939_id(6, 0x24), raw, 1.0, True).signals["Pressure"] == (
        pytest.approx(12.34 * PSI_PA, rel=1e-12)
    )
    for source in (0x23, 0x21, 0x40):  # mapped without a unit, another leg's, unmapped
        decoded = decoder.decode(j1939_id(6, source), raw, 1.0, True)
        assert decoded.signals["Pressure"] == pytest.approx(12.34e5, rel=1e-12), source
    bench.raw(j1939_id(6, 0x24), pressure_bytes(300.0), 2.000, True)  # 300 psi
    (estimate,) = bench.raw(j1939_id(7, 0x23), pressure_bytes(100.0), 2.002, True)  # 100 bar
    assert estimate.valid and estimate.leg == "J2"
    assert estimate.p_rod_Pa == pytest.approx(300 * PSI_PA, rel=1e-12)
    assert estimate.force_raw_N == pytest.approx(
        foot_force_N(100e5, 300 * PSI_PA, config.legs["J2"].geometry), abs=1e-6
    )


def test_the_encoder_sends_each_transducer_in_its_own_unit() -> None:
    encoder = FrameEncoder.from_config(config_of(psi_rod_text()), DATABASE)
    for source, raw in ((0x24, round(20e5 / PSI_PA / 0.01)), (0x23, 2000)):
        frame = encoder.encode(
            "HYD_PRESS", {"Pressure": 20e5, "Status": "ok"}, source_address=source
        )
        assert frame.data[:2] == raw.to_bytes(2, "little"), hex(source)


def test_two_units_for_one_sender_stop_the_config() -> None:
    """Two chambers on one transducer (one source address) in two units; and a chamber
    pinning no sender (it reads them all) in another unit than another chamber's."""
    text = psi_rod_text().replace(
        'rod = { signal = "HYD_PRESS.Pressure", source_address = 0x22, status = "Status" }',
        'rod = { signal = "HYD_PRESS.Pressure", source_address = 0x24, unit = "bar" }',
    )
    error = refused(text)
    assert error.key == "legs.J2.rod"
    assert "HYD_PRESS.Pressure@0x24 is in 'psi' here and in 'bar' for legs.J1.rod" in str(error)
    assert "both from 0x24" in str(error)
    # Same factor, other spelling: one unit.
    assert config_of(text.replace('unit = "bar"', 'unit = "PSIG"')).sender_unit_factors
    unpinned = BASE + (
        '\n[legs.X]\npiston = { signal = "LEG_E2E5.pRod", unit = "psi" }\nrod = "LEG_PSI.pRod"\n'
    )
    error = refused(unpinned)
    assert error.key == "legs.X.piston" and "without source_address" in str(error)


# --- J1939 ----------------------------------------------------------------------------------


def j1939_id(priority: int, source_address: int, pgn_specific: int = 0x20) -> int:
    return int(frame_id_pack(priority, 0, 0, 0xFF, pgn_specific, source_address))


def pressure_bytes(bar: float, status: int = 0) -> bytes:
    return round(bar / 0.01).to_bytes(2, "little") + bytes([status]) + bytes(5)


def test_j1939_frames_match_by_pgn_whatever_priority_and_source() -> None:
    bench = Bench()
    for priority in (0, 3, 6, 7):
        for source in (0x21, 0x80):
            frame_id = j1939_id(priority, source)
            decoded = bench.pipeline.decoder.decode(frame_id, pressure_bytes(150.0), 0.0, True)
            assert decoded.message == "HYD_PRESS" and decoded.source_address == source
            assert decoded.signals["Pressure"] == pytest.approx(150e5)
    # Another PGN (PS 0x21 instead of 0x20) is not ours; nor is a standard 11-bit ID.
    with pytest.raises(Exception, match="not in the DBC"):
        bench.pipeline.decoder.decode(j1939_id(6, 0x21, 0x21), pressure_bytes(1.0), 0.0, True)
    with pytest.raises(Exception, match="not in the DBC"):
        bench.pipeline.decoder.decode(0x21, pressure_bytes(1.0), 0.0, False)


def test_two_transducers_of_one_pgn_are_two_chambers() -> None:
    bench = Bench()
    assert bench.raw(j1939_id(6, 0x22), pressure_bytes(10.0), 1.000, True) == []  # rod: no trigger
    (estimate,) = bench.raw(j1939_id(3, 0x21), pressure_bytes(180.0), 1.002, True)
    assert (estimate.leg, estimate.valid) == ("J1", True)
    assert (estimate.p_piston_Pa, estimate.p_rod_Pa) == (pytest.approx(180e5), pytest.approx(10e5))
    geometry = bench.config.legs["J1"].geometry
    assert estimate.force_raw_N == pytest.approx(foot_force_N(180e5, 10e5, geometry), abs=1e-6)
    assert estimate.t_s == 1.002


def test_unmapped_source_address_is_counted_not_used() -> None:
    bench = Bench()
    assert bench.raw(j1939_id(6, 0x40), pressure_bytes(99.0), 1.0, True) == []
    assert bench.pipeline.bad["unmapped_source"] == 1
    estimates = bench.send("HYD_PRESS", {"Pressure": 5e6, "Status": "ok"}, 1.0, source_address=0x23)
    assert [e.leg for e in estimates] == ["J2"]
    assert bench.pipeline.bad["unmapped_source"] == 1


def test_encoder_sends_j1939_from_the_source_address() -> None:
    frame = FrameEncoder.from_config(config_of(), DATABASE).encode(
        "HYD_PRESS", {"Pressure": 123.45e5, "Status": "ok"}, source_address=0x2C
    )
    assert (frame.arbitration_id, frame.is_extended_id) == (0x18FF202C, True)
    assert frame.data[:2] == (12345).to_bytes(2, "little")  # 123.45 bar at 0.01 bar/bit


def test_source_address_on_a_non_j1939_message_is_refused() -> None:
    text = BASE.replace(
        'piston = "LEG_HUB.pPiston"', 'piston = { signal = "LEG_HUB.pPiston", source_address = 3 }'
    )
    error = refused(text)
    assert error.key == "legs.HUB.piston.source_address" and "not a J1939 message" in str(error)


# --- one transducer per chamber: the timing rule ----------------------------------------------


def test_other_chamber_older_than_max_skew_makes_the_sample_invalid() -> None:
    bench = Bench()
    j2 = bench.config.legs["J2"]
    assert (j2.trigger, j2.max_skew_s) == ("piston", 0.004)
    assert bench.config.legs["J1"].max_skew_s == 0.010  # default: the rod message's cycle
    # No rod value yet.
    (first,) = bench.raw(j1939_id(6, 0x23), pressure_bytes(100.0), 1.000, True)
    assert first.reasons == ("rod_stale", "range")  # no rod value at all: NaN
    bench.raw(j1939_id(6, 0x24), pressure_bytes(5.0), 1.001, True)
    (fresh,) = bench.raw(j1939_id(6, 0x23), pressure_bytes(100.0), 1.004, True)  # 3 ms: ok
    assert fresh.valid and fresh.p_rod_Pa == pytest.approx(5e5)
    (late,) = bench.raw(j1939_id(6, 0x23), pressure_bytes(100.0), 1.0051, True)  # 4.1 ms
    assert (late.valid, late.reasons) == (False, ("rod_stale",))


def test_the_other_chamber_exactly_max_skew_older_is_fresh_at_unix_times() -> None:
    """Senders on one clock (a hub, the bridge): each piston frame goes out with the rod
    frame of the cycle before, exactly ``max_skew_s`` older. At Unix times the difference
    of two frame times is rounded (to ~0.2 us), which must not make some samples stale."""
    bench = Bench()
    reasons = []
    for k in range(300):
        t_s = round(1_795_400_000.123456 + k * 0.01, 6)
        piston = bench.raw(j1939_id(6, 0x21), pressure_bytes(90.0), t_s, True)
        reasons += [estimate.reasons for estimate in piston]
        bench.raw(j1939_id(6, 0x22), pressure_bytes(5.0), t_s, True)
    assert "rod_stale" in reasons[0]  # no rod value yet
    assert all(r == () for r in reasons[1:]), [r for r in reasons[1:] if r]


def test_a_clock_step_back_neither_freshens_a_silent_chamber_nor_ages_live_ones() -> None:
    """NTP steps the wall clock (the frames' clock) back an hour. J1's rod transducer fell
    silent just before: its last value, an hour "younger" than every piston frame after
    the step by the time stamps, must not pair with them. J2's chambers keep sending
    across the step and stay fresh."""
    bench = Bench()
    rod_silent, rod_live = j1939_id(6, 0x22), j1939_id(6, 0x24)
    piston_silent, piston_live = j1939_id(6, 0x21), j1939_id(6, 0x23)
    t0_s = 1_795_400_000.0
    for k in range(5):  # before the step: both legs fresh
        t_s = t0_s + k * 0.002
        bench.raw(rod_silent, pressure_bytes(5.0), t_s, True)
        bench.raw(rod_live, pressure_bytes(6.0), t_s, True)
        (j1,) = bench.raw(piston_silent, pressure_bytes(90.0), t_s + 0.0012, True)
        (j2,) = bench.raw(piston_live, pressure_bytes(80.0), t_s + 0.0012, True)
        assert j1.valid and j2.valid
    after = t0_s + 0.010 - 3600.0  # stepped back; J1's rod says nothing more
    reasons: dict[str, list[tuple[str, ...]]] = {"J1": [], "J2": []}
    for k in range(10):
        t_s = after + k * 0.002
        bench.raw(rod_live, pressure_bytes(6.0), t_s, True)
        (j1,) = bench.raw(piston_silent, pressure_bytes(90.0), t_s + 0.0012, True)
        (j2,) = bench.raw(piston_live, pressure_bytes(80.0), t_s + 0.0012, True)
        reasons["J1"].append(j1.reasons)
        reasons["J2"].append(j2.reasons)
    assert reasons["J2"] == [()] * 10
    # Bus time: J1's last rod value at 0.008, the last frame before the step at 0.0092;
    # the step adds nothing, so J1's piston frames after it come at 0.0104 + 0.002 k:
    # 0.0024 + 0.002 k after the rod value, beyond J1's max_skew_s (0.010, the rod
    # message's cycle) from k = 4 on. By the time stamps it is an hour the other way.
    assert reasons["J1"] == [()] * 4 + [("rod_stale",)] * 6


def test_a_silent_rod_transducer_makes_its_leg_unheard_for_the_health_check() -> None:
    """J1's rod transducer stops; its piston goes on, each sample ``rod_stale``. The
    service's "legs silent" goes by the bus time at each leg's latest sample made with
    both chambers heard: J1's stops at the rod's last frame, J2's goes on. (It went by
    any sample, so the status stayed healthy with every J1 estimate invalid.)"""
    bench = Bench()
    for k in range(100):  # 1 s of 10 ms cycles; J1's rod silent after 0.2 s
        t_s = 1_795_400_000.0 + k * 0.01
        if k < 20:
            bench.raw(j1939_id(6, 0x22), pressure_bytes(5.0), t_s, True)
        bench.raw(j1939_id(6, 0x24), pressure_bytes(6.0), t_s, True)
        bench.raw(j1939_id(6, 0x21), pressure_bytes(90.0), t_s + 0.001, True)
        (j2,) = bench.raw(j1939_id(6, 0x23), pressure_bytes(80.0), t_s + 0.001, True)
        assert j2.valid
    estimator = bench.pipeline.estimator
    heard = estimator.heard_at_s()
    assert estimator.bus_time_s == pytest.approx(0.991)
    assert heard["J2"] == pytest.approx(0.991)
    # J1's rod last at 0.19 s: fresh (max_skew_s 0.010) for the piston frame of 0.191;
    # from 0.201 on (0.011 s after it) J1's samples are rod_stale.
    assert heard["J1"] == pytest.approx(0.191)


def test_rod_trigger_and_each_chambers_status_follows_its_own_frame() -> None:
    text = BASE.replace("max_skew_s = 0.004", 'max_skew_s = 0.004\ntrigger = "rod"')
    bench = Bench(text)
    bench.raw(j1939_id(6, 0x23), pressure_bytes(100.0), 1.000, True)
    (estimate,) = bench.raw(j1939_id(6, 0x24), pressure_bytes(5.0), 1.002, True)
    assert estimate.valid and estimate.t_s == 1.002
    # J1's rod transducer reports a fault: the samples made with that rod value are invalid.
    bench.raw(j1939_id(6, 0x22), pressure_bytes(5.0, status=2), 2.000, True)
    (bad,) = bench.raw(j1939_id(6, 0x21), pressure_bytes(100.0, status=0), 2.001, True)
    assert bad.reasons == ("status_fault",)
    bench.raw(j1939_id(6, 0x22), pressure_bytes(5.0, status=0), 2.010, True)
    (good,) = bench.raw(j1939_id(6, 0x21), pressure_bytes(100.0), 2.011, True)
    assert good.valid


def test_trigger_must_be_a_chamber() -> None:
    assert refused(BASE.replace("max_skew_s = 0.004", 'trigger = "both"')).key == "legs.J2.trigger"
    assert (
        refused(BASE.replace("max_skew_s = 0.004", "max_skew_s = -1.0")).key == "legs.J2.max_skew_s"
    )


# --- protection profiles --------------------------------------------------------------------


def hub(bench: Bench, counter: int, t_s: float, corrupt: bool = False) -> tuple[str, ...]:
    (estimate,) = bench.send(
        "LEG_HUB",
        {"pPiston": 10e6, "pRod": 1e6, "Status": "ok"},
        t_s,
        counter=counter,
        corrupt_crc=corrupt,
    )
    return estimate.reasons


def test_one_bad_crc_costs_exactly_one_sample() -> None:
    bench = Bench()
    reasons = [
        hub(bench, 0, 0.0),
        hub(bench, 1, 0.01),
        hub(bench, 2, 0.02, corrupt=True),
        hub(bench, 3, 0.03),
        hub(bench, 4, 0.04),
    ]
    assert reasons == [(), (), ("crc",), (), ()]
    assert bench.pipeline.frames_lost == 0 and bench.pipeline.bad["crc"] == 1


def test_a_sender_whose_every_frame_fails_its_crc_is_logged_once(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """A data ID or mode other than the sender's: every frame fails its CRC, every sample
    is invalid, and only bad.crc said it (the status stays healthy: sensor faults do not
    make it unhealthy). One frame corrupted now and then is no such line."""
    bench = Bench()
    line = "LEG_HUB: 20 frames in a row failed their CRC: check the message's [protection]"
    for k in range(19):
        hub(bench, k % 15, k * 0.01, corrupt=True)
    hub(bench, 4, 0.19)  # a good one: the streak starts again
    for k in range(19):
        hub(bench, k % 15, 0.2 + k * 0.01, corrupt=True)
    assert line not in caplog.text
    reasons = [hub(bench, k % 15, 0.4 + k * 0.01, corrupt=True) for k in range(30)]
    assert reasons == [("crc",)] * 30
    assert caplog.text.count(line) == 1
    assert bench.pipeline.bad["crc"] == 19 + 19 + 30


def test_frames_lost_around_a_bad_crc_are_counted() -> None:
    """The next good frame after a corrupted one is not flagged, but the frames missing
    between it and the last good one went uncounted (frames_lost 0 here): a burst of
    interference that corrupts some frames and loses others, or the simulator's --drop
    with --bad-crc (184 frames lost in 3 s, 148 counted)."""
    bench = Bench()
    reasons = [
        hub(bench, 0, 0.0),
        hub(bench, 1, 0.01),
        hub(bench, 2, 0.02, corrupt=True),
        hub(bench, 5, 0.05),  # 3 and 4 lost
        hub(bench, 6, 0.06, corrupt=True),
        hub(bench, 7, 0.07, corrupt=True),
        hub(bench, 8, 0.08),  # nothing lost
        hub(bench, 9, 0.09, corrupt=True),
        hub(bench, 9, 0.10),  # a corrupted frame sent again: nothing lost, no repeat
    ]
    assert reasons == [(), (), ("crc",), (), ("crc",), ("crc",), (), ("crc",), ()]
    assert bench.pipeline.frames_lost == 2 and bench.pipeline.bad["crc"] == 4


def test_counter_repeat_jump_within_and_beyond_max_delta() -> None:
    bench = Bench()  # LEG_HUB: default max_delta_counter 2
    reasons = [hub(bench, c, i * 0.01) for i, c in enumerate((5, 6, 6, 8, 12, 13))]
    assert reasons == [(), (), ("counter_repeat",), (), ("counter",), ()]
    assert bench.pipeline.frames_lost == 1 + 3  # 6->8 lost one (valid), 8->12 lost three
    assert bench.pipeline.bad["counter_repeat"] == 1 and bench.pipeline.bad["counter"] == 1


def test_counter_without_crc_is_checked() -> None:
    bench = Bench()
    reasons = []
    for i, counter in enumerate((250, 251, 255, 0, 0)):
        data = bytearray(8)
        data[4] = counter
        (estimate,) = bench.raw(0x102, bytes(data), i * 0.02)
        reasons.append(estimate.reasons)
    assert reasons == [(), (), ("counter",), (), ("counter_repeat",)]


def test_e2e_profile5_frames_from_the_encoder_check_and_bad_ones_fail() -> None:
    bench = Bench()
    signals = {"pPiston": 20e6, "pRod": 1e6}
    frame = bench.encoder.encode("LEG_E2E5", signals, counter=7)
    # Independent reference: cantools' profile 5 (CRC in bytes 0-1, low byte first).
    assert int.from_bytes(frame.data[:2], "little") == compute_profile5_crc(frame.data, 0x1234)
    (ok,) = bench.raw(frame.arbitration_id, frame.data, 0.0)
    # max_delta_counter = 3: counter 7 -> 10 loses two frames and is still fine.
    (jumped,) = bench.send("LEG_E2E5", signals, 0.01, counter=10)
    assert jumped.valid and bench.pipeline.frames_lost == 2
    bad_frame = bench.encoder.encode("LEG_E2E5", signals, counter=11)
    data = bytearray(bad_frame.data)
    data[4] ^= 0x01
    (bad,) = bench.raw(bad_frame.arbitration_id, bytes(data), 0.02)
    (beyond,) = bench.send("LEG_E2E5", signals, 0.03, counter=12)  # resynchronised
    (far,) = bench.send("LEG_E2E5", signals, 0.04, counter=16)
    assert (ok.reasons, bad.reasons, beyond.reasons, far.reasons) == (
        (),
        ("crc",),
        (),
        ("counter",),
    )


@pytest.mark.parametrize(
    ("algorithm", "check"),
    [
        ("crc8_sae_j1850", 0x4B),
        ("e2e_p1", 0x37),
        ("e2e_p11", 0x37),
        ("e2e_p2", 0xDF),
        ("e2e_p22", 0xDF),
        ("e2e_p5", 0x29B1),
    ],
)
def test_each_crc_algorithm_has_its_published_check_value(algorithm: str, check: int) -> None:
    configuration = CRC_ALGORITHMS[algorithm].configuration
    assert TableCrc(configuration).checksum(b"123456789") == check
    assert reference_checksum(configuration)(b"123456789") == check


def test_e2e_profiles_against_independent_implementations() -> None:
    payload = bytes([0x00, 0x05, 0x12, 0x34, 0x56, 0x78, 0x9A, 0xBC])
    p2 = CrcCheck(CRC_ALGORITHMS["e2e_p2"], 0, data_id=0x3C)
    assert p2.compute(payload, 5) == compute_profile2_crc(payload, 0x3C)
    p2_list = CrcCheck(CRC_ALGORITHMS["e2e_p2"], 0, data_id=tuple(range(0x10, 0x20)))
    assert p2_list.compute(payload, 5) == compute_profile2_crc(payload, 0x15)
    p5 = CrcCheck(CRC_ALGORITHMS["e2e_p5"], 0, data_id=0xBEEF)
    assert p5.compute(payload) == compute_profile5_crc(payload, 0xBEEF)
    # Profile 1 (data ID mode both): SAE J1850's polynomial from 0x00, no final XOR, over
    # ID low, ID high, data w/o CRC byte (each mode against AUTOSAR's vectors:
    # tests/dbc/test_e2e_profile1.py).
    p1 = CrcCheck(CRC_ALGORITHMS["e2e_p1"], 7, data_id=0x0123)
    expected = Crc(8, 0x1D).calc(bytes([0x23, 0x01]) + payload[:7])
    assert p1.compute(payload) == expected
    # A CRC anywhere: profile 5 in bytes 6-7 (low byte first, as AUTOSAR writes it).
    moved = CrcCheck(CRC_ALGORITHMS["e2e_p5"], 6, data_id=0xBEEF)
    frame = bytearray(payload)
    moved.write(frame)
    assert frame[:6] == payload[:6] and moved.matches(bytes(frame))
    assert int.from_bytes(frame[6:8], "little") == compute_profile5_crc(
        bytes(frame[6:8]) + payload[:6], 0xBEEF
    )


def test_a_profile_5_crc_the_dbc_declares_motorola_is_low_byte_first() -> None:
    """AUTOSAR's E2E library writes profile 5's CRC low byte first, whatever the DBC's
    signal says: fd_be_float's HYD_HUB_CRC (bytes 30-31 of a big-endian hub) is Motorola.
    Read high byte first, as before, a real sender's every frame was a crc fault."""
    config, database = load_machine_config(FILES / "stranger" / "fd_be_float.toml")
    message = database.get_message_by_name("HYD_HUB_FD")
    check = config.protection["HYD_HUB_FD"].crc_check(message)
    assert check is not None and (check.start_byte, check.end_byte) == (30, 32)
    frame = bytearray(range(32))
    crc = compute_profile5_crc(bytes(frame[30:32]) + bytes(frame[:30]), 0x0610)
    frame[30:32] = crc.to_bytes(2, "little")
    assert check.matches(bytes(frame)) and crc.to_bytes(2, "big") != bytes(frame[30:32])


@pytest.mark.parametrize(
    ("table", "key", "reason"),
    [
        ('crc = "Crc"\ncrc_algorithm = "crc32"', "crc_algorithm", "unknown 'crc32'"),
        ('crc = "Crc"\ncrc_algorithm = "e2e_p5"\ndata_id = 1', "crc", "16-bit signal"),
        ('crc = "Crc"\ncrc_algorithm = "e2e_p2"', "data_id", "missing"),
        ('crc = "Crc"\ndata_id = 3', "data_id", "no data ID"),
        ('crc = "Crc"\ncrc_algorithm = "e2e_p2"\ndata_id = [1, 2]', "data_id", "16 numbers"),
        ('counter = "Counter"\nmax_delta_counter = 16', "max_delta_counter", "1..15"),
        ('counter = "Nope"', "counter", "no signal 'Nope'"),
        ("", "", "neither a counter nor a crc"),
    ],
)
def test_bad_protection_profile_is_refused(table: str, key: str, reason: str) -> None:
    text = BASE.replace(
        '[protection.LEG_HUB]\ncounter = "Counter"\ncrc = "Crc"', "[protection.LEG_HUB]\n" + table
    )
    error = refused(text)
    assert error.key == ("protection.LEG_HUB." + key).rstrip(".") and reason in str(error)


# --- status per leg -------------------------------------------------------------------------


def test_status_ok_is_per_leg_names_and_numbers() -> None:
    bench = Bench()  # HUB: status_ok = ["ok", 1] (1 is over_range in the value table)
    reasons = []
    for i, status in enumerate(("ok", "over_range", "fault")):
        (estimate,) = bench.send(
            "LEG_HUB", {"pPiston": 10e6, "pRod": 1e6, "Status": status}, i * 0.01
        )
        reasons.append(estimate.reasons)
    assert reasons == [(), (), ("status_fault",)]


def test_a_leg_without_status_is_never_judged_by_status() -> None:
    text = BASE.replace("[sensors]", "") + '\n[sensors]\nstatus_ok = "warming_up"\n'
    bench = Bench(text)
    (estimate,) = bench.send("LEG_E2E5", {"pPiston": 20e6, "pRod": 1e6}, 0.0)
    assert estimate.valid  # no status signal: the global status_ok does not apply


def test_status_name_on_a_signal_without_value_table_needs_the_number() -> None:
    text = BASE.replace(
        'rod = { signal = "LEG_E2E5.pRod", unit = "bar" }',
        'rod = { signal = "LEG_E2E5.pRod", unit = "bar", status = "Counter" }',
    )
    error = refused(text)
    assert error.key == "legs.E2E.rod.status_ok" and "status_ok = 0" in str(error)
    numbered = Bench(
        text.replace('status = "Counter" }', 'status = "Counter", status_ok = [7, 8] }')
    )
    (ok,) = numbered.send("LEG_E2E5", {"pPiston": 20e6, "pRod": 1e6}, 0.0, counter=7)
    (bad,) = numbered.send("LEG_E2E5", {"pPiston": 20e6, "pRod": 1e6}, 0.01, counter=9)
    assert (ok.reasons, bad.reasons) == ((), ("status_9",))


def test_status_values_must_be_names_or_numbers() -> None:
    error = refused(BASE.replace('status_ok = ["ok", 1]', "status_ok = [1.5]"))
    assert error.key == "legs.HUB.status_ok"
    error = refused(BASE.replace('status_ok = ["ok", 1]', 'status_ok = "fine"'))
    assert "'fine' is not a value of LEG_HUB.Status" in str(error)


def test_quantized_bar_pressures_give_eq4_to_1_N() -> None:
    """What the end-to-end tests check on vcan0, in process: eq. (4) of the quantized values."""
    bench = Bench()
    geometry = bench.config.legs["J1"].geometry
    for i, (p_bar, r_bar) in enumerate(((187.123456, 12.345678), (0.004, 300.0049))):
        bench.send("HYD_PRESS", {"Pressure": r_bar * 1e5, "Status": 0}, i, source_address=0x22)
        (estimate,) = bench.send(
            "HYD_PRESS", {"Pressure": p_bar * 1e5, "Status": 0}, i + 0.001, source_address=0x21
        )
        quantized = (round(p_bar / 0.01) * 0.01 * 1e5, round(r_bar / 0.01) * 0.01 * 1e5)
        assert estimate.force_raw_N == pytest.approx(foot_force_N(*quantized, geometry), abs=1.0)
        assert not math.isnan(estimate.force_raw_N)


PER_SENDER_DBC = """VERSION ""
NS_ :
BS_:
BU_: T DAQ
BO_ 2566856737 HYD_21: 8 T
 SG_ P : 0|16@1+ (0.01,0) [0|655.35] "bar" DAQ
BO_ 2566856738 HYD_22: 8 T
 SG_ P : 0|16@1+ (0.01,0) [0|655.35] "bar" DAQ
BA_DEF_ BO_ "VFrameFormat" ENUM "StandardCAN","ExtendedCAN","reserved","J1939PG";
BA_DEF_ BO_ "GenMsgCycleTime" INT 0 65535;
BA_DEF_DEF_ "VFrameFormat" "StandardCAN";
BA_DEF_DEF_ "GenMsgCycleTime" 0;
BA_ "VFrameFormat" BO_ 2566856737 3;
BA_ "VFrameFormat" BO_ 2566856738 3;
BA_ "GenMsgCycleTime" BO_ 2566856737 10;
BA_ "GenMsgCycleTime" BO_ 2566856738 10;
"""


def test_one_dbc_message_per_sender_of_a_pgn() -> None:
    """A DBC may define the PGN once per transducer: each message takes its own address."""
    from dbc.database import load_database_string

    database = load_database_string(PER_SENDER_DBC, "per_sender.dbc")
    legs_start = BASE.index("[legs.J1]")
    text = BASE[:legs_start] + ('[legs.L]\npiston = "HYD_21.P"\nrod = "HYD_22.P"\n')
    config = parse_machine_config(tomllib.loads(text), "m.toml", database)
    assert (config.legs["L"].piston.source_address, config.legs["L"].rod.source_address) == (
        0x21,
        0x22,
    )
    pipeline = Pipeline.from_config(config, database)

    def send(source: int, bar: float, t_s: float) -> Any:
        frame = RawFrame(t_s, j1939_id(3, source), True, pressure_bytes(bar))
        return pipeline.process(frame)

    assert send(0x22, 10.0, 1.0).decoded.message == "HYD_22"
    result = send(0x21, 200.0, 1.001)
    assert result.decoded.message == "HYD_21"
    (estimate,) = result.estimates
    assert estimate.valid and estimate.p_rod_Pa == pytest.approx(10e5)
    stray = send(0x30, 50.0, 1.002)
    assert stray.estimates == () and pipeline.bad["unmapped_source"] == 1


@pytest.mark.parametrize(
    ("old", "new", "key", "reason"),
    [
        (
            "source_address = 0x21,",
            "source_address = 254,",
            "legs.J1.piston.source_address",
            "0..253",
        ),
        (
            "source_address = 0x21,",
            'source_address = "0x21",',
            "legs.J1.piston.source_address",
            "integer",
        ),
        (
            'status = "Status" }',
            'status = "LEG_HUB.Status" }',
            "legs.J1.piston.status",
            "own message",
        ),
        ('status = "Status" }', "status_ok = 0 }", "legs.J1.piston.status_ok", "without a status"),
        (
            'rod = { signal = "HYD_PRESS.Pressure", source_address = 0x24 }',
            'rod = { signal = "HYD_PRESS.Pressure", source_address = 0x23 }',
            "legs.J2.rod",
            "the piston's signal HYD_PRESS.Pressure@0x23",
        ),
        ('rod = "LEG_HUB.pRod"', 'rod = "LEG_HUB.pPiston"', "legs.HUB.rod", "LEG_HUB.pPiston"),
        (
            'rod = { signal = "HYD_PRESS.Pressure", source_address = 0x24 }',
            'rod = "HYD_PRESS.Pressure"',
            "legs.J2.rod",
            "HYD_PRESS.Pressure is also legs.J1.piston's (from 0x21)",
        ),
        (
            'source_address = 0x21, status = "Status" }',
            "sa = 1 }",
            "legs.J1.piston.sa",
            "unknown key",
        ),
    ],
)
def test_bad_chamber_keys_are_refused(old: str, new: str, key: str, reason: str) -> None:
    assert old in BASE
    error = refused(BASE.replace(old, new, 1))
    assert error.key == key and reason in str(error)


def test_an_11_bit_message_is_no_j1939_one_even_where_j1939_is_the_dbc_default() -> None:
    """J1939 IDs have 29 bits: with ``VFrameFormat`` defaulting to J1939PG, the DBC's
    standard-ID messages are still matched by their ID (before, their frames were
    ``unknown_id`` and their legs never estimated)."""
    from dbc.database import load_database_string

    dbc = dbc_text(
        'BO_ 768 STD_LEG: 4 Hub\n SG_ pp : 0|16@1+ (0.01,0) [0|655.35] "bar" DAQ\n'
        ' SG_ pr : 16|16@1+ (0.01,0) [0|655.35] "bar" DAQ\n',
        'BA_DEF_DEF_ "VFrameFormat" "J1939PG";\nBA_ "GenMsgCycleTime" BO_ 768 10;\n',
    ).replace('BA_DEF_DEF_ "VFrameFormat" "StandardCAN";\n', "")
    database = load_database_string(dbc, "default_j1939.dbc")
    legs_start = BASE.index("[legs.J1]")
    text = BASE[:legs_start] + '[legs.L]\npiston = "STD_LEG.pp"\nrod = "STD_LEG.pr"\n'
    config = parse_machine_config(tomllib.loads(text), "m.toml", database)
    pipeline = Pipeline.from_config(config, database)
    (estimate,) = pipeline.process(RawFrame(1.0, 0x300, False, bytes([16, 39, 232, 3]))).estimates
    assert estimate.valid and (estimate.p_piston_Pa, estimate.p_rod_Pa) == (100e5, 10e5)
    pinned = text.replace('"STD_LEG.pp"', '{ signal = "STD_LEG.pp", source_address = 0x21 }')
    with pytest.raises(ConfigError, match="not a J1939 message"):
        parse_machine_config(tomllib.loads(pinned), "m.toml", database)
