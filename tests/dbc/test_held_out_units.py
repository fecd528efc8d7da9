"""Pressure units as held-out DBCs spell them (dbc/units.py): German relative pressure
("bar(ü)", "bar rel"), bracketed units, base units spelled out, and absolute units, which
are read as gauge pressures (less the standard atmosphere)."""

from pathlib import Path

import pytest

from daq.frames import RawFrame
from daq.pipeline import Pipeline
from dbc.database import load_database_bytes
from dbc.machine import load_machine_config
from dbc.units import STANDARD_ATMOSPHERE_PA, chamber_unit, pressure_factor_to_Pa
from tests.dbc.test_held_out_machines import PSI_PA, STRANGER, _hub_frame, eq4_N


@pytest.mark.parametrize(
    ("unit", "pa"),
    [("bar(\u00fc)", 1e5), ("BAR\u00fc", 1e5), ("bar rel", 1e5), ("bar (rel)", 1e5)]
    + [("[bar]", 1e5), (" [kPa] ", 1e3), ("N/m\u00b2", 1.0), ("kN/m2", 1e3)]
    + [("N/mm^2", 1e6), ("lbf/in\u00b2", PSI_PA), ("lb/in2", PSI_PA)]
    + [("kPa abs", None), ("bar(a)", None), ("[bara]", None), ("rel", None), ("\u00fc", None)]
    + [("bar(rel.)", 1e5), ("psig.", PSI_PA), ("at\u00fc", 98066.5), ("at", 98066.5)]
    + [("atm", None), ("ata", None), ("bar abs.", None), ("0.01 bar", None)],
)
def test_units_as_held_out_dbcs_spell_them(unit: str, pa: float | None) -> None:
    factor = pressure_factor_to_Pa(unit)
    assert factor == (None if pa is None else pytest.approx(pa, rel=1e-12))


@pytest.mark.parametrize(
    ("unit", "absolute"),
    [("kPa abs", True), ("bar(a)", True), ("PSIA", True), ("bara", True), ("MPa absolute", True)]
    + [("bar abs.", True), ("psi(abs.)", True), ("bar (abs.)", True), ("ata", True)]
    + [("bar", False), ("psig", False), ("a", False), ("kg", False), ("", False), ("Pa", False)],
)
def test_absolute_units_are_told_apart(unit: str, absolute: bool) -> None:
    in_Pa = chamber_unit(unit)
    assert (in_Pa is not None and in_Pa[1] == STANDARD_ATMOSPHERE_PA) is absolute


def _rear_in(tmp_path: Path, unit: str) -> Path:
    """The held-out Motorola hub with HUB_REAR's pressures in ``unit`` (Windows-1252)."""
    text = (STRANGER / "motorola_psi.dbc").read_text(encoding="cp1252")
    assert text.count('"Bar"') == 2
    (tmp_path / "motorola_psi.dbc").write_text(text.replace('"Bar"', f'"{unit}"'), "cp1252")
    (tmp_path / "machine.toml").write_text((STRANGER / "motorola_psi.toml").read_text())
    return tmp_path / "machine.toml"


def test_a_german_relative_pressure_unit_is_bar(tmp_path: Path) -> None:
    """ "bar(ü)" (Überdruck, gauge) stopped the config as no pressure unit."""
    config, database = load_machine_config(_rear_in(tmp_path, "bar(\u00fc)"))
    pipeline = Pipeline.from_config(config, database)
    frame = RawFrame(1.0, 0x00FF0002, True, _hub_frame(0, 1500, 200))
    (estimate,) = pipeline.process(frame).estimates
    assert estimate.valid and estimate.p_piston_Pa == pytest.approx(150e5, rel=1e-12)
    assert estimate.force_raw_N == pytest.approx(eq4_N(150e5, 20e5), rel=1e-12)


def test_an_absolute_unit_is_read_as_gauge_pressure(tmp_path: Path) -> None:
    """An absolute transducer's pressure less the standard atmosphere: eq. (4) takes gauge
    pressures. It was refused (and "set unit = bar" would have read it ~1 bar high)."""
    config, database = load_machine_config(_rear_in(tmp_path, "bar abs"))
    assert (config.legs["RL"].piston.atmosphere_Pa, config.legs["FL"].piston.atmosphere_Pa) == (
        STANDARD_ATMOSPHERE_PA,
        0.0,
    )
    assert config.decoded_units["HUB_REAR"]["RL_pCap"] == "Pa absolute"
    pipeline = Pipeline.from_config(config, database)
    frame = RawFrame(1.0, 0x00FF0002, True, _hub_frame(0, 1500, 200))
    (estimate,) = pipeline.process(frame).estimates
    p_piston_Pa, p_rod_Pa = 150e5 - STANDARD_ATMOSPHERE_PA, 20e5 - STANDARD_ATMOSPHERE_PA
    assert estimate.valid
    assert (estimate.p_piston_Pa, estimate.p_rod_Pa) == pytest.approx((p_piston_Pa, p_rod_Pa))
    assert estimate.force_raw_N == pytest.approx(eq4_N(p_piston_Pa, p_rod_Pa), rel=1e-12)


def test_a_chamber_unit_override_may_be_absolute(tmp_path: Path) -> None:
    override = _rear_in(tmp_path, "bar")
    text = override.read_text().replace(
        'rod = "HUB_REAR.RL_pRod"', 'rod = { signal = "HUB_REAR.RL_pRod", unit = "psia" }'
    )
    override.write_text(text)
    config, database = load_machine_config(override)
    pipeline = Pipeline.from_config(config, database)
    frame = RawFrame(1.0, 0x00FF0002, True, _hub_frame(0, 1500, 200))
    (estimate,) = pipeline.process(frame).estimates
    assert estimate.p_piston_Pa == pytest.approx(150e5)
    assert estimate.p_rod_Pa == pytest.approx(20 * PSI_PA - STANDARD_ATMOSPHERE_PA)


def test_a_dbc_in_utf_8_without_a_byte_order_mark_is_read_as_utf_8(tmp_path: Path) -> None:
    """An editor's default: read as Windows-1252, "bar(ü)" was "bar(Ã¼)" (no pressure
    unit) and "°C" was "Â°C"; a Windows-1252 file reads as before."""
    config = _rear_in(tmp_path, "bar(\u00fc)")
    dbc = tmp_path / "motorola_psi.dbc"
    dbc.write_bytes(dbc.read_text(encoding="cp1252").encode("utf-8"))
    loaded, database = load_machine_config(config)
    assert loaded.legs["RL"].piston.unit == "bar(\u00fc)"
    assert database.get_message_by_name("STATE").get_signal_by_name("OilTemp").unit == "\u00b0C"
    cp1252 = load_database_bytes((STRANGER / "motorola_psi.dbc").read_bytes(), "held-out")
    assert cp1252.get_message_by_name("STATE").get_signal_by_name("OilTemp").unit == "\u00b0C"
